"""The sampled controller in the engine (engine/c/control.c, vsj.control): when it
samples, what it holds, what its sensors read, what its blocks compute, and what it
refuses. The wrist's controllers, their design and scenario files have their own files
(test_control_*.py)."""

import math

import control
import numpy as np
import pytest

from vsj.components import Bearing, DCMotor, Inertia, TorqueSource
from vsj.control import PID, Actuator, Controller, Linear, Sensor
from vsj.engine.core import native
from vsj.engine.plan import Plan, run_batch
from vsj.errors import InputError
from vsj.inputs import Constant, Hold, Sine, Step
from vsj.network import Network, Signal

from test_c_api import engine_objects, step_wrist  # noqa: F401  (fixtures: the C example)
from vsj.simulate import InitialState, SimulationOptions, simulate

R, L, KT, J_ROTOR, GEAR, J_LOAD, B_LOAD = 2.0, 2e-4, 0.025, 1e-6, 10.0, 1e-4, 2e-3
PERIOD = 1e-3


def motor_axis(stiction: float = 0.0) -> Network:
    """One DC motor (voltage ``v``) turning a load with a viscous bearing, an external
    torque ``tau`` on the load and, with ``stiction``, a Coulomb level there."""
    net = Network("axis")
    net.add(DCMotor("m", resistance=R, inductance=L, torque_constant=KT, rotor_inertia=J_ROTOR,
                    gear_ratio=GEAR, channel="v"), Inertia("load", J_LOAD),
            Bearing("b", viscous=B_LOAD, stiction=stiction), TorqueSource("ext", "tau"))
    net.connect("m.flange", "load.flange").connect("m.flange", "b.flange")
    net.connect("m.flange", "ext.flange")
    net.signal(Signal("angle", "load.flange", "load angle"))
    return net


def position_pid(**pid) -> Controller:
    settings = dict(k=40.0, Ti=0.05, Td=0.005, y_min=-12.0, y_max=12.0)
    settings.update(pid)
    return Controller(period=PERIOD, references={"r": Step(1.0, 0.01)},
                      sensors=(Sensor("angle"),),
                      blocks=(PID("u", "r", "angle", **settings),),
                      actuators=(Actuator("v", "u", limits=(-12.0, 12.0)),))


def run(controller, duration=0.3, solver="dopri", net=None, inputs=None, **options):
    options.setdefault("output_step", PERIOD / 4)
    return simulate((net or motor_axis()).assemble(), inputs or {}, duration,
                    controller=controller, ports=False,
                    options=SimulationOptions(solver=solver, friction="viscous", **options))


def sample_rows(result, period=PERIOD):
    """Indices of the output samples that fall on the controller's samples."""
    k = np.round(result.time / period)
    return np.flatnonzero(np.abs(result.time - k * period) < 1e-9 * period)


@pytest.mark.parametrize("solver", ["dopri", "rosenbrock", "timestep"])
def test_actuators_hold_between_samples_and_change_only_at_them(solver):
    r = run(position_pid(), solver=solver, step=PERIOD / 8)
    assert r.success, r.message
    u = r["actuator.v"]
    changes = np.flatnonzero(np.diff(u) != 0.0) + 1
    on_samples = set(sample_rows(r).tolist())
    assert len(changes) > 10
    # a held value is the same double until the next sample: every change sits on one
    assert set(changes.tolist()) <= on_samples
    # the loop works: the load reaches the reference (integral action) with the limits
    assert abs(r["angle"][-1] - 1.0) < 0.01


#: rtol of the runs that two checks below compare with each other (atol 1e-2 of it):
#: tighter than the default, so that a voltage applied at a wrong instant stands out
#: against the solvers' own difference
PAIRED_RTOL = 1e-8


def test_a_closed_loop_equals_its_actuator_values_replayed_open_loop():
    closed = run(position_pid(), output_step=PERIOD, rtol=PAIRED_RTOL, atol=1e-2 * PAIRED_RTOL)
    rows = sample_rows(closed)
    assert len(rows) == len(closed.time)
    replay = Hold(tuple(closed.time), tuple(closed["actuator.v"]))
    opened = run(None, net=motor_axis(), inputs={"v": replay}, output_step=PERIOD,
                 rtol=PAIRED_RTOL, atol=1e-2 * PAIRED_RTOL)
    assert opened.success and closed.success
    # both are dopri runs at PAIRED_RTOL whose steps end on the same voltage edges (the
    # hold's edges sit 1e-9 of a period late): they agree to the solver's tolerance
    # over the run's range of 1 rad
    tol = 100 * PAIRED_RTOL
    assert np.max(np.abs(opened["angle"] - closed["angle"])) < tol


def limpid(readings, refs, period, k, Ti, Td, Nd, wp, wd, y_min, y_max, Ni, mode):
    """The sampled LimPID as its docstring states it, in plain Python."""
    xi, xd, out = 0.0, None, []
    for n, (y, r) in enumerate(zip(readings, refs)):
        e, ep, ed = r - y, wp * r - y, wd * r - y
        if xd is None:
            xd = ed
        d = Nd * (ed - xd) if Td > 0 else 0.0
        xd = ed + (xd - ed) * math.exp(-period * Nd / Td) if Td > 0 else ed
        u = k * (ep + xi + d)
        lim = min(max(u, y_min), y_max)
        rate = e
        if mode == "back-calculation":
            rate += (lim - u) / (k * Ni)
        elif mode == "clamping" and lim != u and (u - lim) * k * e > 0:
            rate = 0.0
        xi += period * rate / Ti
        out.append(lim)
    return np.array(out)


@pytest.mark.parametrize("mode", ["back-calculation", "clamping", "none"])
def test_the_pid_computes_the_sampled_limpid(mode):
    settings = dict(k=40.0, Ti=0.05, Td=0.005, Nd=8.0, wp=0.7, wd=0.3, y_min=-3.0, y_max=3.0,
                    Ni=0.9)
    r = run(position_pid(anti_windup=mode, **settings), output_step=PERIOD)
    rows = sample_rows(r)
    expected = limpid(r["control.angle"][rows], r["control.r"][rows], PERIOD,
                      mode=mode, **settings)
    # the same arithmetic on the same readings: only the order of a few operations
    # differs, so the outputs agree to a few ulps of the output's scale
    assert np.max(np.abs(r["control.u"][rows] - expected)) < 1e-12 * 3.0
    assert np.any(np.abs(r["control.u"][rows]) == 3.0)  # the limits were reached


def overshoot(result, target=1.0):
    return float(np.max(result["angle"]) - target)


def test_anti_windup_keeps_the_overshoot_far_below_a_winding_up_pid():
    limited = dict(k=40.0, Ti=0.02, Td=0.005, y_min=-2.0, y_max=2.0)
    with_aw = run(position_pid(anti_windup="back-calculation", **limited), duration=1.0)
    without = run(position_pid(anti_windup="none", **limited), duration=1.0)
    clamped = run(position_pid(anti_windup="clamping", **limited), duration=1.0)
    assert with_aw.success and without.success and clamped.success
    # the criterion, measured on this pair: at least 5x less overshoot
    assert overshoot(without) > 5 * max(overshoot(with_aw), 1e-3)
    assert overshoot(without) > 5 * max(overshoot(clamped), 1e-3)


def test_sensors_quantise_delay_and_add_seeded_noise():
    counts = 500
    sensors = (Sensor("angle", name="exact"), Sensor.encoder("angle", counts, name="encoder"),
               Sensor("angle", delay=3, name="late"),
               Sensor("angle", noise=0.01, name="noisy"),
               Sensor("m", "current", name="i"))
    ctl = Controller(period=PERIOD, references={"r": Sine(amplitude=1.0, frequency=2.0)},
                     sensors=sensors, blocks=(PID("u", "r", "exact", k=20.0),),
                     actuators=(Actuator("v", "u"),), seed=7)
    r = run(ctl, duration=1.0, output_step=PERIOD)
    rows = sample_rows(r)
    exact, enc = r["control.exact"][rows], r["control.encoder"][rows]
    res = 2 * math.pi / counts
    # encoder: a whole number of counts, the nearest one
    assert np.allclose(enc / res, np.round(enc / res), atol=1e-9)
    assert np.max(np.abs(enc - exact)) <= res / 2 * (1 + 1e-9)
    # delay: three samples late, the first reading repeated before that
    late = r["control.late"][rows]
    assert np.array_equal(late[3:], exact[:-3]) and np.all(late[:3] == exact[0])
    # noise: zero mean and the given deviation, within the sampling error of 1000 draws
    noise = r["control.noisy"][rows] - exact
    n = len(noise)
    assert abs(noise.mean()) < 4 * 0.01 / math.sqrt(n)
    assert abs(noise.std() / 0.01 - 1) < 4 / math.sqrt(2 * n)
    # the current sensor reads the state
    assert np.allclose(r["control.i"][rows], r["motor.m.current"][rows], rtol=0, atol=0)
    # the same seed gives the same bits, another seed other noise
    again = run(ctl, duration=1.0, output_step=PERIOD)
    assert np.array_equal(again["control.noisy"], r["control.noisy"])
    other = run(Controller(**{**ctl.__dict__, "seed": 8}), duration=1.0, output_step=PERIOD)
    assert not np.array_equal(other["control.noisy"], r["control.noisy"])


def test_a_current_limit_bounds_the_voltage_by_the_back_emf():
    i_max = 0.5
    ctl = Controller(period=PERIOD, references={"r": Step(2.0, 0.01)},
                     sensors=(Sensor("angle"),),
                     blocks=(PID("u", "r", "angle", k=100.0),),
                     actuators=(Actuator("v", "u", limits=(-24.0, 24.0), current_limit=i_max),))
    r = run(ctl, output_step=PERIOD)
    rows = sample_rows(r)
    v, w = r["actuator.v"][rows], r["motor.m.speed"][rows]
    # at each sample the voltage keeps the steady current (V - k_t w) / R within the limit
    assert np.all(np.abs(v - KT * w) <= R * i_max * (1 + 1e-12))
    assert np.any(np.abs(v - KT * w) >= R * i_max * (1 - 1e-12))  # and the limit acted


def test_the_voltage_limits_win_over_a_current_limit_and_wide_blocks_run():
    """A back-driven motor's emf would let the current limit ask for far more than the
    supply: the actuator's limits are applied last. A block with more inputs than the
    bus has signals (a wide gain row) runs in the engine's scratch."""
    ctl = Controller(period=PERIOD, sensors=(Sensor("angle", "speed"),),
                     blocks=(PID("u", {}, "angle.speed", k=1.0, y_min=-12, y_max=12),
                             Linear("wide", np.full((1, 40), 0.01), inputs=("u",) * 40,
                                    outputs=("w",))),
                     actuators=(Actuator("v", {"u": 1.0, "w": 0.0}, limits=(-12.0, 12.0),
                                         current_limit=1.0),))
    r = run(ctl, duration=0.2, inputs={"tau": -3.0})
    assert r.success, r.message
    assert np.max(np.abs(r["actuator.v"])) <= 12.0
    assert np.max(np.abs(r["actuator.v"])) == 12.0  # the limit acted
    assert r["control.w"][-1] == pytest.approx(0.4 * r["control.u"][-1], rel=1e-12)


def test_a_linear_block_runs_python_controls_discrete_system():
    # a lead compensator with a pure delay, discretised at the period
    lead = control.c2d(control.tf([0.02, 1.0], [0.002, 1.0]), PERIOD, "tustin")
    system = lead * control.tf([1.0], [1.0, 0.0], PERIOD) * 20.0
    ctl = Controller(period=PERIOD, references={"r": Step(1.0, 0.01)},
                     sensors=(Sensor("angle"),),
                     blocks=(Linear("comp", system, inputs=({"r": 1.0, "angle": -1.0},),
                                    outputs=("u",)),),
                     actuators=(Actuator("v", "u", limits=(-12.0, 12.0)),))
    r = run(ctl, output_step=PERIOD)
    assert r.success
    rows = sample_rows(r)
    error = r["control.r"][rows] - r["control.angle"][rows]
    response = control.forced_response(control.ss(system), U=error).outputs
    # python-control's state space and the engine's sums: a few ulps per sample,
    # accumulated over a stable system's memory
    assert np.max(np.abs(r["control.u"][rows] - response)) < 1e-10 * np.max(np.abs(response))
    # an integrator's pole sits on the unit circle: a PI as a transfer function runs
    pi = Linear("pi", control.tf([2.0, -1.9], [1.0, -1.0], PERIOD), ("r",), ("u",))
    assert pi.matrices(PERIOD)[0].shape == (1, 1)


def test_stiction_and_a_controller_close_the_ledger():
    r = run(position_pid(), solver="timestep", step=1e-4, net=motor_axis(stiction=2e-3),
            duration=0.5, output_step=PERIOD / 2)
    assert r.success, r.message
    assert abs(r.ledger["relative_residual"]) <= 1e-6
    # the controller's work enters through the motor's supply
    assert r.ledger["work_in"]["motor m (electric)"] > 0
    assert r.ledger["dissipated"]["friction b"] > 0


def test_batches_and_blocks_give_the_bits_of_a_single_run():
    structure = motor_axis().assemble()
    opts = SimulationOptions(friction="viscous", output_step=PERIOD)
    plan = Plan.compile(structure, {}, 0.2, opts, InitialState(), "dopri",
                        controller=position_pid())
    times = np.arange(201) * PERIOD
    single = plan.start(ledger=False)
    whole, _, _ = single.advance(times, finish=True)
    split = plan.start(ledger=False)
    first, _, _ = split.advance(times[:77], finish=False)
    second, _, _ = split.advance(times[77:], finish=True)
    assert np.array_equal(np.vstack([first, second]), whole)
    batch = run_batch([plan, plan], times, threads=2)
    assert np.array_equal(batch.states[1], whole)  # the state, then the controller's columns


@pytest.mark.parametrize("change, message", [
    (dict(period=-1e-3), "period must be a finite number > 0"),
    (dict(actuators=()), "drives nothing"),
    (dict(actuators=(Actuator("nope", "u"),)), "not a motor's voltage or a load's torque"),
    (dict(actuators=(Actuator("v", "missing"),)), "unknown signal 'missing'"),
    (dict(actuators=(Actuator("v", "u"), Actuator("v", "u"))), "two actuators drive 'v'"),
    (dict(actuators=(Actuator("tau", "u", current_limit=1.0),)), "needs a motor's channel"),
    (dict(actuators=(Actuator("v", "u", limits=(5.0, -5.0)),)), "limits need low < high"),
    (dict(sensors=(Sensor("nowhere"),)), "unknown signal 'nowhere'"),
    (dict(sensors=(Sensor("angle", delay=-1),)), "delay must be a whole number"),
    # beyond what the engine's arrays hold: refused here, not by the binding's ValueError
    (dict(sensors=(Sensor("angle", delay=10 ** 9),)), r"in 0\.\.100000000, got 1000000000"),
    (dict(sensors=(Sensor("angle", delay=6 * 10 ** 7), Sensor("angle", delay=6 * 10 ** 7,
                                                               name="late"))),
     "delays add up to 120000000 samples"),
    (dict(sensors=(Sensor("angle", quantity="torque"),)), "quantity must be one of"),
    (dict(blocks=(PID("u", "r", "angle", k=1.0, Ti=-1.0),)), "Ti must be a finite number > 0"),
    (dict(blocks=(PID("u", "r", "angle", k=1.0, anti_windup="maybe"),)), "anti_windup"),
    (dict(blocks=(PID("u", "r", "u", k=1.0),)), "unknown signal 'u'"),
    (dict(blocks=(PID("angle", "r", "angle", k=1.0),)), "names used twice"),
    (dict(blocks=(Linear("l", control.tf([1.0], [1.0, -1.5], PERIOD), ("r",), ("u",)),)),
     "unstable"),
    (dict(blocks=(Linear("l", control.tf([1.0], [1.0, 0.5]), ("r",), ("u",)),)),
     "continuous"),
    (dict(blocks=(Linear("l", control.tf([1.0], [1.0, 0.5], 2e-3), ("r",), ("u",)),)),
     "sample time"),
])
def test_bad_controllers_are_refused_naming_what_is_wrong(change, message):
    base = position_pid()
    bad = Controller(**{**base.__dict__, **change})
    with pytest.raises(InputError, match=message):
        run(bad, duration=0.01)


def test_the_time_steppers_step_must_divide_the_period():
    with pytest.raises(InputError, match="must divide it"):
        run(position_pid(), solver="timestep", step=3e-4, output_step=3e-3, duration=0.03)
    with pytest.raises(InputError, match="cannot sample faster"):
        run(position_pid(), solver="timestep", step=2e-3, output_step=2e-3, duration=0.01)


def test_an_input_the_controller_drives_is_refused():
    with pytest.raises(InputError, match="driven by the controller"):
        run(position_pid(), inputs={"v": Constant(1.0)}, duration=0.01)


def test_the_engine_refuses_block_sizes_beyond_the_models():
    """Sizes that would overflow the parameter count's arithmetic are refused before any
    is multiplied (a crafted model through the binding)."""
    structure = motor_axis().assemble()
    plan = Plan.compile(structure, {}, 0.01, SimulationOptions(), InitialState(), "dopri",
                        controller=position_pid())
    blk = plan.model.blk.copy().reshape(-1, 6)
    blk[0, 3] = 3 * 2 ** 61  # a block's states
    with pytest.raises(ValueError, match="do not fit its kind or the model's sizes"):
        native(plan.model._replace(blk=blk.reshape(-1)))
    with pytest.raises(InputError, match="controllers of different sizes"):
        run_batch([plan, Plan.compile(structure, {}, 0.01, SimulationOptions(), InitialState(),
                                      "dopri")], np.zeros(1))


def test_the_engine_refuses_a_block_that_reads_a_later_output():
    structure = motor_axis().assemble()
    plan = Plan.compile(structure, {}, 0.01, SimulationOptions(), InitialState(), "dopri",
                        controller=position_pid())
    blk_in = plan.model.blk_in.copy().reshape(3, -1)
    blk_in[0, -1] = 1.0  # the PID's set-point reads its own output
    with pytest.raises(ValueError, match="reads references, measurements and earlier"):
        native(plan.model._replace(blk_in=blk_in.reshape(-1)))


def test_simulate_batch_closes_each_runs_loop():
    from vsj.simulate import simulate_batch

    structure = motor_axis().assemble()
    opts = SimulationOptions(friction="viscous", output_step=PERIOD)
    starts = [InitialState(), InitialState(angles={"load.flange": 0.5})]
    batch = simulate_batch(structure, {}, 0.2, initials=starts, options=opts,
                           controller=position_pid(), threads=2)
    assert batch.success.all()
    for r, start in enumerate(starts):
        single = simulate(structure, {}, 0.2, options=opts, initial=start,
                          controller=position_pid(), ports=False)
        # the same plan run alone: the same steps, the same bits
        assert np.array_equal(batch["actuator.v"][r], single["actuator.v"])
        assert np.array_equal(batch["angle"][r], single["angle"])
    assert not np.array_equal(batch["control.u"][0], batch["control.u"][1])
    assert "actuator.v" in batch.to_xarray()


def test_a_python_callback_closes_the_same_loop_as_the_engines_pid():
    from vsj.control.callback import run_callback
    from vsj.stepper import Stepper

    settings = dict(k=40.0, Ti=0.05, Td=0.005, Nd=10.0, wp=1.0, wd=0.0, y_min=-12.0,
                    y_max=12.0, Ni=0.9)
    reference = Step(1.0, 0.01)
    state = {"xi": 0.0, "xd": None}

    def pid(t, signals):  # the sampled LimPID, back-calculation, as in `limpid`
        r, y = float(reference.value(t)), signals["angle"]
        e = r - y
        if state["xd"] is None:
            state["xd"] = -y
        d = settings["Nd"] * (-y - state["xd"])
        state["xd"] = -y + (state["xd"] + y) * math.exp(-PERIOD * settings["Nd"] / settings["Td"])
        u = settings["k"] * (e + state["xi"] + d)
        lim = min(max(u, -12.0), 12.0)
        state["xi"] += PERIOD * (e + (lim - u) / (settings["k"] * settings["Ni"])) / settings["Ti"]
        return {"v": lim}

    stepper = Stepper(motor_axis().assemble(), PERIOD,
                      options=SimulationOptions(friction="viscous", rtol=PAIRED_RTOL,
                                                atol=1e-2 * PAIRED_RTOL))
    by_python = run_callback(stepper, pid, 0.3)
    assert by_python.success and by_python.per_call > 0
    in_c = run(position_pid(**settings), output_step=PERIOD, rtol=PAIRED_RTOL,
               atol=1e-2 * PAIRED_RTOL)
    # two dopri integrations at PAIRED_RTOL of the same held voltages: they agree to the
    # solver's tolerance over the run's 1 rad
    assert np.max(np.abs(by_python["angle"] - in_c["angle"])) < 100 * PAIRED_RTOL
    # the voltages: the angles' difference through gains up to k Nd = 400 V/rad
    gain = settings["k"] * settings["Nd"]
    assert np.max(np.abs(by_python["v"] - in_c["actuator.v"])) < gain * 100 * PAIRED_RTOL
    with pytest.raises(InputError, match="unknown channel 'volts'"):
        run_callback(stepper, lambda t, s: {"volts": 1.0}, 0.01)


@pytest.mark.parametrize("method", ["dopri", "timestep"])
def test_the_step_function_runs_the_controller_at_its_own_period(method):
    from vsj.stepper import Stepper

    options = SimulationOptions(friction="viscous", step=PERIOD / 10)
    # periods of five controller samples: the controller samples inside each call
    stepper = Stepper(motor_axis().assemble(), 5 * PERIOD, options=options, method=method,
                      controller=position_pid())
    assert stepper.input_names[-1] == "ref.r"
    state = stepper.initial_state()
    angles = []
    for k in range(60):
        t = k * 5 * PERIOD
        stepper.step(state, {"ref.r": float(Step(1.0, 0.01).value(t))}, out=state)
        angles.append(stepper.signals(state, None)["angle"])
    values = stepper.control_values()
    assert set(values) == {"control.r", "control.angle", "control.u", "actuator.v"}
    whole = run(position_pid(), solver=method, duration=0.3, output_step=5 * PERIOD,
                step=PERIOD / 10)
    # the reference is held over each 5 ms period as the stepper's input, the run's
    # spline steps at 10 ms on the same grid: the same loop; dopri runs agree to the
    # solver's tolerance, the time-stepper's to round-off (the same steps)
    tol = 100 * SimulationOptions().rtol if method == "dopri" else 1e-12
    assert np.max(np.abs(np.array(angles) - whole["angle"][1:])) < tol
    stepper.reset_controller()
    with pytest.raises(InputError, match="whole number of controller periods"):
        Stepper(motor_axis().assemble(), 2.5 * PERIOD, options=options,
                controller=position_pid())


def test_a_model_file_carries_its_controller_to_the_c_api(step_wrist, tmp_path):
    from test_c_api import run_example

    from vsj import export
    from vsj.stepper import Stepper

    stepper = Stepper(motor_axis().assemble(), 5 * PERIOD,
                      options=SimulationOptions(friction="viscous"), controller=position_pid())
    document = export.model_document(stepper)
    path = tmp_path / "axis.vsjm"
    export.write_model(path, document, stepper)
    periods = 40
    inputs = np.zeros((periods, stepper.n_inputs))
    inputs[:, stepper.input_names.index("ref.r")] = np.where(np.arange(periods) >= 2, 1.0, 0.0)
    inputs[:, stepper.input_names.index("tau")] = 0.01  # a disturbance the loop rejects
    _, data = run_example(step_wrist, path, periods, inputs, tmp_path)
    state = np.array(document["initial_state"])
    rows = np.array([o["row"] for o in document["outputs"]])
    expected = [rows @ state]
    stepper.reset_controller()
    for u in inputs:
        stepper.step(state, u, out=state)
        expected.append(rows @ state)
    # the C program and the binding run the same engine on the same model: the same
    # steps and samples, equal to the last bits up to the file's decimal output (17 digits)
    assert np.allclose(data[:, 1:1 + rows.shape[0]], np.array(expected), rtol=1e-15, atol=1e-15)
    assert abs(expected[-1][0] - 1.0) < 0.05  # the loop closed in C: the load reached 1 rad
