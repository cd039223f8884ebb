"""Clutches, brakes, breakaway peaks and spring-dampers, against closed forms."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from vsj.components import (Bearing, Brake, Clutch, Fixed, Inertia, SpringDamper, TorqueSource)
from vsj import params as params_module
from vsj.engine.core import IMPULSE_REL
from vsj.inputs import Constant, Sine, Step, Table
from vsj.network import Network
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import WristOptions, build_wrist

from test_motor import LEDGER_ROUNDOFF_PER_STEP
from test_stiction import IMPULSE_ABS

H = 1e-3
EPS = np.finfo(float).eps
#: Slack of a comparison of sample times [s]: each is k h, rounded to a few ulps of 1 s.
TIME_SLACK = 8 * EPS


def held_speed(torque, inertia, h=H):
    """Largest speed [rad/s] of a body held by true stiction: the impulse solver accepts a
    stuck slip within IMPULSE_ABS + IMPULSE_REL x the free slip, here the speed that
    ``torque`` [N m] gives ``inertia`` [kg m^2] in a step."""
    return IMPULSE_ABS + IMPULSE_REL * abs(torque) * h / inertia


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
    assert abs((first_slip - H) - t_break) <= H + TIME_SLACK
    torque = np.abs(r["friction.clutch.torque"])
    # it held up to the static level (as the mean over its last stuck step: the ramp
    # rises by rate x h over a step) ...
    assert torque.max() == pytest.approx(11.0, abs=rate * H)
    assert torque.max() > 10.0 + 0.5
    # ... and slips at the kinetic level afterwards: the impulse at its cap mu fn h,
    # reported over the step (a few roundings)
    late = r.time > t_break + 5 * H
    np.testing.assert_allclose(torque[late], 10.0, rtol=4 * EPS, atol=0.0)
    assert (r["body.flange.speed"][late] > 0).all()


def test_peak_one_breaks_away_at_the_kinetic_level():
    net = braked(peak=1.0)
    r = run(net, {"tau": Table((0.0, 1.0), (0.0, 20.0)), "brake_force": Constant(1.0)}, 1.0)
    first_slip = r.time[np.argmin(r["friction.brake.stuck"] > 0.5)]
    assert abs((first_slip - H) - 0.5) <= H + TIME_SLACK


def test_a_turning_element_stops_and_holds_below_its_static_level():
    # sliding backward against a push of 12 N m: kinetic 10, static 15; once the
    # body stops, 12 N m cannot break it free again (MSL's peak), ...
    r = run(braked(peak=1.5), {"tau": Constant(12.0), "brake_force": Constant(1.0)}, 0.5,
            speeds={"body.flange": -5.0})
    w = r["body.flange.speed"]
    t_stop = 5.0 * 0.1 / 22.0  # decelerated by 12 + 10 N m
    # the step that contains the stop, then the first sample after it
    after = r.time > t_stop + 2 * H
    assert np.all(np.abs(w[after]) <= held_speed(12.0, 0.1))
    assert np.all(r["friction.brake.stuck"][after] == 1.0)
    # ... while without a peak it turns round and speeds up at (12 - 10) / J: each
    # step adds 20 h to a speed of up to |w|, so the difference of two rounded speeds
    # is 20 h to a few ulps of |w|
    r1 = run(braked(peak=1.0), {"tau": Constant(12.0), "brake_force": Constant(1.0)}, 0.5,
             speeds={"body.flange": -5.0})
    late = r1.time > 0.3
    speed = r1["body.flange.speed"][late]
    np.testing.assert_allclose(np.diff(speed) / H, 20.0, atol=0.0,
                               rtol=4 * EPS * np.max(np.abs(speed)) / (20.0 * H))


def test_without_normal_force_a_brake_is_free_not_stuck():
    # the brake releases at 0.2 s and grips at 0.6 s again; the body coasts in between
    force = Table((0.0, 0.2, 0.2 + 1e-9, 0.6, 0.6 + 1e-9, 1.0), (1.0, 1.0, 0.0, 0.0, 1.0, 1.0))
    r = run(braked(), {"tau": Constant(3.0), "brake_force": force}, 1.0)
    w, stuck, t = r["body.flange.speed"], r["friction.brake.stuck"], r.time
    held, free = (t > 0.01) & (t < 0.2), (t > 0.201) & (t < 0.6)
    assert np.all(np.abs(w[held]) <= held_speed(3.0, 0.1)) and np.all(stuck[held] == 1.0)
    assert np.all(stuck[free] == 0.0)
    # no normal force, no level: the impulse's cap is zero
    assert np.all(r["friction.brake.torque"][free] == 0.0)
    # coasting at 3 / 0.1 rad/s^2 (exact for a constant torque): each step adds a
    # rounding of the speed, and the sample times are rounded too
    coasting = 3.0 / 0.1 * (t[free] - 0.2)
    steps = np.count_nonzero(free) + 1
    np.testing.assert_allclose(w[free], coasting, rtol=0.0,
                               atol=2 * steps * EPS * np.max(coasting) + 3.0 / 0.1 * TIME_SLACK)
    # gripping again at 0.6 s at 12 rad/s: 10 N m against 3 N m stops it 12 x 0.1 / 7 s
    # later, then the step that contains the stop and the first sample after it
    assert np.all(stuck[t > 0.6 + 12.0 * 0.1 / 7.0 + 2 * H] == 1.0)


def test_a_slip_dependent_coefficient_is_followed_while_sliding():
    # spinning down on a brake whose coefficient falls from 0.5 at rest to 0.3 at 10 rad/s
    mu = ((0.0, 0.5), (10.0, 0.3))
    J, fn = 0.1, 20.0
    net = Network("coast")
    net.add(Inertia("body", J), Brake("brake", fn_max=fn, mu=mu))
    net.connect("body.flange", "brake.flange")

    def decel(_, w):
        c = np.interp(abs(w[0]), [0.0, 10.0], [0.5, 0.3])
        return [-c * fn / J * np.sign(w[0])]

    stop = lambda t, w: w[0]  # noqa: E731
    stop.terminal = True
    exact = solve_ivp(decel, (0.0, 0.5), [25.0], events=stop, rtol=1e-10, atol=1e-12,
                      dense_output=True)
    t_stop = exact.t_events[0][0]
    # the level follows the slip at each step's start: a step's speed change is off by
    # h x |da/dw| x (the slip's change over half a step, h |a| / 2), with
    # |da/dw| = fn |dmu/dw| / J and |a| <= fn mu_max / J; over t_stop / h steps the
    # error is first order in h
    dadw, a_max = fn * 0.02 / J, fn * 0.5 / J
    errors = []
    for h in (1e-4, 5e-5):
        r = run(net, {"brake_force": Constant(1.0)}, 0.5, speeds={"body.flange": 25.0}, step=h)
        bound = h * t_stop * dadw * a_max / 2
        sliding = r.time < t_stop - 1e-3
        error = np.max(np.abs(r["body.flange.speed"][sliding] - exact.sol(r.time[sliding])[0]))
        assert error <= bound, (h, error, bound)
        errors.append(error)
        # stopped within the speed error's worth of deceleration and a step, and then
        # held with no torque left on it (a free slip of zero)
        after = r.time > t_stop + bound / (fn * 0.3 / J) + 2 * h
        assert np.all(np.abs(r["body.flange.speed"][after]) <= IMPULSE_ABS)
    # first order: halving the step halves the error (a wrong coefficient would leave a
    # constant error; threshold: the geometric mean of ratios 2 and 1)
    assert errors[0] / errors[1] > 2 ** 0.5, errors


def test_engaging_a_clutch_conserves_momentum_and_locks_on_time():
    # two free inertias at different speeds; the clutch closes at 0.1 s
    net = Network("lockup")
    net.add(Inertia("a", 0.2), Inertia("b", 0.05), Clutch("clutch", fn_max=10.0, mu=0.4))
    net.connect("a.flange", "clutch.a").connect("clutch.b", "b.flange")
    r = run(net, {"clutch_force": Step(1.0, 0.1)}, 0.6,
            speeds={"a.flange": 10.0, "b.flange": 40.0})
    wa, wb = r["a.flange.speed"], r["b.flange.speed"]
    # equal and opposite impulses: the momentum changes only by the speeds' rounding,
    # a couple of ulps per step
    steps = r.solver["steps"]
    momentum = 0.2 * 10.0 + 0.05 * 40.0
    np.testing.assert_allclose(0.2 * wa + 0.05 * wb, momentum, rtol=2 * steps * EPS, atol=0.0)
    # no torque, no change: w + 0 is w
    assert np.all(wa[r.time < 0.1] == 10.0) and np.all(wb[r.time < 0.1] == 40.0)
    # the slip of 30 rad/s closes at 4 N m (1/0.2 + 1/0.05) = 100 rad/s^2
    t_lock = 0.1 + 30.0 / 100.0
    locked = r.time > t_lock + H
    # locked: both at momentum / inertia, to the momentum's rounding and a stuck slip
    # (no torque on the pair: a free slip of zero)
    common = 2 * steps * EPS * 16.0 + IMPULSE_ABS
    np.testing.assert_allclose(wa[locked], 16.0, rtol=0.0, atol=common)
    np.testing.assert_allclose(wb[locked], 16.0, rtol=0.0, atol=common)
    first = r.time[np.argmax(r["friction.clutch.stuck"] > 0.5)]
    assert t_lock - TIME_SLACK <= first <= t_lock + H + TIME_SLACK
    # the heat is the kinetic energy lost: the impulses' work is booked at the mid-step
    # slip, exact for an impulse, so both agree to the ledger's round-off
    heat = r.ledger["dissipated"]["friction clutch"]
    lost = 0.5 * 0.2 * 10 ** 2 + 0.5 * 0.05 * 40 ** 2 - 0.5 * 0.25 * 16 ** 2
    assert heat == pytest.approx(lost, rel=steps * LEDGER_ROUNDOFF_PER_STEP, abs=0.0)
    assert r.ledger["relative_residual"] <= steps * LEDGER_ROUNDOFF_PER_STEP


@pytest.mark.parametrize("friction", ["arctan", "slope"])
def test_smooth_laws_scale_a_clutch_by_its_normal_force(friction):
    # a brake half pressed holds back a body turning fast: 0.5 * 10 N m
    net = braked()
    options = SimulationOptions(friction=friction, rtol=1e-9, atol=1e-11)
    structure = net.assemble()
    r = simulate(structure, {"tau": Constant(0.0), "brake_force": Constant(0.5)}, 0.1,
                 options=options, initial=InitialState(speeds={"body.flange": 50.0}))
    assert r.success, r.message
    assert r.solver["name"] == "dopri"
    speed = r["body.flange.speed"]
    fast = speed > 5.0
    # the law at each sample's speed: arctan k atan(k_b s) short of its level by
    # 1 - (2/pi) atan(k_b s); the slope law saturated past its width
    if friction == "arctan":
        shape = 2 / math.pi * np.arctan(structure.frictions[0].sharpness * speed[fast])
    else:
        shape = 1.0
    # two arctangents (the engine's within an ulp of the exact value, numpy's within a
    # few, as its vectorised loops allow) and a few products
    np.testing.assert_allclose(np.abs(r["friction.brake.torque"][fast]), 5.0 * shape,
                               rtol=8 * EPS, atol=0.0)
    # every ledger term is integrated by the same error-controlled steps as the state
    assert r.ledger["relative_residual"] <= options.rtol


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


def trapezoidal_error(h, J=0.05, c=160.0, d=1.0, amplitude=0.1):
    """Bound on the trapezoidal rule's error [rad] on `ring`'s oscillator. The rule maps
    each mode exp(lambda t) to exp(lambda_h t) with lambda_h = (2/h) artanh(lambda h/2)
    = lambda (1 + (lambda h)^2 / 12 + ...), so a mode of amplitude C is off by at most
    C |lambda|^3 h^2 / 12 t exp(-sigma t) <= C |lambda|^3 h^2 / (12 e sigma); the
    series' next terms add a fraction (w h)^2."""
    wn = math.sqrt(c / J)
    sigma = d / (2 * J)
    zeta = sigma / wn
    mode = amplitude / math.sqrt(1 - zeta ** 2)
    return mode * wn ** 3 * h ** 2 / (12 * math.e * sigma) * (1 + (wn * h) ** 2)


@pytest.mark.parametrize("friction", ["stiction", "arctan"])
def test_a_spring_damper_rings_down_as_the_closed_form_says(friction):
    r, exact = ring(H, friction)
    assert r.solver["name"] == ("timestep" if friction == "stiction" else "dopri")
    error = np.max(np.abs(r["body.flange"] - exact))
    if friction == "stiction":
        # the time-stepper: trapezoidal spring and damper; the ledger of a linear
        # network closes to round-off
        assert error <= trapezoidal_error(H), (error, trapezoidal_error(H))
        assert r.ledger["relative_residual"] <= r.solver["steps"] * LEDGER_ROUNDOFF_PER_STEP
    else:
        # dopri keeps its global error within rtol of the amplitude (test_convergence);
        # its ledger terms are integrated to the same tolerance
        rtol = r.solver["options"]["rtol"]
        assert error <= rtol * 0.1, error
        assert r.ledger["relative_residual"] <= rtol


def test_the_time_stepper_is_second_order_on_a_spring_damper():
    # trapezoidal spring and damper: halving the step quarters the error (first order:
    # halves it; the threshold is their geometric mean)
    errors = []
    for h in (2e-3, 1e-3, 5e-4):
        r, exact = ring(h)
        errors.append(np.max(np.abs(r["body.flange"] - exact)))
    assert errors[0] / errors[1] > 2 ** 1.5 and errors[1] / errors[2] > 2 ** 1.5


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
