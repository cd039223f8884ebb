"""Compiled evaluation of a model: inputs, element forces, accelerations, energies.

State vector ``y = [x (n), v (n), i (motors)]``: generalised angles and speeds
(the free flanges of the network) and the armature currents. When the smooth
solver integrates, the accumulators of `Layout.acc_slices` follow (``with_energy``).

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
from numba import njit

from ..components.elastic_element import spring_law
from ..friction import STICTION, resistive_torque
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
SLIP, TORQUE, SLOPE, EXTRA = range(4)         # frw (per friction element)
DEFL, RATE, SPTAU, STIFF, ENERGY, DVDQ = range(6)  # spw (per spring)
Q, QDOT, STATUS = range(3)                    # scal


class Work(NamedTuple):
    """Scratch arrays of one integration (one set per thread in a batch)."""

    hint: np.ndarray  # (channels,) int64 last spline piece used
    chan: np.ndarray  # (channels, 3) value, derivative, integral
    srcw: np.ndarray  # (s, 5) speed, acceleration, angle, element torque sum, source torque
    frw: np.ndarray   # (f, 4) slip, torque, slope, Coulomb torque set by the time stepper
    spw: np.ndarray   # (k, 6) deflection, rate, torque, stiffness, energy, dV/dq
    ldw: np.ndarray   # (loads, 2) torque, speed
    mow: np.ndarray   # (motors, 2) rotor speed, voltage
    gen: np.ndarray   # (n,) generalised force
    acc: np.ndarray   # (n,) generalised acceleration
    scal: np.ndarray  # (3,) q, dq/dt, status


@njit(cache=True)
def make_work(m):
    d = m.dims
    return Work(np.zeros(d[D_CH], np.int64), np.zeros((d[D_CH], 3)), np.zeros((d[D_S], 5)),
                np.zeros((d[D_F], 4)), np.zeros((d[D_K], 6)), np.zeros((d[D_L], 2)),
                np.zeros((d[D_M], 2)), np.zeros(d[D_N]), np.zeros(d[D_N]), np.zeros(3))


@njit(cache=True, inline="always")
def eval_inputs(t, knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw):
    """Value, derivative and integral of every input channel at ``t``; then the
    sources' speeds, accelerations and angles."""
    for c in range(first.shape[0]):
        p0 = first[c]
        npieces = count[c]
        koff = p0 + c
        t0 = knots[koff]
        if t < t0:
            v = coef[p0, 0]
            chan[c, 0] = v
            chan[c, 1] = 0.0
            chan[c, 2] = (t - t0) * v
            continue
        t_last = knots[koff + npieces]
        if t >= t_last:
            p = p0 + npieces - 1
            tau = t_last - knots[koff + npieces - 1]
            v = coef[p, 0] + tau * (coef[p, 1] + tau * (coef[p, 2] + tau * coef[p, 3]))
            chan[c, 0] = v
            chan[c, 1] = 0.0
            chan[c, 2] = cum[koff + npieces] + (t - t_last) * v
            continue
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
        chan[c, 2] = cum[koff + j] + tau * (c0 + tau * (0.5 * c1 + tau * (c2 / 3.0
                                                                        + 0.25 * c3 * tau)))
    for j in range(src_ch.shape[0]):
        c = src_ch[j]
        srcw[j, U] = chan[c, 0]
        srcw[j, UD] = chan[c, 1]
        srcw[j, SG] = src_pos0[j] + chan[c, 2]


@njit(cache=True, inline="always")
def row_dot(rows, r, x, srcw, col):
    """``rows[r] . (x, srcw[:, col])``: an element's coordinate or speed."""
    n = x.shape[0]
    acc = 0.0
    for i in range(n):
        acc += rows[r, i] * x[i]
    for j in range(srcw.shape[0]):
        acc += rows[r, n + j] * srcw[j, col]
    return acc


@njit(cache=True, inline="always")
def eval_pivot(dims, rows, par, srcw, scal, x, v):
    """Pivot position q [m] and its rate (the last row), with the range check."""
    r = dims[D_R] - 1
    if par[r, 2] > 0.0:
        angle = row_dot(rows, r, x, srcw, SG)
        rate = row_dot(rows, r, v, srcw, U)
        q = par[r, 0] * math.sin(angle)
        qdot = par[r, 0] * math.cos(angle) * rate
    else:
        q = par[r, 1]
        qdot = 0.0
    scal[Q] = q
    scal[QDOT] = qdot
    if q < par[r, 3] - 1e-12 or q > par[r, 4] + 1e-12:
        scal[STATUS] = PIVOT_RANGE
    return q


@njit(cache=True, inline="always")
def eval_springs(dims, rows, par, code, srcw, spw, scal, x, v):
    """Spring deflections, torques, stiffness and energy."""
    q = eval_pivot(dims, rows, par, srcw, scal, x, v)
    f = dims[D_F]
    for kk in range(dims[D_K]):
        r = f + kk
        d = row_dot(rows, r, x, srcw, SG)
        tau, stiff, energy, dvq = spring_law(code[r], par, r, d, q)
        spw[kk, DEFL] = d
        spw[kk, RATE] = row_dot(rows, r, v, srcw, U)
        spw[kk, SPTAU] = tau
        spw[kk, STIFF] = stiff
        spw[kk, ENERGY] = energy
        spw[kk, DVDQ] = dvq


@njit(cache=True, inline="always")
def eval_forces(dims, rows, par, code, chan, srcw, frw, spw, ldw, mow, gen, scal, x, v, cur):
    """All element torques at ``(x, v, i)``, gathered as generalised forces.

    ``gen`` receives the sum on the free coordinates, ``srcw[:, SRCF]`` the sum
    on the source coordinates. Inputs must already be evaluated.
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
    eval_springs(dims, rows, par, code, srcw, spw, scal, x, v)
    for kk in range(k):
        r = f + kk
        tau = spw[kk, SPTAU]
        for i in range(n):
            gen[i] += tau * rows[r, i]
        for j in range(s):
            srcw[j, SRCF] += tau * rows[r, n + j]
    for e in range(f):
        slip = row_dot(rows, e, v, srcw, U)
        torque, slope = resistive_torque(code[e], par, e, slip)
        if code[e] == STICTION:
            torque += frw[e, EXTRA]
        frw[e, SLIP] = slip
        frw[e, TORQUE] = torque
        frw[e, SLOPE] = slope
        for i in range(n):
            gen[i] -= torque * rows[e, i]
        for j in range(s):
            srcw[j, SRCF] -= torque * rows[e, n + j]
    for ld in range(nl):
        r = f + k + ld
        tau = chan[code[r], 0]
        ldw[ld, 0] = tau
        ldw[ld, 1] = row_dot(rows, r, v, srcw, U)
        for i in range(n):
            gen[i] += tau * rows[r, i]
        for j in range(s):
            srcw[j, SRCF] += tau * rows[r, n + j]
    for mo in range(dims[D_M]):
        r = f + k + nl + mo
        torque = par[r, 2] * cur[mo]
        mow[mo, 0] = row_dot(rows, r, v, srcw, U)
        mow[mo, 1] = chan[code[r], 0]
        for i in range(n):
            gen[i] += torque * rows[r, i]
        for j in range(s):
            srcw[j, SRCF] += torque * rows[r, n + j]


@njit(cache=True, inline="always")
def eval_derivatives(t, y, dy, with_energy, dims, mass, Minv, rows, par, code, src_ch,
                     src_pos0, knots, coef, cum, first, count, hint, chan, srcw, frw, spw, ldw,
                     mow, gen, acc, scal):
    """``dy/dt`` of the state, and of the energy accumulators if ``with_energy``."""
    n = dims[D_N]
    s = dims[D_S]
    nm = dims[D_M]
    x = y[:n]
    v = y[n:2 * n]
    cur = y[2 * n:2 * n + nm]
    eval_inputs(t, knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw)
    eval_forces(dims, rows, par, code, chan, srcw, frw, spw, ldw, mow, gen, scal, x, v, cur)
    for i in range(n):
        rhs = gen[i]
        for j in range(s):
            rhs -= mass[i, n + j] * srcw[j, UD]
        acc[i] = rhs
    for i in range(n):
        total = 0.0
        for r in range(n):
            total += Minv[i, r] * acc[r]
        dy[n + i] = total
        dy[i] = v[i]
    for i in range(n):
        acc[i] = dy[n + i]
    for j in range(s):
        tau = -srcw[j, SRCF]
        for i in range(n):
            tau += mass[n + j, i] * acc[i]
        for r in range(s):
            tau += mass[n + j, n + r] * srcw[r, UD]
        srcw[j, SRCTAU] = tau
    base_m = dims[D_F] + dims[D_K] + dims[D_L]
    for mo in range(nm):
        r = base_m + mo
        dy[2 * n + mo] = (mow[mo, 1] - par[r, 0] * cur[mo] - par[r, 2] * mow[mo, 0]) / par[r, 1]
    if with_energy:
        p = 2 * n + nm
        for j in range(s):
            dy[p] = srcw[j, U] * srcw[j, SRCTAU]
            p += 1
        for ld in range(dims[D_L]):
            dy[p] = ldw[ld, 0] * ldw[ld, 1]
            p += 1
        for mo in range(nm):
            dy[p] = mow[mo, 1] * cur[mo]
            p += 1
        for e in range(dims[D_F]):
            dy[p] = frw[e, TORQUE] * frw[e, SLIP]
            p += 1
        for mo in range(nm):
            dy[p] = par[base_m + mo, 0] * cur[mo] * cur[mo]
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


@njit(cache=True)
def derivatives(m, w, t, y, dy, with_energy):
    """`eval_derivatives` for callers holding the model and work tuples."""
    dims, mass, Minv, rows, par, code, src_ch, src_pos0, knots, coef, cum, first, count = m
    hint, chan, srcw, frw, spw, ldw, mow, gen, acc, scal = w
    eval_derivatives(t, y, dy, with_energy, dims, mass, Minv, rows, par, code, src_ch,
                     src_pos0, knots, coef, cum, first, count, hint, chan, srcw, frw, spw, ldw,
                     mow, gen, acc, scal)


@njit(cache=True)
def source_speeds(m, w, t):
    """Speeds of the velocity sources at ``t``."""
    dims, mass, Minv, rows, par, code, src_ch, src_pos0, knots, coef, cum, first, count = m
    hint, chan, srcw, frw, spw, ldw, mow, gen, acc, scal = w
    eval_inputs(t, knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw)
    return srcw[:, U].copy()


@njit(cache=True)
def source_signals(m, t_out):
    """Source angles and speeds at each sample time, shape (samples, sources) each."""
    dims, mass, Minv, rows, par, code, src_ch, src_pos0, knots, coef, cum, first, count = m
    w = make_work(m)
    hint, chan, srcw, frw, spw, ldw, mow, gen, acc, scal = w
    angles = np.empty((t_out.shape[0], src_ch.shape[0]))
    speeds = np.empty((t_out.shape[0], src_ch.shape[0]))
    for i in range(t_out.shape[0]):
        eval_inputs(t_out[i], knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw)
        for j in range(src_ch.shape[0]):
            angles[i, j] = srcw[j, SG]
            speeds[i, j] = srcw[j, U]
    return angles, speeds


@njit(cache=True)
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


@njit(cache=True)
def stored_energy(m, w, t, y):
    """``(kinetic, spring, inductor)`` energy [J] at ``(t, y)``; fills the spring buffer."""
    dims, mass, Minv, rows, par, code, src_ch, src_pos0, knots, coef, cum, first, count = m
    hint, chan, srcw, frw, spw, ldw, mow, gen, acc, scal = w
    n = dims[D_N]
    nm = dims[D_M]
    eval_inputs(t, knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw)
    x = y[:n]
    v = y[n:2 * n]
    eval_springs(dims, rows, par, code, srcw, spw, scal, x, v)
    kin = kinetic_energy(mass, v, srcw[:, U].copy())
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


@njit(cache=True)
def observe_all(m, t_out, out, coulomb, width):
    """Raw observations at every sample (`vsj.engine.observation_layout` names the
    columns); ``coulomb`` holds the stiction torques of each sample."""
    dims, mass, Minv, rows, par, code, src_ch, src_pos0, knots, coef, cum, first, count = m
    w = make_work(m)
    hint, chan, srcw, frw, spw, ldw, mow, gen, acc, scal = w
    n = dims[D_N]
    nm = dims[D_M]
    ns = 2 * n + nm
    raw = np.empty((t_out.shape[0], width))
    dy = np.empty(ns)
    for i in range(t_out.shape[0]):
        for e in range(coulomb.shape[1]):
            frw[e, EXTRA] = coulomb[i, e]
        y = out[i, :ns]
        eval_derivatives(t_out[i], y, dy, False, dims, mass, Minv, rows, par, code, src_ch,
                         src_pos0, knots, coef, cum, first, count, hint, chan, srcw, frw, spw,
                         ldw, mow, gen, acc, scal)
        row = raw[i]
        p = 0
        for j in range(ns):
            row[p] = y[j]
            p += 1
        for j in range(n):
            row[p] = acc[j]
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
