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

**Uncertainty.** The standard errors have two parts (`_covariance`), from a
central-difference Jacobian at the optimum with steps of about half a
standard error (`_central_jacobian`):

* the compared signals' own errors: a sandwich over blocks of consecutive
  samples, the block length chosen from the residuals' autocorrelation (the
  shortest at which block sums are uncorrelated, `_block_samples`);
* the noise of the measured inputs (external torques), which the model takes
  as exact: simulated at the optimum with fresh noise of the inputs' own level
  (`Setup.input_draws` draws, `WristModel.perturbed_residuals`), each draw's
  residual change taken through one Gauss-Newton step; the sandwich's
  expected share of it is taken out so that it is not counted twice.

95 % intervals use Student's t with Welch-Satterthwaite degrees of freedom
(blocks and draws). `WristFit.uncertainty` (``uncertainty`` in the JSON)
says how they were computed. The physical parameters' block of the
covariance is reported (the delays' uncertainty is in it). Identifiability
comes from the singular values of the Jacobian in relative parameter
changes: a direction whose relative standard error exceeds `UNDETERMINED`
(the data fix that combination of parameters to worse than +-50 %) is not
determined; the parameters along it (share above `BLIND_SHARE`) are reported
as not determined, without an interval, and the combination is named. The
covariance is taken over the determined directions only.

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
from scipy import special
from scipy.optimize import least_squares

from ..errors import InputError, SimulationError
from ..measurements import Measurement
from ..params import SCHEMA, Parameters
from ..units import format_quantity
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
#: Level of the test that chooses the sandwich's block length, and the fewest blocks it
#: may leave (`_block_samples`).
BLOCKING_LEVEL, MIN_BLOCKS = 0.99, 8
#: Delays of the compared signals (`vsj.identification.wrist_model`): bounds [s] either
#: way (well inside a window's lead, which leaves room to read the model's signal that
#: much earlier or later) and the unit [s] they are fitted and judged in.
DELAY_BOUND, DELAY_UNIT = 0.02, 1e-3
#: The windows' start states are read again at the fitted delays (`_read_states_late`)
#: when a delay has moved by more than this [s] since they were read: at the wrist's
#: speeds of a few rad/s, 10 us moves a start angle by a tenth of the encoders' noise.
#: At most `STATE_PASSES` such passes (each a short refit) follow the first fit.
STATE_DELAY_TOLERANCE, STATE_PASSES = 1e-5, 3
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
        """The estimate (value, and standard error and 95 % interval where determined;
        status, start, bounds) as plain JSON data (SI values with their units)."""
        ok = self.status == "determined"
        return {"value": self.value, "unit": self.unit, "stderr": self.stderr if ok else None,
                "ci95": list(self.ci95) if ok and self.ci95 else None, "status": self.status,
                "start": self.start, "bounds": list(self.bounds)}


@dataclass
class SignalQuality:
    """How well a fitted model reproduces one signal: ``nrmse``, the rms error over the
    signal's range; ``fit_percent``, ``100 (1 - |error| / |signal - its mean|)`` (the
    fit measure of system identification); the noise level assumed for it (its unit);
    and the number of samples compared."""

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
    #: How the standard errors were computed (`_covariance`): method, block length,
    #: draws of the inputs' noise, each parameter's share of variance from the inputs
    #: and its degrees of freedom.
    uncertainty: dict = field(default_factory=dict)

    @property
    def names(self) -> list[str]:
        """Names of the free parameters, in the order of `values`."""
        return [e.name for e in self.estimates]

    @property
    def values(self) -> np.ndarray:
        """The estimated values (SI) of the free parameters."""
        return np.array([e.value for e in self.estimates])

    def to_json(self) -> dict:
        """The fit (estimates, delays, covariance of the determined parameters, fit quality,
        starts, timings) as plain JSON data (SI values with their units)."""
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
            "wall_time": self.wall_time, "notes": self.notes,
            "uncertainty": self.uncertainty}

    def overrides(self, files: str) -> dict:
        """Parameter-file overrides of the determined estimates, ``source`` saying where
        they come from (what ``--write-params`` writes)."""
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


def _chi2_quantile(p: float, dof: int) -> float:
    """The chi-square distribution's ``p`` quantile for ``dof`` degrees of freedom
    (``scipy.stats.chi2.ppf``'s own formula, without importing scipy.stats)."""
    return 2.0 * float(special.gammaincinv(dof / 2.0, p))


def _design(lo, hi, count: int, seed: int) -> np.ndarray:
    """``count`` points of a Latin hypercube over the bounds (log scale where both are
    positive)."""
    if count <= 0:
        return np.zeros((0, len(lo)))
    from scipy.stats import qmc  # lazy: scipy.stats takes most of a second to import

    sample = qmc.LatinHypercube(d=len(lo), seed=seed).random(count)
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
    _read_states_late(model, smooth, scale, n_par)
    final = _solve(_Problem(model, scale, FINAL), smooth.x, lo_t, hi_t, max_iterations)
    for _ in range(STATE_PASSES):
        # re-weight: each signal's noise from its own residuals (never below the data's
        # own), so that a signal the model cannot follow does not dominate; and read the
        # windows' start states at the delays just fitted; then finish the fit
        noise = _residual_noise(model, final.fun)
        reweight = any(noise[k] > 1.5 * model.noise[k] for k in noise)
        if reweight:
            model.set_noise(noise)
        if not (_read_states_late(model, final, scale, n_par) or reweight):
            break
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
    drawn = None
    if setup.input_draws > 0 and model.noisy_inputs():
        perturbed, ran = model.perturbed_residuals(values, FINAL, setup.input_draws, seed=seed)
        # a draw the wrist failed to simulate says nothing about the noise's effect
        drawn = perturbed[ran] - final.fun[None]
        say(f"inputs' noise: {int(np.sum(ran))} draws")
    result = _statistics(model, final, scale, lo, hi, base, drawn)
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
        # and the start states are read as the fit read its own
        read = dict(zip(model.delay_names, model.state_delays))
        if vmodel.delay_names:
            vmodel.set_state_delays([read.get(n, 0.0) for n in vmodel.delay_names])
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
    result.notes += model.gaps
    return result


def _read_states_late(model: WristModel, result, scale: np.ndarray, n_par: int) -> bool:
    """Read the windows' start states at the delays of the least-squares ``result``
    (`WristModel.set_state_delays`) when one has moved by more than
    `STATE_DELAY_TOLERANCE` since they were read; returns whether they were read
    again. A delay the data do not determine (its standard error, from the solver's
    Jacobian, above `UNDETERMINED` of `DELAY_UNIT`, as `_statistics` judges it) is
    taken as zero: a signal that does not move leaves its delay free to wander to a
    bound, and its start would be read there."""
    delays = result.x[n_par:] * scale[n_par:]
    if not len(delays):
        return False
    J = np.asarray(result.jac, dtype=float)
    s2 = float(np.sum(result.fun ** 2)) / max(len(result.fun) - len(result.x), 1)
    with np.errstate(invalid="ignore"):
        se = np.sqrt(s2 * np.clip(np.diag(np.linalg.pinv(J.T @ J)), 0.0, None))
    determined = (J[:, n_par:] != 0).any(axis=0) & (se[n_par:] * scale[n_par:]
                                                     <= UNDETERMINED * DELAY_UNIT)
    delays = np.where(determined, delays, 0.0)
    if np.max(np.abs(delays - model.state_delays)) <= STATE_DELAY_TOLERANCE:
        return False
    return model.set_state_delays(delays)


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
    limit = _chi2_quantile(SAME_OPTIMUM, len(ref.x))
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


def _statistics(model: WristModel, result, scale, lo, hi, base,
                drawn: np.ndarray | None = None) -> WristFit:
    """Estimates, covariance and identifiability at the optimum ``result`` (its
    ``jac`` the central-difference Jacobian); ``drawn``: residual changes (draws,
    compared values) that fresh noise of the measured inputs makes
    (`WristModel.perturbed_residuals` less ``result.fun``), or None."""
    n_phys = len(model.names)
    names = model.names + model.delay_names
    n_par = len(names)
    theta = result.x
    values = theta * scale
    J = np.asarray(result.jac, dtype=float)
    m = len(result.fun)
    dof = m - n_par
    s2 = float(np.sum(result.fun ** 2)) / max(dof, 1)
    # per relative change of each parameter (of the smaller of its estimate and its
    # start, so that one the data leave open cannot look determined by having drifted
    # to a large bound); per `DELAY_UNIT` of a delay
    unit = np.concatenate([np.minimum(np.abs(values[:n_phys]), np.abs(base[:n_phys])),
                           np.full(n_par - n_phys, DELAY_UNIT)])
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
    bad = np.array([names[i] in undetermined or active[i] for i in range(n_par)])
    inv = (Vt[keep].T / sv[keep] ** 2) @ Vt[keep]
    cov_rel, var_out, var_in, method = _covariance(model, Jrel, result.fun, inv, drawn,
                                                  ~bad[:n_phys], int(np.sum(keep)))
    cov = cov_rel * np.outer(unit, unit)
    cov[bad, :] = np.nan
    cov[:, bad] = np.nan
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
        # Welch-Satterthwaite: the two parts of each variance are estimated from
        # `blocks` blocks and `draws` draws
        blocks, draws = method["blocks"], method["input_draws"]
        nu = (var_out + var_in) ** 2 / (var_out ** 2 / max(blocks - 1, 1)
                                        + (var_in ** 2 / (draws - 1) if draws > 1 else 0.0))
    estimates = []
    for i, name in enumerate(names):
        section, key = name.split(".", 1)
        status = ("not determined" if name in undetermined else "at a bound" if active[i]
                  else "determined")
        e = float(sd[i]) if status == "determined" else math.inf if \
            status == "not determined" else math.nan
        t = special.stdtrit(nu[i], 0.975) if math.isfinite(nu[i]) and nu[i] > 0 else math.inf
        ci = (float(values[i] - t * e), float(values[i] + t * e)) if status == "determined" \
            else None
        estimates.append(Estimate(name, float(values[i]),
                                  SCHEMA[section][key].unit if i < n_phys else "s", e, ci,
                                  status, float(base[i]), (float(lo[i]), float(hi[i]))))
    det = [i for i in range(n_phys) if not bad[i]]
    with np.errstate(invalid="ignore", divide="ignore"):
        method["input_share"] = {names[i]: float(var_in[i] / (var_out[i] + var_in[i]))
                                 for i in det}
    method["dof"] = {names[i]: float(nu[i]) for i in det}
    phys = slice(0, n_phys)
    # the delays are nuisance parameters: reported apart, the covariance of the physical
    # parameters is their block of the whole (the delays' uncertainty included)
    return WristFit(estimates=estimates[phys], delays=estimates[n_phys:],
                    covariance=cov[phys, phys], correlation=corr[phys, phys],
                    undetermined=undetermined, combinations=combinations, starts=[], reached=0,
                    cost=float(result.cost), dof=dof, residual_sd=math.sqrt(s2), quality={},
                    files=[], validation_files=[], synthetic=False, simulations=0,
                    simulated_seconds=0.0, wall_time=0.0, uncertainty=method)


def _covariance(model: WristModel, Jrel: np.ndarray, residuals: np.ndarray, inv: np.ndarray,
                drawn: np.ndarray | None, judged: np.ndarray, n_kept: int):
    """Covariance of the parameters in relative units (see the module docstring):
    ``(cov, variance from the compared signals, variance from the inputs' noise,
    method)``; ``judged``: the physical parameters whose influence chooses the block
    length.

    Two parts. The compared signals' own errors (noise, and what the model does not
    follow) give a sandwich over blocks of consecutive samples, all signals
    together, the block length chosen from the residuals' own autocorrelation
    (`_block_samples`). The measured inputs' noise, which the model takes as exact,
    moves the estimates by as much again or more, and in a way the residuals hide
    (with stiction, a slip that a noise excursion starts early leaves the wrist
    elsewhere until the next one): it is measured by simulation, fresh noise of the
    inputs' own level drawn ``draws`` times at the optimum and each draw's residual
    change ``dr`` taken through one Gauss-Newton step, ``-inv J' dr``; their
    covariance is this part. The observed residuals hold a share of that same
    effect, what is left of it after the parameters have followed it; its
    expected share in the blocks, from the draws' ``dr`` less what the step
    explains, is taken out of the sandwich so that it is not counted twice. A
    finite number of blocks ``G`` understates the spread of block sums about
    estimated parameters by ``(G - 1) / G``, which is put back.
    """
    rows_of, sample_of = _layout(model)
    scores = np.zeros((len(sample_of), Jrel.shape[1]))
    np.add.at(scores, rows_of, Jrel * residuals[:, None])
    influence = scores @ inv
    size = _block_samples(model, influence[:, :len(judged)][:, judged], n_kept)
    labels, count = _block_labels(model, size)
    row_block = labels[rows_of]
    g = np.zeros((count, Jrel.shape[1]))
    np.add.at(g, row_block, Jrel * residuals[:, None])
    meat = g.T @ g * (count / max(count - 1, 1))
    cov_in = np.zeros_like(meat)
    draws = 0 if drawn is None else len(drawn)
    if draws > 1:
        shared = np.zeros_like(meat)
        steps = []
        for dr in drawn:
            step = -inv @ (Jrel.T @ dr)
            steps.append(step)
            # what the draw leaves in the residuals once the parameters have followed it:
            # the observed residuals are those at the optimum
            gd = np.zeros_like(g)
            np.add.at(gd, row_block, Jrel * (dr + Jrel @ step)[:, None])
            shared += gd.T @ gd
        # the steps' spread about their mean: a mean step is what adding noise to noisy
        # inputs does, a curvature of the response rather than an error of the estimate
        cov_in = np.atleast_2d(np.cov(np.array(steps), rowvar=False))
        meat -= shared / draws
        w, V = np.linalg.eigh(0.5 * (meat + meat.T))
        meat = (V * np.clip(w, 0.0, None)) @ V.T
    else:
        draws = 0
    cov_out = inv @ meat @ inv
    period = float(np.median(np.concatenate([np.diff(lg["time"]) for lg in model.logs])))
    method = {
        "method": "block sandwich" + (" + Monte Carlo of the inputs' noise" if draws else ""),
        "block_samples": int(size), "block_seconds": float(size * period),
        "blocks": int(count), "input_draws": int(draws),
        "input_noise": model.noisy_inputs() if draws else {},
        "description": (
            f"sandwich over {count} blocks of {size} samples ({size * period:.3g} s, the "
            "shortest at which the block sums of every determined parameter's influence "
            "are uncorrelated: Jonsson's automated blocking test at "
            f"{100 * BLOCKING_LEVEL:g} %)"
            + (f", plus the spread that {draws} fresh draws of the measured inputs' noise "
               f"({', '.join(model.noisy_inputs())}) cause at the optimum (one "
               "Gauss-Newton step each; the sandwich's expected share of it taken out)"
               if draws else "")
            + "; 95 % intervals from Student's t with Welch-Satterthwaite degrees of "
              "freedom")}
    return cov_out + cov_in, np.diag(cov_out).copy(), np.diag(cov_in).copy(), method


def _layout(model: WristModel) -> tuple[np.ndarray, np.ndarray]:
    """For each entry of the residual vector, the index of its sample (counted over
    every window, in time order within each); and each sample's window."""
    k = len(model.outputs)
    rows, windows = [], []
    first = 0
    for j, w in enumerate(model.windows):
        n = len(w.samples)
        rows.append(np.tile(first + np.arange(n), k))
        windows.append(np.full(n, j))
        first += n
    return np.concatenate(rows), np.concatenate(windows)


def _block_labels(model: WristModel, size: int) -> tuple[np.ndarray, int]:
    """Block of each sample: runs of ``size`` consecutive samples within a window (the
    last of a window may be shorter); and the number of blocks."""
    labels, count = [], 0
    for w in model.windows:
        ids = np.arange(len(w.samples)) // size
        labels.append(count + ids)
        count += int(ids[-1]) + 1
    return np.concatenate(labels), count


def _block_samples(model: WristModel, influence: np.ndarray, n_kept: int) -> int:
    """Block length [samples] of the sandwich: the largest over the columns of
    ``influence`` (per sample, each parameter's share of its estimate's error) of the
    shortest length ``2**j`` at which the sums over consecutive blocks are
    uncorrelated, at that length and every longer one (M. Jonsson, "Standard error
    estimation by an automated blocking method", Phys. Rev. E 98, 043304, 2018: the
    sum over levels of blocks times the squared lag-one correlation is chi-square
    under no correlation, tested at `BLOCKING_LEVEL`). Levels leave at least
    `MIN_BLOCKS` and twice the determined directions' count of blocks, so that the
    sandwich's meat has the rank to describe them."""
    sizes = [len(w.samples) for w in model.windows]
    least = max(MIN_BLOCKS, 2 * n_kept)
    levels = 0
    while sum(n // 2 ** (levels + 1) for n in sizes) >= least:
        levels += 1
    chosen = 0
    ends = np.cumsum([0] + sizes)
    for col in influence.T:
        terms = []
        series = [col[a:b] for a, b in zip(ends[:-1], ends[1:])]
        for _ in range(levels + 1):
            blocks = sum(len(x) for x in series)
            num = sum(float(np.dot(x[:-1], x[1:])) for x in series if len(x) > 1)
            den = sum(float(np.dot(x, x)) for x in series)
            pairs = sum(max(len(x) - 1, 0) for x in series)
            rho = num / den * blocks / max(pairs, 1) if den > 0 else 0.0
            terms.append(blocks * rho ** 2)
            series = [x[:len(x) // 2 * 2].reshape(-1, 2).sum(axis=1) for x in series]
        tail = np.cumsum(terms[::-1])[::-1]
        level = next((j for j in range(len(terms))
                      if tail[j] < _chi2_quantile(BLOCKING_LEVEL, len(terms) - j)),
                     len(terms) - 1)
        chosen = max(chosen, level)
    return 2 ** chosen


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
