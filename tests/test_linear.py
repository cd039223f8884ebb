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
from vsj.linear import EQUILIBRIUM_TOL
from vsj.cli import control as cli_control
from vsj.errors import InputError, SimulationError
from vsj.inputs import Constant, Table
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.stepper import Stepper
from vsj.wrist import WristOptions, build_wrist

EPS = np.finfo(float).eps
#: Twin matrices, relative to the largest term of the hand formula: the twin's
#: right-hand side is linear and its operating point all zeros, so a central
#: difference of a step h changes each rate by exactly (derivative x h) up to the
#: rounding of the rate's few products and sums (say 16, each 1 ulp); Richardson's
#: (4 d(h/2) - d(h)) / 3 adds the two differences' round-off with weights 4/3 and 1/3
#: of 2 and 1 (5/3 in all), and the hand side's own inverse adds cond(M) ulps.
TWIN_TOL = 5 / 3 * 16 * EPS + EPS
#: The order at which the mismatch between the linear model and a simulation of
#: the nonlinear wrist falls with the perturbation's amplitude: the model is the
#: exact derivative, so what remains is the springs' curvature (second order in
#: the amplitude) or the arctan law's (third); a wrong entry of the model would
#: leave a first-order mismatch. Halving the amplitude divides a second-order
#: mismatch by 4 and a first-order one by 2: the threshold is their geometric mean.
SECOND_ORDER_RATIO = 2 ** 1.5

Q_OP = -0.004           # m
LOAD = (0.05, 0.02)     # N m on theta_x, theta_y
SIM = SimulationOptions(rtol=1e-11, atol=1e-14, output_step=1e-3)


def _close(actual, expected, tol, *terms):
    """``actual`` equals ``expected`` to ``tol`` of the largest entry of ``expected``
    and of the ``terms`` it was summed from (round-off scales with the terms)."""
    scale = max(max(np.max(np.abs(x)) for x in (expected, *terms)), 1e-300)
    assert np.max(np.abs(actual - expected)) <= tol * scale, (actual, expected)


def _pole_errors(model) -> tuple[np.ndarray, np.ndarray]:
    """The dynamic states' poles [rad/s] and a bound on each one's round-off: a
    backward-stable eigensolver returns the exact poles of A + E with
    |E| <= n eps |A| (2-norm), which moves a pole by at most |E| times its
    condition 1/|y^H x| (left and right eigenvectors y, x of unit length)."""
    from scipy.linalg import eig

    idx = linear.analysis.dynamic_states(model)
    A = model.A[np.ix_(idx, idx)]
    poles, left, right = eig(A, left=True, right=True)
    overlap = np.abs(np.sum(left.conj() * right, axis=0))
    return poles, len(idx) * EPS * np.linalg.norm(A, 2) / overlap


def _eigenvalue_error(model) -> float:
    """The largest of `_pole_errors` [rad/s]."""
    return float(np.max(_pole_errors(model)[1]))


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
    _close(B[mom, :2], D @ Minv @ Mu - Du, TWIN_TOL, D @ Minv @ Mu, Du)
    _close(B[mom, 2:], G, TWIN_TOL)
    # exact zeros: a rate that does not read a variable is computed from the same
    # numbers on both sides of the difference, so it cancels to 0 on any machine
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
        dynamic = -w * w * h["M"] + 1j * w * h["D"] + K * np.eye(2)
        expected = np.linalg.solve(dynamic, h["G"])
        # A and B to TWIN_TOL, amplified by the condition of each side's solve
        resolvent = 1j * w * np.eye(lin.nstates) - lin.A
        tol = (np.linalg.cond(resolvent) + np.linalg.cond(dynamic)) * TWIN_TOL
        assert abs(got - expected[0, 0]) <= tol * abs(expected[0, 0]), w


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
    # a held pivot's position is its parameter, passed through (0 * sin + 1 * q)
    assert op["q"] == Q_OP
    assert op["inputs"]["tau_x"] == LOAD[0] and op["inputs"]["q"] == Q_OP
    # the springs hold the load: theta torques = G^T-mapped ring torques (virtual work);
    # what is left is the generalised force at which Newton stopped, plus the rounding
    # of G tau (a few ulps of its terms)
    G = hand_matrices(params)["G"]
    ring = np.array([op["outputs"]["vsm_1_torque"], op["outputs"]["vsm_2_torque"]])
    held = G @ np.array(LOAD)
    assert np.max(np.abs(held + ring)) <= EQUILIBRIUM_TOL + 4 * EPS * np.max(np.abs(held))
    result = _simulate_from(params, loaded, {"tau_x": Constant(LOAD[0]),
                                             "tau_y": Constant(LOAD[1])}, 0.2)
    # a leftover generalised force of EQUILIBRIUM_TOL moves theta by at most twice its
    # static deflection (a step force overshoots by at most 2x), through the
    # compliance; the solver's error control adds rtol |theta| + atol
    compliance = np.abs(linear.static_gain(loaded, ["theta_x"], ["tau_x", "tau_y"])).sum()
    theta = op["outputs"]["theta_x"]
    drift = np.max(np.abs(result["theta_x"] - theta))
    assert drift <= 2 * compliance * EQUILIBRIUM_TOL + SIM.rtol * abs(theta) + SIM.atol, drift


def _step_mismatch(params, loaded, case, scale):
    """Largest |linear - simulated| response of each output [rad or rad/s] to an input
    perturbation ``scale`` times the case's, and the simulated response's peak."""
    duration = 1.0
    t = np.arange(0.0, duration + 1e-9, 1e-3)
    U = np.zeros((4, t.size))
    if case == "load step":
        knots, values = (0.0, 0.01, 0.011, duration), (0.0, 0.0, 2e-5 * scale, 2e-5 * scale)
        inputs = {"tau_x": Table(knots, tuple(LOAD[0] + v for v in values)),
                  "tau_y": Constant(LOAD[1])}
        U[2] = np.interp(t, knots, values)
    else:  # a trapezoidal speed pulse of motor 1: its angle steps by 8e-5 rad
        speed = 2e-3 * scale
        knots, values = (0.0, 0.01, 0.011, 0.05, 0.051, duration), (0, 0, speed, speed, 0, 0)
        inputs = {"motor_1": Table(knots, values), "tau_x": Constant(LOAD[0]),
                  "tau_y": Constant(LOAD[1])}
        U[0] = np.interp(t, knots, values)
    result = _simulate_from(params, loaded, inputs, duration)
    response = control.forced_response(loaded, t, U)
    op = loaded.operating_point["outputs"]
    out = {}
    for name in ("theta_x", "theta_y", "phi_1", "phi_2", "theta_x_speed"):
        linear_part = response.outputs[list(loaded.output_labels).index(name)]
        simulated = result[name.replace("_speed", ".speed")] - op[name]
        out[name] = (np.max(np.abs(linear_part - simulated)), np.max(np.abs(simulated)))
    return out


@pytest.mark.parametrize("case", ["load step", "motor pulse"])
def test_step_response_matches_small_perturbation_simulation(params, loaded, case):
    """The linear model is the nonlinear wrist's derivative: its mismatch with a
    simulation falls faster than the perturbation (`SECOND_ORDER_RATIO`). Both
    mismatches stay far above the simulation's error (rtol 1e-11 of the operating
    point's angles, ~1e-12 rad), which the difference of two runs would not see."""
    full = _step_mismatch(params, loaded, case, 1.0)
    half = _step_mismatch(params, loaded, case, 0.5)
    for name, (mismatch, peak) in full.items():
        assert peak > 1e-6, name  # the perturbation moved the output
        assert mismatch / half[name][0] > SECOND_ORDER_RATIO, (name, mismatch, half[name][0])


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
    # the transient that switching the multisine on starts (no larger than the
    # response it leads to) decays at least as fast as the slowest pole: by the
    # window it is below exp(-decay t) of the response; the nonlinearity of a 1e-5 N m
    # perturbation is second order (see test_step_response_...) and far below
    decay = min(-m["pole"].real for m in linear.modes(loaded))
    tol = math.exp(-decay * (duration - 2.0))
    for i, h in enumerate(expected):
        measured = (coef[2 * i] + 1j * coef[2 * i + 1]) / amplitude
        assert abs(measured - h) <= tol * abs(h), (freqs[i], abs(measured - h) / abs(h))


def test_static_compliance_is_the_slope_of_the_operating_points(params, loaded):
    """Central differences of the operating point against the load converge to the
    static gain at second order. Steps of 1e-3 N m keep the truncation error (~1e-5)
    far above the Newton residual's effect (compliance x EQUILIBRIUM_TOL / dtau,
    ~1e-9) and the gain's round-off (cond(A) x the Jacobian's, ~1e-10)."""
    gain = linear.static_gain(loaded, ["theta_x", "theta_y"], ["tau_x"])[:, 0]
    errors = []
    for dtau in (1e-3, 5e-4):
        ends = [linear.linearize(params, Q_OP, load=(LOAD[0] + sign * dtau, LOAD[1]),
                                 statespace=False).operating_point["outputs"]
                for sign in (1, -1)]
        slope = np.array([(ends[0][k] - ends[1][k]) / (2 * dtau)
                          for k in ("theta_x", "theta_y")])
        errors.append(np.abs(slope - gain))
    assert np.all(errors[0] / errors[1] > SECOND_ORDER_RATIO), errors


def test_exponential_model_has_the_stiffness_and_pivot_sensitivity_of_eq_4_5(params):
    ee = params.elastic_element
    q = -0.01
    lin = linear.linearize(params, q, load=(0.02, 0.0),
                           wrist_options=WristOptions(elastic="exponential"),
                           friction="removed")
    k_q = ee.a1 * math.exp(ee.a2 * q) + ee.a3
    torque = lin.C[list(lin.output_labels).index("vsm_1_torque")]
    # the same sum of positive terms in C and here: exp to an ulp each (two libms may
    # differ by one), a contracted multiply-add rounding once instead of twice
    assert torque[0] == pytest.approx(-k_q, rel=4 * EPS, abs=0.0)
    phi = lin.operating_point["states"]["vsm_1.ring.angle"]
    tau = lin.operating_point["outputs"]["vsm_1_torque"]
    dtau_dq = lin.D[list(lin.output_labels).index("vsm_1_torque"),
                    list(lin.input_labels).index("q")]
    exact = -ee.a1 * ee.a2 * math.exp(ee.a2 * q) * phi
    # a central difference over q +- h (h = 1e-7 m in vsj.linear.build): of an
    # exponential its relative error is sinh(x)/x - 1 ~ x^2/6 with x = a2 h; round-off
    # adds the rounding of q +- h (eps |q| / h) and two torques of a few ulps over 2 h
    h = 1e-7
    truncation = (ee.a2 * h) ** 2 / 6
    roundoff = EPS * (abs(q) + 4 * abs(tau / exact)) / h
    assert dtau_dq == pytest.approx(exact, rel=truncation + roundoff, abs=0.0)
    # without friction the modes are undamped and at the natural frequencies, to the
    # eigensolver's round-off
    error = _eigenvalue_error(lin)
    for mode, wn in zip(linear.modes(lin), linear.natural_frequencies(lin)):
        assert abs(mode["pole"].real) <= error, mode
        assert mode["frequency"] == pytest.approx(wn, abs=2 * error)


# -- natural frequencies ----------------------------------------------------------------


def test_natural_frequencies_rise_with_stiffness(params):
    lo, hi = params.pivot.q_min, params.pivot.q_max
    qs = np.linspace(hi, lo, 7)  # from soft to stiff
    models = linear.sweep(params, qs)
    lowest = [linear.natural_frequencies(m)[0] for m in models]
    stiff = [linear.output_stiffness(m)[0, 0] for m in models]
    assert np.all(np.diff(lowest) > 0.0) and np.all(np.diff(stiff) > 0.0)
    # a physical claim, not a numerical one: the pivot varies the stiffness by more
    # than a hundredfold, so the frequency (its square root) by more than tenfold
    assert lowest[-1] > 10 * lowest[0]


@pytest.mark.parametrize("q", [0.01, -0.022])
def test_natural_frequency_matches_a_simulated_free_response(params, q):
    from scipy.optimize import curve_fit

    lin = linear.linearize(params, q, friction="viscous")
    mode = linear.modes(lin)[0]
    # the pair of modes is symmetric (x and y), each a damped single degree of
    # freedom, whose |pole| is its natural frequency: equal to the eigensolvers' round-off
    assert mode["frequency"] == pytest.approx(linear.natural_frequencies(lin)[0],
                                              abs=2 * _eigenvalue_error(lin))
    decay, damped = -mode["pole"].real, mode["pole"].imag
    # twelve periods, or until the response has decayed to 1e-6 of its start (below that
    # the solver's tolerance, not the mode, shapes it): a soft setting is well damped
    duration = min(12 * 2 * math.pi / damped, math.log(1e6) / decay)

    def response(t, amplitude, sigma, omega, phase):
        return amplitude * np.exp(-sigma * t) * np.cos(omega * t + phase)

    errors = []
    for start_angle in (1e-3, 5e-4):
        result = simulate(build_wrist(params).assemble(), {}, duration,
                          initial=InitialState(q=q, angles={"vsm_1.ring": start_angle,
                                                            "vsm_2.ring": start_angle}),
                          options=SimulationOptions(friction="viscous", rtol=1e-10,
                                                    atol=1e-14, output_step=duration / 4000),
                          ports=False)
        y, t = result["theta_x"], result.time
        assert duration * damped / (2 * math.pi) >= 2  # at least two periods to measure
        # a damped oscillation fitted to the simulated response, started a few per cent off
        start = (float(y[0]), 0.97 * decay, 1.03 * damped, 0.0)
        (_, sigma, omega, _), _ = curve_fit(response, t, y, p0=start,
                                            xtol=1e-14, ftol=1e-14, maxfev=20000)
        errors.append(np.abs([omega / damped - 1, sigma / decay - 1]))
    # the springs' curvature shifts the frequency and decay of a finite swing at
    # second order in its amplitude; a wrong pole would leave a constant error (the
    # fit's own, at rtol 1e-10, is far below both)
    assert np.all(errors[0] / errors[1] > SECOND_ORDER_RATIO), errors


# -- other sub-models ---------------------------------------------------------------------


def test_dc_motor_wrist_holds_the_load_with_the_operating_currents(params):
    lin = linear.linearize(params, Q_OP, load=LOAD, motors=(0.1, -0.2),
                           wrist_options=WristOptions(motors="dc"))
    op = lin.operating_point
    assert [n for n in lin.input_labels] == ["tau_x", "tau_y", "voltage_1", "voltage_2", "q"]
    motor = params.motor
    for i in (1, 2):
        # the voltage is set as R i: one product, correctly rounded
        assert op["inputs"][f"voltage_{i}"] == pytest.approx(
            motor.resistance * op["states"][f"motor_{i}.current"], rel=EPS, abs=0.0)
    # the motor position is pinned by Newton's equations, to their tolerance
    assert op["outputs"]["motor_1"] == pytest.approx(0.1, abs=EQUILIBRIUM_TOL)
    # the operating point is an equilibrium of the nonlinear model with these voltages
    period = 0.05
    stepper = Stepper.wrist(params, WristOptions(motors="dc", pivot_drive="fixed",
                                                 fixed_q=Q_OP), period=period)
    state = np.array([op["states"][n] for n in stepper.state_names])
    after = stepper.step(state, [op["inputs"][n] for n in stepper.input_names])
    # the angles may move by the step's error control (rtol |x| + atol) and by a
    # leftover generalised force of EQUILIBRIUM_TOL driving a free rotor against its
    # back-EMF damping k^2 / R over the period (a voltage 1e-7 off moves 2e-8 rad)
    options = stepper.options
    creep = EQUILIBRIUM_TOL * motor.resistance / motor.torque_constant ** 2 * period
    allowed = options.rtol * np.abs(state[:4]) + options.atol + creep
    assert np.all(np.abs(after - state)[:4] <= allowed), np.abs(after - state)[:4]
    # open-loop motors: a rigid-body mode (the rates never read the motor angles), so no
    # static stiffness; the zero poles are zero to the eigensolver's round-off, far
    # below the slowest other pole
    angles = [list(lin.state_labels).index(f"motor_{i}.rotor.angle") for i in (1, 2)]
    assert np.all(lin.A[:, angles] == 0.0)
    poles, errors = _pole_errors(lin)
    at_zero = np.abs(poles) <= errors
    assert at_zero.sum() == 2 and np.all(errors[at_zero] < 1e-3 * np.abs(poles[~at_zero]).min())
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
    # "-0.4cm" converted: the decimal's rounding and one product, an ulp each
    assert data["operating_point"]["q"] == pytest.approx(-0.004, rel=2 * EPS, abs=0.0)
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
    assert isinstance(model, control.StateSpace)
    assert model.operating_point["q"] == pytest.approx(-0.004, rel=2 * EPS, abs=0.0)


def test_an_operating_point_past_the_end_stop_is_warned_about(params):
    pressed = linear.linearize(params, -0.01, load=(20.0, 0.0), statespace=False)
    assert any("past its 1.4 rad end stop" in w for w in pressed.info["warnings"])
    assert linear.linearize(params, -0.01, load=(0.2, 0.0),
                            statespace=False).info["warnings"] == []


def test_the_model_records_the_pivot_position_it_was_held_at(params):
    """The linear model's record of the wrist's options names the q it was held at (it
    said fixed_q = 0 whatever the operating point)."""
    model = linear.linearize(params, -0.004)
    options = model.info["wrist_options"]
    assert options["fixed_q"] == -0.004
    assert options["pivot_drive"].startswith("held at q")
