"""Design optimisation: the elastic element and the VSM as a multi-objective problem.

``vsj design SPEC.toml --out DIR`` varies design parameters of a parameter set
(spring constants, pretension, lever and pulley geometry, end stop, pivot range, the
transmission ratios: any key, within the bounds the design file gives) to find the
designs no other beats in every chosen objective (the Pareto set), under constraints.
`spec` reads the design file, `evaluate` computes a design's objectives and margins
with vsj's models, `optimise` runs pymoo's NSGA-II or NSGA-III over generations whose
designs are evaluated in batches by the sweep's workers (`vsj.sweep.schedulers.Pool`),
checkpointed after each generation, and `results` writes the Pareto set (netCDF), its
page and a chosen design as a parameter file that ``extends`` the base set.
"""

from .evaluate import Problem, evaluate, evaluate_chunk, prototype
from .spec import CONSTRAINTS, OBJECTIVES, DesignSpec, load, loads

__all__ = ["CONSTRAINTS", "DesignSpec", "OBJECTIVES", "Problem", "evaluate", "evaluate_chunk",
           "load", "loads", "prototype"]
