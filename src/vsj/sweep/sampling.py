"""The runs of a sweep: grids, lists, truncated distributions, designs, covariances.

Every draw is made here, once, on the machine that starts the sweep, from the
spec's seed; workers receive the values. So the runs do not depend on how they
are spread over workers, and ``--resume`` draws the same values again (checked
against those stored).

Sampled parameters are drawn in the unit cube first (`unit_design`: NumPy's
``default_rng(seed)``, ``scipy.stats.qmc`` Latin hypercube or scrambled Sobol
points, or SALib's Saltelli and Morris designs), then mapped through the
inverse distribution function of each parameter, truncated to its allowed
range (`to_values`). The same two functions serve `sensitivity_problem` for any
function of the inputs, such as the Ishigami test function.
"""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np

from ..errors import InputError
from .spec import Covariance, Distribution, SweepSpec

#: Morris grid levels (SALib's default is 4).
MORRIS_LEVELS = 4


def unit_design(kind: str, method: str | None, samples: int, dimensions: int,
                seed: int) -> np.ndarray:
    """``(runs, dimensions)`` points in [0, 1): ``kind`` random | lhs | sobol, or the
    design a sensitivity ``method`` (sobol | morris) needs."""
    if method == "sobol":
        # lazy: SALib is heavy; only sensitivity designs
        from SALib.sample import sobol as saltelli

        with warnings.catch_warnings():  # SALib warns when samples is not a power of 2
            warnings.simplefilter("ignore")
            return saltelli.sample(_unit_problem(dimensions), samples, calc_second_order=False,
                                   scramble=True, seed=seed)
    if method == "morris":
        from SALib.sample import morris  # lazy: SALib is heavy; only sensitivity designs

        levels = morris.sample(_unit_problem(dimensions), samples, num_levels=MORRIS_LEVELS,
                               seed=seed)
        # the levels 0 and 1 are the ends of an unbounded distribution: take the
        # centres of MORRIS_LEVELS equally likely bins instead
        return (levels * (MORRIS_LEVELS - 1) + 0.5) / MORRIS_LEVELS
    rng = np.random.default_rng(seed)
    if kind == "random":
        return rng.random((samples, dimensions))
    from scipy.stats import qmc  # lazy: heavy; grid sweeps need none

    if kind == "lhs":
        return qmc.LatinHypercube(d=dimensions, seed=rng).random(samples)
    with warnings.catch_warnings():  # balance properties need a power of 2; not required
        warnings.simplefilter("ignore")
        return qmc.Sobol(d=dimensions, scramble=True, seed=rng).random(samples)


def _unit_problem(dimensions: int) -> dict:
    return {"num_vars": dimensions, "names": [f"x{i}" for i in range(dimensions)],
            "bounds": [[0.0, 1.0]] * dimensions}


def to_values(unit: np.ndarray, distributions: tuple[Distribution, ...]) -> np.ndarray:
    """Map unit-cube points through each distribution's truncated inverse CDF (SI)."""
    from scipy import stats  # lazy: heavy; grid sweeps need none

    out = np.empty_like(unit, dtype=float)
    for j, d in enumerate(distributions):
        u = unit[:, j]
        a = d.arguments
        if d.kind == "uniform":
            out[:, j] = a["low"] + u * (a["high"] - a["low"])
        elif d.kind == "normal":
            lo, hi = ((d.lo - a["mean"]) / a["sd"], (d.hi - a["mean"]) / a["sd"])
            out[:, j] = stats.truncnorm.ppf(u, lo, hi, loc=a["mean"], scale=a["sd"])
        else:
            mu, s = math.log(a["median"]), a["sigma"]
            lo = (math.log(d.lo) - mu) / s if d.lo > 0 else -math.inf
            hi = (math.log(d.hi) - mu) / s if math.isfinite(d.hi) else math.inf
            out[:, j] = np.exp(stats.truncnorm.ppf(u, lo, hi, loc=mu, scale=s))
        out[:, j] = np.clip(out[:, j], d.lo, d.hi)  # the inverse CDF's rounding at the ends
    return out


def covariance_draws(cov: Covariance, samples: int, seed: int) -> np.ndarray:
    """``samples`` draws of a multivariate normal truncated to every parameter's
    allowed range (by rejection: a draw with any value outside is drawn again)."""
    rng = np.random.default_rng([seed, 1])  # a stream of its own, apart from the design's
    mean = np.array(cov.mean)
    matrix = np.array(cov.matrix)
    lo = np.array([b[0] for b in cov.bounds])
    hi = np.array([b[1] for b in cov.bounds])
    out = np.empty((samples, len(mean)))
    filled, tries = 0, 0
    while filled < samples:
        batch = rng.multivariate_normal(mean, matrix, size=max(16, samples - filled),
                                        method="cholesky" if _positive(matrix) else "eigh")
        inside = batch[np.all((batch >= lo) & (batch <= hi), axis=1)]
        take = inside[:samples - filled]
        out[filled:filled + len(take)] = take
        filled += len(take)
        tries += len(batch)
        if tries > 1000 * samples + 10_000:
            raise InputError(f"{cov.origin}: fewer than 1 in 1000 draws of the covariance "
                             "fall inside the parameters' allowed ranges; check the values")
    return out


def _positive(matrix: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(matrix)
        return True
    except np.linalg.LinAlgError:
        return False


def design(spec: SweepSpec) -> tuple[np.ndarray, np.ndarray | None]:
    """Every run's values of the varied quantities (runs, len(spec.varied)), SI, and the
    unit-cube points of the sampled ones (for Morris analysis; None without them).

    The factorial of grids and lists is the outer loop (its first name slowest);
    the samples are the inner one.
    """
    points = list(itertools.product(*(f.values for f in spec.fixed)))
    grid = np.array(points, dtype=float).reshape(len(points), len(spec.fixed))
    d = len(spec.sampled)
    unit = None
    parts = []
    if d:
        unit = unit_design(spec.design, spec.method, spec.samples, d, spec.seed)
        parts.append(to_values(unit, spec.sampled))
    if spec.covariance is not None:
        parts.append(covariance_draws(spec.covariance, spec.samples, spec.seed))
    if not parts:
        return grid, None
    sampled = np.hstack(parts)
    runs = np.hstack([np.repeat(grid, len(sampled), axis=0),
                      np.tile(sampled, (len(grid), 1))])
    if unit is not None:
        unit = np.tile(unit, (len(grid), 1))
    return runs, unit


def sensitivity_problem(distributions: tuple[Distribution, ...]) -> dict:
    """SALib's problem for independent inputs, described in the unit cube."""
    problem = _unit_problem(len(distributions))
    problem["names"] = [d.name for d in distributions]
    return problem
