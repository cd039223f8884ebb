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

static double norm(const double *e, const double *y, const double *y2, double rtol, double atol,
                   int64_t n_err) {
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

static vsj_report done(int status, double t, int64_t steps, int64_t rejected) {
    vsj_report r;
    r.status = status;
    r.t = t;
    r.steps = steps;
    r.rejected = rejected;
    return r;
}

vsj_report vsj_dopri(const vsj_model *m, vsj_work *w, double *y0, int64_t ny, double t0,
                     double t_end, const double *t_out, int64_t n_out, double rtol, double atol,
                     double h_max, int64_t max_steps, int64_t n_err, double *out,
                     int64_t out_cols) {
    double *K = w->K, *yt = w->yt, *y1 = w->y1, *err = w->err, *r3 = w->r3, *r4 = w->r4;
    double *r5 = w->r5, *y = w->y;
    int64_t n_keep = ny < out_cols ? ny : out_cols;
    int64_t i_out = 0, i, j, st, n_steps = 0, n_rejected = 0;
    double t = t0, d0, d1, d2, h, big, h1, err_old = 1e-4;
    int rejected_last = 0;
    if (ny > w->ny_max || n_err > ny || n_err < 0 || vsj__rigid_stop(m))
        return done(VSJ_BAD_ARGUMENT, t0, 0, 0);
    memcpy(y, y0, (size_t)ny * sizeof(double));
    while (i_out < n_out && t_out[i_out] <= t0) {
        for (i = 0; i < n_keep; i++)
            out[out_cols * i_out + i] = y[i];
        i_out++;
    }
    w->status = VSJ_OK;
    vsj__eval_derivatives(m, w, t, y, ny, K);
    if (w->status != VSJ_OK)
        return done(w->status, t, 0, 0);
    /* initial step (Hairer's estimate) */
    d0 = norm(y, y, y, rtol, atol, n_err);
    d1 = norm(K, y, y, rtol, atol, n_err);
    h = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    h = dmin(dmin(h, h_max), t_end - t);
    for (i = 0; i < ny; i++)
        yt[i] = y[i] + h * K[i];
    vsj__eval_derivatives(m, w, t + h, yt, ny, K + ny);
    for (i = 0; i < ny; i++)
        err[i] = K[ny + i] - K[i];
    d2 = norm(err, y, y, rtol, atol, n_err) / h;
    big = dmax(d1, d2);
    h1 = big <= 1e-15 ? dmax(1e-6, h * 1e-3) : pow(0.01 / big, 0.2);
    h = dmin(dmin(dmin(100.0 * h, h1), h_max), t_end - t);
    w->status = VSJ_OK;

    while (t < t_end) {
        int last = 0, stage_bad = 0;
        double e, fac11;
        if (n_steps >= max_steps) {
            memcpy(y0, y, (size_t)ny * sizeof(double));
            return done(VSJ_TOO_MANY_STEPS, t, n_steps, n_rejected);
        }
        if (h < 1e-14 * dmax(1.0, fabs(t))) {
            memcpy(y0, y, (size_t)ny * sizeof(double));
            return done(VSJ_STEP_TOO_SMALL, t, n_steps, n_rejected);
        }
        if (t + h >= t_end) {
            h = t_end - t;
            last = 1;
        }
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
            vsj__eval_derivatives(m, w, t + C[st] * h, yt, ny, K + ny * st);
        }
        for (i = 0; i < ny; i++) {
            double total = 0.0;
            for (j = 0; j < 7; j++)
                total += E[j] * K[ny * j + i];
            err[i] = h * total;
        }
        e = norm(err, y, y1, rtol, atol, n_err);
        n_steps++;
        if (!isfinite(e) || stage_bad || w->status == VSJ_NOT_FINITE) {
            w->status = VSJ_OK;
            h *= 0.1;
            n_rejected++;
            rejected_last = 1;
            continue;
        }
        fac11 = pow(e, 0.17);
        if (e <= 1.0) {
            double t_new, fac, h_new;
            if (w->status != VSJ_OK) { /* a physical limit was crossed at the new point */
                memcpy(y0, y1, (size_t)ny * sizeof(double));
                return done(w->status, t + h, n_steps, n_rejected);
            }
            for (i = 0; i < ny; i++) {
                double d_i = y1[i] - y[i], total = 0.0;
                r3[i] = h * K[i] - d_i;
                r4[i] = d_i - h * K[ny * 6 + i] - r3[i];
                for (j = 0; j < 7; j++)
                    total += D[j] * K[ny * j + i];
                r5[i] = h * total;
            }
            t_new = t + h;
            while (i_out < n_out && t_out[i_out] <= t_new) {
                double th = (t_out[i_out] - t) / h, th1 = 1.0 - th;
                double *row = out + out_cols * i_out;
                for (i = 0; i < n_keep; i++)
                    row[i] = y[i] + th * ((y1[i] - y[i])
                                          + th1 * (r3[i] + th * (r4[i] + th1 * r5[i])));
                i_out++;
            }
            memcpy(y, y1, (size_t)ny * sizeof(double));
            memcpy(K, K + ny * 6, (size_t)ny * sizeof(double));
            t = t_new;
            fac = dmax(0.1, dmin(5.0, fac11 / pow(err_old, 0.04) / 0.9));
            h_new = h / fac;
            if (rejected_last)
                h_new = dmin(h_new, h);
            err_old = dmax(e, 1e-4);
            rejected_last = 0;
            if (last)
                break;
            h = dmin(h_new, h_max);
        } else {
            w->status = VSJ_OK;
            h = h / dmin(5.0, fac11 / 0.9);
            n_rejected++;
            rejected_last = 1;
        }
    }
    memcpy(y0, y, (size_t)ny * sizeof(double));
    return done(VSJ_OK, t, n_steps, n_rejected);
}
