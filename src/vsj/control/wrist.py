"""Controllers in the wrist's own coordinates: the output angles and the stiffness.

A user of the wrist commands the end-effector angles ``(theta_x, theta_y)`` and the
pivot position ``q`` (the stiffness setting, eq 4.5: more negative is stiffer), not the
three motor angles. This module turns those commands into a `Controller` for a wrist
built with DC motors (``WristOptions(motors="dc", pivot_drive="dc")``), every map taken
from the assembled network, never from hard-coded ratios:

* `wrist_kinematics`: the rigid kinematics. With every spring undeflected (the
  configuration the network's spring rows define as zero), the motors' rotor angles fix
  the output angles and the pivot carrier's angle through one constant matrix: the
  planetary gears (eq 3.9, ring held by its elastic element), the transmissions, the
  differential (eq 3.31) and the pivot's gearing (section 3.4). Its inverse maps a
  command in wrist coordinates to rotor angles.
* `wrist_controller`: collocated position control. Each output motor runs a PID on its
  own encoder, whose set-point is the rigid kinematics applied to the commanded
  ``(theta_x, theta_y)``; the stiffness motor runs a PID on the pivot position ``q``
  (measured through the pivot mechanism, ``q = amplitude sin(phi_C)``).
* `impedance_controller`: a virtual spring-damper at the end-effector realised by the
  motors' torques, ``tau_rotor = J^T (K_d (theta_ref - theta) - D_d theta_dot)``, turned
  into voltages by the motor model; the VSM's spring sits in series with it
  (`closed_loop_stiffness`).
* `virtual_spring_damper` and `passivity_bound`: the discrete spring-damper (backward
  difference velocity, zero-order hold) both of the above use, and the bound on the
  physical damping that keeps it passive (Colgate and Schenkel 1997; Abbott and
  Okamura 2005): ``b > K T / 2 + |B|``.

Why collocated (motor-side) feedback. A loop closed on the motors' own angles, with the
elastic elements and the end-effector behind them, is passive at the motor port: its
elastic modes put alternating pole-zero pairs into the loop (the antiresonance comes
first), which never take phase away from it, so one set of gains is stable at every
stiffness setting, from the softest to the stiffest, without scheduling. Feedback on the end-effector angles, through the VSM's
spring, has no such property: its phase falls by 180 degrees at the elastic mode, which
moves by an order of magnitude with q. Collocated feedback also keeps what the wrist is
built for: under a load the output gives way by the stiffness the pivot sets.

Motor model (vsj.components.motor): ``L di/dt = V - R i - k_t omega`` with the torque
``k_t i`` on the rotor. The electrical time constant ``L/R`` (0.24 mH / 2.3 ohm = 0.1 ms
with the bundled parameters) is shorter than a controller's period, so over a period the current is
``(V - k_t omega) / R`` and the voltage-to-angle plant of a rotor is
``a / (s (tau s + 1))`` with ``a = k_t / (k_t^2 + R b)`` [rad/(V s)] and ``tau = R J /
(k_t^2 + R b)`` [s] (J the inertia and b the viscous friction the rotor sees with the
springs held). `MotorPID.design` places the crossover there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Mapping

import numpy as np

from ..errors import InputError
from ..inputs import as_inputs
from ..network import Structure
from ..springs import spring_law
from .controller import PID, Actuator, Controller, Linear, Sensor

#: The wrist's coordinates, in the order of `WristKinematics.to_rotors`' columns: the two
#: end-effector angles [rad] and the pivot position [m] (references of the controllers).
COORDINATES = ("theta_x", "theta_y", "q")
#: Relative size below which an entry of the rigid kinematics counts as zero: the maps
#: are products of a few gear ratios, exact to rounding (1e-16) times their condition.
_ZERO = 1e-9


def _matrix(value, name: str, size: int = 2, *, definite: bool = True) -> np.ndarray:
    """A symmetric ``size`` x ``size`` matrix, positive semi-definite if ``definite``,
    from a number (times the identity) or a matrix; `InputError` naming ``name``
    otherwise."""
    try:
        m = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number or a {size}x{size} matrix, got "
                         f"{value!r}") from None
    if m.ndim == 0:
        m = float(m) * np.eye(size)
    if m.shape != (size, size) or not np.all(np.isfinite(m)):
        raise InputError(f"{name} must be a finite number or a {size}x{size} matrix, got "
                         f"{value!r}")
    if not np.allclose(m, m.T, rtol=1e-12, atol=0.0):
        raise InputError(f"{name} must be symmetric, got {m.tolist()}")
    if definite and np.min(np.linalg.eigvalsh(m)) < 0.0:
        raise InputError(f"{name} must be positive semi-definite (a spring or a damper "
                         f"that takes energy in), got eigenvalues "
                         f"{np.linalg.eigvalsh(m).tolist()}")
    return m


def _null_space(rows: np.ndarray, n: int) -> np.ndarray:
    """An orthonormal basis (n x r) of the vectors the rows send to zero."""
    if rows.size == 0:
        return np.eye(n)
    _, s, vt = np.linalg.svd(rows)
    rank = int(np.sum(s > _ZERO * max(float(s[0]), 1e-300)))
    return vt[rank:].T


@dataclass(frozen=True)
class WristKinematics:
    """The wrist's rigid kinematics, read from an assembled network.

    ``motors`` are the names of the output motors (two) and the stiffness motor (last);
    ``rotors`` their rotor flanges (what the encoders read). ``to_rotors`` (3 x 3) gives
    the rotor angles [rad] that put the end-effector at ``(theta_x, theta_y)`` [rad] and
    the pivot carrier at angle ``phi_C`` [rad] with every spring undeflected;
    ``to_wrist`` is its inverse. ``jacobian`` (2 x 2) = ``d(theta_x, theta_y) / d(rotor
    angles of the output motors)``, the block of ``to_wrist`` the output motors span;
    ``pivot_gain`` = ``d phi_C / d(rotor angle of the stiffness motor)``; the pivot is at
    ``q = amplitude sin(phi_C)`` [m] within ``[q_min, q_max]``.
    """

    motors: tuple[str, str, str]
    rotors: tuple[str, str, str]
    channels: tuple[str, str, str]
    to_rotors: np.ndarray
    to_wrist: np.ndarray
    amplitude: float
    q_min: float
    q_max: float

    @property
    def jacobian(self) -> np.ndarray:
        """``d(theta_x, theta_y) / d(rotor_1, rotor_2)`` (dimensionless, rad/rad)."""
        return self.to_wrist[:2, :2].copy()

    @property
    def pivot_gain(self) -> float:
        """``d phi_C / d rotor_s`` (rad/rad): the pivot carrier turns per stiffness-motor
        rotor turn."""
        return float(self.to_wrist[2, 2])

    def rotor_angles(self, theta_x: float, theta_y: float, q: float) -> np.ndarray:
        """Rotor angles [rad] of the three motors that place the end-effector at
        ``(theta_x, theta_y)`` [rad] and the pivot at ``q`` [m], springs undeflected."""
        if not abs(q) <= self.amplitude:
            raise InputError(f"pivot position q = {q!r} m is beyond the mechanism's reach "
                             f"(|q| <= {self.amplitude:g} m)")
        return self.to_rotors @ np.array([theta_x, theta_y, math.asin(q / self.amplitude)])


def _signal_flange(structure: Structure, name: str) -> str:
    flanges = {s.name: s.flange for s in structure.signals}
    if name not in flanges:
        raise InputError(f"network {structure.name!r} has no signal {name!r} (the wrist's "
                         f"output); its signals: {', '.join(flanges) or 'none'}")
    return flanges[name]


def wrist_kinematics(structure: Structure, outputs: tuple[str, str] = ("theta_x", "theta_y")
                     ) -> WristKinematics:
    """The rigid kinematics of ``structure`` (an assembled wrist with three DC motors):
    the configurations in which every spring row is zero, parametrised by the motors'
    rotor angles, mapped to the ``outputs`` (two signals, the end-effector angles) and the
    pivot carrier's angle.

    Raises `InputError` if the network has velocity sources, not three motors, no pivot
    mechanism, motors that do not fix the rigid configuration, or a stiffness motor that
    would also move the outputs (then the commands would not separate).
    """
    if not isinstance(structure, Structure):
        raise InputError(f"the wrist's controller needs an assembled network "
                         f"(vsj.network.Structure), got {type(structure).__name__}")
    if structure.sources:
        raise InputError(f"network {structure.name!r} has velocity sources "
                         f"({', '.join(s.name for s in structure.sources)}); a controller "
                         "drives DC motors: build the wrist with WristOptions(motors='dc', "
                         "pivot_drive='dc')")
    if len(structure.motors) != 3:
        raise InputError(f"network {structure.name!r} has {len(structure.motors)} DC motors; "
                         "the wrist's controller needs three (two output motors and the "
                         "stiffness motor: WristOptions(motors='dc', pivot_drive='dc'))")
    if structure.pivot.flange is None:
        raise InputError(f"network {structure.name!r} has no pivot mechanism to set the "
                         "stiffness (pivot_drive='fixed'?); build it with pivot_drive='dc'")
    n = structure.n
    springs = structure.spring_rows @ structure.A
    rigid = _null_space(springs, n)
    motor_rows = np.array([structure.rows(m.flange)[0] for m in structure.motors])
    wrist_rows = np.array([structure.rows(_signal_flange(structure, o))[0] for o in outputs]
                          + [structure.pivot_rows()[0]])
    by_motors = motor_rows @ rigid
    if by_motors.shape[1] != 3 or np.linalg.matrix_rank(by_motors) != 3:
        raise InputError(f"network {structure.name!r}: with its springs undeflected the "
                         f"motors do not fix the configuration ({by_motors.shape[1]} rigid "
                         "degrees of freedom for 3 motors)")
    to_wrist = wrist_rows @ rigid @ np.linalg.inv(by_motors)
    scale = np.max(np.abs(to_wrist), axis=1, keepdims=True)
    small = np.abs(to_wrist) <= _ZERO * np.maximum(scale, 1e-300)
    to_wrist[small] = 0.0
    pivot_motors = np.flatnonzero(to_wrist[2] != 0.0)
    if len(pivot_motors) != 1 or np.any(to_wrist[:2, pivot_motors[0]] != 0.0):
        raise InputError(f"network {structure.name!r}: the outputs and the pivot are not "
                         "driven by separate motors (one stiffness motor that moves only "
                         "the pivot is needed)")
    s = int(pivot_motors[0])
    order = [j for j in range(3) if j != s] + [s]
    to_wrist = to_wrist[:, order]
    if abs(np.linalg.det(to_wrist[:2, :2])) <= _ZERO * float(np.max(np.abs(to_wrist[:2, :2]))) ** 2:
        raise InputError(f"network {structure.name!r}: the output motors cannot move "
                         f"{outputs[0]} and {outputs[1]} independently")
    motors = [structure.motors[j] for j in order]
    pivot = structure.pivot
    return WristKinematics(
        motors=tuple(m.name for m in motors), rotors=tuple(m.flange for m in motors),
        channels=tuple(m.channel for m in motors), to_rotors=np.linalg.inv(to_wrist),
        to_wrist=to_wrist, amplitude=float(pivot.amplitude),
        q_min=max(float(pivot.q_min), -float(pivot.amplitude)),
        q_max=min(float(pivot.q_max), float(pivot.amplitude)))


# -- the motors ------------------------------------------------------------------------


@dataclass(frozen=True)
class MotorPlant:
    """What a controller needs of one DC motor in the wrist: resistance ``R`` [ohm],
    torque constant ``k_t`` [N m/A], and the inertia ``J`` [kg m^2] and viscous friction
    ``b`` [N m s/rad] its rotor sees with the springs undeflected and the other motors
    held (the rigid chain behind it reflected to the rotor)."""

    R: float
    k_t: float
    J: float
    b: float

    @property
    def gain(self) -> float:
        """``a = k_t / (k_t^2 + R b)`` [rad/(V s)]: the rotor speed per volt at steady
        state."""
        return self.k_t / (self.k_t ** 2 + self.R * self.b)

    @property
    def time_constant(self) -> float:
        """``tau = R J / (k_t^2 + R b)`` [s]: the rotor's mechanical time constant with
        the back-EMF's damping."""
        return self.R * self.J / (self.k_t ** 2 + self.R * self.b)

    @property
    def damping(self) -> float:
        """``k_t^2 / R + b`` [N m s/rad]: the damping at the rotor from the back-EMF and
        viscous friction (the physical damping of `passivity_bound`)."""
        return self.k_t ** 2 / self.R + self.b


def motor_plants(structure: Structure, kin: WristKinematics) -> tuple[MotorPlant, ...]:
    """`MotorPlant` of each motor of ``kin`` (in its order), from ``structure``'s mass
    matrix and viscous friction coefficients through the rigid kinematics."""
    n = structure.n
    rigid = _null_space(structure.spring_rows @ structure.A, n)
    motor_rows = np.array([structure.rows(f)[0] for f in kin.rotors])
    # the configuration a unit turn of one rotor gives, the others held, springs rigid
    turns = rigid @ np.linalg.inv(motor_rows @ rigid)
    mass = structure.mass_matrix()
    speeds = structure.friction_rows @ structure.A @ turns
    viscous = np.array([f.viscous for f in structure.frictions])
    by_name = {m.name: m for m in structure.motors}
    plants = []
    for j, name in enumerate(kin.motors):
        m = by_name[name]
        plants.append(MotorPlant(R=float(m.resistance), k_t=float(m.torque_constant),
                                 J=float(turns[:, j] @ mass @ turns[:, j]),
                                 b=float(viscous @ speeds[:, j] ** 2)))
    return tuple(plants)


@dataclass(frozen=True)
class MotorPID:
    """Gains of one position loop: ``k`` [V per unit of the measurement: V/rad on a
    rotor, V/m on the pivot], ``Ti`` [s] (``inf``: no integral action), ``Td`` [s], ``Nd``
    (derivative filter: ``Td s / (1 + s Td / Nd)``)."""

    k: float
    Ti: float
    Td: float
    Nd: float = 10.0

    #: The integral's corner as a fraction of the crossover: 1/8 costs 7 degrees of
    #: phase there.
    INTEGRAL_CORNER = 1.0 / 8.0

    @staticmethod
    def design(plant: MotorPlant, bandwidth: float, *, sensitivity: float = 1.0,
               integral: bool = True) -> "MotorPID":
        """PID for ``plant`` measured as ``sensitivity`` units per rotor radian, crossing
        over at ``bandwidth`` w_c [rad/s]. The derivative time cancels the mechanical
        pole (``Td = tau``), so near the crossover the loop is ``w_c / s`` and ``k = w_c /
        (a sensitivity)``. The integral (``Ti = 1 / (c w_c)``, c = `INTEGRAL_CORNER`)
        removes the static error friction and loads leave at the motor.

        The set-point weight stays 1: the engine's integrators start at zero, so with a
        weight below 1 a loop that starts at rest at a non-zero reference (a held
        output angle, the pivot away from 0) would see ``(wp - 1) r`` as an error on its
        first sample and leave its operating point."""
        k = bandwidth / (plant.gain * sensitivity)
        Ti = 1.0 / (MotorPID.INTEGRAL_CORNER * bandwidth) if integral else math.inf
        return MotorPID(k=k, Ti=Ti, Td=plant.time_constant)


def _reference_inputs(references: Mapping[str, object]) -> dict:
    if not isinstance(references, Mapping):
        raise InputError(f"references must be a mapping of {', '.join(COORDINATES)} to "
                         f"signals, got {type(references).__name__}")
    unknown = [str(k) for k in references if k not in COORDINATES]
    if unknown:
        raise InputError(f"references: unknown {', '.join(unknown)}; the wrist's "
                         f"coordinates are {', '.join(COORDINATES)}")
    missing = [c for c in COORDINATES if c not in references]
    if missing:
        raise InputError(f"references: give {', '.join(missing)} (the wrist's coordinates "
                         f"are {', '.join(COORDINATES)}: output angles [rad], pivot "
                         "position [m])")
    return as_inputs(dict(references), COORDINATES)


def _check_q_range(refs: dict, kin: WristKinematics) -> None:
    """A pivot reference outside the mechanism's range at the start or in the long run
    (a constant, a step, a table's last value) is refused here; one that leaves it on the
    way fails the run at the engine's range check."""
    levels = np.atleast_1d(refs["q"].value(np.array([0.0, 1e9])))
    for level in levels:
        if not kin.q_min <= float(level) <= kin.q_max:
            raise InputError(f"reference q = {float(level):g} m is outside the pivot's range "
                             f"[{kin.q_min:g}, {kin.q_max:g}] m")


def _check_rate(bandwidth: float, period: float, name: str) -> None:
    # the zero-order hold costs bandwidth * period / 2 rad of phase at the crossover: at
    # 0.3 that is 9 degrees; the integral's corner takes 7 more and the derivative
    # filter atan(bandwidth Td / Nd), 8 at the motors' Td, which leaves 65 of margin
    if not (math.isfinite(bandwidth) and bandwidth > 0.0):
        raise InputError(f"{name} must be a finite number > 0 rad/s, got {bandwidth!r}")
    if bandwidth * period > 0.3:
        raise InputError(f"{name} = {bandwidth:g} rad/s is too fast for the period "
                         f"{period:g} s (bandwidth * period must be <= 0.3; the hold's "
                         f"delay would eat the phase margin): sample faster or lower it")


def _pivot_loop(kin: WristKinematics, plant: MotorPlant, bandwidth: float, encoder_counts,
                current_limit: float) -> tuple[Sensor, PID, Actuator]:
    """The stiffness motor's loop: PID on the pivot position q (reference ``q``), read
    through the pivot mechanism; an encoder of ``encoder_counts`` on the stiffness motor
    is a resolution in q of its count times dq/d(rotor) at q = 0."""
    # q = amplitude sin(phi_C): the loop gain is highest at q = 0 (cos = 1), so the
    # crossover is `bandwidth` there and lower (by cos phi_C, >= 0.47 over the tested
    # range) towards the ends: the phase margin only grows
    sensitivity = kin.amplitude * abs(kin.pivot_gain)
    gains = MotorPID.design(plant, bandwidth, sensitivity=sensitivity)
    resolution = 0.0
    if encoder_counts is not None:
        resolution = sensitivity * 2.0 * math.pi / float(encoder_counts)
    sensor = Sensor(quantity="q", resolution=resolution, name="q.measured")
    sign = math.copysign(1.0, kin.pivot_gain)
    block = PID("u_q", "q", "q.measured", k=sign * gains.k, Ti=gains.Ti, Td=gains.Td,
                Nd=gains.Nd)
    act = Actuator(kin.channels[2], "u_q", current_limit=current_limit)
    return sensor, block, act


def _encoders(kin: WristKinematics, encoder_counts) -> tuple[Sensor, Sensor]:
    if encoder_counts is None:
        return tuple(Sensor(kin.rotors[j]) for j in range(2))
    return tuple(Sensor.encoder(kin.rotors[j], encoder_counts) for j in range(2))


def _check_period(period) -> float:
    try:
        value = float(period)
    except (TypeError, ValueError):
        raise InputError(f"controller period must be a number of seconds, got "
                         f"{period!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(f"controller period must be > 0 s, got {period!r}")
    return value


def wrist_controller(structure: Structure, references: Mapping[str, object], *,
                     period: float = 1e-3, bandwidth: float = 2 * math.pi * 20.0,
                     pivot_bandwidth: float | None = None, encoder_counts: int | None = None,
                     current_limit: float = math.inf) -> Controller:
    """Position control of the wrist in its own coordinates.

    ``references`` maps ``theta_x``, ``theta_y`` [rad] (end-effector angles) and ``q``
    [m] (pivot position, the stiffness setting) to `vsj.inputs` signals or numbers. Each
    output motor runs a `PID` on its rotor angle (an encoder of ``encoder_counts`` per
    rotor revolution, or exact) towards the rotor angle the rigid kinematics
    (`wrist_kinematics`) gives for the commanded output angles; the stiffness motor runs a
    PID on the pivot position, measured through the pivot mechanism. The gains come from
    each motor's model (`MotorPID.design`) for a crossover of ``bandwidth`` [rad/s]
    (``pivot_bandwidth`` for the stiffness motor, default the same) at the controller's
    ``period`` [s]. ``current_limit`` [A] bounds each motor's current.

    Under a load the end-effector deflects by the VSM's stiffness at the commanded q:
    the motors hold their angles, the elastic elements give way (see the module's notes
    on collocated control). The controller's bus carries the references (``theta_x``,
    ``theta_y``, ``q``), the readings (the rotors' angles, ``q.measured``) and the
    voltages (``u_<motor>``, ``u_q``).
    """
    period = _check_period(period)
    kin = wrist_kinematics(structure)
    refs = _reference_inputs(references)
    _check_q_range(refs, kin)
    pivot_bandwidth = bandwidth if pivot_bandwidth is None else pivot_bandwidth
    _check_rate(bandwidth, period, "bandwidth")
    _check_rate(pivot_bandwidth, period, "pivot_bandwidth")
    plants = motor_plants(structure, kin)
    encoders = _encoders(kin, encoder_counts)
    blocks, actuators = [], []
    for j in range(2):
        gains = MotorPID.design(plants[j], bandwidth)
        setpoint = {c: float(kin.to_rotors[j, i]) for i, c in enumerate(COORDINATES[:2])
                    if kin.to_rotors[j, i] != 0.0}
        name = f"u_{kin.motors[j]}"
        blocks.append(PID(name, setpoint, encoders[j].label, k=gains.k, Ti=gains.Ti,
                          Td=gains.Td, Nd=gains.Nd))
        actuators.append(Actuator(kin.channels[j], name, current_limit=current_limit))
    sensor, block, act = _pivot_loop(kin, plants[2], pivot_bandwidth, encoder_counts,
                                     current_limit)
    return Controller(period=period, references=refs, sensors=(*encoders, sensor),
                      blocks=(*blocks, block), actuators=(*actuators, act))


# -- impedance -----------------------------------------------------------------------


def passivity_bound(period: float, stiffness: float, damping: float) -> float:
    """The least physical viscous damping b [N m s/rad] that keeps a sampled virtual
    spring ``stiffness`` K [N m/rad] and damper ``damping`` B [N m s/rad] (backward
    difference velocity, zero-order hold, period T [s]) passive: ``K T / 2 + |B|``
    (Colgate and Schenkel 1997; Abbott and Okamura 2005, eq 8). Why ``K T / 2``: held
    over a period, the spring's force is the one at the period's start, so over a motion
    it does the work ``(K / 2) sum (x_{k+1} - x_k)^2`` (summation by parts), while a
    damper b dissipates at least ``(b / T) sum (x_{k+1} - x_k)^2`` (Cauchy-Schwarz on
    each period; equality at constant speed)."""
    return float(stiffness) * float(period) / 2.0 + abs(float(damping))


def virtual_spring_damper(name: str, period: float, stiffness, damping, *,
                          references: tuple, positions: tuple, outputs: tuple,
                          measure=None, drive=None) -> Linear:
    """A discrete virtual spring-damper as a `Linear` block, run at ``period`` [s]:

        y_k = G (K (r_k - P m_k) - B P (m_k - m_{k-1}) / T)

    with ``r`` the bus combinations ``references`` (the spring's rest positions), ``m``
    the bus combinations ``positions`` (the measured positions), ``P`` = ``measure``
    (positions to the spring's coordinates; identity by default), ``G`` = ``drive``
    (the spring's forces to the block's outputs; identity by default), ``K`` =
    ``stiffness`` and ``B`` = ``damping`` (numbers or symmetric matrices, in the spring's
    coordinates; a negative damping, which compensates physical damping, is allowed:
    `passivity_bound` says what it costs). The velocity is the backward difference of the
    measured positions over one period; on the first sample the previous position is
    zero (the engine starts a block's state at zero), so a run that starts away from
    zero gets one sample's damper kick ``-B P m_0 / T``."""
    import control  # lazy: python-control is slow to import; only Linear blocks need it

    period = _check_period(period)
    nr, nm = len(references), len(positions)
    P = np.eye(nm) if measure is None else np.atleast_2d(np.asarray(measure, dtype=float))
    if P.shape[1] != nm:
        raise InputError(f"virtual spring-damper {name!r}: measure has {P.shape[1]} columns "
                         f"for {nm} positions")
    ns = P.shape[0]
    if nr != ns:
        raise InputError(f"virtual spring-damper {name!r}: {nr} references for a spring "
                         f"of {ns} coordinates")
    K = _matrix(stiffness, f"virtual spring-damper {name!r}: stiffness", ns, definite=False)
    B = _matrix(damping, f"virtual spring-damper {name!r}: damping", ns, definite=False)
    G = np.eye(ns) if drive is None else np.atleast_2d(np.asarray(drive, dtype=float))
    if G.shape[1] != ns or G.shape[0] != len(outputs):
        raise InputError(f"virtual spring-damper {name!r}: drive must be {len(outputs)} x "
                         f"{ns}, got {G.shape[0]} x {G.shape[1]}")
    # state: the previous measured positions m_{k-1}
    A = np.zeros((nm, nm))
    Bm = np.hstack([np.zeros((nm, nr)), np.eye(nm)])
    C = G @ B @ P / period
    D = G @ np.hstack([K, -(K + B / period) @ P])
    system = control.ss(A, Bm, C, D, period)
    return Linear(name, system, tuple(references) + tuple(positions), tuple(outputs))


def mechanical_stiffness(structure: Structure, q: float,
                         outputs: tuple[str, str] = ("theta_x", "theta_y"), *,
                         deflections: Mapping[str, float] | None = None) -> np.ndarray:
    """The end-effector's stiffness matrix [N m/rad] with the motors' rotors held and the
    pivot at ``q`` [m]: the springs' tangent stiffnesses through the network's
    kinematics, ``(Y H^{-1} Y^T)^{-1}`` with ``H`` the springs' stiffness over the
    coordinates left free when the rotors are held and ``Y`` the outputs' rows over them.
    The tangents are taken at the reference configuration (every spring undeflected) or,
    given ``deflections`` (spring name -> deflection [rad]; a spring left out is
    undeflected), at that state (report fig 4.14's characteristic is the small-motion
    stiffness around it)."""
    n = structure.n
    rotors = np.array([structure.rows(m.flange)[0] for m in structure.motors])
    free = _null_space(rotors, n)
    S = structure.spring_rows @ structure.A @ free
    at = {} if deflections is None else dict(deflections)
    unknown = sorted(set(at) - {sp.name for sp in structure.springs})
    if unknown:
        raise InputError(f"network {structure.name!r} has no spring(s) {', '.join(unknown)}")
    k = np.array([spring_law(sp.law, tuple(sp.parameters), float(at.get(sp.name, 0.0)),
                             float(q))[1] for sp in structure.springs])
    H = S.T @ (k[:, None] * S)
    Y = np.array([structure.rows(_signal_flange(structure, o))[0] for o in outputs]) @ free
    try:
        compliance = Y @ np.linalg.solve(H, Y.T)
        return np.linalg.inv(compliance)
    except np.linalg.LinAlgError:
        raise InputError(f"network {structure.name!r}: with the motors held, the springs do "
                         f"not hold the end-effector at q = {q:g} m (a free mode)") from None


def closed_loop_stiffness(structure: Structure, q: float, virtual_stiffness) -> np.ndarray:
    """The end-effector's static stiffness [N m/rad] under `impedance_controller` with
    the virtual stiffness ``virtual_stiffness`` K_d [N m/rad] at the pivot position ``q``
    [m]: the virtual spring acts on the end-effector angles the motors' encoders give
    through the rigid kinematics, and the VSM's springs lie between those and the
    end-effector, so the two are in series, ``(K_d^{-1} + K_vsm^{-1})^{-1}``
    (`mechanical_stiffness`). The result is below both; a K_d of zero gives zero."""
    Kd = _matrix(virtual_stiffness, "virtual_stiffness")
    Km = mechanical_stiffness(structure, q)
    # K_cl = K_d (K_d + K_m)^{-1} K_m: the series sum, also for a singular K_d
    return Kd @ np.linalg.solve(Kd + Km, Km)


def virtual_stiffness_for(structure: Structure, q: float, stiffness) -> np.ndarray:
    """The virtual stiffness K_d [N m/rad] that gives the end-effector the static
    ``stiffness`` [N m/rad] at the pivot position ``q`` [m] (inverse of
    `closed_loop_stiffness`): ``(K^{-1} - K_vsm^{-1})^{-1}``, which needs ``K`` below the
    VSM's own stiffness there (in series, the controller can only soften)."""
    K = _matrix(stiffness, "stiffness")
    Km = mechanical_stiffness(structure, q)
    if np.min(np.linalg.eigvalsh(K)) <= 0.0:
        raise InputError("stiffness must be positive definite")
    # K_d = (K^-1 - K_m^-1)^-1 = K_m (K_m - K)^-1 K, positive definite iff K_m - K is
    difference = Km - K
    if np.min(np.linalg.eigvalsh((difference + difference.T) / 2)) <= 0.0:
        raise InputError(f"stiffness {K.tolist()} N m/rad is not below the VSM's own "
                         f"{Km.tolist()} N m/rad at q = {q:g} m: in series with it the "
                         "controller can only soften the end-effector (set q stiffer)")
    return Km @ np.linalg.solve(difference, K)


def impedance_controller(structure: Structure, references: Mapping[str, object], *,
                         stiffness, damping, period: float = 1e-3,
                         pivot_bandwidth: float = 2 * math.pi * 20.0,
                         encoder_counts: int | None = None,
                         current_limit: float = math.inf) -> Controller:
    """Impedance control of the end-effector through the output motors.

    The virtual spring ``stiffness`` K_d [N m/rad] and damper ``damping`` D_d [N m
    s/rad] (numbers, or symmetric 2 x 2 matrices over ``(theta_x, theta_y)``) act
    between the commanded ``theta_x``, ``theta_y`` [rad] and the end-effector angles
    the motors' encoders give through the rigid kinematics (theta = J rotor): the rotors
    get ``tau = J^T (K_d (theta_ref - theta) - D_d theta_dot)`` (a `virtual_spring_damper`,
    backward difference velocity), as voltages ``V = R tau / k_t`` (each motor's model;
    the back-EMF is left in place, as physical damping at the rotor: cancelling it would
    trade the damping that keeps the sampled spring passive for a held copy of itself).
    The VSM's springs sit in series with the virtual one, so the end-effector's static
    stiffness is `closed_loop_stiffness`; choose K_d for a target with
    `virtual_stiffness_for`. The pivot follows ``q`` [m] as in `wrist_controller`.

    Raises `InputError` if the sampled spring-damper, seen at the rotors, would not be
    passive against the rotors' own damping (`passivity_bound`, with each matrix's
    largest eigenvalue: a sufficient condition).
    """
    period = _check_period(period)
    kin = wrist_kinematics(structure)
    refs = _reference_inputs(references)
    _check_q_range(refs, kin)
    _check_rate(pivot_bandwidth, period, "pivot_bandwidth")
    Kd = _matrix(stiffness, "impedance stiffness")
    Dd = _matrix(damping, "impedance damping")
    plants = motor_plants(structure, kin)
    J = kin.jacobian
    k_rotor = float(np.max(np.linalg.eigvalsh(J.T @ Kd @ J)))
    d_rotor = float(np.max(np.linalg.eigvalsh(J.T @ Dd @ J)))
    needed = passivity_bound(period, k_rotor, d_rotor)
    have = min(p.damping for p in plants[:2])
    if not needed < have:
        raise InputError(f"impedance stiffness and damping: at the rotors they are a "
                         f"sampled spring of {k_rotor:.4g} N m/rad and damper of "
                         f"{d_rotor:.4g} N m s/rad, which the rotors' own damping "
                         f"{have:.4g} N m s/rad (back-EMF and friction) does not keep "
                         f"passive (needs > K T/2 + |B| = {needed:.4g}): lower them or "
                         "sample faster")
    encoders = _encoders(kin, encoder_counts)
    volts = np.diag([p.R / p.k_t for p in plants[:2]]) @ J.T
    outputs = tuple(f"u_{m}" for m in kin.motors[:2])
    block = virtual_spring_damper("impedance", period, Kd, Dd,
                                  references=COORDINATES[:2],
                                  positions=tuple(e.label for e in encoders),
                                  outputs=outputs, measure=J, drive=volts)
    sensor, pivot_block, pivot_act = _pivot_loop(kin, plants[2], pivot_bandwidth,
                                                 encoder_counts, current_limit)
    actuators = tuple(Actuator(kin.channels[j], outputs[j], current_limit=current_limit)
                      for j in range(2))
    return Controller(period=period, references=refs, sensors=(*encoders, sensor),
                      blocks=(block, pivot_block), actuators=(*actuators, pivot_act))
