"""``vsj design``: multi-objective design optimisation of the elastic element and the VSM
(argument handling and output only; the work is in `vsj.design`)."""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import InputError


def cmd_design(args) -> int:
    """``vsj design SPEC --out DIR``: optimise, and write the Pareto set, its figures and
    page into DIR; with ``--write-params N``, write design N of the Pareto set already
    in DIR as a parameter file. Returns the exit code: 0, 1 if no design is feasible,
    130 if interrupted (the generations done are kept: ``--resume``)."""
    # lazy: pymoo, xarray and matplotlib are for this command only
    from .. import design
    from ..design import optimise, results

    spec = design.load(args.spec)
    out = Path(args.out)
    if args.write_params is not None:
        path = results.write_params(spec, out, args.write_params)
        print(f"wrote {path} (extends the design file's base set; load it with --params; its "
              f"objectives are of the {spec.elastic} elastic model: 'vsj datasheet --params "
              f"{path} --elastic {spec.elastic}' gives them)")
        return 0
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers {args.workers}: must be a whole number >= 1")
    scheduler = None if args.scheduler in (None, "") else args.scheduler
    try:
        outcome = optimise.run(spec, out, resume=args.resume, scheduler=scheduler,
                               workers=args.workers,
                               say=lambda text: print(f"vsj design: {text}", file=sys.stderr))
    except KeyboardInterrupt:
        print(f"vsj: interrupted; the generations done are in {out / optimise.CHECKPOINT}; "
              "run the same command with --resume to go on", file=sys.stderr)
        return 130
    files, feasible = results.write(outcome, out, plots=not args.no_plot)
    evaluated = len(outcome.archive.x)
    print(f"{evaluated} designs evaluated over {outcome.generations} generations "
          f"({outcome.ran} now); {len(outcome.front)} on the Pareto front")
    print(f"wrote {', '.join(str(out / f) for f in files)}")
    if not feasible:
        print(f"vsj: no feasible design: none of the {evaluated} designs evaluated meets "
              f"every constraint ({out / results.PAGE} lists the constraints)",
              file=sys.stderr)
        return 1
    return 0


def register(sub) -> None:
    """Add ``design`` to the ``vsj`` command's subparsers."""
    p = sub.add_parser(
        "design", help="multi-objective design optimisation of the elastic element and the "
                       "VSM (a design file, see vsj.design.spec)",
        description="Vary design parameters within bounds to find the Pareto set of the "
                    "objectives under the constraints of a design file (pymoo NSGA-II or "
                    "NSGA-III); writes pareto.nc, front.png, parallel.png and design.html.")
    p.add_argument("spec", metavar="SPEC.toml", help="the design file")
    p.add_argument("--out", metavar="DIR", required=True, help="output directory")
    p.add_argument("--resume", action="store_true",
                   help="go on from the checkpoint in DIR (the same design file)")
    p.add_argument("--scheduler", metavar="local|ADDRESS",
                   help="evaluate on Dask: 'local' starts a LocalCluster, an address "
                        "(tcp://host:8786) uses a running scheduler (default: every core of "
                        "this machine)")
    p.add_argument("--workers", type=int, metavar="N",
                   help="worker processes on this machine (default: every core)")
    p.add_argument("--write-params", type=int, metavar="INDEX",
                   help="write design INDEX of the Pareto set in DIR as DIR/design-INDEX.toml "
                        "(a parameter file that extends the base set) and stop")
    p.add_argument("--no-plot", action="store_true", help="skip the figures")
    p.set_defaults(func=cmd_design)
