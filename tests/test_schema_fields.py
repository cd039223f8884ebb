"""Each parameter of the wrist is declared once, in `vsj.params.SCHEMA`: the parts of the
wrist take their keywords, bounds and documentation from it, and the wrist reads every
entry through them."""

import dataclasses
import importlib.util
import inspect
import itertools
import math
import re
import sys

import pytest

from vsj import components
from vsj.components import _fields
from vsj.components._fields import Row, SchemaComponent, section
from vsj.errors import InputError
from vsj.network import Component, Parts
from vsj.params import RELATIONS, SCHEMA, Spec
from vsj.wrist import WristOptions, build_wrist

#: Every part of the wrist that takes parameters from a parameter file.
PARTS = [cls for cls in vars(components).values()
         if isinstance(cls, type) and issubclass(cls, SchemaComponent)]
#: Numeric keywords of those parts that are not entries of a parameter file, each with
#: its reason. A new one fails `test_no_part_declares_a_parameter_outside_the_schema`:
#: put it in SCHEMA, or here with its reason.
NOT_IN_SCHEMA = {
    ("ElasticElement", "stiffness"): "the linear model's stiffness, for twin tests "
                                     "(WristOptions.linear_stiffness)",
    ("ElasticElement", "initial_tension"): "coil pretension: static curves only, the engine "
                                           "cannot simulate it",
}
#: Entries of a section a part takes that are not its keywords, each with its reason.
NOT_TAKEN = {
    ("Transmission", "transmission.series_compliance_2"): "DOF 2's compliance: the wrist "
                                                           "gives it to tr_2 as compliance",
}
#: The keywords that are not fields and that a part needs to be built at all.
OPTIONS = {components.ElasticElement: {"model": "geometric"}}
#: The keywords that build a part with no schema entry given (a linear elastic element).
BARE = {components.ElasticElement: {"model": "linear", "stiffness": 1.0}}
#: Components of the wrist that take no parameter (sources and a pinned pivot).
WITHOUT_PARAMETERS = (components.VelocitySource, components.TorqueSource,
                      components.FixedPivot)


def documented(cls) -> dict[str, str]:
    """The docstring's "Parameters" section: keyword -> its entry."""
    section = cls.__doc__.split("Parameters\n----------\n", 1)[1]
    return {block.split(" : ", 1)[0]: block for block in re.split(r"\n(?=\S)", section)}


def test_every_part_of_the_wrist_takes_its_parameters_from_the_schema(params):
    assert {cls.__name__ for cls in PARTS} == {
        "DCMotor", "Differential", "ElasticElement", "PivotMechanism", "PlanetaryGearModule",
        "Transmission"}
    net = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc"))
    for part in net.components:
        assert isinstance(part, (SchemaComponent,) + WITHOUT_PARAMETERS), part


@pytest.mark.parametrize("cls", PARTS, ids=lambda cls: cls.__name__)
def test_no_part_declares_a_parameter_outside_the_schema(cls):
    fields = {f.name: f for f in cls.fields}
    for field in fields.values():
        for key in field.keys:
            section, name = key.split(".", 1)
            assert name in SCHEMA.get(section, {}), f"{cls.__name__}.{field.name}: {key}"
    for name, parameter in inspect.signature(cls).parameters.items():
        if name in fields:
            assert parameter.kind is parameter.KEYWORD_ONLY
            assert parameter.default is fields[name].default
        elif "float" in str(parameter.annotation):
            assert (cls.__name__, name) in NOT_IN_SCHEMA, (
                f"{cls.__name__}({name}=...) is a number outside SCHEMA")


@pytest.mark.parametrize("cls", PARTS, ids=lambda cls: cls.__name__)
def test_each_keyword_is_documented_with_its_entry(cls):
    entries = documented(cls)
    assert list(entries) == ["name"] + [f.name for f in cls.fields]
    for field in cls.fields:
        entry = entries[field.name]
        for key in field.keys:
            section, name = key.split(".", 1)
            spec = SCHEMA[section][name]
            assert spec.description in entry, (cls.__name__, key)
            assert spec.allowed().split(" ")[0] in entry  # ">", ">=" or "finite"
        if not isinstance(field, Row):
            assert f"``{field.key}``" in entry


def _bad(spec):
    """A value the entry refuses: below its minimum, zero where it must not be, or NaN."""
    if spec.minimum is not None:
        return spec.minimum - 1.0
    return 0.0 if spec.nonzero else math.nan


@pytest.mark.parametrize("cls", PARTS, ids=lambda cls: cls.__name__)
def test_a_part_takes_the_files_values_and_refuses_what_the_schema_refuses(cls, params):
    """The bundled set's values build every part, and each entry's out-of-bounds value
    is refused, naming the keyword, the bound and the file's key."""
    good = {f.name: f.read(params) for f in cls.fields}
    part = cls("part", **good, **OPTIONS.get(cls, {}))
    for field in cls.fields:
        assert getattr(part, field.name) == good[field.name]
    for field in cls.fields:
        for index, key in enumerate(field.keys):
            section, name = key.split(".", 1)
            spec = SCHEMA[section][name]
            value = _bad(spec)
            label = field.name
            if isinstance(field, Row):
                value = tuple(value if k == index else v for k, v in enumerate(good[field.name]))
                label = f"{field.name} {name}"
            with pytest.raises(InputError) as error:
                cls("part", **{**good, field.name: value}, **OPTIONS.get(cls, {}))
            message = str(error.value)
            # keyword, the range it broke, the value and the file's key with its meaning
            assert message.startswith(f"part: {label} {spec.check(_bad(spec))}"), message
            assert f"got {_bad(spec)!r}" in message
            assert f"({key}: {spec.description})" in message


@pytest.mark.parametrize("cls", PARTS, ids=lambda cls: cls.__name__)
def test_a_part_needs_no_parameter_set(cls):
    """Built from Python: only required keywords must be given; unknown ones are refused."""
    required = {f.name: 1.0 for f in cls.fields if f.default is inspect.Parameter.empty}
    options = BARE.get(cls, {})
    part = cls("part", **required, **options)
    assert isinstance(part, Component)
    with pytest.raises(TypeError, match="no_such_keyword"):
        cls("part", no_such_keyword=1.0, **required, **options)
    if required:
        with pytest.raises(TypeError, match=f"missing required keyword argument.*"
                                            f"{next(iter(required))}"):
            cls("part", **options)


class _Recording(dict):
    """A parameter set's values that remember which keys were read."""

    def __init__(self, values):
        super().__init__(values)
        self.read = set()

    def __getitem__(self, key):
        self.read.add(key)
        return super().__getitem__(key)


def test_the_wrist_reads_every_entry_of_the_schema_into_its_parts(params):
    """A schema entry that no part reads (or reads under another entry's name) fails."""
    # distinct values in the per-DOF pair, so reading DOF 1's for DOF 2 shows
    params = params.with_overrides({"transmission.series_compliance_1": "0.01 rad/(N m)",
                                    "transmission.series_compliance_2": "0.02 rad/(N m)"},
                                   origin="test")
    values = _Recording(params.values)
    recording = dataclasses.replace(params, values=values)
    for elastic, drive, pivot in itertools.product(("geometric", "exponential"),
                                                   ("velocity", "dc"), ("velocity", "dc")):
        net = build_wrist(recording, WristOptions(elastic=elastic, motors=drive,
                                                  pivot_drive=pivot))
        for part in net.components:
            if not isinstance(part, SchemaComponent):
                continue
            for field in part.fields:
                key = field.key
                if part.name.startswith("tr_") and field.name == "compliance":
                    key = f"transmission.series_compliance_{part.name[-1]}"
                if isinstance(field, Row):
                    assert getattr(part, field.name) == tuple(params[k] for k in field.keys)
                else:
                    assert getattr(part, field.name) == params[key], (part.name, field.name)
    everything = {f"{section}.{name}" for section, specs in SCHEMA.items() for name in specs}
    assert values.read == everything


def test_a_field_is_read_only_from_an_entry_of_its_kind(params):
    with pytest.raises(ValueError, match="compliance cannot be read from transmission.viscous"):
        components.Transmission.from_parameters(
            "tr", params, keys={"compliance": "transmission.viscous"})
    with pytest.raises(ValueError, match="no field"):
        components.Transmission.from_parameters("tr", params, keys={"backlash": "pivot.ratio"})


def _changed(value: float) -> tuple[float, ...]:
    """Other values of an entry, of which one is inside the bounds of the entry and the
    relations of the part (a zero becomes a small positive value; anything else grows by
    a quarter, or else shrinks by a fifth)."""
    return (1.25 * value, 0.8 * value) if value != 0.0 and math.isfinite(value) else (1e-3,)


@pytest.mark.parametrize("cls", PARTS, ids=lambda cls: cls.__name__)
def test_every_field_changes_what_the_part_adds_to_a_network(cls, params):
    """An entry that a part takes but ignores (declared, documented, never used) fails."""
    good = {f.name: f.read(params) for f in cls.fields}
    if cls is components.Transmission:
        good["compliance"] = 1e-3  # the damping acts only with a compliance
    for field in cls.fields:
        for index, key in enumerate(field.keys):
            options = dict(OPTIONS.get(cls, {}))
            if field.name == "exponential":
                options["model"] = "exponential"
            before = repr(cls("part", **good, **options).parts())
            for value in _changed(good[field.name][index] if isinstance(field, Row)
                                  else good[field.name]):
                if isinstance(field, Row):
                    value = tuple(value if k == index else v
                                  for k, v in enumerate(good[field.name]))
                try:
                    part = cls("part", **{**good, field.name: value}, **options)
                    break
                except ValueError:
                    continue
            assert repr(part.parts()) != before, f"{cls.__name__} ignores {field.name} ({key})"


def _sections(cls) -> set[str]:
    return {key.split(".", 1)[0] for field in cls.fields for key in field.keys}


@pytest.mark.parametrize("cls", PARTS, ids=lambda cls: cls.__name__)
def test_each_section_a_part_uses_maps_onto_its_keywords_once(cls):
    """Every entry of a section a part takes is one of its keywords (or a row's entry),
    unless `NOT_TAKEN` says why not; no entry is the keyword of two fields."""
    own = [f.key for f in cls.fields if not isinstance(f, Row)]
    assert len(own) == len(set(own)), own
    rows = {key for f in cls.fields if isinstance(f, Row) for key in f.keys}
    assert not rows & set(own), rows & set(own)
    for name in _sections(cls):
        entries = {f"{name}.{entry}" for entry in SCHEMA[name]}
        skipped = {key for (part, key) in NOT_TAKEN if part == cls.__name__}
        assert entries - skipped == (set(own) | rows) & entries, name
        assert not skipped & (set(own) | rows)


def _run_again(module, name: str, monkeypatch):
    """The code of ``module`` run again as module ``name`` (put in `sys.modules` for the
    test's duration), so that what it builds at import reads today's `SCHEMA`."""
    spec = importlib.util.spec_from_file_location(name, module.__file__)
    fresh = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, name, fresh)
    spec.loader.exec_module(fresh)
    return fresh


def _rebuilt(cls, monkeypatch):
    """``cls`` as the package would define it from today's `SCHEMA`: `_fields` (whose
    `FRICTION` is made at import) and the part's module run again; the package's own
    classes stay as they are."""
    _run_again(_fields, _fields.__name__, monkeypatch)
    module = inspect.getmodule(cls)
    return getattr(_run_again(module, f"{module.__name__}_rebuilt", monkeypatch), cls.__name__)


@pytest.mark.parametrize("cls", PARTS, ids=lambda cls: cls.__name__)
def test_a_new_schema_entry_is_a_keyword_with_its_check_and_doc(cls, params, monkeypatch):
    """An entry added to a section a part takes becomes, with no other code, a keyword
    in its signature, a line of its docs, a bounds check and a value read from a set."""
    new = Spec("m", "cm", "probe entry added by a test", 0.0, strict=True, default=0.25)
    added = {f"{name}.probe_{name}": f"probe_{name}" for name in _sections(cls)}
    for key, word in added.items():
        monkeypatch.setitem(SCHEMA[key.split(".")[0]], word, new)
    part = _rebuilt(cls, monkeypatch)
    required = {f.name: 1.0 for f in cls.fields if f.default is inspect.Parameter.empty}
    values = dict(params.values)
    for key, word in added.items():
        keyword = inspect.signature(part).parameters[word]
        assert (keyword.kind, keyword.default) == (inspect.Parameter.KEYWORD_ONLY, 0.25)
        assert "probe entry added by a test [m], > 0 m" in documented(part)[word]
        with pytest.raises(InputError, match=rf"p: {word} must be > 0 cm, got -1\.0 "
                                             rf"\({key}: probe entry added by a test\)"):
            part("p", **BARE.get(cls, {}), **required, **{word: -1.0})
        values[key] = 0.5
    built = part.from_parameters("p", dataclasses.replace(params, values=values),
                                 **OPTIONS.get(cls, {}))
    assert all(getattr(built, word) == 0.5 for word in added.values())


def _probe(fields, init=None):
    body = {"ports": (), "fields": fields, "parts": lambda self: Parts()}
    if init is not None:
        body["__init__"] = init
    return type("Probe", (SchemaComponent,), body)


def test_an_entry_cannot_be_declared_twice_in_a_part():
    """Two keywords for one entry, or a constructor keyword that repeats a field, is
    refused when the class is made."""
    _probe(section("transmission"))  # the section once: accepted
    with pytest.raises(TypeError, match="entries transmission.ratio, .* taken by more than one"):
        _probe(section("transmission") + section("transmission", rename={
            key: f"other_{key}" for key in SCHEMA["transmission"]}))
    with pytest.raises(TypeError, match="keyword taken twice"):
        _probe(section("transmission") + section("pivot", skip=set(SCHEMA["pivot"]) - {
            "ratio"}))

    def init(self, name, *, ratio=1.0, **values):
        super(type(self), self).__init__(name, **values)

    with pytest.raises(TypeError, match="ratio are fields of SCHEMA"):
        _probe(section("transmission"), init)


def test_a_part_checks_the_relations_between_its_entries_as_a_file_does(params):
    """The pivot range's relations are `RELATIONS`' own, with the same words."""
    reach = {"amplitude": 0.02, "ratio": 10.0}
    texts = {r.text for r in RELATIONS}
    for q_min, q_max in ((0.01, -0.01), (-0.03, 0.01), (-0.01, 0.03)):
        with pytest.raises(InputError) as error:
            components.PivotMechanism("pv", **reach, q_min=q_min, q_max=q_max)
        message = str(error.value)
        assert message.startswith("pv: ") and message.split(": ", 1)[1].split(" (")[0] in texts
        assert f"q_min = {q_min!r}" in message or f"q_max = {q_max!r}" in message
    # the reach itself is allowed, at both ends
    assert components.PivotMechanism("pv", **reach, q_min=-0.02, q_max=0.02).q_max == 0.02
    whole = components.PivotMechanism.from_parameters("pv", params, q_min=None, q_max=None)
    assert (whole.q_min, whole.q_max) == (-params["pivot.amplitude"], params["pivot.amplitude"])
    with pytest.raises(ValueError, match="both as a value and as an entry"):
        components.PivotMechanism.from_parameters("pv", params, keys={"q_min": "pivot.q_max"},
                                                  q_min=None)


def test_the_ideal_planetary_takes_the_tooth_counts_bounds_from_their_entries():
    """`IdealPlanetary` is no part of a file, but its tooth counts are entries: their
    bounds and message are the schema's."""
    for teeth, key in (((0.0, 50.0), "planetary.sun_teeth"),
                       ((16.0, -1.0), "planetary.ring_teeth")):
        spec = SCHEMA["planetary"][key.split(".")[1]]
        with pytest.raises(InputError, match=rf"pg: {key.split('.')[1]} {spec.check(-1.0)}, "
                                             rf"got -?[01]\.0 \({key}: {spec.description}\)"):
            components.IdealPlanetary("pg", *teeth)
