/* One entry point for runs: vsj_begin, then vsj_advance block by block.
 *
 * Every driver of the engine (single runs, batches, sweeps, identification, the
 * step function of estimators and FMUs) starts a run with vsj_begin (the scheme and
 * its settings, the initial state) and samples it with vsj_advance. The steps do
 * not depend on how the samples are split between calls (dopri.c, rosenbrock.c,
 * timestep.c), so a run streamed in blocks equals one sampled at once.
 */
#include <math.h>
#include <string.h>

#include "internal.h"

int vsj_begin(const vsj_model *m, vsj_work *w, const vsj_scheme *scheme, const double *y0,
              int64_t ny, double t0, double t_end) {
    int status;
    if (!vsj__fits(m, w) || !scheme || !y0 || !(scheme->max_steps >= 1) || !isfinite(t0)
        || !isfinite(t_end) || !(t_end >= t0))
        return VSJ_BAD_ARGUMENT;
    w->scheme = *scheme;
    w->run_ny = ny;
    w->run_end = t_end;
    w->run_steps = 0;
    w->run_status = VSJ_BAD_ARGUMENT;
    if (m->n_acts > 0 && scheme->method == VSJ_METHOD_TIMESTEP) {
        /* the samples on the steps' grid: the period a whole number of steps */
        double ratio = m->ctl[VSJ_CTL_PERIOD] / scheme->h;
        if (!(ratio >= 1.0 - 1e-9) || fabs(ratio - floor(ratio + 0.5)) > 1e-9 * ratio)
            return VSJ_BAD_ARGUMENT;
    }
    vsj__control_begin(m, w, t0, y0);
    w->held = NULL;
    w->in_model = NULL; /* the work may have served another model at this address */
    w->ev_model = NULL;
    if (scheme->method == VSJ_METHOD_DOPRI) {
        status = vsj__dopri_begin(m, w, y0, ny, t0, t_end, scheme->rtol, scheme->atol,
                                 scheme->h_max, scheme->max_steps, scheme->n_err);
    } else if (scheme->method == VSJ_METHOD_ROSENBROCK) {
        status = vsj__ros_begin(m, w, y0, ny, t0, t_end, scheme->rtol, scheme->atol,
                                scheme->h_max, scheme->max_steps, scheme->n_err);
    } else if (scheme->method == VSJ_METHOD_TIMESTEP) {
        if (!(scheme->h > 0.0) || ny < vsj_n_state(m)
            || (scheme->ledger && ny < vsj_n_state(m) + vsj_n_acc(m)))
            return VSJ_BAD_ARGUMENT;
        status = vsj_ts_prepare(m, w);
        if (status == VSJ_OK)
            status = vsj__ts_begin(m, w, y0, t0);
        if (status == VSJ_PIVOT_RANGE) /* reported by the advance, at its time */
            status = VSJ_OK;
    } else {
        return VSJ_BAD_ARGUMENT;
    }
    w->run_status = status;
    return status;
}

vsj_report vsj_advance(const vsj_model *m, vsj_work *w, double *y, double t_until, int finish,
                       const vsj_samples *samples) {
    vsj_report rep;
    const vsj_scheme *sc = &w->scheme;
    memset(&rep, 0, sizeof rep);
    rep.status = w->run_status;
    if (!vsj__fits(m, w) || !y || !isfinite(t_until) || t_until > w->run_end) {
        rep.status = VSJ_BAD_ARGUMENT;
        return rep;
    }
    if (w->run_status != VSJ_OK)
        return rep;
    if (sc->method == VSJ_METHOD_DOPRI || sc->method == VSJ_METHOD_ROSENBROCK) {
        rep = vsj__dopri_advance(m, w, samples ? samples->t : NULL, samples ? samples->n : 0,
                                samples ? samples->out : NULL, samples ? samples->out_cols : 0,
                                finish, y);
    } else {
        rep = vsj__ts_advance(m, w, y, finish ? w->run_end : t_until, sc->h,
                             sc->max_steps - w->run_steps, sc->ledger, samples);
        w->run_steps += rep.steps;
        rep.steps = w->run_steps;
    }
    w->run_status = rep.status;
    return rep;
}
