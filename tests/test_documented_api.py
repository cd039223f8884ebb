"""What the documentation shows of the Python API works: `Result`'s methods (README,
Quick start) and every example block of a docstring in ``src/vsj`` (``::`` blocks: TOML
files loaded by their loaders, Python examples executed). README.md's own blocks are
run by tests/test_readme.py."""

from __future__ import annotations

import importlib
from types import SimpleNamespace

import numpy as np
import pytest

import vsj
from doc_examples import check_toml, docstring_examples
from vsj.inputs import Sine
from vsj.output import verify, write_cases

EXAMPLES = docstring_examples()


@pytest.fixture(scope="module")
def short_run():
    """A 0.3 s wrist run (one motor driven), as the README's Python example makes it."""
    params = vsj.params.default()
    wrist = vsj.build_wrist(params).assemble()
    return vsj.simulate(wrist, {"motor_1": Sine(3.0, 0.5)}, 0.3,
                        initial=vsj.InitialState(q=-0.004),
                        options=vsj.SimulationOptions(output_step=0.01))


def test_result_to_xarray_is_the_trajectory_file(short_run, tmp_path):
    """`Result.to_xarray()` gives what `vsj simulate` writes to trajectory.nc: each signal
    over time with its unit, the same numbers (README, Quick start), and the run's report
    as attributes."""
    import xarray as xr

    result = short_run
    ds = result.to_xarray()
    assert list(ds.data_vars) == result.columns()
    assert np.array_equal(ds["time"].values, result.time) and ds["time"].attrs["units"] == "s"
    assert ds.attrs["vsj_version"] == vsj.__version__
    assert ds.attrs["success"] == 1 and ds.attrs["message"] == result.message
    assert ds.attrs["solver"] == result.solver["name"]
    assert ds.attrs["steps"] == result.solver["steps"]
    write_cases(tmp_path / "trajectory.nc", [("run", result)])
    with xr.open_dataset(tmp_path / "trajectory.nc") as written:
        for name in result.columns():
            assert ds[name].attrs["units"] == result.units[name] == written[name].attrs["units"]
            # both hold the run's doubles unchanged: equal bit for bit
            assert np.array_equal(ds[name].values, result[name])
            assert np.array_equal(written[name].isel(case=0).values, ds[name].values), name


def test_result_summary_columns_and_signals(short_run):
    """The rest of `Result` that the README's Quick start uses."""
    result = short_run
    text = result.summary()
    assert text.startswith("success: ") and "energy ledger: work in" in text
    assert f"{result.solver['steps']} steps" in text
    assert result.columns() == list(result.signals)
    assert result["theta_x"] is result.signals["theta_x"] and result.units["theta_x"] == "rad"
    with pytest.raises(KeyError, match="no signal 'theta_z'; signals include theta_x"):
        result["theta_z"]
    assert result.ledger["relative_residual"] < result.solver.get("ledger_tolerance", 1e-3)


def _ran_wrist(namespace, tmp_path):
    assert namespace["result"].success, namespace["result"].message


def _stepped(namespace, tmp_path):
    stepper, state = namespace["stepper"], namespace["state"]
    assert len(state) == len(stepper.state_names) and np.all(np.isfinite(state))


def _committed(namespace, tmp_path):
    out = tmp_path / "out"
    assert (out / "meta.json").is_file() and verify(out) == []


#: What a docstring's Python example leaves to its reader (the names it uses without
#: defining them), and what must hold after it ran; by the owner of the docstring.
PYTHON_EXAMPLES = {
    "vsj": (lambda tmp_path: {}, _ran_wrist),
    "vsj.stepper": (lambda tmp_path: {"params": vsj.params.default(), "u1": 1.0, "u2": -1.0,
                                      "tau_x": 0.01, "tau_y": 0.0}, _stepped),
    "vsj.output.files.ResultSet": (lambda tmp_path: {"args": SimpleNamespace(out=str(tmp_path / "out")),
                                               "estimate": 10_000, "record": {"example": 1}},
                             _committed),
}


def test_docstrings_show_examples():
    """The collection finds the examples (a broken pattern would make the next test
    check nothing)."""
    kinds = {e.kind for e in EXAMPLES}
    assert {"toml", "python", "text"} <= kinds
    assert sum(e.kind == "python" for e in EXAMPLES) == len(PYTHON_EXAMPLES)


@pytest.mark.parametrize("example", [e for e in EXAMPLES if e.kind != "text"],
                         ids=lambda e: e.where)
def test_docstring_example_works(example, tmp_path, monkeypatch):
    """A docstring's TOML example loads with the loader of its kind of file; its Python
    example runs in its module's namespace and does what it shows."""
    monkeypatch.chdir(tmp_path)
    if example.kind == "toml":
        check_toml(example.text, example.where, tmp_path)
        return
    owner = example.where.split(" ")[0]
    assert owner in PYTHON_EXAMPLES, f"{example.where}: a Python example no test runs"
    names, check = PYTHON_EXAMPLES[owner]
    module_name = owner
    while True:
        try:
            module = importlib.import_module(module_name)
            break
        except ModuleNotFoundError:
            module_name = module_name.rpartition(".")[0]
    namespace = {**vars(module), **names(tmp_path)}
    exec(compile(example.text, example.where, "exec"), namespace)
    check(namespace, tmp_path)


def test_linear_bandwidth_is_where_the_response_falls_3_db(params):
    """`vsj.linear.bandwidth` (README, For control design): the lowest frequency at which
    motor position to end-effector position falls 3 dB below its low-frequency value."""
    from vsj import linear

    model = linear.linearize(params, -0.004)
    drive = {"motor_1": 1.0, "motor_2": 1.0}

    def gain(omega):
        return np.abs(linear.transfer(model, "theta_x", drive, omega, input_angle=True))

    omega = linear.bandwidth(model, "theta_x", drive, input_angle=True)
    low = gain([1e-6])[0]
    # the root search stops within 1e-10 in log10(omega), and the gain changes by less
    # than itself per decade there: the ratio is right to 1e-10, 1e-8 leaves room
    assert gain([omega])[0] / low == pytest.approx(10 ** (-3 / 20), rel=1e-8)
    below = np.logspace(-3, np.log10(omega), 400)[:-1]
    assert np.all(gain(below) / low > 10 ** (-3 / 20))
