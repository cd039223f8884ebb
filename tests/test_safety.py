"""Safety figures (issue 34): the ISO/TS 15066 body model and its closed forms, contact
events from sampled signals, and the head injury criterion against its closed form.

Every case is derivable by hand: a half-sine force pulse (peak F0, impulse 2 F0 T/pi,
duration T), a free mass pushed by it, two masses meeting through a linear spring. The
tolerances come from the trapezoidal rule's error on the sample grid (each derived where
it is used) or from the ODE solver's tolerance.
"""

import math
import re

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from vsj.errors import InputError
from vsj.safety import (
    HIC15_WINDOW,
    HIC36_WINDOW,
    REGIONS,
    STANDARD_GRAVITY,
    Tip,
    contact_events,
    hic,
    hic_half_sine,
    hic_spring_impact,
    reduced_mass,
    region,
    robot_effective_mass,
    series_stiffness,
    transfer_energy_limit,
    transient_speed_limit,
    verdict,
)
from vsj.safety.head_injury import OPTIMAL_HALF_ANGLE
from vsj.safety.iso_ts_15066 import TRANSCRIPTIONS

#: relative tolerance of the ODE solves below (rtol 1e-11, atol scaled to the states):
#: their peaks and integrals are right to about 1e-9; 1e-7 leaves room
SOLVER_RTOL = 1e-7


def half_sine(t, start, duration, peak):
    """``peak sin(pi (t - start)/duration)`` on the pulse, zero elsewhere."""
    phase = (t - start) / duration
    return np.where((phase > 0) & (phase < 1), peak * np.sin(np.pi * phase), 0.0)


# -- the ISO/TS 15066 body model ---------------------------------------------------------

def cited_transcriptions(text):
    """The transcription keys a source text names (``S1``, ranges ``S1-S3`` expanded)."""
    keys = set()
    for first, last in re.findall(r"S(\d)(?:-S(\d))?", text):
        keys |= {f"S{i}" for i in range(int(first), int(last or first) + 1)}
    return keys


def test_every_value_cites_its_table_row_and_a_transcription_that_gives_it():
    """Each number of the body model names the standard's table and row and the
    transcriptions it was read from (and those exist)."""
    for reg in REGIONS.values():
        for name in ("effective_mass", "spring_constant"):
            assert reg.sources[name].startswith("ISO/TS 15066:2016 Table A.3, row "
                                                f"'{reg.title}'"), name
        for name in ("quasi_static_force", "transient_force_factor",
                     "transient_pressure_factor"):
            assert reg.sources[name].startswith("ISO/TS 15066:2016 Table A.2, row "
                                                f"'{reg.title}'"), name
        cited = list(reg.sources.values()) + [a.source for a in reg.areas.values()]
        for text in cited:
            keys = cited_transcriptions(text)
            assert keys and keys <= set(TRANSCRIPTIONS), text
        for area in reg.areas.values():
            assert area.source.startswith(f"ISO/TS 15066:2016 Table A.2, region "
                                          f"'{reg.title}', area '{area.title}'")


def test_the_tables_numbers_arrive_in_si():
    """Tables A.2 and A.3 give N/cm^2 and N/mm: the model holds Pa and N/m (a slip of
    the conversion would shift every speed limit by sqrt(1000))."""
    hand, arm = REGIONS["hand"], REGIONS["lower_arm"]
    assert (hand.effective_mass, hand.spring_constant, hand.quasi_static_force) == \
        (0.6, 75e3, 140.0)
    assert (arm.effective_mass, arm.spring_constant, arm.quasi_static_force) == \
        (2.0, 40e3, 160.0)
    assert hand.areas["thenar_eminence"].quasi_static_pressure == 200e4
    assert arm.areas["radial_bone"].quasi_static_pressure == 190e4


def test_transient_limits_are_twice_the_quasi_static_ones():
    """Table A.2 note c: transient contact may reach twice the quasi-static force and
    pressure, for both regions and every area."""
    for reg in REGIONS.values():
        assert reg.permissible_force("transient") == 2 * reg.permissible_force("quasi-static")
        for name in reg.areas:
            assert reg.permissible_pressure(name, "transient") == \
                2 * reg.permissible_pressure(name, "quasi-static")
    assert REGIONS["hand"].permissible_force() == 280.0  # the default is transient


def test_the_most_sensitive_area_has_the_lowest_pressure_limit():
    for reg in REGIONS.values():
        lowest = min(a.quasi_static_pressure for a in reg.areas.values())
        assert reg.most_sensitive_area.quasi_static_pressure == lowest
        assert reg.permissible_pressure(contact="quasi-static") == lowest


def test_reduced_and_robot_effective_mass():
    """Eq A.3 and A.4 by hand."""
    assert reduced_mass(0.6, 0.6) == pytest.approx(0.3, rel=1e-15)
    assert reduced_mass(2.0, 6.0) == pytest.approx(1.5, rel=1e-15)
    assert reduced_mass(2.0, math.inf) == 2.0
    assert robot_effective_mass(10.0, 1.0) == 6.0
    assert robot_effective_mass(10.0) == 5.0


def test_series_stiffness():
    assert series_stiffness(3.0, 6.0) == pytest.approx(2.0, rel=1e-15)
    assert series_stiffness(75e3, math.inf) == 75e3
    assert series_stiffness(math.inf) == math.inf


def test_speed_limit_by_hand():
    """A 0.6 kg robot on the hand: mu = 0.3 kg, sqrt(mu k) = 150 kg/s, so the transient
    280 N allow 28/15 m/s, and the energy mu v^2/2 equals F^2/(2k) (eq A.1, A.2)."""
    limit = transient_speed_limit("hand", 0.6)
    assert limit.reduced_mass == pytest.approx(0.3, rel=1e-15)
    assert limit.speed == pytest.approx(28 / 15, rel=1e-14)
    assert limit.limited_by == "force" and limit.by_pressure is None
    assert limit.energy == pytest.approx(280.0 ** 2 / (2 * 75e3), rel=1e-14)
    assert transfer_energy_limit("hand") == pytest.approx(limit.energy, rel=1e-14)
    quasi = transient_speed_limit("hand", 0.6, contact="quasi-static")
    assert quasi.speed == pytest.approx(limit.speed / 2, rel=1e-14)


def test_a_small_contact_area_makes_pressure_the_limit():
    """On 0.1 cm^2 the hand's most sensitive area (190 N/cm^2, 380 transient) bears
    38 N: the speed falls to 38/150 m/s and the pressure sets it (eq A.6)."""
    limit = transient_speed_limit("hand", 0.6, contact_area=1e-5)
    assert limit.by_pressure == pytest.approx(38 / 150, rel=1e-14)
    assert limit.speed == limit.by_pressure and limit.limited_by == "pressure"
    palm = transient_speed_limit("hand", 0.6, contact_area=1e-5, area="palm")
    assert palm.by_pressure == pytest.approx(52 / 150, rel=1e-14)
    assert transfer_energy_limit("hand", contact_area=1e-5) == \
        pytest.approx(38.0 ** 2 / (2 * 75e3), rel=1e-14)


def two_body_peak_force(speed, body_mass, robot_mass, stiffness):
    """Peak spring force when a robot mass at ``speed`` meets a resting body through a
    linear spring, integrated numerically (no closed form used)."""
    def rhs(t, y):
        x_r, v_r, x_h, v_h = y
        f = stiffness * max(x_r - x_h, 0.0)
        return [v_r, -f / robot_mass, v_h, f / body_mass]

    def separated(t, y):
        return y[0] - y[2]
    separated.terminal, separated.direction = True, -1
    omega = math.sqrt(stiffness / reduced_mass(body_mass, robot_mass))
    scale = speed / omega
    sol = solve_ivp(rhs, (0.0, 2 * math.pi / omega), [0.0, speed, 0.0, 0.0], method="DOP853",
                    rtol=1e-11, atol=[1e-13 * scale, 1e-13 * speed] * 2, events=separated,
                    dense_output=True)
    assert sol.success
    t = np.linspace(0.0, sol.t[-1], 20001)
    y = sol.sol(t)
    return stiffness * np.max(y[0] - y[2]), sol.t[-1]


@pytest.mark.parametrize("body, robot_mass, stiffness", [
    ("hand", 0.6, None), ("lower_arm", 4.0, None), ("hand", 1.5, 20e3)])
def test_the_speed_limit_brings_the_peak_force_to_the_limit(body, robot_mass, stiffness):
    """Twin: two masses integrated through a linear spring at the closed-form speed limit
    reach exactly the permissible transient force, in half a period of the reduced mass."""
    reg = region(body)
    limit = transient_speed_limit(body, robot_mass, stiffness)
    peak, end = two_body_peak_force(limit.speed, reg.effective_mass, robot_mass,
                                    limit.stiffness)
    # 20001 points over the half period put one within pi/40000 of phase from the peak,
    # where a sine is down by (pi/40000)^2/2 = 3e-9
    assert peak == pytest.approx(reg.permissible_force(), rel=SOLVER_RTOL + 1e-8)
    assert end == pytest.approx(math.pi * math.sqrt(limit.reduced_mass / limit.stiffness),
                                rel=SOLVER_RTOL)


def test_a_softer_contact_allows_a_faster_robot():
    """Comparing stiffness settings: a joint compliance in series with the hand's spring
    lowers the stiffness at the contact, and the speed limit grows as 1/sqrt(k)."""
    stiff = transient_speed_limit("hand", 1.0)
    k_soft = series_stiffness(REGIONS["hand"].spring_constant, 25e3)
    soft = transient_speed_limit("hand", 1.0, stiffness=k_soft)
    assert soft.speed / stiff.speed == pytest.approx(math.sqrt(75e3 / k_soft), rel=1e-14)
    assert soft.speed / stiff.speed == pytest.approx(2.0, rel=1e-14)  # k_soft = 75e3/4


def test_verdict_by_hand():
    hand = verdict("hand", 200.0)
    assert hand.passed and hand.force_limit == 280.0 and hand.pressure is None
    assert not verdict("hand", 200.0, contact="quasi-static").passed
    assert verdict("hand", 280.0).passed  # a maximum permissible value is permitted
    arm = verdict("lower_arm", 100.0, peak_pressure=370e4)
    assert arm.area in ("forearm_muscle", "arm_nerve") and arm.pressure_limit == 360e4
    assert not arm.passed and arm.force_ratio == pytest.approx(100 / 320, rel=1e-15)
    assert verdict("lower_arm", 100.0, peak_pressure=370e4, area="radial_bone").passed
    assert "OVER the limit" in str(arm) and "within the limits" in str(hand)


def test_tip_pressure():
    """A flat tip spreads the force over its area; a sphere of radius R in Hertz contact
    touches pi R d, so a linear contact F = k d presses k/(pi R) at every depth."""
    assert Tip.flat(2e-4).pressure(100.0) == pytest.approx(5e5, rel=1e-15)
    sphere = Tip.sphere(0.01)
    depth = np.array([1e-4, 1e-3, 5e-3])
    assert sphere.pressure(3e4 * depth, depth) == pytest.approx(3e4 / (math.pi * 0.01),
                                                                rel=1e-14)
    assert sphere.area(0.02) == pytest.approx(math.pi * 1e-4, rel=1e-15)  # fully in
    assert sphere.pressure(5.0, 0.0) == math.inf  # a force on a point


# -- contact events --------------------------------------------------------------------

def pulse_run(step=1e-4, start=0.0123, duration=0.0301, peak=150.0, end=0.08):
    """A half-sine force pulse sampled on a grid its ends do not fall on."""
    t = np.arange(0.0, end, step)
    return t, half_sine(t, start, duration, peak)


def test_a_half_sine_pulse_is_one_event_with_its_peak_impulse_and_duration():
    step, start, duration, peak = 1e-4, 0.0123, 0.0301, 150.0
    t, f = pulse_run(step, start, duration, peak)
    [event] = contact_events(t, f)
    assert not event.cut_at_start and not event.cut_at_end
    assert event.resolution == pytest.approx(step, rel=1e-9)
    # the nearest sample is at most h/2 from the peak, where sin falls by 1 - cos(pi h/2T)
    assert peak * math.cos(math.pi * step / (2 * duration)) <= event.peak_force <= peak
    assert abs(event.peak_time - (start + duration / 2)) <= step / 2
    # trapezoid: (pi h/T)^2/12 relative inside the pulse, plus a kink at each end where
    # the rule is off by at most slope h^2/8 = pi F0 h^2/(8T): (5/24)(pi h/T)^2 in all
    tol = (math.pi * step / duration) ** 2 / 4
    assert event.impulse == pytest.approx(2 * peak * duration / math.pi, rel=tol)
    shortest, longest = event.duration_bounds
    assert shortest <= duration <= longest and longest - shortest <= 2 * step + 1e-12
    assert abs(event.duration - duration) <= event.resolution
    assert abs(event.start - start) <= step / 2 + 1e-12


def test_no_contact_no_events():
    t = np.linspace(0.0, 1.0, 101)
    assert contact_events(t, np.zeros_like(t)) == []


def test_an_event_cut_by_the_end_of_the_run():
    """A pulse still on when the run stops: flagged, its longest duration unknown, its
    impulse the integral so far, F0 T/pi (1 - cos(pi tau/T)) for tau in contact."""
    step, start, duration, peak = 1e-4, 0.0123, 0.0301, 150.0
    t, f = pulse_run(step, start, duration, peak, end=0.035)
    [event] = contact_events(t, f)
    assert event.cut_at_end and not event.cut_at_start
    assert event.duration_bounds[1] == math.inf and event.end == t[-1]
    tau = t[-1] - start
    exact = peak * duration / math.pi * (1 - math.cos(math.pi * tau / duration))
    # the same trapezoid bound as a whole pulse's, with one kink instead of two
    assert event.impulse == pytest.approx(exact, rel=(math.pi * step / duration) ** 2 / 4)
    late = t >= 0.02
    [first] = contact_events(t[late] - 0.02, f[late])
    assert first.cut_at_start and first.start == 0.0 and first.duration_bounds[1] == math.inf


def test_two_pulses_are_two_events_in_order():
    t = np.arange(0.0, 0.2, 1e-4)
    f = half_sine(t, 0.0203, 0.03, 100.0) + half_sine(t, 0.1107, 0.02, 60.0)
    first, second = contact_events(t, f)
    assert first.end < second.start
    assert first.peak_force > 99.0 and 59.0 < second.peak_force <= 60.0
    assert second.first > first.last + 1


def test_work_and_energy_of_a_free_body_pushed_by_the_pulse():
    """A free mass m at rest pushed by F0 sin(w t) for T = pi/w reaches v = (F0/(m w))
    (1 - cos w t): the work of the force, and the body's kinetic energy gain, end at
    m (2 F0/(m w))^2 / 2."""
    step, start, duration, peak, mass = 1e-4, 0.0123, 0.0301, 150.0, 0.6
    t, f = pulse_run(step, start, duration, peak)
    w = math.pi / duration
    phase = np.clip(t - start, 0.0, duration)
    velocity = peak / (mass * w) * (1 - np.cos(w * phase))
    [event] = contact_events(t, f, body_velocity=velocity,
                             body_energy=0.5 * mass * velocity ** 2)
    exact = 0.5 * mass * (2 * peak / (mass * w)) ** 2
    # F v = (F0^2/(m w))(sin wt - sin 2wt/2): |(F v)''| <= 3 F0^2 w/m gives (pi/8)(w h)^2
    # inside, and the kink at the end (slope 2 F0^2/m) (1/8)(w h)^2: below (w h)^2
    assert event.work == pytest.approx(exact, rel=(w * step) ** 2)
    assert event.energy == event.work and event.energy_kind == "work"
    # the kinetic energy is sampled, not integrated: its rise is exact at the samples
    assert event.body_energy_gain == pytest.approx(exact, rel=1e-12)
    # a body already holding energy (its spring preloaded, say) gains the same
    [no_work] = contact_events(t, f, body_energy=5.0 + 0.5 * mass * velocity ** 2)
    assert no_work.energy_kind == "body energy" and no_work.energy == no_work.body_energy_gain
    assert no_work.body_energy_gain == pytest.approx(exact, rel=1e-12)
    [bare] = contact_events(t, f)
    assert bare.energy is None and bare.energy_kind is None


def test_joint_deflection_torque_and_end_stop_margin():
    """Peak |deflection| and |torque| of each element over the event, and the margin to
    the stop: negative for an element driven past it."""
    t, f = pulse_run()
    deflection = np.column_stack([0.5 * f / 150.0, -1.5 * f / 150.0])
    torque = 2.0 * deflection
    [event] = contact_events(t, f, deflection=deflection, spring_torque=torque,
                             end_stop=1.4)
    big = np.max(f) / 150.0
    assert event.peak_deflection == pytest.approx((0.5 * big, 1.5 * big), rel=1e-15)
    assert event.peak_spring_torque == pytest.approx((1.0 * big, 3.0 * big), rel=1e-15)
    assert event.end_stop_margin == pytest.approx((1.4 - 0.5 * big, 1.4 - 1.5 * big),
                                                  rel=1e-15)
    assert event.end_stop_margin[1] < 0 < event.end_stop_margin[0]
    [single] = contact_events(t, f, deflection=deflection[:, 0], end_stop=[1.0])
    assert single.end_stop_margin == pytest.approx((1.0 - 0.5 * big,), rel=1e-15)


def test_event_pressure_penetration_and_verdict():
    """A linear contact F = k d under a sphere presses k/(pi R) throughout; the event's
    verdict checks its peaks against the region."""
    t, f = pulse_run(peak=300.0)
    k, radius = 3e4, 0.02  # the deepest point, 1 cm, stays within the radius
    [event] = contact_events(t, f, penetration=f / k, tip=Tip.sphere(radius))
    assert event.peak_pressure == pytest.approx(k / (math.pi * radius), rel=1e-14)
    assert event.peak_penetration == pytest.approx(event.peak_force / k, rel=1e-15)
    judged = event.verdict("hand")
    assert judged.force == event.peak_force and judged.pressure == event.peak_pressure
    assert not judged.passed  # 300 N > 280 N
    [flat] = contact_events(t, f * 0.5, tip=Tip.flat(1e-4))
    assert flat.peak_pressure == pytest.approx(flat.peak_force / 1e-4, rel=1e-15)
    assert flat.verdict("hand", area="palm").passed  # 150 N on 1 cm^2 of 520 N/cm^2


# -- head injury criterion -------------------------------------------------------------

@pytest.mark.parametrize("window", [HIC36_WINDOW, HIC15_WINDOW, 0.004])
def test_sampled_hic_matches_the_half_sine_closed_form(window):
    """On a 10 ms half-sine both long windows keep the unconstrained optimum (0.67 T);
    4 ms binds. Error budget, w = pi/T: the trapezoid's window integral is off by
    (w h)^2/12 relative, 2.5 times that in the HIC; a window end on the grid is off by
    at most h/2, costing 1.25 (w h/2)^2 for a shift and 0.98 (w h/2)^2 for a width
    change at the optimum: (w h)^2 bounds the sum."""
    duration, peak, step = 0.01, 800.0, 1e-5
    t = np.arange(-0.002, duration + 0.002, step)
    a = half_sine(t, 0.0, duration, peak)
    numeric, exact = hic(t, a, window), hic_half_sine(peak, duration, window)
    w = math.pi / duration
    assert numeric.value == pytest.approx(exact.value, rel=(w * step) ** 2)
    assert abs(numeric.start - exact.start) <= step and abs(numeric.end - exact.end) <= step
    assert numeric.end - numeric.start <= window * (1 + 1e-9)
    if window > duration:
        span = 2 * OPTIMAL_HALF_ANGLE / w
        assert exact.end - exact.start == pytest.approx(span, rel=1e-14)
    else:
        assert exact.end - exact.start == pytest.approx(window, rel=1e-14)


def test_sampled_hic_keeps_the_window_limit_on_an_uneven_grid():
    """Samples twice as dense in the first half of the pulse: a window of so many samples
    spans twice as long in the second half, and must still be no longer than W. The
    grid's error bound is that of its coarser half, (w h)^2."""
    duration, peak, step, window = 0.01, 800.0, 2e-5, 0.004
    t = np.concatenate([np.arange(-0.002, 0.005, step / 2), np.arange(0.005, 0.012, step)])
    numeric = hic(t, half_sine(t, 0.0, duration, peak), window)
    exact = hic_half_sine(peak, duration, window)
    assert numeric.end - numeric.start <= window * (1 + 1e-9)
    assert numeric.value == pytest.approx(exact.value, rel=(math.pi / duration * step) ** 2)


def test_half_sine_hic_by_hand():
    """From the definition: the window [T/4, 3T/4] holds (A T/pi) sqrt(2), a mean of
    2 sqrt(2) A/pi for T/2; the whole pulse a mean of 2A/pi for T. The optimum (tan x =
    5x/3) beats both, and a window of T/2 gives the first."""
    peak, duration, g = 500.0, 0.01, STANDARD_GRAVITY
    half = duration / 2 * (2 * math.sqrt(2) * peak / (math.pi * g)) ** 2.5
    whole = duration * (2 * peak / (math.pi * g)) ** 2.5
    assert hic_half_sine(peak, duration, window=duration / 2).value == \
        pytest.approx(half, rel=1e-14)
    best = hic_half_sine(peak, duration, window=HIC15_WINDOW)
    assert math.tan(OPTIMAL_HALF_ANGLE) == pytest.approx(5 / 3 * OPTIMAL_HALF_ANGLE,
                                                         rel=1e-14)
    assert best.value > half and best.value > whole
    # the optimum needs 0.67 T: a window of the whole pulse does not bind
    assert hic_half_sine(peak, duration, window=duration).value == best.value


def test_spring_impact_hic_matches_a_simulated_impact():
    """Twin: a robot mass strikes a free head mass through a linear spring (integrated
    numerically); the sampled HIC of the head's acceleration matches the closed form to
    the solver's tolerance plus the grid's (w h)^2."""
    v, m_head, m_robot, k = 1.0, 4.4, 10.0, 150e3
    mu = reduced_mass(m_head, m_robot)
    w = math.sqrt(k / mu)
    duration = math.pi / w

    def rhs(t, y):
        f = k * max(y[0] - y[2], 0.0)
        return [y[1], -f / m_robot, y[3], f / m_head]

    sol = solve_ivp(rhs, (0.0, 1.2 * duration), [0.0, v, 0.0, 0.0], method="DOP853",
                    rtol=1e-11, atol=1e-15, dense_output=True)
    assert sol.success
    step = duration / 2000
    t = np.arange(0.0, 1.2 * duration, step)
    y = sol.sol(t)
    accel = k * np.clip(y[0] - y[2], 0.0, None) / m_head
    exact = hic_spring_impact(v, m_head, k, robot_mass=m_robot)
    assert hic(t, accel).value == pytest.approx(exact.value, rel=(w * step) ** 2 + SOLVER_RTOL)
    # the peak acceleration of the closed form, v sqrt(mu k)/m_H: a sample lies within
    # pi/4000 of phase from the peak, down by (pi/4000)^2/2 = 3e-7
    assert np.max(accel) == pytest.approx(v * math.sqrt(mu * k) / m_head,
                                          rel=SOLVER_RTOL + 1e-6)


def test_hic_of_no_acceleration_is_zero():
    t = np.linspace(0.0, 0.1, 1001)
    assert hic(t, np.zeros_like(t)).value == 0.0


# -- bad input -------------------------------------------------------------------------

T = np.linspace(0.0, 0.01, 11)
F = np.full(11, 1.0)


@pytest.mark.parametrize("call, words", [
    (lambda: region("foot"), "region 'foot' is not known; known regions: hand, lower_arm"),
    (lambda: verdict("elbow", 10.0), "region 'elbow'"),
    (lambda: reduced_mass(-0.6, 1.0), "body_mass must be > 0"),
    (lambda: reduced_mass(0.6, 0.0), "robot_mass must be > 0"),
    (lambda: transient_speed_limit("hand", -1.0), "robot_mass must be > 0"),
    (lambda: transient_speed_limit("hand", 1.0, stiffness=math.nan), "stiffness must be a "
                                                                        "finite number"),
    (lambda: transient_speed_limit("hand", 1.0, area="palm"), "needs contact_area"),
    (lambda: robot_effective_mass(10.0, -1.0), "payload must be >= 0"),
    (lambda: verdict("hand", 10.0, 1e6, area="knee"), "body area 'knee' is not an area"),
    (lambda: verdict("hand", 10.0, contact="clamped"), "contact must be one of"),
    (lambda: verdict("hand", math.nan), "peak_force must be a finite number"),
    (lambda: contact_events(T, F[:-1]), "force has 10 samples, time has 11"),
    (lambda: contact_events(T, np.where(np.arange(11) == 6, np.nan, 1.0)), "force[6] is nan"),
    (lambda: contact_events(T, -F), "force[0] = -1.0 N is negative"),
    (lambda: contact_events(T[::-1], F), "time must increase strictly"),
    (lambda: contact_events(T, F, body_velocity=F[:5]), "body_velocity has 5 samples"),
    (lambda: contact_events(T, F, deflection=np.ones((11, 2, 2))), "deflection must have "
                                                                      "shape"),
    (lambda: contact_events(T, F, end_stop=1.4), "end_stop needs the deflection"),
    (lambda: contact_events(T, F, deflection=np.ones((11, 2)), end_stop=[1.0, 1.0, 1.0]),
     "end_stop must be one angle"),
    (lambda: contact_events(T, F, tip=Tip.sphere(0.01)), "needs the penetration"),
    (lambda: contact_events(T, F, tip="round"), "tip must be a vsj.safety.Tip"),
    (lambda: Tip.sphere(-0.01), "radius must be > 0"),
    (lambda: Tip("cone", 0.01), "kind must be 'flat' or 'sphere'"),
    (lambda: hic(T, -F), "acceleration[0] = -1.0 m/s^2 is negative"),
    (lambda: hic(T, F, window=1e-4), "no window fits"),
    (lambda: hic_half_sine(100.0, 0.0), "duration must be > 0"),
    (lambda: hic_spring_impact(1.0, -4.4, 1e5), "body_mass must be > 0"),
])
def test_bad_input_is_refused_by_name(call, words):
    with pytest.raises(InputError) as caught:
        call()
    assert words in str(caught.value)
