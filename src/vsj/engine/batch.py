"""Many runs of one model in parallel (numba threads on every core).

Runs share the model's structure and inputs; each may differ in its mass
matrix, element parameters, initial source angles (hence the pivot position)
and initial state. Only the states are sampled (the leading columns of the
state vector), straight into the batch's output rows; the final state,
accumulators included, is kept for each run's ledger.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from ..jit import parallel
from .core import OK, make_work
from .dopri import integrate
from .model import D_F, EngineModel
from .timestep import run as timestep_run


@parallel
def dopri_batch(m, masses, Minvs, pars, src0s, y0s, t_end, t_out, rtol, atol, h_max, max_steps,
                n_err, outs, y_end, status, t_stop, steps):
    for r in prange(y0s.shape[0]):
        mr = EngineModel(m.dims, masses[r], Minvs[r], m.rows, m.xp, m.xc, m.xv, m.up, m.uc, m.uv,
                         pars[r], m.code, m.src_ch, src0s[r], m.knots, m.coef, m.cum, m.first,
                         m.count)
        w = make_work(mr)
        y = y0s[r].copy()
        st, ts, ns, _ = integrate(mr, w, y, 0.0, t_end, t_out, rtol, atol, h_max, max_steps,
                                  n_err, outs[r])
        y_end[r] = y
        status[r] = st
        t_stop[r] = ts
        steps[r] = ns


@parallel
def timestep_batch(m, masses, Minvs, pars, src0s, y0s, t_end, h, t_out, max_steps, outs, y_end,
                   status, t_stop, steps, transitions, free):
    no_coulomb = np.zeros((0, m.dims[D_F]))
    no_stuck = np.zeros((0, m.dims[D_F]), dtype=np.bool_)
    for r in prange(y0s.shape[0]):
        mr = EngineModel(m.dims, masses[r], Minvs[r], m.rows, m.xp, m.xc, m.xv, m.up, m.uc, m.uv,
                         pars[r], m.code, m.src_ch, src0s[r], m.knots, m.coef, m.cum, m.first,
                         m.count)
        w = make_work(mr)
        # samples straight into this run's rows; friction torques are not sampled
        st, ts, y, ns, flips = timestep_run(mr, w, y0s[r], t_end, h, t_out, max_steps, False,
                                            outs[r], no_coulomb, no_stuck, free)
        y_end[r] = y
        status[r] = st
        t_stop[r] = ts
        steps[r] = ns
        total = 0
        for e in range(flips.shape[0]):
            total += flips[e]
        transitions[r] = total


__all__ = ["dopri_batch", "timestep_batch", "OK"]
