"""State feedback designed on vsj's linear models (vsj.control.design), run in the C
engine's closed loop (issue 33).

Twin tests: the wrist (nonlinear, C engine, controller in C at 1 kHz) against
python-control's simulation of its linearisation sampled with zero-order hold and closed
with the same controller, for a small step at rest. The wrist here has DC motors, a held
pivot (the plant `vsj.linear.linearize` models), the exponential elastic element (eq 4.5:
linear in the deflection at a fixed pivot) and smooth arctan friction (eq 3.17), whose
linearisation (slope ``b + k k_b`` at rest) is the only approximation: its torque departs
from the linear one by ``k (k_b s - atan(k_b s)) <= (k_b s)^2 / 3`` of itself at slip
speed ``s``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import replace

import control
import numpy as np
import pytest

from vsj import params as vsj_params
from vsj.control import (
    PID,
    Actuator,
    Controller,
    GainSchedule,
    Kalman,
    Luenberger,
    Sensor,
    compile_controller,
    discretize,
    lqr,
    pid_statespace,
    pole_placement,
)
from vsj.errors import InputError
from vsj.inputs import Step
from vsj.linear import linearize
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import WristOptions, build_wrist

PERIOD = 1e-3      # s: the controller's rate, 1 kHz
STEP = 1e-3        # rad: the reference step (issue 33)
DURATION = 0.5     # s: the loops below settle within it
Q0 = 0.01          # m: a compliant setting (K about 0.07 N m/rad, eq 4.5)
#: the issue's bound: 1 % of the step. What fills it: friction's cubic term, below
#: SMALL_SIGNAL**2 / 3 = 0.75 % of the friction torque (each run asserts the premise);
#: the solver (rtol 1e-10) and the linearisation's Jacobian (central differences with
#: Richardson extrapolation, about 1e-8 relative) add under 1e-6 of the step. A loop
#: whose actuators act one sample late moves these responses by more than the bound.
TOLERANCE = 0.01 * STEP
#: largest k_b |s| over the friction elements for the small-signal premise
SMALL_SIGNAL = 0.15
#: tight solver tolerances: integration error far below the 1 % bound
RUN = SimulationOptions(solver="dopri", output_step=PERIOD, rtol=1e-10, atol=1e-14)
MEASURED = ("motor_1", "motor_2", "theta_x", "theta_y")
COMPARED = ("theta_x", "theta_y", "motor_1", "motor_2")
OBSERVER = Kalman({"voltage_1": 1e-2, "voltage_2": 1e-2, "tau_x": 1e-4, "tau_y": 1e-4},
                  {name: 1e-8 for name in MEASURED})
Q_WEIGHTS = {"theta_x": 100.0, "theta_y": 100.0}     # 1/rad^2
R_WEIGHTS = {"voltage_1": 1.0, "voltage_2": 1.0}     # 1/V^2


def _options(q):
    return WristOptions(motors="dc", pivot_drive="fixed", elastic="exponential", fixed_q=q)


@pytest.fixture(scope="module")
def params():
    return vsj_params.load()


@pytest.fixture(scope="module")
def model(params):
    return linearize(params, Q0, wrist_options=_options(Q0))


@pytest.fixture(scope="module")
def wrist(params):
    return build_wrist(params, _options(Q0)).assemble()


@pytest.fixture(scope="module")
def design(model):
    return lqr(model, PERIOD, Q_WEIGHTS, R_WEIGHTS, measured=MEASURED,
               tracked=("theta_x", "theta_y"), observer=OBSERVER)


def _plant(model):
    """The linearised wrist driven by the two motor voltages, sampled with zero-order
    hold by python-control itself."""
    columns = [list(model.input_labels).index(c) for c in ("voltage_1", "voltage_2")]
    continuous = control.ss(model.A, model.B[:, columns], model.C, model.D[:, columns],
                            inputs=["voltage_1", "voltage_2"], outputs=list(model.output_labels),
                            name="plant")
    return control.sample_system(continuous, PERIOD, method="zoh", name="plant_zoh")


def _samples(result):
    n = int(round(DURATION / PERIOD)) + 1
    assert np.allclose(result.time[:n], PERIOD * np.arange(n), rtol=0, atol=1e-12)
    return n


def _small_signal(result, wrist):
    """The largest k_b |slip speed| of the run's friction elements."""
    return max(f.sharpness * np.max(np.abs(result.signals[f"friction.{f.name}.slip"]))
               for f in wrist.frictions if f.k > 0.0)


def _compare(result, response, wrist):
    assert result.success, result.message
    assert _small_signal(result, wrist) <= SMALL_SIGNAL
    n = _samples(result)
    moved = np.max(np.abs(result.signals["theta_x"]))
    assert moved > 0.1 * STEP  # the step moved the output: the comparison is not of zeros
    for name in COMPARED:
        linear = response.outputs[list(response.output_labels).index(name)]
        gap = np.max(np.abs(result.signals[name][:n] - linear))
        assert gap <= TOLERANCE, (name, gap / STEP)


def test_pid_loop_matches_the_linearised_plant(model, wrist):
    """A discrete PID per motor (LimPID within its limits), in the C engine around the
    nonlinear wrist, agrees with python-control's loop of the sampled linear plant and
    the PID as `pid_statespace` gives it, to 1 % of a 1 mrad step of motor 1."""
    pids = (PID("u1", "m1", "motor_1", k=10.0, Ti=0.1, Td=0.01),
            PID("u2", "m2", "motor_2", k=10.0, Ti=0.1, Td=0.01))
    ctl = Controller(PERIOD, (Actuator("voltage_1", "u1"), Actuator("voltage_2", "u2")),
                     sensors=(Sensor("motor_1"), Sensor("motor_2")), blocks=pids,
                     references={"m1": Step(STEP, 0.0), "m2": 0.0})
    result = simulate(wrist, {}, DURATION, controller=ctl, options=RUN)

    blocks = [control.ss(pid_statespace(p, PERIOD), inputs=[f"r{i}", f"motor_{i}"],
                         outputs=[f"voltage_{i}"], name=p.name) for i, p in enumerate(pids, 1)]
    loop = control.interconnect([_plant(model)] + blocks, inplist=["r1", "r2"],
                                outlist=list(COMPARED), outputs=list(COMPARED),
                                check_unused=False)
    t = PERIOD * np.arange(_samples(result))
    reference = np.vstack([np.full(t.size, STEP), np.zeros(t.size)])
    response = control.forced_response(loop, t, reference)
    _compare(result, response, wrist)


def test_lqr_loop_matches_the_linearised_plant(model, wrist, design):
    """The LQR with a Kalman estimator (`lqr`, `StateFeedback.controller`) in the C
    engine around the nonlinear wrist agrees with python-control's loop of the sampled
    linear plant and `StateFeedback.compensator`, to 1 % of a 1 mrad step of theta_x;
    that loop holds theta_x at its reference (steady-state gain 1, none into theta_y)."""
    ctl = design.controller({"theta_x": Step(STEP, 0.0), "theta_y": 0.0})
    result = simulate(wrist, {}, DURATION, controller=ctl, options=RUN)

    loop = control.interconnect([_plant(model), design.compensator()],
                                inplist=["theta_x_ref", "theta_y_ref"], outlist=list(COMPARED),
                                outputs=list(COMPARED), check_unused=False)
    gain = control.dcgain(loop)
    # the steady state solves (I - A) x = B: rounding of eps cond(I - A) relative
    bound = np.finfo(float).eps * np.linalg.cond(np.eye(loop.nstates) - loop.A)
    assert gain[0] == pytest.approx([1.0, 0.0], abs=bound)
    assert gain[1] == pytest.approx([0.0, 1.0], abs=bound)
    t = PERIOD * np.arange(_samples(result))
    reference = np.vstack([np.full(t.size, STEP), np.zeros(t.size)])
    response = control.forced_response(loop, t, reference)
    _compare(result, response, wrist)


def _engine_gain(ctl, wrist, design, model):
    """The state-feedback gain in the arrays the C engine receives: from the compensator
    block ``(Ac, Bc, Cc, Dc)``, ``K = -(Cc + Dc_y C)`` (``Cc = -K (I - L C)``, ``Dc_y =
    -K L``), with ``C`` the measured rows of the model."""
    compiled = compile_controller(ctl, wrist, wrist.channels() + tuple(ctl.references))
    kind, nin, nout, ns = compiled.arrays["blk"][:4]
    assert kind == 1  # a Linear block
    par = compiled.arrays["blk_par"]
    Cc = par[ns * ns + ns * nin:][:nout * ns].reshape(nout, ns)
    Dc = par[ns * ns + ns * nin + nout * ns:].reshape(nout, nin)
    rows = [list(model.output_labels).index(m) for m in design.measured]
    tracked = len(design.tracked)
    return -(Cc + Dc[:, tracked:tracked + len(rows)] @ model.C[rows])


def test_lqr_gains_are_dlqr_of_the_sampled_plant(model, wrist, design):
    """The gain the engine runs equals python-control's ``dlqr`` of the plant sampled
    with zero-order hold, to 1e-9 of its largest entry."""
    sampled = _plant(model)
    Q = sum(w * np.outer(model.C[i], model.C[i]) for i, w in
            ((list(model.output_labels).index(k), w) for k, w in Q_WEIGHTS.items()))
    K, _, _ = control.dlqr(sampled.A, sampled.B, Q, np.diag(list(R_WEIGHTS.values())))
    ctl = design.controller({"theta_x": 0.0, "theta_y": 0.0})
    # K's recovery adds rounding of eps |K| |L| |C| (|L C| ~ 1): far below 1e-9
    assert np.max(np.abs(_engine_gain(ctl, wrist, design, model) - K)) <= 1e-9 * np.max(
        np.abs(K))
    assert np.max(np.abs(design.K - K)) <= 1e-9 * np.max(np.abs(K))


def test_estimator_is_the_current_kalman_filter(model, design):
    """The estimator's gain is the current-form Kalman gain of ``dlqe``'s covariance:
    ``A L`` is python-control's predictor gain from ``dlqe`` on the sampled plant with the
    process noise entering where its inputs do; every estimator pole is inside the unit
    circle."""
    noisy = list(OBSERVER.process_noise)
    columns = [list(model.input_labels).index(c) for c in noisy]
    sampled = control.sample_system(control.ss(model.A, model.B[:, columns], model.C,
                                               model.D[:, columns]), PERIOD, method="zoh")
    rows = [list(model.output_labels).index(m) for m in MEASURED]
    L, _, poles = control.dlqe(sampled.A, sampled.B, model.C[rows],
                               np.diag(list(OBSERVER.process_noise.values())),
                               np.diag([OBSERVER.measurement_noise[m] for m in MEASURED]))
    assert np.max(np.abs(design.A @ design.L - L)) <= 1e-9 * np.max(np.abs(L))
    assert np.max(np.abs(poles)) < 1.0


# Tits-Yang (scipy's place_poles) stops improving the eigenvectors' conditioning after
# its iterations; the poles it placed are checked here
@pytest.mark.filterwarnings("ignore:Convergence was not reached")
def test_pole_placement_places_the_loop_and_the_estimator(model, wrist):
    """`pole_placement` with a `Luenberger` estimator: the requested poles are those of
    the state feedback ``A - B K`` and of the current estimator's error ``A - L C A``,
    and the engine runs the controller."""
    poles = [1e-4, 1.1e-4, 0.43, 0.49, 0.75, 0.76, 0.97, 0.975, 0.98, 0.985]
    observer = Luenberger([0.5e-4, 0.6e-4, 0.3, 0.35, 0.6, 0.65, 0.9, 0.91, 0.92, 0.93])
    placed = pole_placement(model, PERIOD, poles, measured=MEASURED,
                            tracked=("theta_x", "theta_y"), observer=observer)
    A, B, C, K, L = placed.A, placed.B, placed.C_measured, placed.K, placed.L
    norm = lambda M: np.linalg.norm(M, 2)  # noqa: E731
    eps, n = np.finfo(float).eps, A.shape[0]
    for M, wanted, size in ((A - B @ K, poles, norm(A) + norm(B) * norm(K)),
                            (A - L @ C @ A, observer.poles, norm(A) * (1 + norm(L) * norm(C)))):
        # each pole is an eigenvalue of a matrix within rounding (n eps |terms|) of M: a
        # backward error, free of the eigenvectors' conditioning
        for z in wanted:
            assert np.linalg.svd(z * np.eye(n) - M, compute_uv=False)[-1] <= n * eps * size
    ctl = placed.controller({"theta_x": Step(STEP, 0.0), "theta_y": 0.0})
    result = simulate(wrist, {}, 0.2, controller=ctl, options=RUN)
    assert result.success, result.message


def test_operating_point_is_held(params):
    """Around a loaded operating point (motors turned, a torque on each axis), the
    controller's references at the operating point's outputs and sensors reading it give
    the holding voltages: the wrist started there stays there (deviations from the
    operating point are what the compensator sees)."""
    load = (0.002, -0.001)  # N m
    model = linearize(params, Q0, motors=(0.3, -0.1), load=load,
                      wrist_options=_options(Q0))
    design = lqr(model, PERIOD, Q_WEIGHTS, R_WEIGHTS, measured=MEASURED,
                 tracked=("theta_x", "theta_y"), observer=OBSERVER)
    op = model.operating_point
    r0 = {name: op["outputs"][name] for name in ("theta_x", "theta_y")}
    assert min(abs(v) for v in r0.values()) > 1e-3  # a real offset for the test
    ctl = design.controller(r0)
    volts = [a.offset for a in ctl.actuators]
    assert volts == [op["inputs"]["voltage_1"], op["inputs"]["voltage_2"]] and min(map(
        abs, volts)) > 0.0
    states = op["states"]
    initial = InitialState(
        angles={k[:-len(".angle")]: v for k, v in states.items() if k.endswith(".angle")},
        currents={k[:-len(".current")]: v for k, v in states.items() if k.endswith(".current")})
    wrist = build_wrist(params, _options(Q0)).assemble()
    result = simulate(wrist, {"tau_x": load[0], "tau_y": load[1]}, 0.1, controller=ctl,
                      initial=initial, options=RUN)
    assert result.success, result.message
    # an equilibrium to 1e-12 N m (vsj.linear.EQUILIBRIUM_TOL) over a stiffness of ~0.07
    # N m/rad and the solver's rtol 1e-10 leave ~1e-10 rad; a wrong offset moves the
    # output by a fraction of the 1e-3 rad operating point
    for name, value in r0.items():
        assert np.max(np.abs(result.signals[name] - value)) <= 1e-8, name


@pytest.fixture(scope="module")
def schedule(params, model):
    """LQR designs at q = 0.5 cm and 1.5 cm (the test's q = 1 cm lies between)."""
    designs = [lqr(linearize(params, q, wrist_options=_options(q)), PERIOD, Q_WEIGHTS,
                   R_WEIGHTS, measured=MEASURED, tracked=("theta_x", "theta_y"),
                   observer=OBSERVER) for q in (0.015, 0.005)]
    return GainSchedule(designs)


def test_gain_schedule_interpolates_over_the_stiffness_setting(schedule, model, design):
    """Between grid points the schedule's plant and gains are linear in q (midway: the
    mean); at a grid point and with ``nearest`` it is that design; the interpolated
    controller stabilises the linearisation at the commanded q itself."""
    low, high = schedule.designs
    assert (low.q, high.q) == (0.005, 0.015)  # sorted
    middle = schedule.at(Q0)
    assert middle.q == Q0 and "interpolated" in middle.method
    for name in ("K", "L", "A", "B"):
        mean = 0.5 * (getattr(low, name) + getattr(high, name))
        # w = 0.5 exactly up to the rounding of (q - q_low) / (q_high - q_low)
        assert np.max(np.abs(getattr(middle, name) - mean)) <= 1e-12 * np.max(np.abs(mean))
    assert schedule.at(0.005) is low and schedule.at(0.0101, "nearest") is high
    # the commanded q's own plant (sampled), closed by the interpolated compensator
    loop = control.interconnect([_plant(model), middle.compensator()],
                                inplist=["theta_x_ref", "theta_y_ref"], outlist=["theta_x"],
                                check_unused=False)
    assert np.max(np.abs(loop.poles())) < 1.0
    # the exact design differs: the schedule is an approximation between grid points
    assert np.max(np.abs(middle.K - design.K)) > 1e-6 * np.max(np.abs(design.K))
    ctl = schedule.controller(Q0, {"theta_x": 0.0, "theta_y": 0.0})
    assert ctl.period == PERIOD and [a.channel for a in ctl.actuators] == ["voltage_1",
                                                                          "voltage_2"]


def test_gain_schedule_refusals(schedule, design):
    with pytest.raises(InputError, match=r"q = 0.02 m is outside the schedule's grid"):
        schedule.at(0.02)
    with pytest.raises(InputError, match="interpolation must be"):
        schedule.at(Q0, "cubic")
    with pytest.raises(InputError, match="two pivot positions"):
        GainSchedule([design])
    with pytest.raises(InputError, match="same pivot position"):
        GainSchedule([design, design])
    other = dataclasses.replace(design, measured=("motor_1", "motor_2", "theta_x",
                                                  "theta_y.speed"), q=0.02)
    with pytest.raises(InputError, match=r"designs\[1\]: its measured"):
        GainSchedule([design, other])


def _lqr(model, **changes):
    args = dict(Q=Q_WEIGHTS, R=R_WEIGHTS, measured=MEASURED, tracked=("theta_x", "theta_y"),
                observer=OBSERVER)
    args.update(changes)
    return lqr(model, changes.pop("period", PERIOD), **{k: v for k, v in args.items()
                                                        if k != "period"})


def test_designs_that_cannot_stabilise_are_refused(model):
    """A design that cannot stabilise the plant, or whose estimator is unstable, is
    refused with an InputError naming the argument at fault, never returned."""
    # one motor cannot hold both axes: motor 2's angle (a pole at z = 1) is out of reach
    with pytest.raises(InputError, match=r"controlled: the controlled signals cannot move "
                                         r"the modes z = 1 "):
        _lqr(model, controlled=("voltage_1",), tracked=("theta_x",), R={"voltage_1": 1.0})
    # Q weighs theta_x only: the LQR leaves the other axis drifting
    with pytest.raises(InputError, match=r"Q: the LQR leaves a mode of modulus 1"):
        _lqr(model, Q={"theta_x": 100.0})
    # one encoder cannot see both motors' angles
    with pytest.raises(InputError, match=r"measured: the measured signals cannot see"):
        _lqr(model, measured=("motor_1",),
             observer=Kalman(OBSERVER.process_noise, {"motor_1": 1e-8}))
    # an estimator pole outside the unit circle
    with pytest.raises(InputError, match=r"observer.poles: pole 1.02 has modulus 1.02 >= 1"):
        _lqr(model, observer=Luenberger([0.1] * 9 + [1.02]))
    # a state-feedback pole outside the unit circle
    with pytest.raises(InputError, match=r"^poles: pole -1.5 has modulus 1.5"):
        pole_placement(model, PERIOD, [0.5] * 9 + [-1.5], measured=MEASURED,
                       tracked=("theta_x", "theta_y"), observer=OBSERVER)
    # motor encoders alone: the loop is stable though its compensator is not; that is
    # no refusal (the loop is what counts), and its Linear block says so
    design = _lqr(model, Q={"theta_x": 1e4, "theta_y": 1e4}, measured=("motor_1", "motor_2"),
                  observer=Kalman(OBSERVER.process_noise, {"motor_1": 1e-8, "motor_2": 1e-8}))
    assert np.max(np.abs(np.linalg.eigvals(design.compensator().A))) > 1.0
    assert np.max(np.abs(design.closed_loop_poles())) < 1.0
    block = design.controller({"theta_x": 0.0, "theta_y": 0.0}).blocks[0]
    assert block.allow_unstable
    with pytest.raises(InputError, match="controller itself is unstable"):
        replace(block, allow_unstable=False).matrices(PERIOD)


def test_period_the_plant_cannot_be_sampled_at():
    """An undamped 50 Hz oscillator sampled every half period (omega T = pi) loses its
    controllability (A_d = -I): refused naming the period; at 0.9 of it the design
    works."""
    w = 2 * math.pi * 50.0
    oscillator = control.ss([[0.0, w], [-w, 0.0]], [[0.0], [1.0]], [[1.0, 0.0]], 0.0,
                            inputs=["u"], outputs=["y"])
    kwargs = dict(controlled=("u",), measured=("y",),
                  observer=Kalman({"u": 1.0}, {"y": 1e-6}))
    with pytest.raises(InputError, match=r"period 0.01 s: sampled at this period the plant "
                                         r"loses controllability"):
        lqr(oscillator, math.pi / w, {"y": 1.0}, {"u": 1.0}, **kwargs)
    with pytest.raises(InputError, match=r"period 0.01 s: .*\(pathological sampling"):
        pole_placement(oscillator, math.pi / w, [0.5, 0.6], controlled=("u",),
                       measured=("y",), observer=Luenberger([0.1, 0.2]))
    fine = lqr(oscillator, 0.9 * math.pi / w, {"y": 1.0}, {"u": 1.0}, **kwargs)
    assert np.max(np.abs(fine.closed_loop_poles())) < 1.0
    for bad in (0.0, -1e-3, math.nan, math.inf, "1 ms"):
        with pytest.raises(InputError, match="^period must be"):
            lqr(oscillator, bad, {"y": 1.0}, {"u": 1.0}, **kwargs)
    unstable = control.ss([[1e3]], [[1.0]], [[1.0]], 0.0, inputs=["u"], outputs=["y"])
    with pytest.raises(InputError, match=r"period 1 s: the model sampled at this period is "
                                         r"not finite"):
        discretize(unstable, 1.0)


@pytest.mark.parametrize("changes, message", [
    (dict(measured=("theta_z",)), r"measured: unknown signal 'theta_z'"),
    (dict(measured=("theta_x_speed",)), r"measured: spell the speed 'theta_x_speed' as a "
                                        r"run names it: theta_x.speed"),
    (dict(measured=("vsm_1.torque",)), r"measured: 'vsm_1.torque' cannot be measured"),
    (dict(controlled=("voltage_s", "voltage_1")), r"controlled: unknown input 'voltage_s'"),
    (dict(tracked=("theta_x",)), r"tracked: 1 tracked outputs and 2 controlled inputs"),
    (dict(Q={"theta_q": 1.0}), r"Q: unknown name 'theta_q'"),
    (dict(Q={"theta_x": -1.0}), r"Q\['theta_x'\] must be a finite weight >= 0"),
    (dict(R={"voltage_1": 1.0}), r"R must be positive definite"),
    (dict(observer="kalman"), r"observer must be a vsj.control.Kalman or Luenberger"),
    (dict(observer=Kalman({"voltage_1": 1.0}, {"motor_1": 1e-8})),
     r"observer.measurement_noise: give a variance for each measured signal .*missing"),
    (dict(observer=Kalman({"voltage_9": 1.0}, {m: 1e-8 for m in MEASURED})),
     r"observer.process_noise: unknown input 'voltage_9'"),
    (dict(observer=Kalman({"voltage_1": 1.0}, {m: 0.0 for m in MEASURED})),
     r"every variance must be > 0"),
    (dict(observer=Luenberger([0.5] * 3)), r"observer.poles: 3 poles given, the model has "
                                           r"10 states"),
])
def test_bad_design_inputs_name_the_argument(model, changes, message):
    with pytest.raises(InputError, match=message):
        _lqr(model, **changes)


def test_bad_controller_inputs_name_the_argument(design):
    with pytest.raises(InputError, match=r"references: give one for each tracked output; "
                                         r"missing 'theta_y'"):
        design.controller({"theta_x": 0.0})
    with pytest.raises(InputError, match=r"references: 'psi_1' not tracked"):
        design.controller({"theta_x": 0.0, "theta_y": 0.0, "psi_1": 0.0})
    with pytest.raises(InputError, match=r"sensors\['motor_1'\] measures the angle of "
                                         r"'motor_2'"):
        design.controller({"theta_x": 0.0, "theta_y": 0.0},
                          sensors={"motor_1": Sensor("motor_2")})
    with pytest.raises(InputError, match=r"limits: 'voltage_s' not controlled"):
        design.controller({"theta_x": 0.0, "theta_y": 0.0}, limits={"voltage_s": (-1, 1)})
    encoder = Sensor.encoder("motor_1", 4096)
    ctl = design.controller({"theta_x": 0.0, "theta_y": 0.0}, sensors={"motor_1": encoder},
                            limits={"voltage_1": (-12.0, 12.0)})
    assert ctl.sensors[0] is encoder and ctl.actuators[0].limits == (-12.0, 12.0)


def test_pid_statespace_is_the_limpid_law():
    """`pid_statespace` of a PID: proportional on wp r - y, a forward-Euler integral of
    r - y over Ti, and the derivative of wd r - y through Td s / (1 + s Td / Nd) sampled
    exactly (a step of the measurement: a kick of -k Nd decaying by exp(-T Nd / Td) per
    sample)."""
    pid = PID("u", "r", "y", k=2.0, Ti=0.5, Td=0.02, Nd=8.0, wp=0.7, wd=0.3)
    system = pid_statespace(pid, PERIOD)
    assert system.dt == PERIOD
    n = 6
    response = control.forced_response(system, PERIOD * np.arange(n),
                                       np.vstack([np.zeros(n), np.ones(n)]))
    decay = math.exp(-PERIOD * 8.0 / 0.02)
    k = np.arange(n)
    integral = -PERIOD * k / 0.5                        # the integral lags one sample
    derivative = -8.0 * decay ** k                      # N_d (e_d - filter state)
    expected = 2.0 * (-1.0 + integral + derivative)
    assert np.allclose(response.outputs, expected, rtol=1e-12, atol=1e-12)
    with pytest.raises(InputError, match="pid must be a vsj.control.PID"):
        pid_statespace("u", PERIOD)
    with pytest.raises(InputError, match=r"controller block 'u': Ti must be a finite number "
                                         r"> 0"):
        pid_statespace(dataclasses.replace(pid, Ti=-1.0), PERIOD)
