"""What the explorer runs: a setting of its controls, written as a scenario and a
parameter set, run the way ``vsj simulate`` runs them, and the numbers its views show.

A `Setting` is plain data (SI values and choices). `Explorer` turns it into a scenario
table (`scenario_text`) and a parameter set (`parameters`), and `Explorer.run` parses
that very text with `vsj.scenario.loads` and runs its one case with
`vsj.scenario.prepare_case`, as ``vsj simulate`` does: so the files `Explorer.export`
writes give ``vsj simulate`` the same run, bit for bit. Every number in the scenario
is written in SI with Python's shortest round-trip repr, and the parameter set with
`vsj.params.Parameters.to_toml` (exact text): reading them back gives the same floats.

The wrist is the one of report fig 4.15 with DC motors (the issue's "closed loop"):
the pivot is held at the stiffness setting ``q`` (``pivot_drive = "fixed"``), each
output motor runs a PID on its rotor angle towards the rotor angle the rigid kinematics
gives for the commanded end-effector angles (`vsj.control.wrist_kinematics`, the
collocated control of `vsj.control.wrist_controller`), at 1 kHz, and the time-stepper
integrates at 1 ms for every friction law (its cost does not depend on the law, so the
explorer's response time does not either).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from collections.abc import Mapping

import numpy as np
import tomli_w

from .. import scenario as scenarios
from ..control import MotorPID, mechanical_stiffness, motor_plants, wrist_kinematics
from ..errors import InputError
from ..friction import RUN_LAWS
from ..output import atomic_write, check_output_file
from ..params import SCHEMA, Parameters
from ..safety.run_report import report as safety_report
from ..springs import end_stop
from ..sweep.metrics import phase_lag
from ..units import format_quantity, to_si
from ..wrist import WristOptions, build_wrist

#: The references the outputs can follow: a step of theta_x, the circle of report fig
#: 4.15 (theta_x a cosine, theta_y a sine of one radius), a sine of theta_x.
REFERENCES = ("step", "circle", "sine")
#: The controllers: the collocated PID of `vsj.control.wrist_controller`, or without its
#: integral (a PD).
CONTROLLERS = ("PID", "PD")
#: The environments: free space, or a wall facing +theta_x at the tip of the link.
ENVIRONMENTS = ("none", "wall")
#: Elastic element models the explorer offers (`vsj.wrist.ELASTIC_MODELS`): the report's
#: final one (eq 4.5) and the potential form of the geometry (eq 3.1-3.7).
ELASTIC = ("exponential", "geometric")
#: The friction coefficients with a control of their own ("main": the largest levels of
#: table 4.1 and the sharpness every arctan element shares).
FRICTION_KEYS = ("transmission.stiction", "transmission.viscous", "planetary.mesh_stiction",
                 "differential.stiction", "friction.arctan_sharpness")

#: The controller's sample period [s] and the time-stepper's step [s]: 1 kHz as the
#: example controllers and the tracking-safety study run.
PERIOD = 1e-3
#: The link and tip of the wall's contact (examples/environment/wall.toml), and its
#: damping [N s/m^2] (Hunt-Crossley lambda with n = 1).
LINK, TIP_MASS, WALL_DAMPING = 0.1, 0.05, 4000.0
#: The stiffness setting the explorer opens at [m]: the middle one of the examples
#: (the TOML files of examples/environment).
DEFAULT_Q = -0.004
#: The step's start [s]: the loop settles at rest first.
STEP_START = 0.1
#: The crossover [rad/s] the default gains are designed for (`MotorPID.design`), the
#: tracking-safety study's.
BANDWIDTH = 2 * math.pi * 20.0


@dataclass(frozen=True)
class Control:
    """One numeric control: its ``key`` in `Setting` (or a parameter key), ``label``,
    SI ``unit`` and the ``display`` unit its field shows, the values it accepts
    ``[low, high]`` (SI; ``low_open``: low itself excluded) and the slider's span
    ``[start, end]`` (within them: typed values may go beyond the slider's span)."""

    key: str
    label: str
    unit: str
    display: str
    low: float
    high: float
    start: float
    end: float
    low_open: bool = False

    def allowed(self) -> str:
        """The accepted range in words, in the display unit."""
        low = format_quantity(self.low, self.display)
        high = "inf" if self.high == math.inf else format_quantity(self.high, self.display)
        return f"{'(' if self.low_open else '['}{low}, {high}]"

    def parse(self, text: str) -> float:
        """The SI value of ``text`` (a number with a unit, or a bare number in the
        display unit); `InputError` naming the control and its range otherwise."""
        text = str(text).strip()
        try:
            float(text)
            if self.display not in ("", "1"):
                text = f"{text} {self.display}"
        except ValueError:
            pass
        try:
            value = to_si(text, self.unit, where=self.label)
        except InputError as exc:
            raise InputError(f"{exc}; allowed: {self.allowed()}") from None
        return self.check(value)

    def check(self, value: float) -> float:
        """``value`` [SI] if the control accepts it; `InputError` with its range if not."""
        value = float(value)
        inside = (value > self.low if self.low_open else value >= self.low) \
            and value <= self.high
        if not inside:
            raise InputError(f"{self.label}: {format_quantity(value, self.display)} is "
                             f"outside the allowed {self.allowed()}")
        return value

    def show(self, value: float) -> str:
        """``value`` [SI] as the field writes it."""
        return format_quantity(value, self.display)


@dataclass(frozen=True)
class Setting:
    """Everything the explorer's controls set (SI units; angles in rad).

    ``q`` the pivot position [m] (the stiffness setting, eq 4.5: more negative is
    stiffer); ``reference`` one of `REFERENCES` with its ``amplitude`` [rad] (the step's
    height, the circle's radius, the sine's amplitude) and ``frequency`` [Hz] (circle,
    sine); ``duration`` [s]; ``friction`` a friction law (`vsj.friction.RUN_LAWS`) and
    ``coefficients`` the values of `FRICTION_KEYS` that differ from the parameter set
    [SI]; ``controller`` one of `CONTROLLERS` with gains ``k`` [V/rad], ``Ti`` [s],
    ``Td`` [s]; ``environment`` one of `ENVIRONMENTS` with the wall's ``wall_angle``
    [rad] and ``wall_stiffness`` [N/m]; ``elastic`` one of `ELASTIC`.
    """

    q: float
    k: float
    Ti: float
    Td: float
    reference: str = "circle"
    amplitude: float = 0.3
    frequency: float = 1.0
    duration: float = 2.0
    friction: str = "stiction"
    coefficients: Mapping[str, float] = field(default_factory=dict)
    controller: str = "PID"
    environment: str = "none"
    wall_angle: float = 0.2
    wall_stiffness: float = 2e4
    elastic: str = "exponential"

    def check(self) -> None:
        """`InputError` for a choice that is not one of its kind's."""
        for name, choices in (("reference", REFERENCES), ("controller", CONTROLLERS),
                              ("environment", ENVIRONMENTS), ("elastic", ELASTIC),
                              ("friction", RUN_LAWS)):
            if getattr(self, name) not in choices:
                raise InputError(f"{name} must be one of {', '.join(choices)}, got "
                                 f"{getattr(self, name)!r}")
        unknown = sorted(set(self.coefficients) - set(FRICTION_KEYS))
        if unknown:
            raise InputError(f"friction coefficient(s) {', '.join(unknown)}: the explorer "
                             f"sets {', '.join(FRICTION_KEYS)}")

    def fade_in(self) -> float:
        """The circle's and the sine's fade-in [s]: half a period, so that the motion
        starts from rest and a 2 s run at 1 Hz still has a full period after it."""
        return 0.5 / self.frequency


@dataclass(frozen=True)
class Ledger:
    """The energy ledger of a run, grouped for a bar chart: each ``(label, joules)``
    of work in, stored (its change) and dissipated, and the residual [J]."""

    rows: tuple[tuple[str, float], ...]
    residual: float
    relative_residual: float


@dataclass(frozen=True)
class View:
    """What the views show of one run of a setting.

    ``result`` the run (`vsj.simulate.Result`, with every signal of the catalogue);
    ``lag`` the tracking lag [s] of theta_x (None where the run is too short for it);
    ``rms_error`` [rad]; ``stiffness`` the end-effector's 2 x 2 stiffness [N m/rad] at
    the run's last state and ``stiffness_rest`` at rest (springs undeflected);
    ``end_stop`` the elastic element's end stop [rad] (None without one); ``ledger``;
    ``impacts`` per contact its events (`vsj.safety.run_report.report`, with the energy
    the contact took in); ``wall_time`` [s] of the run.
    """

    setting: Setting
    result: object
    lag: float | None
    rms_error: float
    stiffness: np.ndarray
    stiffness_rest: np.ndarray
    end_stop: float | None
    springs: tuple[str, ...]
    ledger: Ledger
    impacts: dict
    torque_constant: float


class Explorer:
    """The explorer's model side for one parameter set: its controls, the scenario of a
    setting, runs and exports. ``origin`` names the set in messages and files."""

    def __init__(self, params: Parameters):
        self.params = params
        wrist = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc",
                                                 elastic="exponential")).assemble()
        kin = wrist_kinematics(wrist)
        #: rotor angles of the output motors per end-effector angle (rigid kinematics)
        self.to_rotors = kin.to_rotors[:2, :2].copy()
        plant = motor_plants(wrist, kin)[0]
        self.design = MotorPID.design(plant, BANDWIDTH)
        self.q_min, self.q_max = kin.q_min, kin.q_max
        self.controls = self._controls()

    def _controls(self) -> dict[str, Control]:
        p = self.params
        pid = self.design
        out = {
            "q": Control("q", "stiffness setting q (pivot position)", "m", "cm",
                         self.q_min, self.q_max, self.q_min, self.q_max),
            "amplitude": Control("amplitude", "reference amplitude (step height, circle "
                                 "radius, sine amplitude)", "rad", "rad", 0.0, 1.0, 0.0, 1.0,
                                 low_open=True),
            "frequency": Control("frequency", "reference frequency (circle, sine)", "Hz",
                                 "Hz", 0.1, 5.0, 0.1, 5.0),
            "duration": Control("duration", "run length", "s", "s", 0.2, 20.0, 0.2, 10.0),
            "k": Control("k", "controller gain k", "V/rad", "V/rad", 0.0, 100.0, 0.0,
                         round(4 * pid.k, 1), low_open=True),
            # from 2 ms: the PID's anti-windup tracks in 0.9 Ti (Modelica's LimPID),
            # which must be longer than the controller's period
            "Ti": Control("Ti", "integral time Ti", "s", "ms", 2e-3, 10.0, 5e-3, 0.5),
            "Td": Control("Td", "derivative time Td", "s", "ms", 0.0, 0.1, 0.0, 0.02),
            "wall_angle": Control("wall_angle", "wall position (theta_x at touch)", "rad",
                                  "rad", 0.0, 1.0, 0.0, 1.0, low_open=True),
            "wall_stiffness": Control("wall_stiffness", "wall stiffness", "N/m", "N/m", 0.0,
                                      1e7, 1e3, 1e5, low_open=True),
        }
        for key in FRICTION_KEYS:
            section, name = key.split(".")
            spec = SCHEMA[section][name]
            value = p[key]
            high = math.inf if spec.maximum is None else spec.maximum
            low = -math.inf if spec.minimum is None else spec.minimum
            # the slider spans a few times the set's value (its schema has no upper
            # bound); a typed value may go up to the schema's
            end = min(high, 4.0 * value if value > 0 else 1.0)
            out[key] = Control(key, f"{spec.description} ({key})", spec.unit, spec.display,
                               low, high, max(low, 0.0), end, low_open=spec.strict)
        return out

    def default(self) -> Setting:
        """The setting the explorer opens with: the circle of fig 4.15 (0.3 rad, 1 Hz) for
        2 s with true stiction, in free space, at the middle stiffness setting of the
        examples (q = -0.4 cm, or the nearest the pivot's range allows), under the gains
        designed for a 20 Hz crossover (`MotorPID.design`)."""
        q = min(max(DEFAULT_Q, self.q_min), self.q_max)
        return Setting(q=q, k=self.design.k, Ti=self.design.Ti, Td=self.design.Td)

    # -- the scenario ------------------------------------------------------------------

    def scenario_table(self, s: Setting) -> dict:
        """The scenario of setting ``s`` as a TOML table (every number SI, exact)."""
        s.check()
        for name in ("q", "amplitude", "frequency", "duration", "k", "Ti", "Td",
                     "wall_angle", "wall_stiffness"):
            self.controls[name].check(getattr(s, name))
        for key, value in s.coefficients.items():
            self.controls[key].check(value)

        def si(value: float, unit: str) -> str:
            return f"{float(value)!r} {unit}"

        ref = {"kind": "sine", "amplitude": si(s.amplitude, "rad"),
               "frequency": si(s.frequency, "Hz"), "fade_in": si(s.fade_in(), "s")}
        if s.reference == "step":
            refs = {"theta_x": {"kind": "step", "height": si(s.amplitude, "rad"),
                                "start": si(STEP_START, "s")},
                    "theta_y": {"kind": "constant", "value": "0.0 rad"}}
        elif s.reference == "circle":  # report fig 4.15's circle: theta_x leads by 90 deg
            refs = {"theta_x": {**ref, "phase": "90.0 deg"}, "theta_y": dict(ref)}
        else:
            refs = {"theta_x": ref, "theta_y": {"kind": "constant", "value": "0.0 rad"}}
        pids = []
        for j in range(2):
            pid = {"name": f"u{j + 1}",
                   "setpoint": {"theta_x": float(self.to_rotors[j, 0]),
                                "theta_y": float(self.to_rotors[j, 1])},
                   "measurement": f"motor_{j + 1}.rotor", "k": si(s.k, "V/rad"),
                   "Td": si(s.Td, "s")}
            if s.controller == "PID":
                pid["Ti"] = si(s.Ti, "s")
            pids.append(pid)
        table = {
            "name": "explore",
            "description": (f"vsj explore: {s.reference} reference, q = {100 * s.q:.3g} cm, "
                            f"{s.friction} friction, {s.controller} on the motors, "
                            f"environment {s.environment}"),
            "network": "wrist", "duration": si(s.duration, "s"),
            "model": {"motors": "dc", "pivot_drive": "fixed", "fixed_q": si(s.q, "m"),
                      "elastic": s.elastic},
            "solver": {"friction": s.friction, "method": "timestep",
                       "step": si(PERIOD, "s"), "output_step": si(PERIOD, "s")},
            "controller": {
                "period": si(PERIOD, "s"), "references": refs,
                "sensors": [{"signal": "motor_1.rotor"}, {"signal": "motor_2.rotor"}],
                "pid": pids,
                "actuators": [{"channel": "voltage_1", "command": "u1"},
                              {"channel": "voltage_2", "command": "u2"}]},
        }
        if s.environment == "wall":
            table["environment"] = {
                "link": si(LINK, "m"), "tip_mass": si(TIP_MASS, "kg"),
                "walls": [{"name": "wall", "angle": si(s.wall_angle, "rad"),
                           "direction": "+x", "stiffness": si(s.wall_stiffness, "N/m"),
                           "damping": si(WALL_DAMPING, "N s/m^2")}]}
        return table

    def scenario_text(self, s: Setting) -> str:
        """The scenario file of setting ``s`` (what `export` writes and `run` parses)."""
        head = ("# written by vsj explore: run it with\n"
                "#   vsj simulate scenario.toml --params params.toml\n"
                "# numbers in SI, each the exact value the explorer ran\n")
        return head + tomli_w.dumps(self.scenario_table(s))

    def parameters(self, s: Setting) -> Parameters:
        """The parameter set of setting ``s``: this explorer's with ``s.coefficients``."""
        if not s.coefficients:
            return self.params
        return self.params.with_overrides(
            {k: f"{float(v)!r} {SCHEMA[k.split('.')[0]][k.split('.')[1]].unit}"
             for k, v in s.coefficients.items()},
            origin=self.params.origin, source="set in vsj explore")

    # -- running ----------------------------------------------------------------------

    def prepare(self, s: Setting):
        """The setting's case, prepared as ``vsj simulate`` prepares it."""
        scen = scenarios.loads(self.scenario_text(s), "vsj explore")
        return scenarios.prepare_case(scen, scen.cases[0], self.parameters(s))

    def run(self, s: Setting) -> View:
        """Run setting ``s`` and compute what the views show. `InputError` if the setting
        is refused or the run fails (with the engine's message)."""
        prepared = self.prepare(s)
        result = prepared.run(ports=False)
        if not result.success:
            raise InputError(f"the run failed: {result.message}")
        structure = prepared.structure
        springs = tuple(sp.name for sp in structure.springs
                        if f"spring.{sp.name}.deflection" in result.signals)
        last = {name: float(result[f"spring.{name}.deflection"][-1]) for name in springs}
        stops = [_end_stop(sp) for sp in structure.springs]
        stop = next((x for x in stops if x is not None), None)
        return View(
            setting=s, result=result, lag=tracking_lag(s, result),
            rms_error=float(np.sqrt(np.mean((result["theta_x"] - result["control.theta_x"]) ** 2
                                            + (result["theta_y"]
                                               - result["control.theta_y"]) ** 2))),
            stiffness=mechanical_stiffness(structure, s.q, deflections=last),
            stiffness_rest=mechanical_stiffness(structure, s.q),
            end_stop=stop, springs=springs, ledger=ledger_rows(result.ledger),
            impacts=impact_figures(result, structure),
            torque_constant=float(self.params["motor.torque_constant"]))

    def export(self, s: Setting, directory: str | Path) -> tuple[Path, Path]:
        """Write the setting as ``scenario.toml`` and ``params.toml`` into ``directory``
        (made if missing); ``vsj simulate scenario.toml --params params.toml`` runs the
        same run. Returns the two paths. `OutputError` (before anything is written) where
        either name holds a file that vsj did not write: a user's own is never replaced."""
        directory = Path(directory)
        paths = directory / "scenario.toml", directory / "params.toml"
        for path in paths:
            check_output_file(path, "the export to", forceable=False)
        directory.mkdir(parents=True, exist_ok=True)
        text = self.scenario_text(s)
        with atomic_write(paths[0], "w") as handle:
            handle.write(text)
        with atomic_write(paths[1], "w") as handle:
            handle.write("# written by vsj explore: the parameter set of the exported "
                         "setting\n" + self.parameters(s).to_toml())
        return paths

    def with_params(self, params: Parameters, s: Setting) -> tuple["Explorer", Setting]:
        """An explorer of another parameter set and ``s`` moved into its controls' ranges
        (q clipped to the new pivot range; the friction coefficients of the new set)."""
        other = Explorer(params)
        q = min(max(s.q, other.q_min), other.q_max)
        return other, replace(s, q=q, coefficients={})


def _end_stop(spring) -> float | None:
    stop = end_stop(spring.law, spring.parameters)
    return None if stop is None else stop[0]


def tracking_lag(s: Setting, result) -> float | None:
    """The time [s] theta_x lags its reference: for the circle and the sine their phase
    difference at the reference's frequency over the last full period after the fade-in
    (`vsj.sweep.metrics.phase_lag`, as the tracking-safety study measures it); for the
    step the delay from the step to theta_x's first reaching half its height. None if the
    run is too short for it (or theta_x never reaches half the step)."""
    t, x, ref = result.time, result["theta_x"], result["control.theta_x"]
    if s.reference == "step":
        after = np.flatnonzero((t >= STEP_START) & (x >= 0.5 * s.amplitude))
        return float(t[after[0]] - STEP_START) if len(after) else None
    period = 1.0 / s.frequency
    if t[-1] < s.fade_in() + period - 1e-12:
        return None
    window = t >= t[-1] - period + 0.5 * PERIOD
    return phase_lag(t[window], x[window], ref[window], s.frequency)


def ledger_rows(ledger: Mapping) -> Ledger:
    """The ledger of a run grouped for the view: work in by source, the change of each
    stored energy, dissipation by kind (friction, winding resistance, contacts)."""
    rows = [(f"in: {name}", float(v)) for name, v in ledger["work_in"].items() if v != 0.0]
    rows += [(f"stored: {name}", float(v)) for name, v in ledger["stored_change"].items()]
    kinds: dict[str, float] = {}
    for name, v in ledger["dissipated"].items():
        kind = name.split(" ", 1)[0]
        kinds[kind] = kinds.get(kind, 0.0) + float(v)
    rows += [(f"dissipated: {kind}", v) for kind, v in kinds.items()]
    rows += [(f"other: {name}", float(v)) for name, v in ledger["nonconservative"].items()]
    return Ledger(tuple(rows), float(ledger["residual"]), float(ledger["relative_residual"]))


def impact_figures(result, structure) -> dict:
    """Per contact the events of `vsj.safety.run_report.report` (peak force, impulse,
    ...), each with ``energy_in``: the most energy the contact took in over the event
    [J], the peak of the integral of its power (stored in the wall, or dissipated by its
    damping). For a wall, which has no body to transfer energy to, this is the energy
    transferred."""
    figures = safety_report(result, structure)
    t = result.time
    for name, events in figures.items():
        power = result[f"contact.{name}.power"]
        work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
        for ev in events:
            span = (t >= ev["start"]) & (t <= ev["end"])
            base = float(work[np.flatnonzero(span)[0]]) if span.any() else 0.0
            ev["energy_in"] = float(np.max(work[span]) - base) if span.any() else 0.0
    return figures


__all__ = ["CONTROLLERS", "Control", "ELASTIC", "ENVIRONMENTS", "Explorer", "FRICTION_KEYS",
           "Ledger", "REFERENCES", "Setting", "View", "impact_figures", "ledger_rows",
           "tracking_lag"]
