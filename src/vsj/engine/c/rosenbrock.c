/* A linearly implicit Rosenbrock 4(3) method with the model's own Jacobian: the
 * scheme for smooth friction laws whose steep slopes make an explicit step short.
 *
 * The coefficients are Hairer and Wanner's RODAS4 ("Solving Ordinary Differential
 * Equations II", section VI.4): six stages, stiffly accurate and L-stable, so that
 * fast modes the steps do not resolve (a stiff, lightly damped torque sensor) are
 * damped rather than carried along. Each step factorises I/(gamma h) - J once,
 * evaluates the model at five stages (its first stage takes the previous step's end
 * point) and, accepted, once more at its end point. J and the time derivative df/dt
 * are analytic (vsj__eval_jacobian: the friction slopes, with a level that follows a
 * speed table or a normal force in time, spring stiffnesses, the pivot's motion,
 * motors and the sources' accelerations). They also give the second derivatives the
 * interpolant below uses, so an approximate J would cost accuracy between the steps
 * as well as shorter steps. As x' = v, the linear systems reduce to the speeds and
 * motor currents.
 *
 * The energy ledger's accumulators (components n_state .. ny-1) ride along as in
 * dopri, outside the error norm, with their own rows of the Jacobian (the rates'
 * derivatives in the state and in time, vsj__eval_ledger_rows), so that they are
 * integrated at the order of the state.
 *
 * Between steps every component is the quintic Hermite interpolant of the step's
 * ends, their first derivatives and their second ones (J f + df/dt, from the
 * Jacobian the next step needs anyway). Its accuracy is controlled too: a long step
 * over a solution that bends inside it (the friction laws' steep slopes switching)
 * can end accurately and still be wrong between its ends, where the samples lie.
 * The difference of the cubic Hermite interpolant (first derivatives only) and the
 * quintic one at the step's middle estimates the cubic's error there; it enters the
 * error norm beside the embedded estimate, so that the quintic, one order better,
 * holds the tolerance between the ends as well. The resumable run shares the
 * adaptive driver of dopri.c (vsj__dopri_advance) and its state (dopri_state).
 */
#include <math.h>
#include <string.h>

#include "internal.h"

#define STAGES 6
static const double GAMMA = 0.25;
/* stage i evaluates at y + sum_j A[i][j] g_j, time t + CT[i] h */
static const double A[STAGES][STAGES - 1] = {
    {0.0, 0.0, 0.0, 0.0, 0.0},
    {1.544, 0.0, 0.0, 0.0, 0.0},
    {0.9466785280815826, 0.2557011698983284, 0.0, 0.0, 0.0},
    {3.314825187068521, 2.896124015972201, 0.9986419139977817, 0.0, 0.0},
    {1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 0.0},
    {1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 1.0}};
static const double CT[STAGES] = {0.0, 0.386, 0.21, 0.63, 1.0, 1.0};
/* stage i's right-hand side adds sum_j C[i][j] g_j / h and h D[i] df/dt */
static const double C[STAGES][STAGES - 1] = {
    {0.0, 0.0, 0.0, 0.0, 0.0},
    {-5.6688, 0.0, 0.0, 0.0, 0.0},
    {-2.430093356833875, -0.2063599157091915, 0.0, 0.0, 0.0},
    {-0.1073529058151375, -9.594562251023355, -20.47028614809616, 0.0, 0.0},
    {7.496443313967647, -10.24680431464352, -33.99990352819905, 11.70890893206160, 0.0},
    {8.083246795921522, -7.981132988064893, -31.52159432874371, 16.31930543123136,
     -6.058818238834054}};
static const double D[STAGES] = {0.25, -0.1043, 0.1035, -0.0362, 0.0, 0.0};
/* stiffly accurate: the solution is the last stage's point plus its g, whose size
 * is the error estimate */

/* work rows of K (each ny long): the first (F) and second (S) derivatives where the
 * run stands (the next step's start), the stages' g, a stage's derivatives and the
 * second ones at a step's end, and the first and second derivatives at the start and
 * at the end of the last accepted step (seen from inside it: the inputs' left limits
 * on a corner) */
enum { F_NOW = 0, S_NOW = 1, G1 = 2, F_STAGE = G1 + STAGES, S_STAGE = F_STAGE + 1,
       F_START = S_STAGE + 1, S_START = F_START + 1, F_END = S_START + 1, S_END = F_END + 1,
       K_ROWS = S_END + 1 };
/* the work holds VSJ_K_ROWS rows (model.c) */
typedef char k_rows_fit[K_ROWS <= VSJ_K_ROWS ? 1 : -1];

static double dmin(double a, double b) { return a < b ? a : b; }
static double dmax(double a, double b) { return a > b ? a : b; }

/* J and df/dt at y, from the evaluation there just made (f its derivatives), into
 * jac, ft and (with the ledger: ny > ns, a full-length evaluation) the accumulators'
 * rows jacc; and the second derivatives there, d/dt f = J f + df/dt, into s (the
 * accumulators' from their rows). */
static void jacobian_at(const vsj_model *m, vsj_work *w, const dopri_state *d, const double *y,
                        const double *f, double *jac, double *ft, double *jacc, double *s) {
    int64_t ns = vsj_n_state(m), i, j;
    vsj__eval_jacobian(m, w, jac, ft);
    if (d->ny > ns)
        vsj__eval_ledger_rows(m, w, y, jac, ft, jacc);
    for (i = 0; i < d->ny; i++) {
        const double *row = i < ns ? jac + ns * i : jacc + (ns + 1) * (i - ns);
        double total = i < ns ? ft[i] : row[ns];
        for (j = 0; j < ns; j++)
            total += row[j] * f[j];
        s[i] = total;
    }
}

/* The Jacobian where the run stands (w->y, derivatives F_NOW) into w->jac, w->ft,
 * w->jacc, and the second derivatives there into S_NOW. */
static void refresh_jacobian(const vsj_model *m, vsj_work *w, const dopri_state *d) {
    jacobian_at(m, w, d, w->y, w->K + d->ny * F_NOW, w->jac, w->ft, w->jacc,
                w->K + d->ny * S_NOW);
}

static void swap(double **a, double **b) {
    double *t = *a;
    *a = *b;
    *b = t;
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
    if (!vsj__fits(m, w) || (ny != ns && ny != ns + vsj_n_acc(m)) || n_err > ns || n_err < 0
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
    vsj__breaks_reset(m, w);
    w->status = VSJ_OK;
    vsj__eval_derivatives(m, w, t0, w->y, ny, K + ny * F_NOW);
    d->status = w->status;
    if (d->status != VSJ_OK || !(t_end > t0))
        return d->status;
    refresh_jacobian(m, w, d);
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

static int reject(vsj_work *w, dopri_state *d, double shrink) {
    w->status = VSJ_OK;
    d->h *= shrink;
    d->rejected++;
    d->rejected_last = 1;
    return 0;
}

/* The quintic Hermite interpolant of the last accepted step at theta in [0, 1]: its
 * first `count` components into out. */
static void hermite(const vsj_work *w, const dopri_state *d, double theta, int64_t count,
                    double *out) {
    const double *yo = w->yo, *y = w->y, *K = w->K;
    const double *fo = K + d->ny * F_START, *so = K + d->ny * S_START;
    const double *f1 = K + d->ny * F_END, *s1 = K + d->ny * S_END;
    double h = d->h_prev, u = 1.0 - theta, t2 = theta * theta, u2 = u * u;
    /* the basis in theta and u = 1 - theta: value, slope and curvature weights of
     * each end (each end's value weight is the other's mirrored) */
    double v1 = t2 * theta * (10.0 - 15.0 * theta + 6.0 * t2), v0 = 1.0 - v1;
    double d0 = h * theta * u2 * u * (1.0 + 3.0 * theta);
    double d1 = -h * t2 * theta * u * (1.0 + 3.0 * u);
    double c0 = 0.5 * h * h * t2 * u2 * u, c1 = 0.5 * h * h * t2 * theta * u2;
    int64_t i;
    for (i = 0; i < count; i++)
        out[i] = v0 * yo[i] + v1 * y[i] + d0 * fo[i] + d1 * f1[i] + c0 * so[i] + c1 * s1[i];
}

/* The error of the cubic Hermite interpolant of the step from (y0, f0, s0) to
 * (y1, f1, s1) at its middle, estimated by its difference from the quintic one there,
 * h (f1 - f0) / 32 - h^2 (s0 + s1) / 64, in the error norm. */
static double middle_error(const vsj_work *w, const dopri_state *d, double h,
                           const double *y1) {
    const double *K = w->K, *y0 = w->y;
    const double *f0 = K + d->ny * F_NOW, *s0 = K + d->ny * S_NOW;
    const double *f1 = K + d->ny * F_END, *s1 = K + d->ny * S_END;
    double *diff = w->err;
    int64_t i;
    for (i = 0; i < d->n_err; i++)
        diff[i] = h / 32.0 * (f1[i] - f0[i]) - h * h / 64.0 * (s0[i] + s1[i]);
    return vsj__err_norm(diff, y0, y1, d->rtol, d->atol, d->n_err);
}

/* The step size's factor for the error e (of order h^4 in the embedded estimate and
 * in the cubic interpolant's error alike). */
static double step_factor(double e) {
    return dmax(0.2, dmin(6.0, 0.9 / sqrt(sqrt(e > 1e-10 ? e : 1e-10))));
}

/* A candidate step's end (y1 at t_land): its derivatives (F_STAGE; the ledger's rates
 * too), the Jacobian there (into the spare w->jac_new, w->ft_new, w->jacc_new: the
 * step's start keeps its own until the step is accepted) and the second derivatives
 * (S_STAGE); the derivatives as seen from inside the step into F_END and S_END (on a
 * corner, the inputs' left limits). Returns the status of the evaluation at the end. */
static int end_point(const vsj_model *m, vsj_work *w, const dopri_state *d, int end,
                     double t_land) {
    int64_t ny = d->ny;
    double *K = w->K;
    int status;
    if (end == 2) { /* on a corner: the step's own end for its interpolant (the
                     * Jacobian's time derivatives, too, from before the corner) */
        w->left = 1;
        vsj__eval_derivatives(m, w, t_land, w->y1, ny, K + ny * F_END);
        w->status = VSJ_OK;
        jacobian_at(m, w, d, w->y1, K + ny * F_END, w->jac_new, w->ft_new, w->jacc_new,
                    K + ny * S_END);
        w->left = 0;
    }
    vsj__eval_derivatives(m, w, t_land, w->y1, ny, K + ny * F_STAGE);
    status = w->status;
    if (status == VSJ_NOT_FINITE)
        return status;
    jacobian_at(m, w, d, w->y1, K + ny * F_STAGE, w->jac_new, w->ft_new, w->jacc_new,
                K + ny * S_STAGE);
    if (end != 2) {
        memcpy(K + ny * F_END, K + ny * F_STAGE, (size_t)ny * sizeof(double));
        memcpy(K + ny * S_END, K + ny * S_STAGE, (size_t)ny * sizeof(double));
    }
    return status;
}

/* The step of length h to t_land accepted: its start kept for the interpolant, the
 * run moved to its end with the end's derivatives and Jacobian. */
static void accept(const vsj_model *m, vsj_work *w, dopri_state *d, double h, int end,
                   double t_land) {
    int64_t ny = d->ny;
    double *K = w->K;
    memcpy(w->yo, w->y, (size_t)ny * sizeof(double));
    memcpy(K + ny * F_START, K + ny * F_NOW, (size_t)ny * sizeof(double));
    memcpy(K + ny * S_START, K + ny * S_NOW, (size_t)ny * sizeof(double));
    memcpy(w->y, w->y1, (size_t)ny * sizeof(double));
    memcpy(K + ny * F_NOW, K + ny * F_STAGE, (size_t)ny * sizeof(double));
    memcpy(K + ny * S_NOW, K + ny * S_STAGE, (size_t)ny * sizeof(double));
    swap(&w->jac, &w->jac_new);
    swap(&w->ft, &w->ft_new);
    swap(&w->jacc, &w->jacc_new);
    d->t_prev = d->t;
    d->h_prev = h;
    d->t = t_land;
    if (end == 2 && w->ctl_on && d->t == w->ctl_next) { /* the controller's sample: the
                                                         * next step's start anew */
        vsj__control_sample(m, w, d->t, w->y);
        vsj__eval_derivatives(m, w, d->t, w->y, ny, K + ny * F_NOW);
        w->status = VSJ_OK;
        refresh_jacobian(m, w, d);
    }
}

int vsj__ros_attempt(const vsj_model *m, vsj_work *w, dopri_state *d) {
    int64_t ny = d->ny, ns = vsj_n_state(m), i;
    double *K = w->K, *y = w->y, *yt = w->yt, *y1 = w->y1, *err = w->err;
    double *g[STAGES], h, e, fac, gh, t_land;
    int end, bad = 0, end_status, st, j;
    for (st = 0; st < STAGES; st++)
        g[st] = K + ny * (G1 + st);
    h = vsj__step_length(m, w, d, &end, &t_land);
    gh = GAMMA * h;
    d->steps++;
    if (!factor(m, w, gh))
        return reject(w, d, 0.5);
    for (st = 0; st < STAGES; st++) {
        const double *f = K + ny * F_NOW;
        if (st > 0) {
            for (i = 0; i < ns; i++) {
                double total = y[i];
                for (j = 0; j < st; j++)
                    total += A[st][j] * g[j][i];
                yt[i] = total;
            }
            f = K + ny * F_STAGE;
            w->left = end == 2 && CT[st] == 1.0; /* a step ending on a corner sees its left */
            vsj__eval_derivatives(m, w, CT[st] == 1.0 ? t_land : d->t + CT[st] * h, yt, ny,
                                  K + ny * F_STAGE);
            w->left = 0;
            bad |= failed(w);
        }
        stage(m, w, ny, f, h, gh, D[st], C[st], (const double *const *)g, st, g[st]);
    }
    for (i = 0; i < ny; i++) {
        double total = y[i] + g[STAGES - 1][i];
        for (j = 0; j < STAGES - 1; j++)
            total += A[STAGES - 1][j] * g[j][i];
        y1[i] = total;
    }
    for (i = 0; i < ns; i++)
        err[i] = g[STAGES - 1][i];
    e = vsj__err_norm(err, y, y1, d->rtol, d->atol, d->n_err);
    if (bad || !isfinite(e))
        return reject(w, d, 0.1);
    if (e > 1.0)
        return reject(w, d, dmin(step_factor(e), 0.9));
    end_status = end_point(m, w, d, end, t_land);
    if (end_status == VSJ_NOT_FINITE)
        return reject(w, d, 0.1);
    if (end_status != VSJ_OK && vsj__locating(h, d->t)) /* a physical limit crossed inside
                                                          * the step: halve it */
        return reject(w, d, 0.5);
    e = dmax(e, middle_error(w, d, h, y1)); /* the interpolant's error, in the same norm */
    if (!isfinite(e))
        return reject(w, d, 0.1);
    fac = step_factor(e);
    if (e > 1.0)
        return reject(w, d, dmin(fac, 0.9));
    accept(m, w, d, h, end, t_land);
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
    if (end != 2) /* a step cut short by a corner says nothing of the next */
        d->h = dmin(h * fac, d->h_max);
    return 1;
}

void vsj__ros_sample(const vsj_work *w, const dopri_state *d, const double *t_out,
                     int64_t n_out, int64_t *i_out, double *out, int64_t out_cols) {
    int64_t n_keep = d->ny < out_cols ? d->ny : out_cols;
    while (*i_out < n_out && t_out[*i_out] <= d->t) {
        if (t_out[*i_out] == d->t) /* the step's end: its state itself */
            memcpy(out + out_cols * *i_out, w->y, (size_t)n_keep * sizeof(double));
        else
            hermite(w, d, (t_out[*i_out] - d->t_prev) / d->h_prev, n_keep,
                    out + out_cols * *i_out);
        if (out_cols >= n_keep + w->nbus + w->nact)
            vsj__control_record(w, t_out[*i_out], out + out_cols * *i_out + n_keep);
        (*i_out)++;
    }
}
