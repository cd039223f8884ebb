"""The vsj command end to end: outputs, exit codes, messages."""

import json

import numpy as np
import pytest

from conftest import SHORT_SCENARIO

from vsj.cli import main
from vsj.output import MANIFEST, read_trajectory, verify

SHORT = SHORT_SCENARIO
#: Round-off of the ledger per solver step (as in tests/test_regression.py).
LEDGER_ROUNDOFF_PER_STEP = 1e-15


def write(tmp_path, text, name="scen.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_simulate_writes_trajectory_meta_and_plot(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(write(tmp_path, SHORT)), "--out", str(out), "--csv",
                 "--plot"]) == 0
    header, data = read_trajectory(out / "trajectory.csv")
    assert header[0] == "time [s]"
    assert all(h.endswith("]") and " [" in h for h in header)
    assert "theta_x [rad]" in header and "friction.pg_1.mesh_sun.power [W]" in header
    assert data.shape == (31, len(header)) and np.all(np.isfinite(data))
    meta = json.loads((out / "meta.json").read_text())
    assert meta["success"] is True and meta["vsj_version"]
    # the run's ledger as the record keeps it: closed to its rtol plus round-off per step
    # (the terms are integrated by the state's error-controlled steps)
    solver = meta["cases"][0]["solver"]
    assert meta["cases"][0]["ledger"]["relative_residual"] <= (
        solver["options"]["rtol"] + solver["steps"] * LEDGER_ROUNDOFF_PER_STEP)
    assert meta["parameters"]["values"]["planetary.ring_inertia"]["source"]
    assert meta["scenario"]["definition"]["duration"] == "0.3 s"
    assert (out / "trajectory.png").stat().st_size > 1000
    assert "success" in capsys.readouterr().out
    # the set: every file with its hash in meta.json and in the directory's manifest
    assert set(meta["files"]) == {"trajectory.nc", "trajectory.csv", "trajectory.png"}
    assert sorted(p.name for p in out.iterdir()) == sorted([*meta["files"], "meta.json",
                                                            MANIFEST])
    assert verify(out) == []
    # the netCDF file holds the same signals, with their units
    import xarray as xr

    with xr.open_dataset(out / "trajectory.nc") as ds:
        assert ds["theta_x"].attrs["units"] == "rad" and ds["time"].attrs["units"] == "s"
        assert np.array_equal(ds["theta_x"].values[0], data[:, header.index("theta_x [rad]")])
        assert ds["success"].values.tolist() == [1]


def test_csv_is_written_only_on_request(tmp_path):
    out = tmp_path / "out"
    assert main(["simulate", str(write(tmp_path, SHORT)), "--out", str(out), "--no-plot"]) == 0
    assert (out / "trajectory.nc").exists() and not (out / "trajectory.csv").exists()


def test_failed_simulation_exits_1_with_time_and_state(tmp_path, capsys):
    text = SHORT.replace('output_step = "10 ms"', 'output_step = "10 ms"\nmax_steps = 5')
    out = tmp_path / "out"
    assert main(["simulate", str(write(tmp_path, text)), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "maximum number of steps at t =" in err and "vsm_1.ring.angle=" in err
    meta = json.loads((out / "meta.json").read_text())
    assert meta["success"] is False and not meta["cases"][0]["success"]


def test_pivot_leaving_its_range_fails(tmp_path, capsys):
    text = SHORT + '[inputs.motor_s]\nkind = "constant"\nvalue = "500 rad/s"\n'
    assert main(["simulate", str(write(tmp_path, text)), "--out", str(tmp_path / "o")]) == 1
    assert "pivot position left its allowed range" in capsys.readouterr().err


@pytest.mark.parametrize("edit,message", [
    (('duration = "0.3 s"', 'duration = "0.3 kg"'), "duration"),
    (('kind = "sine"', 'kind = "square"'), "unknown input kind 'square'"),
    (("[inputs.motor_1]", "[inputs.motor_9]"), "no input 'motor_9'"),
    (('friction = "arctan"', 'friction = "coulomb"'), "unknown friction law"),
    (('q = "-0.4 cm"', 'q = "-3 cm"'), "outside the pivot range"),
    (('network = "wrist"', 'network = "wrist"\ncolour = "red"'), "unknown key(s) colour"),
])
def test_bad_scenarios_exit_2_and_write_nothing(tmp_path, capsys, edit, message):
    out = tmp_path / "out"
    assert main(["simulate", str(write(tmp_path, SHORT.replace(*edit))), "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_unknown_scenario_lists_the_built_ins(capsys):
    assert main(["simulate", "fig-9.9"]) == 2
    err = capsys.readouterr().err
    assert "fig-4.15" in err and "planetary-fixed-sun" in err


def test_multi_case_columns_carry_the_case_label(tmp_path):
    text = SHORT + '[[cases]]\nlabel = "stiff"\ninitial = { q = "-2 cm" }\n' \
                   '[[cases]]\nlabel = "soft"\ninitial = { q = "1 cm" }\n'
    out = tmp_path / "out"
    assert main(["simulate", str(write(tmp_path, text)), "--out", str(out), "--no-plot",
                 "--csv"]) == 0
    header, data = read_trajectory(out / "trajectory.csv")
    stiff = data[:, header.index("phi_1@stiff [rad]")]
    soft = data[:, header.index("phi_1@soft [rad]")]
    assert np.max(np.abs(soft)) > 2 * np.max(np.abs(stiff))  # softer deflects more
    import xarray as xr

    with xr.open_dataset(out / "trajectory.nc") as ds:
        assert ds["case"].values.tolist() == ["stiff", "soft"]
        assert np.array_equal(ds["phi_1"].sel(case="soft").values, soft)


def test_planetary_fit_without_an_answer_writes_its_results_but_no_parameters(tmp_path,
                                                                                capsys):
    files = {}
    for fixed in ("sun", "ring"):
        files[fixed] = tmp_path / f"{fixed}.csv"
        assert main(["synth", "friction", "--fixed", fixed, "--report", "old", "--form",
                     "points", "--out", str(files[fixed])]) == 0
    params, out = tmp_path / "mine.toml", tmp_path / "fit"
    assert main(["fit", "planetary", "--fixed-sun", str(files["sun"]), "--fixed-ring",
                 str(files["ring"]), "--out", str(out), "--write-params", str(params)]) == 1
    assert f"{params} not written" in capsys.readouterr().err
    assert not params.exists() and verify(out) == []
    assert json.loads((out / "planetary.json").read_text())["explained"] is False


def test_an_output_directory_is_checked_before_the_run(tmp_path, capsys):
    """A file where the output directory should be is refused at once (exit 2), not
    after the simulation: the run's summary is never printed."""
    out = tmp_path / "out"
    out.write_text("not a directory\n")
    assert main(["simulate", str(write(tmp_path, SHORT)), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert f"--out {out}: exists and is not a directory" in captured.err
    assert "success" not in captured.out and out.read_text() == "not a directory\n"
