/* The joint Coulomb impulse problem of the time-stepper (timestep.c).
 *
 * With Y^T (n x m, one column L^-1 d_e per unknown e, L the step matrix's
 * Cholesky factor and d_e the unknown's slip row) the Delassus matrix is
 * W = Y Y^T. Given the unknowns' slips q without impulses and bounds
 * lo_e <= p_e <= hi_e, find impulses p with slips s = q - W p such that
 *
 *     p_e = hi_e if s_e > 0,  p_e = lo_e if s_e < 0,  lo_e <= p_e <= hi_e if s_e = 0,
 *
 * (friction: lo = -hi, the Coulomb impulse h c_e; an end stop: [0, inf)). It is
 * solved exactly: the previous solution's stick/slip pattern is checked first
 * (same_pattern: cheap, and it holds on most steps), a primal active-set method
 * takes over when it does not (active_set). Every solve is an n x n one, n the
 * coordinates, however many unknowns there are.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

/* The functions below are inlined into vsj__solve_impulses; those that loop over the
 * coordinates take their count n, which it passes as a constant where it can. */

/* impulse solver: absolute and relative (to the largest free slip) tolerance [rad/s] */
#define IMPULSE_ABS 1e-14
#define IMPULSE_REL 1e-12
#define IMPULSE_MAX_ITER 500
/* relative Tikhonov term that makes the impulse problem strictly convex (polished away) */
#define IMPULSE_REG 1e-9

/* z = YT p */
VSJ_ALWAYS_INLINE void project(const impulses *im, const double *p, double *z, int64_t n) {
    int64_t i, e, m = im->m;
    for (i = 0; i < n; i++) {
        double acc = 0.0;
        const double *row = im->YT + im->ld * i;
        for (e = 0; e < m; e++)
            acc += row[e] * p[e];
        z[i] = acc;
    }
}

/* G = YT diag(mask) YT^T + ridge I and, with a vector vec, t = YT (mask * vec) */
VSJ_ALWAYS_INLINE void gram(const impulses *im, const double *vec, double *G, double *t,
                            double ridge, int64_t n) {
    int64_t i, j, e, m = im->m, ld = im->ld;
    const double *YT = im->YT, *mask = im->mask;
    for (i = 0; i < n; i++) {
        if (vec) {
            double acc_t = 0.0;
            for (e = 0; e < m; e++)
                acc_t += YT[ld * i + e] * mask[e] * vec[e];
            t[i] = acc_t;
        }
        for (j = 0; j <= i; j++) {
            double acc = 0.0;
            for (e = 0; e < m; e++)
                acc += YT[ld * i + e] * mask[e] * YT[ld * j + e];
            G[n * i + j] = acc;
            G[n * j + i] = acc;
        }
        G[n * i + i] += ridge;
    }
}

/* s = q - YT^T z (s may be q) */
VSJ_ALWAYS_INLINE void slips(const impulses *im, const double *q, const double *z, double *s,
                             int64_t n) {
    int64_t i, e, m = im->m;
    for (e = 0; e < m; e++)
        s[e] = q[e];
    for (i = 0; i < n; i++) {
        double zi = z[i];
        const double *row = im->YT + im->ld * i;
        for (e = 0; e < m; e++)
            s[e] -= row[e] * zi;
    }
}

/* Classify unknown e of the warm start: an impulse at (this step's) bound keeps its
 * sign, the others are free (stuck); an uninvolved unknown gets state 2. Sets its
 * mask (1 for free) and returns it; *scale grows to its free slip. */
VSJ_ALWAYS_INLINE int snap_one(const impulses *im, const double *q, const double *lo,
                               const double *hi, double *p, int64_t *state,
                               const unsigned char *active, int64_t e, double *scale) {
    im->mask[e] = 0.0;
    if (active[e] && hi[e] > lo[e]) {
        *scale = vsj__dmax(*scale, fabs(q[e]));
        /* the bounds vary in their last bits from step to step (the step length
         * does): an impulse at last step's bound is at this step's bound
         * (lo <= 0 < hi, hi possibly infinite) */
        if (p[e] >= hi[e] * (1.0 - 1e-9)) {
            p[e] = hi[e];
            state[e] = 1;
        } else if (p[e] <= lo[e] * (1.0 - 1e-9)) {
            p[e] = lo[e];
            state[e] = -1;
        } else {
            state[e] = 0;
            im->mask[e] = 1.0;
            return 1;
        }
    } else {
        p[e] = 0.0;
        state[e] = 2;
    }
    return 0;
}

/* Classify the warm start (snap_one): returns the number free, and the largest free
 * slip in *scale. */
VSJ_ALWAYS_INLINE int64_t snap(const impulses *im, const double *q, const double *lo,
                               const double *hi, double *p, int64_t *state,
                               const unsigned char *active, double *scale) {
    int64_t e, n_free = 0;
    *scale = 0.0;
    for (e = 0; e < im->m; e++)
        n_free += snap_one(im, q, lo, hi, p, state, active, e, scale);
    return n_free;
}

/* Minimum-norm impulses of the stuck (free) unknowns that cancel their slips
 * `slip`: d = Y_F G^-2 Y_F^T s_F with G = Y_F^T Y_F (n x n solves; a tiny
 * ridge where stuck rows are parallel). Writes d (zero off the free set). */
VSJ_ALWAYS_INLINE void stuck_impulses(impulses *im, const double *slip, int64_t n) {
    int64_t i, e, m = im->m;
    double trace = 0.0;
    gram(im, slip, im->G, im->t, 0.0, n);
    for (i = 0; i < n; i++)
        trace += im->G[n * i + i];
    for (i = 0; i < n; i++)
        im->G[n * i + i] += 1e-13 * trace;
    vsj__ldl(im->G, im->Lg, n);
    vsj__ldl_solve(im->Lg, im->t, im->c, n);
    vsj__ldl_solve(im->Lg, im->c, im->t, n);
    for (e = 0; e < m; e++)
        im->d[e] = 0.0;
    for (i = 0; i < n; i++) {
        double ti = im->t[i];
        const double *row = im->YT + im->ld * i;
        for (e = 0; e < m; e++)
            im->d[e] += row[e] * ti * im->mask[e];
    }
}

/* Gc = Y_F Y_F^T and Lk, the factor of Gc + ridge I (vsj__ldl), for the stuck set in
 * mask: (Gc + ridge I)^-2 Y_F s_F are the coefficients of the minimum-norm impulses
 * that cancel the stuck unknowns' slips s_F (stuck_coefficients). */
VSJ_ALWAYS_INLINE void stuck_map(impulses *im, int64_t n) {
    int64_t i;
    double trace = 0.0;
    gram(im, NULL, im->Gc, NULL, 0.0, n);
    for (i = 0; i < n; i++)
        trace += im->Gc[n * i + i];
    memcpy(im->G, im->Gc, (size_t)(n * n) * sizeof(double));
    for (i = 0; i < n; i++)
        im->G[n * i + i] += 1e-13 * trace;
    vsj__ldl(im->G, im->Lk, n);
}

/* c = (Gc + ridge I)^-2 t with stuck_map's factor (c may be t). */
VSJ_ALWAYS_INLINE void stuck_coefficients(const impulses *im, const double *t, double *c,
                                          int64_t n) {
    vsj__ldl_solve(im->Lk, t, c, n);
    vsj__ldl_solve(im->Lk, c, c, n);
}

/* Fast path: does last step's stick/slip pattern still hold? Bound impulses at
 * their caps, the stuck unknowns' impulses the minimum-norm ones that make
 * their slips exactly zero; returns 1 if every condition holds (p is then the
 * solution). With z_B = Y_B p_B the stuck impulses are Y_F^T c with
 * c = (Gc + ridge I)^-2 (Y_F q_F - Gc z_B). Gc and its factor Lk change only with
 * the stuck set or YT and are kept between calls (memo). */
VSJ_ALWAYS_INLINE int same_pattern(impulses *im, const double *q, const double *lo,
                                   const double *hi, double *p, int64_t *state,
                                   const unsigned char *active, int64_t n) {
    int64_t e, i, j, m = im->m, ld = im->ld, n_free;
    const double *YT = im->YT, *mask = im->mask;
    double scale, tol;
    int holds = 1;
    n_free = snap(im, q, lo, hi, p, state, active, &scale);
    tol = IMPULSE_ABS + IMPULSE_REL * scale;
    if (n_free > 0) {
        int known = im->memo[m] > 0.0, fits = 1;
        for (e = 0; e < m; e++)
            known = known && im->memo[e] == mask[e];
        if (!known) {
            stuck_map(im, n);
            for (e = 0; e < m; e++)
                im->memo[e] = mask[e];
            im->memo[m] = 1.0;
        }
        /* z_B, and Y_F s_F with s the slips under the bound impulses alone */
        for (i = 0; i < n; i++) {
            double zb = 0.0, yq = 0.0;
            const double *row = YT + ld * i;
            for (e = 0; e < m; e++) {
                zb += row[e] * (p[e] * (1.0 - mask[e]));
                yq += row[e] * (q[e] * mask[e]);
            }
            im->z[i] = zb;
            im->t[i] = yq;
        }
        for (i = 0; i < n; i++) {
            double acc = im->t[i];
            for (j = 0; j < n; j++)
                acc -= im->Gc[n * i + j] * im->z[j];
            im->t[i] = acc;
        }
        stuck_coefficients(im, im->t, im->c, n);
        for (e = 0; e < m; e++)
            if (mask[e] > 0.0) {
                double pe = 0.0;
                for (i = 0; i < n; i++)
                    pe += YT[ld * i + e] * im->c[i];
                fits = fits && pe >= lo[e] && pe <= hi[e];
                p[e] = pe;
            }
        if (!fits)
            return 0;
    }
    /* z = Y^T p from the impulses themselves, so that the slips checked are those
     * that p gives (z_B + Gc c would round apart from them where the stuck rows are
     * nearly parallel and c is large) */
    project(im, p, im->z, n);
    for (e = 0; e < m; e++) {
        int64_t st = state[e];
        double slip = q[e];
        for (i = 0; i < n; i++)
            slip -= YT[ld * i + e] * im->z[i];
        if (st == 0)
            holds = holds && fabs(slip) <= tol;
        else if (st != 2)
            holds = holds && slip * (double)st >= -tol;
    }
    return holds;
}

/* The largest diagonal entry of W = Y Y^T over the unknowns involved. */
VSJ_ALWAYS_INLINE double largest_delassus(const impulses *im, const int64_t *state, int64_t n) {
    int64_t e, i;
    double w_max = 0.0;
    for (e = 0; e < im->m; e++)
        if (state[e] != 2) {
            double norm = 0.0;
            for (i = 0; i < n; i++)
                norm += im->YT[im->ld * i + e] * im->YT[im->ld * i + e];
            w_max = vsj__dmax(w_max, norm);
        }
    return w_max;
}

/* Newton step on the free set for the gradient in im->g, d = -(eps I + Y_F Y_F^T)^-1 g_F
 * by Woodbury's identity (an n x n solve), then a ratio test at the caps: the first
 * free unknown the step takes to a bound is put there. Returns whether the step was
 * taken whole (the free set's optimum reached). */
VSJ_ALWAYS_INLINE int newton_step(impulses *im, const double *lo, const double *hi, double *p,
                                  int64_t *state, double eps, int64_t n) {
    int64_t e, m = im->m, block = -1;
    double alpha = 1.0;
    gram(im, im->g, im->G, im->t, eps, n);
    vsj__ldl(im->G, im->Lg, n);
    vsj__ldl_solve(im->Lg, im->t, im->c, n);
    slips(im, im->g, im->c, im->d, n); /* d = g - Y c, scaled below */
    for (e = 0; e < m; e++) {
        double de, a;
        if (state[e] != 0)
            continue;
        de = -im->d[e] / eps;
        im->d[e] = de;
        if (de > 0.0 && p[e] + de > hi[e])
            a = (hi[e] - p[e]) / de;
        else if (de < 0.0 && p[e] + de < lo[e])
            a = (lo[e] - p[e]) / de;
        else
            continue;
        if (a < alpha) {
            alpha = a;
            block = e;
        }
    }
    for (e = 0; e < m; e++)
        if (state[e] == 0)
            p[e] = vsj__dmin(hi[e], vsj__dmax(lo[e], p[e] + alpha * im->d[e]));
    if (block < 0)
        return 1;
    p[block] = im->d[block] > 0.0 ? hi[block] : lo[block];
    state[block] = im->d[block] > 0.0 ? 1 : -1;
    return 0;
}

/* The unknown at a bound whose gradient im->g most wants it off the bound (by more
 * than tol), or -1: none does, and the problem is solved. */
VSJ_ALWAYS_INLINE int64_t to_release(const impulses *im, const int64_t *state, double tol) {
    int64_t e, release = -1;
    double worst = tol;
    for (e = 0; e < im->m; e++) {
        int64_t st = state[e];
        if ((st == 1 || st == -1) && im->g[e] * (double)st > worst) {
            worst = im->g[e] * (double)st;
            release = e;
        }
    }
    return release;
}

/* Remove the regularisation's creep from the stuck unknowns (their remaining slips,
 * of order eps p) by the minimum-norm correction of their impulses. */
VSJ_ALWAYS_INLINE void polish(impulses *im, const double *q, const double *lo,
                              const double *hi, double *p, const int64_t *state, int64_t n) {
    int64_t e, m = im->m, n_free = 0;
    for (e = 0; e < m; e++) {
        int free_ = state[e] == 0;
        im->mask[e] = free_ ? 1.0 : 0.0;
        n_free += free_;
    }
    if (n_free > 0) {
        project(im, p, im->z, n);
        slips(im, q, im->z, im->g, n);
        stuck_impulses(im, im->g, n);
        for (e = 0; e < m; e++)
            if (state[e] == 0)
                p[e] = vsj__dmin(hi[e], vsj__dmax(lo[e], p[e] + im->d[e]));
    }
}

/* The general method, from the warm start in p:
 * 1. the box problem min 1/2 p^T (W + eps I) p - q.p with a tiny
 *    eps = 1e-9 max W_ee is strictly convex; a primal active-set method (free
 *    unknowns stuck, the others at a bound) solves it in finitely many
 *    steps, each an n x n solve by Woodbury's identity;
 * 2. polish: the stuck unknowns' remaining slips (of order eps p) are removed
 *    by the minimum-norm correction of their impulses. */
VSJ_ALWAYS_INLINE int active_set(impulses *im, const double *q, const double *lo,
                                 const double *hi, double *p, int64_t *state,
                                 const unsigned char *active, int64_t *iterations, int64_t n) {
    int64_t m = im->m, e, it, n_free, release;
    double scale, w_max, eps, tol;
    int converged = 0, at_optimum = 0;
    snap(im, q, lo, hi, p, state, active, &scale);
    w_max = largest_delassus(im, state, n);
    *iterations = 0;
    if (w_max == 0.0) {
        project(im, p, im->z, n);
        return 1;
    }
    eps = IMPULSE_REG * w_max;
    tol = IMPULSE_ABS + IMPULSE_REL * scale;
    for (it = 0; it < IMPULSE_MAX_ITER; it++) {
        *iterations = it + 1;
        /* gradient of 1/2 p^T (W + eps I) p - q.p */
        project(im, p, im->z, n);
        slips(im, q, im->z, im->g, n);
        n_free = 0;
        for (e = 0; e < m; e++) {
            int free_ = state[e] == 0;
            im->g[e] = eps * p[e] - im->g[e];
            im->mask[e] = free_ ? 1.0 : 0.0;
            n_free += free_;
        }
        if (n_free > 0 && !at_optimum) {
            at_optimum = newton_step(im, lo, hi, p, state, eps, n);
            continue;
        }
        at_optimum = 0;
        release = to_release(im, state, tol);
        if (release < 0) {
            converged = 1;
            break;
        }
        state[release] = 0;
    }
    if (!converged)
        return 0;
    polish(im, q, lo, hi, p, state, n);
    project(im, p, im->z, n);
    return 1;
}

/* The solve for n coordinates. */
VSJ_ALWAYS_INLINE int solve_sized(impulses *im, const double *q, const double *lo,
                                  const double *hi, double *p, int64_t *state,
                                  const unsigned char *active, int64_t *iterations, int64_t n) {
    *iterations = 0;
    if (same_pattern(im, q, lo, hi, p, state, active, n))
        return 1;
    return active_set(im, q, lo, hi, p, state, active, iterations, n);
}

/* Exact Coulomb impulses: slips s = q - Y Y^T p with |p_e| <= cap_e. state
 * (-1, 0 stuck, +1; 2 not involved) and p carry the previous step's solution
 * as a warm start; im->z holds YT p on return. Compiled twice: for two coordinates
 * (the wrist's two rings, when its motors and pivot are driven by speed), where
 * the loops over the coordinates unroll, and for any number. */
int vsj__solve_impulses(impulses *im, const double *q, const double *lo, const double *hi,
                        double *p, int64_t *state, const unsigned char *active,
                        int64_t *iterations) {
    if (im->n == 2)
        return solve_sized(im, q, lo, hi, p, state, active, iterations, 2);
    return solve_sized(im, q, lo, hi, p, state, active, iterations, im->n);
}

int vsj_solve_impulses(int64_t n, int64_t m, const double *YT, int64_t count, const double *qs,
                       const double *cap, const unsigned char *active, double *ps,
                       int64_t *states, int64_t *iterations) {
    impulses im;
    double *block, *p, *lo, *hi;
    int64_t *state, k;
    if (n < 0 || m < 0 || count < 0)
        return VSJ_BAD_ARGUMENT;
    block = (double *)calloc((size_t)(5 * n * n + 4 * n + 7 * m + 2), sizeof(double));
    state = (int64_t *)calloc((size_t)(m + 1), sizeof(int64_t));
    if (!block || !state) {
        free(block);
        free(state);
        return VSJ_NO_MEMORY;
    }
    im.YT = YT;
    im.n = n;
    im.m = m;
    im.ld = m;
    im.G = block;
    im.Lg = im.G + n * n;
    im.Gc = im.Lg + n * n;
    im.Lk = im.Gc + n * n;
    im.t = im.Lk + n * n;
    im.c = im.t + n;
    im.z = im.c + n;
    im.mask = im.z + n;
    im.d = im.mask + m;
    im.g = im.d + m;
    im.memo = im.g + m; /* m + 1 */
    p = im.memo + m + 1;
    lo = p + m;
    hi = lo + m;
    for (k = 0; k < m; k++) {
        lo[k] = -cap[k];
        hi[k] = cap[k];
    }
    for (k = 0; k < count; k++) {
        int64_t it;
        int ok = vsj__solve_impulses(&im, qs + m * k, lo, hi, p, state, active, &it);
        iterations[k] = ok ? it : -1;
        memcpy(ps + m * k, p, (size_t)m * sizeof(double));
        memcpy(states + m * k, state, (size_t)m * sizeof(int64_t));
    }
    free(block);
    free(state);
    return VSJ_OK;
}
