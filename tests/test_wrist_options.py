"""The eq 3.27 option reaches the assembled wrist, from Python and from a scenario."""

import numpy as np
import pytest

from vsj import scenario as scenarios
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
