"""The whole wrist identified from its own signals (output error).

`fit_wrist` finds the free parameters that make the simulated wrist
(`vsj.identification.wrist_model.WristModel`: windows restarted from the
measured state, one batch of the C engine per evaluation) reproduce measured
signals, weighted by each signal's noise:

1. **Noise.** Each compared signal's noise is first estimated from the data
   (second differences), then, after the smooth-law fit, from that signal's
   residuals, so that a signal with a model error the noise cannot explain does
   not dominate.
2. **Starts.** The given start and a space-filling design (a Latin hypercube in
   the logarithms of the bounds) are each fitted with a smooth friction law
   on part of the windows; the command reports how many starts
   reached the best optimum (`SAME_OPTIMUM`: the same cost and the same point, to
   within the noise).
3. **Smooth, then true stiction.** The best start is refined on every window
   with the smooth law, then with true stiction (the time-stepper's exact
   Coulomb impulses), which is how the wrist behaves. The smooth law is the
   arctan law (report eq 3.17) with the parameter set's sharpness. Its optimum
   lies some way from the stiction one (the arctan law creeps under loads that
   stiction holds), but its cost is smooth in the parameters, so starts far apart
   reach the same optimum. The slope law (`vsj.friction`), closer to stiction,
   was tried and left: its cost is rough at the scale of the steps (starts an
   order of magnitude apart ended at different points after 30 iterations on a
   3 s synthetic log).

Least squares: `scipy.optimize.least_squares` (trust region, bounds) in
parameters scaled by their start; Jacobians by forward differences, every
perturbed parameter set of one Jacobian run as one batch.

Each compared signal's delay behind the inputs is fitted with the parameters
(`vsj.identification.wrist_model`, `DELAY_BOUND`); the delays start at zero
from every start and are reported apart from the parameters.

**Uncertainty.** The covariance is a sandwich over blocks of `BLOCK` s of
residuals (see `_statistics`), from a central-difference Jacobian at the
optimum with steps of about half a standard error (`_central_jacobian`); the
physical parameters' block of it is reported (the delays' uncertainty is in
it). Identifiability comes
from the singular values of the Jacobian in relative parameter changes: a
direction whose relative standard error exceeds `UNDETERMINED` (the data fix
that combination of parameters to worse than +-50 %) is not determined; the
parameters along it (share above `BLIND_SHARE`) are reported as not determined,
without an interval, and the combination is named. The covariance is taken over
the determined directions only.

**Fit quality** per compared signal: NRMSE (rms error over the signal's range)
and fit % (``100 (1 - |y - y_sim| / |y - mean y|)``, as MATLAB's ``compare``),
on the fitting logs and on validation logs (windows restarted the same way).
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from scipy.optimize import least_squares

from ..errors import InputError, SimulationError
from ..measurements import Measurement
from ..params import SCHEMA, Parameters
from .wrist_model import Setup, WristModel

#: Relative standard error above which a direction of the parameters is not determined.
UNDETERMINED = 0.5
#: A parameter whose share (squared loading) of undetermined directions exceeds this is
#: reported as not determined.
BLIND_SHARE = 0.1
#: A start reached the best optimum when both its cost and its end point lie within the
#: best one's 95 % confidence region (chi-square with one degree of freedom per free
#: parameter, in units of the best start's residual variance): a start that stopped
#: elsewhere, or at a point with a cost the noise cannot explain, did not.
SAME_OPTIMUM = 0.95
#: Relative forward-difference steps of the Jacobian: the arctan law is smooth; true
#: stiction makes the outputs piecewise smooth in the parameters (kinks where a
#: stick phase begins or ends), which a step a hundred times the noise in a
#: parameter averages over.
FD_STEP = {"arctan": 1e-4, "stiction": 1e-3}
#: Step of the covariance's central differences, in standard errors (`_central_jacobian`).
COVARIANCE_STEP = 0.5
#: Default bounds: the start divided and multiplied by this.
BOUND_FACTOR = 5.0
#: Block length [s] of the covariance's sandwich (see `_statistics`).
BLOCK = 0.5
#: Delays of the compared signals (`vsj.identification.wrist_model`): bounds [s] either
#: way (well inside a window's lead, which leaves room to read the model's signal that
#: much earlier or later) and the unit [s] they are fitted and judged in.
DELAY_BOUND, DELAY_UNIT = 0.02, 1e-3
#: Seconds of the log that each start is fitted to (`_subset`): a start only has to find
#: its basin; the best one is then refined on every window.
START_SECONDS = 10.0
#: Laws of the two stages.
SMOOTH, FINAL = "arctan", "stiction"


@dataclass(frozen=True)
class Estimate:
    """One identified parameter (SI): value, standard error and 95 % interval, or
    why there is none."""

    name: str
    value: float
    unit: str
    stderr: float
    ci95: tuple[float, float] | None
    status: str         # determined, not determined, at a bound
    start: float
    bounds: tuple[float, float]

    def to_json(self) -> dict:
        ok = self.status == "determined"
        return {"value": self.value, "unit": self.unit, "stderr": self.stderr if ok else None,
                "ci95": list(self.ci95) if ok and self.ci95 else None, "status": self.status,
                "start": self.start, "bounds": list(self.bounds)}


@dataclass
class SignalQuality:
    nrmse: float
    fit_percent: float
    noise: float
    samples: int


@dataclass
class WristFit:
    """Result of `fit_wrist`: estimates, covariance, identifiability, fit quality."""

    estimates: list[Estimate]
    covariance: np.ndarray          # SI, NaN rows/columns for undetermined parameters
    correlation: np.ndarray
    undetermined: list[str]
    combinations: list[str]
    starts: list[dict]
    reached: int
    cost: float
    dof: int
    residual_sd: float
    quality: dict[str, dict[str, SignalQuality]]
    files: list[str]
    validation_files: list[str]
    synthetic: bool
    simulations: int
    simulated_seconds: float
    wall_time: float
    notes: list[str] = field(default_factory=list)
    traces: dict = field(default_factory=dict, repr=False)
    delays: list[Estimate] = field(default_factory=list)

    @property
    def names(self) -> list[str]:
        return [e.name for e in self.estimates]

    @property
    def values(self) -> np.ndarray:
        return np.array([e.value for e in self.estimates])

    def to_json(self) -> dict:
        def matrix(a):
            return [[None if not math.isfinite(v) else float(v) for v in row] for row in a]

        # "names", "parameters" and "covariance" are what a sweep's [covariance] file holds
        # (`vsj.sweep.spec.read_covariance`): the determined parameters only, whose
        # covariance is finite; "free" lists every free parameter
        keep = [i for i, e in enumerate(self.estimates) if e.status == "determined"]
        cov = self.covariance[np.ix_(keep, keep)]
        cov = 0.5 * (cov + cov.T)
        return {
            "files": self.files, "validation_files": self.validation_files,
            "synthetic": self.synthetic,
            "names": [self.names[i] for i in keep],
            "covariance": matrix(cov),
            "correlation": matrix(self.correlation[np.ix_(keep, keep)]),
            "covariance_note": "SI, over the determined parameters (names), in their order",
            "free": self.names, "values": [float(v) for v in self.values],
            "units": [e.unit for e in self.estimates],
            "parameters": {e.name: e.to_json() for e in self.estimates},
            "delays": {e.name: e.to_json() for e in self.delays},
            "undetermined": self.undetermined, "combinations": self.combinations,
            "starts": self.starts, "starts_reaching_best": self.reached,
            "cost": self.cost, "dof": self.dof, "residual_sd": self.residual_sd,
            "quality": {kind: {name: vars(q) for name, q in per.items()}
                        for kind, per in self.quality.items()},
            "simulations": self.simulations, "simulated_seconds": self.simulated_seconds,
            "wall_time": self.wall_time, "notes": self.notes}

    def overrides(self, files: str) -> dict:
        """Parameter-file overrides of the determined estimates, ``source`` saying where
        they come from (what ``--write-params`` writes)."""
        from ..units import format_quantity

        out = {}
        for e in self.estimates:
            if e.status == "determined":
                section, key = e.name.split(".", 1)
                spec = SCHEMA[section][key]
                out[e.name] = {"value": format_quantity(e.value, spec.display, digits=8),
                               "source": f"identified from {files} (+- "
                                         f"{format_quantity(e.stderr, spec.display, digits=3)},"
                                         f" 1 standard error)"}
        return out


class _Problem:
    """The least-squares function of one stage: residuals and batch Jacobians, cached."""

    def __init__(self, model: WristModel, scale: np.ndarray, law: str, windows=None):
        self.model, self.scale, self.law, self.windows = model, scale, law, windows
        self._last = (None, None)

    def fun(self, theta):
        key = theta.tobytes()
        if self._last[0] == key:
            return self._last[1]
        r, _ = self.model.residuals((theta * self.scale)[None], self.law, self.windows)
        self._last = (key, r[0])
        return r[0]

    def jac(self, theta):
        f0 = self.fun(theta)
        step = FD_STEP[self.law] * np.maximum(np.abs(theta), 1e-2)
        batch = np.repeat(theta[None], len(theta), axis=0) + np.diag(step)
        r, _ = self.model.residuals(batch * self.scale[None], self.law, self.windows)
        return ((r - f0[None]) / step[:, None]).T


def _bounds(model: WristModel, bounds: Mapping[str, tuple[float, float]] | None):
    lo, hi = [], []
    for name, value in zip(model.names, model.base):
        section, key = name.split(".", 1)
        spec = SCHEMA[section][key]
        if bounds and name in bounds:
            a, b = bounds[name]
        elif value > 0:
            a, b = value / BOUND_FACTOR, value * BOUND_FACTOR
        else:
            raise InputError(f"--free {name}: its start is {value:g}; give bounds "
                             f"({name}=LOW,HIGH) or a nonzero start in --params")
        if spec.minimum is not None:
            a = max(a, spec.minimum + (1e-12 if spec.strict else 0.0))
        if spec.maximum is not None:
            b = min(b, spec.maximum)
        if not (a < b and a <= value <= b):
            raise InputError(f"--free {name}: bounds [{a:g}, {b:g}] must be increasing and hold "
                             f"the start {value:g} (SI)")
        lo.append(a)
        hi.append(b)
    return np.array(lo), np.array(hi)


def _design(lo, hi, count: int, seed: int) -> np.ndarray:
    """``count`` points of a Latin hypercube over the bounds (log scale where both are
    positive)."""
    if count <= 0:
        return np.zeros((0, len(lo)))
    sample = stats.qmc.LatinHypercube(d=len(lo), seed=seed).random(count)
    positive = lo > 0
    out = lo + sample * (hi - lo)
    out[:, positive] = np.exp(np.log(lo[positive]) + sample[:, positive]
                              * (np.log(hi[positive]) - np.log(lo[positive])))
    return out


def _solve(problem: _Problem, theta0, lo, hi, max_nfev: int):
    # ftol 1e-6: the cost of a good fit is about half the number of compared values; a
    # relative change of 1e-6 is far below one unit, a change that moves no estimate
    # by a noticeable part of its standard error
    return least_squares(problem.fun, theta0, jac=problem.jac, bounds=(lo, hi), method="trf",
                         x_scale="jac", max_nfev=max_nfev, ftol=1e-6, xtol=1e-6, gtol=1e-10)


def _subset(model: WristModel) -> list[int]:
    """Windows for the starts: about `START_SECONDS` of the log, spread evenly (all of a
    shorter log)."""
    count = len(model.windows)
    length = float(np.mean([w.duration for w in model.windows]))
    take = max(2, math.ceil(START_SECONDS / max(length, 1e-9)))
    if count <= take:
        return list(range(count))
    return sorted(set(np.linspace(0, count - 1, take).round().astype(int).tolist()))


def fit_wrist(logs: Sequence[Measurement], params: Parameters, setup: Setup, *,
              bounds: Mapping[str, tuple[float, float]] | None = None, starts: int = 4,
              validate: Sequence[Measurement] = (), seed: int = 0,
              start: Mapping[str, float] | None = None, max_iterations: int = 12,
              progress=None) -> WristFit:
    """Identify ``setup.free`` from ``logs`` (see the module docstring).

    ``starts`` counts the starting points: the parameter set's own values (or
    ``start``) and ``starts - 1`` more from a space-filling design over the
    bounds (default: the start divided and multiplied by `BOUND_FACTOR`).
    ``validate`` logs are not fitted; the fit quality is reported on them.
    """
    began = _time.perf_counter()
    say = progress or (lambda text: None)
    model = WristModel(logs, params, setup)
    n_par = len(model.names)
    if model.compared <= 2 * n_par:
        raise InputError(f"{logs[0].path}: {model.compared} compared samples for {n_par} free "
                         "parameters: the log is too short")
    lo, hi = _bounds(model, bounds)
    base = model.base.copy()
    if start:
        for i, name in enumerate(model.names):
            if name in start:
                base[i] = float(np.clip(start[name], lo[i], hi[i]))
    n_delay = len(model.delay_names)
    points = np.vstack([base[None], _design(lo, hi, starts - 1, seed)])
    # the delays start at zero from every start and are not part of the design
    points = np.hstack([points, np.zeros((len(points), n_delay))])
    base = np.concatenate([base, np.zeros(n_delay)])
    lo = np.concatenate([lo, np.full(n_delay, -DELAY_BOUND)])
    hi = np.concatenate([hi, np.full(n_delay, DELAY_BOUND)])
    scale = np.concatenate([np.where(base[:n_par] != 0, np.abs(base[:n_par]), hi[:n_par]),
                            np.full(n_delay, DELAY_UNIT)])
    lo_t, hi_t = lo / scale, hi / scale
    points = points / scale
    subset = _subset(model)
    smooth_subset = _Problem(model, scale, SMOOTH, subset)
    runs = []
    for k, theta0 in enumerate(points):
        r = _solve(smooth_subset, np.clip(theta0, lo_t, hi_t), lo_t, hi_t, max_iterations)
        runs.append(r)
        say(f"start {k + 1}/{len(points)}: cost {r.cost:.6g}")
    costs = np.array([r.cost for r in runs])
    best = int(np.argmin(costs))
    same = _same_optimum(runs, best)
    reached = int(np.sum(same))
    smooth = _solve(_Problem(model, scale, SMOOTH), runs[best].x, lo_t, hi_t,
                    max(3, max_iterations // 3))
    say(f"smooth law, every window: cost {smooth.cost:.6g}")
    final = _solve(_Problem(model, scale, FINAL), smooth.x, lo_t, hi_t, max_iterations)
    # re-weight: each signal's noise from its own residuals (never below the data's own),
    # so that a signal the model cannot follow does not dominate; then finish the fit
    noise = _residual_noise(model, final.fun)
    if any(noise[k] > 1.5 * model.noise[k] for k in noise):
        model.set_noise(noise)
        final = _solve(_Problem(model, scale, FINAL), final.x, lo_t, hi_t,
                       max(3, max_iterations // 3))
    noise = model.noise
    if not np.all(np.isfinite(final.x)):
        raise SimulationError("the fit diverged: non-finite parameters")
    say(f"true stiction: cost {final.cost:.6g}")
    values = final.x * scale
    fit_quality, fit_traces, ok = _quality(model, values)
    if not ok:
        raise SimulationError("the wrist failed to simulate at the identified parameters")
    final.jac = _central_jacobian(_Problem(model, scale, FINAL), final)
    result = _statistics(model, final, scale, lo, hi, base)
    result.starts = [{"start": {n: float(v) for n, v in zip(model.names, p * scale)},
                      "end": {n: float(v) for n, v in zip(model.names, r.x * scale)},
                      "cost": float(r.cost), "reached_best": bool(ok)}
                     for p, r, ok in zip(points, runs, same)]
    result.reached = reached
    result.quality = {"fit": fit_quality}
    result.traces = {"fit": fit_traces}
    if validate:
        vmodel = WristModel(validate, params, setup)
        vmodel.set_noise(noise)
        # the fitted delays carry over signal by signal (the validation logs may
        # compare other signals)
        fitted = dict(zip(model.delay_names, values[n_par:]))
        vvalues = np.concatenate([values[:n_par],
                                  [fitted.get(n, 0.0) for n in vmodel.delay_names]])
        q, traces, _ = _quality(vmodel, vvalues)
        result.quality["validation"] = q
        result.traces["validation"] = traces
        model.runs += vmodel.runs
        model.simulated += vmodel.simulated
    result.files = [lg.path for lg in logs]
    result.validation_files = [lg.path for lg in validate]
    result.synthetic = any(lg.synthetic for lg in list(logs) + list(validate))
    result.simulations = model.runs
    result.simulated_seconds = model.simulated
    result.wall_time = _time.perf_counter() - began
    result.notes += [(f"{len(model.windows)} windows of up to {setup.window:g} s, each "
                      f"restarted from the measured state; the first {setup.lead:g} s of each "
                      "not compared"),
                     f"compared: {', '.join(o.name for o in model.outputs)}; inputs: "
                     + ", ".join(f"{c} <- {col}" for c, (col, _) in model.channels.items())]
    return result


def _central_jacobian(problem: _Problem, result) -> np.ndarray:
    """The Jacobian the uncertainties come from: central differences at the optimum,
    each step `COVARIANCE_STEP` of the parameter's standard error (from the solver's
    forward-difference Jacobian) but at least the solver's own step and at most a
    tenth of the parameter (a delay: of `DELAY_UNIT`). With true stiction the
    outputs have kinks where a stick phase begins or ends; a step as small as the
    solver's makes a column depend on which kinks it happens to cross, and the
    standard errors with it (by a factor of two between neighbouring optima on
    synthetic logs); a step of about the standard error sees the slope that the
    noise-driven scatter of the estimate sees."""
    theta = result.x
    J = np.asarray(result.jac, dtype=float)
    dof = max(len(result.fun) - len(theta), 1)
    s2 = float(np.sum(result.fun ** 2)) / dof
    with np.errstate(divide="ignore", invalid="ignore"):
        se = np.sqrt(s2 * np.clip(np.diag(np.linalg.pinv(J.T @ J)), 0.0, None))
    magnitude = np.maximum(np.abs(theta), 1.0)
    smallest = FD_STEP[problem.law] * np.maximum(np.abs(theta), 1e-2)
    step = np.clip(COVARIANCE_STEP * np.nan_to_num(se, nan=0.0, posinf=0.0), smallest,
                   0.1 * magnitude)
    n = len(theta)
    batch = np.vstack([theta[None] + np.diag(step), theta[None] - np.diag(step)])
    r, _ = problem.model.residuals(batch * problem.scale[None], problem.law, problem.windows)
    return ((r[:n] - r[n:]) / (2.0 * step[:, None])).T


def _same_optimum(runs, best: int) -> np.ndarray:
    """Which starts reached the best one's optimum (`SAME_OPTIMUM`): cost rise and
    distance (in the metric of the best start's Jacobian) both within the chi-square
    quantile times the residual variance."""
    ref = runs[best]
    J = np.asarray(ref.jac, dtype=float)
    dof = max(len(ref.fun) - len(ref.x), 1)
    s2 = max(2.0 * ref.cost / dof, 1e-300)
    limit = stats.chi2.ppf(SAME_OPTIMUM, len(ref.x))
    out = []
    for r in runs:
        step = J @ (r.x - ref.x)
        distance = float(step @ step) / s2
        rise = 2.0 * (r.cost - ref.cost) / s2
        out.append(rise <= limit and distance <= limit)
    return np.array(out, dtype=bool)


def _residual_noise(model: WristModel, weighted: np.ndarray) -> dict[str, float]:
    out = {}
    weights = model.weights()
    pos = 0
    sums = np.zeros(len(model.outputs))
    counts = 0
    for w in model.windows:
        n = len(w.samples)
        block = weighted[pos:pos + n * len(model.outputs)].reshape(len(model.outputs), n)
        sums += np.sum(block ** 2, axis=1)
        counts += n
        pos += n * len(model.outputs)
    for c, o in enumerate(model.outputs):
        rms = math.sqrt(sums[c] / max(counts, 1)) / weights[c]
        out[o.name] = max(rms, model.noise[o.name])
    return out


def _statistics(model: WristModel, result, scale, lo, hi, base) -> WristFit:
    n_phys = len(model.names)
    names = model.names + model.delay_names
    n_par = len(names)
    theta = result.x
    values = theta * scale
    J = np.asarray(result.jac, dtype=float)
    m = len(result.fun)
    dof = m - n_par
    s2 = float(np.sum(result.fun ** 2)) / max(dof, 1)
    # per relative change of each parameter; per `DELAY_UNIT` of a delay
    unit = np.concatenate([np.abs(values[:n_phys]), np.full(n_par - n_phys, DELAY_UNIT)])
    Jrel = J * (unit / scale)[None, :]
    _, sv, Vt = np.linalg.svd(Jrel, full_matrices=False)
    rel_se = np.where(sv > 0, math.sqrt(s2) / np.maximum(sv, 1e-300), math.inf)
    blind = rel_se > UNDETERMINED
    share = np.sum(Vt[blind] ** 2, axis=0) if blind.any() else np.zeros(n_par)
    active = np.asarray(result.active_mask) != 0
    # a parameter the data leave open may drift to a bound: it is reported as not
    # determined (the reason), not as at a bound
    undetermined = [names[i] for i in range(n_par) if share[i] > BLIND_SHARE]
    combinations = []
    for k in np.flatnonzero(blind):
        v = Vt[k]
        big = np.flatnonzero(np.abs(v) > 0.3)
        if len(big) == 1:
            combinations.append(f"{names[big[0]]} alone (relative standard error "
                                 f"{_pct(rel_se[k])})")
        else:
            v = v / v[big[np.argmax(np.abs(v[big]))]]
            terms = " + ".join(f"{v[i]:.2g} ln {names[i]}" if i < n_phys else
                               f"{v[i]:.2g} {names[i]} [ms]" for i in big)
            combinations.append(f"{terms} (relative standard error {_pct(rel_se[k])})")
    keep = ~blind
    # Residuals of a windowed output-error fit are not white: an error in a window's
    # measured start state, or the noise of a measured input, lasts as long as the
    # wrist remembers it (with stiction, a stick phase). The covariance is therefore
    # the sandwich over blocks of `BLOCK` s of consecutive samples (all signals
    # together), which holds for errors correlated over less than a block.
    inv = (Vt[keep].T / sv[keep] ** 2) @ Vt[keep]
    g = np.zeros((n_par,))
    meat = np.zeros((n_par, n_par))
    for rows in _blocks(model):
        g = Jrel[rows].T @ result.fun[rows]
        meat += np.outer(g, g)
    cov_rel = inv @ meat @ inv * (m / max(dof, 1))
    cov = cov_rel * np.outer(unit, unit)
    bad = np.array([names[i] in undetermined or active[i] for i in range(n_par)])
    cov[bad, :] = np.nan
    cov[:, bad] = np.nan
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    t = stats.t.ppf(0.975, max(dof, 1))
    estimates = []
    for i, name in enumerate(names):
        section, key = name.split(".", 1)
        status = ("not determined" if name in undetermined else "at a bound" if active[i]
                  else "determined")
        e = float(sd[i]) if status == "determined" else math.inf if \
            status == "not determined" else math.nan
        ci = (float(values[i] - t * e), float(values[i] + t * e)) if status == "determined" \
            else None
        estimates.append(Estimate(name, float(values[i]),
                                  SCHEMA[section][key].unit if i < n_phys else "s", e, ci,
                                  status, float(base[i]), (float(lo[i]), float(hi[i]))))
    phys = slice(0, n_phys)
    # the delays are nuisance parameters: reported apart, the covariance of the physical
    # parameters is their block of the whole (the delays' uncertainty included)
    return WristFit(estimates=estimates[phys], delays=estimates[n_phys:],
                    covariance=cov[phys, phys], correlation=corr[phys, phys],
                    undetermined=undetermined, combinations=combinations, starts=[], reached=0,
                    cost=float(result.cost), dof=dof, residual_sd=math.sqrt(s2), quality={},
                    files=[], validation_files=[], synthetic=False, simulations=0,
                    simulated_seconds=0.0, wall_time=0.0)


def _blocks(model: WristModel):
    """Index arrays of the residual vector, one per block of `BLOCK` s of samples."""
    pos = 0
    k = len(model.outputs)
    for w in model.windows:
        n = len(w.samples)
        t = model.logs[w.log]["time"][w.samples]
        ids = np.floor((t - t[0]) / BLOCK).astype(int)
        for b in np.unique(ids):
            cols = np.flatnonzero(ids == b)
            yield (pos + np.arange(k)[:, None] * n + cols[None, :]).reshape(-1)
        pos += n * k


def _pct(x: float) -> str:
    return f"{100 * x:.3g} %" if math.isfinite(x) and x < 1e4 else "unbounded"


def _quality(model: WristModel, values: np.ndarray):
    """Per compared signal: NRMSE and fit % with true stiction; and the traces for the
    figures: per signal, per log, (time of that log, measured, simulated)."""
    sims, ok = model.simulate(values[None], FINAL)
    out, traces = {}, {}
    for c, o in enumerate(model.outputs):
        meas, sim, times, logs = [], [], [], []
        for k, w in enumerate(model.windows):
            meas.append(model.measured(k)[c])
            sim.append(sims[k][0, c])
            times.append(model.logs[w.log]["time"][w.samples])
            logs.append(np.full(len(w.samples), w.log))
        y, ys, tt = np.concatenate(meas), np.concatenate(sim), np.concatenate(times)
        which = np.concatenate(logs)
        err = ys - y
        rng = float(np.ptp(y)) or 1.0
        spread = float(np.linalg.norm(y - np.mean(y))) or 1.0
        out[o.name] = SignalQuality(nrmse=float(np.sqrt(np.mean(err ** 2)) / rng),
                                    fit_percent=float(100 * (1 - np.linalg.norm(err) / spread)),
                                    noise=float(model.noise[o.name]), samples=len(y))
        traces[o.name] = {model.logs[i].path: (tt[which == i], y[which == i], ys[which == i])
                          for i in range(len(model.logs))}
    return out, traces, bool(ok[0])
