"""Building linear models: the operating point, then the engine's Jacobians.

`linearize` (the wrist) and `linearize_structure` (any network) linearise the
engine's own right-hand side (`vsj.stepper.Stepper.jacobian`: central
differences with Richardson extrapolation) at rest, after solving for the
equilibrium. They return a `LinearModel` (python-control), or with
``statespace=False`` the plain `LinearData`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import InputError, SimulationError
from ..network import Signal, Structure
from ..simulate import SimulationOptions
from ..springs import end_stop, evaluate
from ..stepper import JACOBIAN_STEP, Stepper
from ..wrist import WristOptions, build_wrist
from .data import FRICTION_TREATMENTS, PIVOT_INPUT, LinearData, select, signal_name

_ENGINE_LAW = {"linearised": "arctan", "viscous": "viscous", "removed": "viscous"}

#: Equilibrium: Newton stops when the generalised forces are below this [N m].
EQUILIBRIUM_TOL = 1e-12
#: Largest number of Newton iterations for the operating point.
EQUILIBRIUM_ITERATIONS = 200


def _treatment(friction: str) -> str:
    if friction not in FRICTION_TREATMENTS:
        raise InputError(f"friction treatment must be one of {', '.join(FRICTION_TREATMENTS)}, "
                         f"got {friction!r} (the sign, slope and stiction laws are not "
                         "differentiable at zero speed)")
    return friction


def _output_table(structure: Structure) -> list[tuple[str, str, str, str | None]]:
    """(output name, kind, unit, flange or spring name) for every output of a network."""
    named = {s.flange for s in structure.signals}
    probes = list(structure.signals) + [Signal(f, f) for f in structure.free if f not in named]
    table = []
    for s in probes:
        table.append((signal_name(s.name), "angle", "rad", s.flange))
        table.append((signal_name(f"{s.name}.speed"), "speed", "rad/s", s.flange))
    for sp in structure.springs:
        table.append((signal_name(f"{sp.name}.torque"), "torque", "N m", sp.name))
    return table


def _equilibrium(stepper: Stepper, state: np.ndarray, u: np.ndarray,
                 pins: list[tuple[np.ndarray, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Solve for the angles and currents at rest: generalised forces zero, pins held.

    Unknowns: the generalised angles ``x`` and the motor currents ``i`` (each
    motor's voltage is then ``R i``, the current it draws at rest). Equations:
    the generalised forces (``dp/dt``) and the pinned positions ``row . x``.
    """
    structure = stepper.structure
    n, nm = stepper.layout.n, stepper.layout.n_motors
    chan = {c: k for k, c in enumerate(stepper.input_names)}
    volt = [chan[m.channel] for m in structure.motors]
    resist = np.array([m.resistance for m in structure.motors])
    if len(pins) != nm:
        raise InputError(f"operating point: {len(pins)} positions pin the free coordinates, "
                         f"but the network has {nm} DC motors whose holding currents are "
                         "unknown; give the motor positions (one per DC motor)")
    unknown = np.concatenate([np.arange(n), 2 * n + np.arange(nm)]).astype(int)
    if unknown.size == 0:
        return state, u
    state = state.copy()
    u = u.copy()

    def residual(z):
        state[unknown] = z
        u[volt] = resist * z[n:]
        force = stepper.rate(state, u)[n:2 * n]
        pinned = [row @ z[:n] - target for row, target in pins]
        return np.concatenate([force, pinned])

    def jac(z):
        state[unknown] = z
        u[volt] = resist * z[n:]
        jx, ju = stepper.jacobian(state, u)
        top = np.hstack([jx[n:2 * n, :n], jx[n:2 * n, 2 * n:2 * n + nm]
                         + ju[n:2 * n, volt] * resist])
        rows = [np.concatenate([row, np.zeros(nm)]) for row, _ in pins]
        return np.vstack([top] + rows) if rows else top

    z = state[unknown].copy()
    r = residual(z)
    for _ in range(EQUILIBRIUM_ITERATIONS):
        if np.max(np.abs(r)) <= EQUILIBRIUM_TOL:
            break
        try:
            dz = np.linalg.solve(jac(z), -r)
        except np.linalg.LinAlgError:
            raise SimulationError("operating point: the equilibrium equations are singular "
                                  "(a free rigid-body motion; pin every motor)") from None
        step = 1.0
        norm = np.max(np.abs(r))
        while step > 1e-6:
            trial = residual(z + step * dz)
            if np.all(np.isfinite(trial)) and np.max(np.abs(trial)) < norm:
                break
            step *= 0.5
        z = z + step * dz
        r = residual(z)
    else:
        raise SimulationError(f"operating point: no equilibrium found after "
                              f"{EQUILIBRIUM_ITERATIONS} Newton iterations (largest "
                              f"generalised force {np.max(np.abs(r)):.3g} N m at "
                              f"{dict(zip(stepper.state_names, state))})")
    residual(z)
    return state, u


def _pivot_sensitivity(structure: Structure, options: SimulationOptions, state, u
                       ) -> np.ndarray:
    """d rate / d q of a fixed pivot, by moving the pivot of the network itself."""
    pivot = structure.pivot

    def f(dq):
        moved = dataclasses.replace(structure, pivot=dataclasses.replace(pivot,
                                                                          fixed=pivot.fixed + dq))
        return Stepper(moved, 1.0, options=options).rate(state, u)

    h = JACOBIAN_STEP * 1e-2  # the pivot moves centimetres: 1e-7 m
    d1 = (f(h) - f(-h)) / (2 * h)
    d2 = (f(h / 2) - f(-h / 2)) / h
    return (4.0 * d2 - d1) / 3.0


def _without_friction(structure: Structure) -> Structure:
    """The same network with every friction element's viscous and Coulomb parts at zero."""
    return dataclasses.replace(structure, frictions=tuple(
        dataclasses.replace(f, viscous=0.0, k=0.0) for f in structure.frictions))


def linearize_structure(structure: Structure, *, angles: Mapping[str, float] | None = None,
                        loads: Mapping[str, float] | None = None, friction: str = "linearised",
                        inputs: Sequence[str] | None = None,
                        outputs: Sequence[str] | None = None,
                        name: str | None = None, statespace: bool = True):
    """Linearise any assembled network at rest.

    ``angles`` holds flanges at given angles [rad]: velocity sources stay
    there; flanges of free coordinates (a DC motor's output) are pinned while
    the equilibrium is solved, one per DC motor, whose holding current and
    voltage follow. ``loads`` maps load channels to constant torques [N m].
    The free angles settle where the generalised forces vanish (Newton's
    method from the undeflected configuration). ``inputs`` and ``outputs``
    select (and order) the model's inputs and outputs by name.
    """
    friction = _treatment(friction)
    if friction == "removed":
        structure = _without_friction(structure)
    options = SimulationOptions(friction=_ENGINE_LAW[friction])
    stepper = Stepper(structure, 1.0, options=options)
    n, nm = stepper.layout.n, stepper.layout.n_motors
    channels = stepper.input_names
    loads = dict(loads or {})
    load_channels = {ld.channel for ld in structure.loads}
    unknown = sorted(set(loads) - load_channels)
    if unknown:
        raise InputError(f"operating point: unknown load channel(s) {', '.join(unknown)}; "
                         f"loads are {', '.join(sorted(load_channels)) or 'none'}")
    for key, value in loads.items():
        if not math.isfinite(value):
            raise InputError(f"operating point: load {key} must be finite, got {value!r}")
    u0 = stepper.input_vector(loads)
    angles = dict(angles or {})
    for key, value in angles.items():
        if not math.isfinite(value):
            raise InputError(f"operating point: angle of {key} must be finite, got {value!r}")
    x0, sigma0 = structure.initial_positions(angles)
    state0 = np.concatenate([x0, np.zeros(n + nm), sigma0])
    pins = []
    for flange, target in angles.items():
        rx, ru = structure.rows(flange)
        if np.any(rx != 0.0):
            pins.append((rx, float(target - ru @ sigma0)))
    state0, u0 = _equilibrium(stepper, state0, u0, pins)

    jx, ju = stepper.jacobian(state0, u0)
    fixed_pivot = structure.pivot.flange is None
    q0 = stepper.pivot_position(state0)
    input_names = list(channels) + ([PIVOT_INPUT] if fixed_pivot else [])
    input_units = list(stepper.input_units) + (["m"] if fixed_pivot else [])
    B_all = ju
    if fixed_pivot:
        B_all = np.hstack([ju, _pivot_sensitivity(structure, options, state0, u0)[:, None]])

    # outputs: angles and speeds are linear in the state and inputs (vsj.network)
    table = _output_table(structure)
    n_state, n_in = stepper.n_state, len(input_names)
    C_all = np.zeros((len(table), n_state))
    D_all = np.zeros((len(table), n_in))
    y0 = np.zeros(len(table))
    Minv, Msu = stepper.model.Minv, stepper.model.mass[:n, n:]
    src_cols = stepper.model.src_ch
    spring_index = {sp.name: k for k, sp in enumerate(structure.springs)}
    warnings = []
    AB = np.hstack([structure.A, structure.B])
    for k, (_, kind, _, ref) in enumerate(table):
        if kind == "angle":
            rx, ru = structure.rows(ref)
            C_all[k, :n] = rx
            C_all[k, 2 * n + nm:] = ru
            y0[k] = rx @ state0[:n] + ru @ state0[2 * n + nm:]
        elif kind == "speed":
            rx, ru = structure.rows(ref)
            C_all[k, n:2 * n] = rx @ Minv
            D_all[k, src_cols] += ru - rx @ Minv @ Msu
        else:
            sp = structure.springs[spring_index[ref]]
            row = structure.spring_rows[spring_index[ref]] @ AB
            deflection = row[:n] @ state0[:n] + row[n:] @ state0[2 * n + nm:]
            tau, stiff = _spring_torque(sp, deflection, q0)
            C_all[k, :n] = -stiff * row[:n]
            C_all[k, 2 * n + nm:] = -stiff * row[n:]
            if fixed_pivot:
                h = 1e-7
                D_all[k, -1] = (_spring_torque(sp, deflection, q0 + h)[0]
                                - _spring_torque(sp, deflection, q0 - h)[0]) / (2 * h)
            y0[k] = tau
            stop = end_stop(sp.law, sp.parameters)
            if stop is not None and abs(deflection) > stop[0]:
                warnings.append(f"spring {sp.name} is deflected {deflection:.4g} rad at the "
                                f"operating point, past its {stop[0]:.4g} rad end stop: the "
                                f"model there is the stop's, not the mechanism's")

    in_idx = select("input", inputs, input_names)
    out_names = [t[0] for t in table]
    out_idx = select("output", outputs, out_names)
    op = {"q": q0,
          "states": dict(zip(stepper.state_names, map(float, state0))),
          "inputs": dict(zip(input_names, map(float, np.append(u0, q0) if fixed_pivot
                                               else u0))),
          "outputs": dict(zip(out_names, map(float, y0 + 0.0)))}  # + 0.0: no "-0"
    info = {"network": structure.name, "friction": FRICTION_TREATMENTS[friction],
            "pivot": ("held at q (a parameter; input 'q' is its sensitivity); the pivot "
                      "mechanism is not back-driven and is not part of the model")
            if fixed_pivot else "moving pivot: its drive is part of the state",
            "coordinates": "momenta p = M v + M_su u (see vsj.linear)", "warnings": warnings}
    data = LinearData(jx, B_all[:, in_idx], C_all[out_idx], D_all[np.ix_(out_idx, in_idx)],
                      state_labels=list(stepper.state_names),
                      input_labels=[input_names[i] for i in in_idx],
                      output_labels=[out_names[i] for i in out_idx],
                      state_units=stepper.state_units,
                      input_units=[input_units[i] for i in in_idx],
                      output_units=[table[i][2] for i in out_idx], operating_point=op,
                      friction=friction, info=info, name=name or structure.name)
    return data.statespace() if statespace else data


def _spring_torque(spring, deflection: float, q: float) -> tuple[float, float]:
    torque, stiffness, _, _ = evaluate(spring.law, spring.parameters, deflection, q)
    return float(torque[0]), float(stiffness[0])


def linearize(params, q: float = 0.0, *, motors: tuple[float, float] = (0.0, 0.0),
              load: tuple[float, float] = (0.0, 0.0), wrist_options=None,
              friction: str = "linearised", inputs: Sequence[str] | None = None,
              outputs: Sequence[str] | None = None, statespace: bool = True):
    """Linearise the wrist at pivot position ``q`` [m], motor positions and a static load.

    ``motors`` are the angles [rad] of the two primary motors' outputs (the
    suns); ``load`` the external torques ``(tau_x, tau_y)`` [N m] on the
    end-effector, which deflect the elastic elements at the operating point.
    ``wrist_options`` (`vsj.wrist.WristOptions`) choose the sub-models; the pivot is
    always held at ``q`` (see the module docstring). ``friction`` is a key of
    `FRICTION_TREATMENTS`. With DC motors, each motor holds its position with
    the current the load needs (open-loop voltage ``R i``). Returns a
    `LinearModel` (python-control), or with ``statespace=False`` the plain
    `LinearData`.
    """
    lo, hi = params.pivot.q_min, params.pivot.q_max
    if not (isinstance(q, (int, float)) and math.isfinite(q)):
        raise InputError(f"pivot position q must be a finite number of metres, got {q!r}")
    if not (lo - 1e-12 <= q <= hi + 1e-12):
        raise InputError(f"pivot position q = {q * 100:.4g} cm is outside the pivot range "
                         f"{lo * 100:.4g} ... {hi * 100:.4g} cm (parameters pivot.q_min, "
                         f"pivot.q_max of {params.origin})")
    if len(motors) != 2 or len(load) != 2:
        raise InputError("motors and load take two values each (motor 1, motor 2; tau_x, tau_y)")
    options = wrist_options or WristOptions()
    held = dataclasses.replace(options, pivot_drive="fixed", fixed_q=float(q))
    structure = build_wrist(params, held).assemble()
    loads = {}
    if options.end_effector == "loaded":
        loads = {"tau_x": float(load[0]), "tau_y": float(load[1])}
    elif any(load):
        raise InputError("a load needs end_effector='loaded' (the driven end-effector's "
                         "angles are inputs)")
    model = linearize_structure(structure, angles={"pg_1.sun": float(motors[0]),
                                                   "pg_2.sun": float(motors[1])},
                                loads=loads, friction=friction, inputs=inputs, outputs=outputs,
                                statespace=statespace)
    model.info.update({"parameters": {"origin": params.origin, "hash": params.hash()},
                       "wrist_options": {**dataclasses.asdict(options), "fixed_q": float(q),
                                         "pivot_drive": f"held at q ({options.pivot_drive} "
                                                        "drive not in the linear model)"},
                       "motors": list(map(float, motors)), "load": list(map(float, load))})
    return model


def sweep(params, qs: Sequence[float], **kwargs) -> list:
    """`linearize` at each pivot position in ``qs`` [m] (other arguments shared)."""
    return [linearize(params, float(q), **kwargs) for q in qs]
