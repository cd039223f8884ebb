"""Linear models of the wrist around an operating point, for control design.

`linearize` returns a python-control `StateSpace` (a `LinearModel`, which
also carries its operating point and how friction was treated) with named
states, inputs and outputs. It linearises the engine's own right-hand side
(`vsj.stepper.rate`, central differences with Richardson extrapolation), so
it works for every sub-model choice of `vsj.wrist.WristOptions` and for any
other network (`linearize_structure`).

Coordinates (the same as `vsj.stepper`)::

    state   x  generalised angles: the free flanges (for the wrist the ring
               angles vsm_i.ring, which are the elastic deflections) [rad]
            p  generalised momenta p = M v + M_su u [N m s]
            i  DC motor currents [A]
            sigma  angles of the velocity sources (motor positions) [rad]
    input   the network's input channels: velocity-source speeds [rad/s],
            load torques [N m], motor voltages [V]; and q [m], the pivot
            position (a fixed pivot's position as an input)
    output  angle [rad] and speed [rad/s] of every named signal of the
            network (theta_x, phi_1, ...; speeds as "<name>_speed"), and the
            torque [N m] that every spring applies ("vsm_1_torque")

Output names are those of `vsj.simulate.Result` with underscores for dots
(``theta_x.speed`` is ``theta_x_speed``): python-control reserves the dot
for ``system.signal`` in interconnections. State names keep vsj's dots.

Momenta rather than speeds because the velocity sources' speeds are inputs:
the kinetic coupling ``M_su du/dt`` would otherwise put the input's
derivative into the model. With momenta the model is proper, and a speed is
an output with a direct feedthrough from the source speeds. Bond graphs
(the report's 20-sim models) use the same states for their inertias.

The pivot is held: the elastic elements do not back-drive it (report section
3.1), so the pivot mechanism and its drive are a separate, one-way chain and
are left out; ``q`` is a parameter of the model and, as input ``q``, the
sensitivity of the ring torques to a small pivot displacement.

Friction (`FRICTION_TREATMENTS`): the wrist rests at the operating point,
where every friction element sits at zero speed. The report's smooth law,
arctan (eq 3.17: ``b s + k atan(k_b s)``), has the slope ``b + k k_b`` there
(for the fitted constants of eq 4.2, ``c1 + c2 c3``): ``linearised`` uses it.
That slope is the small-signal damping, valid while ``k_b |s| << 1`` (speeds
well below 0.1 rad/s with the bundled sharpness of 10 s/rad); for larger
motions friction acts more like a constant torque and damps less. The
Coulomb-like laws (sign, slope, stiction) have no derivative at zero speed
(a jump, a slope set by a numerical width, a set-valued force), so they are
not linearised: ``viscous`` keeps only the viscous part ``b s`` (eq 3.19)
and ``removed`` drops friction altogether.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Mapping, Sequence

import control
import numpy as np

from .errors import InputError, SimulationError
from .friction import LINEAR_TREATMENTS
from .network import Signal, Structure
from .simulate import SimulationOptions
from .stepper import JACOBIAN_STEP, Stepper

#: How friction enters the linear model (see the module docstring).
FRICTION_TREATMENTS = LINEAR_TREATMENTS
_ENGINE_LAW = {"linearised": "arctan", "viscous": "viscous", "removed": "viscous"}

#: Name of the pivot-position input.
PIVOT_INPUT = "q"

#: Equilibrium: Newton stops when the generalised forces are below this [N m].
EQUILIBRIUM_TOL = 1e-12
#: Largest number of Newton iterations for the operating point.
EQUILIBRIUM_ITERATIONS = 200

#: File format tag of `save`/`load`.
FORMAT = "vsj-linear-model"
FORMAT_VERSION = 1


class LinearModel(control.StateSpace):
    """A `control.StateSpace` of a network around an operating point, with its provenance.

    Besides everything a StateSpace does (``poles()``, ``step_response``,
    ``bode_plot``, interconnection by signal names), it carries:
    ``operating_point`` (values of the states, inputs and outputs, and ``q``),
    ``friction`` (the treatment, a key of `FRICTION_TREATMENTS`), the units of
    every state, input and output, and ``info`` (where it came from).
    Results of python-control operations are plain StateSpace objects.
    """

    def __init__(self, A, B, C, D, *, states: Sequence[str], inputs: Sequence[str],
                 outputs: Sequence[str], state_units: Sequence[str],
                 input_units: Sequence[str], output_units: Sequence[str],
                 operating_point: Mapping, friction: str, info: Mapping | None = None,
                 name: str = "wrist"):
        super().__init__(np.asarray(A, float), np.asarray(B, float), np.asarray(C, float),
                         np.asarray(D, float), states=list(states), inputs=list(inputs),
                         outputs=list(outputs), name=name)
        self.state_units = tuple(state_units)
        self.input_units = tuple(input_units)
        self.output_units = tuple(output_units)
        self.operating_point = dict(operating_point)
        self.friction = friction
        self.info = dict(info or {})

    def describe(self) -> str:
        lines = [f"linear model {self.name}: {self.nstates} states, {self.ninputs} inputs, "
                 f"{self.noutputs} outputs; friction {self.friction} "
                 f"({FRICTION_TREATMENTS.get(self.friction, '')})"]
        if "q" in self.operating_point:
            lines.append(f"  pivot q = {self.operating_point['q'] * 100:.4g} cm (held)")
        lines.append("  states:  " + ", ".join(self.state_labels))
        lines.append("  inputs:  " + ", ".join(f"{n} [{u}]" for n, u in
                                                 zip(self.input_labels, self.input_units)))
        lines.append("  outputs: " + ", ".join(self.output_labels))
        for mode in modes(self):
            w, pole = mode["frequency"], mode["pole"]
            if w <= 1e-9 * max(1.0, np.max(np.abs(self.A))):
                lines.append("  pole at 0: a free rigid-body motion")
            elif pole.imag == 0.0:
                lines.append(f"  real pole at {pole.real:.4g} rad/s (time constant "
                             f"{1 / w:.4g} s)")
            else:
                lines.append(f"  mode: {w / (2 * math.pi):.4g} Hz ({w:.4g} rad/s), damping "
                             f"ratio {mode['damping']:.3g}")
        return "\n".join(lines)


# -- building ---------------------------------------------------------------------------


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


def signal_name(name: str) -> str:
    """vsj's dotted name as a python-control signal name (which reserves ``.`` for
    ``system.signal`` in interconnections): dots become underscores."""
    return name.replace(".", "_")


def _select(kind: str, wanted: Sequence[str] | None, available: Sequence[str]) -> list[int]:
    if wanted is None:
        return list(range(len(available)))
    index = {name: i for i, name in enumerate(available)}
    unknown = [w for w in wanted if w not in index]
    if unknown:
        raise InputError(f"unknown {kind}(s) {', '.join(map(repr, unknown))}; available: "
                         f"{', '.join(available)}")
    if len(set(wanted)) != len(wanted):
        raise InputError(f"{kind}s listed twice: {', '.join(wanted)}")
    return [index[w] for w in wanted]


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


def _pivot_sensitivity(stepper: Stepper, state, u) -> np.ndarray:
    """d rate / d q of a fixed pivot (the engine's pivot row is the last)."""
    model = stepper.model
    q0 = model.par[-1, 1]

    def f(dq):
        par = model.par.copy()
        par[-1, 1] = q0 + dq
        stepper.use_model(model._replace(par=par))
        try:
            return stepper.rate(state, u)
        finally:
            stepper.use_model(model)

    h = JACOBIAN_STEP * 1e-2  # the pivot moves centimetres: 1e-7 m
    d1 = (f(h) - f(-h)) / (2 * h)
    d2 = (f(h / 2) - f(-h / 2)) / h
    return (4.0 * d2 - d1) / 3.0


def linearize_structure(structure: Structure, *, angles: Mapping[str, float] | None = None,
                        loads: Mapping[str, float] | None = None, friction: str = "linearised",
                        inputs: Sequence[str] | None = None,
                        outputs: Sequence[str] | None = None,
                        name: str | None = None) -> LinearModel:
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
    stepper = Stepper(structure, 1.0, options=SimulationOptions(friction=_ENGINE_LAW[friction]))
    if friction == "removed":
        par = stepper.model.par.copy()
        par[:stepper.layout.n_frictions, :2] = 0.0
        stepper.use_model(stepper.model._replace(par=par))
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
    B_all = np.hstack([ju, _pivot_sensitivity(stepper, state0, u0)[:, None]]) if fixed_pivot \
        else ju

    # outputs: angles and speeds are linear in the state and inputs (vsj.network)
    table = _output_table(structure)
    n_state, n_in = stepper.n_state, len(input_names)
    C_all = np.zeros((len(table), n_state))
    D_all = np.zeros((len(table), n_in))
    y0 = np.zeros(len(table))
    Minv, Msu = stepper.model.Minv, stepper.model.mass[:n, n:]
    src_cols = stepper.model.src_ch
    spring_index = {sp.name: k for k, sp in enumerate(structure.springs)}
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

    in_idx = _select("input", inputs, input_names)
    out_names = [t[0] for t in table]
    out_idx = _select("output", outputs, out_names)
    op = {"q": q0,
          "states": dict(zip(stepper.state_names, map(float, state0))),
          "inputs": dict(zip(input_names, map(float, np.append(u0, q0) if fixed_pivot
                                               else u0))),
          "outputs": dict(zip(out_names, map(float, y0 + 0.0)))}  # + 0.0: no "-0"
    info = {"network": structure.name, "friction": FRICTION_TREATMENTS[friction],
            "pivot": ("held at q (a parameter; input 'q' is its sensitivity); the pivot "
                      "mechanism is not back-driven and is not part of the model")
            if fixed_pivot else "moving pivot: its drive is part of the state",
            "coordinates": "momenta p = M v + M_su u (see vsj.linear)"}
    return LinearModel(jx, B_all[:, in_idx], C_all[out_idx], D_all[np.ix_(out_idx, in_idx)],
                       states=stepper.state_names, inputs=[input_names[i] for i in in_idx],
                       outputs=[out_names[i] for i in out_idx], state_units=stepper.state_units,
                       input_units=[input_units[i] for i in in_idx],
                       output_units=[table[i][2] for i in out_idx], operating_point=op,
                       friction=friction, info=info, name=name or structure.name)


def _spring_torque(spring, deflection: float, q: float) -> tuple[float, float]:
    from .components.elastic_element import evaluate

    torque, stiffness, _, _ = evaluate(spring.law, spring.parameters, deflection, q)
    return float(torque[0]), float(stiffness[0])


def linearize(params, q: float = 0.0, *, motors: tuple[float, float] = (0.0, 0.0),
              load: tuple[float, float] = (0.0, 0.0), wrist_options=None,
              friction: str = "linearised", inputs: Sequence[str] | None = None,
              outputs: Sequence[str] | None = None) -> LinearModel:
    """Linearise the wrist at pivot position ``q`` [m], motor positions and a static load.

    ``motors`` are the angles [rad] of the two primary motors' outputs (the
    suns); ``load`` the external torques ``(tau_x, tau_y)`` [N m] on the
    end-effector, which deflect the elastic elements at the operating point.
    ``wrist_options`` (`vsj.wrist.WristOptions`) choose the sub-models; the pivot is
    always held at ``q`` (see the module docstring). ``friction`` is a key of
    `FRICTION_TREATMENTS`. With DC motors, each motor holds its position with
    the current the load needs (open-loop voltage ``R i``).
    """
    from .wrist import WristOptions, build_wrist, pivot_range

    lo, hi = pivot_range(params)
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
                                loads=loads, friction=friction, inputs=inputs, outputs=outputs)
    model.info.update({"parameters": {"origin": params.origin, "hash": params.hash()},
                       "wrist_options": {**dataclasses.asdict(options),
                                         "pivot_drive": f"held ({options.pivot_drive} drive "
                                                        "not in the linear model)"},
                       "motors": list(map(float, motors)), "load": list(map(float, load))})
    return model


def sweep(params, qs: Sequence[float], **kwargs) -> list[LinearModel]:
    """`linearize` at each pivot position in ``qs`` [m] (other arguments shared)."""
    return [linearize(params, float(q), **kwargs) for q in qs]


# -- analysis ---------------------------------------------------------------------------


def _blocks(model: LinearModel) -> dict[str, np.ndarray]:
    """Indices of the angle, momentum, current and source-angle states."""
    kinds = {"angle": [], "momentum": [], "current": [], "source": []}
    for k, name in enumerate(model.state_labels):
        kind = name.rsplit(".", 1)[-1]
        kinds[kind if kind in kinds else "angle"].append(k)
    n = len(kinds["momentum"])  # the first n angles are the free ones, then the sources'
    kinds["source"] = kinds["angle"][n:]
    kinds["angle"] = kinds["angle"][:n]
    return {k: np.array(v, dtype=int) for k, v in kinds.items()}


def dynamic_states(model: LinearModel) -> np.ndarray:
    """Indices of the states with dynamics of their own (all but the source angles,
    which only integrate their speeds and whose poles sit at zero)."""
    b = _blocks(model)
    return np.sort(np.concatenate([b["angle"], b["momentum"], b["current"]]))


def natural_frequencies(model: LinearModel) -> np.ndarray:
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


def modes(model: LinearModel) -> list[dict]:
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


def _input_vector(model: LinearModel, input) -> np.ndarray:
    if isinstance(input, str):
        input = {input: 1.0}
    _select("input", list(input), list(model.input_labels))
    b = np.zeros(model.ninputs)
    for name, weight in input.items():
        b[list(model.input_labels).index(name)] = weight
    return b


def transfer(model: LinearModel, output: str, input, omega, *, input_angle: bool = False
             ) -> np.ndarray:
    """Frequency response ``output / input`` at ``omega`` [rad/s] (complex array).

    ``input`` is an input name or a mapping of names to weights (a
    combination, e.g. both motors together). With ``input_angle`` the input is
    a velocity source's angle rather than its speed (the response is
    multiplied by ``j omega``): motor position to end-effector position.
    """
    (k,) = _select("output", [output], list(model.output_labels))
    b = _input_vector(model, input)
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    A, B, C, D = model.A, model.B @ b, model.C[k], model.D[k] @ b
    eye = np.eye(model.nstates)
    response = np.array([C @ np.linalg.solve(1j * w * eye - A, B) + D for w in omega])
    return response * (1j * omega) if input_angle else response


def static_gain(model: LinearModel, outputs: Sequence[str], inputs: Sequence[str]
                ) -> np.ndarray:
    """Steady-state gain (outputs per inputs) with the velocity sources held.

    The source angles are held (their speeds zero), so the gain is that of
    the dynamic states alone; `SimulationError` if those have a free
    rigid-body motion (open-loop DC motors do).
    """
    out_idx = _select("output", outputs, list(model.output_labels))
    in_idx = _select("input", inputs, list(model.input_labels))
    idx = dynamic_states(model)
    A = model.A[np.ix_(idx, idx)]
    if np.linalg.matrix_rank(A) < A.shape[0]:
        raise SimulationError("the model has a free rigid-body motion (a zero pole), so no "
                              "static gain exists; hold the motors with velocity sources")
    B = model.B[np.ix_(idx, in_idx)]
    C = model.C[np.ix_(out_idx, idx)]
    return -C @ np.linalg.solve(A, B) + model.D[np.ix_(out_idx, in_idx)]


def output_stiffness(model: LinearModel, outputs=("theta_x", "theta_y"),
                     inputs=("tau_x", "tau_y")) -> np.ndarray:
    """Static stiffness matrix [N m/rad] at the end-effector, motors held: the inverse of
    the static compliance ``d theta / d tau``."""
    return np.linalg.inv(static_gain(model, outputs, inputs))


def bandwidth(model: LinearModel, output: str, input, *, input_angle: bool = False,
              drop_db: float = -3.0, omega_max: float = 1e5) -> float:
    """Lowest frequency [rad/s] where ``|output/input|`` falls ``drop_db`` below its
    low-frequency value; ``inf`` if it never does below ``omega_max``."""
    from scipy.optimize import brentq

    if input_angle:
        low = abs(transfer(model, output, input, [1e-6], input_angle=True)[0])
    else:
        (k,) = _select("output", [output], list(model.output_labels))
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


def _static(model: LinearModel) -> np.ndarray:
    """Static gain of every output per every input, sources held (see `static_gain`)."""
    return static_gain(model, list(model.output_labels), list(model.input_labels))


# -- files ------------------------------------------------------------------------------


def to_dict(model: LinearModel) -> dict:
    """The model as plain data (the JSON file's content; see `save`)."""
    def named(names, units):
        return [{"name": n, "unit": u} for n, u in zip(names, units)]

    op = model.operating_point
    return {
        "format": FORMAT, "version": FORMAT_VERSION, "name": model.name,
        "time": "continuous",
        "equations": "dx/dt = A x + B u, y = C x + D u, all deviations from the operating "
                     "point, SI units",
        "friction": {"treatment": model.friction,
                     "description": FRICTION_TREATMENTS.get(model.friction, "")},
        "operating_point": {"q": op.get("q"), "states": op.get("states", {}),
                            "inputs": op.get("inputs", {}), "outputs": op.get("outputs", {})},
        "states": named(model.state_labels, model.state_units),
        "inputs": named(model.input_labels, model.input_units),
        "outputs": named(model.output_labels, model.output_units),
        "A": model.A.tolist(), "B": model.B.tolist(), "C": model.C.tolist(),
        "D": model.D.tolist(),
        "info": model.info,
    }


def from_dict(data: Mapping, *, origin: str = "data") -> LinearModel:
    """A `LinearModel` from `to_dict`'s output; `InputError` names what is wrong."""
    if data.get("format") != FORMAT:
        raise InputError(f"{origin}: not a vsj linear model (format {data.get('format')!r}, "
                         f"expected {FORMAT!r})")
    if data.get("version") != FORMAT_VERSION:
        raise InputError(f"{origin}: unsupported version {data.get('version')!r} (this vsj "
                         f"reads version {FORMAT_VERSION})")
    try:
        mats = {k: np.array(data[k], dtype=float) for k in "ABCD"}
        states, inputs, outputs = data["states"], data["inputs"], data["outputs"]
        op = data["operating_point"]
        ns, ni, no = len(states), len(inputs), len(outputs)
        mats = {k: v.reshape(shape) for (k, v), shape in
                zip(mats.items(), [(ns, ns), (ns, ni), (no, ns), (no, ni)])}
        return LinearModel(
            mats["A"], mats["B"], mats["C"], mats["D"],
            states=[s["name"] for s in states], inputs=[s["name"] for s in inputs],
            outputs=[s["name"] for s in outputs], state_units=[s["unit"] for s in states],
            input_units=[s["unit"] for s in inputs], output_units=[s["unit"] for s in outputs],
            operating_point=op, friction=data["friction"]["treatment"],
            info=data.get("info", {}), name=data.get("name", "wrist"))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{origin}: malformed linear model ({type(exc).__name__}: {exc})") \
            from None


def save(model: LinearModel, path: Path) -> None:
    """Write ``.json`` (everything as text) or ``.npz`` (matrices as arrays, names and
    units as string arrays, the rest as JSON text under ``meta``)."""
    from .output import atomic_write, _jsonable

    path = Path(path)
    data = _jsonable(to_dict(model))
    if path.suffix == ".json":
        with atomic_write(path) as handle:
            handle.write(json.dumps(data, indent=1) + "\n")
    elif path.suffix == ".npz":
        meta = {k: v for k, v in data.items() if k not in "ABCD"}
        with atomic_write(path, "wb") as handle:
            np.savez(handle, A=model.A, B=model.B, C=model.C, D=model.D,
                     states=np.array(model.state_labels), inputs=np.array(model.input_labels),
                     outputs=np.array(model.output_labels),
                     state_units=np.array(model.state_units),
                     input_units=np.array(model.input_units),
                     output_units=np.array(model.output_units), meta=np.array(json.dumps(meta)))
    else:
        raise InputError(f"{path}: write a linear model to a .json or .npz file")


def load(path: Path) -> LinearModel:
    """Read a file written by `save`."""
    path = Path(path)
    try:
        if path.suffix == ".json":
            return from_dict(json.loads(path.read_text(encoding="utf-8")), origin=str(path))
        if path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                for k in "ABCD":
                    meta[k] = z[k]
                return from_dict(meta, origin=str(path))
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read a linear model ({exc})") from None
    raise InputError(f"{path}: a linear model file ends in .json or .npz")


__all__ = ["FRICTION_TREATMENTS", "LinearModel", "PIVOT_INPUT", "bandwidth",
           "dynamic_states", "from_dict", "linearize", "linearize_structure", "load", "modes",
           "natural_frequencies", "output_stiffness", "save", "static_gain", "sweep",
           "to_dict", "transfer"]
