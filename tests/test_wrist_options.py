"""The eq 3.27 option reaches the assembled wrist, from Python and from a scenario."""

import numpy as np
import pytest

from vsj import scenario as scenarios
from vsj.cli import main
from vsj.errors import InputError
from vsj.wrist import WristOptions, build_wrist


#: The ring mesh's level and sharpness: the sun mesh's times a ratio of tooth counts (a
#: division and a product, or a division of the two), an ulp each.
TWO_ROUNDINGS = 2 * np.finfo(float).eps


def _agrees(value, expected):
    return abs(value - expected) <= TWO_ROUNDINGS * abs(expected)


def _ring_mesh(structure, name="pg_1.mesh_ring"):
    return next(f for f in structure.frictions if f.name == name)


def test_mesh_relation_sets_the_ring_mesh_of_both_planetaries(params):
    pg = params.planetary
    x = pg.sun_teeth / pg.ring_teeth
    printed = build_wrist(params).assemble()
    equal = build_wrist(params, WristOptions(mesh_relation="equal-force")).assemble()
    for name in ("pg_1.mesh_ring", "pg_2.mesh_ring"):
        assert _agrees(_ring_mesh(printed, name).k, x * pg.mesh_stiction)
        assert _agrees(_ring_mesh(equal, name).k, pg.mesh_stiction / x)
        assert _agrees(_ring_mesh(equal, name).sharpness, pg.mesh_sharpness / x)


def test_a_scenario_chooses_the_relation_and_a_wrong_one_is_named(params, tmp_path):
    text = ('duration = "0.1 s"\n[model]\nmesh_relation = "equal-force"\n'
            '[inputs.motor_1]\nkind = "constant"\nvalue = "1 rad/s"\n')
    scen = scenarios.loads(text, "mine.toml")
    structure = scenarios.prepare_case(scen, scen.cases[0], params).structure
    x = params.planetary.sun_teeth / params.planetary.ring_teeth
    assert _agrees(_ring_mesh(structure).k, params.planetary.mesh_stiction / x)
    with pytest.raises(InputError, match=r"mine.toml: model.mesh_relation: 'equal' is not one of"):
        scenarios.loads(text.replace('"equal-force"', '"equal"'), "mine.toml")


def _circle(elastic: str, cases: int = 1) -> str:
    """A short scenario on the wrist with the ``elastic`` model and ``cases`` cases."""
    return (f'duration = "0.02 s"\n[model]\nelastic = "{elastic}"\n'
            '[inputs.motor_1]\nkind = "constant"\nvalue = "1 rad/s"\n'
            + "".join(f'[[cases]]\nlabel = "c{k}"\n' for k in range(cases)))


def test_a_set_that_changes_what_the_elastic_model_does_not_read_is_warned_of(params,
                                                                              tmp_path):
    """A design changes the springs and anchors (the geometric model's row); run with the
    exponential model of eq 4.5, which does not read them, the run says so. The geometric
    model reads them (no warning), and the bundled set changes nothing."""
    design = params.with_overrides({"elastic_element.spring_stiffness": "150 N/m",
                                    "elastic_element.anchor_y": "2.5 cm"}, origin="design.toml")
    exponential = scenarios.loads(_circle("exponential"), "exp.toml")
    geometric = scenarios.loads(_circle("geometric"), "geo.toml")
    warned = scenarios.prepare_case(exponential, exponential.cases[0], design).run()
    named = [w for w in warned.warnings if "does not read" in w]
    assert len(named) == 1
    assert "design.toml" in named[0] and "'exponential'" in named[0]
    assert "elastic_element.spring_stiffness" in named[0]
    assert "elastic_element.anchor_y" in named[0]
    assert "elastic_element.a1" not in named[0]
    for scen, p in ((geometric, design), (exponential, params)):
        result = scenarios.prepare_case(scen, scen.cases[0], p).run()
        assert not any("does not read" in w for w in result.warnings)
    # a1 changed under the geometric model: the other row, named the same way
    fitted = params.with_overrides({"elastic_element.a1": "0.5 N*m/rad"}, origin="fit.toml")
    other = scenarios.prepare_case(geometric, geometric.cases[0], fitted).run()
    assert any("elastic_element.a1" in w and "'geometric'" in w for w in other.warnings)


def test_the_command_gives_a_warning_every_case_shares_once(params, tmp_path, capsys):
    (tmp_path / "exp.toml").write_text(_circle("exponential", cases=3))
    design = tmp_path / "design.toml"
    design.write_text('extends = "second_prototype"\n[elastic_element]\n'
                      'spring_stiffness = { value = "150 N/m", source = "a design" }\n')
    assert main(["simulate", str(tmp_path / "exp.toml"), "--params", str(design),
                 "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "does not read" in line]
    assert len(lines) == 1 and lines[0].startswith("vsj: warning: [every case]"), err


def test_the_model_commands_say_what_their_elastic_model_does_not_read(params, tmp_path,
                                                                       capsys):
    """vsj linearize (as export-model and fmu, through the same options) and vsj datasheet
    with a design's springs and the exponential model: the warning names --elastic."""
    design = tmp_path / "design.toml"
    design.write_text('extends = "second_prototype"\n[elastic_element]\n'
                      'spring_stiffness = { value = "150 N/m", source = "a design" }\n')
    assert main(["linearize", "--params", str(design), "--elastic", "exponential",
                 "--out", str(tmp_path / "lin.json")]) == 0
    err = capsys.readouterr().err
    assert "elastic_element.spring_stiffness" in err and "--elastic chooses" in err
    assert main(["linearize", "--params", str(design), "--out",
                 str(tmp_path / "lin2.json")]) == 0
    assert "does not read" not in capsys.readouterr().err
    assert main(["datasheet", "--params", str(design), "--elastic", "exponential",
                 "--points", "2", "--out", str(tmp_path / "ds")]) == 0
    assert "--elastic chooses" in capsys.readouterr().err
