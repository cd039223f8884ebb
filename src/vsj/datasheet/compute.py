"""The datasheet's numbers: plain data in SI units (`compute`)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.integrate import cumulative_trapezoid

from .. import __version__
from .. import linear as linear_models
from ..characteristics import pretension_loss, spring_extensions, stiffness
from ..components import PivotMechanism
from ..errors import InputError, SimulationError
from ..inputs import Constant
from ..network import Network
from ..progress import progress
from ..simulate import InitialState, SimulationOptions, simulate
from ..springs import GEOMETRIC, GEOMETRIC_REPORT, evaluate
from ..wrist import WristOptions, build_wrist, elastic_element, motor

CURVE_POINTS = 241
#: The SI unit of each number of the tables (``per_q`` and its ``modes``, the
#: ``torque_deflection`` curves, the ``frequency_response`` grid), written beside them
#: as ``units``: frequencies are in rad/s there, the ratings give them in Hz.
UNITS = {"q": "m", "ring_stiffness": "N m/rad", "output_stiffness": "N m/rad",
         "output_stiffness_linear_model": "N m/rad", "peak_torque": "N m",
         "peak_torque_deflection": "rad", "max_deflection": "rad", "max_energy": "J",
         "pretension_loss_deflection": "rad", "natural_frequencies": "rad/s",
         "frequency": "rad/s", "damping": "1", "position_bandwidth": "rad/s",
         "deflection": "rad", "torque": "N m", "stiffness": "N m/rad", "energy": "J",
         "omega": "rad/s"}
#: Frequency grid of the Bode plots [rad/s].
BODE_OMEGA = np.logspace(-1, 3.5, 300)
#: Friction treatment of the linear models (see `vsj.linear.FRICTION_TREATMENTS`).
DEFAULT_FRICTION = "linearised"
#: Most pivot positions in the tables: a point every 0.03 mm of the prototype's 3 cm
#: range, finer than its pivot can be set; each takes a few linearisations (a fraction
#: of a second), so the most takes minutes, with a progress bar.
MAX_Q_POINTS = 1001


def _kinematics(params, elastic: str):
    """The wrist's static map with the motors held: ``theta = T x`` (x: ring angles).

    Returns ``(T, M, element)``: ``T`` (2 x 2), the mass matrix of the ring
    angles and one elastic element (both are identical, report section 3.1).
    """
    structure = build_wrist(params, WristOptions(elastic=elastic, pivot_drive="fixed",
                                                 fixed_q=0.0)).assemble()
    if structure.free != ("vsm_1.ring", "vsm_2.ring"):
        raise InputError(f"datasheet: expected the ring angles as the only free coordinates, "
                         f"got {', '.join(structure.free)} (a series compliance adds states; "
                         "set transmission.series_compliance_* to 0)")
    T = np.array([structure.rows("diff.theta_x")[0], structure.rows("diff.theta_y")[0]])
    return T, structure.mass_matrix(), elastic_element("vsm", params, elastic)


def output_kinematics(params, elastic: str = "geometric") -> tuple[np.ndarray, np.ndarray]:
    """``(T, M)`` of `_kinematics`: the static map from the ring angles to the outputs
    with the motors held, and the mass matrix of the ring angles. They depend on no
    value of ``[elastic_element]``, so a caller that varies only those (`vsj.design`)
    computes them once and hands them to `Statics`."""
    T, M, _ = _kinematics(params, elastic)
    return T, M


def _output_curve(element, T, q: float, theta: np.ndarray) -> dict[str, np.ndarray]:
    """Torque, tangent stiffness and stored energy about theta_x at deflections ``theta``."""
    c = np.linalg.solve(T, np.array([1.0, 0.0]))  # ring deflection per unit theta_x
    torque = np.zeros_like(theta)
    stiffness = np.zeros_like(theta)
    energy = np.zeros_like(theta)
    for ci in c:
        tau, k, V, _ = evaluate(element.law, element.parameters, ci * theta, q)
        V0 = evaluate(element.law, element.parameters, 0.0, q)[2][0]
        torque += -tau * ci          # restoring torque the end-effector must supply
        stiffness += k * ci * ci
        energy += V - V0
    return {"deflection": theta, "torque": torque, "stiffness": stiffness, "energy": energy,
            "ring_per_output": c}


#: What limits the deflection at a stiffness setting (`deflection_limit`).
END_STOP = "end stop"
PEAK_SLACK = "torque peak: a spring goes slack"
PEAK_GEOMETRY = "torque peak: the lever's geometry"


def deflection_limit(element, ring_per_output, q: float, theta: np.ndarray,
                     torque: np.ndarray) -> tuple[int, str]:
    """Index into ``theta`` of the largest deflection the output holds at ``q`` [m],
    and the limit that decides it (`END_STOP`, `PEAK_SLACK` or `PEAK_GEOMETRY`).

    ``theta`` [rad] runs from 0 to the deflection where a ring reaches its end
    stop, ``torque`` [N m] is the restoring torque there and ``ring_per_output``
    the ring deflections per unit ``theta`` (one per elastic ``element``).
    Past a peak of the restoring ``torque`` the tangent stiffness is negative: a
    load above the peak drives the output onto the stop, so no deflection beyond
    the peak is held. The peak is caused by a spring going slack when one of
    them changes between taut and slack within a grid step of it; otherwise by the
    lever's geometry (the springs' lever arm shrinks faster than their force grows).
    """
    peak = int(np.argmax(torque))
    if peak == len(theta) - 1:
        return peak, END_STOP

    if element.law in (GEOMETRIC, GEOMETRIC_REPORT):
        lo, hi = theta[max(peak - 1, 0)], theta[peak + 1]
        for ci in np.abs(ring_per_output):
            before, after = (np.sign(spring_extensions(element.parameters, q, ci * t))
                             for t in (lo, hi))
            if np.any(before != after):
                return peak, PEAK_SLACK
    return peak, PEAK_GEOMETRY


def _stiffness_change(params, q_from: float, q_to: float) -> dict:
    """Drive the pivot from ``q_from`` to ``q_to`` at the supply voltage (DC motor model).

    A network of the stiffness motor and the pivot mechanism alone: the springs
    do not back-drive the pivot (report section 3.1), so the rest of the wrist
    does not load it. Returns the time to reach ``q_to``, the electric energy
    drawn until then and the trajectory.
    """
    pv, mo = params.pivot, params.motor
    net = Network("pivot-drive")
    # the whole reach, not the set's pivot range: the drive runs on past q_to
    net.add(motor("motor_s", params, "dc", "s"),
            PivotMechanism.from_parameters("pivot", params, q_min=None, q_max=None))
    net.connect("motor_s.flange", "pivot.input")
    structure = net.assemble()
    start = math.asin(q_from / pv.amplitude)
    end = math.asin(q_to / pv.amplitude)
    voltage = math.copysign(mo.voltage_limit, (end - start) * pv.ratio * mo.gear_ratio)
    no_load = mo.voltage_limit / mo.torque_constant  # rotor speed [rad/s]
    travel = abs(end - start) * abs(pv.ratio * mo.gear_ratio)
    duration = 2.0 * travel / no_load + 0.5
    result = simulate(structure, {"voltage_s": Constant(voltage)}, duration,
                      initial=InitialState(q=q_from),
                      options=SimulationOptions(rtol=1e-7, atol=1e-9, output_step=1e-3),
                      ports=False)
    if not result.success:
        raise SimulationError(f"datasheet: stiffness change {q_from} -> {q_to} m: "
                              f"{result.message}")
    q = result["q"]
    passed = np.flatnonzero((q - q_to) * np.sign(q_to - q_from) >= 0.0)
    if passed.size == 0:
        raise SimulationError(f"datasheet: the pivot did not reach q = {q_to} m within "
                              f"{duration:.3g} s at {voltage:g} V")

    k = int(passed[0])
    t = result.time
    t_cross = float(t[0]) if k == 0 else float(
        t[k - 1] + (q_to - q[k - 1]) / (q[k] - q[k - 1]) * (t[k] - t[k - 1]))
    power = result["motor.motor_s.power"]
    energy = float(np.interp(t_cross, t, cumulative_trapezoid(power, t, initial=0.0)))
    # every sample of the electrical start-up (0.1 s), every tenth after it
    end = min(k + 50, len(t))
    keep = np.union1d(np.arange(min(100, end)), np.arange(0, end, 10))
    return {"from_q": q_from, "to_q": q_to, "voltage": voltage, "time": float(t_cross),
            "electric_energy": energy,
            "trajectory": {"time": t[keep], "q": q[keep], "power": power[keep]}}


class Statics:
    """The elastic elements' static quantities about theta_x with both motors held, for
    one parameter set and elastic model: what the datasheet's stiffness, deflection and
    energy ratings are made of, and what `vsj.design` optimises.

    The deflections ``deflections`` [rad] run from 0 to the output deflection at which a
    ring reaches its end stop (`CURVE_POINTS` of them). ``kinematics``, if given, is the
    ``(T, M)`` of `output_kinematics`.
    """

    def __init__(self, params, elastic: str = "geometric", kinematics=None):
        if kinematics is None:
            T, M, element = _kinematics(params, elastic)
        else:
            (T, M), element = kinematics, elastic_element("vsm", params, elastic)
        self.T, self.mass, self.element, self.elastic = T, M, element, elastic
        self.Tinv = np.linalg.inv(T)
        #: ring deflection per unit theta_x, one per elastic element
        self.ring_per_output = self.Tinv @ np.array([1.0, 0.0])
        self.end_stop = params.elastic_element.end_stop
        self.deflections = np.linspace(
            0.0, self.end_stop / float(np.max(np.abs(self.ring_per_output))), CURVE_POINTS)
        self._curves: dict[float, dict] = {}
        #: ring deflection per unit theta_x as `_output_curve` solves for it
        self._solved = np.linalg.solve(T, np.array([1.0, 0.0]))

    def curve(self, q: float) -> dict[str, np.ndarray]:
        """Torque [N m], tangent stiffness [N m/rad] and stored energy [J] about theta_x
        at ``deflections``, with the pivot at ``q`` [m]."""
        if q not in self._curves:
            self._curves[q] = _output_curve(self.element, self.T, q, self.deflections)
        return self._curves[q]

    def output_stiffness(self, q: float) -> float:
        """Stiffness [N m/rad] about theta_x at zero deflection, pivot at ``q`` [m]: the
        first point of `curve`, computed alone when the curve is not (with the same
        operations in the same order, so it is the same number)."""
        if q in self._curves:
            return float(self._curves[q]["stiffness"][0])
        total = 0.0  # `_output_curve`'s sum at zero deflection, term by term alike
        for ci in self._solved:
            k = evaluate(self.element.law, self.element.parameters, ci * 0.0, q)[1][0]
            total += k * ci * ci
        return float(total)

    def at(self, q: float) -> dict:
        """At pivot position ``q`` [m]: the ring's and the output's stiffness at zero
        deflection, the largest deflection held (`deflection_limit`) with the limit
        that decides it, the torque there and the largest energy stored up to it."""
        curve = self.curve(q)
        peak, limit = deflection_limit(self.element, self.ring_per_output, q,
                                       self.deflections, curve["torque"])
        return {"ring_stiffness": stiffness(self.element.law, self.element.parameters, q),
                "output_stiffness": float(curve["stiffness"][0]),
                "peak_torque": float(curve["torque"][peak]),
                "max_deflection": float(self.deflections[peak]),
                "max_deflection_limit": limit,
                "max_energy": float(np.max(curve["energy"][:peak + 1]))}

    def pretension_loss_deflection(self, q: float) -> float:
        """Smallest output deflection [rad] at which a spring goes slack with the pivot
        at ``q`` [m] (`vsj.characteristics.pretension_loss`, searched up to the end
        stop), ``inf`` if none does or the model has no springs."""
        if not self.elastic.startswith("geometric"):
            return math.inf
        slack = pretension_loss(self.element.parameters, q, self.end_stop)
        return float(slack / np.max(np.abs(self.ring_per_output)))


def check_q_points(q_points, option: str = "q_points") -> None:
    """`InputError` unless ``q_points`` (named ``option``) is an integer in
    2..`MAX_Q_POINTS`."""
    if isinstance(q_points, bool) or not (isinstance(q_points, int)
                                          and 2 <= q_points <= MAX_Q_POINTS):
        raise InputError(f"datasheet: {option} must be an integer in 2..{MAX_Q_POINTS}, got "
                         f"{q_points!r}")


def compute(params, *, q_points: int = 9, curve_qs: Sequence[float] | None = None,
            friction: str = DEFAULT_FRICTION, elastic: str = "geometric",
            option: str = "q_points") -> dict:
    """Every datasheet quantity as plain data (SI units; see the module docstring), with a
    progress bar over the pivot positions on a terminal. ``option`` names ``q_points`` in
    messages (the command's ``--points``)."""
    check_q_points(q_points, option)
    q_min, q_max = params.pivot.q_min, params.pivot.q_max
    qs = np.linspace(q_max, q_min, q_points)
    curve_qs = list(np.linspace(q_max, q_min, 5) if curve_qs is None else curve_qs)
    for q in curve_qs:
        if not q_min - 1e-12 <= q <= q_max + 1e-12:
            raise InputError(f"datasheet: curve pivot position {q} m is outside the pivot "
                             f"range {q_min} ... {q_max} m")
    statics = Statics(params, elastic)
    T, M, element = statics.T, statics.mass, statics.element
    Tinv = statics.Tinv
    end_stop = statics.end_stop
    c = statics.ring_per_output
    output_inertia = Tinv.T @ M @ Tinv

    per_q = []
    models = {}
    for q in progress(qs, desc="datasheet", unit="q"):
        static = statics.at(float(q))
        lin = linear_models.linearize(params, float(q), friction=friction,
                                      wrist_options=_options(elastic))
        models[float(q)] = lin
        modes = linear_models.modes(lin)
        per_q.append({
            "q": float(q),
            "ring_stiffness": static["ring_stiffness"],
            "output_stiffness": static["output_stiffness"],
            "output_stiffness_linear_model": float(
                linear_models.output_stiffness(lin)[0, 0]),
            "peak_torque": static["peak_torque"],
            "peak_torque_deflection": static["max_deflection"],
            "max_deflection": static["max_deflection"],
            "max_deflection_limit": static["max_deflection_limit"],
            "max_energy": static["max_energy"],
            "pretension_loss_deflection": statics.pretension_loss_deflection(float(q)),
            "natural_frequencies": linear_models.natural_frequencies(lin).tolist(),
            "modes": [{"frequency": m["frequency"], "damping": m["damping"]} for m in modes],
            "modes_viscous": [{"frequency": m["frequency"], "damping": m["damping"]} for m in
                              linear_models.modes(linear_models.linearize(
                                  params, float(q), friction="viscous",
                                  wrist_options=_options(elastic)))],
            "position_bandwidth": linear_models.bandwidth(
                lin, "theta_x", {"motor_1": 1.0, "motor_2": 1.0}, input_angle=True),
        })

    curves = []
    theta = statics.deflections
    for q in curve_qs:
        curve = _output_curve(element, T, float(q), theta)
        held, limit = deflection_limit(element, c, float(q), theta, curve["torque"])
        curves.append({"q": float(q), "max_deflection": float(theta[held]),
                       "max_deflection_limit": limit, "deflection": theta.tolist(),
                       "torque": curve["torque"].tolist(),
                       "stiffness": curve["stiffness"].tolist(),
                       "energy": curve["energy"].tolist()})

    bode = {"omega": BODE_OMEGA.tolist(), "compliance": [], "motor_to_output": []}
    for q in curve_qs:
        lin = models.get(float(q)) or linear_models.linearize(params, float(q),
                                                              friction=friction,
                                                              wrist_options=_options(elastic))
        h = linear_models.transfer(lin, "theta_x", "tau_x", BODE_OMEGA)
        g = linear_models.transfer(lin, "theta_x", {"motor_1": 1.0, "motor_2": 1.0},
                                   BODE_OMEGA, input_angle=True)
        for key, resp in (("compliance", h), ("motor_to_output", g)):
            bode[key].append({"q": float(q), "magnitude": np.abs(resp).tolist(),
                              "phase": np.unwrap(np.angle(resp)).tolist()})
    kinematic_ratio = abs(linear_models.transfer(
        models[float(qs[0])], "theta_x", {"motor_1": 1.0, "motor_2": 1.0}, [1e-6],
        input_angle=True)[0])

    stiffen = _stiffness_change(params, q_max, q_min)
    soften = _stiffness_change(params, q_min, q_max)
    k_out = [row["output_stiffness"] for row in per_q]
    strongest = max(per_q, key=lambda r: r["peak_torque"])
    richest = max(per_q, key=lambda r: r["max_energy"])
    widest = max(per_q, key=lambda r: r["max_deflection"])
    narrowest = min(per_q, key=lambda r: r["max_deflection"])
    ratings = {
        "output_stiffness_min": _rating(min(k_out), "N m/rad", f"theta_x at q = "
                                        f"{q_max * 100:.3g} cm, zero deflection"),
        "output_stiffness_max": _rating(max(k_out), "N m/rad", f"theta_x at q = "
                                        f"{q_min * 100:.3g} cm, zero deflection"),
        "stiffness_ratio": _rating(max(k_out) / min(k_out), "1", "max / min"),
        "ring_stiffness_min": _rating(min(r["ring_stiffness"] for r in per_q), "N m/rad",
                                      "one elastic element, at the ring"),
        "ring_stiffness_max": _rating(max(r["ring_stiffness"] for r in per_q), "N m/rad",
                                      "one elastic element, at the ring"),
        "max_deflection_max": _rating(widest["max_deflection"], "rad",
                                      _deflection_note(widest, end_stop)),
        "max_deflection_min": _rating(narrowest["max_deflection"], "rad",
                                      _deflection_note(narrowest, end_stop)),
        "peak_torque": _rating(strongest["peak_torque"], "N m",
                               f"largest elastic torque about theta_x, at the maximum "
                               f"deflection (q = {strongest['q'] * 100:.3g} cm, at "
                               f"{strongest['peak_torque_deflection']:.3g} rad, "
                               f"{strongest['max_deflection_limit']})"),
        "max_energy": _rating(richest["max_energy"], "J",
                              f"largest elastic energy up to the maximum deflection (q = "
                              f"{richest['q'] * 100:.3g} cm)"),
        "stiffening_time": _rating(stiffen["time"], "s", f"q {q_max * 100:.3g} -> "
                                   f"{q_min * 100:.3g} cm at {stiffen['voltage']:g} V"),
        "softening_time": _rating(soften["time"], "s", f"q {q_min * 100:.3g} -> "
                                  f"{q_max * 100:.3g} cm at {soften['voltage']:g} V"),
        "stiffening_energy": _rating(stiffen["electric_energy"], "J",
                                     "electric energy drawn by the stiffness motor"),
        "softening_energy": _rating(soften["electric_energy"], "J",
                                    "electric energy drawn by the stiffness motor"),
        "holding_power": _rating(0.0, "W", "the pivot is not back-driven: holding a "
                                 "stiffness costs nothing"),
        "output_inertia_x": _rating(float(output_inertia[0, 0]), "kg m^2",
                                    "about theta_x, motors held"),
        "output_inertia_y": _rating(float(output_inertia[1, 1]), "kg m^2",
                                    "about theta_y, motors held"),
        "natural_frequency_min": _rating(min(r["natural_frequencies"][0] for r in per_q)
                                         / (2 * math.pi), "Hz", "undamped, softest q"),
        "natural_frequency_max": _rating(max(r["natural_frequencies"][0] for r in per_q)
                                         / (2 * math.pi), "Hz", "undamped, stiffest q"),
        "position_bandwidth_min": _rating(min(r["position_bandwidth"] for r in per_q)
                                          / (2 * math.pi), "Hz",
                                          "-3 dB, theta_x per motor angle, softest q"),
        "position_bandwidth_max": _rating(max(r["position_bandwidth"] for r in per_q)
                                          / (2 * math.pi), "Hz",
                                          "-3 dB, theta_x per motor angle, stiffest q"),
        "motor_to_output_ratio": _rating(kinematic_ratio, "1",
                                         "theta_x per motor angle (both motors), static"),
    }
    return {
        "title": "VSA datasheet: 2-DOF variable stiffness wrist (model)",
        "vsj_version": __version__,
        "parameters": {"origin": params.origin, "hash": params.hash(),
                       "name": params.meta.get("name", "")},
        "elastic_model": elastic,
        "friction": {"treatment": friction,
                     "description": linear_models.FRICTION_TREATMENTS[friction]},
        "notes": _notes(params, elastic, friction, per_q, end_stop),
        "ratings": ratings,
        "units": dict(UNITS),
        "per_q": per_q,
        "torque_deflection": curves,
        "frequency_response": bode,
        "stiffness_change": {"stiffening": _plain(stiffen), "softening": _plain(soften)},
        "output_inertia": output_inertia.tolist(),
        "ring_per_output": c.tolist(),
    }


def _options(elastic: str):
    return WristOptions(elastic=elastic)


def _deflection_note(row: dict, end_stop: float) -> str:
    limit = row["max_deflection_limit"]
    return (f"theta_x at q = {row['q'] * 100:.3g} cm, decided by the "
            + (f"end stop ({end_stop:g} rad at a ring)" if limit == END_STOP else limit))


def _rating(value: float, unit: str, note: str) -> dict:
    return {"value": float(value), "unit": unit, "note": note}


def _plain(change: dict) -> dict:
    out = dict(change)
    out["trajectory"] = {k: np.asarray(v).tolist() for k, v in change["trajectory"].items()}
    return out


def _notes(params, elastic: str, friction: str, per_q: list[dict],
           end_stop: float) -> list[str]:
    by_limit: dict[str, list[float]] = {}
    for row in per_q:
        by_limit.setdefault(row["max_deflection_limit"], []).append(row["q"] * 100)
    decided = "; ".join(f"{limit} at q = " + ", ".join(f"{q:.3g}" for q in qs) + " cm"
                        for limit, qs in by_limit.items())
    return [
        "Computed from the model, not measured. Parameter set: "
        f"{params.meta.get('name', params.origin)} (hash {params.hash()[:12]}).",
        f"Elastic element: the {elastic} model; the geometric model's spring geometry is "
        "calibrated to the report's three measured stiffnesses (fig 4.10-4.12).",
        "Output quantities are about theta_x with both primary motors held (ideal "
        "position control): both elastic elements deflect equally.",
        "Maximum deflection, at each setting, is the smaller of two limits: where a ring "
        f"reaches its end stop ({end_stop:g} rad), and where the restoring torque peaks "
        "(past the peak the tangent stiffness is negative: a larger load drives the output "
        "onto the stop, so no deflection beyond it is held). Here it is decided by the "
        f"{decided}. Peak torque and maximum energy are the values at it (the hard stop "
        "excluded).",
        "Stiffness-change time and energy: the pivot mechanism driven by the DC motor model "
        "at the supply voltage, from rest; the motor and pivot-drive parameters are "
        "estimates (the report leaves them uncharacterised).",
        f"Dynamics: linear models with friction {friction} "
        f"({linear_models.FRICTION_TREATMENTS[friction]}). The linearised arctan friction "
        "damps small motions strongly; large motions see less damping.",
        "Position bandwidth: -3 dB frequency of theta_x per motor angle with both motors "
        "moving together.",
    ]
