"""The explorer's model side (issue 36, `vsj.explore.setting`), without a browser: the
exported files give ``vsj simulate`` the explorer's run, the controls refuse what is out
of their range, and the views' numbers (lag, stiffness at a state, ledger) are the
model's."""

from __future__ import annotations

import socket
from dataclasses import replace

import numpy as np
import pytest
import xarray as xr

from vsj import characteristics
from vsj.cli import main
from vsj.control import mechanical_stiffness
from vsj.errors import InputError
from vsj.explore import Explorer, Setting
from vsj.params import load as load_params
from vsj.wrist import WristOptions, build_wrist

#: The issue's bound on the explorer's run against ``vsj simulate`` of its files (one code
#: path, every number written exactly: they agree to the bit).
SAME = 1e-9


@pytest.fixture(scope="module")
def explorer(params):
    return Explorer(params)


def test_export_runs_to_the_same_result(explorer, tmp_path):
    """A setting away from every default (a friction coefficient the set does not have,
    a sine, a PD, a wall): the explorer's run and ``vsj simulate`` of the two files it
    writes are the same run."""
    s = replace(explorer.default(), q=-0.013, reference="sine", amplitude=0.35,
                frequency=1.5, duration=1.0, controller="PD", environment="wall",
                wall_angle=0.25, wall_stiffness=3e4, friction="arctan",
                coefficients={"transmission.stiction": 0.0137,
                              "friction.arctan_sharpness": 25.0})
    view = explorer.run(s)
    scenario, params = explorer.export(s, tmp_path / "files")
    assert load_params(params).values == explorer.parameters(s).values
    assert load_params(params)["transmission.stiction"] == 0.0137
    assert main(["simulate", str(scenario), "--params", str(params), "--out",
                 str(tmp_path / "run")]) == 0
    with xr.open_dataset(tmp_path / "run" / "trajectory.nc") as ds:
        np.testing.assert_allclose(ds["time"].values, view.result.time, rtol=0, atol=SAME)
        for name in ("theta_x", "control.theta_x", "motor_1", "spring.vsm_1.torque",
                     "contact.wall.force", "actuator.voltage_2"):
            np.testing.assert_allclose(ds[name].values[0], view.result[name], rtol=0,
                                       atol=SAME, err_msg=name)
    assert view.impacts["wall"], "the sine reaches the wall"


def test_export_replaces_its_own_files_and_never_a_users(explorer, tmp_path, capsys):
    """A second export replaces the first's files (they carry vsj's mark); a hand-written
    scenario.toml in the directory is refused before either file is written; an --out
    that is a file is refused when the command starts."""
    s = explorer.default()
    first = explorer.export(s, tmp_path / "files")
    assert explorer.export(replace(s, q=0.004), tmp_path / "files") == first
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "scenario.toml").write_text("# my own scenario\nduration = \"1 s\"\n")
    with pytest.raises(InputError, match=r"scenario.toml: exists and vsj did not write it"):
        explorer.export(s, mine)
    assert (mine / "scenario.toml").read_text().startswith("# my own scenario")
    assert not (mine / "params.toml").exists()
    (tmp_path / "afile").write_text("")
    assert main(["explore", "--out", str(tmp_path / "afile"), "--no-browser"]) == 2
    assert "is not a directory" in capsys.readouterr().err


def test_lag_grows_as_the_joint_softens(explorer):
    """From the stiffest setting to the softest, theta_x trails the circle more (the
    elastic elements give way under the output side's inertia and friction), and the
    stiffness the views show falls."""
    lags, stiffness = [], []
    for q in (explorer.q_min, -0.004, explorer.q_max):
        view = explorer.run(replace(explorer.default(), q=q))
        lags.append(view.lag)
        stiffness.append(view.stiffness[0, 0])
    assert lags[0] < lags[1] < lags[2]
    assert stiffness[0] > stiffness[1] > stiffness[2] > 0.0


def test_stiffness_at_a_state_takes_each_spring_tangent(params):
    """`mechanical_stiffness` at deflected springs: with both elements deflected alike
    the wrist's stiffness scales with the element's tangent stiffness at that deflection
    (`vsj.characteristics.stiffness`, the law evaluated on its own), for the geometric
    law whose tangent changes with the deflection."""
    q, phi = -0.004, 0.3
    structure = build_wrist(params, WristOptions(motors="dc", pivot_drive="fixed", fixed_q=q,
                                                 elastic="geometric")).assemble()
    rest = mechanical_stiffness(structure, q)
    bent = mechanical_stiffness(structure, q, deflections={"vsm_1": phi, "vsm_2": phi})
    spring = structure.springs[0]
    ratio = (characteristics.stiffness(spring.law, spring.parameters, q, phi)
             / characteristics.stiffness(spring.law, spring.parameters, q))
    assert abs(ratio - 1.0) > 0.05  # the law is nonlinear here: the check can fail
    # the same products of the same floats, in another order: a few ulp of K
    np.testing.assert_allclose(bent, ratio * rest, rtol=1e-12, atol=1e-12 * np.abs(rest).max())
    with pytest.raises(InputError, match="no spring"):
        mechanical_stiffness(structure, q, deflections={"vsm_3": 0.1})


def test_ledger_view_closes(explorer):
    """The ledger's bars: work in = stored + dissipated + residual (the run's own
    ledger, grouped)."""
    view = explorer.run(replace(explorer.default(), environment="wall"))
    rows = dict(view.ledger.rows)
    work = sum(v for k, v in rows.items() if k.startswith("in: "))
    kept = sum(v for k, v in rows.items() if k.startswith(("stored: ", "dissipated: ")))
    assert "dissipated: contact" in rows and "dissipated: friction" in rows
    assert work - kept == pytest.approx(view.ledger.residual, abs=1e-15 * max(1.0, work))


@pytest.mark.parametrize("text, message", [
    ("abc", "does not start with a number"),
    ("3 cm", "outside the allowed"),
    ("-2.3 cm", "outside the allowed"),
    ("1 s", "cannot be converted"),
])
def test_controls_refuse_with_the_range(explorer, text, message):
    with pytest.raises(InputError, match=message) as caught:
        explorer.controls["q"].parse(text)
    assert "[-2.2 cm, 2 cm]" in str(caught.value)


def test_controls_read_units(explorer):
    q = explorer.controls["q"]
    assert q.parse("-1.5") == pytest.approx(-0.015, rel=1e-15)  # a bare number: cm
    assert q.parse("-0.015 m") == -0.015
    assert q.parse("-2.2 cm") == explorer.q_min
    k = explorer.controls["k"]
    with pytest.raises(InputError, match=r"\(0 V/rad"):
        k.parse("0 V/rad")  # the open end of (0, 100] V/rad
    stiction = explorer.controls["transmission.stiction"]
    assert stiction.parse("4 mN m") == pytest.approx(0.004, rel=1e-15)
    with pytest.raises(InputError, match="outside"):
        stiction.parse("-1 mN m")


def test_setting_refuses_unknown_choices(explorer):
    for change in ({"reference": "square"}, {"friction": "magic"},
                   {"environment": "ceiling"}, {"coefficients": {"motor.resistance": 1.0}}):
        with pytest.raises(InputError):
            explorer.scenario_table(replace(explorer.default(), **change))
    with pytest.raises(InputError, match="outside"):
        explorer.scenario_table(replace(explorer.default(), q=0.05))


def test_short_run_has_no_lag(explorer):
    """A run shorter than the fade-in and one period has no full period to measure."""
    view = explorer.run(replace(explorer.default(), duration=0.5, frequency=1.0))
    assert view.lag is None


def test_cli_refuses_a_bad_port(capsys):
    assert main(["explore", "--port", "0", "--no-browser"]) == 2
    assert "--port" in capsys.readouterr().err


def test_cli_refuses_a_port_in_use_naming_it(capsys):
    """A port another program listens on: exit 2 and the port named, not the server's
    traceback."""
    with socket.socket() as taken:
        taken.bind(("localhost", 0))  # a free port, chosen by the system, now in use
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["explore", "--port", str(port), "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert f"option --port: cannot serve on localhost:{port}" in err
    assert "Traceback" not in err


def test_setting_is_plain_data():
    s = Setting(q=0.0, k=1.0, Ti=0.1, Td=0.0)
    assert replace(s, q=0.01) != s and s.fade_in() == 0.5


def test_another_parameter_set_moves_the_setting_into_its_range(explorer, params):
    """Loading a set whose pivot range is narrower clips q into it, and the friction
    coefficients become the new set's (the controls show what it holds)."""
    narrow = params.with_overrides({"pivot.q_min": "-1 cm", "transmission.stiction": "0.02 N m"},
                                   origin="narrow")
    other, s = explorer.with_params(narrow, replace(explorer.default(), q=explorer.q_min,
                                                    coefficients={"transmission.stiction": 0.001}))
    assert s.q == other.q_min == -0.01 and s.coefficients == {}
    assert other.parameters(s)["transmission.stiction"] == 0.02
    assert other.controls["q"].allowed() == "[-1 cm, 2 cm]"


def test_geometric_elastic_element_runs(explorer):
    """The potential form of the geometry (eq 3.1-3.7): its tangent stiffness changes
    with the deflection, so the ellipse at the run's last state differs from the one at
    rest."""
    view = explorer.run(replace(explorer.default(), elastic="geometric", reference="step",
                                amplitude=0.4, duration=0.6))
    assert view.lag is not None and view.lag > 0.0
    assert not np.allclose(view.stiffness, view.stiffness_rest, rtol=1e-6)
