/* The step function: advance a state by one control period with held inputs.
 *
 * State s = [x (n), p (n), i (motors), sigma (sources)]: momenta p = M v + M_su u
 * rather than speeds, because a velocity source whose speed jumps between two
 * periods gives the free flanges an impulse; the momentum is continuous across
 * the jump, the speeds are not. Within a period the inputs are constant (what
 * a digital controller applies), the sources start at the angles sigma.
 */
#include <math.h>
#include <string.h>

#include "internal.h"

int64_t vsj_step_state_size(const vsj_model *m) {
    return 2 * m->n + m->n_motors + m->n_sources;
}

/* Hold the inputs over the period and start the sources at s[base:]; a controller
 * (whose actuators override the channels they drive) is off until the period begins
 * (begin_period). The evaluation analyses the model's rows anew: the work may have
 * stepped another model at these addresses since, or these rows before they changed. */
static void hold(const vsj_model *m, vsj_work *w, const double *s, const double *inputs) {
    w->held = inputs;
    w->ctl_on = 0;
    w->ev_model = NULL;
    memcpy(w->pos0, s + 2 * m->n + m->n_motors, (size_t)m->n_sources * sizeof(double));
}

/* The engine state y of s (to_engine), and a model's controller sampled at the
 * period's start. */
static void to_engine(const vsj_model *m, const double *s, const double *inputs, double *y,
                      double *scratch);
static void begin_period(const vsj_model *m, vsj_work *w, const double *s, const double *inputs,
                         double dt, double *y) {
    hold(m, w, s, inputs);
    to_engine(m, s, inputs, y, w->sacc);
    if (m->n_acts > 0)
        vsj__control_period(m, w, y, dt);
}

/* Engine state [x, v, i] from [x, p, i, ...]: v = M^-1 (p - M_su u); `scratch` holds
 * 2 n values. */
static void to_engine(const vsj_model *m, const double *s, const double *inputs, double *y,
                      double *scratch) {
    int64_t n = m->n, ns = m->n_sources, sz = n + ns, i, r, j;
    double *free_p = scratch, *sizes = scratch + n; /* p - M_su u, and its terms' size */
    for (r = 0; r < n; r++) {
        double pr = s[n + r], size = fabs(pr);
        for (j = 0; j < ns; j++) {
            double term = m->mass[sz * r + n + j] * inputs[m->src_ch[j]];
            pr -= term;
            size += fabs(term);
        }
        free_p[r] = pr;
        sizes[r] = size;
    }
    for (i = 0; i < n; i++) {
        double acc = 0.0, bound = 0.0;
        y[i] = s[i];
        for (r = 0; r < n; r++) {
            acc += m->Minv[n * i + r] * free_p[r];
            bound += fabs(m->Minv[n * i + r]) * sizes[r];
        }
        /* a speed within the round-off of the cancellation p - M_su u (8 ulp of
         * its terms) is zero: left at 1e-19, it would make the integrator's first
         * step 1e-19 s long with a tight atol (Hairer's initial-step estimate) */
        y[n + i] = fabs(acc) > 8.0 * 2.220446049250313e-16 * bound ? acc : 0.0;
    }
    for (i = 0; i < m->n_motors; i++)
        y[2 * n + i] = s[2 * n + i];
}

/* Back to [x, p, i, sigma] after a period (the sources moved u dt). */
static void from_engine(const vsj_model *m, const double *y, const double *inputs, double dt,
                        double *s) {
    int64_t n = m->n, ns = m->n_sources, sz = n + ns, nm = m->n_motors, r, i, j;
    for (r = 0; r < n; r++) {
        double acc = 0.0;
        s[r] = y[r];
        for (i = 0; i < n; i++)
            acc += m->mass[sz * r + i] * y[n + i];
        for (j = 0; j < ns; j++)
            acc += m->mass[sz * r + n + j] * inputs[m->src_ch[j]];
        s[n + r] = acc;
    }
    for (i = 0; i < nm; i++)
        s[2 * n + i] = y[2 * n + i];
    for (j = 0; j < ns; j++)
        s[2 * n + nm + j] += inputs[m->src_ch[j]] * dt;
}

void vsj_step_speeds(const vsj_model *m, const double *s, const double *inputs, double *v) {
    int64_t n = m->n, ns = m->n_sources, sz = n + ns, i, r, j;
    for (i = 0; i < n; i++) {
        double acc = 0.0;
        for (r = 0; r < n; r++) {
            double pr = s[n + r];
            for (j = 0; j < ns; j++)
                pr -= m->mass[sz * r + n + j] * inputs[m->src_ch[j]];
            acc += m->Minv[n * i + r] * pr;
        }
        v[i] = acc;
    }
}

double vsj_step_pivot_position(const vsj_model *m, const double *s) {
    int64_t r = m->n_rows - 1;
    const double *p = vsj__row(m, r);
    double angle = vsj__xdot(m, r, s) + vsj__udotv(m, r, s + 2 * m->n + m->n_motors);
    return p[2] * p[0] * sin(angle) + (1.0 - p[2]) * p[1];
}

static int step_adaptive(const vsj_model *m, vsj_work *w, const vsj_scheme *sc, double *s,
                         const double *inputs, double dt) {
    int64_t ny = vsj_n_state(m);
    vsj_report rep;
    if (!vsj__fits(m, w) || !(dt > 0.0))
        return VSJ_BAD_ARGUMENT;
    begin_period(m, w, s, inputs, dt, w->sy);
    rep = vsj__adaptive(m, w, sc->method, w->sy, ny, 0.0, dt, sc->rtol, sc->atol, sc->max_steps,
                        ny);
    w->held = NULL;
    if (rep.status == VSJ_OK)
        from_engine(m, w->sy, inputs, dt, s);
    return rep.status;
}

static const double RK4_C[4] = {0.0, 0.5, 0.5, 1.0};
static const double RK4_W[4] = {1.0 / 6.0, 2.0 / 6.0, 2.0 / 6.0, 1.0 / 6.0};

static int step_rk4(const vsj_model *m, vsj_work *w, double *s, const double *inputs, double dt,
                    int64_t substeps) {
    int64_t ny = vsj_n_state(m), sub, stage, i;
    double *y = w->sy, *k = w->sk, *acc = w->sacc, *yt = w->yt, h;
    int status;
    if (!vsj__fits(m, w) || !(dt > 0.0) || substeps < 1 || substeps > VSJ_MAX_PERIOD_STEPS
        || vsj__rigid_stop(m))
        return VSJ_BAD_ARGUMENT;
    begin_period(m, w, s, inputs, dt, y);
    memset(k, 0, (size_t)ny * sizeof(double));
    h = dt / (double)substeps;
    w->status = VSJ_OK;
    /* after the last substep the right-hand side is evaluated once more, at the
     * end point, for its status (the pivot's range, finiteness) */
    for (sub = 0; sub <= substeps; sub++) {
        double t = (double)sub * h;
        int last = sub == substeps;
        for (stage = 0; stage < (last ? 1 : 4); stage++) {
            double a = RK4_C[stage];
            for (i = 0; i < ny; i++)
                yt[i] = stage ? y[i] + a * h * k[i] : y[i];
            vsj__eval_derivatives(m, w, t + a * h, yt, ny, k);
            if (last)
                break;
            for (i = 0; i < ny; i++) {
                if (stage == 0)
                    acc[i] = 0.0;
                acc[i] += RK4_W[stage] * k[i];
            }
        }
        if (!last)
            for (i = 0; i < ny; i++)
                y[i] += h * acc[i];
    }
    status = w->status;
    w->held = NULL;
    if (status == VSJ_OK)
        from_engine(m, y, inputs, dt, s);
    return status;
}

/* One period of the time-stepper: `steps` steps of h (the last shortened to end at dt),
 * as vsj_step has counted and checked them. */
static int step_timestep(const vsj_model *m, vsj_work *w, double *s, const double *inputs,
                         double dt, double h, int64_t steps) {
    vsj_report rep;
    int status;
    begin_period(m, w, s, inputs, dt, w->sy);
    status = vsj__ts_begin(m, w, w->sy, 0.0);
    rep = vsj__ts_advance(m, w, w->sy, dt, h, steps, 0, NULL);
    w->held = NULL;
    if (status == VSJ_OK)
        status = rep.status;
    if (status == VSJ_OK)
        from_engine(m, w->sy, inputs, dt, s);
    return status;
}

int vsj_step_rate(const vsj_model *m, vsj_work *w, const double *s, const double *inputs,
                  double *ds) {
    int64_t n = m->n, nm = m->n_motors, ny = 2 * n + nm, sz = n + m->n_sources, i, r, j;
    int status;
    if (!vsj__fits(m, w))
        return VSJ_BAD_ARGUMENT;
    hold(m, w, s, inputs);
    to_engine(m, s, inputs, w->sy, w->sacc);
    w->status = VSJ_OK;
    vsj__eval_derivatives(m, w, 0.0, w->sy, ny, w->sk);
    for (i = 0; i < n; i++) {
        double acc = 0.0;
        ds[i] = w->sy[n + i];
        for (r = 0; r < n; r++)
            acc += m->mass[sz * i + r] * w->sk[n + r];
        ds[n + i] = acc;
    }
    for (i = 0; i < nm; i++)
        ds[2 * n + i] = w->sk[2 * n + i];
    for (j = 0; j < m->n_sources; j++)
        ds[ny + j] = inputs[m->src_ch[j]];
    status = w->status; /* (a controller's channels: as `inputs` give them) */
    w->held = NULL;
    return status;
}

/* One period with the energy ledger over it (dopri, rosenbrock and the time-stepper). */
static int step_ledger(const vsj_model *m, vsj_work *w, const vsj_scheme *sc, double *s,
                       const double *inputs, double dt, double *ledger) {
    int64_t nstate = vsj_n_state(m), nacc = vsj_n_acc(m), ny = nstate + nacc;
    int status;
    vsj_report rep;
    begin_period(m, w, s, inputs, dt, w->sy);
    memset(w->sy + nstate, 0, (size_t)nacc * sizeof(double));
    if (sc->method == VSJ_METHOD_DOPRI || sc->method == VSJ_METHOD_ROSENBROCK) {
        rep = vsj__adaptive(m, w, sc->method, w->sy, ny, 0.0, dt, sc->rtol, sc->atol,
                            sc->max_steps, nstate);
        status = rep.status;
    } else {
        status = vsj__ts_begin(m, w, w->sy, 0.0);
        rep = vsj__ts_advance(m, w, w->sy, dt, sc->h, (int64_t)ceil(dt / sc->h - 1e-9), 1,
                              NULL);
        if (status == VSJ_OK)
            status = rep.status;
    }
    w->held = NULL;
    if (status == VSJ_OK) {
        memcpy(ledger, w->sy + nstate, (size_t)nacc * sizeof(double));
        from_engine(m, w->sy, inputs, dt, s);
    }
    return status;
}

int vsj_step(const vsj_model *m, vsj_work *w, const vsj_scheme *scheme, double *s,
             const double *inputs, double dt, double *ledger) {
    int method;
    double steps = 1.0; /* the time-stepper's steps in the period */
    if (!scheme || !s || !inputs || !vsj__fits(m, w) || !(dt > 0.0) || !isfinite(dt)
        || scheme->max_steps < 1)
        return VSJ_BAD_ARGUMENT;
    method = scheme->method;
    if (m->n_acts > 0) { /* the controller's samples: a whole number per period (rk4: one),
                          * on the time-stepper's grid */
        double per = dt / m->ctl[VSJ_CTL_PERIOD], steps = m->ctl[VSJ_CTL_PERIOD] / scheme->h;
        if (!(per >= 1.0 - 1e-9) || fabs(per - floor(per + 0.5)) > 1e-9 * per
            || (method == VSJ_METHOD_RK4 && fabs(per - 1.0) > 1e-9)
            || (method == VSJ_METHOD_TIMESTEP
                && (!(steps >= 1.0 - 1e-9) || fabs(steps - floor(steps + 0.5)) > 1e-9 * steps)))
            return VSJ_BAD_ARGUMENT;
    }
    if (method == VSJ_METHOD_TIMESTEP) {
        double per_step = dt / scheme->h;
        if (!(scheme->h > 0.0) || !(per_step <= VSJ_MAX_PERIOD_STEPS))
            return VSJ_BAD_ARGUMENT;
        if (!vsj__ts_prepared_for(m, w) && vsj_ts_prepare(m, w) != VSJ_OK)
            return VSJ_BAD_ARGUMENT;
        steps = ceil(per_step - 1e-9);
        if (steps > (double)scheme->max_steps)
            return VSJ_TOO_MANY_STEPS;
    } else if (method == VSJ_METHOD_DOPRI || method == VSJ_METHOD_ROSENBROCK) {
        if (!vsj__tolerances_ok(scheme->rtol, scheme->atol))
            return VSJ_BAD_ARGUMENT;
    } else if (method != VSJ_METHOD_RK4 || ledger) { /* rk4 keeps no ledger */
        return VSJ_BAD_ARGUMENT;
    }
    if (ledger)
        return step_ledger(m, w, scheme, s, inputs, dt, ledger);
    if (method == VSJ_METHOD_DOPRI || method == VSJ_METHOD_ROSENBROCK)
        return step_adaptive(m, w, scheme, s, inputs, dt);
    if (method == VSJ_METHOD_RK4)
        return step_rk4(m, w, s, inputs, dt, scheme->substeps);
    return step_timestep(m, w, s, inputs, dt, scheme->h, (int64_t)steps);
}
