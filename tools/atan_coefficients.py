"""The polynomial of the engine's arctangent (``vsj__atan`` in engine/c/internal.h), and
the error of the whole function.

The engine reduces |x| about the nearest of the centres 0, 1/2, 1, 3/2 and infinity to
|t| <= 7/16 and evaluates atan(t) = t + t^3 P(t^2). P is the degree-10 Chebyshev fit
(near minimax) of (atan(sqrt u) - sqrt u) / u^1.5 on u in [0, (7/16)^2], computed in
50-digit arithmetic by mpmath (a development tool: vsj itself does not need it). The
script prints the coefficients, lowest degree first, and the atan of each centre as two
doubles. It then repeats the engine's operations in the same order in Python's floats
(IEEE doubles, each operation rounded to nearest, as C without contracted
multiply-adds) and prints, for each interval of the reduction, the largest difference
from the exact arctangent over random arguments and the neighbours of its ends, in units
in the last place of the exact value.

    python tools/atan_coefficients.py
"""

import math
import random

import mpmath as mp

mp.mp.dps = 50
DEGREE = 10
#: the reduction's centres and where each takes over from the one before
CENTRES = (0.0, 0.5, 1.0, 1.5, math.inf)
SWITCHES = (0.4375, 0.6875, 1.1875, 2.4375)


def remainder(u):
    """(atan(sqrt u) - sqrt u) / u^1.5, -1/3 at u = 0."""
    if u == 0:
        return mp.mpf(-1) / 3
    s = mp.sqrt(u)
    return (mp.atan(s) - s) / (u * s)


def split(value) -> tuple[float, float]:
    """The double nearest ``value`` and the double nearest what it leaves out."""
    hi = float(value)
    return hi, float(value - mp.mpf(hi))


def engine_atan(x: float, c: list[float], hi: list[float], lo: list[float]) -> float:
    """vsj__atan's operations, in its order."""
    a = abs(x)
    r = sum(a > s for s in SWITCHES)
    if r == 4:
        t = -1.0 / a
    elif r == 0:
        t = a
    else:
        centre = CENTRES[r]
        t = (a - centre) / (a + 1.0 if centre == 1.0 else 1.0 + centre * a)
    u = t * t
    u2 = u * u
    u4 = u2 * u2
    p = ((c[0] + c[1] * u) + u2 * (c[2] + c[3] * u)
         + u4 * ((c[4] + c[5] * u) + u2 * (c[6] + c[7] * u))
         + u4 * u4 * ((c[8] + c[9] * u) + u2 * c[10]))
    return math.copysign(hi[r] + (t + (lo[r] + t * u * p)), x)


def ulps(value: float, x: float) -> float:
    """|value - atan(x)| in units in the last place of the exact atan(x)."""
    exact = mp.atan(mp.mpf(x))
    return float(abs(mp.mpf(value) - exact) / mp.mpf(math.ulp(float(exact))))


def main() -> None:
    top = mp.mpf(7) / 16
    c = [float(v) for v in reversed(mp.chebyfit(remainder, [0, top * top], DEGREE + 1))]
    print("c[11] = {" + ", ".join(repr(v) for v in c) + "}")
    pairs = [split(mp.atan(mp.mpf(centre))) for centre in CENTRES[1:-1]]
    hi = [0.0] + [h for h, _ in pairs] + [split(mp.pi / 2)[0]]
    lo = [0.0] + [v for _, v in pairs] + [split(mp.pi / 2)[1]]
    print("hi[5] = {" + ", ".join(repr(v) for v in hi) + "}")
    print("lo[5] = {" + ", ".join(repr(v) for v in lo) + "}")
    rng = random.Random(1)
    ends = (1e-12,) + SWITCHES + (1e12,)
    for left, right in zip(ends, ends[1:]):
        xs = [math.exp(rng.uniform(math.log(left), math.log(right))) for _ in range(20000)]
        for end in (left, right):  # the neighbours of the interval's ends
            y = end
            for _ in range(200):
                xs += [y, -y]
                y = math.nextafter(y, math.inf)
        worst = max(ulps(engine_atan(x, c, hi, lo), x) for x in xs)
        print(f"|x| in [{left:g}, {right:g}]: largest error {worst:.3f} ulp")


if __name__ == "__main__":
    main()
