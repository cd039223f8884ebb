/* Adaptive Dormand-Prince 5(4) with dense output: the solver for smooth friction laws.
 *
 * Coefficients and step-size control follow Hairer, Norsett and Wanner,
 * "Solving Ordinary Differential Equations I" (DOPRI5): a fifth-order
 * solution, an embedded fourth-order error estimate, a PI step controller
 * and a fourth-order continuous extension that samples the output times
 * without shortening steps. Energy accumulators ride along in the state but
 * stay out of the error norm (n_err), so they never shorten a step.
 */
#include <math.h>
#include <string.h>

#include "internal.h"

static const double C[7] = {0.0, 0.2, 0.3, 0.8, 8.0 / 9.0, 1.0, 1.0};
static const double A[7][6] = {
    {0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.2, 0.0, 0.0, 0.0, 0.0, 0.0},
    {3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0},
    {44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0},
    {19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0},
    {9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0},
    {35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0},
};
/* error estimate: fifth- minus fourth-order weights */
static const double E[7] = {71.0 / 57600.0,      0.0, -71.0 / 16695.0, 71.0 / 1920.0,
                            -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0};
/* dense output (Hairer's continuous extension of DOPRI5) */
static const double D[7] = {-12715105075.0 / 11282082432.0, 0.0,
                            87487479700.0 / 32700410799.0,  -10690763975.0 / 1880347072.0,
                            701980252875.0 / 199316789632.0, -1453857185.0 / 822651844.0,
                            69997945.0 / 29380423.0};

double vsj__err_norm(const double *e, const double *y, const double *y2, double rtol,
                     double atol, int64_t n_err) {
    double acc = 0.0;
    int64_t i;
    for (i = 0; i < n_err; i++) {
        double a = fabs(y[i]), b = fabs(y2[i]);
        double sc = atol + rtol * (a > b ? a : b);
        double r = e[i] / sc;
        acc += r * r;
    }
    return sqrt(acc / (double)(n_err > 1 ? n_err : 1));
}

static double dmin(double a, double b) { return a < b ? a : b; }
static double dmax(double a, double b) { return a > b ? a : b; }

static vsj_report report_of(const dopri_state *d) {
    vsj_report r;
    r.status = d->status;
    r.t = d->t;
    r.steps = d->steps;
    r.rejected = d->rejected;
    return r;
}

/* The samples of t_out[*i_out ..] that the last accepted step covers (its start yo,
 * end y and Hairer's dense coefficients r3..r5; a sample at its end is y). */
static void sample_step(const vsj_work *w, const dopri_state *d, const double *t_out,
                        int64_t n_out, int64_t *i_out, double *out, int64_t out_cols) {
    int64_t i, n_keep = d->ny < out_cols ? d->ny : out_cols;
    const double *yo = w->yo, *y = w->y, *r3 = w->r3, *r4 = w->r4, *r5 = w->r5;
    while (*i_out < n_out && t_out[*i_out] <= d->t) {
        double th = (t_out[*i_out] - d->t_prev) / d->h_prev, th1 = 1.0 - th;
        double *row = out + out_cols * *i_out;
        if (t_out[*i_out] == d->t) /* the step's end: its state itself, which the
                                    * interpolant gives only to round-off */
            memcpy(row, y, (size_t)n_keep * sizeof(double));
        else
            for (i = 0; i < n_keep; i++)
                row[i] = yo[i] + th * ((y[i] - yo[i])
                                       + th1 * (r3[i] + th * (r4[i] + th1 * r5[i])));
        if (out_cols >= n_keep + w->nbus + w->nact)
            vsj__control_record(w, t_out[*i_out], row + n_keep);
        (*i_out)++;
    }
}

double vsj__initial_step(const vsj_model *m, vsj_work *w, const double *y, const double *f0,
                         int64_t ny, double t0, double t_end, double order, double *scratch) {
    const dopri_state *d = &w->dopri;
    double *yt = w->yt, *err = w->err, d0, d1, d2, h, big, h1;
    int64_t i;
    d0 = vsj__err_norm(y, y, y, d->rtol, d->atol, d->n_err);
    d1 = vsj__err_norm(f0, y, y, d->rtol, d->atol, d->n_err);
    h = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    h = dmin(dmin(h, d->h_max), t_end - t0);
    for (i = 0; i < ny; i++)
        yt[i] = y[i] + h * f0[i];
    vsj__eval_derivatives(m, w, t0 + h, yt, ny, scratch);
    for (i = 0; i < ny; i++)
        err[i] = scratch[i] - f0[i];
    d2 = vsj__err_norm(err, y, y, d->rtol, d->atol, d->n_err) / h;
    big = dmax(d1, d2);
    h1 = big <= 1e-15 ? dmax(1e-6, h * 1e-3) : pow(0.01 / big, 1.0 / order);
    return dmin(dmin(dmin(100.0 * h, h1), d->h_max), t_end - t0);
}

int vsj__dopri_begin(const vsj_model *m, vsj_work *w, const double *y0, int64_t ny, double t0,
                    double t_end, double rtol, double atol, double h_max, int64_t max_steps,
                    int64_t n_err) {
    dopri_state *d = &w->dopri;
    double *K = w->K, *y = w->y;
    memset(d, 0, sizeof *d);
    d->status = VSJ_BAD_ARGUMENT;
    if (!vsj__fits(m, w) || ny > w->ny_max || ny < 0 || n_err > ny || n_err < 0
        || vsj__rigid_stop(m) || !(t_end >= t0) || !(rtol > 0.0) || !(atol > 0.0)
        || !(h_max > 0.0) || max_steps < 1)
        return d->status;
    d->ny = ny;
    d->n_err = n_err;
    d->rtol = rtol;
    d->atol = atol;
    d->h_max = h_max;
    d->max_steps = max_steps;
    d->t = d->t_prev = t0;
    d->t_end = t_end;
    d->err_old = 1e-4;
    vsj__breaks_reset(m, w);
    memcpy(y, y0, (size_t)ny * sizeof(double));
    memcpy(w->yo, y0, (size_t)ny * sizeof(double));
    w->status = VSJ_OK;
    vsj__eval_derivatives(m, w, t0, y, ny, K);
    d->status = w->status;
    if (d->status != VSJ_OK || !(t_end > t0))
        return d->status;
    d->h = vsj__initial_step(m, w, y, K, ny, t0, t_end, 5.0, K + ny);
    w->status = VSJ_OK;
    return d->status;
}

/* One attempted step from (t, y) with h: returns 1 if accepted (y, t advanced, the
 * dense coefficients of the step kept), 0 if rejected (h reduced), -1 on a failure
 * (d->status says which). */
static int attempt(const vsj_model *m, vsj_work *w, dopri_state *d) {
    double *K = w->K, *yt = w->yt, *y1 = w->y1, *err = w->err, *y = w->y;
    int64_t ny = d->ny, i, j, st;
    int end, stage_bad = 0;
    double t_land, h = vsj__step_length(m, w, d, &end, &t_land), e, fac11;
    for (st = 1; st < 7; st++) {
        for (i = 0; i < ny; i++) {
            double total = 0.0;
            for (j = 0; j < st; j++)
                total += A[st][j] * K[ny * j + i];
            yt[i] = y[i] + h * total;
        }
        if (st == 6) {
            memcpy(y1, yt, (size_t)ny * sizeof(double));
            if (w->status == VSJ_NOT_FINITE)
                stage_bad = 1;
            w->status = VSJ_OK; /* only the end point's physical limits count */
        }
        w->left = end == 2 && C[st] == 1.0; /* a step ending on a corner sees its left */
        vsj__eval_derivatives(m, w, C[st] == 1.0 ? t_land : d->t + C[st] * h, yt, ny,
                              K + ny * st);
        w->left = 0;
    }
    for (i = 0; i < ny; i++) {
        double total = 0.0;
        for (j = 0; j < 7; j++)
            total += E[j] * K[ny * j + i];
        err[i] = h * total;
    }
    e = vsj__err_norm(err, y, y1, d->rtol, d->atol, d->n_err);
    d->steps++;
    if (!isfinite(e) || stage_bad || w->status == VSJ_NOT_FINITE) {
        w->status = VSJ_OK;
        d->h = h * 0.1;
        d->rejected++;
        d->rejected_last = 1;
        return 0;
    }
    fac11 = pow(e, 0.17);
    if (e > 1.0) {
        w->status = VSJ_OK;
        d->h = h / dmin(5.0, fac11 / 0.9);
        d->rejected++;
        d->rejected_last = 1;
        return 0;
    }
    if (w->status != VSJ_OK && vsj__locating(h, d->t)) { /* a physical limit crossed inside
                                                           * the step: halve it */
        w->status = VSJ_OK;
        d->h = h * 0.5;
        d->rejected++;
        d->rejected_last = 1;
        return 0;
    }
    if (w->status != VSJ_OK) { /* a physical limit was crossed at the new point */
        memcpy(y, y1, (size_t)ny * sizeof(double));
        d->t += h;
        d->status = w->status;
        return -1;
    }
    for (i = 0; i < ny; i++) {
        double d_i = y1[i] - y[i], total = 0.0;
        w->r3[i] = h * K[i] - d_i;
        w->r4[i] = d_i - h * K[ny * 6 + i] - w->r3[i];
        for (j = 0; j < 7; j++)
            total += D[j] * K[ny * j + i];
        w->r5[i] = h * total;
    }
    memcpy(w->yo, y, (size_t)ny * sizeof(double));
    memcpy(y, y1, (size_t)ny * sizeof(double));
    memcpy(K, K + ny * 6, (size_t)ny * sizeof(double));
    d->t_prev = d->t;
    d->h_prev = h;
    d->t = t_land;
    if (end == 2) { /* the next step starts past the corner: its right limit */
        if (w->ctl_on && d->t == w->ctl_next)
            vsj__control_sample(m, w, d->t, y);
        vsj__eval_derivatives(m, w, d->t, y, ny, K);
        w->status = VSJ_OK;
    }
    {
        double fac = dmax(0.1, dmin(5.0, fac11 / pow(d->err_old, 0.04) / 0.9));
        double h_new = h / fac;
        if (d->rejected_last)
            h_new = dmin(h_new, h);
        d->err_old = dmax(e, 1e-4);
        d->rejected_last = 0;
        if (end != 2) /* a step cut short by a corner says nothing of the next */
            d->h = dmin(h_new, d->h_max);
    }
    return 1;
}

vsj_report vsj__dopri_advance(const vsj_model *m, vsj_work *w, const double *t_out,
                             int64_t n_out, double *out, int64_t out_cols, int finish,
                             double *y_now) {
    dopri_state *d = &w->dopri;
    int64_t i_out = 0, i, n_keep = d->ny < out_cols ? d->ny : out_cols;
    if (!vsj__fits(m, w) || (n_out > 0 && t_out[n_out - 1] > d->t_end)) {
        d->status = d->status != VSJ_OK ? d->status : VSJ_BAD_ARGUMENT;
        return report_of(d);
    }
    if (d->status == VSJ_OK && d->steps == 0) /* samples at the start */
        while (i_out < n_out && t_out[i_out] <= d->t) {
            for (i = 0; i < n_keep; i++)
                out[out_cols * i_out + i] = w->y[i];
            if (out_cols >= n_keep + w->nbus + w->nact)
                vsj__control_record(w, t_out[i_out], out + out_cols * i_out + n_keep);
            i_out++;
        }
    if (d->status == VSJ_OK && d->steps > 0 && d->rosenbrock)
        vsj__ros_sample(w, d, t_out, n_out, &i_out, out, out_cols);
    else if (d->status == VSJ_OK && d->steps > 0)
        sample_step(w, d, t_out, n_out, &i_out, out, out_cols);
    while (d->status == VSJ_OK && d->t < d->t_end && (i_out < n_out || finish)) {
        int accepted;
        if (d->steps >= d->max_steps) {
            d->status = VSJ_TOO_MANY_STEPS;
            break;
        }
        if (d->h < 1e-14 * dmax(1.0, fabs(d->t))) {
            d->status = VSJ_STEP_TOO_SMALL;
            break;
        }
        accepted = d->rosenbrock ? vsj__ros_attempt(m, w, d) : attempt(m, w, d);
        if (accepted > 0 && d->rosenbrock)
            vsj__ros_sample(w, d, t_out, n_out, &i_out, out, out_cols);
        else if (accepted > 0)
            sample_step(w, d, t_out, n_out, &i_out, out, out_cols);
    }
    if (y_now)
        memcpy(y_now, w->y, (size_t)d->ny * sizeof(double));
    return report_of(d);
}

vsj_report vsj__adaptive(const vsj_model *m, vsj_work *w, int method, double *y, int64_t ny,
                         double t0, double t_end, double rtol, double atol, int64_t max_steps,
                         int64_t n_err) {
    int status = method == VSJ_METHOD_ROSENBROCK
                     ? vsj__ros_begin(m, w, y, ny, t0, t_end, rtol, atol, INFINITY, max_steps,
                                      n_err)
                     : vsj__dopri_begin(m, w, y, ny, t0, t_end, rtol, atol, INFINITY, max_steps,
                                        n_err);
    if (status != VSJ_OK) {
        vsj_report r = report_of(&w->dopri);
        if (r.status != VSJ_BAD_ARGUMENT)
            memcpy(y, w->y, (size_t)ny * sizeof(double));
        return r;
    }
    return vsj__dopri_advance(m, w, NULL, 0, NULL, 0, 1, y);
}
