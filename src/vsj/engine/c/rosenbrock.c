/* A linearly implicit Rosenbrock 4(3) method with the model's own Jacobian: the
 * scheme for smooth friction laws whose steep slopes make an explicit step short.
 *
 * The coefficients are Kaps and Rentrop's GRK4T (Numer. Math. 33, 1979), in the
 * form of Hairer and Wanner, "Solving Ordinary Differential Equations II",
 * section IV.7: each step factorises I/(gamma h) - J once, solves four linear
 * systems with it and evaluates the model three times (the fourth stage reuses the
 * third's point); the first evaluation of a step is the previous step's end point.
 * J and the time derivative df/dt are analytic (vsj__eval_jacobian: the friction
 * slopes, spring stiffnesses, motors and the sources' accelerations), so a step
 * costs few more evaluations than the explicit scheme's and is not bounded by
 * the friction slopes. Where J is only approximate (a moving pivot) the error
 * control still holds; the steps are shorter.
 *
 * The energy ledger's accumulators (components n_state .. ny-1) ride along as in
 * dopri, outside the error norm: their rows of the Jacobian (the rates' derivatives
 * in the state and in time) are taken by forward differences, once per step, so
 * that they are integrated at the order of the state. Between steps every
 * component is the cubic Hermite interpolant of the step's ends and their
 * derivatives. The resumable run shares the adaptive driver of dopri.c
 * (vsj__dopri_advance) and its state (dopri_state).
 */
#include <math.h>
#include <string.h>

#include "internal.h"

static const double GAMMA = 0.231;
static const double A21 = 2.0, A31 = 4.52470820736, A32 = 4.16352878860;
static const double C21 = -5.07167533877, C31 = 6.02015272865, C32 = 0.159750684673;
static const double C41 = -1.856343618677, C42 = -8.50538085819, C43 = -2.08407513602;
static const double B[4] = {3.95750374663, 4.62489238836, 0.617477263873, 1.282612945268};
static const double E[4] = {-2.30215540292, -3.07363448539, 0.873280801802, 1.282612945268};
static const double D[4] = {0.231, -0.396296677520e-01, 0.550778939579, -0.553509845700e-01};
static const double ALPHA2 = 0.462, ALPHA3 = 0.880208333333;

/* work rows of K (each ny long) */
enum { F_NOW = 0, G1 = 1, G2 = 2, G3 = 3, G4 = 4, F_STAGE = 5, F_START = 6 };

static double dmin(double a, double b) { return a < b ? a : b; }
static double dmax(double a, double b) { return a > b ? a : b; }

/* J and df/dt at (t, y), from the evaluation there just made (whose derivatives,
 * ny of them, are f). With the ledger (ny > ns), the accumulators' rows by forward
 * differences, each component moved by sqrt(eps) of its error scale. */
static void refresh_jacobian(const vsj_model *m, vsj_work *w, const dopri_state *d, double t,
                             const double *y, const double *f) {
    int64_t ns = vsj_n_state(m), ny = d->ny, na = ny - ns, i, j;
    const double root_eps = 1.4901161193847656e-08;
    double *moved = w->r4, *yt = w->r5;
    vsj__eval_jacobian(m, w, y, w->jac, w->ft);
    if (na == 0)
        return;
    memcpy(yt, y, (size_t)ny * sizeof(double));
    for (j = 0; j <= ns; j++) { /* column ns: the time */
        double delta = j < ns ? root_eps * (fabs(y[j]) + d->atol / d->rtol)
                              : root_eps * dmax(fabs(t), 1.0);
        if (j < ns)
            yt[j] = y[j] + delta;
        vsj__eval_derivatives(m, w, j < ns ? t : t + delta, yt, ny, moved);
        for (i = 0; i < na; i++)
            w->jacc[(ns + 1) * i + j] = (moved[ns + i] - f[ns + i]) / delta;
        if (j < ns)
            yt[j] = y[j];
    }
    w->status = VSJ_OK; /* the moved points' limits are not the run's */
}

int vsj__ros_begin(const vsj_model *m, vsj_work *w, const double *y0, int64_t ny, double t0,
                   double t_end, double rtol, double atol, double h_max, int64_t max_steps,
                   int64_t n_err) {
    dopri_state *d = &w->dopri;
    int64_t ns = vsj_n_state(m);
    double *K = w->K;
    memset(d, 0, sizeof *d);
    d->status = VSJ_BAD_ARGUMENT;
    d->rosenbrock = 1;
    if (!vsj__fits(m, w) || ny > w->ny_max || ny < ns || n_err > ns || n_err < 0
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
    memcpy(w->y, y0, (size_t)ny * sizeof(double));
    memcpy(w->yo, y0, (size_t)ny * sizeof(double));
    w->status = VSJ_OK;
    vsj__eval_derivatives(m, w, t0, w->y, ny, K + ny * F_NOW);
    d->status = w->status;
    if (d->status != VSJ_OK || !(t_end > t0))
        return d->status;
    refresh_jacobian(m, w, d, t0, w->y, K + ny * F_NOW);
    d->h = vsj__initial_step(m, w, w->y, K + ny * F_NOW, ns, t0, t_end, 4.0, K + ny * F_STAGE);
    w->status = VSJ_OK;
    return d->status;
}

/* I/(gamma h) - J for the state [x, v, i] (angles, speeds, motor currents): as
 * x' = v, the angles' rows eliminate, which leaves a system in the speeds and
 * currents (n + nm unknowns), factorised into w->lu. 0 if singular. */
static int factor(const vsj_model *m, vsj_work *w, double gh) {
    int64_t n = m->n, ns = vsj_n_state(m), nr = ns - n, i, j;
    const double *J = w->jac;
    for (i = 0; i < nr; i++)
        for (j = 0; j < nr; j++) {
            double value = -J[ns * (n + i) + n + j];
            if (i < n && j < n)
                value -= gh * J[ns * (n + i) + j];
            w->lu[nr * i + j] = value + (i == j ? 1.0 / gh : 0.0);
        }
    return vsj__lu(w->lu, w->piv, nr);
}

/* out = (I/(gamma h) - J)^-1 (f + h dcoef df/dt + sum_j c[j] g[j] / h) over the ny
 * components, with the factor of `factor` (gh = gamma h) */
static void stage(const vsj_model *m, const vsj_work *w, int64_t ny, const double *f, double h,
                  double gh, double dcoef, const double *c, const double *const *g, int ng,
                  double *out) {
    int64_t n = m->n, ns = vsj_n_state(m), i, j;
    const double *J = w->jac;
    for (i = 0; i < ny; i++) {
        double total = f[i] + h * dcoef * (i < ns ? w->ft[i] : w->jacc[(ns + 1) * (i - ns) + ns]);
        int s;
        for (s = 0; s < ng; s++)
            total += c[s] / h * g[s][i];
        out[i] = total;
    }
    for (i = 0; i < n; i++) { /* the angles' rows, eliminated */
        double total = 0.0;
        for (j = 0; j < n; j++)
            total += J[ns * (n + i) + j] * out[j];
        out[n + i] += gh * total;
    }
    vsj__lu_solve(w->lu, w->piv, out + n, out + n, ns - n);
    for (i = 0; i < n; i++)
        out[i] = gh * (out[i] + out[n + i]);
    for (i = ns; i < ny; i++) { /* the accumulators: no column of J, rows jacc */
        const double *row = w->jacc + (ns + 1) * (i - ns);
        double total = out[i];
        for (j = 0; j < ns; j++)
            total += row[j] * out[j];
        out[i] = gh * total;
    }
}

/* Whether an evaluation failed (non-finite) since the status was last cleared; clears it. */
static int failed(vsj_work *w) {
    int bad = w->status == VSJ_NOT_FINITE;
    w->status = VSJ_OK;
    return bad;
}

static int reject(vsj_work *w, dopri_state *d, double factor) {
    w->status = VSJ_OK;
    d->h *= factor;
    d->rejected++;
    d->rejected_last = 1;
    return 0;
}

/* The Hermite interpolant of the last accepted step at theta in [0, 1]: its first
 * `count` components into out. */
static void hermite(const vsj_work *w, const dopri_state *d, double theta, int64_t count,
                    double *out) {
    const double *yo = w->yo, *y = w->y, *fo = w->K + d->ny * F_START, *f1 = w->K;
    double h = d->h_prev, th1 = theta - 1.0;
    int64_t i;
    for (i = 0; i < count; i++) {
        double dy = y[i] - yo[i];
        out[i] = yo[i] + theta * dy
                 + theta * th1 * ((1.0 - 2.0 * theta) * dy + th1 * h * fo[i] + theta * h * f1[i]);
    }
}

int vsj__ros_attempt(const vsj_model *m, vsj_work *w, dopri_state *d) {
    int64_t ny = d->ny, ns = vsj_n_state(m), i, j;
    double *K = w->K, *y = w->y, *yt = w->yt, *y1 = w->y1, *err = w->err;
    double *g[4], h = d->h, e, fac, gh;
    const double c2[1] = {C21}, c3[2] = {C31, C32}, c4[3] = {C41, C42, C43};
    int last = 0, bad, end_status;
    for (j = 0; j < 4; j++)
        g[j] = K + ny * (G1 + j);
    if (d->t + h >= d->t_end) {
        h = d->t_end - d->t;
        last = 1;
    }
    gh = GAMMA * h;
    d->steps++;
    if (!factor(m, w, gh))
        return reject(w, d, 0.5);
    stage(m, w, ny, K + ny * F_NOW, h, gh, D[0], NULL, NULL, 0, g[0]);
    for (i = 0; i < ns; i++)
        yt[i] = y[i] + A21 * g[0][i];
    vsj__eval_derivatives(m, w, d->t + ALPHA2 * h, yt, ny, K + ny * F_STAGE);
    bad = failed(w);
    stage(m, w, ny, K + ny * F_STAGE, h, gh, D[1], c2, (const double *const *)g, 1, g[1]);
    for (i = 0; i < ns; i++)
        yt[i] = y[i] + A31 * g[0][i] + A32 * g[1][i];
    vsj__eval_derivatives(m, w, d->t + ALPHA3 * h, yt, ny, K + ny * F_STAGE);
    bad |= failed(w);
    stage(m, w, ny, K + ny * F_STAGE, h, gh, D[2], c3, (const double *const *)g, 2, g[2]);
    stage(m, w, ny, K + ny * F_STAGE, h, gh, D[3], c4, (const double *const *)g, 3, g[3]);
    for (i = 0; i < ny; i++)
        y1[i] = y[i] + B[0] * g[0][i] + B[1] * g[1][i] + B[2] * g[2][i] + B[3] * g[3][i];
    for (i = 0; i < ns; i++)
        err[i] = E[0] * g[0][i] + E[1] * g[1][i] + E[2] * g[2][i] + E[3] * g[3][i];
    e = vsj__err_norm(err, y, y1, d->rtol, d->atol, d->n_err);
    if (bad || !isfinite(e))
        return reject(w, d, 0.1);
    fac = dmax(0.2, dmin(6.0, 0.9 / sqrt(sqrt(e > 1e-10 ? e : 1e-10))));
    if (e > 1.0)
        return reject(w, d, dmin(fac, 0.9));
    /* the end point: the next step's first evaluation (the ledger's rates too) */
    vsj__eval_derivatives(m, w, d->t + h, y1, ny, K + ny * F_STAGE);
    end_status = w->status;
    if (end_status == VSJ_NOT_FINITE)
        return reject(w, d, 0.1);
    memcpy(w->yo, y, (size_t)ny * sizeof(double));
    memcpy(K + ny * F_START, K + ny * F_NOW, (size_t)ny * sizeof(double));
    memcpy(y, y1, (size_t)ny * sizeof(double));
    memcpy(K + ny * F_NOW, K + ny * F_STAGE, (size_t)ny * sizeof(double));
    d->t_prev = d->t;
    d->h_prev = h;
    d->t = last ? d->t_end : d->t + h;
    refresh_jacobian(m, w, d, d->t, y, K + ny * F_NOW);
    if (end_status != VSJ_OK) { /* a physical limit was crossed at the new point */
        d->status = end_status;
        return -1;
    }
    if (d->err_old > 0.0) { /* Gustafsson's predictive control: the trend of the errors */
        double predicted = d->h_acc / h * sqrt(sqrt(e * e / d->err_old)) / 0.9;
        fac = dmin(fac, dmax(0.2, dmin(6.0, 1.0 / predicted)));
    }
    d->h_acc = h;
    d->err_old = dmax(1e-2, e);
    if (d->rejected_last)
        fac = dmin(fac, 1.0);
    d->rejected_last = 0;
    d->h = dmin(h * fac, d->h_max);
    return 1;
}

void vsj__ros_sample(const vsj_work *w, const dopri_state *d, const double *t_out,
                     int64_t n_out, int64_t *i_out, double *out, int64_t out_cols) {
    int64_t n_keep = d->ny < out_cols ? d->ny : out_cols;
    while (*i_out < n_out && t_out[*i_out] <= d->t) {
        hermite(w, d, (t_out[*i_out] - d->t_prev) / d->h_prev, n_keep,
                out + out_cols * *i_out);
        (*i_out)++;
    }
}
