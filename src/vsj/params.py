"""Parameter sets: TOML files where every value carries its unit and its source.

A parameter file has one table per sub-model; each key is written as

    ring_inertia = { value = "6.47e-5 kg m^2", source = "report table 4.1 (I_R)" }

Values are parsed with their units and converted to SI on load (`vsj.units`),
so ``"-1.45 1/cm"`` or ``"-0.4 cm"`` work as the report writes them. Loading
checks everything against `SCHEMA` and reports *all* problems at once, each
naming the file, the key, the value and what is allowed: unknown or missing
keys (with the nearest valid key), missing or wrong units, NaN, values outside
physical bounds, and the relations between keys (the pivot range inside the
ring, the lever longer than the pivot's reach).

A file may start from another set and give only what changes::

    extends = "second_prototype"      # a bundled set, or a file path
    [transmission]
    stiction = { value = "0.004 N m", source = "my bench, 2026-11" }

Paths in ``extends`` are relative to the file that names them. A chain of
files that extend one another is followed for at most `MAX_EXTENDS` files and
must not loop; each is a regular file of at most `MAX_BYTES`. A problem is
reported against the file that holds the bad value: a parent's own key against
the parent, and a parent that cannot be read against the file that names it.

Physical parameters live here; numerical knobs (tolerances, the slope width of
the slope friction law) belong to `vsj.simulate.SimulationOptions`.
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import json
import math
import os
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from collections.abc import Mapping, Sequence

import tomli_w

from .errors import InputError, read_text
from .units import format_quantity, to_si


@dataclass(frozen=True)
class Spec:
    """One parameter: SI unit, unit to show, bounds and a one-line description."""

    unit: str
    display: str
    description: str
    minimum: float | None = 0.0
    maximum: float | None = None
    strict: bool = False  # minimum excluded
    nonzero: bool = False
    infinite: bool = False  # "inf <unit>" allowed (a rigid element)
    default: float | None = None  # SI value used when a file leaves the key out

    def check(self, value: float) -> str | None:
        """Why ``value`` is not allowed, or None."""
        if self.infinite and value == math.inf:
            return None
        if not math.isfinite(value):
            return "must be finite"
        if self.minimum is not None:
            if self.strict and not value > self.minimum:
                return f"must be > {self._show(self.minimum)}"
            if not self.strict and not value >= self.minimum:
                return f"must be >= {self._show(self.minimum)}"
        if self.maximum is not None and not value <= self.maximum:
            return f"must be <= {self._show(self.maximum)}"
        if self.nonzero and value == 0.0:
            return "must be nonzero"
        return None

    def _show(self, value: float) -> str:
        return format_quantity(value, self.display)

    def allowed(self, unit: str | None = None) -> str:
        """The values `check` accepts, in words: ``"> 0 ohm"``, ``"finite, nonzero"``;
        bounds in the display unit, or as SI values labelled ``unit`` if given."""
        def show(value: float) -> str:
            if unit is None:
                return self._show(value)
            return f"{value:g}" if unit == "1" else f"{value:g} {unit}"

        words = []
        if self.minimum is not None:
            words.append(f"{'>' if self.strict else '>='} {show(self.minimum)}")
        if self.maximum is not None:
            words.append(f"<= {show(self.maximum)}")
        if not words:
            words.append("finite")
        if self.nonzero:
            words.append("nonzero")
        if self.infinite:
            words.append("or inf (rigid)")
        return ", ".join(words)

    def same_kind(self, other: "Spec") -> bool:
        """Whether ``other`` has this spec's unit and bounds (descriptions may differ)."""
        return (dataclasses.replace(self, description="", default=None)
                == dataclasses.replace(other, description="", default=None))

    def require(self, name: str, value: float) -> float:
        """``value`` as a float if this spec allows it, else `ValueError` naming ``name``
        (what a component checks when it is built without a parameter file)."""
        value = float(value)
        why = self.check(value)
        if why:
            raise ValueError(f"{name} {why}, got {value!r}")
        return value

    def of(self, description: str, **changes) -> "Spec":
        """This kind of quantity as one parameter: its description, and any bound
        that differs."""
        return dataclasses.replace(self, description=description, **changes)


_I = "kg*m**2"
_B = "N*m*s"
_K = "N*m"

# The kinds of quantity the components take, each with its unit and bounds, declared
# once: the schema's entries are built from them (`Spec.of`) and the components check
# their arguments with them (`Spec.require`).
INERTIA = Spec(_I, "kg m^2", "moment of inertia")
VISCOUS = Spec(_B, "N m s/rad", "viscous friction coefficient")
STICTION = Spec(_K, "N m", "stiction parameter k (the Coulomb level is k pi/2)")
SHARPNESS = Spec("s", "s/rad", "arctan sharpness k_b", 0.0, strict=True)
PEAK = Spec("1", "1", "breakaway peak: static over kinetic friction", 1.0)
STIFFNESS = Spec("N*m", "N m/rad", "rotational stiffness", 0.0, strict=True)
COMPLIANCE = Spec("rad/(N*m)", "rad/(N m)", "rotational compliance (0: rigid)")
RATIO = Spec("1", "1", "transmission ratio", None, nonzero=True)
RESISTANCE = Spec("ohm", "ohm", "electrical resistance", 0.0, strict=True)
INDUCTANCE = Spec("H", "mH", "inductance", 0.0, strict=True)
TORQUE_CONSTANT = Spec("N*m/A", "N m/A", "torque (= back-EMF) constant", 0.0, strict=True)
VOLTAGE = Spec("V", "V", "voltage", 0.0, strict=True)
LENGTH = Spec("m", "cm", "length")
FORCE = Spec("N", "N", "force")
SCHEMA: dict[str, dict[str, Spec]] = {
    "planetary": {
        "sun_teeth": Spec("1", "1", "teeth of the sun gear, N_S", 0.0, strict=True),
        "ring_teeth": Spec("1", "1", "teeth of the ring gear, N_R", 0.0, strict=True),
        "sun_inertia": INERTIA.of("inertia of the sun and what is attached, I_S",
                                  strict=True),
        "ring_inertia": INERTIA.of("inertia of the ring and what is attached, I_R",
                                  strict=True),
        "carrier_inertia": INERTIA.of("inertia of the carrier and what is attached, I_C",
                                  strict=True),
        "sun_bearing_viscous": VISCOUS.of("sun bearing viscous friction, b_S"),
        "sun_bearing_stiction": STICTION.of("sun bearing stiction parameter"),
        "ring_bearing_viscous": VISCOUS.of("ring bearing viscous friction, b_R"),
        "ring_bearing_stiction": STICTION.of("ring bearing stiction parameter, k_R"),
        "carrier_bearing_viscous": VISCOUS.of("carrier bearing viscous friction, b_C"),
        "carrier_bearing_stiction": STICTION.of("carrier bearing stiction parameter, k_C"),
        "mesh_stiction": STICTION.of("sun-carrier gear mesh stiction parameter, k_1 = k_a1"),
        "mesh_sharpness": SHARPNESS.of("sun-carrier mesh arctan sharpness, k_b1"),
    },
    "elastic_element": {
        "ring_radius": Spec("m", "cm", "radius of the lever pin on the ring, R", 0.0, strict=True),
        "lever_length": Spec("m", "cm", "lever length from pin to spring end, L", 0.0,
                             strict=True),
        "lever_width": Spec("m", "cm", "half-width of the lever at the springs, W"),
        "anchor_x": Spec("m", "cm", "spring anchor, horizontal offset x0", 0.0, strict=True),
        "anchor_y": Spec("m", "cm", "spring anchor, height y0", None),
        "rest_length": Spec("m", "cm", "spring rest length, s0"),
        "spring_stiffness": Spec("N/m", "N/m", "stiffness of each spring, k", 0.0, strict=True),
        "end_stop": Spec("rad", "rad", "deflection of the physical end stop", 0.0, strict=True),
        "end_stop_stiffness": Spec("N*m", "N m/rad", "stiffness of the end stop ('inf N m/rad': "
                                   "rigid)", 0.0, strict=True, infinite=True),
        "a1": Spec("N*m", "N m/rad", "simplified model K = a1 exp(a2 q) + a3: a1"),
        "a2": Spec("1/m", "1/cm", "simplified model: a2", None),
        "a3": Spec("N*m", "N m/rad", "simplified model: a3"),
        "lever_stiction": STICTION.of("lever and pivot friction, stiction parameter"),
        "lever_viscous": VISCOUS.of("lever and pivot friction, viscous"),
    },
    "pivot": {
        "amplitude": LENGTH.of("pivot travel: gain times ring radius, q = amplitude "
                               "sin(phi_C)", strict=True),
        "ratio": RATIO.of("motor turns per pivot carrier turn (belt and planetary)"),
        "inertia": INERTIA.of("inertia of the pivot gears, at the carrier"),
        "viscous": VISCOUS.of("pivot gear viscous friction, at the carrier"),
        "stiction": STICTION.of("pivot gear stiction parameter, at the carrier"),
        "q_min": LENGTH.of("lowest (stiffest) pivot position allowed", minimum=None),
        "q_max": LENGTH.of("highest (most compliant) pivot position allowed", minimum=None),
    },
    "transmission": {
        "ratio": RATIO.of("carrier speed over differential input speed"),
        "viscous": VISCOUS.of("transmission viscous friction, b_T (carrier side)"),
        "stiction": STICTION.of("transmission stiction parameter, k_T (carrier side)"),
        "series_compliance_1": COMPLIANCE.of("parasitic series compliance in DOF 1 (0: rigid)"),
        "series_compliance_2": COMPLIANCE.of("parasitic series compliance in DOF 2 (0: rigid)"),
        "series_damping": VISCOUS.of("damping in parallel with a series compliance"),
    },
    "differential": {
        "stiction": STICTION.of("differential gear stiction parameter, k_D"),
        "viscous": VISCOUS.of("differential gear viscous friction"),
        "inertia_x": INERTIA.of("end-effector inertia about theta_x"),
        "inertia_y": INERTIA.of("end-effector inertia about theta_y"),
    },
    "motor": {
        "resistance": RESISTANCE.of("armature resistance"),
        "inductance": INDUCTANCE.of("armature inductance"),
        "torque_constant": TORQUE_CONSTANT.of("torque (= back-EMF) constant"),
        "rotor_inertia": INERTIA.of("rotor inertia", strict=True),
        "gear_ratio": RATIO.of("rotor turns per output turn (gearhead)"),
        "viscous": VISCOUS.of("rotor viscous friction"),
        "voltage_limit": VOLTAGE.of("supply voltage (largest command)"),
    },
    "friction": {
        "arctan_sharpness": SHARPNESS.of("arctan sharpness k_b of bearings, transmissions, "
                                         "differential, lever and pivot"),
        "peak": PEAK.of("breakaway peak of the same elements under true stiction: static "
                        "over kinetic Coulomb level (MSL's peak; 1: none)", default=1.0),
    },
}

#: Optional table with free text about the set.
META_KEYS = ("name", "description")


def _bundled(name: str) -> Path:
    return Path(str(resources.files("vsj") / "data" / "params" / name))


DEFAULT_FILE = "second_prototype.toml"
#: The ``origin`` of the bundled set as `default` loads it.
DEFAULT_ORIGIN = f"vsj default ({DEFAULT_FILE})"


@dataclass(frozen=True)
class Parameters:
    """A validated parameter set: SI values, their texts and sources."""

    values: Mapping[str, float]
    sources: Mapping[str, str]
    texts: Mapping[str, str]
    origin: str
    meta: Mapping[str, str]

    def __getitem__(self, key: str) -> float:
        try:
            return self.values[key]
        except KeyError:
            raise KeyError(f"no parameter {key!r}") from None

    def values_of(self, section: str) -> dict[str, float]:
        """The SI values of one section, keyed by their names within it."""
        if section not in SCHEMA:
            raise KeyError(f"no parameter section {section!r}")
        return {name: self.values[f"{section}.{name}"] for name in SCHEMA[section]}

    def section(self, name: str) -> "_Section":
        """The values of section ``name`` (attribute access by key); KeyError if the schema
        has no such section."""
        if name not in SCHEMA:
            raise KeyError(f"no parameter section {name!r}")
        return _Section(self, name)

    def __getattr__(self, name: str) -> "_Section":
        if name in SCHEMA:
            return _Section(self, name)
        raise AttributeError(name)

    def hash(self) -> str:
        """SHA-256 of the SI values (independent of formatting and sources)."""
        canonical = json.dumps({k: repr(v) for k, v in sorted(self.values.items())})
        return hashlib.sha256(canonical.encode()).hexdigest()

    def with_overrides(self, overrides: Mapping[str, object], *, origin: str,
                       source: str | None = None) -> "Parameters":
        """A new validated set with some values replaced (``"section.key": text``)."""
        table: dict[str, dict] = {}
        for key in self.values:
            section, name = key.split(".", 1)
            table.setdefault(section, {})[name] = {"value": self.texts[key],
                                                   "source": self.sources[key]}
        for key, value in overrides.items():
            if "." not in key:
                raise InputError(f"{origin}: parameter override {key!r} must be written "
                                 f"'section.key'")
            section, name = key.split(".", 1)
            entry = dict(value) if isinstance(value, Mapping) else {"value": value}
            entry.setdefault("source", source or f"override in {origin}")
            table.setdefault(section, {})[name] = entry
        table["meta"] = dict(self.meta)
        return _from_table(table, origin)

    def describe(self) -> list[tuple[str, str, str, str]]:
        """Rows (key, value with unit, source, description) in schema order."""
        rows = []
        for section, specs in SCHEMA.items():
            for name, spec in specs.items():
                key = f"{section}.{name}"
                rows.append((key, format_quantity(self.values[key], spec.display),
                             self.sources[key], spec.description))
        return rows

    def to_toml(self) -> str:
        """The set as a parameter file (values in their display units, each with the
        fewest digits, 10 at least, that read back as the same number: a file written
        from an identified set gives the set itself)."""
        doc: dict = {"meta": dict(self.meta)} if self.meta else {}
        for section, specs in SCHEMA.items():
            doc[section] = {}
            for name, spec in specs.items():
                key = f"{section}.{name}"
                doc[section][name] = {"value": _exact_text(self.values[key], spec, key),
                                      "source": self.sources[key]}
        return tomli_w.dumps(doc)


def _exact_text(value: float, spec: Spec, key: str) -> str:
    """``value`` [SI] in ``spec``'s display unit with the fewest significant digits from 10
    up that `to_si` reads back exactly (17 always do, unless the unit's conversion rounds)."""
    for digits in range(10, 18):
        text = format_quantity(value, spec.display, digits=digits)
        if to_si(text, spec.unit, where=key, infinite=spec.infinite) == value:
            break
    return text


def exact_text(key: str, value: float) -> str:
    """``value`` [SI] of the parameter ``key`` (``"section.name"``) as a parameter file
    writes it: in its display unit, with the fewest significant digits from 10 up that
    read back as the same number (`Parameters.to_toml`)."""
    section, name = key.split(".", 1)
    return _exact_text(value, SCHEMA[section][name], key)


class _Section:
    def __init__(self, params: Parameters, name: str):
        self._params = params
        self._name = name

    def __getattr__(self, key: str) -> float:
        full = f"{self._name}.{key}"
        if full not in self._params.values:
            raise AttributeError(f"parameter section {self._name!r} has no {key!r}")
        return self._params.values[full]


def did_you_mean(name: str, choices) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``choices`` to the misspelt ``name``
    (`difflib`), or nothing when none is close: the end of an error message."""
    close = difflib.get_close_matches(name, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _from_table(table: Mapping, origin: str,
                where: Mapping[str, str] | None = None) -> Parameters:
    """Validate a merged table; ``where`` names the file each section and key came from
    (`_table`), ``origin`` the set itself (and anything ``where`` does not name)."""
    def at(*keys: str) -> str:
        return _files(where, origin, keys)

    problems: list[str] = []
    bad: set[str] = set()  # keys with a problem of their own, not also reported missing
    values: dict[str, float] = {}
    sources: dict[str, str] = {}
    texts: dict[str, str] = {}
    meta = {}
    for section, body in table.items():
        if section == "meta":
            if not isinstance(body, Mapping):
                problems.append(f"{at(section)}: [meta] must be a table")
                continue
            for key, text in body.items():
                if key not in META_KEYS:
                    problems.append(f"{at(f'meta.{key}')}: meta.{key}: unknown key; allowed: "
                                    f"{', '.join(META_KEYS)}")
                elif not isinstance(text, str):
                    problems.append(f"{at(f'meta.{key}')}: meta.{key}: expected text in "
                                    f"quotes, got {text!r}")
                else:
                    meta[key] = str(text)
            continue
        if section not in SCHEMA:
            problems.append(f"{at(section)}: unknown section [{section}]"
                            f"{did_you_mean(section, SCHEMA)}; sections: {', '.join(SCHEMA)}")
            continue
        if not isinstance(body, Mapping):
            problems.append(f"{at(section)}: [{section}] must be a table")
            bad.update(f"{section}.{name}" for name in SCHEMA[section])
            continue
        for name, entry in body.items():
            key = f"{section}.{name}"
            file = at(key)
            spec = SCHEMA[section].get(name)
            if spec is None:
                hint = did_you_mean(name, SCHEMA[section])
                problems.append(f"{file}: {key}: unknown key{hint}; "
                                f"[{section}] has {', '.join(SCHEMA[section])}")
                continue
            if not isinstance(entry, Mapping) or "value" not in entry:
                problems.append(f"{file}: {key}: write it as {{ value = \"<number> <unit>\", "
                                f"source = \"<where it comes from>\" }}")
                bad.add(key)
                continue
            extra = set(entry) - {"value", "source"}
            if extra:
                problems.append(f"{file}: {key}: unknown field(s) {', '.join(sorted(extra))}; "
                                "allowed: value, source")
            source = entry.get("source")
            if not isinstance(source, str) or not source.strip():
                what = ("missing source" if source is None or isinstance(source, str) else
                        f"source = {source!r} is not a text")
                problems.append(f"{file}: {key}: {what} (say where the value comes "
                                "from, e.g. \"report table 4.1\" or \"estimated: <how>\")")
                source = ""
            try:
                value = to_si(entry["value"], spec.unit, where=f"{file}: {key}",
                              infinite=spec.infinite)
            except InputError as exc:
                problems.append(str(exc))
                bad.add(key)
                continue
            why = spec.check(value)
            if why:
                problems.append(f"{file}: {key} = {entry['value']!r}: {why} "
                                f"({spec.description})")
                bad.add(key)
                continue
            values[key] = value
            sources[key] = source
            texts[key] = str(entry["value"])
    for section, specs in SCHEMA.items():
        for name in specs:
            key = f"{section}.{name}"
            if key in values or key in bad:
                continue
            if specs[name].default is not None:
                values[key] = specs[name].default
                sources[key] = "default (not in the file)"
                texts[key] = format_quantity(specs[name].default, specs[name].display)
            else:
                problems.append(f"{origin}: {key}: missing ({specs[name].description}, "
                                f"unit {specs[name].display})")
    if not problems:
        problems += _relations(values, origin, where)
    if problems:
        raise InputError("\n".join(problems))
    return Parameters(values=values, sources=sources, texts=texts, origin=origin, meta=meta)


def _files(where: Mapping[str, str] | None, origin: str, keys) -> str:
    """The file (or files, joined by "and") that ``keys`` came from."""
    files = dict.fromkeys((where or {}).get(key, origin) for key in keys)
    return " and ".join(files) or origin


@dataclass(frozen=True)
class Relation:
    """A relation between keys that a parameter set must satisfy: the sum of
    ``weight * value`` over ``terms`` (in their order) is > 0, or >= 0 when not
    ``strict``. ``text`` says what must hold, in words.

    Each relation is linear, so that an importer of the FMU (`vsj.fmu`) can check
    it on tunable parameters with the same arithmetic."""

    terms: tuple[tuple[str, float], ...]
    strict: bool
    text: str

    def margin(self, values: Mapping[str, float]) -> float:
        """The sum that must be positive (or not negative)."""
        return sum(weight * values[key] for key, weight in self.terms)

    def holds(self, values: Mapping[str, float]) -> bool:
        """True if the relation holds for ``values`` (SI values by key)."""
        margin = self.margin(values)
        return margin > 0.0 if self.strict else margin >= 0.0


_REACH = "the pivot range must lie within the mechanism's reach, |q| <= pivot.amplitude"
#: The relations between keys, checked after each key's own bounds.
RELATIONS = (
    Relation((("pivot.q_max", 1.0), ("pivot.q_min", -1.0)), True,
             "pivot.q_min must be below pivot.q_max"),
    Relation((("pivot.amplitude", 1.0), ("pivot.q_min", 1.0)), False, _REACH),
    Relation((("pivot.amplitude", 1.0), ("pivot.q_min", -1.0)), False, _REACH),
    Relation((("pivot.amplitude", 1.0), ("pivot.q_max", 1.0)), False, _REACH),
    Relation((("pivot.amplitude", 1.0), ("pivot.q_max", -1.0)), False, _REACH),
    Relation((("pivot.q_min", 1.0), ("elastic_element.ring_radius", 1.0)), True,
             "pivot.q_min must stay above the ring's bottom pin: q_min + ring_radius > 0"),
    Relation((("elastic_element.lever_length", 1.0), ("elastic_element.ring_radius", -1.0),
              ("pivot.q_max", -1.0)), True,
             "elastic_element.lever_length must exceed ring_radius + pivot.q_max so the lever "
             "reaches past the pivot"),
)


def _show(key: str, value: float) -> str:
    section, name = key.split(".", 1)
    return f"{key} = {format_quantity(value, SCHEMA[section][name].display)}"


def _relations(v: Mapping[str, float], origin: str,
               where: Mapping[str, str] | None = None,
               among: Sequence[Relation] = RELATIONS) -> list[str]:
    """Why the values break the relations ``among`` (default `RELATIONS`): one message
    per broken relation, naming the values it involves and the file(s) they came from."""
    return [f"{_files(where, origin, [k for k, _ in r.terms])}: {r.text} "
            f"({', '.join(_show(k, v[k]) for k, _ in r.terms)})"
            for r in among if not r.holds(v)]


#: Largest parameter file read [bytes]. A parameter file sets the few dozen keys of
#: `SCHEMA`, each a value with its unit and a one-line source: a few kB (the bundled
#: set is 8 kB). 1 MiB leaves room for long sources and comments a hundred times over,
#: and refuses a log, an image or a device named by mistake before it is read.
MAX_BYTES = 1 << 20
#: Most parameter files one ``extends`` chain may hold. A set extends a lab's set that
#: extends a bundled one; 32 is more than any chain a person keeps track of, and
#: bounds the reading at 32 MiB (`MAX_BYTES` each).
MAX_EXTENDS = 32


def load(path: str | Path | None = None) -> Parameters:
    """Load and validate a parameter file (the bundled default when ``path`` is None)."""
    if path is None:
        file = _bundled(DEFAULT_FILE)
        origin = DEFAULT_ORIGIN
    else:
        file, origin = Path(path), str(path)
    text = read_text(file, "parameter file", limit=MAX_BYTES)
    table, where = _table(text, origin, file.parent, file)
    return _from_table(table, origin, where)


def loads(text: str, origin: str = "<string>", *, base: Path | None = None) -> Parameters:
    """Parse parameter-file text; ``origin`` names it in messages, and a relative
    ``extends`` path is read from ``base`` (default: the working directory)."""
    table, where = _table(text, origin, base or Path("."), None)
    return _from_table(table, origin, where)


def bundled_names() -> list[str]:
    """The parameter sets that ship with vsj (names for ``extends``)."""
    return sorted(p.stem for p in _bundled("").glob("*.toml"))


def _toml(text: str, origin: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{origin}: not valid TOML: {exc}") from None


def _parent(parent, origin: str, base: Path) -> tuple[Path, str]:
    """The file that ``extends = parent`` in ``origin`` names, and its name for messages."""
    if not isinstance(parent, str) or not parent.strip():
        raise InputError(f"{origin}: extends must name a bundled parameter set "
                         f"({', '.join(bundled_names())}) or a file, in quotes; got {parent!r}")
    if parent in bundled_names():
        return _bundled(f"{parent}.toml"), f"bundled set {parent}"
    file = base / parent
    if file.suffix != ".toml" and not os.path.lexists(file):
        raise InputError(f"{origin}: extends = {parent!r}: no such file, and not a bundled "
                         f"parameter set ({', '.join(bundled_names())})"
                         f"{did_you_mean(parent, bundled_names())}")
    return file, str(file)


def _table(text: str, origin: str, base: Path, file: Path | None) -> tuple[dict, dict]:
    """The TOML table of a parameter file (``text``, read from ``file`` if not None) with
    the files it ``extends`` merged beneath it, and the name of the file each section
    and key (``"section.key"``) was taken from."""
    layers = [(_toml(text, origin), origin)]  # the file, then what it extends, ...
    seen = {os.path.realpath(file): origin} if file is not None else {}
    while (parent := layers[-1][0].pop("extends", None)) is not None:
        child = layers[-1][1]
        file, name = _parent(parent, child, base)
        key = os.path.realpath(file)  # a symlink loop is left to the read to refuse
        if key in seen:
            raise InputError(f"{child}: extends = {parent!r} makes a cycle of parameter "
                             f"files: {' -> '.join(n for _, n in layers)} -> {seen[key]}")
        if len(layers) == MAX_EXTENDS:
            raise InputError(f"{child}: extends = {parent!r}: a chain of more than "
                             f"{MAX_EXTENDS} parameter files ({layers[0][1]} -> ... -> "
                             f"{child} -> {name}); at most {MAX_EXTENDS} are followed")
        try:
            text = read_text(file, "parameter file", limit=MAX_BYTES)
        except InputError as exc:
            raise InputError(f"{child}: extends = {parent!r}: {exc}") from None
        seen[key] = name
        layers.append((_toml(text, name), name))
        base = file.parent
    merged: dict = {}
    where: dict[str, str] = {}
    for table, name in reversed(layers):
        for section, body in table.items():
            if isinstance(body, Mapping) and isinstance(merged.get(section), Mapping):
                merged[section] = {**merged[section], **body}
            else:
                merged[section] = body
            where[section] = name
            if isinstance(body, Mapping):
                where.update({f"{section}.{key}": name for key in body})
    return merged, where


def default() -> Parameters:
    """The bundled second-prototype set: table 4.1 plus documented estimates."""
    return load(None)
