"""Linear models (vsj.linear).

Twin: the wrist with linear springs and viscous friction, linearised through the
engine, against the hand-derived model of tests/test_twin.py. Then the linear
model of the full nonlinear wrist against small-perturbation simulations of it
(step, frequency and free responses) around the same operating point; files;
input validation; the command line.
"""

import argparse
import json
import math

import control
import numpy as np
import pytest
from conftest import override
from test_twin import K, hand_matrices

from vsj import linear
from vsj.cli import control as cli_control
from vsj.errors import InputError, SimulationError
from vsj.inputs import Constant, Table
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.stepper import Stepper
from vsj.wrist import WristOptions, build_wrist

#: Twin matrices: the linear model's right-hand side is linear, so central
#: differences are exact up to round-off (about 1e-16 / JACOBIAN_STEP = 1e-11
#: relative); 1e-9 of each block's largest entry leaves a margin.
TWIN_TOL = 1e-9
#: Small-perturbation responses: perturbations of 2e-5 N m keep every friction
#: element within k_b |s| < 0.01 of its arctan law, so the linearisation error is
#: of that order times the response (measured: 2e-4 of the peak at most).
STEP_TOL = 1e-3
#: Frequency response from a multisine of 1e-5 N m after 4 s of settling
#: (slowest pole 2.5 rad/s: transients below 5e-5); measured 3e-6.
FREQ_TOL = 1e-4
#: Free response: zero-crossing period over 12 periods sampled 4000 times, against
#: the imaginary part of the pole; measured 1e-5 at most.
FREE_TOL = 1e-4

Q_OP = -0.004           # m
LOAD = (0.05, 0.02)     # N m on theta_x, theta_y
SIM = SimulationOptions(rtol=1e-11, atol=1e-14, output_step=1e-3)


def _close(actual, expected, tol):
    scale = max(np.max(np.abs(expected)), 1e-300)
    assert np.max(np.abs(actual - expected)) <= tol * scale, (actual, expected)


# -- twin ----------------------------------------------------------------------------


def test_linearised_linear_viscous_wrist_is_the_hand_derived_model(params):
    p = override(params, elastic_element__lever_viscous="2e-4 N m s/rad",
                 differential__viscous="3e-4 N m s/rad",
                 planetary__sun_bearing_viscous="1e-5 N m s/rad")
    lin = linear.linearize(p, 0.0,
                           wrist_options=WristOptions(elastic="linear", linear_stiffness=K),
                           friction="viscous", inputs=["motor_1", "motor_2", "tau_x", "tau_y"])
    assert list(lin.state_labels) == ["vsm_1.ring.angle", "vsm_2.ring.angle",
                                      "vsm_1.ring.momentum", "vsm_2.ring.momentum",
                                      "motor_1.flange.angle", "motor_2.flange.angle"]
    h = hand_matrices(p)
    M, Mu, D, Du, G = h["M"], h["Mu"], h["D"], h["Du"], h["G"]
    Minv = np.linalg.inv(M)
    # M phi'' + Mu u' = -K phi - D phi' - Du u + G tau with p = M phi' + Mu u:
    #   phi' = M^-1 (p - Mu u),  p' = -K phi - D M^-1 p + (D M^-1 Mu - Du) u + G tau
    A, B = lin.A, lin.B
    x, mom, src = slice(0, 2), slice(2, 4), slice(4, 6)
    _close(A[x, mom], Minv, TWIN_TOL)
    _close(A[mom, x], -K * np.eye(2), TWIN_TOL)
    _close(A[mom, mom], -D @ Minv, TWIN_TOL)
    _close(B[x, :2], -Minv @ Mu, TWIN_TOL)
    _close(B[mom, :2], D @ Minv @ Mu - Du, TWIN_TOL)
    _close(B[mom, 2:], G, TWIN_TOL)
    assert np.all(A[x, x] == 0.0) and np.all(B[x, 2:] == 0.0)
    # the springs act on the ring angles only: motor angles are pure integrators
    assert np.all(A[:, src] == 0.0) and np.all(A[src] == 0.0)
    _close(B[src, :2], np.eye(2), TWIN_TOL)


def test_frequency_response_of_the_twin_matches_the_hand_model(params):
    lin = linear.linearize(params, 0.0,
                           wrist_options=WristOptions(elastic="linear", linear_stiffness=K),
                           friction="viscous")
    h = hand_matrices(params)
    omega = np.array([0.3, 3.0, 30.0, 300.0])
    for w, got in zip(omega, linear.transfer(lin, "phi_1", "tau_x", omega)):
        # ring angles per end-effector torque: (-w^2 M + j w D + K)^-1 G
        expected = np.linalg.solve(-w * w * h["M"] + 1j * w * h["D"] + K * np.eye(2), h["G"])
        assert abs(got - expected[0, 0]) <= 1e-8 * abs(expected[0, 0])


# -- the nonlinear wrist around an operating point -----------------------------------------


@pytest.fixture(scope="module")
def loaded(params):
    """Linear model of the geometric wrist under a load, arctan friction linearised."""
    return linear.linearize(params, Q_OP, load=LOAD,
                            inputs=["motor_1", "motor_2", "tau_x", "tau_y"])


def _simulate_from(params, lin, inputs, duration):
    op = lin.operating_point["states"]
    structure = build_wrist(params).assemble()  # the pivot driven (at rest), not fixed
    initial = InitialState(q=Q_OP, angles={"vsm_1.ring": op["vsm_1.ring.angle"],
                                           "vsm_2.ring": op["vsm_2.ring.angle"]})
    result = simulate(structure, inputs, duration, initial=initial, options=SIM, ports=False)
    assert result.success, result.message
    return result


def test_operating_point_is_an_equilibrium_that_holds_the_load(params, loaded):
    op = loaded.operating_point
    assert op["q"] == pytest.approx(Q_OP)
    assert op["inputs"]["tau_x"] == LOAD[0] and op["inputs"]["q"] == Q_OP
    # the springs hold the load: theta torques = G^T-mapped ring torques (virtual work)
    G = hand_matrices(params)["G"]
    ring = np.array([op["outputs"]["vsm_1_torque"], op["outputs"]["vsm_2_torque"]])
    assert np.allclose(G @ np.array(LOAD) + ring, 0.0, atol=1e-12)
    result = _simulate_from(params, loaded, {"tau_x": Constant(LOAD[0]),
                                             "tau_y": Constant(LOAD[1])}, 0.2)
    assert np.max(np.abs(result["theta_x"] - op["outputs"]["theta_x"])) < 1e-12


@pytest.mark.parametrize("case", ["load step", "motor pulse"])
def test_step_response_matches_small_perturbation_simulation(params, loaded, case):
    duration = 1.0
    t = np.arange(0.0, duration + 1e-9, 1e-3)
    U = np.zeros((4, t.size))
    if case == "load step":
        knots, values = (0.0, 0.01, 0.011, duration), (0.0, 0.0, 2e-5, 2e-5)
        inputs = {"tau_x": Table(knots, tuple(LOAD[0] + v for v in values)),
                  "tau_y": Constant(LOAD[1])}
        U[2] = np.interp(t, knots, values)
    else:  # a trapezoidal speed pulse of motor 1: its angle steps by 8e-5 rad
        knots, values = (0.0, 0.01, 0.011, 0.05, 0.051, duration), (0, 0, 2e-3, 2e-3, 0, 0)
        inputs = {"motor_1": Table(knots, values), "tau_x": Constant(LOAD[0]),
                  "tau_y": Constant(LOAD[1])}
        U[0] = np.interp(t, knots, values)
    result = _simulate_from(params, loaded, inputs, duration)
    response = control.forced_response(loaded, t, U)
    op = loaded.operating_point["outputs"]
    for name in ("theta_x", "theta_y", "phi_1", "phi_2", "theta_x_speed"):
        linear_part = response.outputs[list(loaded.output_labels).index(name)]
        simulated = result[name.replace("_speed", ".speed")] - op[name]
        assert np.max(np.abs(simulated)) > 1e-6
        assert np.max(np.abs(linear_part - simulated)) <= STEP_TOL * np.max(np.abs(simulated))


def test_frequency_response_matches_small_perturbation_simulation(params, loaded):
    freqs, amplitude, duration = (0.5, 3.0, 12.0), 1e-5, 6.0
    t = np.arange(0.0, duration + 1e-9, 1e-4)
    torque = LOAD[0] + sum(amplitude * np.sin(2 * np.pi * f * t) for f in freqs)
    result = _simulate_from(params, loaded, {"tau_x": Table(tuple(t), tuple(torque), "cubic"),
                                             "tau_y": Constant(LOAD[1])}, duration)
    window = result.time >= duration - 2.0  # whole periods of every frequency
    tw = result.time[window]
    y = result["theta_x"][window] - loaded.operating_point["outputs"]["theta_x"]
    columns = [fun(2 * np.pi * f * tw) for f in freqs for fun in (np.sin, np.cos)]
    coef, *_ = np.linalg.lstsq(np.array(columns + [np.ones_like(tw)]).T, y, rcond=None)
    expected = linear.transfer(loaded, "theta_x", "tau_x", 2 * np.pi * np.array(freqs))
    for i, h in enumerate(expected):
        measured = (coef[2 * i] + 1j * coef[2 * i + 1]) / amplitude
        assert abs(measured - h) <= FREQ_TOL * abs(h)


def test_static_compliance_is_the_slope_of_the_operating_points(params, loaded):
    dtau = 1e-6
    nudged = linear.linearize(params, Q_OP, load=(LOAD[0] + dtau, LOAD[1]))
    slope = [(nudged.operating_point["outputs"][k] - loaded.operating_point["outputs"][k])
             / dtau for k in ("theta_x", "theta_y")]
    gain = linear.static_gain(loaded, ["theta_x", "theta_y"], ["tau_x"])[:, 0]
    assert np.allclose(gain, slope, rtol=1e-4)


def test_exponential_model_has_the_stiffness_and_pivot_sensitivity_of_eq_4_5(params):
    ee = params.elastic_element
    q = -0.01
    lin = linear.linearize(params, q, load=(0.02, 0.0),
                           wrist_options=WristOptions(elastic="exponential"),
                           friction="removed")
    k_q = ee.a1 * math.exp(ee.a2 * q) + ee.a3
    torque = lin.C[list(lin.output_labels).index("vsm_1_torque")]
    assert torque[0] == pytest.approx(-k_q, rel=1e-12)
    phi = lin.operating_point["states"]["vsm_1.ring.angle"]
    dtau_dq = lin.D[list(lin.output_labels).index("vsm_1_torque"),
                    list(lin.input_labels).index("q")]
    assert dtau_dq == pytest.approx(-ee.a1 * ee.a2 * math.exp(ee.a2 * q) * phi, rel=1e-6)
    # without friction the modes are undamped and at the natural frequencies
    for mode, wn in zip(linear.modes(lin), linear.natural_frequencies(lin)):
        assert mode["damping"] == pytest.approx(0.0, abs=1e-9)
        assert mode["frequency"] == pytest.approx(wn, rel=1e-9)


# -- natural frequencies ----------------------------------------------------------------


def test_natural_frequencies_rise_with_stiffness(params):
    lo, hi = params.pivot.q_min, params.pivot.q_max
    qs = np.linspace(hi, lo, 7)  # from soft to stiff
    models = linear.sweep(params, qs)
    lowest = [linear.natural_frequencies(m)[0] for m in models]
    stiff = [linear.output_stiffness(m)[0, 0] for m in models]
    assert np.all(np.diff(lowest) > 0.0) and np.all(np.diff(stiff) > 0.0)
    assert lowest[-1] > 10 * lowest[0]


@pytest.mark.parametrize("q", [0.01, -0.022])
def test_natural_frequency_matches_a_simulated_free_response(params, q):
    from scipy.optimize import curve_fit

    lin = linear.linearize(params, q, friction="viscous")
    mode = linear.modes(lin)[0]
    assert mode["frequency"] == pytest.approx(linear.natural_frequencies(lin)[0], rel=1e-9)
    decay, damped = -mode["pole"].real, mode["pole"].imag
    # twelve periods, or until the response has decayed to 1e-6 of its start (below that
    # the solver's tolerance, not the mode, shapes it): a soft setting is well damped
    duration = min(12 * 2 * math.pi / damped, math.log(1e6) / decay)
    result = simulate(build_wrist(params).assemble(), {}, duration,
                      initial=InitialState(q=q, angles={"vsm_1.ring": 1e-3,
                                                        "vsm_2.ring": 1e-3}),
                      options=SimulationOptions(friction="viscous", rtol=1e-10, atol=1e-14,
                                                output_step=duration / 4000), ports=False)
    y, t = result["theta_x"], result.time
    assert duration * damped / (2 * math.pi) >= 2  # at least two periods to measure

    def response(t, amplitude, sigma, omega, phase):
        return amplitude * np.exp(-sigma * t) * np.cos(omega * t + phase)

    # a damped oscillation fitted to the simulated response, started a few per cent off
    start = (float(y[0]), 0.97 * decay, 1.03 * damped, 0.0)
    (_, sigma, omega, _), _ = curve_fit(response, t, y, p0=start,
                                        xtol=1e-14, ftol=1e-14, maxfev=20000)
    assert omega == pytest.approx(damped, rel=FREE_TOL)
    assert sigma == pytest.approx(decay, rel=10 * FREE_TOL)


# -- other sub-models ---------------------------------------------------------------------


def test_dc_motor_wrist_holds_the_load_with_the_operating_currents(params):
    lin = linear.linearize(params, Q_OP, load=LOAD, motors=(0.1, -0.2),
                           wrist_options=WristOptions(motors="dc"))
    op = lin.operating_point
    assert [n for n in lin.input_labels] == ["tau_x", "tau_y", "voltage_1", "voltage_2", "q"]
    for i in (1, 2):
        assert op["inputs"][f"voltage_{i}"] == pytest.approx(
            params.motor.resistance * op["states"][f"motor_{i}.current"], rel=1e-12)
    assert op["outputs"]["motor_1"] == pytest.approx(0.1, abs=1e-12)
    # the operating point is an equilibrium of the nonlinear model with these voltages
    stepper = Stepper.wrist(params, WristOptions(motors="dc", pivot_drive="fixed",
                                                 fixed_q=Q_OP), period=0.05)
    state = np.array([op["states"][n] for n in stepper.state_names])
    after = stepper.step(state, [op["inputs"][n] for n in stepper.input_names])
    assert np.max(np.abs(after - state)[:4]) < 1e-10
    # open-loop motors: a rigid-body mode, so no static stiffness
    assert min(m["frequency"] for m in linear.modes(lin)) < 1e-6
    with pytest.raises(SimulationError, match="rigid-body"):
        linear.output_stiffness(lin)


def test_input_and_output_selection_and_names(params):
    lin = linear.linearize(params, 0.0, inputs=["tau_x", "q"],
                           outputs=["theta_x", "vsm_1_torque"])
    assert list(lin.input_labels) == ["tau_x", "q"]
    assert list(lin.output_labels) == ["theta_x", "vsm_1_torque"]
    assert lin.input_units == ("N m", "m") and lin.output_units == ("rad", "N m")
    assert isinstance(lin, control.StateSpace) and lin.friction == "linearised"
    assert "pivot q = 0 cm" in lin.describe()
    # a run's spelling of a signal selects the same output
    dotted = linear.linearize(params, 0.0, inputs=["tau_x"], outputs=["theta_x.speed"])
    assert list(dotted.output_labels) == ["theta_x_speed"]


@pytest.mark.parametrize("kwargs, match", [
    ({"q": 0.03}, "outside the pivot range"),
    ({"q": math.nan}, "finite"),
    ({"outputs": ["theta_z"]}, "unknown output"),
    ({"inputs": ["motor_9"]}, "unknown input"),
    ({"friction": "sign"}, "not differentiable"),
    ({"load": (1.0,)}, "two values"),
])
def test_bad_requests_name_the_problem(params, kwargs, match):
    kwargs = {"q": 0.0, **kwargs}
    with pytest.raises(InputError, match=match):
        linear.linearize(params, **kwargs)


# -- files ----------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_files_round_trip(loaded, tmp_path, suffix):
    path = tmp_path / f"model{suffix}"
    linear.save(loaded, path)
    back = linear.load(path)
    for name in "ABCD":
        assert np.array_equal(getattr(back, name), getattr(loaded, name))
    assert back.state_labels == loaded.state_labels
    assert back.output_labels == loaded.output_labels
    assert back.input_units == loaded.input_units
    assert back.operating_point["outputs"] == loaded.operating_point["outputs"]
    assert back.friction == "linearised"


def test_json_format(loaded, tmp_path):
    path = tmp_path / "model.json"
    linear.save(loaded, path)
    data = json.loads(path.read_text())
    assert data["format"] == "vsj-linear-model" and data["version"] == 1
    assert data["friction"]["treatment"] == "linearised"
    assert data["states"][2] == {"name": "vsm_1.ring.momentum", "unit": "N m s"}
    assert len(data["A"]) == 6 and len(data["B"][0]) == 4


def test_loading_something_else_fails_clearly(tmp_path):
    path = tmp_path / "x.json"
    path.write_text('{"format": "other"}')
    with pytest.raises(InputError, match="not a vsj linear model"):
        linear.load(path)
    with pytest.raises(InputError, match=".json or .npz"):
        linear.load(tmp_path / "x.txt")


# -- command line ----------------------------------------------------------------------


def _run(argv):
    parser = argparse.ArgumentParser(prog="vsj")
    cli_control.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args.func(args)


def test_cli_linearize_prints_json(capsys):
    assert _run(["linearize", "--q=-0.4cm", "--tau-x", "0.05 N m", "--json",
                 "--outputs", "theta_x,theta_y"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["operating_point"]["q"] == pytest.approx(-0.004)
    assert [o["name"] for o in data["outputs"]] == ["theta_x", "theta_y"]


def test_cli_linearize_writes_a_file_and_a_summary(tmp_path, capsys):
    out = tmp_path / "lin.npz"
    assert _run(["linearize", "--q", "1 cm", "--friction", "viscous", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "natural frequencies" in text and str(out) in text
    assert linear.load(out).friction == "viscous"


@pytest.mark.parametrize("argv, match", [
    (["linearize", "--q", "5 cm"], "outside the pivot range"),
    (["linearize", "--q", "1"], "no unit"),
    (["linearize", "--outputs", "nope"], "unknown output"),
    (["linearize", "--out", "model.txt"], ".json or .npz"),
])
def test_cli_linearize_rejects_bad_input(argv, match):
    with pytest.raises(InputError, match=match):
        _run(argv)


def test_the_linearize_command_does_not_import_python_control(tmp_path):
    """python-control is slow to import; the command works on `LinearData` (and its
    files load back as python-control models)."""
    import subprocess
    import sys

    out = tmp_path / "lin.json"
    code = ("import sys; from vsj.cli import main; "
            f"code = main(['linearize', '--q=-0.4cm', '--out', {str(out)!r}]); "
            "print('control' in sys.modules); sys.exit(code)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "False"
    model = linear.load(out)
    assert isinstance(model, control.StateSpace) and model.operating_point["q"] == -0.004


def test_an_operating_point_past_the_end_stop_is_warned_about(params):
    pressed = linear.linearize(params, -0.01, load=(20.0, 0.0), statespace=False)
    assert any("past its 1.4 rad end stop" in w for w in pressed.info["warnings"])
    assert linear.linearize(params, -0.01, load=(0.2, 0.0),
                            statespace=False).info["warnings"] == []
