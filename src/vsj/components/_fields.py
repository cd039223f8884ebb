"""Components whose parameters are entries of `vsj.params.SCHEMA`, declared there once.

A part of the wrist (the motor, the differential, ...) takes a section of the
parameter file. Its class names that section (`section`, with a table of the
keys it renames and the defaults it gives Python users) and derives from
`SchemaComponent`; each entry then becomes, without being written again:

* a keyword of the constructor, in its signature (`inspect.signature`, ``help``);
* an attribute of the instance, in SI;
* a check with the entry's own bounds, whose message names the keyword, the
  value, the allowed range and the file's key;
* a line of the class docstring's "Parameters" section with the entry's
  description, unit and bounds;
* a value read from a parameter set by `SchemaComponent.from_parameters`,
  which is all `vsj.wrist.build_wrist` does per component.

So a new parameter of a part is its `Spec` in `SCHEMA` (and its value in the
parameter files) plus the line of `parts` that uses it. The constructor keeps
what is not a physical parameter (an input channel, a model choice) as its own
keywords and passes the rest on: ``def __init__(self, name, *, channel=None,
**values): super().__init__(name, **values)``.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from collections.abc import Iterable, Mapping

from ..errors import InputError
from ..friction import DEFAULT_SHARPNESS
from ..network import Component
from ..params import RELATIONS, SCHEMA, Parameters, Spec
from ..units import from_si

#: The default of a keyword that has none: the caller must give it.
REQUIRED = inspect.Parameter.empty


@dataclass(frozen=True)
class Field:
    """One parameter of a component: keyword ``name``, the schema entry ``key``
    (``"section.name"``) it is, and the value it takes when left out.

    A default is the component's own choice and is accepted even where the
    file's bounds refuse it: it says that a part is absent (0 kg m^2: no
    inertia; ``inf`` V: no voltage rating; None: derived from other values).
    """

    name: str
    key: str
    default: object = REQUIRED

    @property
    def spec(self) -> Spec:
        """The schema entry (`vsj.params.Spec`) of ``key``: unit, bounds and description."""
        section, name = self.key.split(".", 1)
        return SCHEMA[section][name]

    @property
    def keys(self) -> tuple[str, ...]:
        """The schema entries this field reads."""
        return (self.key,)

    def take(self, component: str, value):
        """``value`` in SI if the entry allows it (or it is the default), else an
        `InputError` naming ``component``, the keyword, the value, the range and the
        key."""
        if value is None and self.default is None:
            return None
        return self._check(component, self.name, self.key, value)

    def _check(self, component: str, label: str, key: str, value) -> float:
        if self.default is not REQUIRED and value == self.default:
            return float(value)
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise InputError(f"{component}: {label} must be a number, got {value!r} "
                             f"({key})") from None
        section, name = key.split(".", 1)
        spec = SCHEMA[section][name]
        why = spec.check(number)
        if why:
            raise InputError(f"{component}: {label} {why}, got {number!r} "
                             f"({key}: {spec.description})")
        return number

    def read(self, params: Parameters, key: str | None = None):
        """This field's value in ``params``: its own entry's, or that of ``key``, an
        entry of the same unit and bounds (DOF 2's of a per-DOF pair)."""
        if key is None:
            return params[self.key]
        section, name = key.split(".", 1)
        if not self.spec.same_kind(SCHEMA[section][name]):
            raise ValueError(f"{self.name} cannot be read from {key}: its unit or bounds "
                             f"differ from {self.key}'s")
        return params[key]

    def describe(self) -> str:
        """The docstring entry: description, unit and bounds, default, key."""
        default = "" if self.default is REQUIRED else f", default {self.default!r}"
        return (f"{self.name} : {self.annotation()}{default}\n    "
                f"{_entry(self.spec)}; ``{self.key}``")

    def annotation(self) -> str:
        """The keyword's type, as the generated signature shows it."""
        return "float | None" if self.default is None else "float"


@dataclass(frozen=True)
class Row(Field):
    """A parameter that is a row of schema entries, in the order of ``row`` (a spring
    law's parameter row, `vsj.springs.GEOMETRY_FIELDS`); ``key`` is their section."""

    row: tuple[str, ...] = ()

    @property
    def keys(self) -> tuple[str, ...]:
        """The row's schema entries, in its order."""
        return tuple(f"{self.key}.{name}" for name in self.row)

    def take(self, component: str, value):
        """The row as a tuple in SI, each entry checked by its own bounds."""
        if value is None and self.default is None:
            return None
        try:
            entries = tuple(value)
        except TypeError:
            entries = ()
        if len(entries) != len(self.row):
            raise InputError(f"{component}: {self.name} must be the {len(self.row)} values "
                             f"{', '.join(self.row)} (SI), got {value!r}")
        return tuple(self._check(component, f"{self.name} {name}", key, entry)
                     for name, key, entry in zip(self.row, self.keys, entries))

    @property
    def spec(self) -> Spec:
        """A row has one spec per entry (`keys`), not one."""
        raise TypeError(f"{self.name} is a row of {len(self.row)} entries, not one entry")

    def read(self, params: Parameters, key: str | None = None):
        """The row's values in ``params`` (always from its own entries)."""
        if key is not None:
            raise ValueError(f"{self.name} is a row of [{self.key}]; it cannot be read "
                             f"from {key!r}")
        return tuple(params[k] for k in self.keys)

    def describe(self) -> str:
        """The docstring entry: each entry's description, unit and bounds, in order."""
        entries = "\n".join(f"    - ``{name}``: {_entry(SCHEMA[self.key][name])}"
                            for name in self.row)
        return (f"{self.name} : {self.annotation()}, default {self.default!r}\n    The "
                f"entries of ``[{self.key}]`` in this order:\n\n{entries}")

    def annotation(self) -> str:
        """The keyword's type, as the generated signature shows it."""
        return "Sequence[float] | None"


def _entry(spec: Spec) -> str:
    """``description [unit], bounds`` of an entry, in the unit a component takes: the
    file's display unit where it is SI's scale, else the SI unit."""
    unit = spec.display if spec.display == "1" or from_si(1.0, spec.display) == 1.0 else (
        spec.unit.replace("**", "^").replace("*", " "))
    return f"{spec.description} [{unit}], {spec.allowed(unit)}"


def section(name: str, *, skip: Iterable[str] = (),
            rename: Mapping[str, str] | None = None,
            defaults: Mapping[str, object] | None = None) -> tuple[Field, ...]:
    """The fields of a component taken from section ``name`` of `SCHEMA`: every entry,
    in the schema's order, so that a new entry is a new keyword without more code.

    ``skip``: entries the component does not take as keywords of their own (another
    DOF's, or those a `Row` holds). ``rename``: keyword for an entry whose name in the
    component differs from the file's (``{"series_damping": "damping"}``).
    ``defaults``: value of a keyword left out (by keyword); without one the entry's
    own file default (`Spec.default`) applies, and without that it is required.
    """
    if name not in SCHEMA:
        raise KeyError(f"no parameter section {name!r}")
    specs = SCHEMA[name]
    skip, rename, defaults = set(skip), dict(rename or {}), dict(defaults or {})
    keys = [key for key in specs if key not in skip]
    for what, given, known in (("skipped key", skip, specs), ("renamed key", rename, keys)):
        unknown = sorted(set(given) - set(known))
        if unknown:
            raise KeyError(f"[{name}] has no {what} {', '.join(unknown)}")
    words = [rename.get(key, key) for key in keys]
    unknown = sorted(set(defaults) - set(words))
    if unknown:
        raise KeyError(f"default for {', '.join(unknown)}, not a keyword of [{name}]")
    return tuple(
        Field(word, f"{name}.{key}", defaults.get(
            word, REQUIRED if specs[key].default is None else specs[key].default))
        for key, word in zip(keys, words))


#: The ``[friction]`` section as a friction element takes it: the arctan law's
#: ``sharpness`` and the breakaway ``peak``.
FRICTION = section("friction", rename={"arctan_sharpness": "sharpness"},
                   defaults={"sharpness": DEFAULT_SHARPNESS})


class SchemaComponent(Component):
    """A component whose parameters are `fields` (entries of `SCHEMA`): each one a
    keyword of the constructor and an attribute, checked by its entry's bounds.

    Subclasses set ``fields`` (from `section` and `Row`); their constructor takes
    its other keywords and passes ``**values`` to this one. The signature and the
    docstring's "Parameters" section are generated when the class is made.
    """

    fields: tuple[Field, ...] = ()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        names = [f.name for f in cls.fields]
        if len(set(names)) != len(names):
            raise TypeError(f"{cls.__name__}: a keyword taken twice in {names}")
        # rows are alternative laws' parameter vectors and may share an entry (the end
        # stop); a keyword of its own must be the only one to take its entry
        keys = [f.key for f in cls.fields if not isinstance(f, Row)]
        rows = {key for f in cls.fields if isinstance(f, Row) for key in f.keys}
        twice = sorted({key for key in keys if keys.count(key) > 1 or key in rows})
        if twice:
            raise TypeError(f"{cls.__name__}: schema entries {', '.join(twice)} are taken by "
                            f"more than one keyword")
        own = cls.__dict__.get("__init__")
        if own is None:  # inherit the parent's options under a signature of this class's own
            parent = cls.__mro__[1]

            def own(self, name: str, **values):
                parent.__init__(self, name, **values)

            own.__qualname__ = f"{cls.__qualname__}.__init__"
            cls.__init__ = own
            cls._options = getattr(parent, "_options", ())
        else:
            mine = [p for p in inspect.signature(own).parameters.values()
                    if p.kind is p.KEYWORD_ONLY]
            # keywords of a parent's constructor reach it through **values
            inherited = [p for p in getattr(cls.__mro__[1], "_options", ())
                         if p.name not in {q.name for q in mine}]
            cls._options = tuple(mine + inherited)
        clash = sorted({p.name for p in cls._options} & set(names))
        if clash:
            raise TypeError(f"{cls.__name__}: keyword(s) {', '.join(clash)} are fields of "
                            f"SCHEMA; take them from `fields`, not as keywords of __init__")
        params = [inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD),
                  inspect.Parameter("name", inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                    annotation="str")]
        # a required option first (an elastic element's model), the others after the fields
        params += [p for p in cls._options if p.default is p.empty]
        params += [inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default,
                                     annotation=f.annotation()) for f in cls.fields]
        params += [p for p in cls._options if p.default is not p.empty]
        cls.__init__.__signature__ = inspect.Signature(params)
        if cls.fields:
            cls.__doc__ = (inspect.cleandoc(cls.__doc__ or "") + "\n\nParameters\n----------\n"
                           "name : str\n    The component's name (its flanges are "
                           "``<name>.<port>``).\n"
                           + "\n".join(f.describe() for f in cls.fields))

    def __init__(self, name: str, **values):
        super().__init__(name)
        known = {f.name for f in self.fields}
        unknown = sorted(set(values) - known)
        if unknown:
            raise TypeError(f"{type(self).__name__}() got unexpected keyword argument(s) "
                            f"{', '.join(unknown)}; it takes {', '.join(sorted(known))}")
        missing = [f.name for f in self.fields if f.default is REQUIRED and f.name not in values]
        if missing:
            raise TypeError(f"{type(self).__name__}() missing required keyword argument(s): "
                            f"{', '.join(missing)}")
        for field in self.fields:
            setattr(self, field.name, field.take(name, values.get(field.name, field.default)))
        self.check_relations()

    def check_relations(self) -> None:
        """Check each of `vsj.params.RELATIONS` whose entries are all fields of this
        component (a pivot range within the mechanism's reach), as a parameter file is
        checked; a relation with a value still None (not yet derived) waits for the
        subclass to call this again. Raises `InputError` naming the component, the
        relation and the keywords' values."""
        by_key = {f.key: f for f in self.fields if not isinstance(f, Row)}
        for relation in RELATIONS:
            fields = [by_key.get(key) for key, _ in relation.terms]
            if None in fields or any(getattr(self, f.name) is None for f in fields):
                continue
            values = {f.key: getattr(self, f.name) for f in fields}
            if not relation.holds(values):
                shown = ", ".join(f"{f.name} = {values[f.key]!r}" for f in fields)
                raise InputError(f"{self.name}: {relation.text} ({shown})")

    @classmethod
    def from_parameters(cls, name: str, params: Parameters, *,
                        keys: Mapping[str, str] | None = None, **options) -> "SchemaComponent":
        """This component with every field read from ``params``; ``keys`` reads a field
        from another entry of the same kind (``{"compliance":
        "transmission.series_compliance_2"}``). ``options`` are the other keywords, and
        a field given among them takes that value instead of the set's (``q_min=None``:
        the pivot's whole reach)."""
        keys = dict(keys or {})
        unknown = sorted(set(keys) - {f.name for f in cls.fields})
        if unknown:
            raise ValueError(f"{cls.__name__} has no field(s) {', '.join(unknown)}")
        both = sorted(set(keys) & set(options))
        if both:
            raise ValueError(f"{cls.__name__}: {', '.join(both)} given both as a value and "
                             f"as an entry to read")
        values = {f.name: f.read(params, keys.get(f.name)) for f in cls.fields}
        return cls(name, **{**values, **options})
