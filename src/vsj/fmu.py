"""The wrist as an FMI 2.0 co-simulation FMU (``vsj fmu``).

An FMU is a zip file that any FMI importer (20-sim, OpenModelica's
OMSimulator, Simulink, FMPy, ...) loads without Python. vsj's is laid out as
the Modelica Association's Reference FMUs are:

* ``modelDescription.xml``: the variables, their units, ranges and
  descriptions;
* ``binaries/linux64/vsj_wrist.so`` (and ``binaries/win64/vsj_wrist.dll`` where
  the mingw-w64 cross-compiler is installed): the C engine (``vsj/engine/c``)
  and its FMI layer (``vsj/fmi/vsj_fmu.c``), built with the system compiler;
* ``sources/`` and ``sources/buildDescription.xml``: the same C files, so an
  importer can build the FMU for its own platform;
* ``resources/model.json``: the wrist as `vsj.export` writes it, and
  ``resources/fmu.txt``: how each tunable parameter moves the engine's arrays.

Parameters. The C engine works on the assembled wrist (constraints already
eliminated by `vsj.network`), so the FMU cannot re-assemble it. A parameter
whose effect on the engine's arrays is affine (inertias, friction levels,
viscous coefficients, spring and motor constants, ...) is a tunable parameter
of the FMU: `tunable_map` measures its slope on each array entry and checks
that the map holds at other values, alone and together with the others. The
parameters that change the wrist's kinematics (tooth counts, ratios, the
elastic element's geometry) are constants of an FMU; export another with
``--params`` to change them.
"""

from __future__ import annotations

import hashlib
import math
import os
import shutil
import subprocess
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from . import __version__, export
from .errors import InputError
from .params import SCHEMA, Parameters
from .simulate import InitialState, SimulationOptions
from .wrist import WristOptions

MODEL_IDENTIFIER = "vsj_wrist"
#: value references (see vsj/fmi/vsj_fmu.c)
VR_OUTPUT, VR_Q0, VR_PARAMETER = 10, 99, 100
OUTPUTS = [  # name, unit, description; in the order of the C `enum output`
    ("theta_x", "rad", "end-effector angle about x"),
    ("theta_y", "rad", "end-effector angle about y"),
    ("deflection_1", "rad", "deflection of elastic element 1 (its ring against its lever)"),
    ("deflection_2", "rad", "deflection of elastic element 2"),
    ("q", "m", "pivot position of the variable stiffness mechanism"),
    ("motor_1_angle", "rad", "angle of primary motor 1 (after its gearhead)"),
    ("motor_2_angle", "rad", "angle of primary motor 2"),
    ("motor_s_angle", "rad", "angle of the stiffness (pivot) motor"),
    ("motor_1_speed", "rad/s", "speed of primary motor 1"),
    ("motor_2_speed", "rad/s", "speed of primary motor 2"),
    ("motor_s_speed", "rad/s", "speed of the stiffness motor"),
    ("power_in", "W", ("mean power delivered by the motors and the external torques over the "
                       "last communication step")),
    ("power_dissipated", "W", ("mean power dissipated by friction, armature resistance and "
                               "end stops over the last communication step")),
]
#: an affine map must reproduce the arrays to this fraction of their largest entry
AFFINE_TOLERANCE = 1e-9
SOURCES_C = ("vsj_fmu.c", "fmi2.h")


@dataclass(frozen=True)
class Tunable:
    key: str
    value: float
    minimum: float
    maximum: float
    entries: list[tuple[int, int, float]]  # (array 0 mass / 1 par, index, slope)


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
        found.append(Tunable(key, float(value), low, high, entries))
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
    import pint

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
                      description: str) -> str:
    units: dict[str, str] = {}  # FMI unit name -> the same in pint's notation
    variables = []

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
    for k, (name, unit, text) in enumerate(OUTPUTS):
        real(name, VR_OUTPUT + k, "output", "continuous", unit, text)
    real("pivot_q0", VR_Q0, "parameter", "fixed", "m",
         "initial pivot position q of the variable stiffness mechanism", start=q0,
         minimum=q_range[0], maximum=q_range[1])
    for k, t in enumerate(tunables):
        section, name = t.key.split(".", 1)
        spec = SCHEMA[section][name]
        real(t.key, VR_PARAMETER + k, "parameter", "tunable", spec.unit,
             f"{spec.description} ({params.sources[t.key]})", start=t.value,
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
    <Category name="logStatusError" description="bad calls and failed steps"/>
    <Category name="logAll" description="every message"/>
  </LogCategories>
  <DefaultExperiment startTime="0" stopTime="10" stepSize="{step!r}"/>
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


def compile_binary(kind: str, out: Path) -> None:
    cc = compiler(kind)
    if cc is None:
        raise InputError(f"vsj fmu: no C compiler for {kind}")
    sources = [str(p) for p in _source_paths() if p.suffix == ".c"]
    flags = ["-std=c99", "-O2", "-shared", "-I", str(_engine_dir()), "-I", str(_fmi_dir())]
    if kind == "linux64":
        flags += ["-fPIC", "-fvisibility=hidden"]
    else:
        flags += ["-static-libgcc"]
    done = subprocess.run([cc, *flags, "-o", str(out), *sources, "-lm"], capture_output=True,
                          text=True, check=False)
    if done.returncode != 0:
        raise InputError(f"vsj fmu: building the {kind} binary failed:\n{done.stderr[-2000:]}")


#: values per engine row (VSJ_NPAR of vsj.h); the pivot's row is the last, with
#: amplitude, fixed q, moving, q_min, q_max
ROW_VALUES = 9


def _pivot_range(document: dict) -> tuple[float, float]:
    par = document["engine"]["par"]
    return float(par[-ROW_VALUES + 3]), float(par[-ROW_VALUES + 4])


def build(out: Path, params: Parameters, *, wrist_options: WristOptions | None = None,
          friction: str = "stiction", step: float = 1e-3, q0: float = -0.01,
          win64: bool | None = None) -> dict:
    """Write the FMU to ``out``; returns what was built (tunable parameters,
    platforms). ``win64``: None builds the Windows DLL where the cross-compiler
    is installed, True requires it, False skips it."""
    wrist_options = wrist_options or WristOptions()
    method = "timestep" if friction == "stiction" else "dopri"
    options = SimulationOptions(friction=friction, step=step)
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
    text = json_text(document)
    guid = "{" + str(uuid.UUID(hashlib.md5(text.encode()).hexdigest())) + "}"
    description = (f"vsj wrist ({friction} friction, {method} at {step:g} s; parameters "
                   f"{params.meta.get('name', params.origin)}, hash {params.hash()[:12]})")
    want_win = compiler("win64") is not None if win64 is None else win64
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        (root / "binaries" / "linux64").mkdir(parents=True)
        (root / "resources").mkdir()
        (root / "sources").mkdir()
        (root / "documentation").mkdir()
        (root / "modelDescription.xml").write_text(model_description(
            document, tunables, params, q0, q_range, guid, step, description))
        (root / "resources" / "model.json").write_text(text)
        (root / "resources" / "fmu.txt").write_text(map_text(tunables, q0, q_range))
        for path in _source_paths():
            shutil.copy(path, root / "sources" / path.name)
        (root / "sources" / "buildDescription.xml").write_text(build_description())
        (root / "documentation" / "index.html").write_text(
            f"<html><body><h1>vsj wrist FMU</h1><p>{description}</p><p>Built by vsj "
            f"{__version__}; see vsj's README, section 'The wrist as an FMU'.</p></body></html>\n")
        compile_binary("linux64", root / "binaries" / "linux64" / f"{MODEL_IDENTIFIER}.so")
        platforms = ["linux64"]
        if want_win:
            (root / "binaries" / "win64").mkdir()
            compile_binary("win64", root / "binaries" / "win64" / f"{MODEL_IDENTIFIER}.dll")
            platforms.append("win64")
        from .output import atomic_write

        with atomic_write(Path(out), "wb") as handle, \
                zipfile.ZipFile(handle, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(root).as_posix())
    return {"tunable": [t.key for t in tunables],
            "constant": [k for k in params.values if k not in {t.key for t in tunables}],
            "platforms": platforms, "guid": guid, "method": method}


def json_text(document: dict) -> str:
    import json

    return json.dumps(document, allow_nan=False) + "\n"


def map_text(tunables: list[Tunable], q0: float, q_range: tuple[float, float]) -> str:
    lines = ["vsj-fmu 1", f"parameters {len(tunables)}"]
    for t in tunables:
        low = t.minimum if math.isfinite(t.minimum) else -1.7976931348623157e308
        high = t.maximum if math.isfinite(t.maximum) else 1.7976931348623157e308
        lines.append(f"{t.value!r} {low!r} {high!r} {len(t.entries)}")
        lines += [f"{array} {index} {slope!r}" for array, index, slope in t.entries]
    lines.append(f"pivot {q0!r} {q_range[0]!r} {q_range[1]!r}")
    return "\n".join(lines) + "\n"


__all__ = ["build", "tunable_map", "model_description", "MODEL_IDENTIFIER", "OUTPUTS"]
