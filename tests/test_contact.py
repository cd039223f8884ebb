"""Contact with the environment (vsj.components.Contact, vsj.environment): the
Hunt-Crossley element against closed forms, in every scheme, with stiction and a
controller, in the ledger, and what it refuses."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from vsj import params as params_module
from vsj.components import Bearing, Contact, Inertia, SpringDamper
from vsj.control import wrist_controller
from vsj.environment import Body, Environment, Wall, add_environment
from vsj.errors import InputError
from vsj.inputs import Table
from vsj.network import Network
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import WristOptions, build_wrist

J, L = 2e-3, 0.1           # a rigid link: inertia [kg m^2], length to its tip [m]
M = J / L ** 2             # the tip's effective mass [kg]
V = 0.5                    # impact speed [m/s]


def link(contact: Contact) -> Network:
    net = Network("impact")
    net.add(Inertia("link", J), contact)
    net.connect("link.flange", f"{contact.name}.tip")
    return net


def impact(contact: Contact, solver="dopri", duration=0.05, step=1e-5, **options):
    options.setdefault("rtol", 1e-11)
    options.setdefault("atol", 1e-13)
    return simulate(link(contact).assemble(), {}, duration,
                    initial=InitialState(speeds={"link.flange": V / L}), ports=False,
                    options=SimulationOptions(solver=solver, output_step=step, step=step,
                                              **options))


def crossings(t, d):
    """Times where the penetration d crosses zero (linear interpolation)."""
    i = np.flatnonzero(np.sign(d[:-1]) != np.sign(d[1:]))
    return t[i] - d[i] * (t[i + 1] - t[i]) / (d[i + 1] - d[i])


@pytest.mark.parametrize("solver", ["dopri", "rosenbrock"])
def test_a_linear_contact_gives_the_closed_form_peak_and_duration(solver):
    k = 1e4
    r = impact(Contact("wall", {"tip": L}, stiffness=k), solver)
    assert r.success, r.message
    omega, dt = math.sqrt(k / M), 1e-5
    peak, duration = V * math.sqrt(k * M), math.pi / omega
    # the samples' largest misses the peak by at most (omega dt)^2 / 8 of it; the
    # integration (rtol 1e-11) adds nothing visible
    assert r["contact.wall.force"].max() == pytest.approx(peak, rel=(omega * dt) ** 2 / 8 + 1e-9)
    start, end = crossings(r.time, r["contact.wall.penetration"])[:2]
    # the crossings' linear interpolation errs by the curvature over a sample, d'' dt^2/8,
    # over the speed V: a fraction omega dt / 8 of a sample
    assert end - start == pytest.approx(duration, abs=dt * omega * dt)
    # the link leaves as fast as it came (the contact stores and returns its energy)
    assert r["link.flange.speed"][-1] * L == pytest.approx(-V, rel=1e-8)
    assert abs(r.ledger["relative_residual"]) < 1e-8


def restitution(alpha_v: float) -> float:
    """Hunt and Crossley's coefficient of restitution at alpha v_in: the exact relation of
    their law, from m v dv = -k x^n (1 + alpha v) dx integrated over a whole contact (x
    back at 0): alpha v - ln(1 + alpha v) is the same at v_in and at -v_out, whatever n,
    k and m."""
    g = alpha_v - math.log1p(alpha_v)
    return brentq(lambda e: -alpha_v * e - math.log1p(-alpha_v * e) - g, 1e-9, 1.0 - 1e-12)


@pytest.mark.parametrize("exponent", [1.0, 1.5])
def test_hunt_crossley_damping_gives_its_coefficient_of_restitution(exponent):
    k, alpha = 1e4 * 0.01 ** (1 - exponent), 0.6      # alpha = lambda / k [s/m]
    r = impact(Contact("wall", {"tip": L}, stiffness=k, exponent=exponent,
                       damping=alpha * k), duration=0.08)
    assert r.success, r.message
    e = -r["link.flange.speed"][-1] * L / V
    # the relation is exact for the law; the run meets it to the solver's tolerance
    assert e == pytest.approx(restitution(alpha * V), rel=1e-6)
    assert 0.7 < e < 0.9  # and the damping acted
    # what the contact took and did not give back, it dissipated
    lost = 0.5 * M * V ** 2 * (1 - e ** 2)
    assert r.ledger["dissipated"]["contact wall"] == pytest.approx(lost, rel=1e-6)


@pytest.mark.parametrize("step", [1e-3, 1e-4])
def test_the_time_stepper_keeps_a_linear_contacts_energy(step):
    """The time-stepper books a contact's elastic force as the discrete gradient of its
    energy over each step, so a linear contact returns what it took, on the steps that
    touch and leave the surface too."""
    k = 1e4
    r = impact(Contact("wall", {"tip": L}, stiffness=k), "timestep", step=step)
    assert abs(r.ledger["relative_residual"]) < 1e-12  # booked as the step took it
    # exact where a step's both ends penetrate (the gradient is linear in the end's
    # penetration); a step across the surface leaves a remainder of second order in its
    # change of speed, which is small where the force starts from zero
    energy = 0.5 * M * V ** 2
    assert abs(r.ledger["dissipated"]["contact wall"]) < 1e-6 * energy
    assert r["link.flange.speed"][-1] * L == pytest.approx(-V, rel=1e-6)


def wrist(env: Environment, **options):
    params = params_module.load()
    options = {"elastic": "exponential", **options}
    net = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc", **options))
    return add_environment(net, env).assemble()


def test_several_contacts_act_at_once_in_a_corner():
    env = Environment(link=0.1, contacts=(
        Wall("x_wall", angle=0.05, stiffness=2e4, damping=4e3),
        Wall("y_wall", angle=0.05, stiffness=2e4, damping=4e3, direction=math.pi / 2)))
    s = wrist(env)
    ctl = wrist_controller(s, {"theta_x": 0.2, "theta_y": 0.2, "q": -0.004})
    r = simulate(s, {}, 0.6, controller=ctl, initial=InitialState(q=-0.004),
                 options=SimulationOptions(output_step=1e-3))
    assert r.success, r.message
    both = (r["contact.x_wall.force"] > 0) & (r["contact.y_wall.force"] > 0)
    assert both[-100:].all()  # pressed into the corner, on both walls, to the end
    assert r["theta_x"][-1] == pytest.approx(0.05, abs=2e-3)
    assert r["theta_y"][-1] == pytest.approx(0.05, abs=2e-3)


@pytest.mark.parametrize("friction", ["stiction", "arctan"])
def test_a_joint_held_against_a_wall_by_stiction_does_not_creep(friction):
    """A joint pressed into a wall by its own spring: the motor side (a rotor with a
    bearing whose Coulomb level exceeds the spring's torque) wound 0.2 rad past the
    link, which touches the wall. With true stiction the bearing holds and the wall's
    force stays, to the bit; with the smooth arctan law the bearing yields to any steady
    torque, the spring unwinds and the force creeps away."""
    k_spring, coulomb = 2.0, 1.0  # N m/rad, N m: the spring's 0.4 N m is held
    net = Network("pressed")
    net.add(Inertia("rotor", 1e-4), Inertia("link", J),
            Bearing("bearing", viscous=1e-3, coulomb=coulomb),
            SpringDamper("spring", stiffness=k_spring, damping=1e-3),
            Contact("wall", {"tip": L}, stiffness=2e4, damping=1e6))  # well damped at 0.2 mm
    net.connect("rotor.flange", "bearing.flange").connect("rotor.flange", "spring.a")
    net.connect("spring.b", "link.flange").connect("link.flange", "wall.tip")
    r = simulate(net.assemble(), {}, 2.0, initial=InitialState(angles={"rotor.flange": 0.2,
                                                                       "link.flange": 0.0}),
                 options=SimulationOptions(friction=friction, output_step=1e-3, step=1e-4),
                 ports=False)
    assert r.success, r.message
    late = r["contact.wall.force"][r.time >= 1.0]
    assert late[0] > 0.5 * k_spring * 0.2 / L  # pressed, by about the spring's preload
    if friction == "stiction":
        # the held state: the spring's torque k_s (0.2 - d/L) over L balances the wall's
        # k_c d, so F = k_s 0.2 / (L + k_s / (k_c L)), to round-off, and stays there
        held = k_spring * 0.2 / (L + k_spring / (2e4 * L))
        assert late == pytest.approx(held, rel=1e-12)
        assert np.ptp(late) <= 8 * np.spacing(held)  # a few ulps of rounding per step
        assert r.transitions.get("bearing", 0) <= 2  # it stuck once and stayed stuck
    else:
        assert late[-1] < 0.99 * late[0]


@pytest.mark.parametrize("elastic", ["geometric", "exponential"])
@pytest.mark.parametrize("moving", [False, True])
def test_the_ledger_closes_with_contacts_a_controller_and_stiction_at_the_default_step(
        elastic, moving):
    """Strikes on a wall and a hand, in closed loop with true stiction, at the default
    step, with the default elastic model (geometric: its torque over a step is the
    discrete gradient of its energy) and the exponential one (quadratic in the
    deflection), at a held stiffness setting and while the pivot moves (from 0.2 s to
    0.6 s: the pivot's share of the springs' energy is booked about the mid-step
    position the torques use)."""
    env = Environment(link=0.1, tip_mass=0.05, contacts=(
        Wall("wall", angle=0.1, stiffness=2e4, damping=4e3),
        Body("hand", angle=0.1, direction=math.pi, mass=0.6, stiffness=75e3,
             support_stiffness=1e3, damping=1.5e4)))
    s = wrist(env, elastic=elastic)
    ctl = wrist_controller(s, {"theta_x": Table((0.0, 0.3, 0.31, 1.0), (0.15, 0.15, -0.2, -0.2)),
                               "theta_y": 0.0,
                               "q": Table((0.0, 0.2, 0.6, 1.0),
                                          (-0.004, -0.004, 0.01 if moving else -0.004,
                                           0.01 if moving else -0.004))},
                          current_limit=2.0)
    r = simulate(s, {}, 1.0, controller=ctl, initial=InitialState(q=-0.004),
                 options=SimulationOptions(friction="stiction"))
    assert r.success, r.message
    assert r.solver["name"] == "timestep" and r.solver["step"] == SimulationOptions().step
    assert r["contact.wall.force"].max() > 1.0 and r["contact.hand.force"].max() > 1.0
    assert (np.ptp(r["q"]) > 0.01) == moving
    # the bound: 1e-6 of the energy in play
    assert abs(r.ledger["relative_residual"]) <= 1e-6
    assert r.ledger["dissipated"]["contact wall"] > 0
    assert r.ledger["dissipated"]["contact hand"] > 0


def test_bad_contacts_are_refused_naming_what_is_wrong():
    with pytest.raises(ValueError, match="exponent must be finite and >= 1"):
        Contact("c", {"tip": L}, stiffness=1e4, exponent=0.5)
    with pytest.raises(ValueError, match="stiffness must be finite and > 0"):
        Contact("c", {"tip": L}, stiffness=-1.0)
    with pytest.raises(InputError, match=r"contacts\[0\] \(hand\).mass must be a finite number > 0"):
        Environment(link=0.1, contacts=(Body("hand", angle=0.1, mass=0.0, stiffness=1e4),)).check()
    with pytest.raises(InputError, match="environment.link must be a finite number > 0"):
        Environment(link=-0.1).check()
    with pytest.raises(InputError, match=r"environment.tip: a vsj.safety.Tip .* got str"):
        Environment(link=0.1, tip="5 mm").check()
    with pytest.raises(InputError, match="exponent must be a finite number >= 1"):
        Environment(link=0.1, contacts=(Wall("w", angle=0.1, stiffness=1e4, exponent=-1),)).check()
    env = Environment(link=0.1, contacts=(Wall("wall", angle=-0.02, stiffness=2e4),))
    with pytest.raises(InputError, match="contact 'wall' starts penetrated by 0.002 m"):
        simulate(wrist(env), {}, 0.1, initial=InitialState(q=-0.004))
    with pytest.raises(InputError, match="contact is the environment's law"):
        SimulationOptions(friction="contact").validate()


def test_the_iso_transient_speed_limit_holds_on_the_stiff_preset():
    """ISO/TS 15066's largest transient speed for the hand, v = F / sqrt(mu k) with mu
    the reduced mass of the hand (Table A.3) and the wrist's effective mass at the tip,
    struck by the wrist at its stiffest setting: the engine's peak force is the
    permissible transient force."""
    from vsj import safety

    hand = safety.region("hand")
    env = Environment(link=L, tip_mass=0.2, contacts=(
        Body("hand", angle=0.0, mass=hand.effective_mass, stiffness=hand.spring_constant),))
    params = params_module.load()
    s = add_environment(build_wrist(params, WristOptions(elastic="exponential")), env).assemble()
    # the tip's effective mass: the inertia an impulse at the tip meets (the motors, held
    # by their drives, are behind the elastic elements), 1 / (L^2 r M^-1 r^T)
    r = s.rows("diff.theta_x")[0]
    m_inv_r = np.linalg.solve(s.mass_matrix(), r)
    robot_mass = 1.0 / (L ** 2 * (r @ m_inv_r))
    limit = safety.transient_speed_limit(hand, robot_mass=robot_mass,
                                         stiffness=hand.spring_constant)
    omega = limit.by_force / L
    speeds = dict(zip(s.free, m_inv_r * omega / (r @ m_inv_r)))  # the tip at that speed
    stiffest = s.pivot.q_min
    run = simulate(s, {}, 0.03, initial=InitialState(q=stiffest, speeds=speeds),
                   options=SimulationOptions(rtol=1e-10, atol=1e-12, output_step=1e-5),
                   ports=False)
    assert run.success, run.message
    assert run["theta_x.speed"][0] * L == pytest.approx(limit.by_force, rel=1e-12)
    # the closed form holds for two masses and a spring; the wrist's elastic elements
    # (hundreds of times softer than the hand at the tip) and its held motors add their
    # forces over the contact's few milliseconds: the 2 %
    assert run["contact.hand.force"].max() == pytest.approx(
        hand.permissible_force("transient"), rel=0.02)


def test_the_hic_of_an_engine_impact_on_a_mass_spring_surrogate_is_its_closed_form():
    """A link strikes a free head surrogate (a mass behind a linear contact spring): the
    HIC of the body's acceleration in the engine's run equals the closed form of a linear
    spring impact (a half-sine pulse of the reduced mass's oscillation)."""
    from vsj import safety

    m_head, k, v = 4.5, 1e5, 1.0  # kg, N/m, m/s
    net = Network("head")
    net.add(Inertia("link", J), Inertia("head", m_head * L ** 2),
            Contact("skin", {"tip": L, "body": -L}, stiffness=k))
    net.connect("link.flange", "skin.tip").connect("head.flange", "skin.body")
    dt = 1e-6
    r = simulate(net.assemble(), {}, 0.02, initial=InitialState(speeds={"link.flange": v / L}),
                 options=SimulationOptions(rtol=1e-11, atol=1e-13, output_step=dt),
                 ports=False)
    assert r.success, r.message
    acceleration = r["contact.skin.force"] / m_head  # the body's only force
    touching = np.flatnonzero(acceleration > 0)
    window = slice(max(touching[0] - 1, 0), touching[-1] + 2)
    run = safety.hic(r.time[window], acceleration[window])
    closed = safety.hic_spring_impact(v, m_head, k, robot_mass=M)
    # the sampled pulse (1e-6 s samples of a ~10 ms pulse) and the integration: the
    # trapezoid rule's and the window's placement errors, (omega dt)^2 of the value
    omega = math.sqrt(k / safety.reduced_mass(m_head, M))
    assert run.value == pytest.approx(closed.value, rel=10 * (omega * dt) ** 2 + 1e-9)


def test_a_runs_safety_report_gives_each_events_figures():
    """`vsj.safety.run_report`: a link strikes a free body once; its event's impulse is the
    momentum the body took, the work of the contact on it the body's kinetic energy."""
    from vsj.safety import run_report

    m_body, k = 0.6, 75e3
    net = Network("strike")
    net.add(Inertia("link", J), Inertia("hand", m_body * L ** 2),
            Contact("skin", {"tip": L, "body": -L}, stiffness=k))
    net.connect("link.flange", "skin.tip").connect("hand.flange", "skin.body")
    s = net.assemble()
    r = simulate(s, {}, 0.02, initial=InitialState(speeds={"link.flange": V / L}),
                 options=SimulationOptions(rtol=1e-11, atol=1e-13, output_step=1e-6),
                 ports=False)
    figures = run_report.report(r, s)
    (event,) = figures["skin"]
    body_speed = r["hand.flange.speed"][-1] * L
    # a two-body elastic impact: the body leaves with 2 M V / (M + m_body)
    assert body_speed == pytest.approx(2 * M * V / (M + m_body), rel=1e-8)
    # the trapezoid rule over 1e-6 s samples of a smooth pulse: (omega dt)^2 of it
    omega = math.sqrt(k * (M + m_body) / (M * m_body))
    tol = (omega * 1e-6) ** 2 + 1e-9
    assert event["impulse"] == pytest.approx(m_body * body_speed, rel=tol)
    assert event["energy_kind"] == "work"
    assert event["energy_to_body"] == pytest.approx(0.5 * m_body * body_speed ** 2, rel=tol)
    assert event["passed"]["hand"] == (event["peak_force"] <= 280.0)
    assert run_report.summary(figures)[0].startswith("contact skin: 1 event(s)")


def test_the_time_steppers_contact_never_pulls():
    """A link pressed into a damped contact and then pulled away faster than 1/alpha: the
    law's force would turn negative (k + lambda d' < 0) and is held at zero; the
    time-stepper follows the same law as dopri (an adhesive force would leave the link
    2 % slower)."""
    from vsj.components import TorqueSource

    k, alpha = 1e4, 5.0
    net = Network("pull")
    net.add(Inertia("link", J), Contact("wall", {"tip": L}, stiffness=k, damping=alpha * k),
            TorqueSource("ext", "tau"))
    net.connect("link.flange", "wall.tip").connect("link.flange", "ext.flange")
    tau = Table((0.0, 0.02, 0.0200001, 0.05), (1.0, 1.0, -20.0, -20.0))
    speeds = {}
    for solver, step in (("dopri", 1e-5), ("timestep", 1e-6)):
        r = simulate(net.assemble(), {"tau": tau}, 0.03, ports=False,
                     options=SimulationOptions(solver=solver, output_step=1e-5, step=step,
                                               rtol=1e-10, atol=1e-12, friction="viscous"))
        assert r.success, r.message
        speeds[solver] = r["link.flange.speed"][np.searchsorted(r.time, 0.025)]
    # the time-stepper's first order at 1e-6 s over the 25 ms: about 1e-5 of the speed
    assert speeds["timestep"] == pytest.approx(speeds["dopri"], rel=1e-4)
