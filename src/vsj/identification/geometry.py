"""Calibration of the elastic element's unknown dimensions.

The report gives the elastic element's geometry only as a sketch (fig 3.3):
the ring radius R, lever length L and width W, the spring anchor (x0, y0), the
rest length s0 and the spring stiffness k are not stated. What it does give:

* the measured small-deflection stiffness: 0.063, 0.43 and 7.2 N m/rad at
  q = 1.4, -0.4 and -2.2 cm (fig 4.10-4.12), and the exponential fit of all
  measured points, K(q) = a1 exp(a2 q) + a3 (eq 4.5, fig 4.13);
* where a spring lost its pretension within the measured range: at
  q = 0.2 ... -1.0 cm, not at 2.0 ... 0.8 cm nor at -1.6 ... -2.2 cm
  (section 4.2.2);
* where the non-linearity of the curve peaks: between q = 0.3 and -0.6 cm
  (fig 3.6), judged here over the range a hand explored on the bench;
* that the curves at q = 1.4 and -2.2 cm stay close to straight lines up to
  the end of the measured range (fig 4.10, 4.12: 0.05 N m at 0.8 rad, 1 N m
  at 0.14 rad).

`calibrate_to_report` finds the dimensions that best meet the first, second
and fourth statements; `ReportTargets` holds them. The third cannot be met
together with the first: the measured stiffness ratio K(-2.2 cm)/K(1.4 cm) of
114 forces the lever pin to within about 1 cm of the pivot at the stiffest
setting, where the lever turns about three times as fast as the ring and the
geometry bends the curve whatever the other dimensions are (searches that
included the peak moved it from -2.0 cm at most, while losing up to 15 % of
the stiffness fit). `assess` still reports where the peak falls. The measured range at each pivot position is
modelled after fig 4.10-4.12: deflections up to 0.8 rad, or up to a torque of
1 N m, whichever comes first.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import differential_evolution, least_squares

from .. import characteristics as ch
from ..springs import GEOMETRIC, GEOMETRY_FIELDS

#: Pivot positions of the report's stiffness test (section 4.2.2) [m].
TESTED_Q = tuple(q / 100 for q in (2.0, 1.4, 0.8, 0.2, -0.4, -1.0, -1.6, -2.2))


@dataclass(frozen=True)
class ReportTargets:
    """What the report states about the elastic element (SI)."""

    measured_K: dict = field(default_factory=lambda: {0.014: 0.063, -0.004: 0.43,
                                                      -0.022: 7.2})
    exponential: tuple = (0.2, -145.0, 0.02)  # a1 [N m/rad], a2 [1/m], a3 [N m/rad], eq 4.5
    loss_seen: tuple = (0.002, -0.004, -0.010)
    loss_not_seen: tuple = (0.020, 0.014, 0.008, -0.016, -0.022)
    nonlinearity_peak: tuple = (-0.006, 0.003)
    straight: tuple = (0.014, -0.022)
    range_deflection: float = 0.8    # rad, largest deflection tested by hand
    range_torque: float = 1.0        # N m, largest torque tested by hand
    end_stop: float = 1.40
    end_stop_stiffness: float = 50.0

    def K_exponential(self, q):
        """The report's exponential ``K(q) = a1 exp(a2 q) + a3`` [N m/rad] at pivot
        positions ``q`` [m] (eq 4.5)."""
        a1, a2, a3 = self.exponential
        return a1 * np.exp(a2 * np.asarray(q)) + a3

    def tested_range(self, q: float) -> float:
        """Largest deflection measured at ``q`` [rad] (model of fig 4.10-4.12)."""
        return min(self.range_deflection, self.range_torque / float(self.K_exponential(q)))


def parameter_row(R, L, W, x0, y0, s0, k, targets: ReportTargets) -> np.ndarray:
    """The spring-law parameter row of a geometry (ring radius, lever length and width,
    anchor x and y, rest length [m], spring rate [N/m]) with the report's end stop and
    end-stop stiffness appended."""
    return np.array([R, L, W, x0, y0, s0, k, targets.end_stop, targets.end_stop_stiffness])


def assess(row, targets: ReportTargets | None = None) -> dict:
    """How well a geometry meets the report's statements (for tables and the calibration)."""
    targets = targets or ReportTargets()
    K = {q: ch.stiffness(GEOMETRIC, row, q) for q in TESTED_Q}
    loss = {q: ch.pretension_loss(row, q) for q in TESTED_Q}
    ranges = {q: targets.tested_range(q) for q in TESTED_Q}
    q_grid = np.linspace(-0.022, 0.020, 22)
    nl = np.array([ch.nonlinearity(GEOMETRIC, row, q, max_torque=targets.range_torque,
                                   limit=targets.range_deflection) for q in q_grid])
    return {"K": K, "pretension_loss": loss, "tested_range": ranges,
            "loss_within_range": {q: loss[q] < ranges[q] for q in TESTED_Q},
            "nonlinearity_q": q_grid, "nonlinearity": nl,
            "nonlinearity_peak_q": float(q_grid[int(np.argmax(nl))])}


def _residuals(x, targets: ReportTargets) -> np.ndarray:
    R, beyond, W, x0, y0, pre, k = x
    L = R + 0.020 + beyond
    ell0 = math.hypot(W - x0, L - R - y0)
    s0 = ell0 * (1.0 - pre)
    row = parameter_row(R, L, W, x0, y0, s0, k, targets)
    res = []
    for q in TESTED_Q:
        K = ch.stiffness(GEOMETRIC, row, q)
        if not K > 0:
            return np.full(20, 10.0)
        weight = 3.0 if any(abs(q - m) < 1e-9 for m in targets.measured_K) else 1.0
        goal = next((v for m, v in targets.measured_K.items() if abs(q - m) < 1e-9),
                    float(targets.K_exponential(q)))
        res.append(weight * math.log(K / goal))
    for q in targets.loss_seen:
        ratio = min(ch.pretension_loss(row, q), 5.0) / targets.tested_range(q)
        res.append(2.0 * max(0.0, ratio - 0.9))
    for q in targets.loss_not_seen:
        ratio = min(ch.pretension_loss(row, q), 5.0) / targets.tested_range(q)
        res.append(2.0 * max(0.0, 1.1 - ratio))
    for q in targets.straight:  # measured curves straight up to the end of the range
        phi = targets.tested_range(q)
        goal = next(v for m, v in targets.measured_K.items() if abs(q - m) < 1e-9) * phi
        res.append(2.0 * math.log(max(ch.torque_curve(GEOMETRIC, row, q, [phi])[0], 1e-9) / goal))
    for q in TESTED_Q:  # no snap-through inside the range the hand explored
        phis = np.linspace(0.0, targets.tested_range(q), 30)
        stiff = np.array([ch.stiffness(GEOMETRIC, row, q, p) for p in phis])
        res.append(max(0.0, -stiff.min()) / max(stiff[0], 1e-9))
    return np.array(res)


def _cost(x, targets: ReportTargets) -> float:
    return float(np.sum(_residuals(x, targets) ** 2))


def _unknowns(dims: dict) -> np.ndarray:
    """Search variables of a geometry (the inverse of the map in `_residuals`)."""
    R, L, W, x0, y0, s0, k = (dims[f] for f in GEOMETRY_FIELDS[:7])
    ell0 = math.hypot(W - x0, L - R - y0)
    return np.array([R, L - R - 0.020, W, x0, y0, 1.0 - s0 / ell0, k])


def calibrate_to_report(targets: ReportTargets | None = None, *, seed: int = 0,
                        maxiter: int = 60, workers: int = 1, start: dict | None = None) -> dict:
    """Dimensions (SI, keyed by `GEOMETRY_FIELDS`) that best meet the report's statements.

    A global search (differential evolution, seeded, so the result is
    reproducible) over R, the lever's reach past the highest pivot position,
    W, the anchor (x0, y0), the pretension (as a fraction of the spring length)
    and k, optionally seeded with a ``start`` geometry. Returns the dimensions,
    the residual norm and `assess` of the result.
    """
    targets = targets or ReportTargets()
    # pretension at most 0.6 of the stretched length: springs at most 2.5x their rest length
    bounds = [(0.024, 0.06), (0.005, 0.08), (0.0, 0.02), (0.01, 0.15), (-0.05, 0.15),
              (0.02, 0.6), (5.0, 3000.0)]
    result = differential_evolution(
        functools.partial(_cost, targets=targets), bounds, seed=seed, maxiter=maxiter, tol=1e-10,
        polish=False, x0=None if start is None else _unknowns(start), workers=workers,
        updating="deferred" if workers != 1 else "immediate")
    R, beyond, W, x0, y0, pre, k = result.x
    L = R + 0.020 + beyond
    s0 = math.hypot(W - x0, L - R - y0) * (1.0 - pre)
    row = parameter_row(R, L, W, x0, y0, s0, k, targets)
    dims = dict(zip(GEOMETRY_FIELDS, row.tolist()))
    return {"dimensions": dims, "cost": float(result.fun), "assessment": assess(row, targets)}


@dataclass
class CurveCalibration:
    """The geometry fitted to measured torque-deflection curves."""

    dimensions: dict            # GEOMETRY_FIELDS -> SI value
    start: dict                 # the geometry it started from
    rms_before: float           # relative RMS deviation (of each curve's torque range)
    rms_after: float
    per_curve: list[dict]       # q, rms before and after, K of the calibrated model

    def to_json(self) -> dict:
        """The calibration (dimensions, rms misfit before and after, per curve) as plain
        JSON data (SI values with their units)."""
        return {"dimensions": {k: {"value": v, "unit": _UNITS[k]}
                               for k, v in self.dimensions.items()},
                "relative_rms_before": self.rms_before, "relative_rms_after": self.rms_after,
                "curves": self.per_curve}


_UNITS = {"ring_radius": "m", "lever_length": "m", "lever_width": "m", "anchor_x": "m",
          "anchor_y": "m", "rest_length": "m", "spring_stiffness": "N/m", "end_stop": "rad",
          "end_stop_stiffness": "N m/rad"}
#: Samples per curve used by the calibration (evenly spread over the loop).
CALIBRATION_SAMPLES = 200


def calibrate_to_curves(curves, start: dict) -> CurveCalibration:
    """Fit the seven unknown dimensions to measured curves (`stiffness.CurveFit` list).

    Each curve's friction hysteresis, offset and play (from its linear fit) are
    taken out, leaving the elastic torque; the geometric model (eq 3.1-3.7) is
    fitted to it by least squares on relative deviations (each curve counts in
    proportion to its torque range, so soft and stiff settings weigh alike),
    starting from ``start`` (for example the bundled estimate).
    """
    if len(curves) < 2:
        raise ValueError("the geometry needs curves at two or more pivot positions")
    data = []
    for c in curves:
        idx = np.linspace(0, len(c.deflection) - 1, min(CALIBRATION_SAMPLES,
                                                       len(c.deflection))).astype(int)
        phi = c.deflection[idx] - (0.5 * c.play.value * np.sign(c.torque[idx])
                                   if c.play_detected else 0.0)
        elastic = c.torque[idx] - c.hysteresis.value * c.direction[idx] - c.offset.value
        data.append((c.q, phi, elastic, max(float(np.ptp(elastic)), 1e-9)))
    names = GEOMETRY_FIELDS[:7]
    x0 = np.log([start[n] if start[n] > 0 else 1e-4 for n in names])
    tail = [start.get("end_stop", 1.40), start.get("end_stop_stiffness", 50.0)]

    def row(x):
        return np.concatenate([np.exp(x), tail])

    def residual(x):
        r = row(x)
        out = []
        for q, phi, elastic, scale in data:
            model = ch.torque_curve(GEOMETRIC, r, q, phi)
            out.append((model - elastic) / scale)
        return np.concatenate(out) / math.sqrt(len(data))

    before = residual(x0)
    result = least_squares(residual, x0, x_scale=1.0, max_nfev=400)
    after = result.fun
    n = [len(d[1]) for d in data]
    splits = np.cumsum(n)[:-1]
    per = []
    for (q, *_), b, a in zip(data, np.split(before, splits), np.split(after, splits)):
        k = math.sqrt(len(data))
        per.append({"q": q, "relative_rms_before": float(np.sqrt(np.mean((b * k) ** 2))),
                    "relative_rms_after": float(np.sqrt(np.mean((a * k) ** 2))),
                    "K_model": ch.stiffness(GEOMETRIC, row(result.x), q)})
    dims = dict(zip(names, np.exp(result.x).tolist()))
    return CurveCalibration(dims, {n: start[n] for n in names},
                            float(np.sqrt(np.mean(before ** 2) * len(data))),
                            float(np.sqrt(np.mean(after ** 2) * len(data))), per)
