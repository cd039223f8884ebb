"""What closing the loop costs (`make bench`): a sampled controller in the engine against
the same plant open loop, and a controller written in Python.

Workload: the wrist with DC motors (exponential elastic elements), 2 s; three PIDs at
1 kHz hold the motors on the fig 4.15 sun angles (the circle of report fig 4.15). The
open-loop baseline drives the same plant with the voltages the closed loop applied,
replayed as held inputs (`vsj.inputs.Hold`): the same plant, the same voltage edges
(the adaptive schemes end a step on each), so that the ratio is the controller's own
cost. Both with arctan friction (dopri) and with true stiction (time-stepper, 0.1 ms
steps). Times are engine runs (`Plan.sample`, no observation), the best of several,
closed and open loop alternating in interleaved rounds (this VM's speed drifts).

The Python callback runs the same PIDs through the step function
(`vsj.control.callback.run_callback`); its cost per call is the time per period
spent outside the engine's step.

Prints the ratios and issue 33's target (closed loop <= 1.2x open loop).
"""

from __future__ import annotations

import math
import time

import numpy as np

from vsj import params as params_module
from vsj.control import PID, Actuator, Controller, Sensor
from vsj.control.callback import run_callback
from vsj.engine.plan import Plan
from vsj.inputs import Hold, Position, Sine
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.stepper import Stepper
from vsj.wrist import WristOptions, build_wrist

DURATION = 2.0
PERIOD = 1e-3
ROUNDS = 5
GAINS = dict(k=100.0, Ti=0.2, Td=0.01, y_min=-24.0, y_max=24.0)


def sun_angle(phase_deg: float) -> Sine:
    """The fig 4.15 scenario's sun angle (1.4584 rad at 0.5 Hz, faded in over 2 s)."""
    return Sine(amplitude=1.4584, frequency=0.5, phase=math.radians(phase_deg), fade_in=2.0)


def controller() -> Controller:
    refs = {"r1": sun_angle(45.0), "r2": sun_angle(-45.0), "rs": 0.0}
    return Controller(
        period=PERIOD, references=refs,
        sensors=(Sensor("motor_1"), Sensor("motor_2"), Sensor("motor_s")),
        blocks=(PID("u1", "r1", "motor_1", **GAINS), PID("u2", "r2", "motor_2", **GAINS),
                PID("us", "rs", "motor_s", **GAINS)),
        actuators=(Actuator("voltage_1", "u1"), Actuator("voltage_2", "u2"),
                   Actuator("voltage_s", "us")))


def best(fun, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fun()
        times.append(time.perf_counter() - start)
    return min(times)


def pair(structure, options, initial):
    """(closed-loop plan, open-loop plan replaying its voltages, sample times)."""
    times = np.arange(int(round(DURATION / PERIOD)) + 1) * PERIOD
    closed = Plan.compile(structure, {}, DURATION, options, initial, options.solver,
                          controller=controller())
    run, states, _, _ = closed.sample(times, ledger=False)
    assert run.status == 0, run.status
    n_bus = len(closed.controller.bus)
    volts = states[:, -len(closed.controller.channels):]
    assert volts.shape[1] == 3 and n_bus > 0
    replay = {ch: Hold(tuple(times), tuple(volts[:, j]))
              for j, ch in enumerate(closed.controller.channels)}
    opened = Plan.compile(structure, replay, DURATION, options, initial, options.solver)
    return closed, opened, times


def python_pids():
    """Three sampled LimPIDs (back-calculation) in plain Python, as a callback."""
    refs = {"voltage_1": ("motor_1", sun_angle(45.0)), "voltage_2": ("motor_2", sun_angle(-45.0)),
            "voltage_s": ("motor_s", None)}
    memory = {ch: [0.0, None] for ch in refs}
    k, Ti, Td, Nd, Ni = GAINS["k"], GAINS["Ti"], GAINS["Td"], 10.0, 0.9

    def callback(t, signals):
        out = {}
        for ch, (name, ref) in refs.items():
            r = 0.0 if ref is None else float(ref.value(t))
            y = signals[name]
            xi, xd = memory[ch]
            xd = -y if xd is None else xd
            d = Nd * (-y - xd)
            xd = -y + (xd + y) * math.exp(-PERIOD * Nd / Td)
            u = k * (r - y + xi + d)
            lim = min(max(u, -24.0), 24.0)
            xi += PERIOD * (r - y + (lim - u) / (k * Ni)) / Ti
            memory[ch] = [xi, xd]
            out[ch] = lim
        return out

    return callback


def main() -> int:
    params = params_module.load()
    structure = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc",
                                                 elastic="exponential")).assemble()
    initial = InitialState(q=-0.015)
    print(f"vsj benchmarks: closing the loop; the wrist with DC motors, {DURATION:g} s, three "
          f"PIDs at {1 / PERIOD:g} Hz on the fig 4.15 sun angles\n")
    cases = {
        "arctan, dopri": SimulationOptions(solver="dopri", friction="arctan"),
        "stiction, time-stepper 0.1 ms": SimulationOptions(solver="timestep",
                                                           friction="stiction", step=1e-4),
    }
    plans = {name: pair(structure, options, initial) for name, options in cases.items()}
    timings = {name: {"closed": [], "open": []} for name in cases}
    for _ in range(ROUNDS):  # interleaved: closed and open loop alternate within a round
        for name, (closed, opened, times) in plans.items():
            timings[name]["closed"].append(best(lambda: closed.sample(times, ledger=False), 1))
            timings[name]["open"].append(best(lambda: opened.sample(times, ledger=False), 1))
    print(f"{'plant':<34} {'closed loop [ms]':>17} {'open loop [ms]':>15} {'ratio':>7}")
    ratios = {}
    for name, t in timings.items():
        c, o = min(t["closed"]), min(t["open"])
        ratios[name] = c / o
        print(f"{name:<34} {1e3 * c:>17.1f} {1e3 * o:>15.1f} {c / o:>7.2f}")
    # the closed loop's result: how well the PIDs hold the circle (a sanity figure)
    r = simulate(structure, {}, DURATION, controller=controller(), initial=initial,
                 options=SimulationOptions(solver="dopri", output_step=PERIOD), ports=False)
    lag = np.max(np.abs(r["control.r1"] - r["motor_1"])[r.time > 0.5])
    print(f"  (closed loop tracking: motor 1 within {lag:.2e} rad of its reference after "
          "0.5 s; ledger relative residual "
          f"{r.ledger['relative_residual']:.1e})")

    stepper = Stepper(structure, PERIOD, options=SimulationOptions(friction="arctan"))
    callback_run = run_callback(stepper, python_pids(), DURATION, initial=initial)
    assert callback_run.success, callback_run.message
    closed, _, times = plans["arctan, dopri"]
    c_per_sample = (min(timings["arctan, dopri"]["closed"])
                    - min(timings["arctan, dopri"]["open"])) / len(times)
    print(f"\nPython callback (three LimPIDs through the step function): "
          f"{1e6 * callback_run.per_call:.1f} us per call outside the engine, "
          f"{1e3 * callback_run.wall_time:.0f} ms for the run; the C controller adds "
          f"{1e6 * c_per_sample:.2f} us per sample")
    print("\nissue 33 target: a closed-loop run with C PIDs at 1 kHz costs <= 1.2x the open-loop "
          "run")
    for name, ratio in ratios.items():
        print(f"  {name:<34} {ratio:5.2f}  {'met' if ratio <= 1.2 else 'NOT met'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
