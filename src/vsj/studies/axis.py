"""The wrist reduced to one output axis: the model both studies optimise on.

With ``theta_y`` held at zero the two output motors turn together and the two elastic
elements deflect together, so the wrist of report fig 3.1 moving about ``theta_x`` is a
two-inertia elastic joint:

* ``theta_m`` [rad], the *motor side*: the output angle the motors' rotors would give
  with every spring undeflected (the rigid kinematics of `vsj.control.wrist_kinematics`);
* ``theta`` [rad], the *link*: the end-effector angle ``theta_x``;
* the joint's deflection ``delta = theta_m - theta`` [rad], which the elastic elements
  (report section 3.2) resist with the torque ``tau(delta, q)`` [N m] at the pivot
  position ``q`` [m].

`axis_model` reads everything from vsj's own assembled network, nothing from hard-coded
ratios: the 2 x 2 mass matrix (rotors, suns, rings, carriers, transmissions and
end-effector, reflected; the ring's inertia couples the two sides, so it is not
diagonal), the viscous friction coefficients through the same kinematics, the DC
motors' torque per volt and back-EMF damping (``L/R``, 0.1 ms with the bundled motors,
is neglected against the mechanical time constants), and the joint's torque from the
elastic element's law (`vsj.springs.evaluate`, the engine's compiled code) tabulated
over ``(delta, q)``. The equations of motion::

    M [theta_m'', theta''] = [g V - tau(delta, q), tau(delta, q)] - (G + D) [theta_m', theta']

``g`` [N m/V] is the generalised force per volt (both output motors at the same voltage
``V``), ``G`` [N m s/rad] the back-EMF's damping, ``D`` [N m s/rad] the viscous friction.
What the reduction leaves out, and the engine's run of the real wrist puts back: the
Coulomb part of friction (table 4.1's stiction levels), the motors' inductance, and the
smoothing of the tabulated torque where a spring goes slack (a kink of the law, rounded
by the bicubic spline over one grid cell).

The stiffness setting moves through the pivot mechanism (report section 3.4), driven by
its own DC motor: ``q = amplitude sin(phi_C)``, so the pivot's speed is at most
``pivot_gain omega_0 sqrt(amplitude^2 - q^2)`` with ``omega_0`` the stiffness motor's
no-load speed at its voltage limit (`AxisModel.pivot_rate_limit`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import PchipInterpolator, RectBivariateSpline

from ..control.wrist import wrist_kinematics
from ..errors import InputError, SimulationError, finite_number
from ..network import Structure
from ..params import Parameters
from ..springs import end_stop, evaluate
from ..wrist import WristOptions, build_wrist

#: Deflection grid of the tabulated joint torque: points over the end stop's range. The
#: bicubic spline's error on the smooth parts of the law is of order h^4 tau''''; with
#: 801 points over +-2.1 rad (h = 5 mrad) it is far below the model's other neglects, and
#: a slack spring's kink is rounded over 5 mrad of deflection.
DEFLECTION_POINTS = 801
#: Pivot grid of the tabulated joint torque: 0.5 mm steps over the 4.2 cm pivot range;
#: the stiffness varies as exp(-1.45 q/cm) (eq 4.5), about 7 % per step.
PIVOT_POINTS = 85


def _finite(name: str, value, *, low: float | None = None, strict: bool = True) -> float:
    return finite_number(name, value, low=low, strict=strict)


@dataclass(frozen=True)
class JointTable:
    """The joint's torque ``tau`` [N m] on the link at deflections ``deflection`` [rad]
    (rows) and pivot positions ``q`` [m] (columns), ``holdable`` [rad] the largest
    deflection the joint holds at each ``q`` (the torque's first peak, or the end stop
    where the torque only grows: past the peak the joint's stiffness is negative and a
    load above the peak drives it to the stop).

    `torque` interpolates it with a bicubic spline and gives the partial derivatives the
    optimisers need."""

    deflection: np.ndarray
    q: np.ndarray
    torque_grid: np.ndarray
    holdable: np.ndarray

    def __post_init__(self):
        d, q, t = (np.asarray(a, dtype=float) for a in (self.deflection, self.q,
                                                          self.torque_grid))
        if d.ndim != 1 or q.ndim != 1 or len(d) < 4 or len(q) < 4:
            raise InputError("a joint table needs at least 4 deflections and 4 pivot "
                             "positions (a bicubic spline)")
        if t.shape != (len(d), len(q)) or not np.all(np.isfinite(t)):
            raise InputError(f"joint table: torque must be a finite {len(d)} x {len(q)} "
                             f"array, got shape {t.shape}")
        if np.any(np.diff(d) <= 0) or np.any(np.diff(q) <= 0):
            raise InputError("joint table: deflections and pivot positions must increase")
        if np.asarray(self.holdable).shape != q.shape or np.any(np.asarray(self.holdable) <= 0):
            raise InputError("joint table: holdable must hold one deflection > 0 per pivot "
                             "position")

    @staticmethod
    def linear(stiffness, q, *, deflection_limit: float) -> "JointTable":
        """A linear joint ``tau = K(q) delta`` with ``stiffness`` K [N m/rad] at the pivot
        positions ``q`` [m] (at least 4), holding up to ``deflection_limit`` [rad]. The
        spline is exact in the deflection (cubic in it reproduces a line)."""
        K = np.asarray(stiffness, dtype=float)
        q = np.asarray(q, dtype=float)
        if K.shape != q.shape or np.any(~np.isfinite(K)) or np.any(K <= 0):
            raise InputError("a linear joint needs one finite stiffness > 0 N m/rad per "
                             "pivot position")
        limit = _finite("deflection_limit", deflection_limit, low=0.0)
        d = np.linspace(-limit, limit, 5)
        return JointTable(d, q, d[:, None] * K[None, :], np.full(q.shape, limit))

    @cached_property
    def _spline(self) -> RectBivariateSpline:
        return RectBivariateSpline(self.deflection, self.q, self.torque_grid, kx=3, ky=3)

    @cached_property
    def _holdable(self) -> PchipInterpolator:
        return PchipInterpolator(self.q, self.holdable)

    def torque(self, delta, q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(tau, dtau/ddelta, dtau/dq)`` at deflections ``delta`` [rad] and pivot
        positions ``q`` [m] (arrays of one shape): N m, N m/rad, N m/m. Beyond the
        table's deflections the torque goes on along its tangent at the edge (the spline
        itself would hold the edge's value); pivot positions are held to the table's."""
        delta = np.asarray(delta, dtype=float)
        q = np.clip(np.asarray(q, dtype=float), self.q[0], self.q[-1])
        inside = np.clip(delta, self.deflection[0], self.deflection[-1])
        s = self._spline
        slope = s.ev(inside, q, dx=1)
        beyond = delta - inside
        return (s.ev(inside, q) + slope * beyond, slope,
                s.ev(inside, q, dy=1) + s.ev(inside, q, dx=1, dy=1) * beyond)

    def stiffness(self, q) -> np.ndarray:
        """The joint's stiffness at zero deflection [N m/rad] at pivot positions ``q``
        [m]: the stiffness setting."""
        q = np.asarray(q, dtype=float)
        return self.torque(np.zeros_like(q), q)[1]

    def holdable_deflection(self, q) -> tuple[np.ndarray, np.ndarray]:
        """``(limit [rad], dlimit/dq [rad/m])``: the largest deflection held at ``q``."""
        q = np.clip(np.asarray(q, dtype=float), self.q[0], self.q[-1])
        h = self._holdable
        return h(q), h(q, 1)


@dataclass(frozen=True)
class AxisModel:
    """One output axis of the wrist as an elastic joint (see the module's notes).

    ``mass`` [kg m^2], ``damping`` and ``back_emf`` [N m s/rad]: 2 x 2 over ``(theta_m,
    theta)``; ``voltage_gain`` [N m/V]: the generalised force per volt on each;
    ``voltage_limit`` [V]; ``joint``: the `JointTable`; ``q_min``, ``q_max`` [m]: the
    pivot's range; ``pivot_amplitude`` [m] and ``pivot_speed`` [rad/s]: ``q =
    amplitude sin(phi_C)`` and the largest ``dphi_C/dt`` (the stiffness motor's no-load
    speed through its gearing); ``source``: where it came from.
    """

    mass: np.ndarray
    damping: np.ndarray
    back_emf: np.ndarray
    voltage_gain: np.ndarray
    voltage_limit: float
    joint: JointTable
    q_min: float
    q_max: float
    pivot_amplitude: float
    pivot_speed: float
    source: str = ""
    elastic: str = field(default="geometric")

    def __post_init__(self):
        M = np.asarray(self.mass, dtype=float)
        if M.shape != (2, 2) or not np.all(np.isfinite(M)) or np.min(np.linalg.eigvalsh(
                (M + M.T) / 2)) <= 0:
            raise InputError(f"axis model: mass must be a symmetric positive definite 2 x 2 "
                             f"matrix [kg m^2], got {M.tolist()}")
        for name in ("damping", "back_emf"):
            m = np.asarray(getattr(self, name), dtype=float)
            if m.shape != (2, 2) or not np.all(np.isfinite(m)) or \
                    np.min(np.linalg.eigvalsh((m + m.T) / 2)) < -1e-12 * max(1.0, np.abs(m).max()):
                raise InputError(f"axis model: {name} must be a positive semi-definite 2 x 2 "
                                 f"matrix [N m s/rad], got {m.tolist()}")
        g = np.asarray(self.voltage_gain, dtype=float)
        if g.shape != (2,) or not np.all(np.isfinite(g)) or g[0] == 0:
            raise InputError("axis model: voltage_gain must be 2 finite numbers [N m/V], the "
                             "first (the motor side's) non-zero")
        _finite("voltage_limit", self.voltage_limit, low=0.0)
        if not self.q_min < self.q_max:
            raise InputError(f"axis model: q_min {self.q_min!r} m must be below q_max "
                             f"{self.q_max!r} m")
        if not (self.joint.q[0] <= self.q_min and self.q_max <= self.joint.q[-1]):
            raise InputError("axis model: the joint table must cover the pivot's range")
        _finite("pivot_amplitude", self.pivot_amplitude, low=0.0)
        _finite("pivot_speed", self.pivot_speed, low=0.0)

    @cached_property
    def _inverse_mass(self) -> np.ndarray:
        return np.linalg.inv(np.asarray(self.mass, dtype=float))

    @property
    def no_load_speed(self) -> float:
        """The motors' speed limit reflected to the axis [rad/s]: the speed at which the
        back-EMF cancels the voltage limit, ``g V_max / G`` on the motor side (friction
        aside). A rigid joint's link never moves faster."""
        return float(self.voltage_gain[0] * self.voltage_limit / self.back_emf[0][0])

    def pivot_rate_limit(self, q) -> tuple[np.ndarray, np.ndarray]:
        """``(largest |dq/dt| [m/s], its derivative over q [1/s])`` at pivot positions
        ``q`` [m]: ``pivot_speed sqrt(amplitude^2 - q^2)``."""
        q = np.asarray(q, dtype=float)
        root = np.sqrt(np.maximum(self.pivot_amplitude ** 2 - q ** 2, 0.0))
        return self.pivot_speed * root, -self.pivot_speed * q / np.maximum(root, 1e-300)

    def acceleration(self, state, voltage, q):
        """Accelerations and their partial derivatives along a trajectory.

        ``state`` (n x 4: ``theta_m, theta, omega_m, omega`` in rad and rad/s),
        ``voltage`` (n) [V], ``q`` (n) [m]. Returns ``(acc, d_state, d_voltage, d_q)``:
        ``acc`` n x 2 [rad/s^2]; ``d_state`` n x 2 x 4, ``d_voltage`` n x 2, ``d_q`` n x
        2: the Jacobians the collocation's constraints need."""
        x = np.atleast_2d(np.asarray(state, dtype=float))
        V = np.asarray(voltage, dtype=float).reshape(-1)
        q = np.asarray(q, dtype=float).reshape(-1)
        Minv = self._inverse_mass
        C = np.asarray(self.back_emf, dtype=float) + np.asarray(self.damping, dtype=float)
        g = np.asarray(self.voltage_gain, dtype=float)
        tau, tau_d, tau_q = self.joint.torque(x[:, 0] - x[:, 1], q)
        force = np.stack([-tau, tau], axis=1) + V[:, None] * g[None, :] - x[:, 2:4] @ C.T
        acc = force @ Minv.T
        spring = np.array([[-1.0, 1.0], [1.0, -1.0]])  # d force / d(theta_m, theta) per tau_d
        d_state = np.empty((len(V), 2, 4))
        d_state[:, :, 0:2] = tau_d[:, None, None] * (Minv @ spring)[None]
        d_state[:, :, 2:4] = -(Minv @ C)[None]
        d_voltage = np.broadcast_to(Minv @ g, (len(V), 2)).copy()
        d_q = tau_q[:, None] * (Minv @ np.array([-1.0, 1.0]))[None, :]
        return acc, d_state, d_voltage, d_q

    def simulate(self, time, voltage, q, *, state0=(0.0, 0.0, 0.0, 0.0),
                 rtol: float = 1e-9, atol: float = 1e-11):
        """The reduced model driven by ``voltage`` [V] and ``q`` [m] (callables of time
        [s]) from ``state0``, sampled at ``time`` [s]: an n x 4 array of ``theta_m,
        theta, omega_m, omega``. `SimulationError` if the integration fails."""
        def rhs(t, x):
            acc = self.acceleration(x[None, :], [voltage(t)], [q(t)])[0][0]
            return np.array([x[2], x[3], acc[0], acc[1]])

        time = np.asarray(time, dtype=float)
        sol = solve_ivp(rhs, (float(time[0]), float(time[-1])), np.asarray(state0, float),
                        t_eval=time, rtol=rtol, atol=atol, method="DOP853")
        if not sol.success:
            raise SimulationError(f"reduced axis model: {sol.message} (t = {sol.t[-1]:g} s)")
        return sol.y.T


def _symmetric_coordinates(structure: Structure, outputs=("theta_x", "theta_y")):
    """``P`` (n x 2): the free coordinates for ``(theta_m, theta)`` with ``theta_y`` and
    the stiffness motor held, and the output motors' rotor angles per ``theta_m``."""
    kin = wrist_kinematics(structure, outputs)
    flanges = {s.name: s.flange for s in structure.signals}
    rows = [structure.rows(f)[0] for f in kin.rotors]
    rows += [structure.rows(flanges[o])[0] for o in outputs]
    R = np.array(rows)
    if R.shape[0] != R.shape[1]:
        raise InputError(f"network {structure.name!r}: the one-axis model needs the rotor "
                         f"angles, theta_x and theta_y to fix every coordinate; it has "
                         f"{structure.n} ({', '.join(structure.free)}): a series compliance "
                         "adds coordinates (set transmission.series_compliance_* to 0)")
    per_output = kin.to_rotors[:2, 0]
    P = np.zeros((structure.n, 2))
    for j, (theta_m, theta) in enumerate(((1.0, 0.0), (0.0, 1.0))):
        rhs = np.concatenate([per_output * theta_m, [0.0], [theta, 0.0]])
        P[:, j] = np.linalg.solve(R, rhs)
    return P, per_output, kin


def _joint_table(structure: Structure, P: np.ndarray, q_grid: np.ndarray) -> JointTable:
    """The joint's torque over ``(delta, q)`` from the network's spring rows and laws:
    every spring's deflection must be a multiple ``a_j delta`` of the joint's."""
    arms = []
    for sp, row in zip(structure.springs, structure.spring_rows @ structure.A @ P):
        if abs(row[0] + row[1]) > 1e-9 * max(abs(row[0]), 1e-300):
            raise InputError(f"spring {sp.name!r} of network {structure.name!r} does not "
                             "deflect with theta_m - theta alone")
        arms.append(float(row[0]))
    stops = []
    for sp, a in zip(structure.springs, arms):
        stop = end_stop(sp.law, sp.parameters)
        if stop is None:
            raise InputError(f"spring {sp.name!r} has no end stop to bound the deflection")
        stops.append(stop[0] / abs(a))
    limit = min(stops)
    delta = np.linspace(-limit, limit, DEFLECTION_POINTS)
    torque = np.zeros((len(delta), len(q_grid)))
    for sp, a in zip(structure.springs, arms):
        for k, q in enumerate(q_grid):
            # evaluate's torque is -dV/dphi on the element: the joint's is dV/ddelta
            torque[:, k] -= a * evaluate(sp.law, sp.parameters, a * delta, float(q))[0]
    if not np.all(np.isfinite(torque)):
        raise InputError(f"network {structure.name!r}: the elastic element's geometry breaks "
                         "down inside the pivot range (q + R <= 0)")
    holdable = np.empty(len(q_grid))
    half = len(delta) // 2
    for k in range(len(q_grid)):
        up = torque[half:, k]
        falling = np.flatnonzero(np.diff(up) < 0)
        holdable[k] = delta[half + (falling[0] if len(falling) else len(up) - 1)]
    return JointTable(delta, q_grid, torque, holdable)


def axis_model(params: Parameters, *, elastic: str = "geometric") -> AxisModel:
    """The wrist's ``theta_x`` axis (``theta_y`` held) as an `AxisModel`, read from the
    network `vsj.build_wrist` assembles with DC motors at all three motor ports and the
    ``elastic`` model (``geometric``, ``geometric-report``, ``exponential``)."""
    if not isinstance(params, Parameters):
        raise InputError(f"axis_model needs a vsj.params.Parameters set, got "
                         f"{type(params).__name__}")
    if elastic == "linear":
        raise InputError("axis_model: the linear elastic model has no pivot dependence; use "
                         "geometric, geometric-report or exponential")
    structure = build_wrist(params, WristOptions(elastic=elastic, motors="dc",
                                                 pivot_drive="dc")).assemble()
    P, per_output, kin = _symmetric_coordinates(structure)
    mass = P.T @ structure.mass_matrix() @ P
    mass = (mass + mass.T) / 2  # symmetric to the bit (the products round differently)
    speeds = structure.friction_rows @ structure.A @ P
    viscous = np.array([f.viscous for f in structure.frictions])
    damping = speeds.T @ (viscous[:, None] * speeds)
    by_name = {m.name: m for m in structure.motors}
    gain, emf = np.zeros(2), np.zeros((2, 2))
    signs = np.sign(per_output)
    for j, name in enumerate(kin.motors[:2]):
        m = by_name[name]
        row = structure.rows(m.flange)[0] @ P  # rotor angle per (theta_m, theta)
        # each motor's voltage is sign * V, its torque k_t (V sign - k_t w_rotor) / R
        gain += row * signs[j] * m.torque_constant / m.resistance
        emf += np.outer(row, row) * m.torque_constant ** 2 / m.resistance
    stiffness_motor = by_name[kin.motors[2]]
    pivot_speed = abs(kin.pivot_gain) * stiffness_motor.voltage_limit \
        / stiffness_motor.torque_constant
    q_grid = np.linspace(kin.q_min, kin.q_max, PIVOT_POINTS)
    joint = _joint_table(structure, P, q_grid)
    limits = {by_name[n].voltage_limit for n in kin.motors[:2]}
    if len(limits) != 1:
        raise InputError("axis_model: the two output motors must share one voltage limit")
    return AxisModel(mass=mass, damping=damping, back_emf=emf, voltage_gain=gain,
                     voltage_limit=limits.pop(), joint=joint, q_min=kin.q_min,
                     q_max=kin.q_max, pivot_amplitude=kin.amplitude, pivot_speed=pivot_speed,
                     source=f"vsj wrist network, {elastic} elastic model, parameter set "
                            f"{params.hash()[:12]}", elastic=elastic)


__all__ = ["AxisModel", "JointTable", "axis_model"]
