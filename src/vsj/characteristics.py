"""Static characteristics of the VSM elastic element (report section 3.2.2, 4.2).

All functions take a law code and parameter row of
`vsj.springs` and SI values: deflections in rad, pivot
positions in m, torques in N m. "Torque" here is the element's restoring
torque magnitude ``-tau`` (positive for positive deflection), the quantity the
report plots.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from .springs import (GEOMETRIC, GEOMETRIC_REPORT, N_PARAMETERS, end_stop, evaluate,
                      extensions, geometry, shortest_extension)

#: Deflection grid resolution used to search curves [rad].
GRID = 2e-3
#: Absolute tolerance [rad] of the deflections found by root finding (`brentq`'s xtol:
#: the root it returns lies within XTOL plus 4 ulp of it).
XTOL = 1e-9


def torque_curve(law: int, par, q: float, phi) -> np.ndarray:
    """Restoring torque [N m] at deflections ``phi`` (positive for positive phi)."""
    return -evaluate(law, par, phi, q)[0]


def stiffness(law: int, par, q: float, phi: float = 0.0) -> float:
    """Tangent stiffness [N m/rad] at ``phi`` (default: the small-deflection stiffness)."""
    return float(evaluate(law, par, phi, q)[1][0])


def spring_extensions(par, q: float, phi: float) -> tuple[float, float]:
    """Extensions ``l - s0`` [m] of the two springs (negative: slack)."""
    row = np.zeros((1, N_PARAMETERS))
    row[0, :len(par)] = par
    return extensions(phi, q, tuple(row[0]))


def _limit(law: int, par, limit: float | None) -> float:
    """``limit``, or by default the end stop of the law's parameter row."""
    if limit is not None:
        return float(limit)
    stop = end_stop(law, np.pad(np.asarray(par, dtype=float), (0, N_PARAMETERS))[:N_PARAMETERS])
    if stop is None:
        raise ValueError("this spring law has no end stop: give the deflection limit")
    return stop[0]


def pretension_loss(par, q: float, limit: float | None = None) -> float:
    """Smallest positive deflection [rad] at which a spring goes slack, or ``inf``.

    Springs only pull; where one loses its pretension the torque-deflection
    curve kinks (report fig 3.7, 4.11). Searched up to ``limit`` (default: the
    geometric row's end stop).
    """
    limit = _limit(GEOMETRIC, par, limit)
    row = np.zeros((1, N_PARAMETERS))
    row[0, :len(par)] = par
    phis = np.arange(0.0, limit + GRID, GRID)
    ext = shortest_extension(phis, q, row, 0)
    if ext[0] <= 0.0:
        return 0.0
    below = np.flatnonzero(ext <= 0.0)
    if below.size == 0:
        return math.inf
    i = int(below[0])
    return brentq(lambda p: min(spring_extensions(par, q, p)), phis[i - 1], phis[i], xtol=XTOL)


def deflection_under(law: int, par, q: float, torque: float,
                     limit: float | None = None) -> float:
    """Deflection [rad] where the restoring torque first reaches ``torque``.

    Returns ``limit`` (default: the law's end stop) when the element cannot
    hold that torque before it (report fig 3.5).
    """
    limit = _limit(law, par, limit)
    phis = np.arange(0.0, limit + GRID, GRID)
    tau = torque_curve(law, par, q, phis)
    above = np.flatnonzero(tau >= torque)
    if above.size == 0:
        return limit
    i = int(above[0])
    if i == 0:
        return 0.0
    return brentq(lambda p: torque_curve(law, par, q, [p])[0] - torque, phis[i - 1], phis[i],
                  xtol=XTOL)


def nonlinearity(law: int, par, q: float, max_torque: float = 1.0,
                 limit: float | None = None, points: int = 400) -> float:
    """Relative RMS between the torque curve and its small-deflection tangent (fig 3.6).

    Evaluated over ``0 <= phi <= phi_max`` with ``phi_max`` the deflection
    under ``max_torque`` or the end stop, whichever comes first: the largest
    deflection the element sees in use. The RMS difference is divided by the
    tangent's torque at ``phi_max``, so that compliant and stiff settings
    compare (an absolute RMS grows with the torque level alone). The report
    does not state which "equivalent linear curve" it compares with; the
    tangent at zero is the stiffness the measurements of section 4.2 extract.
    """
    phi_max = deflection_under(law, par, q, max_torque, limit)
    phis = np.linspace(0.0, phi_max, points)
    tau = torque_curve(law, par, q, phis)
    linear = stiffness(law, par, q) * phis
    scale = abs(linear[-1]) if phi_max > 0 else 1.0
    return float(np.sqrt(np.mean((tau - linear) ** 2)) / max(scale, 1e-300))


def eq38_mismatch(par, q: float, phi: float) -> float:
    """Relative difference of eq 3.8's ring torque from the potential model's."""
    row = np.zeros((1, N_PARAMETERS))
    row[0, :len(par)] = par
    _, dV, _, _, T_phi, _ = geometry(phi, q, tuple(row[0]))
    return float((T_phi - dV) / dV) if dV != 0 else 0.0


__all__ = ["torque_curve", "stiffness", "spring_extensions", "pretension_loss",
           "deflection_under", "nonlinearity", "eq38_mismatch", "GEOMETRIC", "GEOMETRIC_REPORT"]
