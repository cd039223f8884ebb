"""The optimisation: pymoo's NSGA-II or NSGA-III, one generation at a time, resumable.

The algorithm is driven by pymoo's ask-and-tell interface: each generation's designs
are asked for, evaluated in chunks of ``design.batch`` by the sweep's workers
(`vsj.sweep.schedulers.Pool`: this machine's cores, or Dask), and told back with their
objectives (minimised: larger-is-better ones negated) and constraints (pymoo's
inequality constraints, <= 0 where met: each margin over its scale, negated, and one
that is 1 for a design whose evaluation failed). pymoo's constraint handling then
prefers any feasible design to an infeasible one and the less violating of two
infeasible ones (Deb's rules, in its tournament and survival).

After each generation the whole state (pymoo's algorithm object, which holds its own
random generator seeded from ``design.seed``, and every design evaluated so far) is
pickled to ``DIR/design-checkpoint.pkl`` through a temporary file. A run killed at
any moment resumes from the last generation written and, since each evaluation is a
pure function of the design, reaches the same designs, bit for bit, as a run that was
never stopped. The Pareto set is taken from every design evaluated: the feasible ones
that no other feasible one dominates.
"""

from __future__ import annotations

import json
import math
import pickle
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.algorithms.moo.nsga3 import NSGA3
from pymoo.core.evaluator import Evaluator
from pymoo.core.problem import Problem as PymooProblem
from pymoo.core.termination import NoTermination
from pymoo.operators.selection.tournament import TournamentSelection, compare
from pymoo.problems.static import StaticProblem
from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting
from pymoo.util.ref_dirs import get_reference_directions

from .. import __version__, params as params_module
from ..errors import InputError
from ..output import atomic_write
from ..sweep.schedulers import Pool
from .evaluate import OK, Problem, evaluate_chunk, margins_violation, objective_matrix
from .spec import DesignSpec

CHECKPOINT = "design-checkpoint.pkl"
#: Version of the checkpoint's layout (a file of another is refused).
FORMAT = 1


class _Bounds(PymooProblem):
    """The design space as pymoo sees it: bounds and counts; vsj evaluates the designs."""

    def __init__(self, spec: DesignSpec, n_constraints: int):
        super().__init__(n_var=len(spec.variables), n_obj=len(spec.objectives),
                         n_ieq_constr=n_constraints,
                         xl=np.array([v.lo for v in spec.variables]),
                         xu=np.array([v.hi for v in spec.variables]))


@dataclass
class Archive:
    """Every design evaluated, in order: vectors (SI), rows of `Problem.columns`,
    statuses, messages and the generation (from 0) that asked for each."""

    x: list = field(default_factory=list)
    rows: list = field(default_factory=list)
    status: list = field(default_factory=list)
    messages: list = field(default_factory=list)
    generation: list = field(default_factory=list)

    def arrays(self, problem: Problem):
        """``(x, rows, status, generation)`` as arrays (empty ones with no design)."""
        n, m = len(problem.spec.variables), len(problem.columns)
        return (np.array(self.x).reshape(-1, n), np.array(self.rows).reshape(-1, m),
                np.array(self.status, dtype=np.int64), np.array(self.generation))


@dataclass
class Outcome:
    """What `run` did: the problem, every design evaluated, the indices (into the
    archive) of the Pareto set, the generations run now and in all, the seconds the
    workers spent in the engine."""

    problem: Problem
    archive: Archive
    front: np.ndarray
    generations: int
    ran: int
    engine_seconds: float = 0.0


def problem_for(spec: DesignSpec) -> Problem:
    """The `Problem` of a design file: its base parameter set loaded (the bundled set
    when it names none) as a parameter file that ``extends`` it would load it."""
    if spec.params is None:
        return Problem(spec, params_module.default())
    try:
        base = params_module.loads(f"extends = {json.dumps(spec.params)}", spec.params)
    except InputError as exc:
        raise InputError(f"{spec.origin}: design.params = {spec.params!r}: {exc}") from None
    return Problem(spec, base)


def _nsga3_tournament(pop, P, random_state=None, **kwargs):
    """NSGA-III's tournament (pymoo's ``comp_by_cv_then_random``: the less violating of
    two designs, else either at random) with every draw from the algorithm's random
    generator. pymoo 0.6.2's own leaves the generator out of the tie-break of two
    equally infeasible designs, which then draws from an unseeded one, so two runs with
    one seed differ (pymoo issue 794, fixed after 0.6.2 by pull request 795); and its
    decorator leaves it a local function, which the checkpoint cannot pickle."""
    winners = np.empty(len(P), dtype=int)
    for i, (a, b) in enumerate(P[:, :2]):
        if pop[a].CV > 0.0 or pop[b].CV > 0.0:
            winners[i] = compare(a, pop[a].CV, b, pop[b].CV, method="smaller_is_better",
                                 return_random_if_equal=True, random_state=random_state)
        else:
            winners[i] = random_state.choice([a, b])
    return winners[:, None]


def algorithm_for(spec: DesignSpec, n_constraints: int):
    """pymoo's algorithm for the design file, set up (its random generator seeded)."""
    if spec.algorithm == "nsga3":
        partitions = 1
        while math.comb(len(spec.objectives) + partitions, partitions + 1) <= spec.population:
            partitions += 1
        directions = get_reference_directions("das-dennis", len(spec.objectives),
                                              n_partitions=partitions)
        algorithm = NSGA3(directions, pop_size=spec.population, seed=spec.seed,
                          selection=TournamentSelection(func_comp=_nsga3_tournament))
    else:
        algorithm = NSGA2(pop_size=spec.population, seed=spec.seed)
    algorithm.setup(_Bounds(spec, n_constraints), termination=NoTermination())
    return algorithm


def _read_checkpoint(path: Path, spec: DesignSpec) -> dict:
    try:
        with open(path, "rb") as handle:
            state = pickle.load(handle)
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError) as exc:
        raise InputError(f"--resume: {path}: cannot read the checkpoint ({exc}); start a new "
                         "directory") from None
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise InputError(f"--resume: {path}: not a checkpoint of this vsj (format "
                         f"{FORMAT}); start a new directory")
    if state["spec"] != spec.sha256():
        raise InputError(f"--resume: {path}: the checkpoint is of another design file (its "
                         f"text differs from {spec.origin}); use that file, or start a new "
                         "directory")
    return state


def run(spec: DesignSpec, out: str | Path, *, resume: bool = False,
        scheduler: str | None = None, workers: int | None = None, say=None) -> Outcome:
    """Optimise ``spec`` with its checkpoint in ``out`` (see the module docstring);
    ``resume`` goes on from the checkpoint there. ``say(text)``, if given, is told of
    each generation."""
    problem = problem_for(spec)
    out = Path(out)
    path = out / CHECKPOINT
    say = say or (lambda text: None)
    if resume:
        if not path.exists():
            raise InputError(f"--resume: {out} holds no {CHECKPOINT}: nothing to resume; run "
                             "without --resume")
        state = _read_checkpoint(path, spec)
        algorithm, archive, done = state["algorithm"], state["archive"], state["generation"]
    else:
        if path.exists():
            raise InputError(f"--out {out}: holds an optimisation ({CHECKPOINT}); finish it "
                             "with --resume, or choose another directory")
        n_g = sum(c.role == "margin" for c in problem.columns) + 1
        algorithm, archive, done = algorithm_for(spec, n_g), Archive(), 0
    ran, engine = 0, 0.0
    if done < spec.generations:
        with Pool(scheduler, workers) as pool:
            while done < spec.generations:
                population = algorithm.ask()
                x = population.get("X")
                start = len(archive.x)
                chunks = [(i, start + a, x[a:a + spec.batch])
                          for i, a in enumerate(range(0, len(x), spec.batch))]
                results = pool.run(evaluate_chunk, problem, chunks)
                rows = np.concatenate([r.metrics for r in results])
                status = np.concatenate([r.status for r in results])
                engine += sum(r.kernel_time for r in results)
                F = objective_matrix(problem, rows)
                F = np.where(np.isfinite(F), F, np.inf)
                G = margins_violation(problem, rows, status)
                Evaluator().eval(StaticProblem(algorithm.problem, F=F, G=G), population)
                algorithm.tell(infills=population)
                archive.x.extend(x.tolist())
                archive.rows.extend(rows.tolist())
                archive.status.extend(status.tolist())
                archive.messages.extend(m for r in results for m in r.messages)
                archive.generation.extend([done] * len(x))
                done += 1
                ran += 1
                with atomic_write(path, "wb") as handle:
                    pickle.dump({"format": FORMAT, "spec": spec.sha256(),
                                 "vsj_version": __version__, "generation": done,
                                 "algorithm": algorithm, "archive": archive}, handle,
                                protocol=pickle.HIGHEST_PROTOCOL)
                feasible = int(np.count_nonzero(np.all(G <= 0.0, axis=1)))
                say(f"generation {done}/{spec.generations}: {len(x)} designs, {feasible} "
                    "feasible")
    return Outcome(problem, archive, pareto(problem, archive), done, ran, engine)


def pareto(problem: Problem, archive: Archive) -> np.ndarray:
    """Indices into ``archive`` of its Pareto set: the feasible designs (every margin
    >= 0, evaluated) that no other feasible design dominates, each design vector once,
    in the order of the first objective (as the optimiser minimises it)."""
    x, rows, status, _ = archive.arrays(problem)
    if not len(x):
        return np.zeros(0, dtype=int)
    G = margins_violation(problem, rows, status)
    feasible = np.flatnonzero(np.all(G <= 0.0, axis=1) & (status == OK))
    if not len(feasible):
        return np.zeros(0, dtype=int)
    F = objective_matrix(problem, rows[feasible])
    first = feasible[NonDominatedSorting().do(F, only_non_dominated_front=True)]
    _, unique = np.unique(x[first], axis=0, return_index=True)
    first = first[np.sort(unique)]
    order = np.lexsort(objective_matrix(problem, rows[first]).T[::-1])
    return first[order]
