"""The simulation engine (private): arrays in, trajectories out.

`model.compile_model` turns a network into arrays; `plan.Plan` is what every driver
runs (the arrays, inputs, scheme, duration and initial state), through the binding's
one run function; the C library under ``c/`` (public header ``c/vsj.h``) evaluates
forces and integrates them; `core.Engine` evaluates a model at given instants
(observation, energies). Users call `vsj.simulate`, which drives these.
"""

from .core import (FRICTION_SOLVER, NOT_FINITE, OK, PIVOT_RANGE, STATUS_TEXT, STEP_TOO_SMALL,
                   TOO_MANY_STEPS, Engine)
from .model import EngineModel, Layout, compile_model

__all__ = ["Engine", "EngineModel", "Layout", "compile_model", "STATUS_TEXT", "OK",
           "NOT_FINITE", "PIVOT_RANGE", "TOO_MANY_STEPS", "STEP_TOO_SMALL", "FRICTION_SOLVER"]


def observation_layout(layout: Layout) -> dict[str, slice]:
    """Names of the columns `Engine.observe` writes, as slices."""
    n, s, f, k = layout.n, layout.n_sources, layout.n_frictions, layout.n_springs
    nl, nm = layout.n_loads, layout.n_motors
    sizes = [("x", n), ("v", n), ("current", nm), ("a", n), ("sigma", s), ("u", s), ("ud", s),
             ("q", 1), ("qdot", 1), ("fr_s", f), ("fr_f", f), ("sp_d", k), ("sp_dd", k),
             ("sp_tau", k), ("sp_V", k), ("sp_k", k), ("src_tau", s), ("ld_tau", nl),
             ("ld_w", nl), ("mo_w", nm), ("mo_V", nm)]
    out, start = {}, 0
    for name, size in sizes:
        out[name] = slice(start, start + size)
        start += size
    return out
