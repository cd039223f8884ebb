"""Fixed-step time stepping with exact Coulomb stiction, compiled.

A velocity-level scheme in the family of Moreau and Jean, chosen for true
stiction (see docs in `vsj.friction` and the README's "True stiction" section
for the measurements behind the choice). Per step of length ``h``:

* springs: trapezoidal rule, linearised about the start of the step with the
  law's analytic stiffness (energy-conserving for linear springs, stable for
  stiff ones);
* smooth friction and viscous parts: implicit Euler, linearised (so the stiff
  slope law of fig 4.8 stays stable);
* DC motor armatures: implicit Euler;
* Coulomb parts of ``stiction`` elements: impulses ``p_e``, bounded by
  ``h k_e pi/2``, decided *together* for all elements by the box-constrained
  problem

      s = q - W p,   |p_e| <= h c_e,
      p_e = +h c_e if s_e > 0,  p_e = -h c_e if s_e < 0,  |p_e| <= h c_e if s_e = 0,

  with ``W = D H^-1 D^T`` the Delassus matrix of the elements' slip rows and
  ``q`` their slip speeds without Coulomb friction. It is solved exactly
  (`solve_impulses`: last step's stick/slip pattern checked first, an
  active-set method when it no longer holds), warm-started from the previous
  step; an element with ``s_e = 0`` holds exactly (no creep), and which
  elements hold is decided jointly through ``W`` (coupled through the gears
  and the differential). Elements whose slip rows are parallel (bearings and
  meshes that turn with one gear) slip together, so they are posed as one
  unknown bounded by their summed levels, which is the same problem, smaller
  (13 unknowns become 7 in the wrist).

Every force's work is booked against the mid-step speed, which is the velocity
the scheme actually moves with, so the energy ledger closes up to the spring
linearisation (third order in the step). Friction power sampled at step ends is
``-f s <= 0`` by construction of the impulses.
"""

from __future__ import annotations

import math

import numpy as np

from ..components.elastic_element import row, spring_law
from ..friction import STICTION, VISCOUS, coulomb_level, resistive_torque
from ..jit import inline, kernel, loop
from .core import (FRICTION_SOLVER, NOT_FINITE, OK, SG, STATUS, TOO_MANY_STEPS, U, eval_channel,
                   eval_inputs, eval_source, pivot_angle, pivot_at, pivot_position, xadd, xdot)
from .model import D_F, D_K, D_L, D_M, D_N, D_R, D_S

#: Slip speed [rad/s] below which an element counts as stuck.
STUCK_SPEED = 1e-10
#: Impulse solver: absolute and relative (to the largest free slip) tolerance [rad/s].
IMPULSE_ABS = 1e-14
IMPULSE_REL = 1e-12
IMPULSE_MAX_ITER = 500
#: Relative Tikhonov term that makes the impulse problem strictly convex (removed by polishing).
IMPULSE_REG = 1e-9
#: Relative change of the step matrix H below which its factor is reused (round-off:
#: a pivot held still moves q, hence the springs' stiffness, in the last bits).
H_REUSE = 1e-12
#: Relative difference below which two friction rows count as parallel (one impulse).
PARALLEL = 1e-12


@inline
def _cholesky(H, L, k, floor):
    """Cholesky factor of the leading k x k block of ``H`` into ``L``.

    With ``floor`` a non-positive pivot is clamped (for Gram matrices that may
    be singular); without, it returns False.
    """
    for i in range(k):
        for j in range(i + 1):
            acc = H[i, j]
            for r in range(j):
                acc -= L[i, r] * L[j, r]
            if i == j:
                if acc <= 0.0:
                    if not floor:
                        return False
                    acc = 1e-300
                L[i, i] = math.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
    return True


@inline
def _forward(L, b, out, k):
    """Solve ``L out = b`` (lower triangular, leading k x k block)."""
    for i in range(k):
        acc = b[i]
        for r in range(i):
            acc -= L[i, r] * out[r]
        out[i] = acc / L[i, i]


@inline
def _backward(L, b, out, k):
    """Solve ``L^T out = b`` (``out`` may be ``b``)."""
    for i in range(k - 1, -1, -1):
        acc = b[i]
        for r in range(i + 1, k):
            acc -= L[r, i] * out[r]
        out[i] = acc / L[i, i]


@inline
def _solve(L, b, out, k):
    """Solve ``L L^T out = b`` given the Cholesky factor."""
    _forward(L, b, out, k)
    _backward(L, out, out, k)


@inline
def _project(YT, p, z, n):
    """``z = YT p``: the impulses' effect in the scaled speed coordinates."""
    m = YT.shape[1]
    for i in range(n):
        acc = 0.0
        for e in range(m):
            acc += YT[i, e] * p[e]
        z[i] = acc


@inline
def _gram(YT, mask, vec, G, t, ridge, n):
    """``G = YT diag(mask) YT^T + ridge I`` and ``t = YT (mask * vec)``."""
    m = YT.shape[1]
    for i in range(n):
        acc_t = 0.0
        for e in range(m):
            acc_t += YT[i, e] * mask[e] * vec[e]
        t[i] = acc_t
        for j in range(i + 1):
            acc = 0.0
            for e in range(m):
                acc += YT[i, e] * mask[e] * YT[j, e]
            G[i, j] = acc
            G[j, i] = acc
        G[i, i] += ridge


@inline
def _snap(q, cap, p, state, active, mask):
    """Classify the warm start: impulses at (this step's) bound keep their sign,
    the others are free (stuck); uninvolved elements get state 2. Fills ``mask``
    (1 for free) and returns ``(number free, largest free slip)``."""
    n_free = 0
    scale = 0.0
    for e in range(q.shape[0]):
        ce = cap[e]
        mask[e] = 0.0
        if active[e] and ce > 0.0:
            scale = max(scale, abs(q[e]))
            # the cap varies in its last bits from step to step (the step length does):
            # an impulse at last step's bound is at this step's bound
            if p[e] >= ce * (1.0 - 1e-9):
                p[e] = ce
                state[e] = 1
            elif p[e] <= -ce * (1.0 - 1e-9):
                p[e] = -ce
                state[e] = -1
            else:
                state[e] = 0
                mask[e] = 1.0
                n_free += 1
        else:
            p[e] = 0.0
            state[e] = 2
    return n_free, scale


@inline
def _stuck_impulses(YT, mask, slip, G, Lg, t, c, d, n):
    """Minimum-norm impulses of the stuck (free) elements that cancel their slips
    ``slip`` (computed with the other impulses applied): ``d = Y_F G^-2 Y_F^T s_F``
    with ``G = Y_F^T Y_F``, only n x n solves. ``G`` may be singular (parallel
    rows: elements in series): a tiny ridge. Writes ``d`` (zero off the free set)."""
    m = YT.shape[1]
    _gram(YT, mask, slip, G, t, 0.0, n)
    trace = 0.0
    for i in range(n):
        trace += G[i, i]
    for i in range(n):
        G[i, i] += 1e-13 * trace
    _cholesky(G, Lg, n, True)
    _solve(Lg, t, c, n)
    _solve(Lg, c, t, n)
    for e in range(m):
        d[e] = 0.0
    for i in range(n):
        ti = t[i]
        for e in range(m):
            d[e] += YT[i, e] * ti * mask[e]


@inline
def _slips(YT, q, z, s, n):
    """``s = q - YT^T z`` (``s`` may be ``q``)."""
    m = YT.shape[1]
    for e in range(m):
        s[e] = q[e]
    for i in range(n):
        zi = z[i]
        for e in range(m):
            s[e] -= YT[i, e] * zi


@kernel
def impulse_workspace(n, m):
    """Scratch arrays of `solve_impulses` for n coordinates and m elements.

    The last three hold the fast path's memo: ``Gc = Y_F Y_F^T`` and
    ``K = (Gc + ridge I)^-2`` of the stuck set recorded in ``memo[:m]``
    (``memo[m]`` is 1 while they are valid; set it to 0 when ``YT`` changes).
    """
    return (np.zeros(m), np.zeros((n, n)), np.zeros((n, n)), np.zeros(n), np.zeros(n),
            np.zeros(m), np.zeros(m), np.zeros(n), np.zeros((n, n)), np.zeros((n, n)),
            np.zeros(m + 1))


@loop
def _stuck_map(YT, mask, Gc, K, Lg, t, c):
    """``Gc = Y_F Y_F^T`` and ``K = (Gc + ridge I)^-2`` for the stuck set ``mask``.

    ``K Y_F s_F`` are the coefficients of the minimum-norm impulses that cancel
    the stuck elements' slips ``s_F`` (see `_stuck_impulses`); the ridge keeps
    ``K`` finite when the stuck rows are parallel (elements in series).

    The explicit ``K`` loses accuracy when stuck rows are nearly parallel; the
    fast path may use it because its result is checked (a miss falls back to
    the active-set method), while the active set's final polish, which is not
    checked afterwards, solves with the factor (`_stuck_impulses`). Replacing
    the polish by ``K`` left 7e-9 of slip where 1e-9 is allowed in
    tests/test_stiction.py.
    """
    n = YT.shape[0]
    _gram(YT, mask, mask, Gc, t, 0.0, n)
    trace = 0.0
    for i in range(n):
        trace += Gc[i, i]
    for i in range(n):
        for j in range(n):
            K[i, j] = Gc[i, j]
        K[i, i] += 1e-13 * trace
    _cholesky(K, Lg, n, True)
    for j in range(n):
        for i in range(n):
            t[i] = 1.0 if i == j else 0.0
        _solve(Lg, t, c, n)
        _solve(Lg, c, t, n)
        for i in range(n):
            K[i, j] = t[i]


@inline
def _same_pattern(YT, q, cap, p, state, active, ws, n):
    """Fast path: does last step's stick/slip pattern still hold?

    Bound impulses at their caps, the stuck elements' impulses the minimum-norm
    ones that make their slips exactly zero; True if every condition holds
    (stuck impulses within their caps, slipping elements' slips in the direction
    of their impulses), and ``p`` is then the solution. Worked in the n
    coordinates: with ``z_B = Y_B p_B`` the stuck impulses are ``Y_F^T c`` with
    ``c = K (Y_F q_F - Gc z_B)``, and they add ``Gc c`` to ``z``. ``Gc`` and ``K``
    change only with the stuck set or ``YT`` and are kept between calls. Far
    cheaper than the active-set method, and true on most steps.
    """
    mask, _, Lg, t, c, d, g, z, Gc, K, memo = ws
    m = YT.shape[1]
    n_free, scale = _snap(q, cap, p, state, active, mask)
    tol = IMPULSE_ABS + IMPULSE_REL * scale
    for e in range(m):
        d[e] = p[e] * (1.0 - mask[e])
    _project(YT, d, z, n)  # z_B
    if n_free > 0:
        known = memo[m] > 0.0
        for e in range(m):
            known = known and memo[e] == mask[e]
        if not known:
            _stuck_map(YT, mask, Gc, K, Lg, t, c)
            for e in range(m):
                memo[e] = mask[e]
            memo[m] = 1.0
        for e in range(m):
            d[e] = q[e] * mask[e]
        _project(YT, d, t, n)
        for i in range(n):
            acc = t[i]
            for j in range(n):
                acc -= Gc[i, j] * z[j]
            t[i] = acc  # Y_F s_F, s the slips under the bound impulses alone
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += K[i, j] * t[j]
            c[i] = acc
        for e in range(m):
            d[e] = 0.0
        for i in range(n):
            ci = c[i]
            for e in range(m):
                d[e] += YT[i, e] * ci
        fits = True
        for e in range(m):
            if mask[e] > 0.0:
                fits = fits and abs(d[e]) <= cap[e]
                p[e] = d[e]
        if not fits:
            return False
        for i in range(n):
            acc = z[i]
            for j in range(n):
                acc += Gc[i, j] * c[j]
            z[i] = acc
    _slips(YT, q, z, g, n)
    holds = True
    for e in range(m):
        st = state[e]
        if st == 0:
            holds = holds and abs(g[e]) <= tol
        elif st != 2:
            holds = holds and g[e] * st >= -tol
    return holds


@loop
def _active_set(YT, q, cap, p, state, active, ws):
    """The general method (see `solve_impulses`), from the warm start in ``p``.

    Like `_stuck_map`, a function of its own rather than inlined: both run
    only when the stick/slip pattern or the step matrix changes, and out of
    line they keep the common step's code smaller (2-3% faster).
    """
    mask, G, Lg, t, c, d, g, z, _, _, _ = ws
    n, m = YT.shape
    _, scale = _snap(q, cap, p, state, active, mask)
    w_max = 0.0
    for e in range(m):
        if state[e] != 2:
            norm = 0.0
            for i in range(n):
                norm += YT[i, e] * YT[i, e]
            w_max = max(w_max, norm)
    if w_max == 0.0:
        _project(YT, p, z, n)
        return True, 0
    eps = IMPULSE_REG * w_max
    tol = IMPULSE_ABS + IMPULSE_REL * scale
    converged = False
    iterations = 0
    at_optimum = False  # the free set was just minimised: check the bound set next
    for it in range(IMPULSE_MAX_ITER):
        iterations = it + 1
        # gradient of 1/2 p^T (W + eps I) p - q.p
        _project(YT, p, z, n)
        _slips(YT, q, z, g, n)
        n_free = 0
        for e in range(m):
            g[e] = eps * p[e] - g[e]
            free = state[e] == 0
            mask[e] = 1.0 if free else 0.0
            n_free += free
        if n_free > 0 and not at_optimum:
            # Newton step on the free set, d = -(eps I + Y_F Y_F^T)^-1 g_F by
            # Woodbury's identity (an n x n solve), then a ratio test at the caps
            _gram(YT, mask, g, G, t, eps, n)
            _cholesky(G, Lg, n, True)
            _solve(Lg, t, c, n)
            _slips(YT, g, c, d, n)  # d = g - Y c, scaled below
            alpha = 1.0
            block = -1
            for e in range(m):
                if state[e] != 0:
                    continue
                de = -d[e] / eps
                d[e] = de
                if de > 0.0 and p[e] + de > cap[e]:
                    a = (cap[e] - p[e]) / de
                elif de < 0.0 and p[e] + de < -cap[e]:
                    a = (-cap[e] - p[e]) / de
                else:
                    continue
                if a < alpha:
                    alpha = a
                    block = e
            for e in range(m):
                if state[e] == 0:
                    p[e] = min(cap[e], max(-cap[e], p[e] + alpha * d[e]))
            if block >= 0:
                p[block] = cap[block] if d[block] > 0.0 else -cap[block]
                state[block] = 1 if d[block] > 0.0 else -1
            else:
                at_optimum = True
            continue
        at_optimum = False
        worst = tol
        release = -1
        for e in range(m):
            st = state[e]
            if (st == 1 or st == -1) and g[e] * st > worst:
                worst = g[e] * st
                release = e
        if release < 0:
            converged = True
            break
        state[release] = 0
    if not converged:
        return False, iterations
    # polish: remove the regularisation's creep from the stuck elements
    n_free = 0
    for e in range(m):
        free = state[e] == 0
        mask[e] = 1.0 if free else 0.0
        n_free += free
    if n_free > 0:
        _project(YT, p, z, n)
        _slips(YT, q, z, g, n)
        _stuck_impulses(YT, mask, g, G, Lg, t, c, d, n)
        for e in range(m):
            if state[e] == 0:
                p[e] = min(cap[e], max(-cap[e], p[e] + d[e]))
    _project(YT, p, z, n)
    return True, iterations


@inline
def solve_impulses(YT, q, cap, p, state, active, ws, n):
    """Exact Coulomb impulses: slips ``s = q - Y Y^T p`` with ``|p_e| <= cap_e``.

    ``YT`` holds one column ``L^-1 d_e`` per element (``H = L L^T``), so the
    Delassus matrix is ``W = Y Y^T`` with ``Y = YT^T``. W has rank n (the
    degrees of freedom) while there are many more elements, and while the
    sources move, the elements of one chain cannot all stick, so the problem is
    degenerate and first-order methods crawl.

    First the fast path (`_same_pattern`): last step's stick/slip pattern,
    checked exactly. When it fails (a transition), two stages:

    1. the box problem ``min 1/2 p^T (W + eps I) p - q.p`` with a tiny
       ``eps = 1e-9 max W_ee`` is strictly convex; a primal active-set method
       (free elements stuck, the others at a bound) solves it in finitely many
       steps, each an n x n solve by Woodbury's identity;
    2. polish: the stuck elements' remaining slips (of order eps p, a creep of
       ~1e-12 rad/s) are removed by the minimum-norm correction of their
       impulses, so stuck elements hold exactly (to round-off).

    ``n`` is the number of rows of ``YT`` that are used (the free coordinates;
    a compile-time constant inside the stepping loop, see `free_token`).
    ``state`` (-1, 0 free, +1; 2 = not involved) and ``p`` carry the previous
    step's solution as a warm start; ``ws`` is `impulse_workspace`, whose ``z``
    (index 7) holds ``YT p`` on return. Returns
    ``(converged, active-set iterations)`` (0 iterations: the fast path held).
    """
    if _same_pattern(YT, q, cap, p, state, active, ws, n):
        return True, 0
    return _active_set(YT, q, cap, p, state, active, ws)


@inline
def _element_slips(DxT, DuT, v, u, s, n):
    """Every element's slip ``s = Dx v + Du u`` (dense, one coordinate per row of
    ``DxT`` and ``DuT``: the inner loops run over elements and vectorise)."""
    for e in range(s.shape[0]):
        s[e] = 0.0
    for i in range(n):
        vi = v[i]
        for e in range(s.shape[0]):
            s[e] += DxT[i, e] * vi
    for j in range(u.shape[0]):
        uj = u[j]
        for e in range(s.shape[0]):
            s[e] += DuT[j, e] * uj


@inline
def _udot(up, uc, uv, r, vec):
    """Source part of row ``r`` dotted with a source vector (sparse)."""
    acc = 0.0
    for k in range(up[r], up[r + 1]):
        acc += uv[k] * vec[uc[k]]
    return acc


@inline
def _uadd(up, uc, uv, r, vec, scale):
    """``vec += scale * (source part of row r)``."""
    for k in range(up[r], up[r + 1]):
        vec[uc[k]] += scale * uv[k]


@inline
def _outer(xp, xc, xv, r, H, scale):
    """``H += scale * d d^T`` with ``d`` the free-coordinate part of row ``r``."""
    for a in range(xp[r], xp[r + 1]):
        for b in range(xp[r], xp[r + 1]):
            H[xc[a], xc[b]] += scale * xv[a] * xv[b]


@inline
def _sizes(dims):
    """Coordinates, sources, friction elements, springs, loads and motors of a model."""
    return dims[D_N], dims[D_S], dims[D_F], dims[D_K], dims[D_L], dims[D_M]


@inline
def _parallel(DxT, DuT, e, g):
    """``alpha`` with row ``e`` = ``alpha`` row ``g`` (free and source parts, to
    round-off), or 0 if the rows are not parallel (row ``g`` nonzero)."""
    dot = 0.0
    norm = 0.0
    big = 0.0
    for i in range(DxT.shape[0]):
        dot += DxT[i, e] * DxT[i, g]
        norm += DxT[i, g] * DxT[i, g]
        big = max(big, abs(DxT[i, e]))
    for j in range(DuT.shape[0]):
        dot += DuT[j, e] * DuT[j, g]
        norm += DuT[j, g] * DuT[j, g]
        big = max(big, abs(DuT[j, e]))
    if norm == 0.0:
        return 0.0
    alpha = dot / norm
    for i in range(DxT.shape[0]):
        if abs(DxT[i, e] - alpha * DxT[i, g]) > PARALLEL * big:
            return 0.0
    for j in range(DuT.shape[0]):
        if abs(DuT[j, e] - alpha * DuT[j, g]) > PARALLEL * big:
            return 0.0
    return alpha


def free_token(m):
    """The last argument of `run` for model ``m``: a tuple of n zeros, one per
    free coordinate.

    A tuple's length is part of its numba type, so `run` is compiled once per
    number of free coordinates and its stepping loop sees that number as a
    constant: the many loops over the coordinates (two in the wrist) are then
    unrolled. Measured on the fig 4.15 stiction run: a fifth less time per
    step, for one more compilation (about a minute, cached on disk) per
    distinct number of free coordinates.
    """
    return (0,) * int(m.dims[D_N])


@kernel
def run(m, w, y0, duration, h, t_out, max_steps, ledger, out, coulomb, stuck, free):
    """Integrate with fixed step ``h``; sample at ``t_out`` (multiples of ``h``).

    ``free`` is `free_token` of ``m``.

    The samples go into caller-owned arrays, as with `dopri.integrate`: ``out``
    (one row per sample, NaN-filled by the caller so that rows after a failure
    stay NaN) takes the leading ``out.shape[1]`` entries of the state and
    accumulator vector; ``coulomb`` and ``stuck`` (one row per sample, one
    column per friction element) are filled only if they have rows. A batch
    passes its own output row and no ``coulomb``/``stuck`` rows, so its runs
    allocate no per-sample memory.

    With ``ledger`` False the energy accumulators are not booked (they stay as
    in ``y0``): batch runs, which report states only, skip that work, and the
    pivot's range is then checked at mid-steps and at the end (half a step
    later than with the ledger, which checks at every step's end).

    Returns ``(status, t, y, steps, transitions)``. ``out`` gets the state and
    accumulators at each sample, ``coulomb`` the Coulomb torque of each
    stiction element over the step ending there (the resistive torque,
    positive against positive slip), ``stuck`` whether it held.
    ``transitions`` counts, per element, the starts and ends of stick
    phases; a phase starts when an element has held for two consecutive steps,
    so a speed reversal that touches zero for a single step (the scheme's
    resolution) is not counted as sticking.
    """
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, cum, \
        first, count = m
    n, s_n, nf, nk, nl, nm = _sizes(dims)
    if len(free) != n:
        raise ValueError("timestep.run: free must be free_token(m), one entry per free "
                         "coordinate")
    sampled = coulomb.shape[0] > 0
    if out.shape[0] != t_out.shape[0] or stuck.shape != coulomb.shape \
            or (sampled and coulomb.shape != (t_out.shape[0], nf)):
        raise ValueError("timestep.run: out needs one row per sample; coulomb and stuck "
                         "either none or one row per sample and one column per friction element")
    n_state = 2 * n + nm

    transitions = np.zeros(nf, dtype=np.int64)
    held = np.zeros(nf, dtype=np.int64)
    y = y0.copy()
    x = y[:n].copy()
    v = y[n:2 * n].copy()
    cur = y[2 * n:n_state].copy()

    # Coulomb impulses act on free coordinates ("active"); elements driven by
    # sources alone ("driven") just follow their slip
    active = np.zeros(nf, dtype=np.bool_)
    driven = np.zeros(nf, dtype=np.bool_)
    for e in range(nf):
        if code[e] == STICTION:
            if xp[e + 1] > xp[e]:
                active[e] = True
            else:
                driven[e] = True
    # Elements whose smooth part is linear (viscous, and stiction's viscous part)
    # are summed once into constant matrices: their share of the step matrix is
    # h Bx and of the right-hand side -h Bu u1. Every element's slip is computed
    # from dense element matrices stored one coordinate per row, so that the
    # loops over elements are plain vector operations.
    linear = np.zeros(nf, dtype=np.bool_)
    Bx = np.zeros((n, n))
    Bu = np.zeros((n, s_n))
    DxT = np.zeros((n, nf + nk))  # friction elements, then springs
    DuT = np.zeros((s_n, nf + nk))
    for e in range(nf + nk):
        for k in range(xp[e], xp[e + 1]):
            DxT[xc[k], e] = xv[k]
        for k in range(up[e], up[e + 1]):
            DuT[uc[k], e] = uv[k]
        if e < nf and (code[e] == STICTION or code[e] == VISCOUS):
            linear[e] = True
            b = par[e, 0]
            for i in range(n):
                for c in range(n):
                    Bx[i, c] += b * DxT[i, e] * DxT[c, e]
                for j in range(s_n):
                    Bu[i, j] += b * DxT[i, e] * DuT[j, e]
    # The impulse problem is posed over groups of active elements. Elements whose
    # rows (free and source parts) are parallel, row_e = ratio[e] row_lead, slip
    # together (in the wrist: the bearings and meshes that turn at the speed of
    # one gear), so one impulse along the lead's row, bounded by their levels
    # summed as sum |ratio_e| c_e, stands for all of them. That is exact: the
    # impulses' feasible set and the stick/slip conditions are the same, and the
    # problem shrinks (13 unknowns to 7 in the wrist). slot[e] is the unknown of
    # element e (-1: not active), share[e] its part of that impulse: in proportion
    # to its level, so a slipping group puts every element at its level, and a
    # stuck group's load (which the contact conditions leave undetermined)
    # loads each element to the same fraction of its level.
    slot = np.full(nf, -1, dtype=np.int64)
    ratio = np.zeros(nf)
    lead = np.empty(nf, dtype=np.int64)
    na = 0
    for e in range(nf):
        if not active[e]:
            continue
        for a in range(na):
            alpha = _parallel(DxT, DuT, e, lead[a])
            if alpha != 0.0:
                slot[e] = a
                ratio[e] = alpha
                break
        if slot[e] < 0:
            slot[e] = na
            ratio[e] = 1.0
            lead[na] = e
            na += 1
    DxA = np.empty((n, na))
    DuA = np.empty((s_n, na))
    for a in range(na):
        DxA[:, a] = DxT[:, lead[a]]
        DuA[:, a] = DuT[:, lead[a]]
    involved = np.ones(na, dtype=np.bool_)
    level = np.zeros(na)  # Coulomb levels of the groups
    for e in range(nf):
        if slot[e] >= 0:
            level[slot[e]] += abs(ratio[e]) * coulomb_level(par, e)
    share = np.zeros(nf)
    for e in range(nf):
        if slot[e] >= 0 and level[slot[e]] > 0.0:
            share[e] = math.copysign(coulomb_level(par, e) / level[slot[e]], ratio[e])
    # index lists, so that the per-step loops visit only the elements concerned:
    # smooth parts that are not linear, and elements whose stick phases are counted
    nonlinear = np.flatnonzero(~linear)
    watched = np.flatnonzero(active | driven)
    # at mid-step only the loads, the motor voltages and the pivot's sources are
    # read: their channels (mid_ch) and the pivot's sources (mid_src); a load or
    # voltage constant in time (one piece of degree 0) keeps its value from t = 0.
    # At step end only the sources' channels are read (end_ch).
    r_load = nf + nk
    r_piv = dims[D_R] - 1
    wanted = np.zeros(first.shape[0], dtype=np.bool_)
    for rr in range(r_load, r_load + nl + nm):
        c = code[rr]
        p0 = first[c]
        steady = count[c] == 1 and coef[p0, 1] == 0.0 and coef[p0, 2] == 0.0 \
            and coef[p0, 3] == 0.0
        wanted[c] = not steady
    mid_src = uc[up[r_piv]:up[r_piv + 1]].copy()
    for j in mid_src:
        wanted[src_ch[j]] = True
    mid_ch = np.flatnonzero(wanted)
    wanted[:] = False
    for j in range(s_n):
        wanted[src_ch[j]] = True
    end_ch = np.flatnonzero(wanted)

    H = np.empty((n, n))
    H_last = np.zeros((n, n))
    Lc = np.empty((n, n))
    r = np.empty(n)
    vfree = np.empty(n)
    v1 = np.empty(n)
    x1 = np.empty(n)
    col = np.empty(n)
    drow = np.empty(n)
    YlT = np.zeros((n, na))
    qv = np.zeros(na)
    cap = np.zeros(na)
    p = np.zeros(na)
    slip = np.zeros(nf)
    state = np.zeros(na, dtype=np.int64)
    ws = impulse_workspace(n, na)
    s0 = np.empty(nf)
    f0 = np.empty(nf)
    df0 = np.empty(nf)
    force = np.empty(nf)
    sp_c = np.empty(nk)
    sp_kap = np.empty(nk)
    u0 = np.empty(s_n)
    sg0 = np.empty(s_n)
    u1 = np.empty(s_n)
    sg1 = np.empty(s_n)
    um = np.empty(s_n)
    ldm = np.empty(nl)
    vm = np.empty(nm)
    srcF = np.empty(s_n)
    i1 = np.empty(nm)

    scratch = (H, H_last, Lc, YlT, ws, Bx, Bu, DxT, DuT, x, v, cur, r, vfree, v1, x1, col, drow,
               qv, cap, p, slip, s0, f0, df0, force, sp_c, sp_kap, u0, sg0, u1, sg1, um, ldm, vm,
               srcF, i1, held, state, active, driven, linear,
               share, slot, DxA, DuA, involved, level, nonlinear, watched, mid_ch, mid_src, end_ch)

    status, t, steps_done = _steps(m, w, scratch, y, duration, h, t_out, max_steps, ledger, out,
                                   coulomb, stuck, transitions, free)
    return status, t, y, steps_done, transitions


@loop
def _steps(m, w, scratch, y, duration, h, t_out, max_steps, ledger, out, coulomb, stuck,
           transitions, free):
    """The stepping loop of `run`, over preallocated arrays; returns ``(status, t, steps)``.

    The number of free coordinates is ``len(free)``, a compile-time constant
    (see `free_token`); the helpers it inlines take it as their ``n``.

    Compiled as `vsj.jit.loop` (it allocates nothing): without reference
    counting, which in this branchy loop cost about a tenth of the time.
    """
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, cum, \
        first, count = m
    hint, chan, srcw, frw, spw, ldw, mow, gen, scal = w
    H, H_last, Lc, YlT, ws, Bx, Bu, DxT, DuT, x, v, cur, r, vfree, v1, x1, col, drow, qv, cap, \
        p, slip, s0, f0, df0, force, sp_c, sp_kap, u0, sg0, u1, sg1, um, ldm, vm, srcF, i1, \
        held, state, active, driven, linear, share, slot, DxA, DuA, involved, level, nonlinear, \
        watched, mid_ch, mid_src, end_ch = scratch
    na = level.shape[0]
    _, s_n, nf, nk, nl, nm = _sizes(dims)
    n = len(free)
    r_load = nf + nk
    r_mot = r_load + nl
    r_piv = dims[D_R] - 1
    moving_pivot = par[r_piv, 2] > 0.0
    n_state = 2 * n + nm
    a_src = n_state
    a_load = a_src + s_n
    a_elec = a_load + nl
    a_fric = a_elec + nm
    a_res = a_fric + nf
    a_spr = a_res + nm
    a_piv = a_spr + nk
    n_out = t_out.shape[0]
    n_col = min(out.shape[1], y.shape[0])
    sample_friction = coulomb.shape[0] > 0

    eval_inputs(0.0, knots, coef, cum, first, count, hint, chan, src_ch, src_pos0, srcw)
    for j in range(s_n):
        u0[j] = srcw[j, U]
        sg0[j] = srcw[j, SG]
    # one exit at the end: early returns of arrays from inside the loop would make
    # numba count references of every live array on every step
    status = OK
    scal[STATUS] = OK
    q_prev = pivot_position(dims, xp, xc, xv, up, uc, uv, par, srcw, scal, x)
    # the mid-step pivot position is recomputed only when its angle changes (a
    # pivot held still costs no sine per step)
    angle_mid = math.nan
    q_mid = q_prev
    steps_total = int(math.ceil(duration / h - 1e-9))
    if scal[STATUS] != OK:
        status = int(scal[STATUS])
        steps_total = 0
    elif steps_total > max_steps:
        status = TOO_MANY_STEPS
        steps_total = 0
    _element_slips(DxT, DuT, v, u0, slip, n)  # carried: each step starts from the last one's
    steps_done = 0
    i_out = 0
    if n_out > 0 and t_out[0] <= 0.0:
        for j in range(n_col):
            out[0, j] = y[j]
        i_out = 1
    t = 0.0
    for step in range(steps_total):
        # time from the step count: summing h would drift by ~1e-11 s over a long run
        t1 = (step + 1) * h if step < steps_total - 1 else duration
        hs = t1 - t
        # mid-step inputs (loads, voltages) and pivot position
        for i in range(mid_ch.shape[0]):
            eval_channel(mid_ch[i], t + 0.5 * hs, knots, coef, cum, first, count, hint, chan)
        for i in range(mid_src.shape[0]):
            eval_source(mid_src[i], chan, src_ch, src_pos0, srcw)
        for ld in range(nl):
            ldm[ld] = chan[code[r_load + ld], 0]
        for mo in range(nm):
            vm[mo] = chan[code[r_mot + mo], 0]
        for i in range(n):
            x1[i] = x[i] + 0.5 * hs * v[i]
        angle = pivot_angle(dims, xp, xc, xv, up, uc, uv, srcw, x1)
        if angle != angle_mid:
            angle_mid = angle
            q_mid = pivot_at(par, r_piv, angle, scal)
        for i in range(end_ch.shape[0]):
            eval_channel(end_ch[i], t1, knots, coef, cum, first, count, hint, chan)
        for j in range(s_n):
            eval_source(j, chan, src_ch, src_pos0, srcw)
            u1[j] = srcw[j, U]
            sg1[j] = srcw[j, SG]

        # H v1 = r: inertia, springs (trapezoidal), smooth friction and motors (implicit)
        for i in range(n):
            total = 0.0
            for c in range(n):
                H[i, c] = mass[i, c] + hs * Bx[i, c]
                total += mass[i, c] * v[c]
            for j in range(s_n):
                total -= mass[i, n + j] * (u1[j] - u0[j]) + hs * Bu[i, j] * u1[j]
            r[i] = total
        for k in range(nk):
            rr = nf + k
            d0 = 0.0
            rate = 0.0
            for i in range(n):
                d0 += DxT[i, rr] * x[i]
                rate += DxT[i, rr] * v[i]
            dsig = 0.0
            for j in range(s_n):
                d0 += DuT[j, rr] * sg0[j]
                dsig += DuT[j, rr] * (sg1[j] - sg0[j])
            tau, kap, _, _ = spring_law(code[rr], row(par, rr), d0, q_mid)
            c_k = tau - 0.5 * kap * dsig - 0.25 * kap * hs * rate
            sp_c[k] = c_k
            sp_kap[k] = kap
            for i in range(n):
                di = DxT[i, rr]
                r[i] += hs * c_k * di
                for c in range(n):
                    H[i, c] += 0.25 * hs * hs * kap * di * DxT[c, rr]
        for e in range(nf):
            s0[e] = slip[e]
        for i in range(nonlinear.shape[0]):
            e = nonlinear[i]
            se = slip[e]
            fe, dfe = resistive_torque(code[e], par[e, 0], par[e, 1], par[e, 2], par[e, 3], se)
            f0[e] = fe
            df0[e] = dfe
            const = fe - dfe * se + dfe * _udot(up, uc, uv, e, u1)
            xadd(xp, xc, xv, e, r, -hs * const)
            _outer(xp, xc, xv, e, H, hs * dfe)
        for ld in range(nl):
            xadd(xp, xc, xv, r_load + ld, r, hs * ldm[ld])
        for mo in range(nm):
            rr = r_mot + mo
            R, Lm, kt = par[rr, 0], par[rr, 1], par[rr, 2]
            g = 1.0 / (1.0 + hs * R / Lm)
            const = kt * g * (cur[mo] + hs / Lm * (vm[mo] - kt * _udot(up, uc, uv, rr, u1)))
            damp = kt * kt * g * hs / Lm
            xadd(xp, xc, xv, rr, r, hs * const)
            _outer(xp, xc, xv, rr, H, hs * damp)
        # H changes only with non-linear springs, smooth friction slopes or a moving
        # pivot; while it stays within round-off of the matrix last factored
        # (H_last), that factor and Y, YlT are reused
        scale_h = 0.0
        for i in range(n):
            for c in range(n):
                scale_h = max(scale_h, abs(H_last[i, c]))
        same = step > 0
        for i in range(n):
            for c in range(n):
                same = same and abs(H[i, c] - H_last[i, c]) <= H_REUSE * scale_h
        if n > 0 and not same:
            for i in range(n):
                for c in range(n):
                    H_last[i, c] = H[i, c]
            if not _cholesky(H, Lc, n, False):
                status = NOT_FINITE
                break
            for a in range(na):
                for i in range(n):
                    drow[i] = DxA[i, a]
                _forward(Lc, drow, col, n)  # L^-1 d_e: W = Y Y^T, Y = YlT^T
                for i in range(n):
                    YlT[i, a] = col[i]
            ws[-1][na] = 0.0  # the impulse solver's memo was made with the old YlT
        if n > 0:
            _solve(Lc, r, vfree, n)

        # Coulomb impulses of the stiction elements, all together
        if na > 0:
            for a in range(na):
                cap[a] = hs * level[a]
            _element_slips(DxA, DuA, vfree, u1, qv, n)
            ok, _ = solve_impulses(YlT, qv, cap, p, state, involved, ws, n)
            if not ok:
                status = FRICTION_SOLVER
                break
            # the impulses change the speeds by H^-1 D^T p = L^-T (YlT p)
            _backward(Lc, ws[7], v1, n)
            for i in range(n):
                v1[i] = vfree[i] - v1[i]
        else:
            for i in range(n):
                v1[i] = vfree[i]
        for i in range(n):
            x1[i] = x[i] + 0.5 * hs * (v[i] + v1[i])
        for mo in range(nm):
            rr = r_mot + mo
            R, Lm, kt = par[rr, 0], par[rr, 1], par[rr, 2]
            g = 1.0 / (1.0 + hs * R / Lm)
            omega1 = xdot(xp, xc, xv, rr, v1, 0) + _udot(up, uc, uv, rr, u1)
            i1[mo] = g * (cur[mo] + hs / Lm * (vm[mo] - kt * omega1))

        # energy bookkeeping against mid-step speeds
        for j in range(s_n):
            um[j] = 0.5 * (u0[j] + u1[j])
            srcF[j] = 0.0
        _element_slips(DxT, DuT, v1, u1, slip, n)
        # the elements' torques are wanted by the ledger and at the samples only
        sample = i_out < n_out and t_out[i_out] <= t1 + 0.5 * h
        for e in range(nf if ledger or sample else 0):
            s1 = slip[e]
            fe = par[e, 0] * s1 if linear[e] else f0[e] + df0[e] * (s1 - s0[e])
            if active[e]:
                fe += share[e] * p[slot[e]] / hs
            elif driven[e] and s1 != 0.0:
                fe += coulomb_level(par, e) * (1.0 if s1 > 0.0 else -1.0)
            force[e] = fe
            if ledger:
                y[a_fric + e] += hs * fe * 0.5 * (s0[e] + s1)
                _uadd(up, uc, uv, e, srcF, -fe)
        q_end = q_prev
        if moving_pivot and (ledger or step == steps_total - 1):  # at t1, for the ledger
            q_end = pivot_position(dims, xp, xc, xv, up, uc, uv, par, srcw, scal, x1)
        if ledger:  # springs, loads, motors and sources
            for k in range(nk):
                rr = nf + k
                tau_avg = sp_c[k] - 0.25 * sp_kap[k] * hs * xdot(xp, xc, xv, rr, v1, 0)
                dd = (xdot(xp, xc, xv, rr, x1, 0) - xdot(xp, xc, xv, rr, x, 0)
                      + _udot(up, uc, uv, rr, sg1) - _udot(up, uc, uv, rr, sg0))
                y[a_spr + k] += tau_avg * dd
                _uadd(up, uc, uv, rr, srcF, tau_avg)
                if q_end != q_prev:
                    d1 = xdot(xp, xc, xv, rr, x1, 0) + _udot(up, uc, uv, rr, sg1)
                    e1 = spring_law(code[rr], row(par, rr), d1, q_end)[2]
                    e0 = spring_law(code[rr], row(par, rr), d1, q_prev)[2]
                    y[a_piv + k] += e1 - e0
            for ld in range(nl):
                rr = r_load + ld
                omega = 0.5 * (xdot(xp, xc, xv, rr, v, 0) + xdot(xp, xc, xv, rr, v1, 0))
                omega += _udot(up, uc, uv, rr, um)
                y[a_load + ld] += hs * ldm[ld] * omega
                _uadd(up, uc, uv, rr, srcF, ldm[ld])
            for mo in range(nm):
                rr = r_mot + mo
                imid = 0.5 * (cur[mo] + i1[mo])
                y[a_elec + mo] += hs * vm[mo] * imid
                y[a_res + mo] += hs * par[rr, 0] * i1[mo] * imid
                _uadd(up, uc, uv, rr, srcF, par[rr, 2] * i1[mo])
            for j in range(s_n):
                impulse = -hs * srcF[j]
                for i in range(n):
                    impulse += mass[n + j, i] * (v1[i] - v[i])
                for c in range(s_n):
                    impulse += mass[n + j, n + c] * (u1[c] - u0[c])
                y[a_src + j] += um[j] * impulse

        # advance
        for i in range(n):
            x[i] = x1[i]
            v[i] = v1[i]
        for mo in range(nm):
            cur[mo] = i1[mo]
        for j in range(s_n):
            u0[j] = u1[j]
            sg0[j] = sg1[j]
        t = t1
        q_prev = q_end
        for i in range(watched.shape[0]):
            e = watched[i]
            if abs(slip[e]) <= STUCK_SPEED:
                held[e] += 1
                if held[e] == 2:
                    transitions[e] += 1
            else:
                if held[e] >= 2:
                    transitions[e] += 1
                held[e] = 0
        steps_done = step + 1
        if scal[STATUS] != OK:
            status = int(scal[STATUS])
            break
        finite = True
        for i in range(n):
            y[i] = x[i]
            y[n + i] = v[i]
            finite = finite and math.isfinite(x[i]) and math.isfinite(v[i])
        if not finite:
            status = NOT_FINITE
            break
        for mo in range(nm):
            y[2 * n + mo] = cur[mo]
        while i_out < n_out and t_out[i_out] <= t + 0.5 * h:
            for j in range(n_col):
                out[i_out, j] = y[j]
            if sample_friction:
                for i in range(watched.shape[0]):
                    e = watched[i]
                    coulomb[i_out, e] = force[e] - par[e, 0] * slip[e]
                    stuck[i_out, e] = abs(slip[e]) <= STUCK_SPEED
            i_out += 1
    return status, t, steps_done
