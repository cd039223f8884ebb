"""Observer-based state feedback designed with python-control on vsj's linear models,
run by the C engine as one `Linear` block.

A design (`lqr`, `pole_placement`) takes a continuous linear model of the wrist around
an operating point (`vsj.linear.linearize`: deviations from the operating point, with
named states, inputs and outputs) and

1. samples it with zero-order hold at the controller's period (`discretize`,
   ``control.sample_system(..., method="zoh")``): exact for a linear plant whose inputs
   are held between samples, which is what the engine's actuators do;
2. computes the state-feedback gain ``K`` of the sampled plant: ``control.dlqr`` (LQR,
   weights ``Q`` and ``R``) or ``control.place`` (given closed-loop poles);
3. computes the gain ``L`` of a *current* estimator of the state from the measured
   signals (the engine reads its sensors and sets its actuators at the same instant, so
   the estimate may use the measurement of that sample): a Kalman filter (`Kalman`: the
   a-priori covariance ``P`` of ``control.dlqe``, ``L = P C^T (C P C^T + V)^-1``) or a
   Luenberger observer (`Luenberger`: ``control.place`` on the pair ``(A^T, (C A)^T)``,
   which places the eigenvalues of the error dynamics ``A - L C A``);
4. solves for the steady state ``(N_x, N_u)`` that holds the tracked outputs at their
   references (``[A - I, B; C_t, D_t] [N_x; N_u] = [0; I]``).

At each sample ``k`` the compensator (`StateFeedback.compensator`) runs, in deviations
from the operating point (``y0``, ``u0``, ``r0``)::

    x_k     = xp_k + L (y_k - C xp_k)          estimate after the measurement
    u_k     = N_u r_k - K (x_k - N_x r_k)      motor voltages (held until k + 1)
    xp_k+1  = A x_k + B u_k                    prediction to the next sample

a state-space system from (references, measurements) to the controlled inputs with a
direct feedthrough. `StateFeedback.controller` wraps it as a `vsj.control.Controller`:
a `Sensor` per measured signal, one `Linear` block and an `Actuator` per controlled
input whose offset is the operating point's holding voltage. The observer predicts with
the voltage it commands; while an actuator clips it (limits, current limit), the
estimate drifts from the plant, as it would on the robot.

A stable loop may need an unstable compensator (the controller alone, without the plant,
diverging): for this wrist, an estimator from the motor encoders alone tends to give
one; measuring the output angles too (``theta_x``, ``theta_y``) gives a stable one. A
design is checked for the loop it closes on its plant (`StateFeedback.check`), and its
`Linear` block then runs whatever its compensator's own poles (``allow_unstable``).

**Gain scheduling over the stiffness setting.** The elastic elements' stiffness, and so
the plant, changes with the pivot position ``q``. `GainSchedule` holds designs made at a
grid of pivot positions (one linear model each, `vsj.linear.sweep`) and gives the
design for a commanded ``q``: ``interpolation="linear"`` interpolates, linearly in ``q``
between the two neighbouring grid points, every element of the sampled plant (``A``,
``B``, the measured and tracked output rows), of the gains ``K`` and ``L`` and of the
operating point; recomputes ``N_x`` and ``N_u`` from the interpolated plant; and checks
that the result still closes a stable loop on the interpolated plant.
``interpolation="nearest"`` picks the design of the nearest grid point unchanged. The
engine runs one linear compensator per run, so the schedule is evaluated when the
controller is built, for the one stiffness setting the run holds; a run that changes the
stiffness needs a controller per setting.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from collections.abc import Mapping, Sequence

import control
import numpy as np

from ..errors import InputError
from ..inputs import Constant, Input
from ..linear.data import signal_name
from .controller import PID, Actuator, Controller, Linear, Sensor

#: A closed loop, estimator or compensator counts as stable when the moduli of its
#: eigenvalues stay this far below 1: the eigenvalues of a sampled model are computed to
#: about n eps ||A|| and a margin this small is one the robot cannot use anyway.
STABILITY_MARGIN = 1e-9

#: Relative size of the smallest singular value of ``[z I - A, B]`` below which a mode
#: ``z`` counts as uncontrollable (unobservable for ``[z I - A; C]``) in the diagnosis of
#: a failed design, after balancing: well above rounding (1e-16 times the conditioning)
#: and well below any mode a design can act on.
RANK_TOLERANCE = 1e-8


# ---- the model and its sampling -------------------------------------------------------

def _as_statespace(model, where: str = "model") -> control.StateSpace:
    if hasattr(model, "statespace") and not isinstance(model, control.StateSpace):
        model = model.statespace()  # vsj.linear.LinearData
    if not isinstance(model, control.StateSpace):
        raise InputError(f"{where} must be a linear model (vsj.linear.linearize, or a "
                         f"python-control StateSpace), got {type(model).__name__}")
    if not model.isctime(strict=True):
        raise InputError(f"{where} must be continuous (dt = 0); it has dt = {model.dt!r}: "
                         "give the model vsj.linear.linearize returns, the design samples it")
    return model


def _period(period) -> float:
    try:
        T = float(period)
    except (TypeError, ValueError):
        raise InputError(f"period must be a number of seconds, got {period!r}") from None
    if not (math.isfinite(T) and T > 0.0):
        raise InputError(f"period must be a finite number of seconds > 0, got {period!r}")
    return T


def _index(labels: Sequence[str], names: Sequence[str], what: str, where: str) -> list[int]:
    if isinstance(names, str):
        names = (names,)
    idx = []
    for name in names:
        label = name if name in labels else signal_name(str(name))
        if label not in labels:
            raise InputError(f"{where}: unknown {what} {name!r}; the model has "
                             f"{', '.join(labels)}")
        if labels.index(label) in idx:
            raise InputError(f"{where}: {what} {name!r} is listed twice")
        idx.append(labels.index(label))
    return idx


def discretize(model, period: float, inputs: Sequence[str] | None = None
               ) -> control.StateSpace:
    """The continuous linear ``model`` sampled with zero-order hold at ``period`` [s]
    (``control.sample_system``, method ``zoh``), keeping the inputs named in ``inputs``
    (all if None) and every output, with their names. `InputError` if the period is not
    a finite positive number or the sampled model is not finite (a period the plant's
    unstable modes overflow in)."""
    model = _as_statespace(model)
    T = _period(period)
    labels = list(model.input_labels)
    cols = list(range(model.ninputs)) if inputs is None else _index(labels, inputs, "input",
                                                                    "inputs")
    sub = control.ss(model.A, model.B[:, cols], model.C, model.D[:, cols],
                     states=list(model.state_labels), inputs=[labels[c] for c in cols],
                     outputs=list(model.output_labels), name=model.name)
    with np.errstate(over="ignore", invalid="ignore"):
        sampled = control.sample_system(sub, T, method="zoh", name=f"{model.name}_zoh")
    if not (np.all(np.isfinite(sampled.A)) and np.all(np.isfinite(sampled.B))):
        raise InputError(f"period {T:g} s: the model sampled at this period is not finite "
                         f"(its fastest growth rate {np.max(np.linalg.eigvals(model.A).real):.4g}"
                         " 1/s overflows over one period); sample faster")
    return sampled


# ---- diagnosis of a design that fails ------------------------------------------------

def _balanced(A: np.ndarray, B: np.ndarray, C: np.ndarray):
    """A diagonal similarity of (A, B, C) that evens out the states' scales (momenta,
    angles and currents differ by orders of magnitude), for rank tests."""
    from scipy.linalg import matrix_balance  # lazy: only a failed design needs it

    _, (scale, _) = matrix_balance(A, permute=False, separate=True)
    return A * (1.0 / scale)[:, None] * scale[None, :], B / scale[:, None], C * scale[None, :]


def _lost_modes(A: np.ndarray, B: np.ndarray, outside) -> list[complex]:
    """Eigenvalues of A in the region ``outside`` (a predicate) at which ``[z I - A, B]``
    loses rank: the modes ``B`` cannot move (for observability pass ``A.T, C.T``)."""
    n = A.shape[0]
    lost = []
    scale = max(np.linalg.norm(np.hstack([A, B]), 2), 1e-300)
    for z in np.linalg.eigvals(A):
        if not outside(z):
            continue
        s = np.linalg.svd(np.hstack([z * np.eye(n) - A, B]), compute_uv=False)
        if s[-1] <= RANK_TOLERANCE * scale:
            lost.append(complex(z))
    return lost


def _number(v: complex, digits: int = 6) -> str:
    """A real or complex number as text (a real one without ``+0j``)."""
    v = complex(v)
    if abs(v.imag) <= 1e-12 * max(1.0, abs(v)):
        return f"{v.real:.{digits}g}"
    return f"{v.real:.{digits}g}{v.imag:+.{digits}g}j"


def _describe(z: complex, period: float) -> str:
    """A z-plane mode and its continuous counterpart ``s = log(z) / period`` [1/s]."""
    z = complex(z)
    s = np.log(z) / period if z != 0 else complex(-np.inf)
    return f"z = {_number(z)} (s = {_number(s, 4)} 1/s)"


def _diagnose(model: control.StateSpace, sampled: control.StateSpace, cols: list[int],
              rows: np.ndarray | None, period: float, what: str, where: str) -> str:
    """Why the sampled pair cannot be stabilised (``rows`` None) or observed (``rows`` the
    measured output rows): the modes it loses, and whether sampling at ``period`` lost
    them (pathological sampling) or the continuous model lacks them already."""
    A, Bc = model.A, model.B[:, cols]
    Ad, Bd = sampled.A, sampled.B[:, :len(cols)]
    C = rows if rows is not None else np.zeros((0, A.shape[0]))
    Ab, Bb, Cb = _balanced(Ad, Bd, C)
    Ac_b, Bc_b, Cc_b = _balanced(A, Bc, C)
    unstable_d = lambda z: abs(z) >= 1.0 - STABILITY_MARGIN  # noqa: E731
    unstable_c = lambda s: s.real >= -STABILITY_MARGIN  # noqa: E731
    if rows is None:
        lost_d, lost_c = _lost_modes(Ab, Bb, unstable_d), _lost_modes(Ac_b, Bc_b, unstable_c)
    else:
        lost_d = _lost_modes(Ab.T, Cb.T, unstable_d)
        lost_c = _lost_modes(Ac_b.T, Cc_b.T, unstable_c)
    if lost_d and not lost_c:
        return (f"period {period:g} s: sampled at this period the plant loses {what} of its "
                f"modes {', '.join(_describe(z, period) for z in lost_d)} (pathological "
                "sampling: two modes whose frequencies differ by a multiple of 2 pi / period "
                "fall onto one); choose another period")
    if lost_d:
        verb = "move" if rows is None else "see"
        return (f"{where}: the {where} signals cannot {verb} the modes "
                f"{', '.join(_describe(z, period) for z in lost_d)} of the sampled plant, "
                "which do not decay on their own")
    return ""


# ---- observers -------------------------------------------------------------------------

@dataclass(frozen=True)
class Kalman:
    """A (steady-state) Kalman filter as the estimator: ``process_noise`` maps model
    inputs (the controlled voltages [V], load torques [N m], ...) to the variance of a
    white disturbance added to them and held over each period [unit^2];
    ``measurement_noise`` maps each measured signal to the variance of its noise
    [unit^2] (an encoder of resolution ``d`` quantises with variance ``d^2 / 12``; add
    the sensor's noise squared). The gain comes from the a-priori error covariance of
    ``control.dlqe``."""

    process_noise: Mapping[str, float]
    measurement_noise: Mapping[str, float]


@dataclass(frozen=True)
class Luenberger:
    """A Luenberger observer as the estimator: ``poles`` are the eigenvalues of its error
    dynamics in the z-plane of the sampled plant (modulus < 1; a continuous pole ``s``
    [1/s] is ``exp(s period)``), one per state of the model, placed with
    ``control.place``."""

    poles: Sequence[complex]


def _variances(spec, names: Sequence[str], where: str) -> np.ndarray:
    if not isinstance(spec, Mapping):
        raise InputError(f"{where} must map names to variances, got {type(spec).__name__}")
    out = []
    for name, value in spec.items():
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise InputError(f"{where}[{name!r}] must be a number, got {value!r}") from None
        if not (math.isfinite(v) and v >= 0.0):
            raise InputError(f"{where}[{name!r}] must be a finite variance >= 0, got "
                             f"{value!r}")
        out.append(v)
    return np.array(out)


def _poles(values, n: int, where: str) -> np.ndarray:
    try:
        p = np.asarray(values, dtype=complex).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"{where} must be a list of numbers (z-plane poles), got "
                         f"{values!r}") from None
    if p.size != n:
        raise InputError(f"{where}: {p.size} poles given, the model has {n} states")
    if not np.all(np.isfinite(p)):
        raise InputError(f"{where} must be finite, got {values!r}")
    if np.max(np.abs(p)) >= 1.0 - STABILITY_MARGIN:
        worst = p[np.argmax(np.abs(p))]
        raise InputError(f"{where}: pole {_number(worst)} has modulus {abs(worst):.6g} >= 1: "
                         "unstable in the z-plane of the sampled plant (a continuous pole s "
                         "[1/s] is exp(s period))")
    if np.max(np.abs(np.sort_complex(p) - np.sort_complex(p.conj()))) > 1e-12 * max(
            1.0, np.max(np.abs(p))):
        raise InputError(f"{where}: complex poles must come in conjugate pairs")
    return p


def _check_placed(M: np.ndarray, wanted: np.ndarray, where: str, why: str) -> None:
    got = np.sort_complex(np.linalg.eigvals(M))
    # eigenvalues of a placed matrix are accurate to about sqrt(eps) for repeated poles
    if np.max(np.abs(got - np.sort_complex(wanted))) > 1e-6:
        raise InputError(f"{where}: the poles could not be placed ({why}); the model's "
                         f"placed eigenvalues are {', '.join(_number(z, 4) for z in got)}")


# ---- the design ------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class StateFeedback:
    """An observer-based state feedback for a sampled linear plant (see the module
    docstring for its equations), in deviations from the operating point.

    Attributes
    ----------
    period : float
        Sample period [s].
    A, B : ndarray
        The plant sampled with zero-order hold: ``x+ = A x + B u`` (``u`` the
        ``controlled`` inputs).
    C_measured : ndarray
        Rows of the measured signals over the state.
    C_tracked, D_tracked : ndarray
        Rows of the tracked outputs over the state and the controlled inputs.
    K : ndarray
        State-feedback gain, ``u = -K x`` [input unit / state unit].
    L : ndarray
        Current-estimator gain (``x = xp + L (y - C xp)``).
    N_x, N_u : ndarray
        Steady state and inputs per unit of reference.
    controlled, measured, tracked : tuple of str
        Controlled input channels (``voltage_1``), measured signals (``motor_1``,
        ``theta_x.speed``, ``motor_1.current``) and tracked outputs, as a run names them.
    u0, y0, r0 : ndarray
        Operating point: controlled inputs, measured signals, tracked outputs.
    q : float or None
        Pivot position of the operating point [m] (None if the model has none).
    states : tuple of str
        The model's state names.
    method : str
        How it was designed (``dlqr``, ``place``, ``interpolated ...``).
    observer : str
        The estimator (``Kalman (control.dlqe)`` or ``Luenberger (control.place)``).
    """

    period: float
    A: np.ndarray
    B: np.ndarray
    C_measured: np.ndarray
    C_tracked: np.ndarray
    D_tracked: np.ndarray
    K: np.ndarray
    L: np.ndarray
    N_x: np.ndarray
    N_u: np.ndarray
    controlled: tuple
    measured: tuple
    tracked: tuple
    u0: np.ndarray
    y0: np.ndarray
    r0: np.ndarray
    q: float | None
    states: tuple
    method: str
    observer: str = field(default="")

    # -- the compensator
    def compensator(self) -> control.StateSpace:
        """The compensator as a discrete python-control system (``dt = period``): inputs
        the references of the tracked outputs (named ``<tracked>_ref``) then the
        measured signals, outputs the controlled inputs, all as deviations from the
        operating point (python-control's names: dots become underscores)."""
        A, B, C, K, L = self.A, self.B, self.C_measured, self.K, self.L
        n = A.shape[0]
        N_r = self.N_u + K @ self.N_x
        closed = A - B @ K
        update = np.eye(n) - L @ C
        Ac = closed @ update
        Bc = np.hstack([B @ N_r, closed @ L])
        Cc = -K @ update
        Dc = np.hstack([N_r, -K @ L])
        return control.ss(Ac, Bc, Cc, Dc, self.period,
                          inputs=[signal_name(f"{t}.ref") for t in self.tracked]
                          + [signal_name(m) for m in self.measured],
                          outputs=list(self.controlled),
                          states=[signal_name(f"{s}.estimate") for s in self.states],
                          name="state_feedback")

    def closed_loop_poles(self) -> np.ndarray:
        """Eigenvalues (z-plane) of the sampled plant closed by the compensator: those
        of ``A - B K`` and of ``A - L C A`` for a design made at this plant."""
        comp = self.compensator()
        m = len(self.tracked)
        Dy, By = comp.D[:, m:], comp.B[:, m:]
        C = self.C_measured
        top = np.hstack([self.A + self.B @ Dy @ C, self.B @ comp.C])
        bottom = np.hstack([By @ C, comp.A])
        return np.linalg.eigvals(np.vstack([top, bottom]))

    def check(self) -> "StateFeedback":
        """Itself, after checking that the loop it closes on its plant is stable
        (`InputError` otherwise); the compensator alone may be unstable."""
        where = f"state feedback ({self.method})"
        rho = np.max(np.abs(self.closed_loop_poles()))
        if not rho < 1.0 - STABILITY_MARGIN:
            raise InputError(f"{where}: the closed loop is unstable (an eigenvalue of modulus "
                             f"{rho:.6g} >= 1)")
        return self

    # -- the controller
    def _sensor(self, name: str, given) -> Sensor:
        if name.endswith(".current"):
            default = Sensor(name[:-len(".current")], "current", name=name)
        elif name.endswith(".speed"):
            default = Sensor(name[:-len(".speed")], "speed")
        else:
            default = Sensor(name, "angle")
        if given is None:
            return default
        if not isinstance(given, Sensor):
            raise InputError(f"sensors[{name!r}] must be a vsj.control.Sensor, got "
                             f"{type(given).__name__}")
        if (given.signal, given.quantity) != (default.signal, default.quantity):
            raise InputError(f"sensors[{name!r}] measures the {given.quantity} of "
                             f"{given.signal!r}; the design measures the {default.quantity} "
                             f"of {default.signal!r}")
        return given

    def controller(self, references: Mapping[str, object] | None = None, *,
                   sensors: Mapping[str, Sensor] | None = None, name: str = "state_feedback",
                   limits: Mapping[str, tuple] | None = None, current_limit: float = math.inf,
                   seed: int = 0) -> Controller:
        """A `vsj.control.Controller` running this design in the engine.

        Parameters
        ----------
        references : mapping
            Each tracked output (as named in ``tracked``) to its reference, an absolute
            value (`vsj.inputs.Input` or a number, in the output's unit); one per tracked
            output. On the controller's bus as ``<tracked>.ref``.
        sensors : mapping, optional
            Measured signal to the `Sensor` that reads it (to give it a resolution, noise
            or delay; the design assumes none); by default an exact sensor.
        name : str
            The `Linear` block's name; its outputs are ``<name>.<channel>`` on the bus.
        limits : mapping, optional
            Controlled channel to its ``(low, high)`` limits [V] (default: the motor's
            ``voltage_limit``).
        current_limit : float
            Every controlled motor's current limit [A].
        seed : int
            Seed of the sensors' noise.
        """
        references = dict(references or {})
        unknown = sorted(set(references) - set(self.tracked))
        if unknown:
            raise InputError(f"references: {', '.join(map(repr, unknown))} not tracked; the "
                             f"design tracks {', '.join(self.tracked) or 'nothing'}")
        missing = [t for t in self.tracked if t not in references]
        if missing:
            raise InputError(f"references: give one for each tracked output; missing "
                             f"{', '.join(map(repr, missing))}")
        for key, value in references.items():
            if not isinstance(value, Input) and (isinstance(value, bool) or not isinstance(
                    value, (int, float, np.integer, np.floating))):
                raise InputError(f"references[{key!r}] must be a vsj.inputs signal or a "
                                 f"number, got {type(value).__name__}")
        sensors = dict(sensors or {})
        stray = sorted(set(sensors) - set(self.measured))
        if stray:
            raise InputError(f"sensors: {', '.join(map(repr, stray))} not measured; the "
                             f"design measures {', '.join(self.measured)}")
        limits = dict(limits or {})
        stray = sorted(set(limits) - set(self.controlled))
        if stray:
            raise InputError(f"limits: {', '.join(map(repr, stray))} not controlled; the "
                             f"design drives {', '.join(self.controlled)}")
        read = tuple(self._sensor(m, sensors.get(m)) for m in self.measured)
        comp = self.compensator()
        refs = {f"{t}.ref": references[t] for t in self.tracked}
        inputs = list(refs) + [s.label for s in read]
        offset = np.concatenate([self.r0, self.y0])
        B, D = comp.B, comp.D
        if np.any(offset != 0.0):
            # deviations from a non-zero operating point: a constant input of 1 carries
            # -(B, D) times the operating point's references and readings
            bias = f"{name}.one"
            refs[bias] = Constant(1.0)
            inputs.append(bias)
            B = np.hstack([B, -(B @ offset)[:, None]])
            D = np.hstack([D, -(D @ offset)[:, None]])
        system = control.ss(comp.A, B, comp.C, D, self.period)
        outputs = tuple(f"{name}.{c}" for c in self.controlled)
        block = Linear(name, system, tuple(inputs), outputs, allow_unstable=True)  # loop checked
        acts = tuple(Actuator(c, out, offset=float(u0), limits=limits.get(c),
                              current_limit=current_limit)
                     for c, out, u0 in zip(self.controlled, outputs, self.u0))
        return Controller(self.period, acts, sensors=read, blocks=(block,), references=refs,
                          seed=seed)


def _measured_rows(model: control.StateSpace, names: Sequence[str], op: Mapping
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(C rows, D rows, operating values) of the measured signals."""
    rows, drows, y0 = [], [], []
    outputs, states = list(model.output_labels), list(model.state_labels)
    for name in names:
        if not isinstance(name, str):
            raise InputError(f"measured: names are strings, got {name!r}")
        if name.endswith(".current"):
            if name not in states:
                raise InputError(f"measured: {name!r} is not a motor current of the model; "
                                 f"its states are {', '.join(states)}")
            k = states.index(name)
            rows.append(np.eye(model.nstates)[k])
            drows.append(np.zeros(model.ninputs))
            y0.append(op.get("states", {}).get(name, 0.0))
            continue
        if name.endswith((".torque", "_torque")) or name == "q":
            raise InputError(f"measured: {name!r} cannot be measured by a vsj.control.Sensor "
                             "(angles, speeds, motor currents)")
        label = signal_name(name)
        if label not in outputs:
            raise InputError(f"measured: unknown signal {name!r}; the model's outputs are "
                             f"{', '.join(outputs)} (speeds spelt as a run names them: "
                             "theta_x.speed), and motor currents <motor>.current")
        if name != label and not name.endswith(".speed"):
            raise InputError(f"measured: {name!r}: a sensor reads a named signal's angle or "
                             "its speed (<signal>.speed)")
        if name.endswith("_speed") and label == name:
            raise InputError(f"measured: spell the speed {name!r} as a run names it: "
                             f"{name[:-len('_speed')]}.speed")
        k = outputs.index(label)
        rows.append(model.C[k])
        drows.append(model.D[k])
        y0.append(op.get("outputs", {}).get(label, 0.0))
    return np.array(rows, dtype=float).reshape(len(names), model.nstates), \
        np.array(drows, dtype=float).reshape(len(names), model.ninputs), np.array(y0)


def _weights(W, names: Sequence[str], rows: np.ndarray | None, size: int, where: str
             ) -> np.ndarray:
    """A weight matrix: a mapping of names to weights (over the rows given), or a full
    symmetric positive semi-definite matrix of ``size``."""
    if isinstance(W, Mapping):
        M = np.zeros((size, size))
        for key, value in W.items():
            try:
                w = float(value)
            except (TypeError, ValueError):
                raise InputError(f"{where}[{key!r}] must be a number, got {value!r}") from None
            if not (math.isfinite(w) and w >= 0.0):
                raise InputError(f"{where}[{key!r}] must be a finite weight >= 0, got "
                                 f"{value!r}")
            label = key if key in names else signal_name(str(key))
            if label not in names:
                raise InputError(f"{where}: unknown name {key!r}; allowed: {', '.join(names)}")
            r = rows[names.index(label)] if rows is not None else np.eye(size)[names.index(label)]
            M += w * np.outer(r, r)
        return M
    try:
        M = np.atleast_2d(np.asarray(W, dtype=float))
    except (TypeError, ValueError):
        raise InputError(f"{where} must be a mapping of names to weights or a matrix, got "
                         f"{type(W).__name__}") from None
    if M.shape != (size, size):
        raise InputError(f"{where} must be {size} x {size}, got {M.shape[0]} x {M.shape[1]}")
    if not np.all(np.isfinite(M)) or np.max(np.abs(M - M.T)) > 1e-12 * np.max(np.abs(M)):
        raise InputError(f"{where} must be finite and symmetric")
    if np.min(np.linalg.eigvalsh(M)) < -1e-12 * np.max(np.abs(M)):
        raise InputError(f"{where} must be positive semi-definite")
    return M


def _setup(model, period, controlled, measured, tracked, observer, noise_inputs=()):
    """What both designs share: the model sampled, the rows and the operating point."""
    model = _as_statespace(model)
    T = _period(period)
    controlled = (controlled,) if isinstance(controlled, str) else tuple(controlled)
    measured = (measured,) if isinstance(measured, str) else tuple(measured)
    tracked = (tracked,) if isinstance(tracked, str) else tuple(tracked)
    if not controlled:
        raise InputError("controlled: name at least one input the controller drives")
    if not measured:
        raise InputError("measured: name at least one measured signal")
    inputs = list(model.input_labels)
    ctrl = _index(inputs, controlled, "input", "controlled")
    controlled = tuple(inputs[c] for c in ctrl)
    extra = [i for i in _index(inputs, noise_inputs, "input",
                               "observer.process_noise") if i not in ctrl]
    if not isinstance(observer, (Kalman, Luenberger)):
        raise InputError(f"observer must be a vsj.control.Kalman or Luenberger, got "
                         f"{type(observer).__name__}")
    op = dict(getattr(model, "operating_point", {}) or {})
    C_m, D_m, y0 = _measured_rows(model, measured, op)
    if np.any(D_m[:, ctrl] != 0.0):
        raise InputError("measured: a measured signal depends directly on a controlled input "
                         "(a speed fed through from a velocity source); measure angles, or "
                         "drive DC motors")
    outputs = list(model.output_labels)
    trk = _index(outputs, tracked, "output", "tracked")
    C_t, D_t = model.C[trk], model.D[np.ix_(trk, ctrl)]
    r0 = np.array([op.get("outputs", {}).get(outputs[k], 0.0) for k in trk])
    u0 = np.array([op.get("inputs", {}).get(inputs[c], 0.0) for c in ctrl])
    sampled = discretize(model, T, [inputs[c] for c in ctrl + extra])
    q = op.get("q")
    common = dict(period=T, A=sampled.A, B=sampled.B[:, :len(ctrl)], C_measured=C_m,
                  C_tracked=C_t, D_tracked=D_t, controlled=controlled, measured=measured,
                  tracked=tuple(tracked), u0=u0, y0=y0, r0=r0,
                  q=None if q is None else float(q), states=tuple(model.state_labels))
    return model, sampled, ctrl, common


def _reference_gains(A, B, C_t, D_t, where: str) -> tuple[np.ndarray, np.ndarray]:
    """``(N_x, N_u)``: the steady state and inputs that hold the tracked outputs at a unit
    reference, ``[A - I, B; C_t, D_t] [N_x; N_u] = [0; I]``."""
    n, m, p = A.shape[0], B.shape[1], C_t.shape[0]
    if p == 0:
        return np.zeros((n, 0)), np.zeros((m, 0))
    if p != m:
        raise InputError(f"{where}: {p} tracked outputs and {m} controlled inputs; a "
                         "reference needs as many of each (one steady state per reference)")
    M = np.block([[A - np.eye(n), B], [C_t, D_t]])
    rhs = np.vstack([np.zeros((n, p)), np.eye(p)])
    if np.linalg.cond(M) > 1e12:  # 1e-4 of 1/eps: a reference the plant barely holds
        raise InputError(f"{where}: the controlled inputs cannot hold the tracked outputs at "
                         "an arbitrary steady value (the steady-state equations are "
                         "singular)")
    N = np.linalg.solve(M, rhs)
    return N[:n], N[n:]


def _observer_gain(observer, model, sampled, common, ctrl, where: str) -> tuple[np.ndarray, str]:
    A, C = common["A"], common["C_measured"]
    measured = list(common["measured"])
    if isinstance(observer, Kalman):
        inputs = list(sampled.input_labels)
        cols = _index(inputs, list(observer.process_noise), "input", f"{where}.process_noise")
        G = sampled.B[:, cols]
        W = np.diag(_variances(observer.process_noise, inputs, f"{where}.process_noise"))
        unknown = sorted(set(observer.measurement_noise) - set(measured))
        missing = [m for m in measured if m not in observer.measurement_noise]
        if unknown or missing:
            raise InputError(f"{where}.measurement_noise: give a variance for each measured "
                             f"signal ({', '.join(measured)}); "
                             + (f"unknown {', '.join(map(repr, unknown))}" if unknown else
                                f"missing {', '.join(map(repr, missing))}"))
        V = np.diag(_variances({m: observer.measurement_noise[m] for m in measured}, measured,
                               f"{where}.measurement_noise"))
        if np.min(np.diag(V)) <= 0.0:
            raise InputError(f"{where}.measurement_noise: every variance must be > 0 (an "
                             "exact sensor leaves the filter's gain undefined)")
        try:
            _, P, _ = control.dlqe(A, G, C, W, V)
        except (np.linalg.LinAlgError, ValueError, control.ControlArgument) as err:
            why = _diagnose(model, sampled, ctrl, C, common["period"], "observability",
                            "measured")
            raise InputError(why or f"{where}: no steady-state Kalman filter exists for "
                             f"these noises and measurements ({err}); make every mode that "
                             "does not decay on its own visible in the measured signals "
                             "and stirred by the process noise") from None
        return P @ C.T @ np.linalg.inv(C @ P @ C.T + V), "Kalman (control.dlqe)"
    poles = _poles(observer.poles, A.shape[0], f"{where}.poles")
    try:
        L = control.place(A.T, (C @ A).T, poles).T
    except (np.linalg.LinAlgError, ValueError, control.ControlArgument) as err:
        why = _diagnose(model, sampled, ctrl, C, common["period"], "observability",
                        "measured")
        raise InputError(why or f"{where}.poles: control.place cannot place them ({err})") \
            from None
    _check_placed(A - L @ C @ A, poles, f"{where}.poles", "the measured signals do not see "
                  "every mode")
    return L, "Luenberger (control.place)"


def _finish(model, sampled, ctrl, common, K, method, observer) -> StateFeedback:
    L, kind = _observer_gain(observer, model, sampled, common, ctrl, "observer")
    A, C = common["A"], common["C_measured"]
    rho = np.max(np.abs(np.linalg.eigvals(A - L @ C @ A)))
    if not rho < 1.0 - STABILITY_MARGIN:
        raise InputError(f"observer: the estimator is unstable (an eigenvalue of A - L C A of "
                         f"modulus {rho:.6g} >= 1)")
    N_x, N_u = _reference_gains(A, common["B"], common["C_tracked"], common["D_tracked"],
                                "tracked")
    return StateFeedback(K=K, L=L, N_x=N_x, N_u=N_u, method=method, observer=kind,
                         **common).check()


def lqr(model, period: float, Q, R, *, controlled: Sequence[str] = ("voltage_1", "voltage_2"),
        measured: Sequence[str], tracked: Sequence[str] = (), observer) -> StateFeedback:
    """An LQR state feedback with an estimator, for ``model`` sampled at ``period``.

    Parameters
    ----------
    model : vsj.linear.LinearModel or control.StateSpace
        Continuous linear model (`vsj.linear.linearize`), deviations from its operating
        point.
    period : float
        The controller's period [s]; the model is sampled with zero-order hold at it.
    Q : mapping or ndarray
        State weight: a mapping of outputs of the model (``theta_x``, ``vsm_1.torque``)
        to weights [1/unit^2], summed as ``w c^T c`` over their rows, or a full
        symmetric positive semi-definite matrix over the model's states.
    R : mapping or ndarray
        Input weight: controlled channel to weight [1/V^2] (each > 0), or a symmetric
        positive definite matrix.
    controlled : sequence of str
        The inputs the controller drives (motor voltages).
    measured : sequence of str
        What its sensors read: named signals' angles (``motor_1``), speeds
        (``motor_1.speed``), motor currents (``motor_1.current``).
    tracked : sequence of str
        Outputs given references (as many as ``controlled``, or none: a regulator).
    observer : Kalman or Luenberger
        The estimator.

    Returns
    -------
    StateFeedback
        With ``K`` from ``control.dlqr(A, B, Q, R)`` of the sampled plant.
    """
    noise = observer.process_noise if isinstance(observer, Kalman) else ()
    model, sampled, ctrl, common = _setup(model, period, controlled, measured, tracked,
                                          observer, tuple(noise))
    n, m = common["A"].shape[0], common["B"].shape[1]
    Qm = _weights(Q, list(model.output_labels), model.C, n, "Q")
    Rm = _weights(R, list(common["controlled"]), None, m, "R")
    if np.min(np.linalg.eigvalsh(Rm)) <= 0.0:
        raise InputError("R must be positive definite: give every controlled input a weight "
                         "> 0")
    try:
        K, _, _ = control.dlqr(common["A"], common["B"], Qm, Rm)
    except (np.linalg.LinAlgError, ValueError, control.ControlArgument) as err:
        why = _diagnose(model, sampled, ctrl, None, common["period"], "controllability",
                        "controlled")
        raise InputError(why or f"Q, R: control.dlqr finds no stabilising gain ({err}); Q must "
                         "weigh every mode that does not decay on its own") from None
    rho = np.max(np.abs(np.linalg.eigvals(common["A"] - common["B"] @ K)))
    if not rho < 1.0 - STABILITY_MARGIN:
        why = _diagnose(model, sampled, ctrl, None, common["period"], "controllability",
                        "controlled")
        raise InputError(why or f"Q: the LQR leaves a mode of modulus {rho:.6g} unmoved (Q "
                         "does not weigh it); weigh every mode that does not decay on its "
                         "own")
    return _finish(model, sampled, ctrl, common, np.asarray(K, float), "dlqr", observer)


def pole_placement(model, period: float, poles: Sequence[complex], *,
                   controlled: Sequence[str] = ("voltage_1", "voltage_2"),
                   measured: Sequence[str], tracked: Sequence[str] = (), observer
                   ) -> StateFeedback:
    """A state feedback placing the closed-loop ``poles`` (z-plane of the plant sampled
    at ``period`` [s], modulus < 1, one per state) with ``control.place``, with an
    estimator; the other arguments as `lqr`."""
    noise = observer.process_noise if isinstance(observer, Kalman) else ()
    model, sampled, ctrl, common = _setup(model, period, controlled, measured, tracked,
                                          observer, tuple(noise))
    p = _poles(poles, common["A"].shape[0], "poles")
    try:
        K = control.place(common["A"], common["B"], p)
    except (np.linalg.LinAlgError, ValueError, control.ControlArgument) as err:
        why = _diagnose(model, sampled, ctrl, None, common["period"], "controllability",
                        "controlled")
        raise InputError(why or f"poles: control.place cannot place them ({err})") from None
    _check_placed(common["A"] - common["B"] @ K, p, "poles",
                  "the controlled inputs do not reach every mode")
    return _finish(model, sampled, ctrl, common, np.asarray(K, float), "place", observer)


# ---- gain scheduling over the stiffness setting --------------------------------------

#: StateFeedback fields interpolated over q (the sampled plant, the gains and the
#: operating point); N_x and N_u follow from the interpolated plant.
_SCHEDULED = ("A", "B", "C_measured", "C_tracked", "D_tracked", "K", "L", "u0", "y0", "r0")


@dataclass(frozen=True, eq=False)
class GainSchedule:
    """Designs (`StateFeedback`) at a grid of pivot positions ``q`` [m], for one period,
    one set of controlled, measured and tracked signals and one model structure; see the
    module docstring for what `at` interpolates. ``designs`` are sorted by ``q``."""

    designs: tuple

    def __post_init__(self):
        designs = tuple(self.designs)
        if len(designs) < 2:
            raise InputError("designs: a gain schedule needs designs at two pivot positions "
                             "at least")
        for i, d in enumerate(designs):
            if not isinstance(d, StateFeedback):
                raise InputError(f"designs[{i}] must be a StateFeedback (vsj.control.lqr or "
                                 f"pole_placement), got {type(d).__name__}")
            if d.q is None:
                raise InputError(f"designs[{i}]: its model has no pivot position q (design "
                                 "on models from vsj.linear.linearize)")
        first = designs[0]
        for i, d in enumerate(designs[1:], 1):
            for key in ("period", "controlled", "measured", "tracked", "states"):
                if getattr(d, key) != getattr(first, key):
                    raise InputError(f"designs[{i}]: its {key} {getattr(d, key)!r} differs "
                                     f"from designs[0]'s {getattr(first, key)!r}")
        designs = tuple(sorted(designs, key=lambda d: d.q))
        qs = [d.q for d in designs]
        if any(b - a <= 0.0 for a, b in zip(qs, qs[1:])):
            raise InputError(f"designs: two designs at the same pivot position "
                             f"(q = {', '.join(f'{q:g}' for q in qs)} m)")
        object.__setattr__(self, "designs", designs)

    @property
    def qs(self) -> np.ndarray:
        """The grid of pivot positions [m], increasing."""
        return np.array([d.q for d in self.designs])

    def at(self, q: float, interpolation: str = "linear") -> StateFeedback:
        """The design for the commanded pivot position ``q`` [m] within the grid:
        ``linear`` interpolates between the neighbouring grid points (module docstring),
        ``nearest`` picks the nearest one's design unchanged."""
        try:
            q = float(q)
        except (TypeError, ValueError):
            raise InputError(f"q must be a number of metres, got {q!r}") from None
        qs = self.qs
        if not (math.isfinite(q) and qs[0] <= q <= qs[-1]):
            raise InputError(f"q = {q!r} m is outside the schedule's grid {qs[0]:g} ... "
                             f"{qs[-1]:g} m (it does not extrapolate)")
        if interpolation == "nearest":
            return self.designs[int(np.argmin(np.abs(qs - q)))]
        if interpolation != "linear":
            raise InputError(f"interpolation must be 'linear' or 'nearest', got "
                             f"{interpolation!r}")
        j = int(min(np.searchsorted(qs, q, side="right"), len(qs) - 1))
        lo, hi = self.designs[j - 1], self.designs[j]
        w = (q - lo.q) / (hi.q - lo.q)
        if w == 0.0 or w == 1.0:
            return lo if w == 0.0 else hi
        parts = {k: (1.0 - w) * getattr(lo, k) + w * getattr(hi, k) for k in _SCHEDULED}
        N_x, N_u = _reference_gains(parts["A"], parts["B"], parts["C_tracked"],
                                    parts["D_tracked"], "tracked")
        method = (f"interpolated at q = {q:g} m between the {lo.method} designs at "
                  f"{lo.q:g} and {hi.q:g} m")
        design = dataclasses.replace(lo, **parts, N_x=N_x, N_u=N_u, q=q, method=method)
        try:
            return design.check()
        except InputError as err:
            raise InputError(f"q = {q:g} m: {err}; the grid is too coarse there (add a "
                             f"design between {lo.q:g} and {hi.q:g} m)") from None

    def controller(self, q: float, references: Mapping[str, object] | None = None, *,
                   interpolation: str = "linear", **kwargs) -> Controller:
        """`StateFeedback.controller` of the design `at` ``q`` [m]."""
        return self.at(q, interpolation).controller(references, **kwargs)


# ---- a PID as a linear system ------------------------------------------------------------

def pid_statespace(pid: PID, period: float) -> control.StateSpace:
    """The discrete linear system the engine's `PID` is while its output stays within its
    limits: inputs (set-point, measurement), output the PID's, states (integral,
    derivative filter), ``dt = period`` [s] (engine/c/control.c: a forward-Euler
    integral, the derivative filter sampled exactly with its input held). The engine
    starts the filter state at the first sample's ``wd r - y`` (no derivative kick);
    start this system's state at ``(0, wd r0 - y0)`` to match. A feed-forward term is
    not part of it."""
    if not isinstance(pid, PID):
        raise InputError(f"pid must be a vsj.control.PID, got {type(pid).__name__}")
    T = _period(period)
    k, Ti, Td, Nd, wp, wd = pid.parameters(T)[:6]
    integral = T / Ti if math.isfinite(Ti) else 0.0
    decay = math.exp(-T * Nd / Td) if Td > 0.0 else 0.0
    d = Nd if Td > 0.0 else 0.0
    A = np.array([[1.0, 0.0], [0.0, decay]])
    B = np.array([[integral, -integral], [(1.0 - decay) * wd, -(1.0 - decay)]])
    C = np.array([[k, -k * d]])
    D = np.array([[k * (wp + d * wd), -k * (1.0 + d)]])
    return control.ss(A, B, C, D, T, inputs=["setpoint", "measurement"], outputs=[pid.name],
                      states=["integral", "derivative_filter"], name=pid.name)
