"""True stiction: exact holding, analytic stick-slip, breakaway, hysteresis, energy, no chatter."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from vsj import benches
from vsj import scenario as scenarios
from vsj.components import Bearing, IdealGear, Inertia, TorqueSource
from vsj.engine import _core
from vsj.inputs import Sine, Table
from vsj.network import Network
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import build_wrist

# inertia, Coulomb level, drive; the frequency is incommensurate with the steps so that
# the transitions fall at every phase of a step and the errors average honestly
J, LEVEL, AMPLITUDE, FREQ = 1e-3, 0.01, 0.016, 0.9137


def coulomb_reference(t_end):
    """Speed of J dw/dt = A sin(2 pi f t) - F sgn(w), sticking when |A sin| <= F,
    from rest: piecewise closed form, transitions found by root finding.

    Returns the speed function and the stick intervals.
    """
    om = 2 * math.pi * FREQ
    drive = lambda t: AMPLITUDE * math.sin(om * t)  # noqa: E731
    pieces, sticks = [], []
    t = 0.0
    while t < t_end:
        # stuck from t until |drive| exceeds the level
        grid = np.arange(t, t_end + 1e-3, 1e-3)
        over = np.flatnonzero(np.abs([drive(x) for x in grid]) > LEVEL)
        if over.size == 0:
            sticks.append((t, t_end))
            break
        k = over[0]
        t1 = t if k == 0 else brentq(lambda x: abs(drive(x)) - LEVEL, grid[k - 1], grid[k])
        if t1 > t:
            sticks.append((t, t1))
        sign = 1.0 if drive(t1) > 0 else -1.0

        def speed(x, t1=t1, sign=sign):
            return (AMPLITUDE / om * (math.cos(om * t1) - math.cos(om * x))
                    - sign * LEVEL * (x - t1)) / J

        grid = np.arange(t1 + 1e-6, t_end + 1e-3, 1e-3)
        stop = np.flatnonzero(np.sign([speed(x) for x in grid]) != sign)
        t2 = t_end if stop.size == 0 else brentq(speed, grid[stop[0] - 1] if stop[0] else t1 + 1e-9,
                                                 grid[stop[0]])
        pieces.append((t1, t2, speed))
        t = t2
    sticks = [(a, b) for a, b in sticks if b - a > 1e-9]

    def w(x):
        for a, b, f in pieces:
            if a <= x <= b:
                return f(x)
        return 0.0

    return np.vectorize(w), sticks


def coulomb_run(h, t_end):
    net = Network("coulomb")
    net.add(Inertia("mass", J), Bearing("bearing", coulomb=LEVEL),
            TorqueSource("push", "tau"))
    net.connect("mass.flange", "bearing.flange").connect("mass.flange", "push.flange")
    return simulate(net.assemble(), {"tau": Sine(AMPLITUDE, FREQ)}, t_end,
                    options=SimulationOptions(friction="stiction", step=h, output_step=h),
                    ports=False)


def intervals(t, flag):
    """(first, last) sample time of each run of True in a sampled flag.

    A sample at t_k reports the step that ends there, so a true transition at
    t* is found at the sample of the step that contains it.
    """
    padded = np.concatenate([[0], flag.astype(int), [0]])
    starts = np.flatnonzero(np.diff(padded) == 1)
    ends = np.flatnonzero(np.diff(padded) == -1) - 1
    return [(t[a], t[b]) for a, b in zip(starts, ends)]


def test_coulomb_benchmark_matches_the_analytic_solution():
    t_end = 12.0
    reference, sticks = coulomb_reference(t_end)
    assert len(sticks) >= 3  # the drive's amplitude exceeds the level: stick and slip alternate
    errors = {}
    for h in (1e-3, 1e-4):
        r = coulomb_run(h, t_end)
        assert r.success
        speed = r["mass.flange.speed"]
        # RMS over time: between transitions the scheme is second order, at a
        # transition one sample may be off by up to (acceleration x step)
        errors[h] = np.sqrt(np.mean((speed - reference(r.time)) ** 2))
        held = r["friction.bearing.stuck"] > 0.5
        # stick phases longer than two steps (speed reversals touch zero for a step)
        found = [(a, b) for a, b in intervals(r.time, held) if b - a > 1.5 * h]
        assert len(found) == len(sticks)
        for (a, b), (ra, rb) in zip(found, sticks):
            assert abs(a - ra) <= h + 1e-12 and abs(b - rb) <= h + 1e-12
    # first-order scheme: ten times smaller steps, at least five times smaller error
    # the error shrinks with the step (ten times smaller steps, at least five times smaller)
    assert errors[1e-4] < errors[1e-3] / 5
    assert errors[1e-4] < 1e-3 * np.max(np.abs(reference(np.linspace(0, t_end, 999))))


def geared_run(split):
    """The Coulomb benchmark's inertia with its friction either split over a bearing
    on the inertia and one behind a gear of ratio RATIO, or lumped into one bearing
    with the far level reflected through the gear."""
    near, far, ratio = 0.004, 0.015, -2.5
    net = Network("geared")
    net.add(Inertia("mass", J), TorqueSource("push", "tau"))
    net.connect("mass.flange", "push.flange")
    if split:
        net.add(Bearing("near", coulomb=near), IdealGear("gear", ratio),
                Bearing("far", coulomb=far))
        net.connect("mass.flange", "near.flange").connect("mass.flange", "gear.a")
        net.connect("gear.b", "far.flange")
    else:
        net.add(Bearing("near", coulomb=near + far / abs(ratio)))
        net.connect("mass.flange", "near.flange")
    r = simulate(net.assemble(), {"tau": Sine(AMPLITUDE, FREQ)}, 8.0, ports=False,
                 options=SimulationOptions(friction="stiction", step=1e-3, output_step=1e-3))
    assert r.success
    return r, (near, far, ratio)


def test_elements_that_slip_together_share_one_impulse_exactly():
    """Two stiction elements whose slips are proportional (here through a gear) are
    posed as one impulse unknown: the motion is that of one element with the summed
    (reflected) level, a slipping pair puts each element at its own level, and a
    stuck pair loads both to the same fraction of their levels."""
    split, (near, far, ratio) = geared_run(True)
    lumped, _ = geared_run(False)
    speed = split["mass.flange.speed"]
    assert np.max(np.abs(speed - lumped["mass.flange.speed"])) <= 1e-12 * np.max(np.abs(speed))
    t_near, t_far = split["friction.near.torque"], split["friction.far.torque"]
    stuck = split["friction.near.stuck"] > 0.5
    assert np.array_equal(stuck, split["friction.far.stuck"] > 0.5)
    assert 0.05 < stuck.mean() < 0.95  # both phases occur
    slipping = ~stuck & (split.time > 0)  # the first sample reports no step
    np.testing.assert_allclose(np.abs(t_near[slipping]), near, rtol=1e-12)
    np.testing.assert_allclose(np.abs(t_far[slipping]), far, rtol=1e-12)
    np.testing.assert_allclose(np.abs(t_near[stuck]) / near, np.abs(t_far[stuck]) / far,
                               atol=1e-12)
    # the torques on the inertia add up to the lumped element's, stuck or slipping
    np.testing.assert_allclose(t_near + t_far / ratio, lumped["friction.near.torque"],
                               atol=1e-12 * far)


def test_wrist_holds_a_constant_load_exactly(params):
    """Motors held, a constant torque on the end-effector: once at rest, no drift at all."""
    structure = build_wrist(params).assemble()
    load = Table((0.0, 0.5, 12.0), (0.0, 0.05, 0.05))
    r = simulate(structure, {"tau_x": load}, 12.0, initial=InitialState(q=0.005),
                 options=SimulationOptions(friction="stiction"), ports=False)
    assert r.success
    after = r.time >= 2.0
    drift = np.max(np.abs(r["theta_x"][after] - r["theta_x"][after][0]))
    assert drift < 1e-9
    assert abs(r["theta_x"][-1]) > 1e-3  # it did deflect under the load before holding

    slope = simulate(structure, {"tau_x": load}, 12.0, initial=InitialState(q=0.005),
                     options=SimulationOptions(friction="slope", slope_width=1e-3),
                     ports=False)
    creep = abs(slope["theta_x"][-1] - slope["theta_x"][after][0])
    assert creep > 1e-5  # the slope model creeps under the same load
    # ... at the speed its slope predicts: inside the band an element's slip speed is
    # its torque times w over its Coulomb level
    i = int(np.searchsorted(slope.time, 6.0))
    for element in structure.frictions:
        level = element.coulomb
        if level == 0 or element.law is not None:
            continue
        torque = slope[f"friction.{element.name}.torque"][i]
        slip = -slope[f"friction.{element.name}.power"][i] / torque if torque else 0.0
        if abs(torque) < 0.9 * level:
            assert slip == pytest.approx(torque * 1e-3 / level, rel=0.01, abs=1e-12)


def test_breakaway_at_the_predicted_static_level(params):
    structure = benches.planetary_bench(params, fixed="sun", drive="torque").assemble()
    pg = params.planetary
    x = pg.sun_teeth / pg.ring_teeth
    level = math.pi / 2 * (pg.carrier_bearing_stiction + pg.ring_bearing_stiction * (1 + x)
                           + pg.mesh_stiction * (1 + x * x))
    ramp = Table((0.0, 10.0), (0.0, 2 * level))
    r = simulate(structure, {"drive": ramp}, 10.0, ports=False,
                 options=SimulationOptions(friction="stiction", step=1e-4, output_step=1e-4))
    # held exactly (to round-off) until the torque reaches the static level, then it moves
    moving = np.flatnonzero(np.abs(r["carrier.speed"]) > 1e-12)
    assert moving.size
    applied = r["load.motor.torque"][moving[0]]
    assert applied == pytest.approx(level, rel=0.01)
    assert r["carrier.speed"][-1] > 1e-2


def hysteresis_width(result, lo=-0.2, hi=0.2):
    """Mean torque difference between the loading and unloading branches over |phi| < 0.2."""
    phi, torque = result["phi"], result["spring.sensor.compliance.torque"]
    rate = np.gradient(phi, result.time)
    grid = np.linspace(lo, hi, 21)
    up = np.interp(grid, *_branch(phi, torque, rate > 1e-3))
    down = np.interp(grid, *_branch(phi, torque, rate < -1e-3))
    return float(np.mean(up - down))


def _branch(phi, torque, mask):
    order = np.argsort(phi[mask])
    return phi[mask][order], torque[mask][order]


def test_elastic_bench_hysteresis_is_independent_of_speed(params):
    scen = scenarios.load("elastic-bench")
    widths = {}
    for case in scen.cases:
        r = scenarios.prepare_case(scen, case, params).run(ports=False)
        assert r.success
        widths[case.label] = hysteresis_width(r)
    expected = 2 * params.elastic_element.lever_stiction * math.pi / 2  # both branches
    assert widths["slow"] == pytest.approx(expected, rel=0.05)
    assert widths["fast"] == pytest.approx(widths["slow"], rel=0.05)


@pytest.fixture(scope="module")
def fig415_stiction(params):
    scen = scenarios.load("fig-4.15")
    case = scen.cases[0]
    prep = scenarios.prepare_case(scen, case, params)
    structure, inputs = prep.structure, prep.inputs
    runs = {}
    for h in (1e-3, 5e-4, 2.5e-4):
        runs[h] = simulate(structure, inputs, case.duration, initial=case.initial,
                           ports=False,
                           options=SimulationOptions(friction="stiction", step=h,
                                                     output_step=1e-3))
        assert runs[h].success, runs[h].message
    return structure, runs


def test_friction_never_injects_energy_and_the_ledger_closes(fig415_stiction):
    structure, runs = fig415_stiction
    r = runs[1e-3]
    for element in structure.frictions:
        assert np.all(r[f"friction.{element.name}.power"] <= 1e-15)
    assert r.ledger["relative_residual"] < 1e-4
    assert r.ledger["total_dissipated"] > 0.1


def test_stick_slip_transitions_do_not_grow_as_the_step_shrinks(fig415_stiction):
    _, runs = fig415_stiction
    counts = {h: sum(r.transitions.values()) for h, r in runs.items()}
    assert counts[1e-3] > 10  # the scenario does stick and slip
    assert counts[2.5e-4] <= 1.1 * counts[1e-3] + 2
    assert counts[5e-4] <= 1.1 * counts[1e-3] + 2


def _solve_sequence(YT, qs, cap, active):
    """Solve a sequence of impulse problems, each warm-started from the last
    (the time-stepper's use); returns impulses, states and active-set iterations
    (-1 where the solver did not converge)."""
    ps = np.zeros(qs.shape)
    states = np.zeros(qs.shape, np.int64)
    iterations = np.zeros(qs.shape[0], np.int64)
    _core.solve_impulses(np.ascontiguousarray(YT), np.ascontiguousarray(qs), cap, active, ps,
                         states, iterations)
    return ps, states, iterations


def test_impulse_solver_fast_path_gives_exact_coulomb_solutions():
    """Both paths of the impulse solver (last step's pattern, and the active-set
    method when it fails) give impulses that satisfy the Coulomb conditions:
    within the caps, stuck elements' slips zero, slipping elements' impulses at
    the cap in the direction of their slip. Rows include parallel pairs
    (elements in series) and an uninvolved element."""
    rng = np.random.default_rng(7)
    base = rng.normal(size=(2, 4))
    YT = np.concatenate([base, 0.5 * base[:, :2], np.zeros((2, 1))], axis=1)  # 7 elements
    m = YT.shape[1]
    cap = rng.uniform(0.2, 1.0, m)
    active = np.ones(m, dtype=np.bool_)
    active[-1] = False
    # slowly varying free slips, so that the pattern usually survives a step
    t = np.linspace(0.0, 6.0, 600)[:, None]
    qs = 1.5 * np.sin(t * rng.uniform(0.5, 2.0, m) + rng.uniform(0, 6, m))
    qs[:, 4:6] = 0.5 * qs[:, 0:2]  # consistent parallel pairs can stick together
    ps, states, iterations = _solve_sequence(YT, qs, cap, active)
    assert np.all(iterations >= 0)  # every solve converged
    fast = iterations == 0
    assert 0.1 < fast.mean() < 1.0  # both paths are exercised
    slips = qs - ps @ YT.T @ YT
    scale = np.abs(qs).max()
    assert np.all(np.abs(ps) <= cap * (1 + 1e-12))
    assert np.all(ps[:, ~active] == 0.0)
    for k in range(len(qs)):
        for e in np.nonzero(active)[0]:
            if states[k, e] == 0:  # stuck: no slip beyond round-off
                assert abs(slips[k, e]) <= 1e-9 * scale
            else:  # slipping: full impulse, in the direction of the slip
                assert abs(ps[k, e]) == cap[e]
                assert np.sign(ps[k, e]) == states[k, e]
                assert slips[k, e] * states[k, e] >= -1e-9 * scale
    assert (states[:, :-1] == 0).any()  # some elements stick
