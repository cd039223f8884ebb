"""The ``vsj`` command: a thin layer over the library (no physics here).

Exit codes: 0 success, 1 a simulation or fit failed, 2 bad input.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import asdict
from pathlib import Path

from .. import __version__, params
from ..errors import InputError, SimulationError
from ..simulate import Result, catalogue, sample_times
from ..simulate.driver import sample_count
from ..units import to_si
from . import control, design, explore, fit, study, sweep


def _params(path: str | None):
    return params.load(path)


def cmd_params(args) -> int:
    """``vsj params``: print a parameter set (value, unit, description, source per key), or
    with ``--check`` validate a file. Returns the exit code (0)."""
    if args.check and args.file and args.check != args.file:
        raise InputError(f"vsj params: give one file, either to print ({args.file}) or to "
                         f"--check ({args.check}), not both")
    params = _params(args.check or args.file)
    if args.check:
        print(f"{args.check}: ok ({len(params.values)} parameters, hash {params.hash()[:12]})")
        return 0
    print(f"# parameter set: {params.meta.get('name', params.origin)} ({params.origin})")
    print(f"# hash {params.hash()}")
    rows = params.describe()
    width = max(len(r[0]) for r in rows)
    vwidth = max(len(r[1]) for r in rows)
    for key, value, source, description in rows:
        print(f"{key:<{width}}  {value:>{vwidth}}  {description}; {source}")
    return 0


def cmd_simulate(args) -> int:
    """``vsj simulate``: run every case of a scenario and write trajectory.nc and meta.json
    (trajectory.csv, trajectory.png on request) as one result set. Returns the exit code:
    0, or 1 if a case failed."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import scenario as scenarios
    from ..output import (ResultSet, TrajectoryFile, parameters_record, trajectory_bytes,
                          write_meta, write_trajectory_csv)

    params = _params(args.params)
    scen = scenarios.load(args.scenario)
    prepared = [scenarios.prepare_case(scen, case, params, in_memory=False)
                for case in scen.cases]
    grids = {(c.duration, c.options.output_step) for c in scen.cases}
    if len(grids) > 1:
        raise InputError(f"{scen.origin}: all cases must share duration and output_step so "
                         "that they fit one trajectory file")
    (duration, output_step), = grids
    tables = [catalogue(p.structure, ports=True, controller=p.plan.controller)
              for p in prepared]
    # the size from the sample count: a grid too large for the disk is refused before
    # it is made
    size = trajectory_bytes(sample_count(duration, output_step),
                            len({s.name for t in tables for s in t}), len(scen.cases),
                            csv=args.csv, plot=args.plot)
    out = Path(args.out)
    runs, records = [], []
    with ResultSet(out, "simulate", size=size) as results:
        time = sample_times(duration, output_step)
        with results.write("trajectory.nc", "w+b") as handle:
            trajectory = TrajectoryFile(handle, [c.label for c in scen.cases], time, tables)
            sinks = [trajectory.case(k) for k in range(len(prepared))]
            ran = scenarios.run_cases(prepared, sinks=sinks, label=f"simulate {scen.name}")
            for k, (case, result) in enumerate(zip(prepared, ran)):
                trajectory.success[k] = int(result.success)
                runs.append((case.case.label, result))
                records.append({"label": case.case.label, "success": result.success,
                                "message": result.message, "solver": result.solver,
                                "ledger": result.ledger,
                                "stick_slip_transitions": result.transitions,
                                "warnings": list(result.warnings),
                                "parameters_hash": case.params.hash(),
                                "parameter_overrides": dict(case.case.params)})
                if any(f.contact is not None for f in case.structure.frictions):
                    records[-1]["safety"] = _safety(trajectory, k, case)
                    if not result.success:  # the figures of the part it ran
                        reached = trajectory.reached[k]
                        records[-1]["safety_until"] = \
                            float(trajectory.time[reached - 1]) if reached else 0.0
            trajectory.close()
            if args.csv:
                write_trajectory_csv(results.path("trajectory.csv"), trajectory)
            if args.plot:
                from ..plots import trajectory_file_figure  # lazy: only --plot draws

                trajectory_file_figure(trajectory, scen.cases[0].network,
                                       results.path("trajectory.png"),
                                       title=f"{scen.name}: {scen.description}")
        ok = all(r.success for _, r in runs)
        write_meta(results.path("meta.json"), {
            "scenario": {"name": scen.name, "description": scen.description,
                         "origin": scen.origin, "definition": dict(scen.table)},
            "parameters": parameters_record(params), "success": ok, "cases": records,
            "files": results.hashes()})
    for (label, result), record in zip(runs, records):
        prefix = f"[{label}] " if len(runs) > 1 else ""
        print(prefix + result.summary().replace("\n", "\n" + prefix))
        if "safety" in record:
            from ..safety.run_report import summary  # lazy: only runs with contacts

            for line in summary(record["safety"], record.get("safety_until")):
                print(prefix + line)
    print(f"wrote {', '.join(str(out / name) for name in results.written)}")
    _print_warnings(runs)
    if not ok:
        failed = [f"{label}: {r.message}" for label, r in runs if not r.success]
        print("simulation failed:\n  " + "\n  ".join(failed), file=sys.stderr)
        return 1
    return 0


def _print_warnings(runs) -> None:
    """Each run's warnings on stderr, labelled with its case; a warning every case of
    several gives (a parameter its model does not read, say) once, for them all."""
    shared = set.intersection(*(set(r.warnings) for _, r in runs)) if len(runs) > 1 else set()
    for text in dict.fromkeys(t for _, r in runs for t in r.warnings if t in shared):
        print(f"vsj: warning: [every case] {text}", file=sys.stderr)
    for label, result in runs:
        for text in result.warnings:
            if text not in shared:
                print(f"vsj: warning: [{label}] {text}", file=sys.stderr)


def _safety(trajectory, k: int, case) -> dict:
    """The safety figures (`vsj.safety.run_report`) of case ``k`` (a prepared case) of a
    streamed trajectory (with its environment's tip geometry): its contact, spring and
    speed signals read back from the file, the contacts sampled again from its plan where
    the file's samples could miss them."""
    from ..safety.run_report import reads, report  # lazy: only runs with contacts need it

    reached = trajectory.reached[k]
    wanted = reads(case.structure, trajectory.names(k))
    signals = {name: trajectory.read(name, k, 0, reached) for name in wanted}
    run = Result(time=trajectory.time[:reached], signals=signals, units={}, ledger={},
                 success=True, message="", solver={})
    environment = case.case.environment
    return report(run, case.structure, None if environment is None else environment.tip,
                  plan=case.plan)


def cmd_scenarios(args) -> int:
    """``vsj scenarios``: list the built-in scenarios with their descriptions. Returns the
    exit code (0)."""
    # lazy: only this command needs it, and every vsj command imports vsj.cli
    from .. import scenario as scenarios

    for name in scenarios.builtin_names():
        scen = scenarios.load(name)
        print(f"{name:<24} {scen.description}")
    return 0


def cmd_reproduce(args) -> int:
    """``vsj reproduce``: regenerate the report's figures, report.html and results.json.
    Returns the exit code: 0, or 1 if a figure failed."""
    # lazy: only this command needs it, and every vsj command imports vsj.cli
    from ..reproduce import run

    params = _params(args.params)
    start = time.perf_counter()
    result = run(Path(args.out), params, reduced=args.reduced, only=args.only)
    for o in result.outcomes:
        status = "ok" if o.error is None else f"FAILED: {o.error}"
        print(f"{o.name:<9} {status}")
    print(result.headline_text())
    print(f"wrote {len(result.outcomes) - len(result.failed)} figures, "
          f"{Path(args.out) / 'report.html'} and {Path(args.out) / 'results.json'} in "
          f"{time.perf_counter() - start:.0f} s")
    if result.failed:
        for o in result.failed:
            print(f"vsj: {o.name} failed:\n{o.traceback}" if o.traceback else
                  f"vsj: {o.name} failed: {o.error}", file=sys.stderr)
        return 1
    return 0


def cmd_verify(args) -> int:
    """``vsj verify``: check an output directory (result sets or a sweep) against its
    manifest. Returns the exit code: 0 if complete, 1 if not."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from ..output import MANIFEST, read_manifest, verify
    from ..sweep import store

    directory = Path(args.dir)
    if not directory.is_dir():
        raise InputError(f"{directory}: not a directory")
    sweep = os.path.lexists(directory / store.MANIFEST)
    if sweep and not os.path.lexists(directory / MANIFEST):
        problems = store.verify(directory)
    else:
        problems = verify(directory)
        if problems == [f"{directory}: no {MANIFEST}"]:
            problems = [f"{directory}: no {MANIFEST} (result sets) or {store.MANIFEST} "
                        "(a sweep): not an output directory of vsj"]
    if problems:
        print(f"{directory}:\n  " + "\n  ".join(problems), file=sys.stderr)
        return 1
    if sweep and not os.path.lexists(directory / MANIFEST):
        record = store.read_manifest(directory, "")
        print(f"{directory}: a complete sweep of {record['runs']} runs: its "
              f"{record['chunks']} chunks and {len(record['files'])} files as "
              f"{store.MANIFEST} records them")
        return 0
    sets = read_manifest(directory)["sets"]
    files = sum(len(entry["files"]) for entry in sets.values())
    print(f"{directory}: {len(sets)} result set(s), {files} files as {MANIFEST} records them")
    return 0


def cmd_msl(args) -> int:
    """``vsj msl``: rebuild a Modelica Standard Library example, simulate it with the
    time-stepper and compare it with the MSL reference result. Returns the exit code: 0,
    or 1 if it leaves the reference's tube or stick/slip intervals."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import msl
    from ..output import ResultSet, cases_dataset, write_dataset, write_meta

    if args.example not in msl.EXAMPLES:
        raise InputError(f"msl: unknown example {args.example!r}; allowed: "
                         f"{', '.join(msl.EXAMPLES)}")
    step = to_si(args.step, "s", where="--step")
    if not 1e-6 <= step <= 1e-2:
        raise InputError(f"--step: {args.step} is outside the allowed 1 us to 10 ms")
    example = msl.EXAMPLES[args.example]()
    reference = msl.reference(example)
    result = example.simulate(step)
    if not result.success:
        raise SimulationError(f"{example.name}: {result.message}")
    outcome = msl.check(example, result, reference)
    out = Path(args.out)
    stem = f"msl-{example.name}"
    with ResultSet(out, "msl", name=stem) as results:
        write_dataset(results.path(f"{stem}.nc"), cases_dataset([(example.name, result)]))
        if not args.no_plot:
            msl.figure(example, result, reference, outcome, results.path(f"{stem}.png"))
        write_meta(results.path(f"{stem}.json"), {
            "example": example.name, "model": example.model, "step": step,
            "reference": example.reference_file, "passed": outcome.passed,
            "tubes": [asdict(t) for t in outcome.tubes], "modes": outcome.modes,
            "files": results.hashes()})
    print(f"{example.model}, {example.duration:g} s at {step * 1e3:g} ms steps, against "
          f"the MSL reference:")
    print(outcome.summary())
    print(f"wrote {', '.join(str(out / name) for name in results.written)}")
    if not outcome.passed:
        print(f"{example.name}: outside the MSL reference's tube or stick/slip intervals",
              file=sys.stderr)
        return 1
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``vsj`` command with all its subcommands; each subcommand
    sets ``func`` to the function that runs it."""
    parser = argparse.ArgumentParser(
        prog="vsj", description="Model, simulate and characterise the 2-DOF variable "
                                "stiffness joint.")
    parser.add_argument("--version", action="version", version=f"vsj {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("params", help="print a parameter set with units and sources, or check "
                                      "a parameter file")
    p.add_argument("file", nargs="?", help="parameter file (default: the bundled set)")
    p.add_argument("--check", metavar="FILE", help="validate FILE; exit 0 if valid, 2 if not")
    p.set_defaults(func=cmd_params)

    p = sub.add_parser("simulate", help="run a scenario (built-in name or TOML file)")
    p.add_argument("scenario", help="built-in scenario name (see 'vsj scenarios') or a file")
    p.add_argument("--params", metavar="FILE", help="parameter file (default: bundled set)")
    p.add_argument("--out", metavar="DIR", default="out", help="output directory (default out)")
    p.add_argument("--plot", action="store_true",
                   help="also draw trajectory.png (off by default: matplotlib more than "
                        "doubles the command's time)")
    p.add_argument("--no-plot", action="store_false", dest="plot",
                   help="no PNG (the default; kept for scripts written before --plot)")
    p.add_argument("--csv", action="store_true",
                   help="also write trajectory.csv (a spreadsheet's format; slower to write)")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("scenarios", help="list the built-in scenarios")
    p.set_defaults(func=cmd_scenarios)

    p = sub.add_parser("reproduce", help="regenerate every figure of the report with the "
                                         "report's numbers beside vsj's")
    p.add_argument("--out", metavar="DIR", default="reproduction",
                   help="output directory (default reproduction)")
    p.add_argument("--params", metavar="FILE", help="parameter file (default: bundled set)")
    p.add_argument("--reduced", action="store_true",
                   help="cheaper runs (fewer cases, shorter simulations), same figures and rows")
    p.add_argument("--only", nargs="+", metavar="FIG", help="only these figures (fig-4.13 ...)")
    p.set_defaults(func=cmd_reproduce)

    p = sub.add_parser("verify", help="check that an output directory holds complete result "
                                      "sets or a complete sweep, every file as its manifest "
                                      "records it and no other")
    p.add_argument("dir", metavar="DIR", help="an output directory of vsj")
    p.set_defaults(func=cmd_verify)

    p = sub.add_parser("msl", help="rebuild a Modelica Standard Library drive train and "
                                   "compare it with the MSL's published reference result")
    p.add_argument("example", metavar="EXAMPLE", help="friction or coupled-clutches")
    p.add_argument("--step", default="1 ms", help="time-stepper step (default 1 ms)")
    p.add_argument("--out", metavar="DIR", default="msl", help="output directory (default msl)")
    p.add_argument("--no-plot", action="store_true", help="skip the PNG")
    p.set_defaults(func=cmd_msl)

    fit.register(sub)
    control.register(sub)
    sweep.register(sub)
    study.register(sub)
    design.register(sub)
    explore.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``vsj`` command with ``argv`` (default: the process's arguments). Returns the
    exit code: 0 success, 1 a simulation or fit failed, 2 bad input, 130 interrupted, 141
    the reader of its output went away (``vsj params | head``: SIGPIPE's code)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except InputError as exc:
        print(f"vsj: error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"vsj: failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("vsj: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # what is left for standard output goes nowhere, so that flushing it at exit
        # raises no second error; whatever the command wrote to files is complete
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141


if __name__ == "__main__":
    sys.exit(main())
