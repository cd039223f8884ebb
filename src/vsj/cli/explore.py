"""The ``vsj explore`` command: the joint in the browser (a thin layer over
`vsj.explore`; the page is a Bokeh server application, the optional extra ``explore``)."""

from __future__ import annotations

import sys
from pathlib import Path

from .. import params
from ..errors import InputError


def cmd_explore(args) -> int:
    """``vsj explore``: serve the explorer at ``http://localhost:PORT/`` until interrupted
    (and open it in the browser unless ``--no-browser``). Returns the exit code."""
    if not 1 <= args.port <= 65535:
        raise InputError(f"option --port: a port number in [1, 65535], got {args.port}")
    try:
        # lazy: Bokeh is the optional extra 'explore', needed by this command only
        from ..explore.app import serve
    except ImportError as exc:
        raise InputError(f"vsj explore needs Bokeh ({exc}): pip install 'vsj[explore]'") \
            from None
    from ..explore import Explorer  # lazy: the explorer's model side, for this command

    explorer = Explorer(params.load(args.params))
    out = Path(args.out)
    if out.exists() and not out.is_dir():  # refused now, not at the first export
        raise InputError(f"--out {out}: is not a directory; the explorer writes its exports "
                         "(scenario.toml, params.toml) into a directory")

    def ready(port: int) -> None:
        print(f"vsj explore: serving http://localhost:{port}/ (exports go to {out}); "
              "Ctrl-C stops it", file=sys.stderr, flush=True)

    serve(explorer, port=args.port, out=out, show=not args.no_browser, ready=ready)
    return 0


def register(sub) -> None:
    """Add ``explore`` to the ``vsj`` command's subparsers."""
    p = sub.add_parser(
        "explore", help="the joint in the browser: sliders for the stiffness, references, "
                        "friction, controller and environment, views redrawn on each change",
        description="Serve the explorer (a Bokeh server application; works offline) and "
                    "open it in the browser. Its export button writes scenario.toml and "
                    "params.toml into --out, which 'vsj simulate' runs to the same result.")
    p.add_argument("--params", metavar="FILE", help="parameter set (default: the bundled one)")
    p.add_argument("--port", type=int, default=5006, help="port to serve on (default 5006)")
    p.add_argument("--out", metavar="DIR", default="explore",
                   help="where the export button writes its files (default explore)")
    p.add_argument("--no-browser", action="store_true", help="serve only; open no browser")
    p.set_defaults(func=cmd_explore)
