"""The elastic element's stiffness from torque-deflection curves (report section 4.2).

For each curve (one pivot position q) the loop is described, in its linear
regime, by

    T = K (phi - p sign(T)) + h sign(dphi/dt) + T0

with the linear stiffness K, the friction hysteresis h (half the loop's width
in torque, the same at every speed: fig 4.10-4.12), an offset T0 and the play p
of the pivot (the deflection crosses a band of width 2p while the torque
changes sign, fig 4.12). The model is linear in (K, K p, h, T0), so each fit is
ordinary least squares.

The linear regime is found automatically: the local stiffness is fitted in
bands of ``|phi|`` and the regime is the run of bands, from zero deflection out,
whose stiffness stays within `LINEAR_BAND` of the innermost band. Where the
stiffness then drops, a spring has lost its pretension (section 4.2.2); the
deflection where that happens is reported. Play is reported when p is larger
than both three standard errors and `PLAY_MIN`.

The stiffness values then give K(q) = a1 exp(a2 q) + a3 (eq 4.5, fig 4.13),
fitted on relative deviations (K spans two decades), with standard errors
and 95 % intervals from the residual scatter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import special
from scipy.optimize import least_squares

from ..errors import InputError, SimulationError
from ..measurements import LIMITS, Measurement
from ..units import to_si
from .friction import Estimate, estimates

#: Bands of ``|phi|`` whose local stiffness is within this fraction of the innermost
#: band's belong to the linear regime.
LINEAR_BAND = 0.10
#: A drop of the local stiffness by more than this fraction marks loss of pretension.
LOSS_DROP = 0.25
BANDS = 10
#: Smallest play reported [rad].
PLAY_MIN = 2e-3
#: Play is estimated on deflections up to this fraction of the largest.
INNER = 0.4


@dataclass
class CurveFit:
    """The linear description of one torque-deflection curve."""

    source: str
    q: float
    K: Estimate
    hysteresis: Estimate
    offset: Estimate
    play: Estimate
    play_detected: bool
    linear_limit: float                # |phi| up to which the curve is linear [rad]
    pretension_loss: float | None      # |phi| where the stiffness drops [rad], if seen
    band_phi: np.ndarray               # band centres [rad]
    band_K: np.ndarray                 # local stiffness per band [N m/rad]
    deflection: np.ndarray
    torque: np.ndarray
    direction: np.ndarray              # sign of dphi/dt per sample
    used: np.ndarray                   # samples in the linear fit
    synthetic: bool = False
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        """The curve's fit (K, hysteresis, offset, play, linear limit, pretension loss) as
        plain JSON data (SI values with their units)."""
        return {"file": self.source, "synthetic": self.synthetic, "q": {"value": self.q,
                                                                        "unit": "m"},
                "K": self.K.to_json(), "hysteresis": self.hysteresis.to_json(),
                "offset": self.offset.to_json(),
                "play": {**self.play.to_json(), "detected": self.play_detected},
                "linear_limit": {"value": self.linear_limit, "unit": "rad"},
                "pretension_loss": None if self.pretension_loss is None else
                {"value": self.pretension_loss, "unit": "rad"},
                "notes": self.notes}


@dataclass
class ExponentialFit:
    """K(q) = a1 exp(a2 q) + a3 over the curves (eq 4.5)."""

    a1: Estimate
    a2: Estimate
    a3: Estimate
    q: np.ndarray
    K: np.ndarray
    relative_rms: float

    def predict(self, q) -> np.ndarray:
        """Stiffness ``a1 exp(a2 q) + a3`` [N m/rad] at pivot positions ``q`` [m] (report eq
        4.5)."""
        return self.a1.value * np.exp(self.a2.value * np.asarray(q)) + self.a3.value

    def to_json(self) -> dict:
        """The exponential fit (a1, a2, a3, relative rms) as plain JSON data (SI values with
        their units)."""
        return {"model": "K = a1 exp(a2 q) + a3", "a1": self.a1.to_json(),
                "a2": self.a2.to_json(), "a3": self.a3.to_json(),
                "relative_rms": self.relative_rms}


@dataclass
class StiffnessFit:
    """Result of `fit_stiffness`: one `CurveFit` per curve and, with curves at enough pivot
    positions, the exponential K(q) over them (else None)."""
    curves: list[CurveFit]
    exponential: ExponentialFit | None

    def to_json(self) -> dict:
        """The fits of every curve and the exponential as plain JSON data (SI values with
        their units)."""
        return {"curves": [c.to_json() for c in self.curves],
                "synthetic": any(c.synthetic for c in self.curves),
                "exponential": None if self.exponential is None else
                self.exponential.to_json()}


def pivot_of(m: Measurement) -> float:
    """The pivot position of a curve [m]: its pivot column, or a ``# pivot: 1.4 cm`` line."""
    if "pivot" in m:
        q = m["pivot"]
        if np.ptp(q) > 1e-6:
            raise InputError(f"{m.path}: the pivot column changes ({q.min() * 100:g} to "
                             f"{q.max() * 100:g} cm); one curve needs one pivot position")
        return float(np.mean(q))
    text = m.comment_value("pivot")
    if text is None:
        raise InputError(f"{m.path}: no pivot position; add a 'pivot [cm]' column or a "
                         "comment line '# pivot: 1.4 cm'")

    where = f"{m.path}, comment 'pivot: {text}'"
    q = to_si(text, "m", where=where)
    limit, why = LIMITS["pivot"]
    if not abs(q) <= limit:
        raise InputError(f"{where}: {q * 100:.3g} cm is beyond +-{limit * 100:g} cm ({why}); "
                         "check the value and its unit")
    return q


def _direction(m: Measurement) -> np.ndarray:
    """Sign of the deflection rate, from a smoothed derivative (time order)."""
    phi = m["deflection"]
    t = m["time"] if "time" in m else np.arange(len(phi), dtype=float)
    span = max(3, len(phi) // 200)
    kernel = np.ones(span) / span
    smooth = np.convolve(phi, kernel, mode="same")
    d = np.gradient(smooth, t)
    s = np.sign(d)
    # samples at a standstill take the direction of the motion before them
    for i in range(1, len(s)):
        if s[i] == 0:
            s[i] = s[i - 1]
    return s


def _regression(phi, T, direction, with_play: bool):
    cols = [phi, direction, np.ones_like(phi)] + ([-np.sign(T)] if with_play else [])
    A = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(A, T, rcond=None)
    r = T - A @ coef
    dof = max(len(T) - A.shape[1], 1)
    s2 = float(r @ r) / dof
    cov = np.linalg.pinv(A.T @ A) * s2
    return coef, np.sqrt(np.clip(np.diag(cov), 0, None)), cov, dof, math.sqrt(s2)


def fit_curve(m: Measurement) -> CurveFit:
    """Linear stiffness, hysteresis, play, linear regime and pretension loss of one curve."""
    for quantity in ("deflection", "torque"):
        if quantity not in m:
            raise InputError(f"{m.path}: a stiffness fit needs deflection and torque columns")
    q = pivot_of(m)
    phi, T = m["deflection"], m["torque"]
    direction = _direction(m)
    if np.all(direction > 0) or np.all(direction < 0):
        raise InputError(f"{m.path}: the deflection only moves one way; a loop (back and "
                         "forth) is needed to separate stiffness from friction")
    reach = float(np.max(np.abs(phi)))
    if reach <= 0:
        raise InputError(f"{m.path}: the deflection is zero throughout")
    # torque noise from sample-to-sample differences (the signal is slow beside them)
    noise = float(np.median(np.abs(np.diff(T)))) / (0.6745 * math.sqrt(2.0))
    # 1. play, from the inner part (where the curve is most likely linear), leaving out
    # the samples near zero torque where a pivot with play would be crossing it
    near_zero = np.abs(T) < 4 * noise
    inner = (np.abs(phi) <= INNER * reach) & ~near_zero
    coef, err, cov, _, sd = _regression(phi[inner], T[inner], direction[inner], True)
    K0, Kp = coef[0], coef[3]
    play = Kp / K0 if K0 > 0 else 0.0
    play_err = abs(play) * math.hypot(err[0] / K0, err[3] / max(abs(Kp), 1e-300)) \
        if K0 > 0 else math.inf
    play_detected = play > max(3 * play_err, PLAY_MIN)
    corrected = phi - (play * np.sign(T) if play_detected else 0.0)
    # samples while the pivot crosses its play carry no stiffness information
    crossing = near_zero if play_detected else np.zeros(len(T), bool)
    # 2. local stiffness in bands of |phi|
    edges = np.linspace(0.0, float(np.max(np.abs(corrected))), BANDS + 1)
    band_K, band_phi = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (np.abs(corrected) >= lo) & (np.abs(corrected) <= hi) & ~crossing
        if sel.sum() < 10 or np.ptp(corrected[sel]) <= 0:
            band_K.append(math.nan)
        else:
            # a band on both sides of zero: slope through each side separately
            slopes = []
            for side in (1, -1):
                s = sel & (np.sign(corrected) == side)
                if s.sum() >= 6 and np.ptp(corrected[s]) > 0:
                    A = np.column_stack([corrected[s], direction[s], np.ones(s.sum())])
                    slopes.append(np.linalg.lstsq(A, T[s], rcond=None)[0][0])
            band_K.append(float(np.mean(slopes)) if slopes else math.nan)
        band_phi.append(0.5 * (lo + hi))
    band_K, band_phi = np.array(band_K), np.array(band_phi)
    valid = np.flatnonzero(np.isfinite(band_K))
    if valid.size < 2:
        raise InputError(f"{m.path}: too few samples spread over the deflection to find the "
                         "linear regime")
    ref = float(np.median(band_K[valid[:2]]))  # the innermost bands' stiffness
    limit_band = valid[0]
    for i in valid:
        if abs(band_K[i] / ref - 1) <= LINEAR_BAND:
            limit_band = i
        else:
            break
    linear_limit = float(edges[limit_band + 1])
    loss = None
    for i in valid:
        if i > limit_band and band_K[i] < (1 - LOSS_DROP) * ref:
            loss = float(edges[i])
            break
    notes = []
    if loss is not None:
        notes.append(f"the stiffness drops beyond |phi| = {loss:.3g} rad: a spring loses its "
                     "pretension (section 4.2.2)")
    if linear_limit < float(edges[-1]) and loss is None:
        notes.append(f"the curve leaves the linear regime at |phi| = {linear_limit:.3g} rad")
    # 3. the linear fit on the linear regime
    used = (np.abs(corrected) <= linear_limit) & ~crossing
    if used.sum() < 10:
        raise InputError(f"{m.path}: only {int(used.sum())} samples in the linear regime")
    coef, err, cov, dof, sd = _regression(phi[used], T[used], direction[used], play_detected)
    t = special.stdtrit(dof, 0.975)  # Student's t quantile

    def est(name, value, e, unit):
        return Estimate(name, float(value), unit, float(e), (float(value - t * e),
                                                             float(value + t * e)))

    K = coef[0]
    if not K > 0:
        raise SimulationError(f"{m.path}: the fitted stiffness is {K:.3g} N m/rad; the curve "
                              "does not describe a spring")
    if play_detected:
        p = coef[3] / K
        pe = abs(p) * math.sqrt(max((err[3] / coef[3]) ** 2 + (err[0] / K) ** 2
                                    - 2 * cov[0, 3] / (K * coef[3]), 0.0))
    else:
        p, pe = 0.0, 0.0
    return CurveFit(
        source=m.path, q=q, K=est("K", K, err[0], "N m/rad"),
        hysteresis=est("hysteresis", coef[1], err[1], "N m"),
        offset=est("offset", coef[2], err[2], "N m"), play=est("play", 2 * p, 2 * pe, "rad"),
        play_detected=bool(play_detected), linear_limit=linear_limit, pretension_loss=loss,
        band_phi=band_phi, band_K=band_K, deflection=phi, torque=T, direction=direction,
        used=used, synthetic=m.synthetic, notes=notes)


def fit_exponential(q, K) -> ExponentialFit:
    """K(q) = a1 exp(a2 q) + a3 (eq 4.5) on relative deviations; q in m, K in N m/rad
    (`InputError` unless both are finite 1-D arrays of one length, q within the pivot
    positions a bench reaches and K > 0)."""
    try:
        q, K = np.asarray(q, float), np.asarray(K, float)
    except (TypeError, ValueError):
        raise InputError("the fit of K(q): q and K must be sequences of numbers") from None
    if q.ndim != 1 or K.ndim != 1 or len(q) != len(K):
        raise InputError(f"the fit of K(q): q and K must be 1-D and of one length, got shapes "
                         f"{q.shape} and {K.shape}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(K))):
        raise InputError("the fit of K(q): q and K must be finite (a NaN or inf is in them)")
    limit, why = LIMITS["pivot"]
    if np.any(np.abs(q) > limit):
        raise InputError(f"the fit of K(q): q = {q[np.argmax(np.abs(q))]:g} m is beyond "
                         f"+-{limit * 100:g} cm ({why}); q is in metres")
    if np.any(K <= 0.0):
        raise InputError(f"the fit of K(q): K = {K[np.argmin(K)]:g} N m/rad; a spring's "
                         "stiffness is > 0")
    if len(q) < 4:
        raise InputError(f"the fit of K(q) needs curves at 4 or more pivot positions, got "
                         f"{len(q)}")
    if len(np.unique(np.round(q, 6))) < 3:
        raise InputError("the fit of K(q) needs at least 3 different pivot positions")

    def residual(p):
        return (p[0] * np.exp(p[1] * q) + p[2]) / K - 1.0

    # a2 by profile over a grid (the model is linear in a1, a3 for fixed a2)
    best = None
    for a2 in np.linspace(-600, 600, 241):
        A = np.column_stack([np.exp(a2 * q), np.ones_like(q)]) / K[:, None]
        lin, *_ = np.linalg.lstsq(A, np.ones_like(q), rcond=None)
        cost = float(np.sum((A @ lin - 1) ** 2))
        if best is None or cost < best[0]:
            best = (cost, a2, lin)
    _, a2, (a1, a3) = best
    result = least_squares(residual, [a1, a2, a3], x_scale="jac")
    if not result.success:
        raise SimulationError(f"the fit of K(q) did not converge ({result.message})")

    dof = len(q) - 3
    est = estimates(result, ["a1", "a2", "a3"], ["N m/rad", "1/m", "N m/rad"], max(dof, 1))
    return ExponentialFit(*est, q=q, K=K,
                          relative_rms=float(np.sqrt(np.mean(result.fun ** 2))))


def fit_stiffness(measurements: list[Measurement]) -> StiffnessFit:
    """Fit every curve, then K(q) when there are enough pivot positions."""
    if not measurements:
        raise InputError("no torque-deflection files given")
    curves = sorted((fit_curve(m) for m in measurements), key=lambda c: -c.q)
    exponential = None
    if len(curves) >= 4:
        exponential = fit_exponential([c.q for c in curves], [c.K.value for c in curves])
    return StiffnessFit(curves, exponential)
