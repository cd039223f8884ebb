"""``vsj synth`` and ``vsj fit``: the characterisation commands (section 4 of the report).

Only argument handling and output here; the work is in `vsj.synth` and
`vsj.identification`. With ``--json`` the result object is the only thing on
standard output (messages go to standard error), so it can be piped.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import tomllib
from pathlib import Path

import numpy as np

from .. import __version__, params
from ..errors import InputError, read_text
from ..params import SCHEMA
from ..springs import GEOMETRIC, GEOMETRY_FIELDS
from ..units import to_si
from ..wrist import WristOptions, geometry


def _force(parser) -> None:
    """The --force of a command that writes single files (vsj replaces only a file that
    carries its mark unless forced, `vsj.output.check_output_file`)."""
    parser.add_argument("--force", action="store_true",
                        help="replace an output file even if vsj did not write it")


def _at_least_one(text: str) -> int:
    """A whole number >= 1 (argparse type): a count of starts or threads."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


def _floats(text: str, count: int, what: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"{what}: {text!r} is not a comma-separated list of numbers") from None
    if len(values) != count:
        raise InputError(f"{what}: expected {count} numbers, got {len(values)}")
    return values


def _params(path):
    return params.load(path)


def _say(args, text: str) -> None:
    """Human-readable output: stdout, or stderr when stdout carries JSON."""
    print(text, file=sys.stderr if getattr(args, "json", False) else sys.stdout)


def _print_json(args, record: dict) -> None:
    if args.json:
        from ..output import _jsonable  # lazy: not every command writes files (vsj.output)

        print(json.dumps(_jsonable(record), indent=2))


def _results(out: Path | None, kind: str, **options):
    """The `vsj.output.ResultSet` of ``--out DIR`` (entering it checks the directory, so
    enter it before the work), or, without ``--out``, a context that gives None."""
    # lazy: not every command writes files (vsj.output)
    from ..output import SMALL_OUTPUT_BYTES, ResultSet

    if out is None:
        return contextlib.nullcontext()
    return ResultSet(out, kind, size=SMALL_OUTPUT_BYTES, **options)


def cmd_synth_friction(args) -> int:
    """``vsj synth friction``: write a synthetic torque-velocity curve of the planetary
    bench (labelled synthetic). Returns the exit code: 0 (bad input raises `InputError`,
    which `main` turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import measurements, synth
    from ..output import SMALL_OUTPUT_BYTES, check_output_file, write_errors

    check_output_file(args.out, "--out", size=SMALL_OUTPUT_BYTES, force=args.force)
    if args.report:  # argparse has checked it is 'old' or 'second'
        constants, params = synth.REPORT_CONSTANTS[(args.report, args.fixed)], None
    elif args.constants:
        constants, params = _floats(args.constants, 3, "--constants c1,c2,c3"), None
    else:
        constants, params = None, _params(args.params)
    data = synth.friction(fixed=args.fixed, constants=constants, params=params, form=args.form,
                          noise=args.noise, ripple_fraction=args.ripple, angle=not args.no_angle,
                          seed=args.seed)
    with write_errors("--out", args.out):
        measurements.write(args.out, data.columns, data.comments)
    print(f"wrote {args.out} (synthetic, {len(next(iter(data.columns.values()))[0])} rows)")
    return 0


def cmd_synth_stiffness(args) -> int:
    """One curve per pivot position: into a ``.csv`` file for a single curve, or into a
    directory as one result set of these curves. Curves that earlier runs wrote there at
    other positions are kept; one at the same position is replaced."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import measurements, synth
    from ..output import SMALL_OUTPUT_BYTES, check_output_file, write_errors

    params = _params(args.params)
    bad = [q for q in args.q if not math.isfinite(q)]
    if bad:
        raise InputError(f"--q: pivot positions must be finite numbers of cm, got {bad[0]!r}")
    qs = [q / 100 for q in args.q]
    out = Path(args.out)
    single = len(qs) == 1 and out.suffix == ".csv"
    if single:
        check_output_file(out, "--out", size=SMALL_OUTPUT_BYTES, force=args.force)
    # each position to 0.1 cm, a negative zero as zero
    names = [f"stiffness_q{round(q * 100, 1) + 0.0:+.1f}cm.csv" for q in qs]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"--q: two positions give the same curve ({twice[0]}: positions are "
                         "written to 0.1 cm)")
    if not single:
        _refuse_other_positions(out, qs, names)
    written = []
    with _results(None if single else out, "synth stiffness",
                  name="synth stiffness " + " ".join(names), files=names) as results:
        for q, name in zip(qs, names):
            data = synth.stiffness(q=q, params=params, noise=args.noise, play=args.play,
                                   seed=args.seed + int(round(q * 1e4)) % 1000, model=args.model)
            if single:
                with write_errors("--out", out):
                    measurements.write(out, data.columns, data.comments)
                written.append((out, q))
            else:
                measurements.write(results.path(name), data.columns, data.comments)
                written.append((out / name, q))
    for path, q in written:
        print(f"wrote {path} (synthetic, q = {q * 100:g} cm)")
    return 0


def _refuse_other_positions(out: Path, qs, names) -> None:
    """`InputError` if a curve file of ``out`` that this run would replace holds another
    pivot position than the run's (file names keep 0.1 cm: 1.44 cm would replace 1.4 cm);
    a file whose position cannot be read is not vsj's curve, and the result set's own
    check refuses it."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import measurements
    from ..identification.stiffness import pivot_of

    for q, name in zip(qs, names):
        path = out / name
        if not path.is_file():
            continue
        try:
            held = pivot_of(measurements.read(path))
        except InputError:
            continue
        if f"{held * 100:g}" != f"{q * 100:g}":
            raise InputError(f"--q {q * 100:g}: {path} holds the curve at q = {held * 100:g} cm, "
                             "another position with the same file name (positions are written "
                             "to 0.1 cm); write this one to another directory, or remove that "
                             "file first")


def _out(args) -> Path | None:
    return None if args.out is None else Path(args.out)


def cmd_fit_friction(args) -> int:
    """``vsj fit friction``: fit ``T = c1 w + c2 atan(c3 w)`` (report eq 4.2) to one curve,
    with JSON and a figure. Returns the exit code: 0 (bad input raises `InputError`,
    which `main` turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import measurements
    from ..identification.friction import fit_curve
    from ..identification.plots import friction_figure
    from ..output import write_meta
    from ..plots import save

    m = measurements.read(args.file, required=("velocity", "torque"))
    out = _out(args)
    stem = Path(args.file).stem
    json_name, png_name = f"{stem}-friction.json", f"{stem}-friction.png"
    with _results(out, "fit friction", name=f"fit friction {stem}",
                  files=(json_name, png_name)) as results:
        fit = fit_curve(m)
        record = fit.to_json()
        if results is not None:
            write_meta(results.path(json_name), record)
            save(friction_figure(fit), results.path(png_name))
    _print_json(args, record)
    lines = [f"{args.file}: {fit.form}, {len(fit.velocity)} points"
             + (" [synthetic data]" if fit.synthetic else "")]
    for e in (fit.c1, fit.c2, fit.c3):
        if e.status == "determined":
            lines.append(f"  {e.name} = {e.value:.5g} +- {e.stderr:.2g} {e.unit}  "
                         f"(95 %: {e.ci95[0]:.4g} .. {e.ci95[1]:.4g})")
        else:
            lines.append(f"  {e.name} = {e.value:.5g} {e.unit}  ({e.status})")
    if fit.ripple is not None:
        lines.append(f"  ripple: rms {fit.ripple.rms * 1e3:.3g} mN m, peak-to-peak "
                     f"{fit.ripple.peak_to_peak * 1e3:.3g} mN m ({fit.ripple.method})")
    lines += [f"  note: {n}" for n in fit.notes]
    if out is not None:
        lines.append(f"wrote {out / png_name}, {out / json_name}")
    _say(args, "\n".join(lines))
    return 0


def _write_params(path: str, overrides: dict, base: str | None) -> None:
    # lazy: not every command writes files (vsj.output)
    from ..output import atomic_write, write_errors

    params = _params(base)
    identified = params.with_overrides(overrides, origin=str(path))

    with write_errors("--write-params", path), atomic_write(Path(path)) as handle:
        handle.write(f"# parameter set written by vsj {__version__}\n" + identified.to_toml())


def _check_write_params(args) -> None:
    # lazy: not every command writes files (vsj.output)
    from ..output import SMALL_OUTPUT_BYTES, check_output_file

    if args.write_params:
        check_output_file(args.write_params, "--write-params", size=SMALL_OUTPUT_BYTES,
                          force=args.force)


def cmd_fit_planetary(args) -> int:
    """``vsj fit planetary``: the planetary module's parameters from the fixed-sun and
    fixed-ring curves, optionally written to a parameter file. Returns the exit code: 0,
    or 1 if no model explains the curves or the written file does not reproduce them."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import measurements
    from ..identification.friction import fit_curve
    from ..identification.planetary import fit_planetary
    from ..identification.plots import planetary_figure
    from ..output import write_meta
    from ..plots import save

    sun_data = measurements.read(args.fixed_sun, required=("velocity", "torque"))
    ring_data = measurements.read(args.fixed_ring, required=("velocity", "torque"))
    _check_write_params(args)
    out = _out(args)
    with _results(out, "fit planetary") as results:
        result = fit_planetary(fit_curve(sun_data), fit_curve(ring_data),
                               tooth_ratio=args.tooth_ratio, significance=args.significance)
        if results is not None:
            write_meta(results.path("planetary.json"), result.to_json())
            save(planetary_figure(result), results.path("planetary.png"))
    record = result.to_json()
    lines = [result.verdict]
    for name, s in result.fits.items():
        verdict = ("rejected" if not s.explains else "passes, but the test does not "
                   "discriminate" if s.too_small else "explains both curves")
        lines.append(f"{name} model: {verdict} "
                     f"(chi2 {s.chi2:.3g} on {s.dof} dof, p = {s.p_value:.2g}; rms deviation "
                     + ", ".join(f"{k} {v * 1e3:.3g} mN m" for k, v in s.misfit.items()) + ")")
        if s.explains:
            lines += [f"  {what}: {text}" for what, text in
                      (("caution", s.caution()), ("noise", s.noise_note())) if text]
    chosen = result.chosen
    if chosen is not None:
        lines += _planetary_parameters(chosen)
    if out is not None:
        lines.append(f"wrote {out / 'planetary.png'}, {out / 'planetary.json'}")
    failed = None
    if args.write_params and chosen is not None:
        deviation = _write_planetary_params(args, result)
        record["written"] = {"file": args.write_params, "round_trip_deviation": deviation}
        lines.append(f"wrote {args.write_params}: the bench run forward with it gives the "
                     f"fitted curves to {deviation:.2g} of their largest torque")
        if not deviation <= PLANETARY_ROUND_TRIP:
            failed = (f"{args.write_params} does not reproduce the fitted curves (relative "
                      f"deviation {deviation:.3g}, allowed {PLANETARY_ROUND_TRIP:g})")
    _print_json(args, record)
    _say(args, "\n".join(lines))
    if chosen is None:
        print("vsj: no parameter set explains both curves"
              + (f"; {args.write_params} not written" if args.write_params else ""),
              file=sys.stderr)
        return 1
    if failed:
        print(f"vsj: {failed}", file=sys.stderr)
        return 1
    return 0


#: A parameter file written by ``fit planetary --write-params`` reproduces the fitted
#: curves to this fraction of their largest torque: the values are written in full
#: precision, and the bench and the fit add the same seven friction torques in another
#: order (rounding, about 1e-16).
PLANETARY_ROUND_TRIP = 1e-9


def _planetary_parameters(chosen) -> list[str]:
    """The chosen structure's parameters, with what the data leave open."""
    lines = [f"parameters ({chosen.structure} model):"]
    for e in chosen.parameters:
        err = (f"+- {e.stderr:.2g}" if math.isfinite(e.stderr)
               else "(one of many)" if e.name in chosen.same_curves
               else "(at a bound)" if e.name in chosen.at_bound else "(not determined)")
        lines.append(f"  {e.name:<5} = {e.value:.5g} {err} {e.unit}")
    alone = [n for n in chosen.undetermined if n not in chosen.same_curves]
    if alone:
        lines.append("  not determined by these data: " + ", ".join(alone))
    for c in chosen.combinations:
        lines.append(f"  determined: {c}")
    bound = [n for n in chosen.at_bound if n not in chosen.same_curves]
    if bound:
        lines.append("  at a bound: " + ", ".join(bound))
    if chosen.over_parameterised:
        units = {e.name: e.unit for e in chosen.parameters}
        lines.append("  over-parameterised: this set is one of many that give the very same "
                     "curves:")
        for name, (lo, hi) in chosen.same_curves.items():
            lines.append(f"    {name} anywhere from {lo:.4g} to {hi:.4g} {units[name]} "
                         "(the others adjusted)")
    if chosen.ratio_one_of_many:
        lo, hi = chosen.tooth_ratio_accepted
        lines.append(f"  tooth ratio one of many: the test accepts every x from {lo:.3g} to "
                     f"{hi:.3g} (refitted on a grid of step 0.05); give --tooth-ratio "
                     "N_S/N_R if the gear's teeth are known")
    return lines


def _write_planetary_params(args, result) -> float:
    """Write the set with the fit's planetary parameters; run the bench forward with the
    file as written and return its largest deviation from the fitted curves, relative to
    their largest torque."""
    # lazy: scipy.optimize, for the fits only
    from ..identification.planetary import bench_curves

    base = _params(args.params)
    files = f"{args.fixed_sun} and {args.fixed_ring}"
    teeth = (base.planetary.sun_teeth, base.planetary.ring_teeth)
    _write_params(args.write_params, result.parameter_overrides(files, teeth), args.params)
    predicted = result.chosen.predicted
    forward = bench_curves(_params(args.write_params),
                           {k: v for k, (v, _) in predicted.items()})
    return max(float(np.max(np.abs(forward[k] - t)) / np.max(np.abs(t)))
               for k, (_, t) in predicted.items())


def cmd_fit_stiffness(args) -> int:
    """``vsj fit stiffness``: stiffness K per torque-deflection curve and K(q) (report eq
    4.5) over the curves, optionally the spring geometry calibrated to them. Returns the
    exit code: 0 (bad input raises `InputError`, which `main` turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import characteristics as ch
    from .. import measurements
    from ..identification.geometry import calibrate_to_curves
    from ..identification.plots import geometry_figure, stiffness_figure
    from ..identification.stiffness import fit_stiffness
    from ..output import write_meta
    from ..plots import save

    data = [measurements.read(f, required=("deflection", "torque")) for f in args.files]
    if args.write_params and len(data) < 4 and not args.calibrate_geometry:
        raise InputError("--write-params: nothing to write: K(q) needs curves at 4 or more "
                         "pivot positions, and --calibrate-geometry is not given")
    _check_write_params(args)
    out = _out(args)
    calibration = start = None
    with _results(out, "fit stiffness") as results:
        fit = fit_stiffness(data)
        record = fit.to_json()
        if args.calibrate_geometry:
            start = dict(zip(GEOMETRY_FIELDS, geometry(_params(args.params))))
            calibration = calibrate_to_curves(fit.curves, start)
            record["geometry"] = calibration.to_json()
        if results is not None:
            write_meta(results.path("stiffness.json"), record)
            model_K = None
            if calibration is not None:
                row = _row(calibration.dimensions, start)
                model_K = lambda q: ch.stiffness(GEOMETRIC, row, q)  # noqa: E731
            save(stiffness_figure(fit, model_K), results.path("stiffness.png"))
            if calibration is not None:
                save(geometry_figure(calibration, fit.curves, _row(start, start),
                                     _row(calibration.dimensions, start)),
                     results.path("geometry.png"))
    _print_json(args, record)
    lines = []
    for c in fit.curves:
        extra = []
        if c.play_detected:
            extra.append(f"play {c.play.value * 1e3:.3g} mrad")
        if c.pretension_loss is not None:
            extra.append(f"stiffness drops beyond {c.pretension_loss:.3g} rad")
        lines.append(f"q = {c.q * 100:6.3g} cm: K = {c.K.value:.4g} +- {c.K.stderr:.2g} N m/rad, "
                     f"hysteresis {c.hysteresis.value * 1e3:.3g} mN m, linear to "
                     f"{c.linear_limit:.3g} rad" + ("; " + ", ".join(extra) if extra else ""))
    e = fit.exponential
    if e is not None:
        lines.append(f"K(q) = a1 exp(a2 q) + a3: a1 = {e.a1.value:.4g} +- {e.a1.stderr:.2g} N m/rad, "
                     f"a2 = {e.a2.value / 100:.4g} +- {e.a2.stderr / 100:.2g} 1/cm, "
                     f"a3 = {e.a3.value:.4g} +- {e.a3.stderr:.2g} N m/rad "
                     f"(relative rms {e.relative_rms:.2g})")
    else:
        lines.append("K(q) not fitted: curves at 4 or more pivot positions are needed")
    overrides = {}
    if calibration is not None:
        lines.append(f"geometry calibrated: relative rms {calibration.rms_before:.3g} -> "
                     f"{calibration.rms_after:.3g}")
        units = {"spring_stiffness": "N/m"}
        for k, v in calibration.dimensions.items():
            unit = units.get(k, "cm")
            value = v * 100 if unit == "cm" else v
            overrides[f"elastic_element.{k}"] = {"value": f"{value:.6g} {unit}"}
            lines.append(f"  {k} = {value:.5g} {unit}")
    if out is not None:
        lines.append(f"wrote {out / 'stiffness.png'}, {out / 'stiffness.json'}")
        if calibration is not None:
            lines.append(f"wrote {out / 'geometry.png'}")
    if args.write_params:
        if e is not None:
            for name, unit, scale in (("a1", "N m/rad", 1), ("a2", "1/cm", 0.01),
                                      ("a3", "N m/rad", 1)):
                overrides[f"elastic_element.{name}"] = {
                    "value": f"{getattr(e, name).value * scale:.6g} {unit}"}
        source = "identified from " + ", ".join(args.files)
        for v in overrides.values():
            v["source"] = source
        _write_params(args.write_params, overrides, args.params)
        lines.append(f"wrote {args.write_params}")
    _say(args, "\n".join(lines))
    return 0


def _row(dims: dict, start: dict):
    return np.array([dims.get(k, start.get(k)) for k in GEOMETRY_FIELDS])


# -- the whole wrist ----------------------------------------------------------------------


def _free(items) -> tuple[tuple[str, ...], dict]:
    """``--free NAME`` or ``NAME=LOW,HIGH`` (bounds in the parameter's display unit, as
    `vsj params` shows it) -> names and SI bounds."""
    names, bounds = [], {}
    for item in items:
        name, _, rest = item.partition("=")
        name = name.strip()
        names.append(name)
        if rest:
            section, _, key = name.partition(".")
            spec = SCHEMA.get(section, {}).get(key)
            if spec is None:
                hint = params.did_you_mean(name, [f"{s}.{k}" for s in SCHEMA for k in SCHEMA[s]])
                raise InputError(f"--free {name}: no such parameter{hint}")
            parts = rest.split(",")
            if len(parts) != 2:
                raise InputError(f"--free {item}: bounds are written NAME=LOW,HIGH")
            bounds[name] = tuple(to_si(f"{v.strip()} {spec.display}", spec.unit,
                                       where=f"--free {name}") for v in parts)
    return tuple(names), bounds


def _setup_file(path) -> dict:
    """A small TOML with any of: inputs, outputs, free (lists of names), window, lead
    (seconds as text with units)."""
    try:
        doc = tomllib.loads(read_text(path, "fit set-up file"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    allowed = {"inputs", "outputs", "free"}
    extra = set(doc) - allowed
    if extra:
        raise InputError(f"{path}: unknown key {sorted(extra)[0]!r}; allowed: "
                         f"{', '.join(sorted(allowed))}")
    for key, value in doc.items():
        if not (isinstance(value, list) and all(isinstance(v, str) for v in value)):
            raise InputError(f"{path}: {key} must be a list of names")
    return doc


def _check_pivot(log, params) -> None:
    """Refuse a log whose pivot position leaves the parameter set's pivot range: its
    median (the position a fixed pivot takes), or a sample by more than 1 % of the range
    (beyond a sensor's noise: a column in another unit, or another prototype's log)."""
    if "q" not in log.columns:
        return
    q = np.asarray(log["q"], dtype=float)
    lo, hi = params["pivot.q_min"], params["pivot.q_max"]
    margin = 0.01 * (hi - lo)
    outside = np.flatnonzero((q < lo - margin) | (q > hi + margin))
    median = float(np.median(q))
    if len(outside) or not lo <= median <= hi:
        k = int(outside[0]) if len(outside) else None
        where = (f"line {int(log.lines[k])}: " if k is not None and log.lines is not None
                 else "")
        value = q[k] if k is not None else median
        raise InputError(f"{log.path}: {where}the pivot position q = {value * 1e3:.4g} mm"
                         f"{'' if k is not None else ' (the median)'} is outside the pivot "
                         f"range of the parameter set, [{lo * 1e3:.4g}, {hi * 1e3:.4g}] mm "
                         "(pivot.q_min, q_max); is the q column in the unit its header says?")


def cmd_fit_wrist(args) -> int:
    """``vsj fit wrist``: the assembled wrist's free parameters from logs of its signals by
    output error, with standard errors, validation and a report. Returns the exit code: 0
    (bad input raises `InputError`, which `main` turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import measurements
    from ..identification import wrist_report
    from ..identification.wrist import fit_wrist
    from ..identification.wrist_model import Setup, all_known_columns, check_free

    setup_doc = _setup_file(args.setup) if args.setup else {}
    free_items = list(args.free or []) + list(setup_doc.get("free", []))
    names, bounds = _free(free_items)
    params = _params(args.params)
    check_free(names, params)
    known = all_known_columns()
    logs = [measurements.read_log(f, known) for f in args.logs]
    validate = [measurements.read_log(f, known) for f in (args.validate or [])]
    for log in (*logs, *validate):
        _check_pivot(log, params)
    motors = args.motor_model
    if motors is None:
        motors = "dc" if any(c.startswith("voltage_") or c.endswith(".voltage")
                             for c in logs[0].columns) else "velocity"
    inputs = args.inputs or setup_doc.get("inputs")
    outputs = args.outputs or setup_doc.get("outputs")
    setup = Setup(free=names, wrist=WristOptions(motors=motors, elastic=args.elastic),
                  inputs=tuple(inputs) if inputs else None,
                  outputs=tuple(outputs) if outputs else None,
                  window=to_si(args.window, "s", where="--window"),
                  threads=args.threads, delays=not args.no_delays)
    if not setup.window > 0:
        raise InputError(f"--window {args.window}: must be > 0 s")
    _check_write_params(args)
    out = _out(args)
    with _results(out, "fit wrist") as results:
        fit = fit_wrist(logs, params, setup, bounds=bounds, starts=args.starts,
                        validate=validate, seed=args.seed,
                        progress=lambda text: print(text, file=sys.stderr))
        written = wrist_report.write(fit, results) if results is not None else []
    record = fit.to_json()
    _print_json(args, record)
    lines = [f"{', '.join(fit.files)}: {len(fit.names)} parameters"
             + (" [synthetic data]" if fit.synthetic else "")]
    for e in fit.estimates:
        if e.status == "determined":
            lines.append(f"  {e.name} = {e.value:.6g} +- {e.stderr:.2g} {e.unit}  "
                         f"(95 %: {e.ci95[0]:.5g} .. {e.ci95[1]:.5g})")
        else:
            lines.append(f"  {e.name} = {e.value:.6g} {e.unit}  ({e.status}: no interval)")
    for e in fit.delays:
        lines.append(f"  {e.name} = {e.value * 1e3:.4g} +- {e.stderr * 1e3:.2g} ms (behind the "
                     "inputs)" if e.status == "determined" else
                     f"  {e.name} = {e.value * 1e3:.4g} ms ({e.status})")
    for c in fit.combinations:
        lines.append(f"  not determined by these data: {c}")
    lines += [f"  note: {note}" for note in fit.notes]
    if fit.uncertainty:
        lines.append(f"  standard errors: {fit.uncertainty['description']}")
    lines.append(f"  {fit.reached} of {len(fit.starts)} starts reached the best optimum (same "
                 "cost and end point within the noise)")
    for kind, per in fit.quality.items():
        lines.append(f"  {kind}: " + ", ".join(f"{n} fit {q.fit_percent:.4g} % (NRMSE "
                                                  f"{q.nrmse:.3g})" for n, q in per.items()))
    lines.append(f"  {fit.simulations} window simulations ({fit.simulated_seconds:.4g} s "
                 f"simulated) in {fit.wall_time:.3g} s")
    if out is not None:
        lines.append("wrote " + ", ".join(str(out / n) for n in written))
    if args.write_params:
        overrides = fit.overrides(", ".join(args.logs))
        _write_params(args.write_params, overrides, args.params)
        left = [f"{e.name} ({e.status})" for e in fit.estimates if e.name not in overrides]
        lines.append(f"wrote {args.write_params}" + (
            f"; not written, so it keeps the set's value: {', '.join(left)}; the values "
            "written were fitted with it at its estimate" if left else ""))
    _say(args, "\n".join(lines))
    return 0


def cmd_synth_wrist(args) -> int:
    """``vsj synth wrist``: a synthetic log of the wrist running an experiment file
    (labelled synthetic). Returns the exit code: 0 (bad input raises `InputError`, which
    `main` turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import measurements, synth
    from ..identification import wrist_experiment
    from ..output import SMALL_OUTPUT_BYTES, check_output_file, write_errors

    experiment = wrist_experiment.load(args.experiment)
    check_output_file(args.out, "--out", size=SMALL_OUTPUT_BYTES, force=args.force)
    data = synth.wrist(experiment, _params(args.params), seed=args.seed)
    with write_errors("--out", args.out):
        measurements.write_log(args.out, data.columns, data.comments)
    print(f"wrote {args.out} (synthetic, {len(data.columns['time'][0])} rows)")
    return 0


def cmd_excite(args) -> int:
    """``vsj excite``: design a Ds-optimal excitation for the named parameters within the
    motors' limits and write it as an experiment file. Returns the exit code: 0 (bad
    input raises `InputError`, which `main` turns into 2)."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from ..identification import wrist_experiment
    from ..identification.wrist_model import check_free
    from ..output import SMALL_OUTPUT_BYTES, atomic_write, check_output_file, write_errors

    names, _ = _free(args.free)
    params = _params(args.params)
    check_free(names, params)
    duration = to_si(args.duration, "s", where="--duration")
    if not 1.0 <= duration <= 600.0:
        raise InputError(f"--duration {args.duration}: from 1 s to 600 s")
    max_speed = (to_si(args.max_speed, "rad/s", where="--max-speed") if args.max_speed
                 else None)
    max_motor_torque = (to_si(args.max_motor_torque, "N*m", where="--max-motor-torque")
                        if args.max_motor_torque else None)
    for flag, value in (("--max-speed", max_speed), ("--max-motor-torque", max_motor_torque)):
        if value is not None and not value > 0:
            raise InputError(f"{flag}: must be > 0")
    max_torque = to_si(args.max_torque, "N*m", where="--max-torque")
    if not max_torque >= 0:
        raise InputError(f"--max-torque {args.max_torque}: must be >= 0 N m")
    q = to_si(args.q, "m", where="--q")
    if not params["pivot.q_min"] <= q <= params["pivot.q_max"]:
        raise InputError(f"--q {args.q}: outside the pivot range of the parameter set, "
                         f"[{params['pivot.q_min'] * 100:g}, {params['pivot.q_max'] * 100:g}] cm")
    if args.candidates < 1:
        raise InputError(f"--candidates {args.candidates}: must be a whole number >= 1")
    check_output_file(args.out, "--out", size=SMALL_OUTPUT_BYTES, force=args.force)
    d = wrist_experiment.design(
        params, names, duration, max_speed=max_speed, max_torque=max_torque,
        max_motor_torque=max_motor_torque, q=q, candidates=args.candidates, seed=args.seed,
        progress=lambda text: print(text, file=sys.stderr))
    with write_errors("--out", args.out), atomic_write(Path(args.out)) as handle:
        handle.write(d.experiment.to_toml())
    lim = d.limits
    lines = [f"wrote {args.out}: {d.experiment.description}",
             f"  motor limits: speed {lim.max_speed:.4g} rad/s, torque {lim.max_torque:.4g} N m, "
             f"supply {lim.voltage:.4g} V; the design's peaks: "
             + "; ".join(f"{m} {u['speed']:.4g} rad/s, {u['torque']:.4g} N m, "
                         f"{u['voltage']:.3g} V" for m, u in d.use.items() if m != "worst"),
             f"  log det of the information on the free parameters, delays as nuisance "
             f"(relative units): {d.logdet:.4g}; plain sine {d.reference_logdet:.4g}",
             "  predicted standard errors of a fit (the sensors' and the torque inputs' noise, "
             "the delays a fit estimates; design / plain sine):"]
    for n in names:
        lines.append(f"    {n}: {d.stderr[n]:.3g} / {d.reference_stderr[n]:.3g} (start "
                     f"{params[n]:.4g}, SI)")
    record = {"experiment": args.out, "logdet": d.logdet, "plain_sine_logdet": d.reference_logdet,
              "predicted_stderr": d.stderr, "plain_sine_stderr": d.reference_stderr,
              "max_speed": lim.max_speed, "max_motor_torque": lim.max_torque,
              "voltage_limit": lim.voltage, "max_torque": max_torque,
              "motor_peaks": {m: u for m, u in d.use.items() if m != "worst"},
              "plain_sine_motor_peaks": {m: u for m, u in d.reference_use.items()
                                         if m != "worst"}}
    _print_json(args, record)
    _say(args, "\n".join(lines))
    return 0


def register(sub) -> None:
    """Add ``synth`` and ``fit`` with their sub-commands to an argparse sub-parser set."""
    p = sub.add_parser("synth", help="write synthetic measurement files (labelled synthetic)")
    kinds = p.add_subparsers(dest="kind", required=True)
    f = kinds.add_parser("friction", help="a fixed-sun or fixed-ring torque-velocity curve")
    _force(f)
    f.add_argument("--fixed", choices=("sun", "ring"), required=True)
    source = f.add_mutually_exclusive_group()
    source.add_argument("--report", choices=("old", "second"),
                        help="use the report's fitted constants (fig 4.2-4.5)")
    source.add_argument("--constants", metavar="C1,C2,C3",
                        help="T = c1 w + c2 atan(c3 w) with these constants (SI)")
    source.add_argument("--params", metavar="FILE",
                        help="simulate the bench with this parameter set (default: bundled)")
    f.add_argument("--form", choices=("segments", "points", "sweep"), default="segments")
    f.add_argument("--noise", type=float, default=0.02,
                   help="torque noise sd, relative to the largest torque (default 0.02)")
    f.add_argument("--ripple", type=float, default=0.15,
                   help="angle-dependent ripple rms, relative to the largest torque")
    f.add_argument("--no-angle", action="store_true", help="leave out the angle column")
    f.add_argument("--seed", type=int, default=1)
    f.add_argument("--out", required=True, metavar="FILE")
    f.set_defaults(func=cmd_synth_friction)
    x = kinds.add_parser("wrist", help="a log of the whole wrist running an experiment")
    _force(x)
    x.add_argument("--experiment", required=True, metavar="EXP.toml")
    x.add_argument("--params", metavar="FILE", help="the true parameter set (default bundled)")
    x.add_argument("--seed", type=int, default=1)
    x.add_argument("--out", required=True, metavar="LOG.csv")
    x.set_defaults(func=cmd_synth_wrist)
    s = kinds.add_parser("stiffness", help="torque-deflection curves of the elastic bench")
    _force(s)
    s.add_argument("--q", type=float, action="append", required=True, metavar="CM",
                   help="pivot position in cm (repeat for several curves)")
    s.add_argument("--params", metavar="FILE", help="parameter file (default: bundled)")
    s.add_argument("--model", choices=("geometric", "exponential"), default="geometric")
    s.add_argument("--noise", type=float, default=0.01)
    s.add_argument("--play", type=float, default=None,
                   help="pivot play [rad] (default 0.02 at q <= -1.6 cm, else 0)")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--out", required=True,
                   help="a .csv file for one curve, else a directory")
    s.set_defaults(func=cmd_synth_stiffness)

    p = sub.add_parser("fit", help="fit the report's models to measurement files")
    kinds = p.add_subparsers(dest="kind", required=True)
    f = kinds.add_parser("friction", help="T = c1 w + c2 atan(c3 w) to one curve (eq 4.2)")
    f.add_argument("file")
    f.add_argument("--json", action="store_true", help="print the result as JSON")
    f.add_argument("--out", metavar="DIR", help="write the plot and JSON here")
    f.set_defaults(func=cmd_fit_friction)
    g = kinds.add_parser("planetary", help="the planetary module's parameters from both tests")
    _force(g)
    g.add_argument("--fixed-sun", required=True, metavar="FILE")
    g.add_argument("--fixed-ring", required=True, metavar="FILE")
    g.add_argument("--tooth-ratio", type=float, metavar="X",
                   help="N_S/N_R when known (otherwise fitted)")
    g.add_argument("--significance", type=float, default=1e-3,
                   help="chi-square level below which a model is rejected (default 1e-3)")
    g.add_argument("--json", action="store_true")
    g.add_argument("--out", metavar="DIR", help="write the plot and JSON here")
    g.add_argument("--params", metavar="FILE", help="base parameter set for --write-params")
    g.add_argument("--write-params", metavar="FILE",
                   help="write the base set with the identified planetary parameters")
    g.set_defaults(func=cmd_fit_planetary)
    k = kinds.add_parser("stiffness", help="K per curve and K(q) (eq 4.5) from several curves")
    _force(k)
    k.add_argument("files", nargs="+")
    k.add_argument("--json", action="store_true")
    k.add_argument("--out", metavar="DIR", help="write plots and JSON here")
    k.add_argument("--calibrate-geometry", action="store_true",
                   help="also fit the geometric model's dimensions to the curves")
    k.add_argument("--params", metavar="FILE", help="base parameter set")
    k.add_argument("--write-params", metavar="FILE",
                   help="write the base set with a1..a3 (and the calibrated geometry)")
    k.set_defaults(func=cmd_fit_stiffness)
    w = kinds.add_parser("wrist", help="the assembled wrist's parameters from logs of its "
                                       "signals (output error)")
    w.add_argument("logs", nargs="+", metavar="LOG.csv")
    w.add_argument("--free", action="append", metavar="NAME[=LOW,HIGH]",
                   help="a parameter to identify (section.key; bounds in its display unit); "
                        "repeat for more")
    w.add_argument("--params", metavar="FILE", help="start and fixed values (default bundled)")
    w.add_argument("--inputs", nargs="+", metavar="COLUMN", help="columns that drive the model "
                   "(default: every input channel found)")
    w.add_argument("--outputs", nargs="+", metavar="COLUMN", help="columns compared (default: "
                   "every measured signal the states determine)")
    w.add_argument("--setup", metavar="FILE", help="TOML with inputs, outputs, free")
    w.add_argument("--validate", nargs="+", metavar="LOG.csv", help="held-out logs")
    w.add_argument("--elastic", default="geometric",
                   choices=("geometric", "geometric-report", "exponential"),
                   help="elastic element model (default geometric)")
    w.add_argument("--motor-model", choices=("velocity", "dc"),
                   help="primary motors (default: dc when the log has voltages)")
    w.add_argument("--window", default="5 s", help="window length (default 5 s)")
    w.add_argument("--starts", type=_at_least_one, default=4,
                   help="starting points (default 4)")
    w.add_argument("--no-delays", action="store_true", help="do not estimate each compared "
                   "signal's delay behind the inputs (channels recorded simultaneously)")
    w.add_argument("--seed", type=int, default=0, help="seed of the space-filling starts")
    w.add_argument("--threads", type=_at_least_one,
                   help="engine threads (default: every core)")
    w.add_argument("--json", action="store_true")
    w.add_argument("--out", metavar="DIR", help="write the page, plots and JSON here")
    w.add_argument("--write-params", metavar="FILE",
                   help="write the parameter set with the determined estimates")
    _force(w)
    w.set_defaults(func=cmd_fit_wrist)
    e = sub.add_parser("excite", help="design an excitation of the wrist that makes the named "
                                      "parameters identifiable (Ds-optimal)")
    _force(e)
    e.add_argument("--free", action="append", required=True, metavar="NAME")
    e.add_argument("--duration", required=True, help="e.g. '20 s'")
    e.add_argument("--params", metavar="FILE")
    e.add_argument("--max-speed", help="motor (sun) speed limit (default: half the no-load "
                                       "speed of the parameter set's motors)")
    e.add_argument("--max-motor-torque", help="motor torque limit at the gearhead's output "
                   "(default: the stall torque at the supply voltage); the design also keeps "
                   "each motor on its speed-torque line")
    e.add_argument("--max-torque", default="0.1 N m", help="external torque pulses' height")
    e.add_argument("--q", default="0 cm", help="pivot position (default 0 cm)")
    e.add_argument("--candidates", type=int, default=6)
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--json", action="store_true")
    e.add_argument("--out", required=True, metavar="EXP.toml")
    e.set_defaults(func=cmd_excite)
