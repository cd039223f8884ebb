"""Compiled evaluation of a model: inputs, element forces, accelerations, energies.

State vector ``y = [x (n), v (n), i (motors)]``: generalised angles and speeds
(the free flanges of the network) and the armature currents. When the smooth
solver integrates, the accumulators of `Layout.acc_slices` follow.

Equations of motion (see `vsj.network`): with flange speeds ``A v + B u`` and
the kinetic energy matrix ``[[M, Msu], [Mus, Mss]]`` over ``(v, u)``,

    M a = sum_elements (A^T torque) - Msu du/dt
    tau_sources = Mus a + Mss du/dt - sum_elements (B^T torque)

where ``tau_sources`` is the torque each velocity source must supply.

The hot functions take explicit arrays and are inlined into the integrators
(see `vsj.engine.model` for why); none of them allocates.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..components.elastic_element import row, spring_law
from ..friction import STICTION, resistive_torque
from ..jit import inline, kernel
from .model import D_CH, D_F, D_K, D_L, D_M, D_N, D_R, D_S

OK = 0
NOT_FINITE = 1
PIVOT_RANGE = 2
TOO_MANY_STEPS = 3
STEP_TOO_SMALL = 4
FRICTION_SOLVER = 5

STATUS_TEXT = {
    OK: "ok",
    NOT_FINITE: "the state or a force became non-finite",
    PIVOT_RANGE: "the pivot position left its allowed range",
    TOO_MANY_STEPS: "the solver reached its maximum number of steps",
    STEP_TOO_SMALL: "the step size fell below the round-off limit (stiff or discontinuous "
                    "dynamics; try the time-stepping solver)",
    FRICTION_SOLVER: "the stiction solver did not converge",
}

# columns of the work arrays
U, UD, SG, SRCF, SRCTAU = range(5)            # srcw (per source)
SLIP, TORQUE, EXTRA = range(3)                # frw (per friction element)
DEFL, RATE, SPTAU, STIFF, ENERGY, DVDQ = range(6)  # spw (per spring)
Q, QDOT, STATUS = range(3)                    # scal


class Work(NamedTuple):
    """Scratch arrays of one integration (one set per thread in a batch)."""

    hint: np.ndarray  # (channels,) int64 last spline piece used
    chan: np.ndarray  # (channels, 3) value, derivative, integral
    srcw: np.ndarray  # (s, 5) speed, acceleration, angle, element torque sum, source torque
    frw: np.ndarray   # (f, 3) slip, torque, Coulomb torque set by the time stepper
    spw: np.ndarray   # (k, 6) deflection, rate, torque, stiffness, energy, dV/dq
    ldw: np.ndarray   # (loads, 2) torque, speed
    mow: np.ndarray   # (motors, 2) rotor speed, voltage
    gen: np.ndarray   # (n,) generalised force
    scal: np.ndarray  # (3,) q, dq/dt, status


@kernel
def make_work(m):
    d = m.dims
    return Work(np.zeros(d[D_CH], np.int64), np.zeros((d[D_CH], 3)), np.zeros((d[D_S], 5)),
                np.zeros((d[D_F], 3)), np.zeros((d[D_K], 6)), np.zeros((d[D_L], 2)),
                np.zeros((d[D_M], 2)), np.zeros(d[D_N]), np.zeros(3))


@inline
def eval_channel(c, t, knots, coef, cum, first, count, hint, chan):
    """Value, derivative and integral of input channel ``c`` at ``t`` into ``chan[c]``."""
    p0 = first[c]
    npieces = count[c]
    koff = p0 + c
    t0 = knots[koff]
    if t < t0:
        v = coef[p0, 0]
        chan[c, 0] = v
        chan[c, 1] = 0.0
        chan[c, 2] = (t - t0) * v
        return
    t_last = knots[koff + npieces]
    if t >= t_last:
        p = p0 + npieces - 1
        tau = t_last - knots[koff + npieces - 1]
        v = coef[p, 0] + tau * (coef[p, 1] + tau * (coef[p, 2] + tau * coef[p, 3]))
        chan[c, 0] = v
        chan[c, 1] = 0.0
        chan[c, 2] = cum[koff + npieces] + (t - t_last) * v
        return
    j = hint[c]
    if j < 0 or j >= npieces:
        j = 0
    while knots[koff + j + 1] <= t:
        j += 1
    while knots[koff + j] > t:
        j -= 1
    hint[c] = j
    tau = t - knots[koff + j]
    p = p0 + j
    c0, c1, c2, c3 = coef[p, 0], coef[p, 1], coef[p, 2], coef[p, 3]
    chan[c, 0] = c0 + tau * (c1 + tau * (c2 + tau * c3))
    chan[c, 1] = c1 + tau * (2.0 * c2 + 3.0 * c3 * tau)
    chan[c, 2] = cum[koff + j] + tau * (c0 + tau * (0.5 * c1 + tau * (c2 / 3.0 + 0.25 * c3 * tau)))


@inline
def eval_source(j, chan, src_ch, src_pos0, srcw):
    """Speed, acceleration and angle of source ``j`` from its (evaluated) channel."""
    c = src_ch[j]
    srcw[j, U] = chan[c, 0]
    srcw[j, UD] = chan[c, 1]
    srcw[j, SG] = src_pos0[j] + chan[c, 2]


@inline
def eval_inputs(t, knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw):
    """Value, derivative and integral of every input channel at ``t``; then the
    sources' speeds, accelerations and angles."""
    for c in range(first.shape[0]):
        eval_channel(c, t, knots, coef, cum, first, count, hint, chan)
    for j in range(src_ch.shape[0]):
        eval_source(j, chan, src_ch, src_pos0, srcw)


@inline
def xdot(xp, xc, xv, r, vec, off):
    """Free-coordinate part of row ``r`` dotted with ``vec[off:off + n]`` (sparse).

    Offsets instead of slices: a slice is a new array, and its reference
    counting does not get pruned in the hot loops. Indices are cast to unsigned
    here and in `udot`, `xadd`, `uadd`: numba then omits its negative-index
    wrap-around, which on these loaded column indices took a fifth of the smooth
    solver's time (measured on fig 4.15).
    """
    acc = 0.0
    for k in range(xp[r], xp[r + 1]):
        i = np.uint64(k)
        acc += xv[i] * vec[np.uint64(off + xc[i])]
    return acc


@inline
def udot(up, uc, uv, r, srcw, col):
    """Source part of row ``r`` dotted with column ``col`` of the source work array."""
    acc = 0.0
    for k in range(up[r], up[r + 1]):
        i = np.uint64(k)
        acc += uv[i] * srcw[np.uint64(uc[i]), np.uint64(col)]
    return acc


@inline
def xadd(xp, xc, xv, r, vec, scale):
    """``vec += scale * (free-coordinate part of row r)``."""
    for k in range(xp[r], xp[r + 1]):
        i = np.uint64(k)
        vec[np.uint64(xc[i])] += scale * xv[i]


@inline
def uadd(up, uc, uv, r, srcw, col, scale):
    """``srcw[:, col] += scale * (source part of row r)``."""
    for k in range(up[r], up[r + 1]):
        i = np.uint64(k)
        srcw[np.uint64(uc[i]), np.uint64(col)] += scale * uv[i]


@inline
def pivot_at(par, r, angle, scal):
    """Pivot position q [m] at pivot-mechanism angle ``angle`` (row ``r``), with
    the range check: a pivot outside its range sets ``scal[STATUS]``.

    Written without branches: numba's reference counting of the array
    arguments does not get pruned in branchy inlined code (it cost ~100 ns).
    """
    moving = par[r, 2]  # 1 with a pivot mechanism, 0 for a fixed pivot (row of zeros)
    q = moving * par[r, 0] * math.sin(angle) + (1.0 - moving) * par[r, 1]
    scal[Q] = q
    outside = (q < par[r, 3] - 1e-12) + (q > par[r, 4] + 1e-12)
    scal[STATUS] = max(scal[STATUS], PIVOT_RANGE * min(outside, 1))
    return q


@inline
def pivot_angle(dims, xp, xc, xv, up, uc, uv, srcw, x):
    """Angle of the pivot mechanism (the last row) at generalised angles ``x``."""
    r = dims[D_R] - 1
    return xdot(xp, xc, xv, r, x, 0) + udot(up, uc, uv, r, srcw, SG)


@inline
def pivot_position(dims, xp, xc, xv, up, uc, uv, par, srcw, scal, x):
    """Pivot position q [m] (the last row) at generalised angles ``x``, with the
    range check."""
    return pivot_at(par, dims[D_R] - 1, pivot_angle(dims, xp, xc, xv, up, uc, uv, srcw, x), scal)


@inline
def eval_pivot(dims, xp, xc, xv, up, uc, uv, par, srcw, scal, y):
    """`pivot_position` and its rate ``scal[QDOT]``; ``y`` holds the generalised
    angles and then their speeds (offset n)."""
    r = dims[D_R] - 1
    n = dims[D_N]
    angle = pivot_angle(dims, xp, xc, xv, up, uc, uv, srcw, y)
    rate = xdot(xp, xc, xv, r, y, n) + udot(up, uc, uv, r, srcw, U)
    q = pivot_at(par, r, angle, scal)
    scal[QDOT] = par[r, 2] * par[r, 0] * math.cos(angle) * rate
    return q


@inline
def eval_springs(dims, xp, xc, xv, up, uc, uv, par, code, srcw, spw, scal, y):
    """Spring deflections, torques, stiffness and energy (``y`` as in `eval_pivot`)."""
    q = eval_pivot(dims, xp, xc, xv, up, uc, uv, par, srcw, scal, y)
    n = dims[D_N]
    f = dims[D_F]
    for kk in range(dims[D_K]):
        r = f + kk
        d = xdot(xp, xc, xv, r, y, 0) + udot(up, uc, uv, r, srcw, SG)
        tau, stiff, energy, dvq = spring_law(code[r], row(par, r), d, q)
        spw[kk, DEFL] = d
        spw[kk, RATE] = xdot(xp, xc, xv, r, y, n) + udot(up, uc, uv, r, srcw, U)
        spw[kk, SPTAU] = tau
        spw[kk, STIFF] = stiff
        spw[kk, ENERGY] = energy
        spw[kk, DVDQ] = dvq


@inline
def eval_forces(dims, xp, xc, xv, up, uc, uv, par, code, chan, srcw, frw, spw, ldw, mow, gen,
                scal, y, full):
    """All element torques at the state ``y``, gathered as generalised forces.

    ``gen`` receives the sum on the free coordinates and, with ``full``,
    ``srcw[:, SRCF]`` the sum on the source coordinates. Without ``full`` the
    elements that only the sources feel are skipped: the dynamics do not need
    them, only the ledger and the source torques do. Inputs must already be
    evaluated.
    """
    n = dims[D_N]
    s = dims[D_S]
    f = dims[D_F]
    k = dims[D_K]
    nl = dims[D_L]
    for i in range(n):
        gen[i] = 0.0
    for j in range(s):
        srcw[j, SRCF] = 0.0
    eval_springs(dims, xp, xc, xv, up, uc, uv, par, code, srcw, spw, scal, y)
    for kk in range(k):
        r = f + kk
        tau = spw[kk, SPTAU]
        xadd(xp, xc, xv, r, gen, tau)
        if full:
            uadd(up, uc, uv, r, srcw, SRCF, tau)
    for e in range(f):
        if not full and xp[e + 1] == xp[e]:
            continue
        slip = xdot(xp, xc, xv, e, y, n) + udot(up, uc, uv, e, srcw, U)
        # (the slope is left unused: then the compiler drops its division)
        torque = resistive_torque(code[e], par[e, 0], par[e, 1], par[e, 2], par[e, 3], slip)[0]
        if code[e] == STICTION:
            torque += frw[e, EXTRA]
        frw[e, SLIP] = slip
        frw[e, TORQUE] = torque
        xadd(xp, xc, xv, e, gen, -torque)
        if full:
            uadd(up, uc, uv, e, srcw, SRCF, -torque)
    for ld in range(nl):
        r = f + k + ld
        tau = chan[code[r], 0]
        ldw[ld, 0] = tau
        ldw[ld, 1] = xdot(xp, xc, xv, r, y, n) + udot(up, uc, uv, r, srcw, U)
        xadd(xp, xc, xv, r, gen, tau)
        if full:
            uadd(up, uc, uv, r, srcw, SRCF, tau)
    for mo in range(dims[D_M]):
        r = f + k + nl + mo
        torque = par[r, 2] * y[2 * n + mo]
        mow[mo, 0] = xdot(xp, xc, xv, r, y, n) + udot(up, uc, uv, r, srcw, U)
        mow[mo, 1] = chan[code[r], 0]
        xadd(xp, xc, xv, r, gen, torque)
        if full:
            uadd(up, uc, uv, r, srcw, SRCF, torque)


@inline
def eval_derivatives(t, y, dy, dims, mass, Minv, xp, xc, xv, up, uc, uv, par, code, src_ch,
                     src_pos0, knots, coef, cum, first, count, hint, chan, srcw, frw, spw, ldw, mow,
                     gen, scal):
    """``dy/dt`` of the state and, if ``dy`` is long enough, of the energy accumulators
    and the source torques (see `eval_forces`).

    (At most 30 parameters: numba's inliner refuses more.)
    """
    n = dims[D_N]
    s = dims[D_S]
    nm = dims[D_M]
    eval_inputs(t, knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw)
    full = dy.shape[0] > 2 * n + nm
    eval_forces(dims, xp, xc, xv, up, uc, uv, par, code, chan, srcw, frw, spw, ldw, mow, gen, scal,
                y, full)
    for i in range(n):
        for j in range(s):
            gen[i] -= mass[i, n + j] * srcw[j, UD]
    for i in range(n):
        total = 0.0
        for r in range(n):
            total += Minv[i, r] * gen[r]
        dy[n + i] = total
        dy[i] = y[n + i]
    if full:
        for j in range(s):
            tau = -srcw[j, SRCF]
            for i in range(n):
                tau += mass[n + j, i] * dy[n + i]
            for r in range(s):
                tau += mass[n + j, n + r] * srcw[r, UD]
            srcw[j, SRCTAU] = tau
    base_m = dims[D_F] + dims[D_K] + dims[D_L]
    for mo in range(nm):
        r = base_m + mo
        dy[2 * n + mo] = (mow[mo, 1] - par[r, 0] * y[2 * n + mo] - par[r, 2] * mow[mo, 0]) / par[r, 1]
    if full:
        p = 2 * n + nm
        for j in range(s):
            dy[p] = srcw[j, U] * srcw[j, SRCTAU]
            p += 1
        for ld in range(dims[D_L]):
            dy[p] = ldw[ld, 0] * ldw[ld, 1]
            p += 1
        for mo in range(nm):
            dy[p] = mow[mo, 1] * y[2 * n + mo]
            p += 1
        for e in range(dims[D_F]):
            dy[p] = frw[e, TORQUE] * frw[e, SLIP]
            p += 1
        for mo in range(nm):
            dy[p] = par[base_m + mo, 0] * y[2 * n + mo] ** 2
            p += 1
        for kk in range(dims[D_K]):
            dy[p] = spw[kk, SPTAU] * spw[kk, RATE]
            p += 1
        for kk in range(dims[D_K]):
            dy[p] = spw[kk, DVDQ] * scal[QDOT]
            p += 1
    for i in range(dy.shape[0]):
        if not math.isfinite(dy[i]):
            scal[STATUS] = NOT_FINITE


@kernel
def derivatives(m, w, t, y, dy):
    """`eval_derivatives` for callers holding the model and work tuples."""
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, cum, first, \
        count = m
    hint, chan, srcw, frw, spw, ldw, mow, gen, scal = w
    eval_derivatives(t, y, dy, dims, mass, Minv, xp, xc, xv, up, uc, uv, par, code, src_ch,
                     src_pos0, knots, coef, cum, first, count, hint, chan, srcw, frw, spw, ldw, mow,
                     gen, scal)


@kernel
def source_speeds(m, w, t):
    """Speeds of the velocity sources at ``t``."""
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, cum, first, \
        count = m
    hint, chan, srcw, frw, spw, ldw, mow, gen, scal = w
    eval_inputs(t, knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw)
    return srcw[:, U].copy()


@kernel
def source_signals(m, t_out):
    """Source angles and speeds at each sample time, shape (samples, sources) each."""
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, cum, first, \
        count = m
    w = make_work(m)
    hint, chan, srcw, frw, spw, ldw, mow, gen, scal = w
    angles = np.empty((t_out.shape[0], src_ch.shape[0]))
    speeds = np.empty((t_out.shape[0], src_ch.shape[0]))
    for i in range(t_out.shape[0]):
        eval_inputs(t_out[i], knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw)
        for j in range(src_ch.shape[0]):
            angles[i, j] = srcw[j, SG]
            speeds[i, j] = srcw[j, U]
    return angles, speeds


@kernel
def kinetic_energy(mass, v, u):
    """Kinetic energy [J] of all flanges, free (speeds ``v``) and driven (``u``)."""
    n = v.shape[0]
    s = u.shape[0]
    e = 0.0
    for i in range(n + s):
        a = v[i] if i < n else u[i - n]
        for r in range(n + s):
            b = v[r] if r < n else u[r - n]
            e += 0.5 * a * mass[i, r] * b
    return e


@kernel
def stored_energy(m, w, t, y):
    """``(kinetic, spring, inductor)`` energy [J] at ``(t, y)``; fills the spring buffer."""
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, cum, first, \
        count = m
    hint, chan, srcw, frw, spw, ldw, mow, gen, scal = w
    n = dims[D_N]
    nm = dims[D_M]
    eval_inputs(t, knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw)
    eval_springs(dims, xp, xc, xv, up, uc, uv, par, code, srcw, spw, scal, y)
    kin = kinetic_energy(mass, y[n:2 * n].copy(), srcw[:, U].copy())
    pot = 0.0
    for kk in range(dims[D_K]):
        pot += spw[kk, ENERGY]
    ind = 0.0
    base_m = dims[D_F] + dims[D_K] + dims[D_L]
    for mo in range(nm):
        ind += 0.5 * par[base_m + mo, 1] * y[2 * n + mo] ** 2
    return kin, pot, ind


def observation_width(n: int, s: int, f: int, k: int, nl: int, nm: int) -> int:
    return 3 * n + nm + 3 * s + 2 + 2 * f + 5 * k + s + 2 * nl + 2 * nm


@kernel
def observe_all(m, t_out, out, coulomb, width):
    """Raw observations at every sample (`vsj.engine.observation_layout` names the
    columns); ``coulomb`` holds the stiction torques of each sample."""
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, cum, first, \
        count = m
    w = make_work(m)
    hint, chan, srcw, frw, spw, ldw, mow, gen, scal = w
    n = dims[D_N]
    nm = dims[D_M]
    ns = 2 * n + nm
    raw = np.empty((t_out.shape[0], width))
    dy = np.empty(out.shape[1])  # full length: source torques and every element
    for i in range(t_out.shape[0]):
        for e in range(coulomb.shape[1]):
            frw[e, EXTRA] = coulomb[i, e]
        y = out[i]
        eval_derivatives(t_out[i], y, dy, dims, mass, Minv, xp, xc, xv, up, uc, uv, par, code,
                         src_ch, src_pos0, knots, coef, cum, first, count, hint, chan, srcw, frw,
                         spw, ldw, mow, gen, scal)
        row = raw[i]
        p = 0
        for j in range(ns):
            row[p] = y[j]
            p += 1
        for j in range(n):
            row[p] = dy[n + j]
            p += 1
        for col in (SG, U, UD):
            for j in range(srcw.shape[0]):
                row[p] = srcw[j, col]
                p += 1
        row[p] = scal[Q]
        row[p + 1] = scal[QDOT]
        p += 2
        for col in (SLIP, TORQUE):
            for e in range(frw.shape[0]):
                row[p] = frw[e, col]
                p += 1
        for col in (DEFL, RATE, SPTAU, ENERGY, STIFF):
            for kk in range(spw.shape[0]):
                row[p] = spw[kk, col]
                p += 1
        for j in range(srcw.shape[0]):
            row[p] = srcw[j, SRCTAU]
            p += 1
        for col in (0, 1):
            for ld in range(ldw.shape[0]):
                row[p] = ldw[ld, col]
                p += 1
        for col in (0, 1):
            for mo in range(mow.shape[0]):
                row[p] = mow[mo, col]
                p += 1
    return raw
