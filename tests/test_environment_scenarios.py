"""The environment in scenario files (issue 34): the [environment] table read with its
units into a `vsj.environment.Environment` at the wrist's end-effector, run by `vsj
simulate` with its contact signals, changed by cases; every bad input refused with the
file and the key path (exit code 2); the examples in examples/environment run and show
what their comments say; the ledger closes with contacts in closed loop with stiction."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from scenario_checks import fails, write
from vsj import scenario as scenarios
from vsj.cli import main
from vsj.environment import Body, Wall
from vsj.errors import InputError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "environment"
#: Relative residual the time-stepper's ledger may leave per step where every element
#: is booked exactly over a step (linear or exponential springs, contacts): each step
#: adds about thirty booked terms (the elements' works and losses, the contacts' and
#: springs' stored parts), each rounded to an ulp (2.2e-16) of an accumulator that may be
#: a few times the energy in play, and compilers order (and fuse) the sums differently:
#: 64 ulps a step.
LEDGER_ROUNDOFF_PER_STEP = 64 * 2.2e-16

#: A short closed loop against a wall: PDs on the output motors' rotor angles drive
#: theta_x from 0 towards 0.2 rad; the wall is at 0.1 rad; the pivot is fixed.
BASE = """name = "env"
network = "wrist"
duration = "0.3 s"
[model]
motors = "dc"
pivot_drive = "fixed"
fixed_q = "-0.4 cm"
[solver]
friction = "stiction"
method = "timestep"
[environment]
link = "10 cm"
tip_mass = "50 g"
[[environment.walls]]
name = "wall"
angle = "0.1 rad"
stiffness = "2e4 N/m"
damping = "4000 N s/m^2"
[controller]
rate = "1 kHz"
[controller.references.theta_x]
kind = "step"
height = "0.2 rad"
start = "20 ms"
[controller.references.theta_y]
kind = "constant"
value = "0 rad"
[[controller.sensors]]
signal = "motor_1.rotor"
[[controller.sensors]]
signal = "motor_2.rotor"
[[controller.pid]]
name = "u1"
setpoint = { theta_x = 28.875, theta_y = 28.875 }
measurement = "motor_1.rotor"
k = "2.98 V/rad"
Td = "4.8 ms"
[[controller.pid]]
name = "u2"
setpoint = { theta_x = 28.875, theta_y = -28.875 }
measurement = "motor_2.rotor"
k = "2.98 V/rad"
Td = "4.8 ms"
[[controller.actuators]]
channel = "voltage_1"
command = "u1"
[[controller.actuators]]
channel = "voltage_2"
command = "u2"
"""

WALL = """[[environment.walls]]
name = "wall"
angle = "0.1 rad"
stiffness = "2e4 N/m"
damping = "4000 N s/m^2"
"""

#: A hand surrogate facing -x (touched where theta_x reaches -0.1 rad).
BODY = """[[environment.bodies]]
name = "hand"
angle = "0.1 rad"
direction = "-x"
mass = "0.6 kg"
stiffness = "75 N/mm"
support_stiffness = "100 N/m"
support_damping = "2 N s/m"
"""


def edit(old: str, new: str, text: str = BASE) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def with_wall(lines: str, text: str = BASE) -> str:
    """``text`` with ``lines`` in place of the wall's keys after its name."""
    return edit(WALL, '[[environment.walls]]\nname = "wall"\n' + lines, text)


def environment(text: str):
    return scenarios.loads(text, "env.toml").cases[0].environment


def run(text: str, origin: str = "env.toml", **kwargs):
    return scenarios.run(scenarios.loads(text, origin), **kwargs)


# ---------------------------------------------------------------- reading and running


def test_the_table_becomes_the_environment_in_si():
    """Every value in SI with its unit's factor: the link in cm, the tip in g, angles in
    degrees, a stiffness in N/mm, a named direction, and a body's support."""
    env = environment(edit(WALL, WALL.replace('"0.1 rad"', '"6 deg"')
                           .replace('"2e4 N/m"', '"20 N/mm"') + BODY))
    assert env.link == 0.1 and env.tip_mass == 0.05
    wall, hand = env.contacts
    assert isinstance(wall, Wall) and isinstance(hand, Body)
    # the units' exact factors, each rounded once (vsj.units)
    assert wall.angle == pytest.approx(6 * math.pi / 180, rel=1e-15)
    assert (wall.stiffness, wall.exponent, wall.damping, wall.direction) == (2e4, 1.0, 4e3, 0.0)
    assert (hand.mass, hand.stiffness, hand.support_stiffness, hand.support_damping) == (
        0.6, 7.5e4, 100.0, 2.0)
    assert hand.direction == math.pi and hand.angle == 0.1


@pytest.mark.parametrize("stiffness, damping, si_stiffness, si_damping", [
    ('"7.5e4 N/m^1.5"', '"1.5e4 N s/m^2.5"', 7.5e4, 1.5e4),
    ('"7.5e4 N/m^(3/2)"', '"15 kN s/m**2.5"', 7.5e4, 1.5e4),
    ('"75 N/mm^1.5"', '"0.015 N s/mm^2.5"', 75 / 1e-3 ** 1.5, 0.015 / 1e-3 ** 2.5),
])
def test_a_hertz_contact_takes_its_stiffness_in_newtons_per_metre_to_the_exponent(
        stiffness, damping, si_stiffness, si_damping):
    """n = 1.5 (Hertz): k in N/m^1.5 and lambda in N s/m^2.5, which the units' grammar
    (integer exponents) cannot write: the length's power is read as a decimal or a
    fraction, checked against the exponent, and converted as a force (times time) over
    one length unit to that power."""
    env = environment(with_wall(f'angle = "0.1 rad"\nexponent = 1.5\nstiffness = {stiffness}\n'
                                f'damping = {damping}\n'))
    (wall,) = env.contacts
    assert wall.exponent == 1.5
    # a power of the length's factor and a product: a few roundings of 1e-16 each
    assert wall.stiffness == pytest.approx(si_stiffness, rel=1e-14)
    assert wall.damping == pytest.approx(si_damping, rel=1e-14)


def free_impact_restitution(stiffness: float, exponent: float, damping: float,
                            mass: float, speed: float) -> float:
    """The coefficient of restitution of a free mass striking a Hunt-Crossley contact
    at ``speed``, by integrating the impact (an independent reference)."""
    def rate(t, y):
        d, v = y
        force = max(0.0, stiffness * d ** exponent + damping * d ** exponent * v) if d > 0 else 0.0
        return [v, -force / mass]

    def leaves(t, y):
        return y[0] if t > 0 else 1.0
    leaves.terminal, leaves.direction = True, -1
    period = math.pi * math.sqrt(mass / stiffness)  # of the linear contact: a scale
    sol = solve_ivp(rate, (0.0, 100 * period), [0.0, speed], events=leaves, rtol=1e-11,
                    atol=1e-15, max_step=period / 200)
    return -sol.y_events[0][0][1] / speed


@pytest.mark.parametrize("restitution, exponent", [(0.9, 1.0), (0.5, 1.5), (0.2, 1.0)])
def test_a_restitution_at_an_impact_speed_becomes_the_damping_that_gives_it(
        restitution, exponent):
    """restitution e at impact_speed v: the damping with which a free mass striking the
    contact at v leaves it at e v, whatever its mass (the relation of the law itself,
    not Hunt and Crossley's first order e = 1 - (2/3) alpha v, which is off by 4 % at
    e = 0.8 and by 33 % at 0.5)."""
    k = 7.5e4
    unit = "N/m" if exponent == 1.0 else "N/m^1.5"
    env = environment(with_wall(f'angle = "0.1 rad"\nexponent = {exponent}\n'
                                f'stiffness = "{k} {unit}"\nrestitution = {restitution}\n'
                                'impact_speed = "30 cm/s"\n'))
    (wall,) = env.contacts
    assert wall.damping == scenarios.restitution_damping(k, restitution, 0.3)
    for mass in (0.05, 2.0):
        e = free_impact_restitution(k, exponent, wall.damping, mass, 0.3)
        # the integration's tolerance (rtol 1e-11) and the event's location: far below
        assert e == pytest.approx(restitution, rel=1e-6)
    # near e = 1 the root is Hunt and Crossley's first order: alpha v = (3/2)(1 - e)
    alpha_v = scenarios.restitution_damping(1.0, 1 - 1e-6, 1.0)
    assert alpha_v == pytest.approx(1.5e-6, rel=1e-5)  # the next order: (1 - e) relative
    assert scenarios.restitution_damping(k, 1.0, 0.3) == 0.0


def test_simulate_runs_the_environment_and_writes_its_signals(tmp_path, capsys):
    """`vsj simulate` adds the walls and bodies to the wrist: each contact's force,
    penetration, rate, power and energy, the body's displacement, and the ledger's
    entry of each contact; the wall is touched and pushes."""
    out = tmp_path / "out"
    text = edit(WALL, WALL + BODY)
    assert main(["simulate", str(write(tmp_path, text)), "--out", str(out)]) == 0
    capsys.readouterr()
    import xarray as xr

    with xr.open_dataset(out / "trajectory.nc") as ds:
        for name in ("wall", "hand"):
            for what in ("force", "penetration", "rate", "power", "energy"):
                assert f"contact.{name}.{what}" in ds
        force = ds["contact.wall.force"].values[0]
        hand = ds["hand"].values[0]
    assert np.max(force) > 0.0 and np.min(force) >= 0.0
    assert np.all(hand == 0.0)  # the hand at -0.1 rad is never reached
    meta = json.loads((out / "meta.json").read_text())
    ledger = meta["cases"][0]["ledger"]
    assert "contact wall" in ledger["dissipated"] and "contact hand" in ledger["dissipated"]
    assert meta["scenario"]["definition"]["environment"]["link"] == "10 cm"


def test_a_case_changes_a_contact_by_name_or_replaces_an_array(params):
    """[cases.environment.walls.wall] changes that wall's keys and leaves the rest; a
    case may replace the link or a whole array."""
    text = edit(WALL, WALL + BODY) + (
        '[[cases]]\nlabel = "base"\n'
        '[[cases]]\nlabel = "stiff"\n[cases.environment.walls.wall]\nstiffness = "1e5 N/m"\n'
        '[[cases]]\nlabel = "heavy"\n[cases.environment.bodies.hand]\nmass = "2 kg"\n'
        '[[cases]]\nlabel = "long"\n[cases.environment]\nlink = "15 cm"\n'
        '[[cases]]\nlabel = "no walls"\n[cases.environment]\nwalls = []\n')
    envs = [c.environment for c in scenarios.loads(text, "env.toml").cases]
    assert [e.contacts[0].stiffness for e in envs[:4]] == [2e4, 1e5, 2e4, 2e4]
    assert [e.contacts[0].damping for e in envs[:4]] == [4e3] * 4
    assert [e.contacts[-1].mass for e in envs] == [0.6, 0.6, 2.0, 0.6, 0.6]
    assert [e.link for e in envs] == [0.1, 0.1, 0.1, 0.15, 0.1]
    assert [type(c).__name__ for c in envs[4].contacts] == ["Body"]
    # the change reaches the network each case builds
    scen = scenarios.loads(text, "env.toml")
    prepared = scenarios.prepare_case(scen, scen.cases[1], params)
    (wall,) = [f for f in prepared.structure.frictions if f.name == "wall"]
    assert wall.contact[0] == 1e5


def test_a_case_naming_no_contact_of_the_scenario_is_refused(tmp_path, capsys):
    fails(tmp_path, capsys,
          BASE + '[[cases]]\n[cases.environment.walls.table]\nstiffness = "1e5 N/m"\n',
          "cases[0].environment.walls.table", "no walls entry named 'table'", "'wall'")


# ------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("change, expected", [
    # an unknown kind of contact, an unknown key of a contact
    ((WALL, WALL + '[[environment.springs]]\nname = "s"\n'),
     ("environment: unknown key(s) springs",
      "allowed: bodies, link, tip_area, tip_mass, tip_radius, walls")),
    # the tip's geometry: one of two, each in its unit and > 0
    (('tip_mass = "50 g"', 'tip_mass = "50 g"\ntip_area = "1 cm^2"\ntip_radius = "5 mm"'),
     ("environment: give tip_area (a flat face) or tip_radius (a rounded tip), not both",)),
    (('tip_mass = "50 g"', 'tip_mass = "50 g"\ntip_area = "1 cm"'),
     ("environment.tip_area", "cannot be converted to 'm^2'")),
    (('tip_mass = "50 g"', 'tip_mass = "50 g"\ntip_radius = "0 mm"'),
     ("environment.tip_radius = '0 mm': must be > 0 m",)),
    ((WALL, WALL.replace("stiffness", "stifness")),
     ("environment.walls[0]: unknown key(s) stifness", "allowed:")),
    ((WALL, WALL + '[[environment.bodies]]\nname = "h"\nangle = "0.2 rad"\n'
      'stiffness = "1 N/mm"\nsupport = "1 N/m"\n'),
     ("environment.bodies[0]: unknown key(s) support", "support_stiffness")),
    # a stiffness in the wrong unit: not a force over a length, not over the exponent's
    # power, and a non-integer power written for an integer exponent
    ((WALL, WALL.replace('"2e4 N/m"', '"2e4 N m"')),
     ("environment.walls[0].stiffness", "cannot be converted", "is in N/m (force over "
      "penetration^1)")),
    ((WALL, WALL.replace('stiffness = "2e4 N/m"', 'exponent = 1.5\nstiffness = "2e4 N/m"')),
     ("environment.walls[0].stiffness = '2e4 N/m'", "exponent = 1.5 is in N/m^1.5",
      "such as \"2e4 N/m^1.5\"")),
    ((WALL, WALL.replace('"2e4 N/m"', '"2e4 N/m^1.5"')),
     ("environment.walls[0].stiffness = '2e4 N/m^1.5': its length is to the power 1.5",
      "exponent = 1 is in N/m")),
    ((WALL, WALL.replace('"2e4 N/m"', '"2e4"')),
     ("environment.walls[0].stiffness", "has no unit")),
    ((WALL, WALL.replace('"4000 N s/m^2"', '"4000 N s/m"')),
     ("environment.walls[0].damping", "damping with exponent = 1 is in N s/m^2")),
    # exponents below 1 and negative; negative or zero stiffness, negative damping
    ((WALL, WALL.replace('stiffness = "2e4 N/m"', 'exponent = 0.5\nstiffness = "2e4 N/m"')),
     ("environment.walls[0].exponent = 0.5: must be >= 1",)),
    ((WALL, WALL.replace('stiffness = "2e4 N/m"', 'exponent = -1\nstiffness = "2e4 N/m"')),
     ("environment.walls[0].exponent = -1: must be >= 1",)),
    ((WALL, WALL.replace('"2e4 N/m"', '"-2e4 N/m"')),
     ("environment.walls[0].stiffness = '-2e4 N/m': must be > 0",)),
    ((WALL, WALL.replace('"4000 N s/m^2"', '"-1 N s/m^2"')),
     ("environment.walls[0].damping = '-1 N s/m^2': must be >= 0",)),
    ((WALL, WALL.replace('stiffness = "2e4 N/m"\n', '')),
     ("environment.walls[0]: missing 'stiffness' (unit N/m",)),
    # damping given twice, a restitution without its speed or out of range
    ((WALL, WALL + 'restitution = 0.8\nimpact_speed = "0.1 m/s"\n'),
     ("environment.walls[0]: give damping, or restitution with impact_speed, not both",)),
    ((WALL, WALL.replace('damping = "4000 N s/m^2"', 'restitution = 0.8')),
     ("environment.walls[0]: restitution needs impact_speed",)),
    ((WALL, WALL.replace('damping = "4000 N s/m^2"',
                         'restitution = 0.05\nimpact_speed = "0.1 m/s"')),
     ("environment.walls[0].restitution = 0.05: must be from 0.1 to 1",)),
    # a body without mass, or of none
    ((WALL, WALL + BODY.replace('mass = "0.6 kg"\n', '')),
     ("environment.bodies[0]: missing 'mass' (unit kg)", "environment.walls")),
    ((WALL, WALL + BODY.replace('"0.6 kg"', '"0 kg"')),
     ("environment.bodies[0].mass = '0 kg': must be > 0 kg",)),
    # the link: none, zero, negative; a negative tip mass
    (('link = "10 cm"', 'link = "0 cm"'), ("environment.link = '0 cm': must be > 0 m",)),
    (('link = "10 cm"', 'link = "-5 cm"'), ("environment.link = '-5 cm': must be > 0 m",)),
    (('link = "10 cm"\n', ''), ("environment: missing 'link' (unit m)",)),
    (('tip_mass = "50 g"', 'tip_mass = "-50 g"'),
     ("environment.tip_mass = '-50 g': must be >= 0 kg",)),
    # names: missing, taken twice, not a name; a direction that is not one
    ((WALL, WALL.replace('name = "wall"\n', '')), ("environment.walls[0]: missing 'name'",)),
    ((WALL, WALL + BODY.replace('"hand"', '"wall"')),
     ("environment.bodies[0].name: 'wall' is taken by environment.walls[0]",)),
    ((WALL, WALL.replace('"wall"', '"a wall"')),
     ("environment.walls[0].name: 'a wall' is not a contact's name",)),
    ((WALL, WALL.replace('angle = "0.1 rad"', 'angle = "0.1 rad"\ndirection = "z"')),
     ("environment.walls[0].direction", "does not start with a number",
      "or name an axis: +x, x, -x, +y, y, -y")),
    ((WALL, WALL.replace('angle = "0.1 rad"', 'angle = "10 cm"')),
     ("environment.walls[0].angle", "cannot be converted to 'rad'")),
    # arrays that are not arrays of tables
    ((WALL, '[environment.walls]\nname = "wall"\n'),
     ("environment.walls: must be an array of tables ([[environment.walls]])",)),
])
def test_bad_environment_input_is_refused_with_the_file_and_key(tmp_path, capsys, change,
                                                               expected):
    fails(tmp_path, capsys, edit(*change), *expected)


def test_a_contact_that_starts_penetrated_is_refused_with_its_key(tmp_path, capsys):
    """The engine refuses a run whose contact starts penetrated (at theta = 0 a wall at
    -0.01 rad along +x is 1 mm inside the tip); the file and the contact's entry are in
    the message, and nothing is written."""
    fails(tmp_path, capsys, edit('angle = "0.1 rad"', 'angle = "-0.01 rad"'),
          "environment.walls[0]: contact 'wall' starts penetrated by 0.001 m")
    # a body too, and in a file of cases: the top-level key path the case reads it from,
    # and the case; a case's own key path where it sets the body itself
    text = edit(WALL, WALL + BODY.replace('"0.1 rad"', '"-0.02 rad"')) + (
        '[[cases]]\nlabel = "ok"\n[cases.environment.bodies.hand]\nangle = "0.1 rad"\n'
        '[[cases]]\nlabel = "inside"\n')
    fails(tmp_path, capsys, text, "scenario.toml: environment.bodies[0] (read for cases[1]): "
          "contact 'hand' starts penetrated by 0.002 m")
    text = edit(WALL, WALL + BODY) + (
        '[[cases]]\nlabel = "ok"\n[[cases]]\nlabel = "inside"\n'
        '[cases.environment.bodies.hand]\nangle = "-0.02 rad"\n')
    fails(tmp_path, capsys, text, "scenario.toml: cases[1].environment.bodies[0]: contact "
          "'hand' starts penetrated by 0.002 m")


def test_a_top_level_value_is_named_at_its_own_line_in_a_file_of_cases(tmp_path, capsys):
    """A bad value in the file's top level that a case takes over is named by its top-level
    key path (the line to change), with the case that read it; a fixed pivot outside the
    parameter set's pivot range is refused with its key."""
    cases = '[[cases]]\nlabel = "a"\n[[cases]]\nlabel = "b"\n'
    fails(tmp_path, capsys, edit('k = "2.98 V/rad"', 'k = "2.98 V/m"') + cases,
          "scenario.toml: controller.pid[0].k (read for cases[0]) (unit V/rad",
          "'2.98 V/m' has unit V/m")
    fails(tmp_path, capsys, edit('fixed_q = "-0.4 cm"', 'fixed_q = "5 cm"'),
          "scenario.toml: model.fixed_q = 5 cm: outside the pivot range of the parameter set, "
          "[-2.2, 2] cm")
    fails(tmp_path, capsys, edit('fixed_q = "-0.4 cm"', 'fixed_q = "-1 m"') + cases,
          "scenario.toml: model.fixed_q (read for cases[0]) = -100 cm: outside the pivot range")
    fails(tmp_path, capsys, BASE + '[[cases]]\nlabel = "a"\nmodel = { fixed_q = "-3 cm" }\n',
          "scenario.toml: cases[0]: model.fixed_q = -3 cm: outside the pivot range")
    # a case that sets another key of the same table still inherits the bad one
    fails(tmp_path, capsys, edit('friction = "stiction"', 'friction = "bogus"')
          + '[[cases]]\nlabel = "a"\nsolver = { output_step = "2 ms" }\n',
          "scenario.toml: solver.friction (read for cases[0]): unknown friction law 'bogus'")
    # the case's own value, and a message that names no key path: as they were
    fails(tmp_path, capsys, BASE + '[[cases]]\nlabel = "a"\n[cases.controller.pid.u1]\n'
          'k = "2.98 V/m"\n', "scenario.toml: cases[0].controller.pid[0].k (unit V/rad")
    fails(tmp_path, capsys, edit('duration = "0.3 s"\n', '') + cases,
          "scenario.toml: cases[0]: missing 'duration'")
    # touching at the start is not penetrated
    (r,) = run(edit('angle = "0.1 rad"', 'angle = "0 rad"'), duration=0.01)
    assert r.result.success


def test_an_environment_needs_the_wrist(tmp_path, capsys):
    text = ('network = "elastic-bench"\nduration = "0.1 s"\n[bench]\nq = "-0.4 cm"\n'
            '[environment]\nlink = "10 cm"\n')
    fails(tmp_path, capsys, text, "environment: the elastic-bench has no end-effector",
          'network = "wrist"')


def test_the_restitution_function_refuses_what_it_cannot_give():
    with pytest.raises(InputError, match="restitution 0.01: must be from 0.1 to 1"):
        scenarios.restitution_damping(1e4, 0.01, 1.0)


# ------------------------------------------------------------------------- examples


def example(name: str):
    return scenarios.load(str(EXAMPLES / name))


def test_the_wall_example_presses_and_holds_without_creep():
    """examples/environment/wall.toml, as its comments say: the contact force is
    positive while the tip is pressed (and 0 before and after); with stiction theta_x and
    the force stay constant to the bit while the transmissions hold it, and after the
    release the end-effector stays where friction stops it, short of 0; the smooth law
    creeps in both; the ledger closes."""
    runs = {r.case.label: r.result for r in scenarios.run(example("wall.toml"))}
    assert set(runs) == {"stiction", "smooth"}
    # the reference: ramps 0.05-0.15 s, holds to 0.65 s, ramps back to 0 by 0.75 s
    windows = {"approach": (0.0, 0.1), "held": (0.35, 0.65), "after": (0.8, 1.0)}
    for label, r in runs.items():
        assert r.success, r.message
        s, t = r.signals, r.time
        assert r.solver["name"] == "timestep" and r.solver["step"] == 1e-3
        part = {k: (t >= a) & (t <= b) for k, (a, b) in windows.items()}
        force = s["contact.wall.force"]
        assert np.min(force) >= 0.0
        assert np.all(force[part["approach"]] == 0.0) and np.all(force[part["after"]] == 0.0)
        assert np.min(force[part["held"]]) > 0.1  # pressed: tenths of a newton
        assert "contact wall" in r.ledger["dissipated"]
        # the exponential springs and the contact are booked exactly over each step
        assert abs(r.ledger["relative_residual"]) <= r.solver["steps"] * LEDGER_ROUNDOFF_PER_STEP
    stuck, smooth = runs["stiction"].signals, runs["smooth"].signals
    held = part["held"]
    assert np.all(stuck["friction.tr_1.friction.stuck"][held] == 1.0)
    # no creep: the held state is solved again every step, so what moves is round-off,
    # a few ulps of the state per step, at most adding up over the window's steps
    steps = int(np.count_nonzero(held))
    assert np.ptp(stuck["theta_x"][held]) <= 4 * steps * np.spacing(
        np.max(stuck["theta_x"][held]))
    force_held = stuck["contact.wall.force"][held]
    # the force is the contact's stiffness times that: 2e4 N/m at the 0.1 m link
    assert np.ptp(force_held) <= 2e4 * 0.1 * 4 * steps * np.spacing(
        np.max(stuck["theta_x"][held]))
    # the smooth law creeps while held: a slip speed under any torque (its slope width
    # 0.01 rad/s) moves the tip by far more than round-off (1e-17 rad)
    assert np.ptp(smooth["theta_x"][held]) > 1e-9
    # after the release: rest short of 0 against creep back towards it. Over two
    # successive 50 ms a settling motion falls by its decay (the loop's slow pole: more
    # than tenfold), a creep goes on (it slows only as the springs' push falls)
    t = runs["stiction"].time
    at = [int(np.searchsorted(t, x)) for x in (0.9, 0.95, 1.0 - 1e-9)]
    for theta, falls in ((stuck["theta_x"], True), (smooth["theta_x"], False)):
        first, second = theta[at[0]] - theta[at[1]], theta[at[1]] - theta[at[2]]
        assert first > 0.0 and second >= 0.0  # towards 0
        assert (second < 0.1 * first) == falls, (first, second)
    assert stuck["theta_x"][-1] > 0.05 and smooth["theta_x"][-1] < 0.03
    assert smooth["theta_x"][at[0]] - smooth["theta_x"][-1] > 1e-3  # millimetres at the tip


def first_strike(r, link: float):
    """Impact speed v [m/s], peak force F [N] and duration T [s] of a result's first
    contact of the hand: the touching and leaving instants interpolated where the
    penetration crosses 0, the speed there from the rate of penetration."""
    s, t = r.signals, r.time
    d = s["contact.hand.penetration"]
    inside = d > 0.0
    i0 = int(np.argmax(inside))
    i1 = i0 + int(np.argmin(inside[i0:]))

    def crossing(i):
        return t[i - 1] - d[i - 1] * (t[i] - t[i - 1]) / (d[i] - d[i - 1])

    t0, t1 = crossing(i0), crossing(i1)
    v = float(np.interp(t0, t[i0 - 1:i0 + 1], s["contact.hand.rate"][i0 - 1:i0 + 1]))
    return v, float(np.max(s["contact.hand.force"][i0:i1])), t1 - t0, i0


def test_the_hand_example_is_the_two_body_impact_of_iso_ts_15066():
    """examples/environment/hand-impact.toml, as its comments say (its first 0.15 s: the
    first strike at each setting)."""
    scen = example("hand-impact.toml")
    runs = {r.case.label: r for r in scenarios.run(scen, duration=0.15)}
    assert set(runs) == {"stiff", "middle"}
    strikes = {}
    for label, run_ in runs.items():
        r, env = run_.result, run_.case.environment
        (hand,) = env.contacts
        assert (hand.mass, hand.stiffness, hand.exponent, hand.damping) == (0.6, 7.5e4, 1.0, 0.0)
        assert r.success, r.message
        s = r.signals
        force, d = s["contact.hand.force"], s["contact.hand.penetration"]
        # the contact only pushes, and only when tip and hand overlap
        assert np.min(force) >= 0.0 and np.all(force[d <= 0.0] == 0.0)
        v, peak, duration, touch = first_strike(r, env.link)
        # the hand at rest until the first strike, pushed away by it
        assert np.all(s["hand"][:touch] == 0.0) and np.max(s["hand"]) > 0.0
        # the two-body impact: F = v sqrt(mu k), T = pi sqrt(mu / k), so pi F / (v T) is
        # k, whatever mu. 2 %: the model leaves out the rest of the wrist acting on the
        # link within the impact (the springs' push and friction, a few % of the peak,
        # which enter pi F / (v T) with weight 1 - 2/pi, and inertia behind the
        # transmissions' compliances joining in); the sampling of F (0.1 ms of a 3 ms
        # half-sine) costs below 0.2 %
        assert math.pi * peak / (v * duration) == pytest.approx(hand.stiffness, rel=0.02)
        # the link side strikes, not the motors behind the springs: the reduced mass
        # F^2 / (v^2 k) is a small part of the hand's ("about a tenth"; a striker as
        # heavy as the motors' reflected inertia would bring it near the hand's 0.6 kg)
        mu = (peak / v) ** 2 / hand.stiffness
        assert mu < hand.mass / 4
        strikes[label] = v, peak
        if label == "stiff":  # the hand bounces on its support and is struck again
            assert np.count_nonzero(np.diff((d > 0.0).astype(int)) == 1) >= 2
        # no damping: the contact gives back all it stores, to the ledger's own bound
        assert abs(r.ledger["dissipated"]["contact hand"]) <= 1e-6 * r.ledger["total_in"]
        assert abs(r.ledger["relative_residual"]) <= 1e-6
    # the stiff setting swings the tip in faster and strikes harder: about three times
    assert strikes["stiff"][0] > 2.5 * strikes["middle"][0]
    assert strikes["stiff"][1] > 2.5 * strikes["middle"][1]


def test_the_examples_run_with_vsj_simulate(tmp_path, capsys):
    """Each example as a user runs it (shortened by a copy with a shorter duration)."""
    for name in ("wall.toml", "hand-impact.toml"):
        text = (EXAMPLES / name).read_text()
        short = text.replace('duration = "1 s"', 'duration = "0.2 s"').replace(
            'duration = "0.4 s"', 'duration = "0.1 s"')
        assert short != text
        out = tmp_path / f"out-{name}"
        assert main(["simulate", str(write(tmp_path, short, name)), "--out", str(out)]) == 0
        meta = json.loads((out / "meta.json").read_text())
        assert meta["success"]
    capsys.readouterr()


# -------------------------------------------------------------------------- the ledger


def pressing_loop(model: str, step: str = "") -> str:
    """BASE with a wall and a hand surrogate: theta_x goes to 0.2 rad (into the wall at
    0.1 rad), holds, then to -0.2 rad (into the hand at -0.1 rad), with PIDs (their
    integrals make the motors stick and slip while pressed); ``model`` lines go into
    [model], ``step`` into [solver]."""
    text = edit(WALL, WALL + BODY)
    text = edit('kind = "step"\nheight = "0.2 rad"\nstart = "20 ms"',
                'kind = "steps"\nlevels = [0.2, -0.2]\nunit = "rad"\nhold = "0.2 s"\n'
                'ramp = "50 ms"\nstart = "20 ms"', text)
    text = edit('duration = "0.3 s"', 'duration = "0.6 s"', text)
    text = edit('fixed_q = "-0.4 cm"\n', 'fixed_q = "-0.4 cm"\n' + model, text)
    text = edit('method = "timestep"\n', 'method = "timestep"\n' + step, text)
    return text.replace('Td = "4.8 ms"', 'Ti = "64 ms"\nTd = "4.8 ms"')


@pytest.mark.parametrize("model", ['elastic = "exponential"\n',
                                   'elastic = "linear"\nlinear_stiffness = "0.5 N m"\n',
                                   'elastic = "geometric"\n'])
def test_the_ledger_closes_with_contacts_in_closed_loop_with_stiction(model):
    """Issue 34: the ledger closes with contacts, in closed loop, at the default step
    (the time-stepper at 1 ms, the controller sampling every step), with true stiction:
    the tip strikes a wall and is pressed against it, then swings into a hand surrogate.
    With the exponential (report eq 4.5) or linear springs every element's work over a
    step, the contacts' included, is booked exactly: the residual is round-off. The
    report's geometric element (eq 3.8) adds the residual of its linearisation over a
    step, second order in the step (tests/test_stiction.py check_ledger)."""
    (r,) = run(pressing_loop(model))
    result, s = r.result, r.result.signals
    assert result.success, result.message
    assert result.solver["name"] == "timestep" and result.solver["step"] == 1e-3
    # both contacts were made, and friction stuck and slipped
    assert np.max(s["contact.wall.force"]) > 0.1 and np.max(s["contact.hand.force"]) > 0.1
    assert sum(result.transitions.values()) > 0
    assert {"contact wall", "contact hand"} <= set(result.ledger["dissipated"])
    residual = abs(result.ledger["relative_residual"])
    if "geometric" not in model:
        assert residual <= result.solver["steps"] * LEDGER_ROUNDOFF_PER_STEP
        assert residual <= 1e-6  # the bound
    else:
        (halved,) = run(pressing_loop(model, 'step = "0.5 ms"\n'))
        finer = abs(halved.result.ledger["relative_residual"])
        # second order: ratio 4 when the step halves, first order 2: their geometric mean
        assert residual / finer > 2 ** 1.5, (residual, finer)


def test_simulate_writes_each_contacts_safety_figures(tmp_path, capsys):
    """`vsj simulate` of a scenario with an environment puts each case's contact events,
    with their ISO/TS 15066 verdicts, into meta.json, and prints a line per contact; an
    event's peak is read from the contact sampled finer where the trajectory's samples
    (0.1 ms) could under-read it: at least their largest, and above it by at most what a
    half-sine's peak can lie above its samples, (pi h / T)^2 / 8 of it (h the spacing, T
    the event's duration; tests/test_contact_sampling.py checks the reading itself)."""
    import xarray as xr

    out = tmp_path / "hand"
    assert main(["simulate", str(EXAMPLES / "hand-impact.toml"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "contact hand:" in printed and "transient limit" in printed
    meta = json.loads((out / "meta.json").read_text())
    with xr.open_dataset(out / "trajectory.nc") as ds:
        for k, case in enumerate(meta["cases"]):
            events = case["safety"]["hand"]
            force = ds["contact.hand.force"].values[k]
            worst = max(events, key=lambda e: e["peak_force"])
            sampled, h = float(np.nanmax(force)), float(ds["time"][1] - ds["time"][0])
            bound = (np.pi * h / worst["duration"]) ** 2 / 8
            assert sampled <= worst["peak_force"] <= sampled * (1 + bound)
            assert all(e["resolved"] for e in events)
            first = events[0]
            assert first["passed"]["hand"] == (first["peak_force"] <= 280.0)  # Table A.2
            assert first["energy_kind"] == "work" and first["energy_to_body"] > 0
            assert set(first["joint"]) == {"vsm_1", "vsm_2"}


def test_a_tip_geometry_adds_the_peak_pressure_and_its_verdict(tmp_path, capsys):
    """With ``tip_radius`` the hand example's events carry their peak pressure: the
    largest, over the samples in contact, of the force over the Hertz area pi R d (the
    trajectory's own force and penetration), and the verdict checks it against the
    hand's most sensitive area (ISO/TS 15066 Table A.2, transient: twice the
    quasi-static)."""
    import xarray as xr
    from vsj.safety import region

    radius = 0.02
    text = edit('tip_mass = "50 g"', f'tip_mass = "50 g"\ntip_radius = "{radius * 100:g} cm"',
                (EXAMPLES / "hand-impact.toml").read_text())
    out = tmp_path / "tip"
    assert main(["simulate", str(write(tmp_path, text)), "--out", str(out)]) == 0
    capsys.readouterr()
    meta = json.loads((out / "meta.json").read_text())
    hand = region("hand")
    limit = 2.0 * hand.most_sensitive_area.quasi_static_pressure
    with xr.open_dataset(out / "trajectory.nc") as ds:
        for k, case in enumerate(meta["cases"]):
            force = ds["contact.hand.force"].values[k]
            depth = ds["contact.hand.penetration"].values[k]
            for event in case["safety"]["hand"]:
                span = slice(event_index(ds, event["start"]), event_index(ds, event["end"]) + 1)
                f, d = force[span], depth[span]
                inside = f > 0
                expected = np.max(f[inside] / (np.pi * radius * np.minimum(d[inside], radius)))
                # the same samples and the same formula: equal to round-off
                assert event["peak_pressure"] == pytest.approx(expected, rel=1e-12)
                assert "pressure" in event["iso_ts_15066"]["hand"]
                assert event["passed"]["hand"] == (event["peak_force"] <= 280.0
                                                   and event["peak_pressure"] <= limit)


def event_index(ds, t: float) -> int:
    """The sample nearest time ``t`` [s] (an event's start and end lie half a sample
    outside its first and last samples in contact)."""
    return int(np.argmin(np.abs(ds["time"].values - t)))


def test_a_failed_case_says_how_far_its_safety_figures_go(tmp_path, capsys):
    """A case that stops early (its solver's step limit) has contact figures of the part it
    ran only: the line and meta.json say up to when, not a bare "no contact"."""
    text = (EXAMPLES / "hand-impact.toml").read_text().replace(
        '[[cases]]\nlabel = "stiff"\n', '[[cases]]\nlabel = "stiff"\nsolver = { max_steps = 500 }\n')
    out = tmp_path / "out"
    assert main(["simulate", str(write(tmp_path, text)), "--out", str(out)]) == 1
    printed = capsys.readouterr().out
    stiff, middle = json.loads((out / "meta.json").read_text())["cases"]
    assert not stiff["success"] and middle["success"] and "safety_until" not in middle
    until = stiff["safety_until"]
    assert 0.0 < until < 0.1  # the first strike comes later
    assert f"[stiff] contact hand: no contact up to t = {until:.6g} s, where the run stopped" \
        in printed


def test_a_wall_is_judged_as_clamping_and_a_body_as_a_strike():
    """A hand between the tip and a wall cannot recoil: it is clamped, and ISO/TS 15066's
    quasi-static limits apply (Table A.2: 140 N for the hand, 160 N for the lower arm);
    a struck body can recoil, the transient ones (twice those)."""
    from vsj.safety.run_report import report, summary

    (r,) = run(pressing_loop(""))  # into the wall, then into the hand
    figures = report(r.result, r.result.plan.structure)
    assert figures["wall"] and figures["hand"]
    for ev in figures["wall"]:
        assert ev["contact"] == "quasi-static"
        assert ev["passed"] == {"hand": ev["peak_force"] <= 140.0,
                                "lower_arm": ev["peak_force"] <= 160.0}
    for ev in figures["hand"]:
        assert ev["contact"] == "transient"
        assert ev["passed"] == {"hand": ev["peak_force"] <= 280.0,
                                "lower_arm": ev["peak_force"] <= 320.0}
    assert "quasi-static limits: clamped against a wall" in summary({"wall": figures["wall"]})[0]
    # whatever the direction it faces: a wall facing -x where the hand stood is a wall too
    facing = BODY.replace("[[environment.bodies]]", "[[environment.walls]]").replace(
        'mass = "0.6 kg"\n', "").replace('support_stiffness = "100 N/m"\n', "").replace(
        'support_damping = "2 N s/m"\n', "").replace('stiffness = "75 N/mm"', 'stiffness = "2e4 N/m"')
    (r,) = run(pressing_loop("").replace(BODY, facing))
    figures = report(r.result, r.result.plan.structure)
    assert figures["wall"] and figures["hand"]
    assert {ev["contact"] for ev in figures["wall"] + figures["hand"]} == {"quasi-static"}


def test_the_energy_to_a_body_is_the_work_on_it_at_its_own_speed():
    """The body's speed in the direction the contact pushes it is its own displacement's
    rate times the link (the hand faces -x: the wrist's coordinates, some of which the
    contact's row weighs negatively too, are not the body's)."""
    from vsj.safety import run_report

    (r,) = run(pressing_loop(""))
    structure = r.result.plan.structure
    e = [fr.name for fr in structure.frictions].index("hand")
    speed = run_report._body_velocity(structure, e, r.result)
    assert np.array_equal(speed, 0.1 * r.result["hand.speed"])  # the link, 10 cm
    assert run_report._body_velocity(structure, [fr.name for fr in structure.frictions]
                                     .index("wall"), r.result) is None
