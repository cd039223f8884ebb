"""The ``vsj linearize``, ``vsj datasheet`` and ``vsj export-model`` commands (a thin
layer, no physics).

`register` adds them to the ``vsj`` command's subparsers; each handler returns
the exit code (0) and raises `vsj.errors.InputError` for bad input (exit 2) or
`vsj.errors.SimulationError` when a computation fails (exit 1).

Values with units are written as in parameter files: ``--q=-0.4cm`` (the
``=`` keeps argparse from reading a negative value as an option),
``--tau-x "0.05 N m"``, ``--motor-1 "0.1 rad"``.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from .. import params
from ..errors import InputError, SimulationError
from ..friction import RUN_LAWS
from ..friction import LINEAR_TREATMENTS as FRICTION_TREATMENTS
from ..simulate import InitialState, SimulationOptions
from ..stepper import METHODS
from ..units import to_si
from ..wrist import DRIVES, ELASTIC_MODELS, WristOptions, build_wrist, unread_changes


def _params(path: str | None):
    return params.load(path)


def _quantity(text: str, unit: str, option: str) -> float:
    value = to_si(text, unit, where=f"option {option}")
    if not math.isfinite(value):
        raise InputError(f"option {option}: {text!r} is not finite")
    return value


def _names(text: str | None) -> list[str] | None:
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise InputError(f"expected a comma-separated list of names, got {text!r}")
    return names


def _warn_unread(parameters, options: WristOptions) -> None:
    """Say on stderr what ``parameters`` changes that the wrist of ``options`` does not
    read (`vsj.wrist.unread_changes`: a design's springs with the exponential model)."""
    if parameters.origin != params.DEFAULT_ORIGIN:
        for text in unread_changes(build_wrist(parameters, options), parameters,
                                   choose="--elastic"):
            print(f"vsj: warning: {text}", file=sys.stderr)


def _wrist_options(args, parameters):
    """WristOptions from the options `_add_wrist_arguments` adds; what ``parameters``
    changes in vain for them is said on stderr (`_warn_unread`)."""
    if args.linear_stiffness and args.elastic != "linear":
        raise InputError(f"--linear-stiffness {args.linear_stiffness}: the stiffness of the "
                         f"'linear' elastic model, which --elastic {args.elastic} is not; give "
                         "--elastic linear with it")
    options = WristOptions(elastic=args.elastic, motors=args.motor_model,
                           pivot_drive=getattr(args, "pivot_drive", "velocity"),
                           linear_stiffness=(_quantity(args.linear_stiffness, "N*m",
                                                       "--linear-stiffness")
                                             if args.linear_stiffness else None))
    options.validate()
    _warn_unread(parameters, options)
    return options


def _add_tolerance_arguments(p) -> None:
    """--rtol and --atol of the adaptive step functions, defaulting to the simulator's."""
    p.add_argument("--rtol", type=float, default=SimulationOptions.rtol,
                   help="dopri/rosenbrock relative tolerance (default %(default)g)")
    p.add_argument("--atol", type=float, default=SimulationOptions.atol,
                   help="dopri/rosenbrock absolute tolerance (default %(default)g)")


def _add_wrist_arguments(p, elastic_models, drives, *, pivot_drive: bool = False) -> None:
    """The wrist's sub-model options (`vsj.wrist.WristOptions`) of a command; with
    ``pivot_drive`` the stiffness motor's too (the exported models)."""
    p.add_argument("--elastic", default="geometric", choices=list(elastic_models),
                   help="elastic element model (default geometric)")
    p.add_argument("--linear-stiffness", metavar="STIFFNESS",
                   help="stiffness of the 'linear' elastic model, e.g. '0.8 N m/rad'")
    p.add_argument("--motor-model", default="velocity", choices=list(drives),
                   help="primary motors: velocity sources or DC motors (default velocity)")
    if pivot_drive:
        p.add_argument("--pivot-drive", default="velocity", choices=list(drives),
                       help="stiffness motor: velocity source or DC motor (default velocity)")


def cmd_linearize(args) -> int:
    """``vsj linearize``: the wrist linearised about an operating point, printed (or as
    JSON) and optionally saved to .json or .npz. Returns the exit code: 0 (bad input
    raises `InputError`, which `main` turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import linear
    from ..output import SMALL_OUTPUT_BYTES, _jsonable, check_output_file, write_errors

    if args.out is not None and Path(args.out).suffix not in (".json", ".npz"):
        raise InputError(f"--out {args.out}: a linear model is written to a .json or .npz file")
    if args.out is not None:
        check_output_file(args.out, "--out", size=SMALL_OUTPUT_BYTES, force=args.force)
    params = _params(args.params)
    model = linear.linearize(
        params, _quantity(args.q, "m", "--q"),
        motors=(_quantity(args.motor_1, "rad", "--motor-1"),
                _quantity(args.motor_2, "rad", "--motor-2")),
        load=(_quantity(args.tau_x, "N*m", "--tau-x"), _quantity(args.tau_y, "N*m", "--tau-y")),
        wrist_options=_wrist_options(args, params), friction=args.friction,
        inputs=_names(args.inputs),
        outputs=_names(args.outputs), statespace=False)
    for text in model.info.get("warnings", []):
        print(f"vsj: warning: {text}", file=sys.stderr)
    if args.out is not None:
        with write_errors("--out", args.out):
            linear.save(model, Path(args.out))
    if args.json:
        print(json.dumps(_jsonable(linear.to_dict(model)), indent=1))
        return 0
    print(model.describe())
    print("operating point:")
    for name, value in model.operating_point["outputs"].items():
        if not name.endswith("_speed"):
            print(f"  {name} = {value:.6g}")
    freqs = linear.natural_frequencies(model)
    print("natural frequencies (undamped): "
          + ", ".join(f"{w / (2 * math.pi):.4g} Hz" for w in freqs))
    names = set(model.output_labels) & {"theta_x", "theta_y"}
    if names == {"theta_x", "theta_y"} and {"tau_x", "tau_y"} <= set(model.input_labels):
        try:
            k = linear.output_stiffness(model)
            print(f"end-effector stiffness, motors held: K_xx = {k[0, 0]:.4g}, "
                  f"K_yy = {k[1, 1]:.4g}, K_xy = {k[0, 1]:.4g} N m/rad")
        except SimulationError as exc:  # a rigid-body mode: the model is still valid
            print(f"end-effector stiffness: none ({exc})")
    if args.out is not None:
        print(f"wrote {args.out}")
    return 0


def cmd_datasheet(args) -> int:
    """``vsj datasheet``: compute the wrist's datasheet and write it as HTML and JSON in one
    result set. Returns the exit code: 0 (bad input raises `InputError`, which `main`
    turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import datasheet
    from ..output import ResultSet

    params = _params(args.params)
    datasheet.check_q_points(args.points, "--points")  # before the directory is touched
    _warn_unread(params, WristOptions(elastic=args.elastic))
    with ResultSet(Path(args.out), "datasheet", size=datasheet.OUTPUT_BYTES) as results:
        sheet = datasheet.compute(params, q_points=args.points, friction=args.friction,
                                  elastic=args.elastic, option="--points")
        html_path, json_path = datasheet.write(sheet, results)
    for key, rating in sheet["ratings"].items():
        print(f"{key.replace('_', ' '):<26} {rating['value']:>10.4g} {rating['unit']:<8} "
              f"{rating['note']}")
    print(f"wrote {html_path}, {json_path}")
    return 0


def cmd_export_model(args) -> int:
    """``vsj export-model``: write the wrist, with a parameter set and model options, as a
    model file (binary, `vsj.export`) that the C library loads (``vsj_load_model``) and
    steps one control period at a time. Returns the exit code: 0 (bad input raises
    `InputError`, which `main` turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import export
    from ..output import SMALL_OUTPUT_BYTES, check_output_file, write_errors

    check_output_file(args.out, "--out", size=SMALL_OUTPUT_BYTES, force=args.force)
    params = _params(args.params)
    method = args.method or ("timestep" if args.friction == "stiction" else "dopri")
    options = SimulationOptions(friction=args.friction,
                                step=_quantity(args.step, "s", "--step"),
                                rtol=args.rtol, atol=args.atol)
    wrist_options = _wrist_options(args, params)
    stepper = export.wrist_stepper(params, wrist_options, options=options, method=method,
                                   period=_quantity(args.period, "s", "--period"),
                                   substeps=args.substeps)
    initial = InitialState(q=_quantity(args.q, "m", "--q") if args.q is not None else None)
    document = export.model_document(stepper, params=params, initial=initial,
                                     wrist_options=wrist_options)
    with write_errors("--out", args.out):
        export.write_model(Path(args.out), document, stepper)
    print(f"wrote {args.out}: {len(document['inputs'])} inputs "
          f"({', '.join(i['name'] for i in document['inputs'])}), a state of "
          f"{len(document['state'])}, {len(document['outputs'])} outputs; step function "
          f"{method} over {stepper.period:g} s periods")
    return 0


def cmd_fmu(args) -> int:
    """``vsj fmu``: build an FMI 2.0 co-simulation FMU of the wrist and/or write an FMI
    cross-check folder. Returns the exit code: 0 (bad input raises `InputError`, which
    `main` turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import fmu
    from ..output import check_output_file, write_errors

    if args.out is None and args.cross_check is None:
        raise InputError("vsj fmu: give --out FILE.fmu, --cross-check DIR, or both")
    if args.out is not None:
        if Path(args.out).suffix != ".fmu":
            raise InputError(f"--out {args.out}: an FMU is written to a .fmu file")
        check_output_file(args.out, "--out", size=8 * 2 ** 20, force=args.force)
    if args.cross_check is not None and Path(args.cross_check).exists() \
            and not Path(args.cross_check).is_dir():
        raise InputError(f"--cross-check {args.cross_check}: not a directory")
    params = _params(args.params)
    step = _quantity(args.step, "s", "--step")
    if not 1e-6 <= step <= 1e-2:
        raise InputError(f"--step {args.step}: allowed from 1 us to 10 ms")
    win64 = {"auto": None, "yes": True, "no": False}[args.win64]
    if win64 and fmu.compiler("win64") is None:
        raise InputError("--win64 yes: the mingw-w64 cross-compiler (x86_64-w64-mingw32-gcc; "
                         "Debian: apt-get install gcc-mingw-w64-x86-64) is not installed")
    settings = dict(wrist_options=_wrist_options(args, params), friction=args.friction,
                    step=step,
                    q0=_quantity(args.q, "m", "--q"), win64=win64, method=args.method,
                    rtol=args.rtol, atol=args.atol)
    info = None
    if args.out is not None:
        info = fmu.build(Path(args.out), params, **settings)
        print(f"wrote {args.out}: FMI 2.0 co-simulation, {info['method']} at {step:g} s, "
              f"binaries for {', '.join(info['platforms'])}, sources included; "
              f"{len(info['tunable'])} tunable parameters, {len(info['constant'])} fixed by "
              f"this export ({', '.join(info['constant'])})")
    if args.cross_check is not None:
        with write_errors("--cross-check", args.cross_check):
            info = fmu.cross_check(Path(args.cross_check), params, **settings)
        print(f"wrote the FMI cross-check folder{'s' if len(info['folders']) > 1 else ''} "
              f"{', '.join(info['folders'])}: the FMU, held inputs every {info['period']:g} s "
              f"over {info['steps']} steps, vsj's reference run, options, README")
    for platform, text in info["warnings"].items():
        print(f"warning: the {platform} compiler said:\n{text}")
    if "win64" not in info["platforms"] and win64 is None:
        print("no win64 DLL: the mingw-w64 cross-compiler x86_64-w64-mingw32-gcc is not on "
              "PATH (Debian: apt-get install gcc-mingw-w64-x86-64); an importer on Windows "
              "can also build the FMU from its sources/")
    return 0


def register(sub) -> None:
    """Add ``linearize``, ``datasheet`` and ``export-model`` to the ``vsj`` command's
    subparsers."""
    p = sub.add_parser(
        "linearize", help="linear state-space model of the wrist around an operating point",
        description="Linearise the wrist at a pivot position, motor positions and a static "
                    "load; print a summary, or the model as JSON, and write it to .json or "
                    ".npz. Friction: " + "; ".join(f"{k}: {v}" for k, v in
                                                   FRICTION_TREATMENTS.items()))
    p.add_argument("--q", default="0 cm", metavar="LENGTH",
                   help="pivot position with unit, e.g. --q=-0.4cm (default 0 cm)")
    p.add_argument("--motor-1", default="0 rad", metavar="ANGLE",
                   help="position of motor 1's output (default 0 rad)")
    p.add_argument("--motor-2", default="0 rad", metavar="ANGLE",
                   help="position of motor 2's output (default 0 rad)")
    p.add_argument("--tau-x", default="0 N m", metavar="TORQUE",
                   help="static external torque about theta_x (default 0 N m)")
    p.add_argument("--tau-y", default="0 N m", metavar="TORQUE",
                   help="static external torque about theta_y (default 0 N m)")
    p.add_argument("--friction", default="linearised", choices=list(FRICTION_TREATMENTS),
                   help="friction treatment (default linearised)")
    _add_wrist_arguments(p, ELASTIC_MODELS, DRIVES)
    p.add_argument("--inputs", metavar="NAMES", help="comma-separated inputs to keep")
    p.add_argument("--outputs", metavar="NAMES", help="comma-separated outputs to keep")
    p.add_argument("--params", metavar="FILE", help="parameter file (default: bundled set)")
    p.add_argument("--out", metavar="FILE", help="write the model to FILE (.json or .npz)")
    p.add_argument("--force", action="store_true",
                   help="replace --out even if vsj did not write it")
    p.add_argument("--json", action="store_true", help="print the model as JSON")
    p.set_defaults(func=cmd_linearize)

    p = sub.add_parser(
        "datasheet", help="VSA datasheet of the wrist (HTML with plots, and JSON)",
        description="Stiffness range, torque-deflection curves, maximum deflection and "
                    "torque, stored energy, stiffness-change time and energy, output "
                    "inertia, natural frequencies, Bode plots and bandwidth, from the model.")
    p.add_argument("--out", metavar="DIR", default="out",
                   help="output directory (default out): datasheet.html, datasheet.json")
    p.add_argument("--params", metavar="FILE", help="parameter file (default: bundled set)")
    p.add_argument("--points", type=int, default=9,
                   help="pivot positions in the tables (default 9)")
    p.add_argument("--friction", default="linearised", choices=list(FRICTION_TREATMENTS),
                   help="friction treatment of the dynamics (default linearised)")
    p.add_argument("--elastic", default="geometric",
                   choices=[m for m in ELASTIC_MODELS if m != "linear"],
                   help="elastic element model (default geometric)")
    p.set_defaults(func=cmd_datasheet)

    p = sub.add_parser(
        "export-model", help="write the wrist as a model file for the C engine (vsj.h)",
        description="Write the wrist, with a parameter set and model options, as a model "
                    "file (binary, with a checksum) that the C library reads "
                    "(vsj_load_model) and steps one control period at a time "
                    "(examples/c/step_wrist.c).")
    p.add_argument("--out", metavar="FILE", required=True,
                   help="model file to write (e.g. wrist.vsjm)")
    p.add_argument("--force", action="store_true",
                   help="replace --out even if vsj did not write it")
    p.add_argument("--params", metavar="FILE", help="parameter file (default: bundled set)")
    _add_wrist_arguments(p, ELASTIC_MODELS, DRIVES, pivot_drive=True)
    p.add_argument("--friction", default="arctan", choices=list(RUN_LAWS),
                   help="friction law (default arctan)")
    p.add_argument("--method", choices=list(METHODS),
                   help="step function: dopri or rosenbrock (adaptive), rk4 (fixed cost) or "
                        "timestep (true stiction); default timestep with --friction stiction, "
                        "else dopri")
    p.add_argument("--period", default="1 ms", metavar="TIME",
                   help="control period (default 1 ms)")
    p.add_argument("--step", default="1 ms", metavar="TIME",
                   help="time-stepper step (default 1 ms)")
    p.add_argument("--substeps", type=int, default=4, help="rk4 substeps per period (default 4)")
    _add_tolerance_arguments(p)
    p.add_argument("--q", metavar="LENGTH",
                   help="pivot position of the initial state, e.g. --q=-1cm (default 0 cm)")
    p.set_defaults(func=cmd_export_model)

    p = sub.add_parser(
        "fmu", help="write the wrist as an FMI 2.0 co-simulation FMU (20-sim, OpenModelica, "
                    "Simulink, FMPy)",
        description="Write a standalone FMI 2.0 co-simulation FMU of the wrist: binaries "
                    "built from the C engine with the system compiler (and for win64 with "
                    "mingw-w64 where installed; each kept in ~/.cache/vsj/fmu and reused while "
                    "the sources, compiler and flags stay the same), its sources with "
                    "buildDescription.xml, and the model in resources/. See the user guide's page "
                    "'The FMU and the C API' (docs/user-guide/c-api-fmu.md).")
    p.add_argument("--out", metavar="FILE", help="FMU to write (.fmu)")
    p.add_argument("--force", action="store_true",
                   help="replace --out even if vsj did not write it")
    p.add_argument("--cross-check", metavar="DIR",
                   help="also (or instead) write an FMI cross-check folder under DIR "
                        "(fmus/2.0/cs/<platform>/vsj/<version>/vsj_wrist: the FMU, "
                        "vsj_wrist_in.csv, vsj_wrist_ref.csv, vsj_wrist_ref.opt, README.md)")
    p.add_argument("--params", metavar="FILE", help="parameter file (default: bundled set)")
    _add_wrist_arguments(p, ELASTIC_MODELS, DRIVES, pivot_drive=True)
    p.add_argument("--friction", default="stiction", choices=list(RUN_LAWS),
                   help="friction law (default stiction: the time-stepper)")
    # the FMU runs the step methods that keep an energy ledger (not rk4); vsj.fmu, not
    # imported here, checks the same list
    p.add_argument("--method", default="auto",
                   choices=("auto",) + tuple(m for m in METHODS if m != "rk4"),
                   help="step function inside the FMU: the time-stepper at --step, or dopri "
                        "or rosenbrock (adaptive; smooth laws only); auto: timestep for "
                        "stiction, else dopri")
    p.add_argument("--step", default="1 ms", metavar="TIME",
                   help="internal step (the time-stepper's; default 1 ms)")
    _add_tolerance_arguments(p)
    p.add_argument("--q", default="-1 cm", metavar="LENGTH",
                   help="default initial pivot position, the parameter pivot_q0 (default -1 cm)")
    p.add_argument("--win64", choices=("auto", "yes", "no"), default="auto",
                   help="also build binaries/win64 with mingw-w64 (auto: where installed)")
    p.set_defaults(func=cmd_fmu)


__all__ = ["register", "cmd_linearize", "cmd_datasheet", "cmd_export_model", "cmd_fmu"]

