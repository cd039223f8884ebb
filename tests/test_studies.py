"""The optimisation studies (vsj.studies, issue 34): the reduced impact model against the
mass-spring-mass closed form and an independent integration, the one-axis model against
the wrist's own network, the safe-brachistochrone optimiser against its fixed-stiffness
baseline on a tiny problem, the explosive ratio of an elastic and a rigid joint, and the
refusals of bad input. The heavy optimisations of the studies themselves are not run
here (they take minutes); their pieces are, on problems small enough for seconds."""

import html
import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from vsj.control.wrist import mechanical_stiffness, wrist_kinematics
from vsj.errors import InputError
from vsj.reproduce.base import CATEGORIES, Context
from vsj.studies import (HAND, AxisModel, BodyModel, Explosive, JointTable, SafeMotion,
                         axis_model, explosive_motion, impact, mass_spring_mass_peak,
                         optimise, optimise_wrist, reduced_explosive, safe_and_fast,
                         safe_speeds, verify, write)
from vsj.studies.brachistochrone import (Strategy, _elastic_problem, _instant_problem,
                                         _smooth_guess)
from vsj.studies.collocation import _Transcription
from vsj.studies.study import (EXPLOSIVE_STATEMENT, RESOLUTION, SOFTENING,
                              _stiff_soft_stiff)
from vsj.studies.explosive import _linear_axis, _linear_run
from vsj.wrist import WristOptions, build_wrist

#: Relative accuracy of the modal impact solution: each phase is exact up to the
#: generalised eigenproblem's backward error (a few eps times the stiffness ratio of the
#: modes, here at most 1e3) and the crossing and peak searches, which brentq and the
#: bounded search end at 1e-15 s and 1e-14 of the time: far below 1e-9.
MODAL = 1e-9


def link_and_rotor(J_m=2e-3, J_l=1.5e-4, coupling=0.0):
    return np.array([[J_m, coupling], [coupling, J_l]])


@pytest.mark.parametrize("coupling", [0.0, -5e-5])
def test_a_mass_spring_mass_impact_gives_the_closed_form(coupling):
    """K = 0: the rotors never take part and the link strikes with its own effective mass
    (the Schur complement of the mass matrix when the ring couples the sides); K
    infinite: rotors and link are one mass. Both are the mass-spring-mass impact, whose
    peak force is v sqrt(k mu): the relative motion's kinetic energy, all in the spring."""
    M, link, v = link_and_rotor(coupling=coupling), 0.1, 1.3
    alone = (M[1, 1] - M[0, 1] ** 2 / M[0, 0]) / link ** 2
    free = impact(M, 0.0, link, HAND, speed_motor=v / link, speed_link=v / link)
    assert free.first_peak == pytest.approx(
        mass_spring_mass_peak(v, HAND.stiffness, alone, HAND.mass), rel=MODAL)
    # the duration of a linear contact is half its period, pi sqrt(mu / k)
    mu = alone * HAND.mass / (alone + HAND.mass)
    assert free.duration == pytest.approx(math.pi * math.sqrt(mu / HAND.stiffness), rel=MODAL)
    rigid = impact(M, math.inf, link, HAND, speed_motor=v / link, speed_link=v / link)
    whole = float(M.sum()) / link ** 2
    assert rigid.peak_force == pytest.approx(
        mass_spring_mass_peak(v, HAND.stiffness, whole, HAND.mass), rel=MODAL)
    assert rigid.contacts == 1  # one mass on a free body touches once
    # a stiff joint approaches the rigid one from below: in series with the contact its
    # compliance l^2 / K lowers the stiffness the rotors meet by the share r^-1 = k_c l^2
    # / K, so the force (as its square root) by at most half that; the eigenproblem's
    # conditioning adds r eps = 2e-10
    r = 1e6
    stiff = impact(M, r * HAND.stiffness * link ** 2, link, HAND, speed_motor=v / link,
                   speed_link=v / link)
    shortfall = 1.0 - stiff.first_peak / rigid.peak_force
    assert -MODAL < shortfall <= 0.5 / r + MODAL


def test_the_impact_scales_with_the_speed():
    """Every phase is linear and undamped: doubling the speeds doubles every force and
    leaves every time as it was."""
    M, K = link_and_rotor(coupling=-5e-5), 2.0
    a = impact(M, K, 0.1, HAND, speed_motor=7.0, speed_link=9.0, deflection=0.01)
    b = impact(M, K, 0.1, HAND, speed_motor=14.0, speed_link=18.0, deflection=0.02)
    assert b.peak_force == pytest.approx(2 * a.peak_force, rel=MODAL)
    assert b.contacts == a.contacts
    assert b.end == pytest.approx(a.end, rel=MODAL)


def test_an_impact_through_a_joint_agrees_with_an_independent_integration():
    """The modal solution's contacts, peak and end against DOP853 (rtol 1e-12) with the
    contact switched on and off by events; after the modal solution's last contact the
    integration, carried on for ten slow periods, must find no other (the proof that
    none can come: the body moves away faster than the tip can)."""
    M, K, link = link_and_rotor(coupling=-5e-5), 0.5, 0.1
    body = BodyModel("test", 0.6, 2e4, 100.0)
    w_m, w_l, d0 = 10.0, 12.0, 0.02
    hit = impact(M, K, link, body, speed_motor=w_m, speed_link=w_l, deflection=d0)
    assert hit.contacts >= 2  # the rotors push the link back onto the body
    M3 = np.zeros((3, 3))
    M3[:2, :2] = M
    M3[2, 2] = body.mass
    Minv = np.linalg.inv(M3)

    def force(z):
        return body.stiffness * (link * z[1] - z[2])

    def rhs(touching):
        def f(t, y):
            z, v = y[:3], y[3:]
            tau = K * (z[0] - z[1])
            F = force(z) if touching else 0.0
            return np.concatenate([v, Minv @ np.array([-tau, tau - link * F, F])])
        return f

    def gap(t, y):
        return link * y[1] - y[2]

    y = np.array([d0, 0.0, 0.0, w_m, w_l, 0.0])
    t, touching, contacts, peak = 0.0, True, 0, 0.0
    horizon = hit.end + 10 * 2 * math.pi * math.sqrt(M[1, 1] / K)
    while t < horizon:
        gap.terminal = True
        gap.direction = -1.0 if touching else 1.0
        sol = solve_ivp(rhs(touching), (t, horizon), y, method="DOP853", rtol=1e-12,
                        atol=1e-15, events=gap, dense_output=True)
        if touching:
            contacts += 1
            ts = np.linspace(sol.t[0], sol.t[-1], 20001)
            peak = max(peak, float(np.max(force(sol.sol(ts)[:3]))))
        if sol.status != 1:
            break
        t, y = float(sol.t_events[0][0]), sol.y_events[0][0]
        touching = not touching
    assert contacts == hit.contacts
    # the integration's tolerance (1e-12) and the sampled peak's miss, (omega dt)^2 / 8
    # of it with 20 000 samples over a contact (omega dt below 2e-4)
    assert peak == pytest.approx(hit.peak_force, rel=1e-7)


@pytest.fixture(scope="module")
def model(params):
    return axis_model(params)


def test_the_axis_model_is_the_wrists_own(params, model):
    """The one-axis model read from the network: its stiffness setting is
    `mechanical_stiffness` of the whole wrist at theta_x, and its motors' speed limit the
    no-load speed through the rigid kinematics."""
    s = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc")).assemble()
    for q in (model.q_min, -0.004, 0.013, model.q_max):
        # the bicubic spline's slope at zero deflection: its error is of order
        # h^3 tau'''' / 24 with h = 5 mrad, about 1e-6 K for the element's curves
        assert model.joint.stiffness(q) == pytest.approx(mechanical_stiffness(s, q)[0, 0],
                                                         rel=1e-5)
    kin = wrist_kinematics(s)
    m = params.motor
    rotor = m.voltage_limit / m.torque_constant
    assert model.no_load_speed == pytest.approx(rotor * kin.to_wrist[0, :2].sum(), rel=1e-12)
    # the motor side carries the rotors' reflected inertia, far above the link's
    assert model.mass[0, 0] > 10 * model.mass[1, 1]
    # the pivot's speed limit: the stiffness motor's no-load speed through its gearing
    assert model.pivot_speed == pytest.approx(rotor * abs(kin.pivot_gain), rel=1e-12)


def tiny_model(pivot_speed=20.0):
    """A joint whose stiffness spans three decades over q in [0, 1] (100 to 0.1 N m/rad),
    a deflection limit of 0.3 rad, a light link behind heavy rotors: stiff settings have
    torque to accelerate, soft ones let the rotors decouple from an impact."""
    q = np.linspace(0.0, 1.0, 6)
    joint = JointTable.linear(100.0 * 10.0 ** (-3 * q), q, deflection_limit=0.3)
    return AxisModel(mass=np.diag([1e-3, 1e-4]), damping=np.zeros((2, 2)),
                     back_emf=np.diag([0.02, 0.0]), voltage_gain=np.array([0.04, 0.0]),
                     voltage_limit=24.0, joint=joint, q_min=0.0, q_max=1.0,
                     pivot_amplitude=1.0, pivot_speed=pivot_speed)


#: The tiny problem's body: soft enough (1 kN/m at 0.1 m, 10 N m/rad) that the joint's
#: stiffness decides how much of the rotors an impact meets.
TINY_BODY = BodyModel("test", 0.5, 1e3, 10.0)


def test_a_stiffness_schedule_beats_the_best_fixed_stiffness_on_a_tiny_problem():
    """Bicchi and Tonietti's finding where the physics holds it: the safe speed grows as
    the joint softens and the torque it can hold shrinks, so the optimal schedule goes
    stiff (to accelerate), soft (at speed), stiff (to brake), and is faster than any one
    setting held."""
    m = tiny_model()
    setup = SafeMotion(distance=1.0, link=0.1, body=TINY_BODY, nodes=8, safety_points=6,
                       fixed_candidates=3)
    safe = safe_speeds(m, setup)
    assert np.all(np.diff(safe.speed) > 0)  # softer is safer here
    found = optimise(m, setup, ("best fixed", "schedule"))
    best, schedule = found["best fixed"], found["schedule"]
    # every fixed setting is a schedule, so the schedule can only be faster; it must be
    # faster by more than the controls' smoothing term can move T (SMOOTHING times the
    # largest squared step of a scaled control, 4)
    assert schedule.T < best.T * (1 - RESOLUTION)
    # and each candidate fixed setting is slower than the best one
    assert min(best.candidates.values()) == pytest.approx(best.T, rel=1e-12)
    q = schedule.q
    middle = np.max(q[2:-2])
    assert middle > q[0] and middle > q[-1]  # soft in the middle (higher q is softer)
    assert q[-1] < q[len(q) // 2]             # and stiff again at the end
    # the schedule respects the pivot's speed: |dq/dt| within its limit at every node
    rate = schedule.solution.controls[:, 1]
    assert np.all(np.abs(rate) <= m.pivot_rate_limit(q)[0] * (1 + 1e-6))


def test_what_counts_as_stiff_soft_stiff():
    """The study's reading of a schedule (q at evenly spaced nodes, higher is softer):
    soft in the middle three fifths by `SOFTENING` of the range against both outer
    fifths; a schedule that also softens at the start, or only softens, does not count."""
    step = 1.5 * SOFTENING  # beyond the threshold, on a range of 1
    assert _stiff_soft_stiff(np.array([0, 0, step, step, step, step, step, 0, 0, 0.0]), 1.0)
    assert not _stiff_soft_stiff(np.array([step, 0, step, step, step, step, 0, 0, 0, 0]), 1.0)
    assert not _stiff_soft_stiff(np.linspace(0.0, 1.0, 10), 1.0)
    flat = 0.5 * SOFTENING  # below the threshold
    assert not _stiff_soft_stiff(np.array([0, 0, flat, flat, flat, flat, flat, 0, 0, 0]), 1.0)


def test_the_exact_propagation_reproduces_a_motors_step_response():
    """The explosive study's exact linear propagation on the rigid axis under full
    voltage: omega(t) = omega_0 (1 - exp(-t / tau)) at every sample, to round-off."""
    m = tiny_model()
    F, G, link, _ = _linear_axis(m, 0.0, rigid=True)
    times = np.linspace(0.0, 0.2, 5)
    states = _linear_run(F, G, times, np.full(5, 24.0), 0.2, 50)
    t = np.linspace(0.0, 0.2, len(states))
    J, C = float(m.mass.sum()), float(m.back_emf.sum())
    expected = m.no_load_speed * (1.0 - np.exp(-t * C / J))
    assert states @ link == pytest.approx(expected, rel=1e-12, abs=1e-12 * m.no_load_speed)


def test_the_reduced_models_integration_is_its_exact_solution():
    """Twin: `AxisModel.simulate` (DOP853, the bicubic joint table) and the exact
    propagation of the same linear joint by matrix exponentials agree along a bang-bang
    profile with ramps, over several periods of the elastic mode."""
    m = tiny_model()
    q = 0.6
    times = np.linspace(0.0, 0.12, 9)
    volts = 24.0 * np.array([1, 1, -1, -1, 1, 1, -1, 0.5, 0.0])
    F, G, link, deflection = _linear_axis(m, q, rigid=False)
    exact = _linear_run(F, G, times, volts, 0.12, 40)
    t = np.linspace(0.0, 0.12, len(exact))
    states = m.simulate(t, lambda s: float(np.interp(s, times, volts)), lambda s: q)
    scale = np.max(np.abs(exact), axis=0)
    # DOP853 at rtol 1e-9 and atol 1e-11 keeps the global error within about a hundred
    # local tolerances over the run's few hundred steps
    assert np.max(np.abs(states - exact) / scale) < 1e-6


def test_an_elastic_joint_throws_faster_than_its_motors_a_rigid_one_cannot():
    """The explosive ratio on the reduced model: a rigid joint's best is full voltage
    throughout, 1 - exp(-T / tau) of the no-load speed (T = 3 tau here), exactly 1 over a
    long window and never more; the elastic joint, pumped at its resonance within its
    deflection limit, passes its motors' speed limit."""
    m = tiny_model()
    tau = float(m.mass.sum()) / float(m.back_emf.sum())
    rigid = reduced_explosive(m, 0.5, window=3 * tau, knots=6, rigid=True)
    assert rigid.success, rigid.message
    # SLSQP's ftol (1e-10) on the ratio, and knots at their bound
    assert rigid.ratio == pytest.approx(1.0 - math.exp(-3.0), rel=1e-8)
    # over 40 time constants the rigid joint reaches its motors' limit and never passes
    # it: SLSQP stops when the ratio moves by less than its ftol (1e-10), which can leave
    # each of the 11 knots (whose influence on the end falls as exp(-t / tau)) short by
    # about that much
    rigid = reduced_explosive(m, 0.5, window=40 * tau, knots=11, rigid=True)
    assert 1.0 - 1e-8 < rigid.ratio <= 1.0
    # at q = 0.6 (1.6 N m/rad) the elastic mode's period, 50 ms, spans four knots
    elastic = reduced_explosive(m, 0.6, window=0.15, knots=12)
    assert elastic.success, elastic.message
    assert elastic.ratio > 1.0
    assert elastic.history[-1] >= elastic.history[0]  # the optimiser improved its start


def test_study_inputs_are_refused_with_input_error(params, model):
    ctx = Context(params=params, reduced=True)
    with pytest.raises(InputError, match="distance must be a finite number > 0"):
        SafeMotion(distance=-1.0).check()
    with pytest.raises(InputError, match="nodes must be a whole number >= 4"):
        safe_and_fast(ctx, setup=SafeMotion(nodes=2), model=model)
    with pytest.raises(InputError, match="needs a vsj.reproduce.base.Context"):
        safe_and_fast("fig", model=model)
    with pytest.raises(InputError, match="body 'hand': mass must be a finite number > 0"):
        BodyModel("hand", 0.0, 75e3, 280.0).check()
    with pytest.raises(InputError, match="speed_link must be > 0"):
        impact(model.mass, 1.0, 0.1, HAND, speed_motor=1.0, speed_link=-1.0)
    with pytest.raises(InputError, match="link must be a finite number > 0"):
        impact(model.mass, 1.0, 0.0, HAND, speed_motor=1.0, speed_link=1.0)
    with pytest.raises(InputError, match="window must be a finite number > 0"):
        Explosive(window=0.0).check()
    with pytest.raises(InputError, match="outside the pivot's range"):
        optimise_wrist(params, Explosive(q=0.05), model=model)
    with pytest.raises(InputError, match="sweep position 1.0 m is outside"):
        explosive_motion(ctx, sweep=(1.0,), model=model)
    with pytest.raises(InputError, match="unknown strategies"):
        optimise(model, SafeMotion(), ("fastest",))
    with pytest.raises(InputError, match="the linear elastic model has no pivot"):
        axis_model(params, elastic="linear")
    with pytest.raises(InputError, match="positive definite"):
        AxisModel(mass=np.diag([1.0, -1.0]), damping=np.zeros((2, 2)),
                  back_emf=np.zeros((2, 2)), voltage_gain=np.array([1.0, 0.0]),
                  voltage_limit=1.0, joint=model.joint, q_min=model.q_min,
                  q_max=model.q_max, pivot_amplitude=0.025, pivot_speed=1.0)
    rigid = Strategy("rigid", None)
    with pytest.raises(InputError, match="cannot run strategy 'rigid'"):
        verify(params, rigid, SafeMotion(), model=model)
    with pytest.raises(InputError, match="a study's Figure"):
        write("not a figure", ".")


def test_the_collocations_jacobians_are_its_constraints_derivatives():
    """The exact Jacobians SLSQP is given (Simpson defects, path constraints at nodes and
    midpoints) against central differences, for the rate-limited and the instant
    schedule on the tiny problem at a perturbed guess."""
    m = tiny_model()
    setup = SafeMotion(distance=1.0, link=0.1, body=TINY_BODY, nodes=5, safety_points=6)
    safe = safe_speeds(m, setup)
    rng = np.random.default_rng(7)
    X, U = _smooth_guess(m, setup, 0.1, 5, 0.4)
    for problem, x, u in ((_elastic_problem(m, setup, safe, (0.0, 1.0), True, 0.1), X, U),
                          (_instant_problem(m, setup, safe, 0.1), X[:, :4],
                           np.column_stack([U[:, 0], np.full(6, 0.4)]))):
        tr = _Transcription(problem, 5, 0.1)
        y = tr.pack(x + 0.01 * rng.standard_normal(x.shape),
                    u + 0.01 * rng.standard_normal(u.shape), 0.1)
        for fn in (tr.defects, tr.path):
            J = fn(y)[1]
            step = 1e-6
            numeric = np.column_stack([(fn(y + step * e)[0] - fn(y - step * e)[0]) / (2 * step)
                                       for e in np.eye(len(y))])
            # central differences err by step^2 f''' / 6 (1e-12 on these scaled, order-one
            # functions) and by round-off eps |f| / step (2e-10)
            assert np.max(np.abs(J - numeric)) <= 1e-8 * max(1.0, np.max(np.abs(J)))


def test_the_explosive_study_end_to_end_in_its_reduced_form(params, model, tmp_path):
    """The study as `vsj reproduce` or a `vsj study` command would run it (reduced: a
    100 ms window, two settings, a few iterations): a Figure whose rows carry the
    reproduction's categories and no report value (a new study), a ratio above the rigid
    joint's, and its PNG, SVG and JSON written."""
    fig = explosive_motion(Context(params=params, reduced=True), model=model)
    assert fig.name == "study-explosive-motion"
    assert {r.category for r in fig.rows} <= set(CATEGORIES)
    assert all(r.statement == EXPLOSIVE_STATEMENT for r in fig.rows)
    assert all(r.verdict() == "not compared" for r in fig.rows)
    assert fig.data["ratio"] > 1.0 > fig.data["reduced"]["rigid"]
    # the joint optimisation starts from the best fixed setting's profile and keeps the
    # fastest it ran, so it is never below it (the same engine run: to the bit)
    assert fig.data["ratio"] >= max(fig.data["sweep"]["ratio"])
    files = write(fig, tmp_path)
    assert [f.name for f in files] == ["study-explosive-motion.png",
                                       "study-explosive-motion.svg",
                                       "study-explosive-motion.json",
                                       "study-explosive-motion.html"]
    record = json.loads(files[2].read_text())
    assert record["data"]["ratio"] == pytest.approx(fig.data["ratio"], rel=1e-15)
    assert len(record["rows"]) == len(fig.rows)
    # the page shows every row under its category, and the finding it tests
    text = html.unescape(files[3].read_text())
    assert all(r.quantity in text for r in fig.rows)
    assert "Haddadin et al. (2011)" in text and "no row has a report value" in text
