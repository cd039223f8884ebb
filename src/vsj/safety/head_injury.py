"""The head injury criterion (HIC) of an acceleration time series, and its closed form for
a mass struck through a linear spring.

The HIC of a head acceleration magnitude ``a(t)`` [m/s^2] over windows of at most ``W``
seconds (``W`` = 15 ms for HIC15, 36 ms for HIC36) is

    HIC = max over t1 < t2 <= t1 + W of (t2 - t1) [ (1/(t2 - t1)) int_t1^t2 a dt / g ]^2.5

with ``g`` the standard gravity: the mean acceleration over the window, in g, to the
power 2.5, times the window's length in seconds.

`hic` evaluates it on samples. The integral is the trapezoidal rule's, kept as a running
sum so that each window costs one subtraction; every pair of samples at most ``W`` apart
is a window, so the cost is ``O(n w)`` for ``n`` samples with ``w`` of them in a window
(``O(n^2)`` when the window spans the series). Window ends are sample times: the
maximum found is within ``O((omega h)^2)`` of the continuous one for a pulse whose
acceleration varies at angular frequency ``omega``, sampled every ``h``.

`hic_half_sine` is the closed form for a half-sine pulse ``a(t) = A sin(pi t / T)``,
``0 <= t <= T``, the head's acceleration when a mass-spring impact (Gao and Wampler,
"Head injury criterion", IEEE Robotics & Automation Magazine 16(4), 2009) pushes it
through a linear spring. The form is derived here, not copied from the paper (whose text
could not be read). For a fixed window length the integral of a symmetric pulse that is
concave where it is positive is largest on the window centred on the peak; there, with
``omega = pi/T`` and ``x = omega (t2 - t1)/2``,

    HIC(x) = (A/g)^2.5 (2/omega) sin(x)^2.5 / x^1.5 .

``d ln HIC / dx = 2.5 cot x - 1.5/x`` vanishes at ``tan x = (5/3) x``, ``x* = 1.0528``
(`OPTIMAL_HALF_ANGLE`): the best window spans 0.6702 T around the peak. HIC rises with
``x`` below ``x*``, so when ``W`` is shorter than that span the window is ``W`` long:
``x = min(x*, omega W/2)``. `hic_spring_impact` gives ``A`` and ``T`` of the impact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ._checks import non_negative, number, series, time_axis
from .iso_ts_15066 import reduced_mass

#: Standard gravity [m/s^2], the g of the HIC.
STANDARD_GRAVITY = 9.80665
#: Window lengths of HIC15 and HIC36 [s].
HIC15_WINDOW = 0.015
HIC36_WINDOW = 0.036
#: Sample times carry rounding: a window longer than the limit by no more than this
#: fraction of it counts as within the limit (a window of exactly ``W`` on a grid of
#: spacing ``W/k`` is then not lost to the last bit).
WINDOW_SLACK = 1e-9


def _optimal_half_angle() -> float:
    """The root ``x*`` of ``2.5 x cos x = 1.5 sin x`` in (1, 1.2) (the stationary point of
    the half-sine's HIC), by bisection to the last bit."""
    lo, hi = 1.0, 1.2  # the residual is positive at 1.0 and negative at 1.2
    while True:
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            return mid
        if 2.5 * mid * math.cos(mid) - 1.5 * math.sin(mid) > 0:
            lo = mid
        else:
            hi = mid


#: Half the phase ``omega (t2 - t1)/2`` [rad] of the HIC window of a half-sine pulse when
#: the window limit does not bind: the root of ``tan x = (5/3) x``.
OPTIMAL_HALF_ANGLE = _optimal_half_angle()


@dataclass(frozen=True)
class HeadInjury:
    """A head injury criterion and the window that gives it.

    Attributes
    ----------
    value : float
        HIC [-] (by convention unitless: a time in s times a mean acceleration in g to
        the power 2.5).
    start, end : float
        The window ``t1, t2`` [s] that gives it.
    window : float
        The limit on the window length ``W`` [s].
    """

    value: float
    start: float
    end: float
    window: float


def _reach(t: np.ndarray, limit: float) -> np.ndarray:
    """For each sample, the index of the last sample at most ``limit`` [s] after it."""
    return np.searchsorted(t, t + limit * (1.0 + WINDOW_SLACK), side="right") - 1


def hic(time, acceleration, window: float = HIC15_WINDOW,
        gravity: float = STANDARD_GRAVITY) -> HeadInjury:
    """HIC of sampled head acceleration over windows of at most ``window`` [s].

    Parameters
    ----------
    time : array_like, shape (n,)
        Sample times [s], strictly increasing.
    acceleration : array_like, shape (n,)
        Magnitude of the head's acceleration [m/s^2], >= 0 (the resultant; ``np.abs`` of
        a single axis).
    window : float
        Longest window [s]: `HIC15_WINDOW` (default) or `HIC36_WINDOW`.
    gravity : float
        The g that scales the acceleration [m/s^2].

    Returns
    -------
    HeadInjury
        The value and its window (``value`` 0 and an empty window at the first sample
        when the acceleration is zero throughout).
    """
    where = "hic"
    t = time_axis(where, time)
    a = series(where, "acceleration", acceleration, t.size, "m/s^2")
    non_negative(where, "acceleration", a, "m/s^2",
                 "pass the magnitude of the acceleration (np.abs of a single axis)")
    limit = number(where, "window", window, "s")
    g = number(where, "gravity", gravity, "m/s^2")
    n = t.size
    reach = _reach(t, limit)
    lags = int(np.max(reach - np.arange(n)))
    if lags == 0:
        raise InputError(f"{where}: window {limit!r} s is shorter than every sample spacing "
                         f"(the shortest is {float(np.min(np.diff(t)))!r} s): no window fits")
    # running integral: velocity change from the first sample [m/s]
    v = np.concatenate(([0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))))
    best, where_best = 0.0, (0, 0)
    for lag in range(1, lags + 1):
        length = t[lag:] - t[:-lag]
        mean = (v[lag:] - v[:-lag]) / (g * length)
        value = np.where(reach[:-lag] >= np.arange(lag, n), length * mean ** 2.5, -1.0)
        i = int(np.argmax(value))
        if value[i] > best:
            best, where_best = float(value[i]), (i, i + lag)
    return HeadInjury(best, float(t[where_best[0]]), float(t[where_best[1]]), limit)


def hic_half_sine(peak_acceleration: float, duration: float,
                  window: float = HIC15_WINDOW,
                  gravity: float = STANDARD_GRAVITY) -> HeadInjury:
    """Closed-form HIC of the pulse ``a(t) = A sin(pi t / T)`` on ``0 <= t <= T``.

    ``peak_acceleration`` is ``A`` [m/s^2], ``duration`` is ``T`` [s]; the window is
    centred on the peak (see the module's notes for the derivation), its times measured
    from the pulse's start.
    """
    where = "hic_half_sine"
    peak = number(where, "peak_acceleration", peak_acceleration, "m/s^2")
    span = number(where, "duration", duration, "s")
    limit = number(where, "window", window, "s")
    g = number(where, "gravity", gravity, "m/s^2")
    omega = math.pi / span
    x = min(OPTIMAL_HALF_ANGLE, 0.5 * omega * limit)
    value = (peak / g) ** 2.5 * (2.0 / omega) * math.sin(x) ** 2.5 / x ** 1.5
    return HeadInjury(value, 0.5 * span - x / omega, 0.5 * span + x / omega, limit)


def hic_spring_impact(speed: float, body_mass: float, stiffness: float,
                      robot_mass: float = math.inf, window: float = HIC15_WINDOW,
                      gravity: float = STANDARD_GRAVITY) -> HeadInjury:
    """Closed-form HIC of a free mass ``body_mass`` [kg] struck at relative ``speed``
    [m/s] through a linear spring ``stiffness`` [N/m] by a robot of effective mass
    ``robot_mass`` [kg] (``inf``: one the contact does not slow).

    The relative motion is an undamped oscillation of the reduced mass ``mu`` (ISO/TS
    15066 eq A.3) at ``omega = sqrt(k/mu)`` that lasts half a period, ``T = pi/omega``;
    the contact force peaks at ``v sqrt(mu k)``, so the body's acceleration is a half-sine
    of peak ``A = v sqrt(mu k) / m_H``, whose HIC is `hic_half_sine`'s.
    """
    where = "hic_spring_impact"
    v = number(where, "speed", speed, "m/s")
    m_h = number(where, "body_mass", body_mass, "kg")
    k = number(where, "stiffness", stiffness, "N/m")
    number(where, "robot_mass", robot_mass, "kg", allow_inf=True)
    mu = reduced_mass(m_h, robot_mass)
    omega = math.sqrt(k / mu)
    return hic_half_sine(v * math.sqrt(mu * k) / m_h, math.pi / omega, window, gravity)
