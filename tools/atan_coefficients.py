"""The polynomial of the engine's arctangent (``vsj__atan`` in engine/c/internal.h).

The engine reduces |x| to |t| <= tan(pi/8) and evaluates atan(t) = t + t^3 P(t^2). P
is the degree-10 Chebyshev fit (near minimax) of (atan(sqrt u) - sqrt u) / u^1.5 on
u in [0, tan(pi/8)^2], computed in 50-digit arithmetic by mpmath (a development tool:
vsj itself does not need it). The script prints the coefficients, lowest degree first,
and the largest relative error of t + t^3 P(t^2) in double precision over 200 001
points of the interval, in units of 2^-52.

    python tools/atan_coefficients.py
"""

import mpmath as mp
import numpy as np

mp.mp.dps = 50
DEGREE = 10


def remainder(u):
    """(atan(sqrt u) - sqrt u) / u^1.5, -1/3 at u = 0."""
    if u == 0:
        return mp.mpf(-1) / 3
    s = mp.sqrt(u)
    return (mp.atan(s) - s) / (u * s)


def main() -> None:
    top = mp.tan(mp.pi / 8)
    coefficients = [float(c) for c in reversed(mp.chebyfit(remainder, [0, top * top],
                                                           DEGREE + 1))]
    print("c[11] = {" + ", ".join(repr(c) for c in coefficients) + "}")
    worst = 0.0
    for t in np.linspace(-float(top), float(top), 200_001):
        if t == 0.0:
            continue
        u = t * t
        p = 0.0
        for c in reversed(coefficients):
            p = p * u + c
        value = t + t * u * p
        exact = mp.atan(mp.mpf(t))
        worst = max(worst, float(abs(mp.mpf(value) - exact) / abs(exact)))
    # relative error in units of 2^-52 (an ulp at 1; half of one is the last sum's rounding)
    print(f"largest relative error: {worst / np.finfo(float).eps:.3f} x 2^-52")


if __name__ == "__main__":
    main()
