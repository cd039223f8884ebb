"""The ``vsj study`` command: the model studies that go beyond the report (a thin layer
over `vsj.safety.tradeoff`), each writing its figure, its numbers and a page."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from .. import params
from ..errors import InputError
from ..output import SMALL_OUTPUT_BYTES, ResultSet
from ..units import to_si

#: The studies, by name: what each shows.
STUDIES = {
    "tracking-safety": "fig 4.15's tracking lag in closed loop against the peak force of a "
                       "collision with a hand surrogate, over the stiffness setting",
    "impact-speed": "the largest impact speed within ISO/TS 15066's transient force for the "
                    "hand and the lower arm, over the stiffness setting, against a rigid joint",
    "safe-and-fast": "the minimum time of a theta_x motion while a collision at any instant "
                     "stays within the hand's force bound: rigid, stiffest, best fixed "
                     "setting and an optimised stiffness schedule (a few minutes)",
    "explosive-motion": "the largest theta_x speed over the motors' speed limit, with the "
                        "voltage and the stiffness setting optimised (a few minutes)",
}
#: The studies run by optimisation (`vsj.studies`), by their names there; they take no
#: pivot positions.
OPTIMISED = {"safe-and-fast": "study-safe-and-fast",
             "explosive-motion": "study-explosive-motion"}


def _positions(text: str | None, lo: float, hi: float, count: int) -> list[float]:
    if text is None:
        return [float(q) for q in np.linspace(lo, hi, count)]
    values = [to_si(part.strip(), "m", where="option --q") for part in text.split(",")
              if part.strip()]
    if not values:
        raise InputError("option --q: give pivot positions with units, e.g. --q=-2cm,0cm,2cm")
    return values


def cmd_study(args) -> int:
    """``vsj study NAME``: run a study and write ``NAME.png``, ``NAME.json`` and
    ``NAME.html`` into ``--out`` as one result set (`vsj.output.ResultSet`). Returns the
    exit code."""
    if args.name not in STUDIES:
        raise InputError(f"unknown study {args.name!r}; studies: {', '.join(STUDIES)}")
    p = params.load(args.params)
    if args.name in OPTIMISED:
        return _optimised(args, p)
    if args.settings < 2:
        raise InputError(f"option --settings: at least 2, got {args.settings}")
    quick = dict(fade_in=1.0, duration=5.0) if args.quick else {}
    from ..wrist import WristOptions, build_wrist  # lazy: the wrist for its pivot range

    pivot = build_wrist(p, WristOptions(motors="dc", pivot_drive="dc")).assemble().pivot
    qs = _positions(args.q, pivot.q_min, pivot.q_max, args.settings)
    out = Path(args.out)
    with ResultSet(out, "study", name=f"study {args.name}", size=SMALL_OUTPUT_BYTES) as results:
        result, module = _run(args, p, qs, quick)
        png = results.path(f"{args.name}.png")
        module.figure(result, png)
        with results.write(f"{args.name}.json", "w") as handle:
            json.dump(result.as_dict(), handle, indent=1)
        with results.write(f"{args.name}.html", "w") as handle:
            handle.write(module.page(result, png.read_bytes()))
    print(result.summary())
    print(f"wrote {', '.join(str(out / name) for name in results.written)}")
    return 0


def _run(args, p, qs, quick):
    """Run the fixed-setting study `args.name`: (its result, the module that draws it)."""
    # lazy: the studies' modules (and the controllers, the environment) are for this command
    from ..safety import impact, tradeoff

    print(f"vsj study {args.name}: {len(qs)} stiffness settings", file=sys.stderr)
    if args.name == "tracking-safety":
        module = tradeoff
        result = tradeoff.run(p, qs, tradeoff.Setup(**quick), progress=lambda k: print(
            f"  q = {100 * qs[k]:.2f} cm done", file=sys.stderr))
    else:
        module = impact
        result = impact.run(p, qs, progress=lambda name: print(f"  {name} done",
                                                                file=sys.stderr))
    return result, module


def _optimised(args, p) -> int:
    """Run one of the `OPTIMISED` studies and write its PNG, SVG, JSON and page."""
    if args.q is not None:
        raise InputError(f"option --q: study {args.name} chooses its own stiffness settings")
    # lazy: the optimisation studies load SciPy's optimisers and the reproduction's figures
    from ..reproduce.base import Context
    from ..studies import STUDIES as RUNS, write

    out = Path(args.out)
    with ResultSet(out, "study", name=f"study {args.name}", size=SMALL_OUTPUT_BYTES) as results:
        print(f"vsj study {args.name}: optimising{' (reduced)' if args.quick else ''}",
              file=sys.stderr)
        figure = RUNS[OPTIMISED[args.name]](Context(params=p, reduced=args.quick))
        # `write` names its four files after the figure: each is a file of this set
        staging = {results.path(f"{figure.name}.{ext}").parent
                   for ext in ("png", "svg", "json", "html")}
        write(figure, staging.pop())
    print(figure.caption)
    print(f"wrote {', '.join(str(out / name) for name in results.written)}")
    return 0


def register(sub) -> None:
    """Add ``study`` to the ``vsj`` command's subparsers."""
    p = sub.add_parser(
        "study", help="model studies beyond the report (safety against tracking, ...)",
        description="Run a model study and write its figure, numbers (JSON) and page. "
                    "Studies: " + "; ".join(f"{k}: {v}" for k, v in STUDIES.items()))
    p.add_argument("name", metavar="STUDY", help=f"one of {', '.join(STUDIES)}")
    p.add_argument("--params", metavar="FILE", help="parameter set (default: the bundled one)")
    p.add_argument("--out", default="study", metavar="DIR", help="output directory")
    p.add_argument("--q", metavar="LENGTHS",
                   help="pivot positions, comma separated with units (default: --settings "
                        "evenly over the pivot's range)")
    p.add_argument("--settings", type=int, default=7, metavar="N",
                   help="number of stiffness settings over the pivot's range (default 7)")
    p.add_argument("--quick", action="store_true",
                   help="shorter runs (one turn less of the circle; a smaller problem for "
                        "the optimised studies)")
    p.set_defaults(func=cmd_study)
