"""Torque-velocity curves of the planetary module: T(w) = c1 w + c2 atan(c3 w).

Report section 4.1 (eq 4.2, 4.4): with the sun or the ring fixed, the torque
needed to drive the carrier at a constant speed follows this form. A
measurement comes in one of three forms, recognised automatically:

* ``points``: velocity and torque only, one row per speed (already averaged);
* ``segments``: a time series with the carrier held at a series of constant
  speeds; each plateau is averaged after its transient;
* ``sweep``: a time series with slowly varying speed; every sample is fitted.

With an angle column the angle-dependent ripple of fig 4.6 is separated from
the friction and reported (the report could not): every sample of the
plateaus (or of the sweep) is fitted at once with the curve plus a Fourier
series in the carrier angle, mirrored with the direction of motion as fig 4.6
shows, so the ripple's own uncertainty enters the constants'. Uncertainties are
the usual least-squares ones: standard errors from the residual variance and
the Jacobian, 95 % confidence intervals from Student's t; residuals correlated
from row to row widen them (`serial_inflation`) and are noted. A constant the data
cannot determine (all points at one speed, say) or one at a bound has no
interval, and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace, field

import numpy as np
from scipy import special
from scipy.optimize import least_squares

from ..errors import InputError, SimulationError
from ..measurements import Measurement

#: Harmonics of the carrier angle used for the ripple.
RIPPLE_HARMONICS = 4
#: A plateau: speed within this fraction (plus 5 mrad/s) of its start...
PLATEAU_TOLERANCE = 0.01
#: ... for at least this long [s] (a slow sweep never stays that long); its first
#: part is discarded as transient.
PLATEAU_MIN_DURATION = 1.0
TRANSIENT_FRACTION = 0.25
TAIL_FRACTION = 0.05
#: Singular values of the column-scaled Jacobian below this fraction of the largest are
#: taken as zero: the Jacobian comes from finite differences with relative steps near
#: 1e-8, so directions weaker than this are not seen by the data.
RANK_TOLERANCE = 1e-7
#: A parameter whose share of the data's blind directions exceeds this is not determined.
BLIND_SHARE = 1e-3


@dataclass(frozen=True)
class Estimate:
    """A fitted parameter: value, unit, standard error and 95 % confidence interval.

    The standard error is NaN for a parameter at a bound (no symmetric interval
    exists) and infinite for one the data do not determine.
    """

    name: str
    value: float
    unit: str
    stderr: float
    ci95: tuple[float, float]

    @property
    def status(self) -> str:
        """``determined``, ``at a bound`` or ``not determined``."""
        if math.isnan(self.stderr):
            return "at a bound"
        return "determined" if math.isfinite(self.stderr) else "not determined"

    def to_json(self) -> dict:
        """JSON form; a standard error that does not exist (parameter at a bound, or not
        determined by the data) is null, and so is its interval."""
        finite = math.isfinite(self.stderr)
        return {"value": self.value, "unit": self.unit,
                "stderr": self.stderr if finite else None,
                "ci95": list(self.ci95) if finite else None, "status": self.status}


@dataclass
class Ripple:
    """Angle-dependent torque ripple separated from the friction curve."""

    method: str
    rms: float          # N m
    peak_to_peak: float  # N m
    angle: np.ndarray   # rad, a grid over one revolution
    torque: np.ndarray  # N m, ripple at positive speed on that grid

    def to_json(self) -> dict:
        """The ripple's size (rms and peak to peak, N m) as plain JSON data (SI values with
        their units)."""
        return {"method": self.method, "rms": self.rms, "peak_to_peak": self.peak_to_peak,
                "unit": "N m"}


@dataclass
class FrictionFit:
    """Result of `fit_curve`: c1, c2, c3 with uncertainties and the data used."""

    c1: Estimate
    c2: Estimate
    c3: Estimate
    form: str
    velocity: np.ndarray      # the fitted points (segment means, points or samples)
    torque: np.ndarray
    residual_rms: float
    dof: int
    ripple: Ripple | None = None
    raw: tuple[np.ndarray, np.ndarray] | None = None
    source: str = ""
    synthetic: bool = False
    notes: list[str] = field(default_factory=list)

    def predict(self, velocity) -> np.ndarray:
        """Torque [N m] of the fitted ``c1 w + c2 atan(c3 w)`` (report eq 4.2) at
        ``velocity`` [rad/s]."""
        w = np.asarray(velocity, dtype=float)
        return self.c1.value * w + self.c2.value * np.arctan(self.c3.value * w)

    @property
    def values(self) -> np.ndarray:
        """The fitted ``(c1, c2, c3)`` as an array (SI)."""
        return np.array([self.c1.value, self.c2.value, self.c3.value])

    def to_json(self) -> dict:
        """The fit (constants with uncertainties, data size, residual, ripple, notes) as
        plain JSON data (SI values with their units)."""
        return {"file": self.source, "synthetic": self.synthetic, "form": self.form,
                "model": "T = c1 w + c2 atan(c3 w)",
                "c1": self.c1.to_json(), "c2": self.c2.to_json(), "c3": self.c3.to_json(),
                "points": int(len(self.velocity)), "residual_rms": self.residual_rms,
                "ripple": None if self.ripple is None else self.ripple.to_json(),
                "notes": self.notes}


def curve(c, w):
    """``c[0] w + c[1] atan(c[2] w)`` (report eq 4.2): torque [N m] at speed ``w`` [rad/s]
    for constants ``c``."""
    return c[0] * w + c[1] * np.arctan(c[2] * w)


def estimates(result, names, units, dof, scale=1.0) -> list[Estimate]:
    """Standard errors and 95 % intervals from a least-squares result.

    Parameters at a bound (``result.active_mask``) get a NaN standard error. The
    others' covariance comes from the column-scaled Jacobian's singular values;
    a parameter that moves along a direction the data do not see (rank
    deficiency), or any parameter when no degree of freedom is left for the
    residual variance, gets an infinite one: not determined.
    """
    J = np.asarray(result.jac, dtype=float)
    err = np.full(len(names), math.nan)
    free = np.flatnonzero(np.asarray(result.active_mask) == 0)
    if dof < 1:
        err[free] = math.inf
    elif free.size:
        s2 = float(np.sum(result.fun ** 2)) / dof * scale
        colscale = np.maximum(np.linalg.norm(J[:, free], axis=0), 1e-300)
        _, sv, Vt = np.linalg.svd(J[:, free] / colscale, full_matrices=False)
        rank = int(np.sum(sv > RANK_TOLERANCE * sv[0])) if sv[0] > 0 else 0
        blind = np.linalg.norm(Vt[rank:], axis=0)
        cov = (Vt[:rank].T / sv[:rank] ** 2) @ Vt[:rank] * s2 / np.outer(colscale, colscale)
        err[free] = np.where(blind > BLIND_SHARE, math.inf,
                             np.sqrt(np.clip(np.diag(cov), 0.0, None)))
    t = special.stdtrit(max(dof, 1), 0.975)  # Student's t quantile
    return [Estimate(n, float(v), u, float(e), (float(v - t * e), float(v + t * e)))
            for n, v, u, e in zip(names, result.x, units, err)]


def unseen(est: list[Estimate], w: np.ndarray) -> list[Estimate]:
    """``est`` (c1, c2, c3, ...) with the constants the curve's form keeps the data from
    determining marked so (an infinite standard error), whatever the Jacobian's round-off
    says: all three where the points lie at fewer than three speed magnitudes other than
    zero (the curve is odd and passes through 0, so three constants need three), and c3
    where c2 rests at its bound 0 (the arctangent term, and with it c3, then leaves the
    curve)."""
    speeds = np.unique(np.abs(np.asarray(w, dtype=float)))
    few = np.count_nonzero(speeds) < 3
    flat = est[1].status == "at a bound"  # its only bound is 0

    def blind(e: Estimate) -> Estimate:
        return replace(e, stderr=math.inf, ci95=(-math.inf, math.inf))

    return [blind(e) if e.status != "at a bound" and (few and k < 3 or flat and k == 2)
            else e for k, e in enumerate(est)]


def serial_inflation(residuals: np.ndarray, size: float | None = None
                     ) -> tuple[float, float]:
    """``(factor, rho)``: how far the correlation of the residuals from row to row (in
    the data's order) widens the variance of the estimates, and their lag-1
    autocorrelation.

    Least squares takes the residuals as independent. Neighbouring samples of a time
    series are not when the model leaves structure out (a transient, a ripple without
    its angle), and then the classical variance is too small by the ratio of the
    residuals' long-run variance to their variance. That ratio is estimated with a
    Bartlett window, weights ``1 - j / S`` at lag ``j``, whose width ``S`` follows
    Andrews's AR(1) plug-in rule (`serial_window`), an approximation that holds where
    the Jacobian's rows change slowly beside the correlation's length, as they do
    along a sweep or a plateau. The factor is 1 unless the lag-1 autocorrelation
    exceeds what chance gives independent residuals (2 / sqrt(n), about the one-sided
    2.5 % point), so independent points keep their classical intervals; and for fewer
    than 8 residuals, residuals that are not all finite, and residuals without
    variance: a constant, or rounding, a billionth of ``size`` or less (the data's
    size, such as the largest measured value; default the residuals' own)."""
    raw = np.asarray(residuals, dtype=float)
    n = len(raw)
    if n < 8 or not np.all(np.isfinite(raw)):
        return 1.0, 0.0
    e = raw - raw.mean()
    # autocovariances at every lag, from one zero-padded FFT (not a quadratic sum)
    spectrum = np.fft.rfft(e, 2 * n)
    gamma = np.fft.irfft(spectrum * np.conj(spectrum), 2 * n)[:n] / n
    size = float(np.max(np.abs(raw))) if size is None else abs(float(size))
    if not gamma[0] > (1e-9 * size) ** 2:
        return 1.0, 0.0
    rho = float(gamma[1] / gamma[0])
    if rho <= 2.0 / math.sqrt(n):
        return 1.0, rho
    width = serial_window(rho, n)
    lags = np.arange(1, min(math.ceil(width), n))
    long_run = gamma[0] + 2.0 * np.sum((1.0 - lags / width) * gamma[lags])
    return max(1.0, float(long_run / gamma[0])), rho


def serial_window(rho: float, n: int) -> float:
    """Width ``S`` of the Bartlett window of `serial_inflation` for ``n`` residuals of
    lag-1 autocorrelation ``rho``: Andrews's plug-in rule for an AR(1) series,
    ``S = 1.1447 (alpha n)^(1/3)`` with ``alpha = 4 rho^2 / ((1 - rho)^2 (1 + rho)^2)``
    (Andrews 1991, Econometrica 59: 817, section 6), which balances the window's bias
    against its variance."""
    r = min(rho, 1.0 - 1e-6)  # a residual that is all trend: the window spans the data
    alpha = 4.0 * r ** 2 / ((1.0 - r) ** 2 * (1.0 + r) ** 2)
    return 1.1447 * (alpha * n) ** (1.0 / 3.0)


def plateaus(time: np.ndarray, velocity: np.ndarray) -> list[slice]:
    """Index ranges where the speed stays constant long enough (transient removed)."""
    out = []
    n = len(time)
    start = 0
    while start < n:
        ref = velocity[start]
        tol = PLATEAU_TOLERANCE * abs(ref) + 0.005
        end = _departure(velocity, start + 1, ref, tol)
        if time[end - 1] - time[start] >= PLATEAU_MIN_DURATION and abs(ref) > 1e-9:
            skip = int(math.ceil(TRANSIENT_FRACTION * (end - start)))
            tail = int(math.ceil(TAIL_FRACTION * (end - start)))  # the next ramp's start
            out.append(slice(start + skip, end - tail))
        start = end
    return out


def _departure(values: np.ndarray, i: int, ref: float, tol: float) -> int:
    """The first index from ``i`` on where ``values`` leaves ``ref +- tol`` (the length
    if none), searched in chunks that double, so that a long plateau costs a few
    array operations and a short one little more than its length."""
    n = len(values)
    chunk = 64
    while i < n:
        j = min(n, i + chunk)
        hit = np.flatnonzero(np.abs(values[i:j] - ref) > tol)
        if hit.size:
            return i + int(hit[0])
        i = j
        chunk *= 2
    return n


def _ripple(coef, method: str) -> Ripple:
    grid = np.linspace(0, 2 * math.pi, 181)
    shape = _fourier(grid) @ coef
    return Ripple(method, float(np.sqrt(np.mean(shape ** 2))), float(np.ptp(shape)), grid, shape)


def _fourier(angle: np.ndarray) -> np.ndarray:
    cols = [np.ones_like(angle)]
    for k in range(1, RIPPLE_HARMONICS + 1):
        cols += [np.cos(k * angle), np.sin(k * angle)]
    return np.column_stack(cols)


#: The c3 grid of `_profile_c3` [s/rad].
C3_GRID = np.logspace(-2, 4, 121)


def _profile_c3(w, T, extra=None):
    """The best c3 on a log grid, with c1, c2 >= 0 (and any extra linear columns) solved
    exactly for each: the model is linear in everything but c3.

    A starting point for the full fit. Only the arctan column changes with c3, so
    the normal equations of every grid point are built at once (one matrix
    product) and solved as one stack. The bounds c1, c2 >= 0: the bounded optimum
    is the unconstrained minimum on one of the four faces (c1 and c2 each free or
    zero), so the best feasible face minimum is it (ties go to the smaller c3,
    then to the face with more free constants).
    """
    w = np.asarray(w, dtype=float)
    T = np.asarray(T, dtype=float)
    E = np.zeros((len(w), 0)) if extra is None else np.asarray(extra, dtype=float)
    fixed = np.column_stack([w, E])             # the columns that do not depend on c3
    G_fixed = fixed.T @ fixed
    b_fixed = fixed.T @ T
    TT = float(T @ T)
    k = fixed.shape[1] + 1                      # unknowns: c1, c2, then the extra columns
    grid = len(C3_GRID)
    A = np.arctan(C3_GRID[:, None] * w[None, :])  # the arctan column of every grid point
    # unknown order: c1 (w), c2 (a), extra columns
    G = np.empty((grid, k, k))
    b = np.empty((grid, k))
    G[:, 0, 0] = G_fixed[0, 0]
    G[:, 0, 2:] = G[:, 2:, 0] = G_fixed[0, 1:]
    G[:, 2:, 2:] = G_fixed[1:, 1:]
    G[:, 1, 1] = np.einsum("gi,gi->g", A, A)
    G[:, 0, 1] = G[:, 1, 0] = A @ w
    aE = A @ E
    G[:, 1, 2:] = aE
    G[:, 2:, 1] = aE
    b[:, 0], b[:, 1], b[:, 2:] = b_fixed[0], A @ T, b_fixed[1:]
    faces = ((0, 1), (1,), (0,), ())
    costs = np.full((grid, len(faces)), math.inf)
    solutions = np.zeros((grid, len(faces), k))
    for f, free in enumerate(faces):
        keep = list(free) + list(range(2, k))
        x = np.zeros((grid, k))
        if keep:
            Gs = G[:, keep][:, :, keep]
            bs = b[:, keep]
            try:
                x[:, keep] = np.linalg.solve(Gs, bs[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                x[:, keep] = np.array([np.linalg.lstsq(g, r, rcond=None)[0]
                                       for g, r in zip(Gs, bs)])
        cost = 0.5 * (TT - 2.0 * np.einsum("gi,gi->g", b, x)
                      + np.einsum("gi,gij,gj->g", x, G, x))
        feasible = (x[:, 0] >= 0.0) & (x[:, 1] >= 0.0)
        costs[:, f] = np.where(feasible, cost, math.inf)
        solutions[:, f] = x
    g, f = np.unravel_index(int(np.argmin(costs)), costs.shape)
    lin = solutions[g, f]
    return np.concatenate([[lin[0], lin[1], C3_GRID[g]], lin[2:]])


def fit_curve(m: Measurement) -> FrictionFit:
    """Fit T = c1 w + c2 atan(c3 w) to one torque-velocity measurement."""
    if "velocity" not in m or "torque" not in m:
        raise InputError(f"{m.path}: a friction fit needs velocity and torque columns")
    notes: list[str] = []
    angle = m.columns.get("angle")
    w, T = np.asarray(m["velocity"], dtype=float), np.asarray(m["torque"], dtype=float)
    lengths = {len(np.ravel(v)) for v in m.columns.values()}
    if w.ndim != 1 or len(lengths) > 1:
        raise InputError(f"{m.path}: the columns must be 1-D and of one length, got "
                         f"{', '.join(f'{k} {np.shape(v)}' for k, v in m.columns.items())}")
    if not (np.all(np.isfinite(w)) and np.all(np.isfinite(T))):
        raise InputError(f"{m.path}: velocity and torque must be finite (a NaN or inf is in "
                         "them)")
    raw = (w, T)
    if "time" not in m:
        form, keep = "points", np.arange(len(w))
    else:
        segments = plateaus(m["time"], w)
        covered = sum(s.stop - s.start for s in segments) / len(m)
        if len(segments) >= 4 and covered >= 0.3:
            form = "segments"
            keep = np.concatenate([np.arange(s.start, s.stop) for s in segments])
        else:
            form, keep = "sweep", np.arange(len(w))
    ripple = None
    if form != "points" and angle is not None:
        # every kept sample, friction and ripple together: T = curve(w) + sign(w) F(angle),
        # F a Fourier series in the carrier angle, mirrored with the direction (fig 4.6)
        w, T = w[keep], T[keep]
        A = _fourier(np.mod(angle[keep], 2 * math.pi))[:, 1:] * np.sign(w)[:, None]

        def residual(p):
            return curve(p[:3], w) + A @ p[3:] - T

        p0 = _profile_c3(w, T, A)
        lower = [0.0, 0.0, 1e-6] + [-np.inf] * A.shape[1]
        result = least_squares(residual, p0, bounds=(lower, np.inf), x_scale="jac")
        ripple = _ripple(np.concatenate([[0.0], result.x[3:]]), "Fourier series in the carrier "
                         "angle, fitted with the curve to every sample" +
                         (" of the plateaus" if form == "segments" else ""))
        # the points shown are the plateau means with the fitted ripple taken out
        if form == "segments":
            rip = A @ result.x[3:]
            w, T = _means(segments, m["velocity"], m["torque"], keep, rip)
    else:
        if form == "segments":
            w, T = _means(segments, m["velocity"], m["torque"], keep, None)
        elif form == "sweep":
            w, T = w[keep], T[keep]
        result = least_squares(lambda p: curve(p, w) - T, _profile_c3(w, T),
                               bounds=([0, 0, 1e-6], np.inf), x_scale="jac")
    if len(result.fun) < 4:
        raise InputError(f"{m.path}: {len(result.fun)} usable points ({form}); at least 4 speeds "
                         "are needed to fit three constants")
    if not result.success:
        raise SimulationError(f"{m.path}: the friction fit did not converge ({result.message})")
    if np.all(raw[0] >= 0) or np.all(raw[0] <= 0):
        notes.append("all speeds have one sign: the fit assumes the curve is odd")
    dof = len(result.fun) - len(result.x)
    names = ["c1", "c2", "c3"] + [f"ripple{i}" for i in range(len(result.x) - 3)]
    units = ["N m s/rad", "N m", "s/rad"] + ["N m"] * (len(result.x) - 3)
    factor, rho = serial_inflation(result.fun, size=float(np.max(np.abs(T))))
    if factor > 1.0:
        notes.append(_correlated(form, rho, factor, len(result.fun), angle is not None))
    est = unseen(estimates(result, names, units, dof, scale=factor), w)
    for status, why in (("not determined", "not determined by these data (points at 4 or "
                                            "more different speeds are needed, and for c3 a "
                                            "curve with c2 > 0)"),
                        ("at a bound", "at a bound of the fit")):
        which = [e.name for e in est[:3] if e.status == status]
        if which:
            notes.append(f"{', '.join(which)}: {why}; no interval")
    return FrictionFit(c1=est[0], c2=est[1], c3=est[2], form=form, velocity=np.asarray(w),
                       torque=np.asarray(T), residual_rms=float(np.sqrt(np.mean(result.fun ** 2))),
                       dof=dof, ripple=ripple, raw=raw, source=m.path, synthetic=m.synthetic,
                       notes=notes)


def _correlated(form: str, rho: float, factor: float, n: int, has_angle: bool) -> str:
    """The note of a fit whose residuals are correlated from row to row
    (`serial_inflation`): what it means and what usually causes it."""
    if form == "points":
        cause = (f"{n} rows taken as one averaged speed each: if this is a time series, "
                 "give its time column, and the plateaus are averaged after their "
                 "transients")
    elif not has_angle:
        cause = ("an angle-dependent ripple (fig 4.6) with no angle column to fit it: give "
                 "the carrier angle")
    else:
        cause = "a transient or a ripple that the model does not describe"
    return (f"the residuals are correlated from row to row (lag-1 autocorrelation "
            f"{rho:.2f}), so the data hold structure the curve does not explain ({cause}); "
            f"the standard errors are widened {math.sqrt(factor):.3g}x for it, but the "
            "constants themselves may be biased")


def _means(segments, velocity, torque, keep, ripple):
    """Mean speed and torque of each plateau (less the fitted ripple, if given)."""
    corrected = torque[keep] - (0.0 if ripple is None else ripple)
    speeds, torques, start = [], [], 0
    for seg in segments:
        n = seg.stop - seg.start
        speeds.append(float(np.mean(velocity[keep][start:start + n])))
        torques.append(float(np.mean(corrected[start:start + n])))
        start += n
    return np.array(speeds), np.array(torques)
