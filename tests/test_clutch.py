"""Clutches, brakes, breakaway peaks and spring-dampers, against closed forms."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from vsj.components import (Bearing, Brake, Clutch, Fixed, Inertia, SpringDamper, TorqueSource)
from vsj import params as params_module
from vsj.inputs import Constant, Sine, Step, Table
from vsj.network import Network
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import WristOptions, build_wrist

H = 1e-3


def run(net, inputs, duration, *, speeds=None, friction="stiction", step=H):
    options = SimulationOptions(friction=friction, step=step, output_step=step)
    result = simulate(net.assemble(), inputs, duration, options=options,
                      initial=InitialState(speeds=speeds or {}), ports=False)
    assert result.success, result.message
    return result


def braked(peak=1.0, mu=0.5, fn_max=20.0, J=0.1):
    """An inertia with a torque source, held to the ground by a brake."""
    net = Network("braked")
    net.add(Inertia("body", J), TorqueSource("push", "tau"),
            Brake("brake", fn_max=fn_max, mu=mu, peak=peak))
    net.connect("body.flange", "push.flange").connect("body.flange", "brake.flange")
    return net


@pytest.mark.parametrize("rate", [20.0, 19.37, 21.71])
def test_a_ramped_torque_breaks_a_peaked_clutch_free_at_the_static_level(rate):
    # kinetic level mu fn = 10 N m, static 11 N m: breakaway where rate t = 11
    net = Network("ramp")
    net.add(Fixed("ground"), Clutch("clutch", fn_max=20.0, mu=0.5, peak=1.1),
            Inertia("body", 0.1), TorqueSource("push", "tau"))
    net.connect("ground.flange", "clutch.a").connect("clutch.b", "body.flange")
    net.connect("body.flange", "push.flange")
    r = run(net, {"tau": Table((0.0, 1.0), (0.0, rate)), "clutch_force": Constant(1.0)}, 1.0)
    t_break = 11.0 / rate
    stuck = r["friction.clutch.stuck"] > 0.5
    first_slip = r.time[np.argmin(stuck)]
    assert stuck[: np.argmin(stuck)].all()
    # the breakaway step [first_slip - h, first_slip] starts within a step of the instant
    assert abs((first_slip - H) - t_break) <= H + 1e-12
    torque = np.abs(r["friction.clutch.torque"])
    # it held up to the static level (as the mean over its last stuck step) ...
    assert torque.max() == pytest.approx(11.0, abs=rate * H)
    assert torque.max() > 10.0 + 0.5
    # ... and slips at the kinetic level afterwards
    late = r.time > t_break + 5 * H
    assert np.allclose(torque[late], 10.0, rtol=1e-9)
    assert (r["body.flange.speed"][late] > 0).all()


def test_peak_one_breaks_away_at_the_kinetic_level():
    net = braked(peak=1.0)
    r = run(net, {"tau": Table((0.0, 1.0), (0.0, 20.0)), "brake_force": Constant(1.0)}, 1.0)
    first_slip = r.time[np.argmin(r["friction.brake.stuck"] > 0.5)]
    assert abs((first_slip - H) - 0.5) <= H + 1e-12


def test_a_turning_element_stops_and_holds_below_its_static_level():
    # sliding backward against a push of 12 N m: kinetic 10, static 15; once the
    # body stops, 12 N m cannot break it free again (MSL's peak), ...
    r = run(braked(peak=1.5), {"tau": Constant(12.0), "brake_force": Constant(1.0)}, 0.5,
            speeds={"body.flange": -5.0})
    w = r["body.flange.speed"]
    t_stop = 5.0 * 0.1 / 22.0  # decelerated by 12 + 10 N m
    assert np.all(np.abs(w[r.time > t_stop + 2 * H]) < 1e-12)
    assert np.all(r["friction.brake.stuck"][r.time > t_stop + 2 * H] == 1.0)
    # ... while without a peak it turns round and speeds up at (12 - 10) / J
    r1 = run(braked(peak=1.0), {"tau": Constant(12.0), "brake_force": Constant(1.0)}, 0.5,
             speeds={"body.flange": -5.0})
    late = r1.time > 0.3
    assert np.allclose(np.diff(r1["body.flange.speed"][late]) / H, 20.0, rtol=1e-6)


def test_without_normal_force_a_brake_is_free_not_stuck():
    # the brake releases at 0.2 s and grips at 0.6 s again; the body coasts in between
    force = Table((0.0, 0.2, 0.2 + 1e-9, 0.6, 0.6 + 1e-9, 1.0), (1.0, 1.0, 0.0, 0.0, 1.0, 1.0))
    r = run(braked(), {"tau": Constant(3.0), "brake_force": force}, 1.0)
    w, stuck, t = r["body.flange.speed"], r["friction.brake.stuck"], r.time
    held, free = (t > 0.01) & (t < 0.2), (t > 0.201) & (t < 0.6)
    assert np.all(np.abs(w[held]) < 1e-12) and np.all(stuck[held] == 1.0)
    assert np.all(stuck[free] == 0.0)
    assert np.allclose(r["friction.brake.torque"][free], 0.0, atol=1e-12)
    assert np.allclose(w[free], 3.0 / 0.1 * (t[free] - 0.2), rtol=1e-9, atol=1e-9)
    # gripping again at 0.6 s: 10 N m against 3 N m stops it within 30 * 0.1 / 7 s
    assert np.all(stuck[t > 0.6 + 12.0 * 0.1 / 7.0 + 2 * H] == 1.0)


def test_a_slip_dependent_coefficient_is_followed_while_sliding():
    # spinning down on a brake whose coefficient falls from 0.5 at rest to 0.3 at 10 rad/s
    mu = ((0.0, 0.5), (10.0, 0.3))
    net = Network("coast")
    net.add(Inertia("body", 0.1), Brake("brake", fn_max=20.0, mu=mu))
    net.connect("body.flange", "brake.flange")
    r = run(net, {"brake_force": Constant(1.0)}, 0.5, speeds={"body.flange": 25.0}, step=1e-4)

    def decel(_, w):
        c = np.interp(abs(w[0]), [0.0, 10.0], [0.5, 0.3])
        return [-c * 20.0 / 0.1 * np.sign(w[0])]

    stop = lambda t, w: w[0]  # noqa: E731
    stop.terminal = True
    exact = solve_ivp(decel, (0.0, 0.5), [25.0], events=stop, rtol=1e-10, atol=1e-12,
                      dense_output=True)
    t_stop = exact.t_events[0][0]
    sliding = r.time < t_stop - 1e-3
    # the level follows the slip at each step's start: first order in the step
    assert np.allclose(r["body.flange.speed"][sliding], exact.sol(r.time[sliding])[0],
                       atol=1e-2)
    assert np.all(np.abs(r["body.flange.speed"][r.time > t_stop + 2e-4]) < 1e-12)


def test_engaging_a_clutch_conserves_momentum_and_locks_on_time():
    # two free inertias at different speeds; the clutch closes at 0.1 s
    net = Network("lockup")
    net.add(Inertia("a", 0.2), Inertia("b", 0.05), Clutch("clutch", fn_max=10.0, mu=0.4))
    net.connect("a.flange", "clutch.a").connect("clutch.b", "b.flange")
    r = run(net, {"clutch_force": Step(1.0, 0.1)}, 0.6,
            speeds={"a.flange": 10.0, "b.flange": 40.0})
    wa, wb = r["a.flange.speed"], r["b.flange.speed"]
    assert np.allclose(0.2 * wa + 0.05 * wb, 0.2 * 10.0 + 0.05 * 40.0, rtol=1e-12)
    assert np.all(wa[r.time < 0.1] == 10.0) and np.all(wb[r.time < 0.1] == 40.0)
    # the slip of 30 rad/s closes at 4 N m (1/0.2 + 1/0.05) = 100 rad/s^2
    t_lock = 0.1 + 30.0 / 100.0
    locked = r.time > t_lock + H
    assert np.allclose(wa[locked], 16.0, rtol=1e-12) and np.allclose(wb[locked], 16.0)
    first = r.time[np.argmax(r["friction.clutch.stuck"] > 0.5)]
    assert t_lock - 1e-12 <= first <= t_lock + H + 1e-12
    # the heat is the kinetic energy lost
    heat = r.ledger["dissipated"]["friction clutch"]
    lost = 0.5 * 0.2 * 10 ** 2 + 0.5 * 0.05 * 40 ** 2 - 0.5 * 0.25 * 16 ** 2
    assert heat == pytest.approx(lost, rel=1e-9)
    assert r.ledger["relative_residual"] < 1e-9


@pytest.mark.parametrize("friction", ["arctan", "slope"])
def test_smooth_laws_scale_a_clutch_by_its_normal_force(friction):
    # a brake half pressed holds back a body turning fast: 0.5 * 10 N m
    net = braked()
    options = SimulationOptions(friction=friction, rtol=1e-9, atol=1e-11)
    r = simulate(net.assemble(), {"tau": Constant(0.0), "brake_force": Constant(0.5)}, 0.1,
                 options=options, initial=InitialState(speeds={"body.flange": 50.0}))
    assert r.success, r.message
    assert r.solver["name"] == "dopri"
    fast = r["body.flange.speed"] > 5.0
    assert np.allclose(np.abs(r["friction.brake.torque"][fast]), 5.0, rtol=0.02)
    assert r.ledger["relative_residual"] < 1e-6


def ring(step, friction="stiction"):
    """J phi'' + d phi' + c phi = 0 from phi = 0.1 rad at rest: (result, closed form)."""
    J, c, d = 0.05, 160.0, 1.0
    net = Network("ring")
    net.add(Fixed("ground"), SpringDamper("sd", stiffness=c, damping=d), Inertia("body", J),
            Bearing("bearing"))
    net.connect("ground.flange", "sd.a").connect("sd.b", "body.flange")
    net.connect("body.flange", "bearing.flange")
    options = SimulationOptions(friction=friction, step=step, output_step=step, rtol=1e-10,
                                atol=1e-12)
    r = simulate(net.assemble(), {}, 0.5, options=options,
                 initial=InitialState(angles={"body.flange": 0.1}), ports=False)
    assert r.success, r.message
    zeta = d / (2 * math.sqrt(c * J))
    wn = math.sqrt(c / J)
    wd = wn * math.sqrt(1 - zeta ** 2)
    t = r.time
    exact = 0.1 * np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))
    return r, exact


@pytest.mark.parametrize("friction, tol", [("stiction", 2e-3), ("arctan", 1e-6)])
def test_a_spring_damper_rings_down_as_the_closed_form_says(friction, tol):
    r, exact = ring(H, friction)
    assert r.solver["name"] == ("timestep" if friction == "stiction" else "dopri")
    assert np.max(np.abs(r["body.flange"] - exact)) < tol * 0.1
    assert r.ledger["relative_residual"] < 1e-8


def test_the_time_stepper_is_second_order_on_a_spring_damper():
    # trapezoidal spring and damper: halving the step quarters the error
    errors = []
    for h in (2e-3, 1e-3, 5e-4):
        r, exact = ring(h)
        errors.append(np.max(np.abs(r["body.flange"] - exact)))
    assert errors[0] / errors[1] > 3.5 and errors[1] / errors[2] > 3.5


def test_clutch_and_brake_parameters_are_checked():
    with pytest.raises(ValueError, match="peak of c"):
        Clutch("c", fn_max=1.0, peak=0.9)
    with pytest.raises(ValueError, match="fn_max of c"):
        Clutch("c", fn_max=-1.0)
    with pytest.raises(ValueError, match="slip speeds must increase"):
        Brake("c", fn_max=1.0, mu=((0.0, 0.5), (0.0, 0.4)))
    with pytest.raises(ValueError, match="row 1"):
        Brake("c", fn_max=1.0, mu=((0.0, 0.5), (1.0, -0.4)))
    with pytest.raises(ValueError, match="mu must be a number or rows"):
        Brake("c", fn_max=1.0, mu="high")
    with pytest.raises(ValueError, match="peak of b"):
        Bearing("b", stiction=0.1, peak=float("nan"))


def test_the_wrist_keeps_peak_one_everywhere(params):
    structure = build_wrist(params).assemble()
    assert structure.frictions
    assert all(fr.peak == 1.0 and fr.normal is None and fr.table is None
               for fr in structure.frictions)


def test_the_wrist_friction_peak_is_a_parameter(params):
    # friction.peak reaches every friction element of the wrist; a parameter file
    # without it gets 1; a peak above 1 holds the joint longer under true stiction
    text = params_module._bundled(params_module.DEFAULT_FILE).read_text()
    lines = [line for line in text.splitlines() if not line.startswith("peak =")]
    assert len(lines) == len(text.splitlines()) - 1
    older = params_module.loads("\n".join(lines), "older.toml")
    assert older.friction.peak == 1.0 and "default" in older.sources["friction.peak"]
    peaked = params.with_overrides({"friction.peak": "1.5"}, origin="test")
    structure = build_wrist(peaked).assemble()
    assert {fr.peak for fr in structure.frictions if fr.k > 0} == {1.5}
    with pytest.raises(Exception, match="friction.peak"):
        params.with_overrides({"friction.peak": "0.9"}, origin="test")

    def stuck_samples(p):
        net = build_wrist(p, WristOptions(end_effector="loaded", pivot_drive="fixed")).assemble()
        r = simulate(net, {"tau_x": Sine(0.05, 2.0)}, 1.0,
                     options=SimulationOptions(friction="stiction", output_step=0.01))
        assert r.success, r.message
        return sum(r[f"friction.{fr.name}.stuck"].sum() for fr in net.frictions)

    assert stuck_samples(peaked) > stuck_samples(params)
