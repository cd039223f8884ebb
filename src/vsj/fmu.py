"""The wrist as an FMI 2.0 co-simulation FMU (``vsj fmu``).

An FMU is a zip file that any FMI importer (20-sim, OpenModelica's
OMSimulator, Simulink, FMPy, ...) loads without Python. vsj's is laid out as
the Modelica Association's Reference FMUs are:

* ``modelDescription.xml``: the variables, their units, ranges and
  descriptions;
* ``binaries/linux64/vsj_wrist.so`` (and ``binaries/win64/vsj_wrist.dll`` where
  the mingw-w64 cross-compiler is installed): the C engine (``vsj/engine/c``)
  and its FMI layer (``vsj/fmi``: ``vsj_fmu.c``, the fmi2 entry points, and the
  ``fmu_*.c`` files behind them), built with the system compiler;
* ``sources/`` and ``sources/buildDescription.xml``: the same C files, so an
  importer can build the FMU for its own platform;
* ``resources/model.vsjm``: the wrist as `vsj.export` writes it, and
  ``resources/fmu.txt``: how each tunable parameter moves the engine's arrays,
  what a parameter file allows it (bounds, relations between keys), and what the
  checks of a run need (end stops, voltage limits, the ledger's tolerance).

`cross_check` writes the FMU with inputs, vsj's reference result and options
in the layout of the FMI cross-check repository (modelica/fmi-cross-check), which
FMPy's ``fmpy.cross_check.validate_vendor_repo`` checks.

Parameters. The C engine works on the assembled wrist (constraints already
eliminated by `vsj.network`), so the FMU cannot re-assemble it. A parameter
whose effect on the engine's arrays is affine (inertias, friction levels,
viscous coefficients, spring and motor constants, ...) is a tunable parameter
of the FMU: `tunable_map` measures its slope on each array entry and checks
that the map holds at other values, alone and together with the others. The
elastic element's springs and geometry are tunable too: they are rows of its
spring law. The parameters that change the wrist's kinematics (tooth counts,
ratios, series compliances), those a model option leaves unused, and one of
each pair that enters the arrays as a product (which no affine map predicts)
are constants of an FMU; `vsj fmu` lists them. Export another with
``--params`` to change them.

What the FMU refuses and reports. It refuses (fmi2Error, with the reason through
the importer's logger) another FMU's GUID, a parameter value that a parameter file
refuses (`vsj.params.SCHEMA` and `vsj.params.RELATIONS`), a state serialized by
another FMU (its header carries the GUID, which fingerprints the model file, the
parameter map and vsj's version) or one damaged or holding non-finite values,
and a non-finite or past-the-stop-time step. Each step is checked as
`vsj.simulate` checks a run (`vsj.simulate.checks`): a spring `DIVERGED` past its
end stop is an error that ends the run; a spring `INTO_STOP` past it, or a motor
above its voltage limit, a warning (once per run); the energy ledger of the run is
judged at fmi2Terminate.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import shutil
import struct
import subprocess
import tempfile
import uuid
import zipfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from . import __version__, export, pages, scenario
from .errors import InputError
from .engine.core import available_cores
from .engine.plan import ATOL, RTOL
from .output import atomic_write
from .params import RELATIONS, SCHEMA, Parameters
from .params import default as default_params
from .simulate import DIVERGED, INTO_STOP, InitialState, SimulationOptions
from .simulate.signals import SignalSpec, catalogue
from .springs import ROW_FIELDS
from .stepper import Stepper
from .wrist import WristOptions

MODEL_IDENTIFIER = "vsj_wrist"
#: value references (see vsj/fmi/vsj_fmu.c; their C names are in fmu_internal.h)
VR_OUTPUT, VR_Q0, VR_PARAMETER = 10, 99, 100
#: The FMU's outputs, in the order of the C `enum output`: FMI name and the signal of
#: the wrist's table (`vsj.simulate.signals.catalogue`) it is, whose unit and
#: description it takes; the two mean powers are the FMU's own (`OWN_OUTPUTS`).
OUTPUTS = [
    ("theta_x", "theta_x"),
    ("theta_y", "theta_y"),
    ("deflection_1", "spring.vsm_1.deflection"),
    ("deflection_2", "spring.vsm_2.deflection"),
    ("q", "q"),
    ("motor_1_angle", "motor_1"),
    ("motor_2_angle", "motor_2"),
    ("motor_s_angle", "motor_s"),
    ("motor_1_speed", "motor_1.speed"),
    ("motor_2_speed", "motor_2.speed"),
    ("motor_s_speed", "motor_s.speed"),
    ("power_in", None),
    ("power_dissipated", None),
]
#: Unit and description of the outputs that are not signals of a run.
OWN_OUTPUTS = {
    "power_in": ("W", "mean power delivered by the motors and the external torques over the "
                      "last communication step"),
    "power_dissipated": ("W", "mean power dissipated by friction, armature resistance and end "
                              "stops over the last communication step"),
}
#: an affine map must reproduce the arrays to this fraction of their largest entry
AFFINE_TOLERANCE = 1e-9
#: the FMI layer's files (vsj/fmi), shipped in ``sources/``; every .c one is compiled and
#: listed in buildDescription.xml
SOURCES_C = ("vsj_fmu.c", "fmu_setup.c", "fmu_parameters.c", "fmu_ledger.c", "fmu_state.c",
             "fmu_internal.h", "fmi2.h")


@dataclass(frozen=True)
class Tunable:
    """A parameter the FMU lets an importer change (``fmi2SetReal``): its key, value and
    range, and how it enters the model's arrays (affine ``entries``)."""

    key: str
    value: float
    minimum: float
    maximum: float
    entries: list[tuple[int, int, float]]  # (array 0 mass / 1 par, index, slope)
    strict: bool = False  # the minimum is excluded
    nonzero: bool = False


def _arrays(params: Parameters, wrist_options, options, method, period):
    stepper = export.wrist_stepper(params, wrist_options, options=options, method=method,
                                   period=period)
    model = stepper.model
    fixed = {name: np.asarray(getattr(model, name)).ravel().copy()
             for name in export.ENGINE_ARRAYS if name not in ("mass", "Minv", "par")}
    return (np.asarray(model.mass, float).ravel().copy(),
            np.asarray(model.par, float).ravel().copy(), fixed)


def _override(params: Parameters, values: dict[str, float]) -> Parameters:
    texts = {}
    for key, value in values.items():
        section, name = key.split(".", 1)
        unit = SCHEMA[section][name].unit
        texts[key] = repr(float(value)) if unit == "1" else f"{float(value)!r} {unit}"
    return params.with_overrides(texts, origin="vsj fmu (parameter map)")


def _span(spec) -> tuple[float, float]:
    low = spec.minimum if spec.minimum is not None else -math.inf
    high = spec.maximum if spec.maximum is not None else math.inf
    return low, high


def tunable_map(params: Parameters, wrist_options, options, method, period
                ) -> list[Tunable]:
    """The parameters whose effect on the engine's arrays is affine, with their
    slopes; measured by finite changes of each and checked at other values."""
    mass0, par0, fixed0 = _arrays(params, wrist_options, options, method, period)
    scale = np.concatenate([np.abs(mass0), np.abs(par0)]).max()
    found: list[Tunable] = []
    for key, value in params.values.items():
        section, name = key.split(".", 1)
        spec = SCHEMA[section][name]
        if not math.isfinite(value):
            continue
        low, high = _span(spec)
        step = 1e-2 * (abs(value) if value != 0.0 else 1.0)
        if value + 2 * step > high:
            step = -step
        if not (low <= value + 2 * step <= high) or (spec.strict and value + 2 * step <= low):
            continue
        try:
            mass1, par1, fixed1 = _arrays(_override(params, {key: value + step}), wrist_options,
                                          options, method, period)
            mass2, par2, fixed2 = _arrays(_override(params, {key: value + 2 * step}),
                                          wrist_options, options, method, period)
        except InputError:
            continue
        if any(not np.array_equal(fixed0[k], fixed1[k]) or not np.array_equal(fixed0[k],
                                                                              fixed2[k])
               for k in fixed0):
            continue  # kinematics or sizes change: a constant of the FMU
        before = np.concatenate([mass0, par0])
        slope = (np.concatenate([mass1, par1]) - before) / step
        if not np.allclose(before + 2 * step * slope, np.concatenate([mass2, par2]), rtol=0,
                           atol=AFFINE_TOLERANCE * scale):
            continue
        slope[np.abs(slope * step) <= 1e-15 * scale] = 0.0
        entries = [(0, int(i), float(slope[i])) if i < mass0.size
                   else (1, int(i - mass0.size), float(slope[i]))
                   for i in np.flatnonzero(slope)]
        if not entries:
            continue  # no effect on this model (e.g. a DC-motor constant with velocity drives)
        found.append(Tunable(key, float(value), low, high, entries, spec.strict,
                             spec.nonzero))
    _check_together(params, found, (mass0, par0), scale, wrist_options, options, method, period)
    return found


def _check_together(params, found, base, scale, wrist_options, options, method, period):
    """All tunable parameters changed at once must still be predicted by the sum of
    their maps; a parameter that takes part in a product with another is dropped."""
    rng = np.random.default_rng(0)
    while found:
        changed = {}
        for t in found:
            span = 0.05 * (abs(t.value) if t.value != 0.0 else 1.0)
            x = t.value + rng.uniform(-span, span)
            changed[t.key] = min(max(x, t.minimum), t.maximum)
        mass, par, _ = _arrays(_override(params, changed), wrist_options, options, method,
                               period)
        predicted = np.concatenate(base).copy()
        for t in found:
            for array, index, slope in t.entries:
                predicted[index + (0 if array == 0 else base[0].size)] += (
                    slope * (changed[t.key] - t.value))
        error = np.abs(predicted - np.concatenate([mass, par]))
        if error.max() <= AFFINE_TOLERANCE * scale:
            return
        worst = int(np.argmax(error))
        array, index = (0, worst) if worst < base[0].size else (1, worst - base[0].size)
        culprits = [t for t in found if any(a == array and i == index for a, i, _ in t.entries)]
        found.remove(culprits[-1])


def _unit_xml(units: dict[str, str]) -> str:
    import pint  # lazy: heavy, only the unit names of the model description need it

    ureg = pint.UnitRegistry()
    base = {"[mass]": "kg", "[length]": "m", "[time]": "s", "[current]": "A",
            "[temperature]": "K"}
    lines = ["  <UnitDefinitions>"]
    for unit in sorted(units):
        q = ureg.parse_units(units[unit].replace("rad", "radian"))
        exponents = {base[k]: int(v) for k, v in q.dimensionality.items() if k in base}
        rad = dict(q._units).get("radian", 0)
        if rad:
            exponents["rad"] = int(rad)
        attrs = " ".join(f'{k}="{v}"' for k, v in exponents.items())
        lines.append(f"    <Unit name={quoteattr(unit)}><BaseUnit {attrs}/></Unit>")
    lines.append("  </UnitDefinitions>")
    return "\n".join(lines)


def _display(si_unit: str) -> str:
    """An FMI unit name from a pint SI unit string (``N*m*s`` -> ``N.m.s``)."""
    return si_unit.replace("**", "").replace("*", ".").replace(" ", "")


def model_description(document: dict, tunables: list[Tunable], params: Parameters,
                      q0: float, q_range: tuple[float, float], guid: str, step: float,
                      description: str, signals: dict[str, SignalSpec],
                      tolerance: float | None = None) -> str:
    """The FMU's modelDescription.xml: its inputs, outputs (units and descriptions from
    ``signals``, the run's signal table), the initial pivot position and the tunable
    parameters, with FMI's unit definitions; ``tolerance``, an adaptive scheme's relative
    tolerance, is the default experiment's."""
    units: dict[str, str] = {}  # FMI unit name -> the same in pint's notation
    variables = []
    experiment_tolerance = f' tolerance="{float(tolerance)!r}"' if tolerance is not None else ""

    def real(name, vr, causality, variability, unit, text, start=None, minimum=None,
             maximum=None, initial=None):
        if unit != "1":
            units[_display(unit)] = unit
            unit = _display(unit)
        attrs = [f"name={quoteattr(name)}", f'valueReference="{vr}"',
                 f"causality={quoteattr(causality)}", f"variability={quoteattr(variability)}",
                 f"description={quoteattr(text)}"]
        if initial:
            attrs.append(f'initial="{initial}"')
        inner = [f'unit="{unit}"'] if unit != "1" else []
        if start is not None:
            inner.append(f'start="{start!r}"')
        if minimum is not None and math.isfinite(minimum):
            inner.append(f'min="{minimum!r}"')
        if maximum is not None and math.isfinite(maximum):
            inner.append(f'max="{maximum!r}"')
        variables.append(f"    <ScalarVariable {' '.join(attrs)}>\n"
                         f"      <Real {' '.join(inner)}/>\n    </ScalarVariable>")

    for vr, entry in enumerate(document["inputs"]):
        unit = entry["unit"].replace(" ", "*")
        what = {"tau_x": "external torque on the end-effector about x",
                "tau_y": "external torque on the end-effector about y"}.get(
            entry["name"], f"command of {entry['name']} (held over each communication step)")
        real(entry["name"], vr, "input", "continuous", unit, what, start=0.0)
    for k, (name, signal) in enumerate(OUTPUTS):
        unit, text = ((signals[signal].unit.replace(" ", "*"), signals[signal].description)
                      if signal else OWN_OUTPUTS[name])
        real(name, VR_OUTPUT + k, "output", "continuous", unit, text)
    real("pivot_q0", VR_Q0, "parameter", "fixed", "m",
         "initial pivot position q of the variable stiffness mechanism", start=q0,
         minimum=q_range[0], maximum=q_range[1])
    for k, t in enumerate(tunables):
        section, name = t.key.split(".", 1)
        spec = SCHEMA[section][name]
        # FMI's min is inclusive: an excluded bound (a zero stiffness) is said in words
        excluded = (f"; must be > {t.minimum!r}" if t.strict else "") + (
            "; must be nonzero" if t.nonzero else "")
        real(t.key, VR_PARAMETER + k, "parameter", "tunable", spec.unit,
             f"{spec.description} ({params.sources[t.key]}){excluded}", start=t.value,
             minimum=t.minimum, maximum=t.maximum)
    variables.append('    <ScalarVariable name="n_stuck" valueReference="0" causality="output" '
                     'variability="discrete" initial="calculated" description="number of '
                     'friction elements stuck at the end of the last communication step '
                     '(true stiction only)">\n      <Integer/>\n    </ScalarVariable>')
    n_in = len(document["inputs"])
    outputs = "\n".join(f'      <Unknown index="{n_in + k + 1}"/>' for k in range(len(OUTPUTS)))
    stuck_index = len(variables)
    outputs += f'\n      <Unknown index="{stuck_index}"/>'
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="vsj_wrist" guid="{guid}"
  description={quoteattr(description)}
  generationTool="vsj {__version__}" version="{__version__}"
  variableNamingConvention="structured" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true"
    canGetAndSetFMUstate="true" canSerializeFMUstate="true" canNotUseMemoryManagementFunctions="true"
    canBeInstantiatedOnlyOncePerProcess="false" canInterpolateInputs="false"
    maxOutputDerivativeOrder="0">
    <SourceFiles>
{chr(10).join(f'      <File name="{name}"/>' for name in _source_names() if name.endswith('.c'))}
    </SourceFiles>
  </CoSimulation>
{_unit_xml(units)}
  <LogCategories>
    <Category name="logStatusError" description="bad calls, failed steps and runs"/>
    <Category name="logStatusWarning"
      description="a spring past its end stop, a motor above its voltage limit"/>
    <Category name="logAll" description="every message"/>
  </LogCategories>
  <DefaultExperiment startTime="0" stopTime="10" stepSize="{float(step)!r}"{experiment_tolerance}/>
  <ModelVariables>
{chr(10).join(variables)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{outputs}
    </Outputs>
    <InitialUnknowns>
{outputs}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def _engine_dir() -> Path:
    return Path(str(resources.files("vsj") / "engine" / "c"))


def _fmi_dir() -> Path:
    return Path(str(resources.files("vsj") / "fmi"))


def _source_names() -> list[str]:
    return sorted(p.name for p in _engine_dir().glob("*.[ch]")) + list(SOURCES_C)


def _source_paths() -> list[Path]:
    return sorted(_engine_dir().glob("*.[ch]")) + [_fmi_dir() / name for name in SOURCES_C]


def build_description() -> str:
    """The FMU's sources/buildDescription.xml: every C file it carries, to compile as
    one binary."""
    files = "\n".join(f'      <SourceFile name="{name}"/>' for name in _source_names()
                      if name.endswith(".c"))
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiBuildDescription fmiVersion="3.0">
  <BuildConfiguration modelIdentifier="{MODEL_IDENTIFIER}" description="C99; link with libm">
    <SourceFileSet language="C99">
{files}
    </SourceFileSet>
  </BuildConfiguration>
</fmiBuildDescription>
"""


def compiler(kind: str = "linux64") -> str | None:
    """The C compiler for a platform: the system one for linux64, mingw-w64 for win64."""
    if kind == "linux64":
        for cc in (os.environ.get("CC"), "cc", "gcc", "clang"):
            if cc and shutil.which(cc):
                return cc
        return None
    return shutil.which("x86_64-w64-mingw32-gcc")


#: The binaries this process compiled or read from the cache: the key of `compile_binary`
#: -> (the binary's bytes, its file mode, what the compiler said). The binary is the
#: engine and its FMI layer only (the model and its parameters are resources of the
#: FMU), so a process that builds several FMUs (the cross-check, a script exporting
#: several parameter sets, the tests) compiles the same sources once.
_COMPILED: dict[tuple, tuple[bytes, int, str]] = {}


def _sources_digest(paths: list[Path]) -> str:
    """SHA-256 over the names and bytes of ``paths`` (headers included)."""
    digest = hashlib.sha256()
    for path in paths:
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def cache_dir() -> Path:
    """Where compiled FMU binaries are kept between runs: ``$VSJ_CACHE/fmu``, else
    ``$XDG_CACHE_HOME/vsj/fmu`` (``~/.cache/vsj/fmu`` where neither is set). Deleting it
    is always safe: the next build compiles again."""
    base = os.environ.get("VSJ_CACHE")
    if not base:
        base = str(Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "vsj")
    return Path(base) / "fmu"


def _entry(key: tuple) -> Path:
    """The cache entry of ``key``: its binary is ``.bin``, its record ``.json``."""
    return cache_dir() / hashlib.sha256(repr(key).encode()).hexdigest()


def _checksum(key: tuple, binary: bytes, mode: int, said: str) -> str:
    """SHA-256 over everything a cache entry holds: its key, the binary, its file mode
    and what the compiler said."""
    digest = hashlib.sha256(json.dumps([repr(key), mode, said]).encode() + b"\0")
    digest.update(binary)
    return digest.hexdigest()


def _cached(key: tuple) -> tuple[bytes, int, str] | None:
    """The binary, mode and compiler output stored for ``key``, or None: nothing stored,
    the cache unreadable, or an entry whose checksum (`_checksum`, recorded beside the
    binary) does not match what it holds: a damaged entry is compiled anew, never used.
    (The checksum does not stop someone who rewrites an entry and its record together,
    as nothing stops an edit of the installed package.)"""
    stem = _entry(key)
    try:
        meta = json.loads(stem.with_suffix(".json").read_text())
        binary = stem.with_suffix(".bin").read_bytes()
        if not isinstance(meta, dict) or not isinstance(meta.get("mode"), int) \
                or not isinstance(meta.get("said"), str):
            return None
        mode, said = meta["mode"], meta["said"]
        if mode & ~0o777 or _checksum(key, binary, mode, said) != meta.get("sha256"):
            return None
        return binary, mode, said
    except (OSError, ValueError):
        return None


def _store(key: tuple, entry: tuple[bytes, int, str]) -> None:
    """Keep a compiled binary for other processes (best effort: a cache that cannot be
    written only costs the next build its compile). Each file appears whole (written
    under a temporary name, then renamed), the record last."""
    binary, mode, said = entry
    stem = _entry(key)
    meta = json.dumps({"key": repr(key), "sha256": _checksum(key, binary, mode, said),
                       "mode": mode, "said": said})
    try:
        stem.parent.mkdir(parents=True, exist_ok=True)
        for suffix, data in ((".bin", binary), (".json", meta.encode())):
            handle, aside = tempfile.mkstemp(dir=stem.parent, prefix=f".{stem.name}",
                                             suffix=".tmp")
            try:
                with os.fdopen(handle, "wb") as file:
                    file.write(data)
                os.replace(aside, stem.with_suffix(suffix))
            finally:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(aside)
    except OSError:
        pass


def _compiler_version(cc: str) -> str:
    """What ``cc --version`` says (a compiler upgraded in place builds anew)."""
    done = subprocess.run([cc, "--version"], capture_output=True, text=True, check=False)
    return done.stdout.strip()


def compile_binary(kind: str, out: Path) -> str:
    """Build the FMU's binary for ``kind`` (linux64 or win64) into ``out``; returns
    what the compiler said (empty: no warning under -Wall -Wextra). The same sources,
    compiler (its path and version) and flags give the same binary: it is compiled once
    and then copied, from this process's memory (`_COMPILED`) or from the files of
    `cache_dir`."""
    cc = compiler(kind)
    if cc is None:
        raise InputError(f"vsj fmu: no C compiler for {kind}")
    paths = _source_paths()
    sources = [str(p) for p in paths if p.suffix == ".c"]
    # -fno-math-errno as setup.py builds the engine (it reads no errno)
    flags = ["-std=c99", "-O2", "-fno-math-errno", "-Wall", "-Wextra",
             "-I", str(_engine_dir()), "-I", str(_fmi_dir())]
    link = ["-shared"]
    if kind == "linux64":
        flags += ["-fPIC", "-fvisibility=hidden"]
    else:
        link += ["-static-libgcc"]
    key = (kind, shutil.which(cc), tuple(flags), tuple(link), _sources_digest(paths))
    if key not in _COMPILED:
        stored = (*key, _compiler_version(cc))
        entry = _cached(stored)
        if entry is None:
            entry = _compile(cc, flags, link, sources, kind, out)  # kept only if it succeeds
            _store(stored, entry)
        _COMPILED[key] = entry
    binary, mode, said = _COMPILED[key]
    Path(out).write_bytes(binary)
    os.chmod(out, mode)
    return said


def _compile(cc, flags, link, sources, kind, out) -> tuple[bytes, int, str]:
    """Compile the binary into ``out``: each source to an object, side by side (one
    compiler per core: the engine's files take seconds each, and the largest start
    first, not last on one core while the others idle), then the objects linked with
    ``link``. Returns its bytes, its mode (permission bits) and what the compiler
    said."""
    def run(command):
        return subprocess.run(command, capture_output=True, text=True, check=False)

    with tempfile.TemporaryDirectory(prefix="vsj-fmu-") as scratch:
        objects = [str(Path(scratch) / f"{k}-{Path(source).stem}.o")
                   for k, source in enumerate(sources)]
        largest_first = sorted(range(len(sources)), key=lambda k: -os.path.getsize(sources[k]))
        with ThreadPoolExecutor(min(len(sources), available_cores())) as pool:
            done_in_order = dict(zip(largest_first, pool.map(
                lambda k: run([cc, *flags, "-c", "-o", objects[k], sources[k]]), largest_first)))
        steps = [done_in_order[k] for k in range(len(sources))]
        if all(done.returncode == 0 for done in steps):
            steps.append(run([cc, *link, "-o", str(out), *objects, "-lm"]))
        for done in steps:  # the first failure: a compile's, else the link's
            if done.returncode != 0:
                raise InputError(f"vsj fmu: building the {kind} binary failed:\n"
                                 f"{done.stderr[-2000:]}")
    said = "\n".join(done.stderr.strip() for done in steps if done.stderr.strip())
    return Path(out).read_bytes(), os.stat(out).st_mode & 0o777, said


METHODS = ("auto", "timestep", "dopri", "rosenbrock")
#: The step functions with an error control, which follow an importer's tolerance
#: (fmi2SetupExperiment) in place of the model file's rtol, atol scaled alike.
ADAPTIVE = ("dopri", "rosenbrock")


def choose_method(friction: str, method: str = "auto") -> str:
    """The step function an FMU runs (see `build`)."""
    if method not in METHODS:
        raise InputError(f"method {method!r}: one of {', '.join(METHODS)}")
    if method == "auto":
        return "timestep" if friction == "stiction" else "dopri"
    if method in ("dopri", "rosenbrock") and friction == "stiction":
        raise InputError(f"the stiction law needs the time-stepper (method timestep); {method} "
                         "integrates the smooth laws only")
    return method


#: values per engine row (VSJ_NPAR of vsj.h); the pivot's row is the last, with
#: amplitude, fixed q, moving, q_min, q_max
ROW_VALUES = 9


def _pivot_range(document: dict) -> tuple[float, float]:
    par = document["engine"]["par"]
    return float(par[-ROW_VALUES + 3]), float(par[-ROW_VALUES + 4])


def build(out: Path, params: Parameters, *, wrist_options: WristOptions | None = None,
          friction: str = "stiction", step: float = 1e-3, q0: float = -0.01,
          win64: bool | None = None, method: str = "auto", rtol: float = RTOL,
          atol: float = ATOL) -> dict:
    """Write the FMU to ``out``; returns what was built (tunable parameters,
    platforms, compiler warnings). ``win64``: None builds the Windows DLL where the
    cross-compiler is installed, True requires it, False skips it. ``method``: the
    engine's step function, ``timestep`` (the time-stepper at ``step``; needed by
    true stiction), ``dopri`` or ``rosenbrock`` (adaptive, to ``rtol`` and ``atol``,
    or to the tolerance an importer passes to fmi2SetupExperiment, with atol scaled alike);
    ``auto`` takes the time-stepper for stiction and dopri for the smooth laws."""
    wrist_options = wrist_options or WristOptions()
    method = choose_method(friction, method)
    options = SimulationOptions(friction=friction, step=step, rtol=rtol, atol=atol)
    stepper = export.wrist_stepper(params, wrist_options, options=options, method=method,
                                   period=step)
    document = export.model_document(stepper, params=params, initial=InitialState(q=q0),
                                     wrist_options=wrist_options)
    # the FMU sets the pivot from pivot_q0 itself: store the state at rest with q = 0
    document["initial_state"] = export.model_document(
        stepper, params=params, initial=InitialState(q=0.0),
        wrist_options=wrist_options)["initial_state"]
    tunables = tunable_map(params, wrist_options, options, method, step)
    q_range = _pivot_range(document)
    if not q_range[0] <= q0 <= q_range[1]:
        raise InputError(f"--q {q0:g} m is outside the pivot's range [{q_range[0]:g}, "
                         f"{q_range[1]:g}] m")
    program = export.program_bytes(document, stepper)
    body = map_body(tunables, params, q0, checks_of(stepper, document, options))
    # the GUID fingerprints everything a state depends on: model, map and vsj's version
    guid = "{" + str(uuid.UUID(hashlib.md5(program + (body + __version__).encode())
                               .hexdigest())) + "}"
    description = (f"vsj wrist ({friction} friction, {method} at {step:g} s; parameters "
                   f"{params.meta.get('name', params.origin)}, hash {params.hash()[:12]})")
    want_win = compiler("win64") is not None if win64 is None else win64
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        (root / "binaries" / "linux64").mkdir(parents=True)
        (root / "resources").mkdir()
        (root / "sources").mkdir()
        (root / "documentation").mkdir()
        signals = {spec.name: spec for spec in catalogue(stepper.structure, ports=False)}
        (root / "modelDescription.xml").write_text(model_description(
            document, tunables, params, q0, q_range, guid, step, description, signals,
            rtol if method in ADAPTIVE else None))
        (root / "resources" / "model.vsjm").write_bytes(program)
        (root / "resources" / "fmu.txt").write_text(map_text(guid, body))
        for path in _source_paths():
            shutil.copy(path, root / "sources" / path.name)
        (root / "sources" / "buildDescription.xml").write_text(build_description())
        (root / "documentation" / "index.html").write_text(pages.document("vsj wrist FMU", [
            f"<p>{pages.esc(description)}</p><p>It refuses, with fmi2Error and the reason through "
            "the logger, what vsj refuses elsewhere (a parameter value a parameter file "
            "refuses, another FMU's GUID or state), and checks each run as vsj simulate "
            "does: a spring far past its end stop ends the run, one pressed into it or a "
            "motor above its voltage limit gives fmi2Warning, and fmi2Terminate judges the "
            f"run's energy ledger.</p><p>Built by vsj {pages.esc(__version__)}; see vsj's README, "
            "section 'The wrist as an FMU'.</p>"]))
        said = {"linux64": compile_binary(
            "linux64", root / "binaries" / "linux64" / f"{MODEL_IDENTIFIER}.so")}
        platforms = ["linux64"]
        if want_win:
            (root / "binaries" / "win64").mkdir()
            said["win64"] = compile_binary(
                "win64", root / "binaries" / "win64" / f"{MODEL_IDENTIFIER}.dll")
            platforms.append("win64")

        with atomic_write(Path(out), "wb") as handle, \
                zipfile.ZipFile(handle, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(root).as_posix())
    return {"tunable": [t.key for t in tunables],
            "constant": [k for k in params.values if k not in {t.key for t in tunables}],
            "platforms": platforms, "guid": guid, "method": method,
            "warnings": {k: v for k, v in said.items() if v}}


# -- the FMI cross-check folder --------------------------------------------------------

#: the cross-check run: length [s], how often the commands change [s] (a 100 Hz
#: controller; also the communication step), and an external torque tau_x [N m]
#: applied from CROSS_CHECK_LOAD_START [s] on
CROSS_CHECK_DURATION = 4.0
CROSS_CHECK_PERIOD = 0.01
CROSS_CHECK_LOAD = 0.05
CROSS_CHECK_LOAD_START = 3.0
#: DC-motor wrists: voltage amplitude [V] of the circle (the fig-4.15 pattern)
CROSS_CHECK_VOLTAGE = 1.5
#: outputs in X_ref.csv, with the `vsj.stepper.Stepper` signal each is read from
CROSS_CHECK_OUTPUTS = ("theta_x", "theta_y", "q", "motor_1_angle", "motor_2_angle")


def _fade(t: np.ndarray, rise: float) -> np.ndarray:
    z = np.clip(t / rise, 0.0, 1.0)
    return z ** 3 * (10.0 - 15.0 * z + 6.0 * z * z)


def cross_check_commands(names: list[str], period: float, steps: int) -> np.ndarray:
    """The held inputs of the cross-check, one row per communication step.

    The fig-4.15 motion (report fig 4.15, the built-in scenario): velocity-driven
    motors get the mean speed of the scenario's motor angles over each step, so that
    the motor angles at the communication points are the scenario's; DC motors get
    sine voltages with the same frequency, phases and fade-in. ``tau_x`` steps to
    `CROSS_CHECK_LOAD` at `CROSS_CHECK_LOAD_START`.
    """

    t = np.arange(steps + 1) * period
    u = np.zeros((steps, len(names)))
    scen = scenario.load("fig-4.15")
    case = scen.cases[0]
    motion = scenario.parse_inputs(case, case.build(default_params()))
    for j, name in enumerate(names):
        if name in ("motor_1", "motor_2"):
            u[:, j] = np.diff(motion[name].value(t)) / period
        elif name in ("voltage_1", "voltage_2"):
            phase = math.pi / 4 if name.endswith("1") else -math.pi / 4
            start = t[:-1]
            u[:, j] = CROSS_CHECK_VOLTAGE * _fade(start, 2.0) * np.sin(math.pi * start + phase)
        elif name == "tau_x":
            u[:, j] = np.where(t[:-1] >= CROSS_CHECK_LOAD_START - 1e-9, CROSS_CHECK_LOAD, 0.0)
    return u


def _csv(path: Path, names, rows) -> None:
    lines = [",".join(f'"{n}"' for n in names)]
    lines += [",".join(f"{float(x):.17g}" for x in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")


def cross_check(directory: Path, params: Parameters, *,
                wrist_options: WristOptions | None = None, friction: str = "stiction",
                step: float = 1e-3, q0: float = -0.01, win64: bool | None = None,
                method: str = "auto", rtol: float = RTOL, atol: float = ATOL) -> dict:
    """Write an FMI cross-check folder (the modelica/fmi-cross-check layout):
    ``fmus/2.0/cs/<platform>/vsj/<version>/vsj_wrist/`` with the FMU,
    ``vsj_wrist_in.csv`` (held commands, a step at each change),
    ``vsj_wrist_ref.csv`` (vsj's own run of the same held inputs: the step function
    `vsj.stepper.Stepper`, one call per communication step), ``vsj_wrist_ref.opt``
    and ``README.md``. One folder per platform the FMU has a binary for."""

    wrist_options = wrist_options or WristOptions()
    chosen = choose_method(friction, method)
    period = step * max(1, round(CROSS_CHECK_PERIOD / step))
    steps = int(round(CROSS_CHECK_DURATION / period))
    with tempfile.TemporaryDirectory() as scratch:
        fmu_path = Path(scratch) / f"{MODEL_IDENTIFIER}.fmu"
        info = build(fmu_path, params, wrist_options=wrist_options, friction=friction,
                     step=step, q0=q0, win64=win64, method=chosen, rtol=rtol, atol=atol)
        stepper = Stepper.wrist(params, wrist_options, period,
                                options=SimulationOptions(friction=friction, step=step,
                                                          rtol=rtol, atol=atol),
                                method=chosen)
        names = list(stepper.input_names)
        commands = cross_check_commands(names, period, steps)
        rows = stepper.angle_rows(["theta_x", "theta_y", "motor_1", "motor_2"])
        state = stepper.initial_state(InitialState(q=q0))
        t = np.arange(steps + 1) * period
        ref = np.empty((steps + 1, 1 + len(CROSS_CHECK_OUTPUTS)))
        for k in range(steps + 1):
            if k:
                state = stepper.step(state, commands[k - 1])
            theta_x, theta_y, motor_1, motor_2 = rows @ state
            ref[k] = (t[k], theta_x, theta_y, stepper.pivot_position(state), motor_1, motor_2)
        held = []
        for k in range(steps):
            held.append((t[k], *commands[k]))
            held.append((t[k + 1], *commands[k]))
        written = []
        for platform in info["platforms"]:
            folder = (Path(directory) / "fmus" / "2.0" / "cs" / platform / "vsj" / __version__
                      / MODEL_IDENTIFIER)
            folder.mkdir(parents=True, exist_ok=True)
            shutil.copy(fmu_path, folder / f"{MODEL_IDENTIFIER}.fmu")
            _csv(folder / f"{MODEL_IDENTIFIER}_in.csv", ["time", *names], held)
            _csv(folder / f"{MODEL_IDENTIFIER}_ref.csv", ["time", *CROSS_CHECK_OUTPUTS], ref)
            (folder / f"{MODEL_IDENTIFIER}_ref.opt").write_text(
                f"StartTime, 0.0\nStopTime, {CROSS_CHECK_DURATION!r}\nStepSize, {period!r}\n"
                f"RelTol, 1e-06\nOutputIntervalLength, {period!r}\n")
            (folder / "README.md").write_text(_cross_check_readme(
                info, friction, chosen, step, period, q0, names, platform))
            written.append(str(folder))
    return {**info, "folders": written, "period": period, "steps": steps}


def _cross_check_readme(info, friction, method, step, period, q0, names, platform) -> str:
    binary = ("built on Linux with the system compiler" if platform == "linux64" else
              "cross-compiled with mingw-w64; its results have not been checked on Windows "
              "by vsj")
    return f"""# vsj_wrist: vsj's 2-DOF variable stiffness wrist as an FMI 2.0 co-simulation FMU

Exported by vsj {__version__} (`vsj fmu --cross-check`). The {platform} binary was {binary}.
The FMU also carries its C sources and `sources/buildDescription.xml`.

- Model: the wrist of the report, {friction} friction, step function `{method}` (internal
  step {step:g} s), initial pivot position q = {q0:g} m (parameter `pivot_q0`).
- Inputs (`vsj_wrist_in.csv`): {', '.join(names)}. The commands change every
  {period:g} s and are held in between (the FMU holds its inputs over a communication
  step); the file has two rows at each change, the old and the new value. The motion is
  the circle of report fig 4.15 (built-in scenario `fig-4.15`, first case); `tau_x`
  steps to {CROSS_CHECK_LOAD:g} N m at {CROSS_CHECK_LOAD_START:g} s.
- Reference (`vsj_wrist_ref.csv`): vsj's own run of the same held inputs, its step
  function (`vsj.stepper.Stepper`, method `{method}`) called once per communication step.
- Options (`vsj_wrist_ref.opt`): communication step {period:g} s, stop time
  {CROSS_CHECK_DURATION:g} s.

Reproduce with FMPy:

    python -m fmpy.cross_check.validate_vendor_repo <this repository>
"""


@dataclass(frozen=True)
class Checks:
    """What the FMU's checks of a run need: per spring (in the model's order) its
    name and the column of its end-stop angle in its row of the engine's ``par``
    (-1: none); per voltage-limited input its index, limit [V] and motor; the
    ledger's tolerance."""

    springs: list[tuple[str, int]]
    limits: list[tuple[int, float, str]]
    ledger_tolerance: float


def checks_of(stepper, document: dict, options: SimulationOptions) -> Checks:
    """The `Checks` of a stepper's wrist, checked against its exported arrays."""
    structure = stepper.structure
    par = np.asarray(document["engine"]["par"], float).reshape(-1, ROW_VALUES)
    code = document["engine"]["code"]
    first = len(structure.frictions)
    springs = []
    for k, sp in enumerate(structure.springs):
        fields = ROW_FIELDS.get(sp.law)
        column = fields.index("end_stop") if fields else -1
        if code[first + k] != sp.law or (column >= 0 and par[first + k, column]
                                         != sp.parameters[column]):
            raise RuntimeError(f"vsj fmu: spring {sp.name} is not at row {first + k} of the "
                               "exported model")
        springs.append((sp.name, column))
    names = [entry["name"] for entry in document["inputs"]]
    limits = [(names.index(mo.channel), float(mo.voltage_limit), mo.name)
              for mo in structure.motors if math.isfinite(mo.voltage_limit)]
    return Checks(springs, limits, options.ledger_tolerance)


def _bits(value: float) -> str:
    """A real number as the map holds it: the 16 hexadecimal digits of its IEEE 754 bits
    (no locale of the importing host can misread them)."""
    return struct.pack(">d", float(value)).hex()


def map_body(tunables: list[Tunable], params: Parameters, q0: float, checks: Checks) -> str:
    """``fmu.txt`` after its GUID line (the layout: vsj/fmi/fmu_setup.c)."""
    lines = [f"parameters {len(tunables)}"]
    for t in tunables:
        low = t.minimum if math.isfinite(t.minimum) else -1.7976931348623157e308
        high = t.maximum if math.isfinite(t.maximum) else 1.7976931348623157e308
        flags = (1 if t.strict else 0) | (2 if t.nonzero else 0)
        section, name = t.key.split(".", 1)
        unit = _display(SCHEMA[section][name].unit)
        lines.append(f"{t.key} {unit} {_bits(t.value)} {_bits(low)} {_bits(high)} {flags} "
                     f"{len(t.entries)}")
        lines += [f"{array} {index} {_bits(slope)}" for array, index, slope in t.entries]
    index = {t.key: k for k, t in enumerate(tunables)}
    lines.append(f"relations {len(RELATIONS)}")
    for relation in RELATIONS:
        lines.append(f"{int(relation.strict)} {len(relation.terms)} {relation.text}")
        for key, weight in relation.terms:
            section, name = key.split(".", 1)
            unit = _display(SCHEMA[section][name].unit)
            lines.append(f"{index[key]} {_bits(weight)} {_bits(0.0)} {key} {unit}" if key in index
                         else f"-1 {_bits(weight)} {_bits(params[key])} {key} {unit}")
    lines.append(f"pivot {_bits(q0)}")
    lines.append(f"springs {len(checks.springs)} {_bits(INTO_STOP)} {_bits(DIVERGED)}")
    lines += [f"{name} {column}" for name, column in checks.springs]
    lines.append(f"limits {len(checks.limits)}")
    lines += [f"{k} {_bits(limit)} {motor}" for k, limit, motor in checks.limits]
    lines.append(f"ledger {_bits(checks.ledger_tolerance)}")
    return "\n".join(lines) + "\n"


def map_text(guid: str, body: str) -> str:
    """The FMU's resources/fmu.txt: format version and GUID, then ``body`` (the
    parameter map, `map_body`)."""
    return f"vsj-fmu 3\nguid {guid}\n{body}"


__all__ = ["build", "cross_check", "choose_method", "compile_binary", "tunable_map", "model_description", "MODEL_IDENTIFIER", "OUTPUTS"]
