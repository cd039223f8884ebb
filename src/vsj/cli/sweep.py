"""``vsj sweep``: many runs of one scenario (argument handling and output only; the work
is in `vsj.sweep`)."""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import InputError


def cmd_sweep(args) -> int:
    """``vsj sweep``: run a sweep file and write its store, metrics and plots. Returns the
    exit code: 0 (failed runs are reported, not fatal), 1 if the sweep is unfinished or
    every run failed, 130 if interrupted."""
    # lazy: only this command needs these, and every vsj command imports vsj.cli
    from .. import sweep
    from ..sweep.analysis import header

    if args.chunk is not None and args.chunk < 1:
        raise InputError(f"--chunk {args.chunk}: must be a whole number >= 1")
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers {args.workers}: must be a whole number >= 1")
    spec = sweep.with_method(sweep.load(args.spec), args.method)
    scheduler = None if args.scheduler in (None, "") else args.scheduler
    try:
        outcome = sweep.run(spec, Path(args.out), resume=args.resume, scheduler=scheduler,
                            chunk=args.chunk, workers=args.workers,
                            plots=not args.no_plot,
                            announce=lambda text: print(f"vsj sweep: {text}", file=sys.stderr))
    except KeyboardInterrupt:
        if (Path(args.out) / sweep.store.MANIFEST).exists():
            print(f"vsj: interrupted; the finished chunks are in {args.out}; run the same "
                  "command with --resume to do the rest", file=sys.stderr)
        else:  # stopped before it recorded the sweep: nothing to resume
            print(f"vsj: interrupted before the sweep was recorded; nothing was kept in "
                  f"{args.out}: run the same command again", file=sys.stderr)
        return 130
    except sweep.Unfinished as exc:
        print(f"vsj: failed: {exc}", file=sys.stderr)
        return 1
    print(f"{outcome.runs} runs ({outcome.ran} now, {outcome.failed} failed) in "
          f"{outcome.chunks} chunks, {outcome.seconds:.1f} s")
    if outcome.sensitivity:
        head = header(outcome.method)
        print("  ".join(head))
        for row in outcome.sensitivity:
            print("  ".join([row[0], row[1]] + [f"{v:.3g}" for v in row[2:]]))
    print(f"wrote {', '.join(str(Path(args.out) / f) for f in outcome.files)}")
    if outcome.failed:
        print(f"vsj: {outcome.failed} run(s) failed; metrics.csv and sweep.json give each "
              "one's status and message", file=sys.stderr)
    if outcome.failed and outcome.failed == outcome.runs:
        print("vsj: failed: every run of the sweep failed", file=sys.stderr)
        return 1
    return 0


def register(sub) -> None:
    """Add ``sweep`` to an argparse sub-parser set."""
    p = sub.add_parser("sweep", help="many runs of a scenario: grids, Monte Carlo, "
                                     "sensitivity (a sweep file, see vsj.sweep.spec)")
    p.add_argument("spec", metavar="SPEC.toml", help="the sweep file")
    p.add_argument("--out", metavar="DIR", required=True, help="output directory")
    p.add_argument("--resume", action="store_true",
                   help="finish the sweep in DIR: run only the chunks not done yet")
    p.add_argument("--scheduler", metavar="local|ADDRESS",
                   help="run chunks on Dask: 'local' starts a LocalCluster, an address "
                        "(tcp://host:8786) uses a running scheduler (default: every core of "
                        "this machine)")
    p.add_argument("--chunk", type=int, metavar="N", help="runs per chunk (default: runs/16, "
                                                          "at most 256)")
    p.add_argument("--workers", type=int, metavar="N",
                   help="worker processes on this machine (default: every core)")
    p.add_argument("--method", choices=("sobol", "morris"),
                   help="sensitivity analysis (overrides the file's sweep.method)")
    p.add_argument("--no-plot", action="store_true", help="skip the figures")
    p.set_defaults(func=cmd_sweep)
