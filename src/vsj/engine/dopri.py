"""Adaptive Dormand-Prince 5(4) integration with dense output, compiled.

The smooth solver, for friction laws that are functions of speed (viscous,
arctan, sign, slope). Coefficients and the step-size controller follow Hairer,
Norsett and Wanner, *Solving Ordinary Differential Equations I* (DOPRI5): a
fifth-order solution, an embedded fourth-order error estimate, a PI step
controller and a fourth-order continuous extension used to sample the output
times without shortening steps.

The energy accumulators ride along in the state vector but are excluded from
the error norm (``n_err``): they never shorten a step.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import inline, kernel, loop
from .core import NOT_FINITE, OK, STATUS, STEP_TOO_SMALL, TOO_MANY_STEPS, eval_derivatives

#: Butcher tableau: nodes and coefficients of stages 2-7 (stage 7 is the solution).
C = np.array([0.0, 0.2, 0.3, 0.8, 8.0 / 9.0, 1.0, 1.0])
A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.2, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0],
    [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0],
    [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
])
#: Error estimate: difference of the fifth- and fourth-order weights.
E = np.array([71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0,
              22.0 / 525.0, -1.0 / 40.0])
#: Dense output (Hairer's continuous extension of DOPRI5).
D = np.array([-12715105075.0 / 11282082432.0, 0.0, 87487479700.0 / 32700410799.0,
              -10690763975.0 / 1880347072.0, 701980252875.0 / 199316789632.0,
              -1453857185.0 / 822651844.0, 69997945.0 / 29380423.0])


@inline
def _norm(e, y, y2, rtol, atol, n_err):
    acc = 0.0
    for i in range(n_err):
        sc = atol + rtol * max(abs(y[i]), abs(y2[i]))
        acc += (e[i] / sc) ** 2
    return math.sqrt(acc / max(n_err, 1))


@kernel
def integrate(m, w, y0, t0, t_end, t_out, rtol, atol, h_max, max_steps, n_err, out):
    """Integrate from ``t0`` to ``t_end``; write ``y`` at each ``t_out`` into ``out``.

    Returns ``(status, t, n_steps, n_rejected)``; ``y0`` is overwritten with the
    final state (the last good state on failure). ``out`` may be narrower than
    the state: its columns receive the leading components.
    """
    ny = y0.shape[0]
    scratch = (np.empty((7, ny)), np.empty(ny), np.empty(ny), np.empty(ny), np.empty(ny),
               np.empty(ny), np.empty(ny), y0.copy())
    return _integrate(m, w, scratch, y0, t0, t_end, t_out, rtol, atol, h_max, max_steps, n_err,
                      out)


@inline
def _copy(src, dst):
    for i in range(src.shape[0]):
        dst[i] = src[i]


@loop
def _integrate(m, w, scratch, y0, t0, t_end, t_out, rtol, atol, h_max, max_steps, n_err, out):
    """The loop of `integrate`, over preallocated arrays (compiled as `vsj.jit.loop`,
    without reference counting)."""
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, cum, first, \
        count = m
    hint, chan, srcw, frw, spw, ldw, mow, gen, scal = w
    K, yt, y1, err, r3, r4, r5, y = scratch
    ny = y0.shape[0]
    n_keep = min(ny, out.shape[1])
    t = t0
    n_out = t_out.shape[0]
    i_out = 0
    while i_out < n_out and t_out[i_out] <= t0:
        for i in range(n_keep):
            out[i_out, i] = y[i]
        i_out += 1
    scal[STATUS] = OK
    eval_derivatives(t, y, K[0], dims, mass, Minv, xp, xc, xv, up, uc, uv, par, code, src_ch,
                     src_pos0, knots, coef, cum, first, count, hint, chan, srcw, frw, spw, ldw, mow,
                     gen, scal)
    if scal[STATUS] != OK:
        return int(scal[STATUS]), t, 0, 0
    # initial step (Hairer's estimate)
    d0 = _norm(y, y, y, rtol, atol, n_err)
    d1 = _norm(K[0], y, y, rtol, atol, n_err)
    h = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h = min(h, h_max, t_end - t)
    for i in range(ny):
        yt[i] = y[i] + h * K[0, i]
    eval_derivatives(t + h, yt, K[1], dims, mass, Minv, xp, xc, xv, up, uc, uv, par, code, src_ch,
                     src_pos0, knots, coef, cum, first, count, hint, chan, srcw, frw, spw, ldw, mow,
                     gen, scal)
    for i in range(ny):
        err[i] = K[1, i] - K[0, i]
    d2 = _norm(err, y, y, rtol, atol, n_err) / h
    big = max(d1, d2)
    h1 = max(1e-6, h * 1e-3) if big <= 1e-15 else (0.01 / big) ** 0.2
    h = min(100.0 * h, h1, h_max, t_end - t)
    scal[STATUS] = OK

    err_old = 1e-4
    n_steps = 0
    n_rejected = 0
    rejected_last = False
    while t < t_end:
        if n_steps >= max_steps:
            _copy(y, y0)
            return TOO_MANY_STEPS, t, n_steps, n_rejected
        if h < 1e-14 * max(1.0, abs(t)):
            _copy(y, y0)
            return STEP_TOO_SMALL, t, n_steps, n_rejected
        last = False
        if t + h >= t_end:
            h = t_end - t
            last = True
        stage_bad = False
        for st in range(1, 7):
            for i in range(ny):
                total = 0.0
                for j in range(st):
                    total += A[st, j] * K[j, i]
                yt[i] = y[i] + h * total
            if st == 6:
                for i in range(ny):
                    y1[i] = yt[i]
                if scal[STATUS] == NOT_FINITE:
                    stage_bad = True
                scal[STATUS] = OK  # only the end point's physical limits count
            eval_derivatives(t + C[st] * h, yt, K[st], dims, mass, Minv, xp, xc, xv, up, uc, uv,
                             par, code, src_ch, src_pos0, knots, coef, cum, first, count, hint,
                             chan, srcw, frw, spw, ldw, mow, gen, scal)
        for i in range(ny):
            total = 0.0
            for j in range(7):
                total += E[j] * K[j, i]
            err[i] = h * total
        e = _norm(err, y, y1, rtol, atol, n_err)
        n_steps += 1
        if not math.isfinite(e) or stage_bad or scal[STATUS] == NOT_FINITE:
            scal[STATUS] = OK
            h *= 0.1
            n_rejected += 1
            rejected_last = True
            continue
        fac11 = e ** 0.17
        if e <= 1.0:
            if scal[STATUS] != OK:  # a physical limit was crossed at the new point
                _copy(y1, y0)
                return int(scal[STATUS]), t + h, n_steps, n_rejected
            for i in range(ny):
                d_i = y1[i] - y[i]
                r3[i] = h * K[0, i] - d_i
                r4[i] = d_i - h * K[6, i] - r3[i]
                total = 0.0
                for j in range(7):
                    total += D[j] * K[j, i]
                r5[i] = h * total
            t_new = t + h
            while i_out < n_out and t_out[i_out] <= t_new:
                th = (t_out[i_out] - t) / h
                th1 = 1.0 - th
                for i in range(n_keep):
                    out[i_out, i] = y[i] + th * ((y1[i] - y[i]) + th1 * (r3[i] + th * (
                        r4[i] + th1 * r5[i])))
                i_out += 1
            for i in range(ny):
                y[i] = y1[i]
                K[0, i] = K[6, i]
            t = t_new
            fac = max(0.1, min(5.0, fac11 / err_old ** 0.04 / 0.9))
            h_new = h / fac
            if rejected_last:
                h_new = min(h_new, h)
            err_old = max(e, 1e-4)
            rejected_last = False
            if last:
                break
            h = min(h_new, h_max)
        else:
            scal[STATUS] = OK
            h = h / min(5.0, fac11 / 0.9)
            n_rejected += 1
            rejected_last = True
    _copy(y, y0)
    return OK, t, n_steps, n_rejected
