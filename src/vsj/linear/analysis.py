"""Analysis of linear models: modes, natural frequencies, frequency responses, static
gains and stiffness, bandwidth. Each function takes a `LinearData` or a
`LinearData` (python-control) alike.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..errors import InputError, SimulationError, is_number
from .data import LinearData, select


def _blocks(model: LinearData) -> dict[str, np.ndarray]:
    """Indices of the angle, momentum, current and source-angle states."""
    kinds = {"angle": [], "momentum": [], "current": [], "source": []}
    for k, name in enumerate(model.state_labels):
        kind = name.rsplit(".", 1)[-1]
        kinds[kind if kind in kinds else "angle"].append(k)
    n = len(kinds["momentum"])  # the first n angles are the free ones, then the sources'
    kinds["source"] = kinds["angle"][n:]
    kinds["angle"] = kinds["angle"][:n]
    return {k: np.array(v, dtype=int) for k, v in kinds.items()}


def dynamic_states(model: LinearData) -> np.ndarray:
    """Indices of the states with dynamics of their own (all but the source angles,
    which only integrate their speeds and whose poles sit at zero)."""
    b = _blocks(model)
    return np.sort(np.concatenate([b["angle"], b["momentum"], b["current"]]))


def natural_frequencies(model: LinearData) -> np.ndarray:
    """Undamped natural frequencies [rad/s], ascending: ``sqrt(eig(M^-1 K))``.

    ``M^-1`` and ``K`` are read from the model (``dx/dt = M^-1 p``,
    ``dp/dt = -K x + ...``), so friction and motor circuits are ignored.
    """
    b = _blocks(model)
    A = model.A
    Minv = A[np.ix_(b["angle"], b["momentum"])]
    K = -A[np.ix_(b["momentum"], b["angle"])]
    w2 = np.linalg.eigvals(Minv @ K)
    return np.sort(np.sqrt(np.maximum(w2.real, 0.0)))


def modes(model: LinearData) -> list[dict]:
    """Poles of the dynamic states as modes: frequency ``|pole|`` [rad/s], damping ratio
    ``-Re(pole)/|pole|`` and the pole; one entry per complex pair, ascending."""
    idx = dynamic_states(model)
    poles = np.linalg.eigvals(model.A[np.ix_(idx, idx)]) if idx.size else np.zeros(0)
    out = []
    for p in poles:
        if p.imag < 0.0:
            continue
        w = abs(p)
        out.append({"frequency": float(w), "damping": float(-p.real / w) if w > 0 else 1.0,
                    "pole": complex(p)})
    return sorted(out, key=lambda m: (m["frequency"], m["damping"]))


def _input_vector(model: LinearData, input) -> np.ndarray:
    if isinstance(input, str):
        input = {input: 1.0}
    select("input", list(input), list(model.input_labels))
    b = np.zeros(model.ninputs)
    for name, weight in input.items():
        b[list(model.input_labels).index(name)] = weight
    return b


def transfer(model: LinearData, output: str, input, omega, *, input_angle: bool = False
             ) -> np.ndarray:
    """Frequency response ``output / input`` at ``omega`` [rad/s] (complex array).

    ``input`` is an input name or a mapping of names to weights (a
    combination, e.g. both motors together). With ``input_angle`` the input is
    a velocity source's angle rather than its speed (the response is
    multiplied by ``j omega``): motor position to end-effector position.
    """
    (k,) = select("output", [output], list(model.output_labels))
    b = _input_vector(model, input)
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    A, B, C, D = model.A, model.B @ b, model.C[k], model.D[k] @ b
    eye = np.eye(model.nstates)
    response = np.array([C @ np.linalg.solve(1j * w * eye - A, B) + D for w in omega])
    return response * (1j * omega) if input_angle else response


def static_gain(model: LinearData, outputs: Sequence[str], inputs: Sequence[str]
                ) -> np.ndarray:
    """Steady-state gain (outputs per inputs) with the velocity sources held.

    The source angles are held (their speeds zero), so the gain is that of
    the dynamic states alone; `SimulationError` if those have a free
    rigid-body motion (open-loop DC motors do).
    """
    out_idx = select("output", outputs, list(model.output_labels))
    in_idx = select("input", inputs, list(model.input_labels))
    idx = dynamic_states(model)
    A = model.A[np.ix_(idx, idx)]
    if np.linalg.matrix_rank(A) < A.shape[0]:
        raise SimulationError("the model has a free rigid-body motion (a zero pole), so no "
                              "static gain exists; hold the motors with velocity sources")
    B = model.B[np.ix_(idx, in_idx)]
    C = model.C[np.ix_(out_idx, idx)]
    return -C @ np.linalg.solve(A, B) + model.D[np.ix_(out_idx, in_idx)]


def output_stiffness(model: LinearData, outputs=("theta_x", "theta_y"),
                     inputs=("tau_x", "tau_y")) -> np.ndarray:
    """Static stiffness matrix [N m/rad] at the end-effector, motors held: the inverse of
    the static compliance ``d theta / d tau``."""
    return np.linalg.inv(static_gain(model, outputs, inputs))


def bandwidth(model: LinearData, output: str, input, *, input_angle: bool = False,
              drop_db: float = -3.0, omega_max: float = 1e5) -> float:
    """Lowest frequency [rad/s] where ``|output/input|`` falls ``drop_db`` below its
    low-frequency value; ``inf`` if it never does below ``omega_max``."""
    from scipy.optimize import brentq  # lazy: heavy; only the bandwidth search needs it

    if not is_number(drop_db) or not (math.isfinite(drop_db) and drop_db < 0.0):
        raise InputError(f"bandwidth: drop_db must be a negative number of dB (a fall, -3 "
                         f"for the usual bandwidth), got {drop_db!r}")
    if not is_number(omega_max) or not omega_max > 1e-3:
        raise InputError(f"bandwidth: omega_max must be a frequency above 1e-3 rad/s (where "
                         f"the search starts), got {omega_max!r}")
    if input_angle:
        low = abs(transfer(model, output, input, [1e-6], input_angle=True)[0])
    else:
        (k,) = select("output", [output], list(model.output_labels))
        low = abs(_static(model)[k] @ _input_vector(model, input))
    if low == 0.0:
        raise SimulationError(f"{output} does not respond to {input} at low frequency")
    level = low * 10 ** (drop_db / 20)
    grid = np.logspace(-3, math.log10(omega_max), 600)
    mag = np.abs(transfer(model, output, input, grid, input_angle=input_angle))
    below = np.flatnonzero(mag < level)
    if below.size == 0:
        return math.inf
    i = int(below[0])
    if i == 0:
        return float(grid[0])

    def f(logw):
        return abs(transfer(model, output, input, [10 ** logw], input_angle=input_angle)[0]) \
            - level

    return float(10 ** brentq(f, math.log10(grid[i - 1]), math.log10(grid[i]), xtol=1e-10))


def _static(model: LinearData) -> np.ndarray:
    """Static gain of every output per every input, sources held (see `static_gain`)."""
    return static_gain(model, list(model.output_labels), list(model.input_labels))


