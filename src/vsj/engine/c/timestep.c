/* Fixed-step time stepping with exact Coulomb stiction.
 *
 * A velocity-level scheme in the family of Moreau and Jean, for true sticking
 * (the open problem of report section 4.1.3 and its conclusion). Per step of
 * length h:
 *
 *   - springs: trapezoidal rule, linearised about the start of the step with
 *     the law's analytic stiffness; the geometric element's potential form by
 *     the discrete gradient of its energy (its torque over the step is its
 *     energy's change over the deflection's), linearised about a prediction;
 *   - smooth friction and viscous parts: implicit Euler, linearised (damping
 *     that stays stable however stiff); dampers (elements flagged
 *     VSJ_F_TRAPEZOIDAL, such as a spring-damper's) the trapezoidal rule, so
 *     that an oscillator's spring and damper are second order together;
 *   - DC motor armatures: exactly, as a linear RL circuit driven by the
 *     step's mid-step voltage and back-EMF (the rotor moves with the mid-step
 *     speed, as every force is booked), so an electrical time constant far
 *     below the step is neither a stability nor an energy problem;
 *   - Coulomb parts of stiction elements: impulses p_e with |p_e| <= h c_e
 *     (c_e = k_e pi/2), decided together for all elements by
 *
 *         s = q - W p,  p_e = +h c_e if s_e > 0,  -h c_e if s_e < 0,
 *         |p_e| <= h c_e if s_e = 0,
 *
 *     with W = D H^-1 D^T the Delassus matrix of the elements' slip rows and
 *     q their slips without Coulomb friction. It is solved exactly: last
 *     step's stick/slip pattern is checked first (cheap, and it holds on most
 *     steps), an active-set method takes over when it does not (impulses.c,
 *     with the small dense solves of linalg.c). An element
 *     with s_e = 0 holds exactly (no creep), and which elements hold is decided
 *     jointly through the gears and the differential.
 *
 * Elements whose slip rows are parallel (the bearings and meshes that turn
 * with one gear) slip together; they are posed as one unknown bounded by
 * their levels summed through the gear ratios: the same problem, smaller. A
 * stuck group loads each element to the same fraction of its static level
 * (the contact conditions leave that split open).
 *
 * Every force's work is booked against the mid-step speed, the speed the
 * scheme moves with, so the energy ledger (ledger.c) closes up to the springs'
 * and contacts' linearisation about their predicted end (of fifth order in the
 * step's deflection) and the pivot's motion within the step.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "internal.h"

/* slip speed [rad/s] below which an element counts as stuck */
#define STUCK_SPEED 1e-10
/* relative change of the step matrix below which its factor is reused */
#define H_REUSE 1e-12
/* relative difference below which two friction rows count as parallel */
#define PARALLEL 1e-12
/* two step lengths within this fraction of h are the same step (round-off of t0 + k h) */
#define STEP_SAME 1e-9

/* ---- the armature circuit over one step -------------------------------------- */

/* L di/dt = V - R i - k w with V and w held over a step of length h has the exact
 * solution i(t) = i_inf + (i0 - i_inf) exp(-t/tau), tau = L/R, i_inf = (V - k w)/R.
 * Per motor: e = exp(-h/tau); decay = tau (1 - e) [s], so that the charge is
 * Q = i_inf (h - decay) + i0 decay; gain = (h - decay)/R; half = tau (1 - e^2)/2, the
 * integral of exp(-2t/tau), for the Joule heat. h - decay = tau g(h/tau) with
 * g(x) = x - 1 + exp(-x), taken from its series where the closed form cancels. The
 * values are kept while the step keeps its length (rl_h); every use within a step
 * takes rl_h with them, so the circuit's energy balance holds exactly. */
static void armature_steps(const vsj_model *m, ts_work *t, double h, double h_nominal) {
    int64_t mo, r_mot = m->n_frictions + m->n_springs + m->n_loads;
    if (fabs(h - t->rl_h) <= STEP_SAME * h_nominal) /* the same step, to round-off */
        return;
    for (mo = 0; mo < m->n_motors; mo++) {
        const double *p = vsj__row(m, r_mot + mo);
        double R = p[0], L = p[1], tau, x, g;
        if (!(L > 0.0)) { /* no inductance: the current follows at once */
            t->rl_e[mo] = 0.0;
            t->rl_decay[mo] = 0.0;
            t->rl_gain[mo] = h / R;
            t->rl_half[mo] = 0.0;
            continue;
        }
        tau = L / R;
        x = h / tau;
        g = x < 1e-2 ? 0.5 * x * x
                           * (1.0 - x / 3.0 * (1.0 - x / 4.0 * (1.0 - x / 5.0 * (1.0 - x / 6.0))))
                     : x + expm1(-x);
        t->rl_e[mo] = exp(-x);
        t->rl_decay[mo] = -tau * expm1(-x);
        t->rl_gain[mo] = tau * g / R;
        t->rl_half[mo] = -0.5 * tau * expm1(-2.0 * x);
    }
    t->rl_h = h;
}

/* ---- the stepper's set-up ---------------------------------------------------- */

/* The impulse problem over the friction unknowns and, with `full`, the end
 * stops' too. Without the stops it is the leading block of the full one (the
 * stops' compliance rows vanish in the friction columns), so it is posed on the
 * same arrays: a smaller problem while no stop is involved, as on most steps. */
static impulses impulses_of(vsj_work *w, int full) {
    ts_work *t = &w->ts;
    impulses im;
    im.YT = t->YlT;
    im.ld = t->na + t->nc;
    im.n = full ? w->n + t->ncomp : w->n;
    im.m = full ? t->na + t->nc : t->na;
    im.mask = t->mask;
    im.G = t->G;
    im.Lg = t->Lg;
    im.t = t->tv;
    im.c = t->cv;
    im.d = t->d;
    im.g = t->g;
    im.z = t->z;
    im.Gc = t->Gc;
    im.Lk = t->Lk;
    im.memo = t->memo;
    return im;
}

/* alpha with row e = alpha row g (free and source parts, to round-off), or 0 */
static double parallel(const ts_work *t, int64_t cols, int64_t n, int64_t s, int64_t e,
                       int64_t g) {
    double dot = 0.0, norm = 0.0, big = 0.0, alpha;
    int64_t i, j;
    for (i = 0; i < n; i++) {
        dot += t->DxT[cols * i + e] * t->DxT[cols * i + g];
        norm += t->DxT[cols * i + g] * t->DxT[cols * i + g];
        big = vsj__dmax(big, fabs(t->DxT[cols * i + e]));
    }
    for (j = 0; j < s; j++) {
        dot += t->DuT[cols * j + e] * t->DuT[cols * j + g];
        norm += t->DuT[cols * j + g] * t->DuT[cols * j + g];
        big = vsj__dmax(big, fabs(t->DuT[cols * j + e]));
    }
    if (norm == 0.0)
        return 0.0;
    alpha = dot / norm;
    for (i = 0; i < n; i++)
        if (fabs(t->DxT[cols * i + e] - alpha * t->DxT[cols * i + g]) > PARALLEL * big)
            return 0.0;
    for (j = 0; j < s; j++)
        if (fabs(t->DuT[cols * j + e] - alpha * t->DuT[cols * j + g]) > PARALLEL * big)
            return 0.0;
    return alpha;
}

/* Whether element e holds: no slip, and not free (a clutch or brake without
 * normal force is free, as MSL's mode 2, even when its flanges turn alike). */
static int holding(const vsj_model *m, const vsj_work *w, int64_t e) {
    return fabs(w->ts.slip[e]) <= STUCK_SPEED && !vsj__free(m, w, e);
}

static double coulomb_level(const vsj_model *m, int64_t e) {
    return vsj__row(m, e)[1] * (0.5 * VSJ_PI);
}

/* Each group's level (the sum of its elements' through the gear ratios) and each
 * element's share of the group's impulse: in proportion to its level, so a
 * slipping group puts every element at its level and a stuck one loads each to
 * the same fraction of its own. */
static void share_levels(ts_work *t, int64_t nf) {
    int64_t a, e;
    for (a = 0; a < t->na; a++) {
        t->level[a] = 0.0;
        t->hold[a] = 0.0;
    }
    for (e = 0; e < nf; e++)
        if (t->slot[e] >= 0) {
            t->level[t->slot[e]] += fabs(t->ratio[e]) * t->lev[e];
            t->hold[t->slot[e]] += fabs(t->ratio[e]) * t->levs[e];
        }
    for (e = 0; e < nf; e++) {
        t->share[e] = 0.0;
        if (t->slot[e] >= 0 && t->level[t->slot[e]] > 0.0)
            t->share[e] = copysign(t->lev[e] / t->level[t->slot[e]], t->ratio[e]);
    }
}

/* Coulomb impulses act on free coordinates (active); stiction elements that only
 * sources drive just follow their slip (driven). Every element row is stored densely,
 * one coordinate per row (DxT, DuT), so that the loops over elements are vector
 * loops. */
static void dense_rows(const vsj_model *m, ts_work *t) {
    int64_t n = m->n, s = m->n_sources, nf = m->n_frictions, cols = nf + m->n_springs, e, k;
    for (e = 0; e < nf; e++) {
        int stick = m->code[e] == VSJ_STICTION;
        t->active[e] = stick && m->xp[e + 1] > m->xp[e];
        t->driven[e] = stick && !t->active[e];
    }
    memset(t->Bx, 0, (size_t)(n * n) * sizeof(double));
    memset(t->Bu, 0, (size_t)(n * s) * sizeof(double));
    memset(t->DxT, 0, (size_t)(n * cols) * sizeof(double));
    memset(t->DuT, 0, (size_t)(s * cols) * sizeof(double));
    for (e = 0; e < cols; e++) {
        for (k = m->xp[e]; k < m->xp[e + 1]; k++)
            t->DxT[cols * m->xc[k] + e] = m->xv[k];
        for (k = m->up[e]; k < m->up[e + 1]; k++)
            t->DuT[cols * m->uc[k] + e] = m->uv[k];
    }
}

/* Elements whose smooth part is linear (viscous, and stiction's viscous part) are
 * summed once: their share of the step matrix is h Bx and of the right-hand side
 * -h Bu u1 (a damper's weighted by theta = 1/2, the other half taken at the step's
 * start). */
static void linear_parts(const vsj_model *m, ts_work *t) {
    int64_t n = m->n, s = m->n_sources, nf = m->n_frictions, cols = nf + m->n_springs;
    int64_t e, i, j, c;
    t->n_damper = 0;
    for (e = 0; e < nf; e++) {
        t->linear[e] = m->code[e] == VSJ_STICTION || m->code[e] == VSJ_VISCOUS;
        t->theta[e] = 1.0;
        if (t->linear[e]) {
            double b;
            if (vsj__row(m, e)[VSJ_F_TRAPEZOIDAL] != 0.0) {
                t->theta[e] = 0.5;
                t->damper[t->n_damper++] = e;
            }
            b = t->theta[e] * vsj__row(m, e)[0];
            for (i = 0; i < n; i++) {
                for (c = 0; c < n; c++)
                    t->Bx[n * i + c] += b * t->DxT[cols * i + e] * t->DxT[cols * c + e];
                for (j = 0; j < s; j++)
                    t->Bu[s * i + j] += b * t->DxT[cols * i + e] * t->DuT[cols * j + e];
            }
        }
    }
}

/* Groups of parallel active elements: one impulse unknown each (slot), shared in
 * proportion to the elements' levels (share). Sets na, the number of groups. */
static void friction_groups(const vsj_model *m, ts_work *t) {
    int64_t n = m->n, s = m->n_sources, nf = m->n_frictions, cols = nf + m->n_springs;
    int64_t e, a, na = 0;
    for (e = 0; e < nf; e++) {
        t->slot[e] = -1;
        t->ratio[e] = 0.0;
        if (!t->active[e])
            continue;
        for (a = 0; a < na; a++) {
            double alpha = parallel(t, cols, n, s, e, t->lead[a]);
            if (alpha != 0.0) {
                t->slot[e] = a;
                t->ratio[e] = alpha;
                break;
            }
        }
        if (t->slot[e] < 0) {
            t->slot[e] = na;
            t->ratio[e] = 1.0;
            t->lead[na] = e;
            na++;
        }
    }
    t->na = na;
}

/* End stops: a spring whose law has one, and whose deflection the free coordinates
 * move, gets two unilateral constraints (|d| <= stop), appended to the impulse
 * unknowns with bounds [0, inf); a compliant stop adds its compliance as a row of its
 * own to YlT (one more row of the problem). Then every unknown's rows, a stop's with
 * its side's sign (DxA, DuA). */
static void end_stops(const vsj_model *m, ts_work *t) {
    int64_t n = m->n, s = m->n_sources, nf = m->n_frictions, cols = nf + m->n_springs;
    int64_t na = t->na, k, rr, a, i, j, mt;
    t->nc = 0;
    t->ncomp = 0;
    for (k = 0; k < m->n_springs; k++) {
        double angle, stiffness, side;
        rr = nf + k;
        t->has_stop[k] = vsj__stop(m->code[rr], vsj__row(m, rr), &angle, &stiffness)
                         && m->xp[rr + 1] > m->xp[rr];
        if (!t->has_stop[k])
            continue;
        for (side = 1.0; side >= -1.0; side -= 2.0) {
            int64_t row = t->nc++;
            t->cspring[row] = k;
            t->csign[row] = side;
            t->cstop[row] = angle;
            t->ckstop[row] = stiffness;
            t->ccomp[row] = isfinite(stiffness) ? t->ncomp++ : -1;
        }
    }
    mt = na + t->nc;
    for (a = 0; a < mt; a++) {
        int64_t from = a < na ? t->lead[a] : nf + t->cspring[a - na];
        double side = a < na ? 1.0 : t->csign[a - na];
        for (i = 0; i < n; i++)
            t->DxA[mt * i + a] = side * t->DxT[cols * i + from];
        for (j = 0; j < s; j++)
            t->DuA[mt * j + a] = side * t->DuT[cols * j + from];
        t->involved[a] = a < na; /* end stops: decided step by step */
    }
}

/* The elements' Coulomb levels at rest, and the index lists: smooth parts that are
 * not linear; elements whose stick phases are counted. */
static void levels_and_lists(const vsj_model *m, ts_work *t) {
    int64_t e, nf = m->n_frictions;
    t->any_varying = 0;
    for (e = 0; e < nf; e++) {
        t->lev[e] = t->levs[e] = coulomb_level(m, e);
        t->any_varying = t->any_varying || ((t->active[e] || t->driven[e]) && vsj__varying(m, e));
    }
    share_levels(t, nf);
    t->n_nonlinear = 0;
    t->n_watched = 0;
    for (e = 0; e < nf; e++) {
        if (!t->linear[e])
            t->nonlinear[t->n_nonlinear++] = e;
        if (t->active[e] || t->driven[e])
            t->watched[t->n_watched++] = e;
    }
}

/* Whether the pivot's angle stays as it is: it follows no free coordinate, and its
 * sources' speeds are inputs that are zero throughout (a constant zero spline, with
 * zero integrals, that no controller drives), so that their angles do not move. (Held
 * inputs, the step function's, are other values: step_inputs checks.) */
static int pivot_still(const vsj_model *m) {
    int64_t r_piv = m->n_rows - 1, k;
    if (m->xp[r_piv + 1] > m->xp[r_piv])
        return 0;
    for (k = m->up[r_piv]; k < m->up[r_piv + 1]; k++) {
        int64_t ch = m->src_ch[m->uc[k]], p0 = m->first[ch], koff = p0 + ch;
        const double *cf = m->coef + 4 * p0;
        if (m->count[ch] != 1 || cf[0] != 0.0 || cf[1] != 0.0 || cf[2] != 0.0 || cf[3] != 0.0
            || m->cum[koff] != 0.0 || m->cum[koff + 1] != 0.0 || m->period[2 * ch + 1] != 0.0)
            return 0;
        if (vsj__among(m->act_ch, m->n_acts, ch))
            return 0;
    }
    return 1;
}

/* Whether source j drives the pivot. */
static int pivot_source(const ts_work *t, int64_t j) {
    return vsj__among(t->mid_src, t->n_mid_src, j);
}

/* At mid-step only the loads, the motor voltages and the pivot's sources are read; a
 * load or voltage constant in time (and not a controller's) keeps its value from t = 0.
 * At step end only the sources' channels are read. */
static void channel_lists(const vsj_model *m, ts_work *t) {
    int64_t nf = m->n_frictions, r_load = nf + m->n_springs, r_piv = m->n_rows - 1;
    int64_t rr, e, k, c, j;
    memset(t->wanted, 0, (size_t)m->n_channels);
    for (rr = r_load; rr < r_load + m->n_loads + m->n_motors; rr++) {
        int64_t ch = m->code[rr], p0 = m->first[ch];
        const double *cf = m->coef + 4 * p0;
        int steady = m->count[ch] == 1 && cf[1] == 0.0 && cf[2] == 0.0 && cf[3] == 0.0;
        t->wanted[ch] = !steady;
    }
    for (k = 0; k < m->n_acts; k++) /* a controller's: held values that change */
        t->wanted[m->act_ch[k]] = 1;
    for (e = 0; e < nf; e++) /* the normal forces of clutches and brakes */
        if (vsj__row(m, e)[VSJ_F_CHANNEL] >= 0.0)
            t->wanted[(int64_t)vsj__row(m, e)[VSJ_F_CHANNEL]] = 1;
    t->n_mid_src = 0;
    t->pivot_still = pivot_still(m);
    for (k = m->up[r_piv]; k < m->up[r_piv + 1]; k++) {
        t->mid_src[t->n_mid_src++] = m->uc[k];
        t->wanted[m->src_ch[m->uc[k]]] |= !t->pivot_still;
    }
    t->n_mid_ch = 0;
    for (c = 0; c < m->n_channels; c++)
        if (t->wanted[c])
            t->mid_ch[t->n_mid_ch++] = c;
    memset(t->wanted, 0, (size_t)m->n_channels);
    /* a channel is read at the end unless only a still pivot's sources read it */
    for (j = 0; j < m->n_sources; j++)
        t->wanted[m->src_ch[j]] |= !(t->pivot_still && pivot_source(t, j));
    t->n_end_ch = 0;
    for (c = 0; c < m->n_channels; c++)
        if (t->wanted[c])
            t->end_ch[t->n_end_ch++] = c;
}

/* No stick/slip history: no impulses, no factor, no counts. */
/* The numbers one call hands the next (the factor, the impulse problem's rows, the last
 * impulses as its warm start and the memo of its stuck set): forgotten, so that the
 * next step makes them afresh. The stick counts are kept. */
static void forget_numbers(const vsj_model *m, ts_work *t) {
    int64_t n = m->n, nk = m->n_springs, nf = m->n_frictions;
    int64_t nr = n + 2 * nk, mu = nf + 2 * nk, a;
    memset(t->H_last, 0, (size_t)(n * n) * sizeof(double));
    memset(t->YlT, 0, (size_t)(nr * mu) * sizeof(double));
    memset(t->qv, 0, (size_t)mu * sizeof(double));
    memset(t->lo, 0, (size_t)mu * sizeof(double));
    memset(t->hi, 0, (size_t)mu * sizeof(double));
    memset(t->p, 0, (size_t)mu * sizeof(double));
    memset(t->mask, 0, (size_t)mu * sizeof(double));
    memset(t->memo, 0, (size_t)(mu + 1) * sizeof(double));
    memset(t->Gc, 0, (size_t)(nr * nr) * sizeof(double));
    memset(t->Lk, 0, (size_t)(nr * nr) * sizeof(double));
    for (a = 0; a < mu; a++)
        t->state[a] = 0;
    t->hs_prev = NAN;
    t->rl_h = NAN; /* the armature steps follow the parameters */
    t->angle_prev = NAN; /* the pivot's too */
    t->factored = 0;
    t->memo_full = -1;
}

/* A fresh history: no numbers from earlier calls, no stick phases counted. */
static void clear_history(const vsj_model *m, ts_work *t) {
    int64_t e;
    forget_numbers(m, t);
    for (e = 0; e < m->n_frictions; e++) {
        t->held[e] = 0;
        t->transitions[e] = 0;
    }
}

/* Whether the last impulses, the next step's warm start, are finite: a period whose
 * inputs overflowed the model (1e306 V) can leave them not, and its state unchanged
 * (vsj_step), which the next period must step from as a fresh work would. */
static int impulses_finite(const vsj_model *m, const ts_work *t) {
    int64_t a, mu = m->n_frictions + 2 * m->n_springs;
    for (a = 0; a < mu; a++)
        if (!isfinite(t->p[a]))
            return 0;
    return 1;
}

int vsj_ts_prepare(const vsj_model *m, vsj_work *w) {
    ts_work *t = &w->ts;
    if (!vsj__fits(m, w))
        return VSJ_BAD_ARGUMENT;
    dense_rows(m, t);
    linear_parts(m, t);
    friction_groups(m, t);
    end_stops(m, t);
    levels_and_lists(m, t);
    channel_lists(m, t);
    clear_history(m, t);
    t->prepared = 1;
    t->for_par = m->par;
    t->for_rows = m->xv;
    t->for_mass = m->mass;
    return VSJ_OK;
}

/* every element's slip s = Dx v + Du u (dense rows, one coordinate per row) */
VSJ_ALWAYS_INLINE void element_slips(const double *restrict DxT, const double *restrict DuT,
                                     int64_t cols, int64_t count, const double *restrict v,
                                     int64_t n, const double *restrict u, int64_t s_n,
                                     double *restrict s) {
    int64_t e, i, j;
    for (e = 0; e < count; e++)
        s[e] = 0.0;
    for (i = 0; i < n; i++) {
        double vi = v[i];
        const double *row = DxT + cols * i;
        for (e = 0; e < count; e++)
            s[e] += row[e] * vi;
    }
    for (j = 0; j < s_n; j++) {
        double uj = u[j];
        const double *row = DuT + cols * j;
        for (e = 0; e < count; e++)
            s[e] += row[e] * uj;
    }
}

/* H += scale d d^T with d the free-coordinate part of row r */
VSJ_ALWAYS_INLINE void outer(const vsj_model *m, int64_t r, double *H, double scale, int64_t n) {
    int64_t a, b;
    for (a = m->xp[r]; a < m->xp[r + 1]; a++)
        for (b = m->xp[r]; b < m->xp[r + 1]; b++)
            H[n * m->xc[a] + m->xc[b]] += scale * m->xv[a] * m->xv[b];
}

/* The memo (the stuck set's matrices) holds for the problem it was made for
 * and the YlT it was made with: forget it when either changes. */
static void forget_memo(ts_work *t) {
    t->memo[t->na] = 0.0;
    t->memo[t->na + t->nc] = 0.0;
}

/* The problem posed with the end stops (full) or without them (impulses_of); without,
 * the stops' unknowns take no impulse and are out of it. */
static void use_problem(vsj_work *w, impulses *im, int full) {
    ts_work *t = &w->ts;
    int64_t a;
    *im = impulses_of(w, full);
    if (full != t->memo_full) {
        forget_memo(t);
        t->memo_full = full;
    }
    if (!full)
        for (a = t->na; a < t->na + t->nc; a++) {
            t->p[a] = 0.0;
            t->state[a] = 2;
        }
}

/* Whether the time-stepper's analysis in w was made for m (its arrays). */
int vsj__ts_prepared_for(const vsj_model *m, const vsj_work *w) {
    const ts_work *t = &w->ts;
    return t->prepared && t->for_par == m->par && t->for_rows == m->xv && t->for_mass == m->mass;
}

int vsj__ts_begin(const vsj_model *m, vsj_work *w, const double *y, double t0) {
    ts_work *t = &w->ts;
    int64_t n, nm, j;
    double angle;
    if (!vsj__ts_prepared_for(m, w)) /* (the callers have checked that w fits m) */
        return VSJ_BAD_ARGUMENT;
    n = m->n;
    nm = m->n_motors;
    memcpy(t->x, y, (size_t)n * sizeof(double));
    memcpy(t->v, y + n, (size_t)n * sizeof(double));
    memcpy(t->cur, y + 2 * n, (size_t)nm * sizeof(double));
    if (!impulses_finite(m, t)) /* a failed call's numbers: not a warm start */
        forget_numbers(m, t);
    vsj__eval_inputs(m, w, t0);
    for (j = 0; j < m->n_sources; j++) {
        t->u0[j] = w->srcw[SRCW * j + U];
        t->sg0[j] = w->srcw[SRCW * j + SG];
    }
    w->status = VSJ_OK;
    /* the pivot's position is recomputed only when its angle changes (the step
     * function's calls follow one another: a pivot held still costs no sine) */
    angle = vsj__pivot_angle(m, w, t->x);
    if (angle != t->angle_prev) {
        t->angle_prev = angle;
        t->q_prev = vsj__pivot_at(m, w, angle);
    } else {
        vsj__pivot_record(m, w, t->q_prev);
    }
    t->angle_mid = t->angle_prev;
    t->q_mid = t->q_prev;
    t->t = t0;
    t->origin = t0;
    t->k = 0;
    t->first = 1; /* (the factor and the impulse memo are kept for the same matrix) */
    element_slips(t->DxT, t->DuT, m->n_frictions + m->n_springs, m->n_frictions, t->v, n, t->u0,
                  m->n_sources, t->slip);
    return w->status;
}

static void sample(const vsj_model *m, const vsj_work *w, const vsj_samples *smp,
                   int64_t i_out, const double *y, int64_t n_col) {
    const ts_work *t = &w->ts;
    int64_t j, k, nf = m->n_frictions;
    for (j = 0; j < n_col; j++)
        smp->out[smp->out_cols * i_out + j] = y[j];
    if (smp->out_cols >= n_col + w->nbus + w->nact)
        vsj__control_record(w, smp->t[i_out], smp->out + smp->out_cols * i_out + n_col);
    if (smp->coulomb)
        for (k = 0; k < t->n_watched; k++) {
            int64_t e = t->watched[k];
            smp->coulomb[nf * i_out + e] = t->force[e] - vsj__row(m, e)[0] * t->slip[e];
            smp->stuck[nf * i_out + e] = (unsigned char)holding(m, w, e);
        }
}

/* ---- one step, from tnow to t1 = tnow + hs ----------------------------------- */

/* Levels that follow a normal force, a table or a peak: each element's at its slip of
 * the step's start, and its static one (mid-step inputs). */
static void step_levels(const vsj_model *m, vsj_work *w) {
    ts_work *t = &w->ts;
    int64_t e, nf = m->n_frictions;
    for (e = 0; e < nf; e++)
        if ((t->active[e] || t->driven[e]) && vsj__varying(m, e)) {
            t->levs[e] = coulomb_level(m, e) * vsj__normal(m, w, e, 0.0, 1);
            t->lev[e] = fabs(t->slip[e]) <= STUCK_SPEED
                            ? t->levs[e]
                            : coulomb_level(m, e) * vsj__normal(m, w, e, t->slip[e], 0);
        }
    share_levels(t, nf);
}

/* The step's inputs: at mid-step the loads, voltages and normal forces, and the pivot
 * position at the midpoint x + hs/2 v (kept while its angle stays); at the step's end
 * the sources' speeds u1 and angles sg1. Held inputs (the step function) change only
 * from call to call, and vsj__ts_begin reads every channel: the steady ones left out
 * of mid_ch keep the held value it read. */
VSJ_ALWAYS_INLINE void step_inputs(const vsj_model *m, vsj_work *w, double tnow, double t1,
                                   double hs, int64_t n) {
    ts_work *t = &w->ts;
    int64_t i, j, ld, mo, r_load = m->n_frictions + m->n_springs;
    /* a pivot held still keeps its position (held inputs may move it) */
    int moves = !t->pivot_still || w->held;
    double angle;
    for (i = 0; i < t->n_mid_ch; i++)
        vsj__eval_channel(m, w, t->mid_ch[i], tnow + 0.5 * hs);
    for (i = 0; moves && i < t->n_mid_src; i++) {
        if (t->pivot_still) /* (then its channels are not in mid_ch) */
            vsj__eval_channel(m, w, m->src_ch[t->mid_src[i]], tnow + 0.5 * hs);
        vsj__eval_source(m, w, t->mid_src[i]);
    }
    if (t->any_varying)
        step_levels(m, w);
    for (ld = 0; ld < m->n_loads; ld++)
        t->ldm[ld] = w->chan[3 * m->code[r_load + ld]];
    for (mo = 0; mo < m->n_motors; mo++)
        t->vm[mo] = w->chan[3 * m->code[r_load + m->n_loads + mo]];
    if (moves) {
        for (i = 0; i < n; i++)
            t->x1[i] = t->x[i] + 0.5 * hs * t->v[i];
        angle = vsj__pivot_angle(m, w, t->x1);
        if (angle != t->angle_mid) {
            t->angle_mid = angle;
            t->q_mid = vsj__pivot_at(m, w, angle);
        }
    }
    for (i = 0; i < t->n_end_ch; i++)
        vsj__eval_channel(m, w, t->end_ch[i], t1);
    for (j = 0; j < m->n_sources; j++) {
        int still = t->pivot_still && pivot_source(t, j);
        if (still && !moves) { /* held still: speed 0, the same angle */
            t->u1[j] = t->u0[j];
            t->sg1[j] = t->sg0[j];
            continue;
        }
        if (still) /* (then its channel is not in end_ch) */
            vsj__eval_channel(m, w, m->src_ch[j], t1);
        vsj__eval_source(m, w, j);
        t->u1[j] = w->srcw[SRCW * j + U];
        t->sg1[j] = w->srcw[SRCW * j + SG];
    }
}

/* H v1 = r, its inertia and linear friction: H = M + hs Bx, r = M v - M_su (u1 - u0)
 * - hs Bu u1. */
VSJ_ALWAYS_INLINE void assemble_inertia(const vsj_model *m, ts_work *t, double hs, int64_t n) {
    int64_t s_n = m->n_sources, i, j, c;
    for (i = 0; i < n; i++) {
        double total = 0.0;
        for (c = 0; c < n; c++) {
            t->H[n * i + c] = m->mass[(n + s_n) * i + c] + hs * t->Bx[n * i + c];
            total += m->mass[(n + s_n) * i + c] * t->v[c];
        }
        for (j = 0; j < s_n; j++)
            total -= m->mass[(n + s_n) * i + n + j] * (t->u1[j] - t->u0[j])
                     + hs * t->Bu[s_n * i + j] * t->u1[j];
        t->r[i] = total;
    }
}

/* A spring's torque over a step, as the discrete gradient of its energy between the
 * start's deflection d0 and the prediction d1p = d0 + hs rate0 + dsig (the rate held):
 * the endpoint-corrected trapezoidal rule of V' over [d0, d1p], whose error is of
 * fifth order in the step's deflection (the plain quotient (V(d1p) - V(d0)) / (d1p -
 * d0) would cancel as the step's deflection vanishes). Returns the torque at d1p
 * and in *kap twice its slope in the end deflection, so that the torque over the
 * step is that less kap / 2 (d1 - d1p), as the trapezoidal rule's is with the law's
 * stiffness. */
static double spring_gradient(const vsj_model *m, vsj_work *w, int64_t k, double d0,
                              double tau0, double kap0, double d1p, double *kap) {
    int64_t rr = m->n_frictions + k;
    double kap1, en, dvq, span = d1p - d0;
    double tau1 = vsj__spring(m->code[rr], vsj__row(m, rr), d1p, w->ts.q_mid, &kap1, &en,
                              &dvq, w->spcache + 4 * k, !w->ts.has_stop[k]);
    /* the slope of the mean gradient in its end: (2 V''(d1) + V''(d0)) / 6, exact for
     * a cubic energy */
    *kap = (2.0 * kap1 + kap0) * (1.0 / 3.0);
    return 0.5 * (tau0 + tau1) + span * (kap1 - kap0) * (1.0 / 12.0);
}

/* The end speeds that keep spring k within its stop, for its two end-stop unknowns
 * (from `stop` on): |d| <= stop at the step's end, with d1 = d0 + h/2 (d0' + d1'),
 * lets the end speed side d1' be at most cb (the trapezoidal position update). d0 and
 * rate0, its deflection and rate at the step's start, are the spring's own
 * (assemble_springs). Returns the next stop unknown. */
static int64_t stop_speeds(ts_work *t, double hs, int64_t k, int64_t stop, double d0,
                           double rate0) {
    for (; stop < t->nc && t->cspring[stop] == k; stop++) {
        double side = t->csign[stop];
        t->cb[stop] = 2.0 / hs * (t->cstop[stop] - side * d0) - side * rate0;
    }
    return stop;
}

/* The springs, by the trapezoidal rule linearised about the step's start with the
 * law's stiffness (the end stops are constraints of the impulse problem); a law whose
 * torque is its energy's gradient and whose energy is not quadratic in the deflection
 * (the geometric element's potential form) by its discrete gradient, so that the
 * ledger books its work as the change of its energy. */
VSJ_ALWAYS_INLINE void assemble_springs(const vsj_model *m, vsj_work *w, double hs, int64_t n) {
    ts_work *t = &w->ts;
    int64_t s_n = m->n_sources, nf = m->n_frictions, cols = nf + m->n_springs;
    int64_t i, j, c, k, rr, stop = 0;
    for (k = 0; k < m->n_springs; k++) {
        double d0 = 0.0, rate = 0.0, rate0, dsig = 0.0, kap, en, dvq, tau, c_k;
        rr = nf + k;
        for (i = 0; i < n; i++) {
            d0 += t->DxT[cols * i + rr] * t->x[i];
            rate += t->DxT[cols * i + rr] * t->v[i];
        }
        rate0 = rate; /* the rate with the sources' part (rate: the free coordinates') */
        for (j = 0; j < s_n; j++) {
            double d = t->DuT[cols * j + rr];
            d0 += d * t->sg0[j];
            dsig += d * (t->sg1[j] - t->sg0[j]);
            rate0 += d * t->u0[j];
        }
        if (t->has_stop[k])
            stop = stop_speeds(t, hs, k, stop, d0, rate0);
        tau = vsj__spring(m->code[rr], vsj__row(m, rr), d0, t->q_mid, &kap, &en, &dvq,
                          w->spcache + 4 * k, !t->has_stop[k]);
        if (m->code[rr] == VSJ_GEOMETRIC) {
            tau = spring_gradient(m, w, k, d0, tau, kap, d0 + hs * rate + dsig, &kap);
            c_k = tau + 0.25 * kap * hs * rate; /* the torque at d1p, less its rate0 part */
        } else {
            c_k = tau - 0.5 * kap * dsig - 0.25 * kap * hs * rate;
        }
        t->sp_c[k] = c_k;
        t->sp_kap[k] = kap;
        for (i = 0; i < n; i++) {
            double di = t->DxT[cols * i + rr];
            t->r[i] += hs * c_k * di;
            for (c = 0; c < n; c++)
                t->H[n * i + c] += 0.25 * hs * hs * kap * di * t->DxT[cols * c + rr];
        }
    }
}

/* Friction's smooth parts: the dampers' half at the step's start, the non-linear laws
 * linearised about the start's slip (implicit Euler); then the loads' torques. */
/* The penetration of contact e at the step's start. */
static double contact_depth(const vsj_model *m, const ts_work *t, int64_t e) {
    return vsj__xdot(m, e, t->x) + vsj__udotv(m, e, t->sg0) - vsj__row(m, e)[VSJ_C_GAP];
}

/* A contact's elastic energy k d^(n+1) / (n+1) (0 apart) and force k d^n. */
static double contact_energy(const double *p, double d, double *force) {
    double k = p[VSJ_C_STIFFNESS], n = p[VSJ_C_EXPONENT], dn;
    if (!(d > 0.0)) {
        *force = 0.0;
        return 0.0;
    }
    dn = n == 1.0 ? d : pow(d, n);
    *force = k * dn;
    return k * dn * d / (n + 1.0);
}

/* The discrete gradient g = (V(d1) - V(d0)) / (d1 - d0) of a contact's elastic energy
 * and its derivative in d1, dg = (V'(d1) - g) / (d1 - d0). Where both ends penetrate and
 * lie within 1e-3 of each other, their Taylor series about d0 instead (the quotients
 * would cancel: dg's rounding grows as 1 / (d1 - d0)^2): g = F + F' h / 2 + F'' h^2 / 6,
 * dg = F' / 2 + F'' h / 3 with h = d1 - d0 and F = k d^n. */
static void contact_gradient(const double *p, double d0, double d1, double *g, double *dg) {
    double f0, f1, v0 = contact_energy(p, d0, &f0), v1 = contact_energy(p, d1, &f1);
    double span = d1 - d0, n = p[VSJ_C_EXPONENT];
    if (d0 > 0.0 && d1 > 0.0 && fabs(span) <= 1e-3 * d0) {
        double f1d = n * f0 / d0, f2d = (n - 1.0) * f1d / d0; /* F', F'' at d0 */
        *g = f0 + 0.5 * f1d * span + f2d * span * span / 6.0;
        *dg = 0.5 * f1d + f2d * span / 3.0;
        return;
    }
    if (span == 0.0) { /* apart, or on the surface, and not moving */
        *g = f0;
        *dg = 0.0;
        return;
    }
    *g = (v1 - v0) / span;
    *dg = (f1 - *g) / span;
}

/* A contact's damping coefficient lambda d^n at penetration d (0 apart). */
static double contact_damping(const double *p, double d) {
    double n = p[VSJ_C_EXPONENT];
    if (!(d > 0.0))
        return 0.0;
    return p[VSJ_C_DAMPING] * (n == 1.0 ? d : pow(d, n));
}

VSJ_ALWAYS_INLINE void assemble_friction(const vsj_model *m, vsj_work *w, double hs, int64_t n) {
    ts_work *t = &w->ts;
    int64_t i, e, ld, r_load = m->n_frictions + m->n_springs;
    memcpy(t->s0, t->slip, (size_t)m->n_frictions * sizeof(double));
    for (i = 0; i < t->n_damper; i++) {
        e = t->damper[i];
        vsj__xadd(m, e, t->r, -hs * (1.0 - t->theta[e]) * vsj__row(m, e)[0] * t->s0[e]);
    }
    for (i = 0; i < t->n_nonlinear; i++) {
        const double *p;
        double se, fe, dfe, cnst;
        e = t->nonlinear[i];
        p = vsj__row(m, e);
        se = t->slip[e];
        if (m->code[e] == VSJ_CONTACT) {
            /* The elastic part as the discrete gradient (V(d1) - V(d0)) / (d1 - d0): the
             * ledger books the force over the step's displacement d1 - d0 (the positions
             * move by the trapezoidal rule), so the contact's work is exactly its stored
             * energy's change, on the steps that touch or leave the surface too. d1 is
             * d1p + hs (s1 - s0) / 2 about the prediction d1p = d0 + hs s0, linearised
             * there. The damping part at the mid-step penetration and rate (s0 + s1) / 2,
             * the trapezoidal rule's, as a damper's. */
            double d0 = contact_depth(m, t, e), d1p = d0 + hs * se, g, dg, c;
            contact_gradient(p, d0, d1p, &g, &dg);
            c = contact_damping(p, 0.5 * (d0 + d1p));
            dfe = 0.5 * hs * dg + 0.5 * c;
            fe = g - 0.5 * hs * dg * se + 0.5 * c * se; /* the force is fe + dfe s1 */
            if (!(g + c * se > 0.0)) /* the predicted force would pull: none, as the law */
                fe = dfe = 0.0;     /* says (it never pulls) */
            t->f0[e] = fe + dfe * se;                    /* f0 + df0 (s1 - s0) */
            t->df0[e] = dfe;
            cnst = fe + dfe * vsj__udotv(m, e, t->u1);
            vsj__xadd(m, e, t->r, -hs * cnst);
            outer(m, e, t->H, hs * dfe, n);
            continue;
        }
        fe = vsj__friction(m->code[e], p[0],
                           vsj__varying(m, e) ? p[1] * vsj__normal(m, w, e, se, 0) : p[1],
                           p[2], p[3], se, &dfe);
        t->f0[e] = fe;
        t->df0[e] = dfe;
        cnst = fe - dfe * se + dfe * vsj__udotv(m, e, t->u1);
        vsj__xadd(m, e, t->r, -hs * cnst);
        outer(m, e, t->H, hs * dfe, n);
    }
    for (ld = 0; ld < m->n_loads; ld++)
        vsj__xadd(m, r_load + ld, t->r, hs * t->ldm[ld]);
}

/* The motors' torque impulse k Q, with Q the step's charge (armature_steps) at the
 * mid-step rotor speed (om0 + om1)/2, om1 = d.v1 + (source part at u1): linear in v1,
 * so it joins the step matrix as a damping k^2 gain / 2. */
VSJ_ALWAYS_INLINE void assemble_motors(const vsj_model *m, ts_work *t, double hs, double h,
                                       int64_t n) {
    int64_t mo, rr, r_mot = m->n_frictions + m->n_springs + m->n_loads;
    armature_steps(m, t, hs, h);
    for (mo = 0; mo < m->n_motors; mo++) {
        double kt, gain, om0, cnst;
        rr = r_mot + mo;
        kt = vsj__row(m, rr)[2];
        gain = t->rl_gain[mo];
        om0 = vsj__xdot(m, rr, t->v) + vsj__udotv(m, rr, t->u0);
        t->om0[mo] = om0;
        cnst = kt * (gain * (t->vm[mo] - 0.5 * kt * (om0 + vsj__udotv(m, rr, t->u1)))
                     + t->cur[mo] * t->rl_decay[mo]);
        vsj__xadd(m, rr, t->r, cnst);
        outer(m, rr, t->H, 0.5 * kt * kt * gain, n);
    }
}

/* H v1 = r: inertia, springs (trapezoidal), smooth friction, loads, motors. */
VSJ_ALWAYS_INLINE void assemble_step(const vsj_model *m, vsj_work *w, double hs, double h,
                                     int64_t n) {
    assemble_inertia(m, &w->ts, hs, n);
    assemble_springs(m, w, hs, n);
    assemble_friction(m, w, hs, n);
    assemble_motors(m, &w->ts, hs, h, n);
}

/* The speeds without Coulomb impulses, vfree = H^-1 r, and the impulse problem's rows
 * YlT = L^-1 D^T. H changes only with non-linear springs, smooth friction slopes or a
 * moving pivot; while it stays within round-off of the matrix last factored, that
 * factor and YlT are reused. On a call's first step (t->first, vsj__ts_begin) they
 * are reused only for the very same matrix, to the bit, so that a call's steps do
 * not depend on the calls before it. VSJ_NOT_FINITE if H is not positive definite. */
VSJ_ALWAYS_INLINE int factor_step(ts_work *t, double hs, double h, int64_t n) {
    int64_t na = t->na, mt = na + t->nc, i, c;
    double scale_h = 0.0;
    int same = t->factored, fresh = 0, first = t->first;
    if (first) {
        same = same && memcmp(t->H, t->H_last, (size_t)(n * n) * sizeof(double)) == 0;
        t->first = 0;
    } else {
        for (i = 0; i < n * n; i++)
            scale_h = vsj__dmax(scale_h, fabs(t->H_last[i]));
        for (i = 0; i < n * n; i++)
            same = same && fabs(t->H[i] - t->H_last[i]) <= H_REUSE * scale_h;
    }
    if (n > 0 && !same) {
        memcpy(t->H_last, t->H, (size_t)(n * n) * sizeof(double));
        if (!vsj__cholesky(t->H, t->Lc, n, n, 0)) {
            t->factored = 0; /* Lc is half written: no step, now or on a retry, uses it */
            return VSJ_NOT_FINITE;
        }
        vsj__forward_block(t->Lc, t->DxA, t->YlT, mt, mt, n); /* L^-1 d_e: W = Y Y^T */
        forget_memo(t); /* it was made with the old YlT */
        t->factored = 1;
        fresh = 1;
    }
    if (n > 0)
        vsj__solve(t->Lc, t->r, t->vfree, n);
    /* a compliant stop of stiffness k adds 2 / (h^2 k) to the Delassus matrix's
     * diagonal: a row of its own in YlT, so that W = Y Y^T still */
    /* step lengths t1 - tnow differ by round-off from step to step: only a
     * real change (the last, shortened step) rewrites the rows and drops the
     * solver's memo; with a fresh factor (whose rows they join), and on a call's
     * first step, they follow the step's length to the bit */
    if (t->ncomp > 0
        && (fresh || first ? hs != t->hs_prev : !(fabs(hs - t->hs_prev) <= STEP_SAME * h))) {
        memset(t->YlT + mt * n, 0, (size_t)(t->ncomp * mt) * sizeof(double));
        for (c = 0; c < t->nc; c++)
            if (t->ccomp[c] >= 0)
                t->YlT[mt * (n + t->ccomp[c]) + na + c] = sqrt(2.0 / (hs * hs * t->ckstop[c]));
        forget_memo(t);
        t->hs_prev = hs;
    }
    return VSJ_OK;
}

/* The impulse problem's free slips qv and bounds: the friction groups' Coulomb
 * impulses, and each end stop's bound on its end speed. A stop is in the problem if
 * the free motion would pass it, or it pushed last step; the others are checked
 * after the solve. */
VSJ_ALWAYS_INLINE void impulse_bounds(const vsj_model *m, ts_work *t, double hs, int64_t n) {
    int64_t na = t->na, mt = na + t->nc, a, c;
    for (a = 0; a < na; a++) {
        t->lo[a] = -hs * t->level[a];
        t->hi[a] = hs * t->level[a];
    }
    element_slips(t->DxA, t->DuA, mt, mt, t->vfree, n, t->u1, m->n_sources, t->qv);
    for (c = 0; c < t->nc; c++) { /* cb: stop_speeds */
        a = na + c;
        t->qv[a] -= t->cb[c];
        t->lo[a] = 0.0;
        t->hi[a] = INFINITY;
        t->involved[a] = t->qv[a] > 0.0 || t->p[a] > 0.0;
    }
}

/* End stops left out of the problem that its impulses drove into their stop: put in.
 * Returns whether any was. */
VSJ_ALWAYS_INLINE int stops_reached(ts_work *t, int64_t n) {
    int64_t na = t->na, mt = na + t->nc, a, c, i;
    int added = 0;
    for (c = 0; c < t->nc; c++) {
        double slip;
        a = na + c;
        if (t->involved[a])
            continue;
        slip = t->qv[a];
        for (i = 0; i < n; i++)
            slip -= t->YlT[mt * i + a] * t->z[i];
        if (slip > 0.0) {
            t->involved[a] = 1;
            added = 1;
        }
    }
    return added;
}

/* A group that slipped at the step's start and comes to rest or turns within it meets
 * its static level there (MSL's peak): its bounds become that level. Returns whether
 * any group's did. */
VSJ_ALWAYS_INLINE int peaks_met(ts_work *t, double hs, int64_t n) {
    int64_t na = t->na, mt = na + t->nc, a, i;
    int added = 0;
    for (a = 0; a < na; a++) {
        double s0 = t->slip[t->lead[a]], s1 = t->qv[a];
        if (!(t->hold[a] > t->level[a]) || fabs(s0) <= STUCK_SPEED)
            continue;
        for (i = 0; i < n; i++)
            s1 -= t->YlT[mt * i + a] * t->z[i];
        if (fabs(s1) <= STUCK_SPEED || (s1 > 0.0) != (s0 > 0.0)) {
            t->lo[a] = -hs * t->hold[a];
            t->hi[a] = hs * t->hold[a];
            added = 1;
        }
    }
    return added;
}

/* The end speeds v1: vfree less what the Coulomb impulses of the stiction elements and
 * the end stops' impulses, decided all together, take. The problem is solved again
 * while the solution drives an end stop left out into its stop (at most once per
 * stop) and, once, with the static levels of groups that come to rest. */
VSJ_ALWAYS_INLINE int impulse_step(const vsj_model *m, vsj_work *w, double hs, int64_t n) {
    ts_work *t = &w->ts;
    impulses im;
    int64_t na = t->na, c, i, pass, iterations;
    if (na + t->nc == 0) {
        memcpy(t->v1, t->vfree, (size_t)n * sizeof(double));
        return VSJ_OK;
    }
    impulse_bounds(m, t, hs, n);
    for (pass = 0;; pass++) {
        int added, full = 0;
        for (c = 0; c < t->nc; c++)
            full = full || t->involved[na + c];
        use_problem(w, &im, full);
        if (!vsj__solve_impulses(&im, t->qv, t->lo, t->hi, t->p, t->state, t->involved,
                                 &iterations))
            return VSJ_FRICTION_SOLVER;
        added = stops_reached(t, n);
        if (pass == 0)
            added = peaks_met(t, hs, n) || added;
        if (!added || pass > t->nc)
            break;
    }
    /* the impulses change the speeds by H^-1 D^T p = L^-T (YlT p) */
    vsj__backward(t->Lc, t->z, t->v1, n, n);
    for (i = 0; i < n; i++)
        t->v1[i] = t->vfree[i] - t->v1[i];
    return VSJ_OK;
}

/* The step's end: positions by the trapezoidal rule, and the motors' armature
 * currents, charge and Joule heat over the step (armature_steps) with the mid-step
 * back-EMF. */
VSJ_ALWAYS_INLINE void step_end(const vsj_model *m, ts_work *t, double hs, int64_t n) {
    int64_t i, mo, rr, r_mot = m->n_frictions + m->n_springs + m->n_loads;
    for (i = 0; i < n; i++)
        t->x1[i] = t->x[i] + 0.5 * hs * (t->v[i] + t->v1[i]);
    for (mo = 0; mo < m->n_motors; mo++) {
        const double *p;
        double R, kt, emf, i_inf, c;
        rr = r_mot + mo;
        p = vsj__row(m, rr);
        R = p[0];
        kt = p[2];
        emf = t->vm[mo] - 0.5 * kt * (t->om0[mo] + vsj__xdot(m, rr, t->v1)
                                       + vsj__udotv(m, rr, t->u1));
        i_inf = emf / R;
        c = t->cur[mo] - i_inf;
        t->i1[mo] = i_inf + c * t->rl_e[mo];
        t->charge[mo] = t->rl_gain[mo] * emf + t->cur[mo] * t->rl_decay[mo];
        t->heat[mo] = R * (i_inf * i_inf * t->rl_h + 2.0 * i_inf * c * t->rl_decay[mo]
                           + c * c * t->rl_half[mo]);
    }
}

/* The elements' slips at the step's end and, where `forces` (the ledger and the
 * samples want them), each friction element's torque as the step took it: its smooth
 * part plus its share of the group's Coulomb impulse (a driven element: its level
 * against its slip). */
VSJ_ALWAYS_INLINE void element_forces(const vsj_model *m, ts_work *t, double hs, int forces,
                                      int64_t n) {
    int64_t e, nf = m->n_frictions;
    element_slips(t->DxT, t->DuT, nf + m->n_springs, nf, t->v1, n, t->u1, m->n_sources, t->slip);
    if (forces) {
        double inv_hs = 1.0 / hs;
        for (e = 0; e < nf; e++) {
            double s1 = t->slip[e], fe;
            fe = t->linear[e] ? vsj__row(m, e)[0]
                                    * (t->theta[e] * s1 + (1.0 - t->theta[e]) * t->s0[e])
                              : t->f0[e] + t->df0[e] * (s1 - t->s0[e]);
            if (t->active[e])
                fe += t->share[e] * t->p[t->slot[e]] * inv_hs;
            else if (t->driven[e] && s1 != 0.0)
                fe += t->lev[e] * (s1 > 0.0 ? 1.0 : -1.0);
            t->force[e] = fe;
        }
    }
}

/* The pivot position at the step's end, where the ledger or the call's last step
 * wants it (a pivot held still costs no sine); else the start's. */
static double pivot_end(const vsj_model *m, vsj_work *w, int wanted) {
    ts_work *t = &w->ts;
    double q_end = t->q_prev;
    if (wanted && vsj__row(m, m->n_rows - 1)[2] > 0.0) {
        double angle_end = vsj__pivot_angle(m, w, t->x1);
        if (angle_end != t->angle_prev)
            q_end = vsj__pivot_at(m, w, angle_end);
        t->angle_prev = angle_end;
    }
    return q_end;
}

static void exchange(double **a, double **b) {
    double *c = *a;
    *a = *b;
    *b = c;
}

/* The step's end becomes the start of the next: state, time (on the grid origin +
 * k h, or off it after a shortened step), pivot, and the stick phases counted. */
static void advance_state(const vsj_model *m, vsj_work *w, double t1, int on_grid,
                          double q_end) {
    ts_work *t = &w->ts;
    int64_t i, e;
    /* the end's arrays trade places with the start's (each step writes all of its
     * end's afresh) */
    exchange(&t->x, &t->x1);
    exchange(&t->v, &t->v1);
    exchange(&t->cur, &t->i1);
    exchange(&t->u0, &t->u1);
    exchange(&t->sg0, &t->sg1);
    t->t = t1;
    if (on_grid) {
        t->k++;
    } else { /* off the grid: the next call's grid starts here */
        t->origin = t1;
        t->k = 0;
    }
    t->q_prev = q_end;
    for (i = 0; i < t->n_watched; i++) {
        e = t->watched[i];
        if (holding(m, w, e)) {
            t->held[e]++;
            if (t->held[e] == 2)
                t->transitions[e]++;
        } else {
            if (t->held[e] >= 2)
                t->transitions[e]++;
            t->held[e] = 0;
        }
    }
}

/* The state into y (angles, speeds, currents); 0 if an angle or speed is not finite
 * (the currents are then left). */
static int put_state(const vsj_model *m, const ts_work *t, double *y) {
    int64_t i, mo, n = m->n;
    int finite_ = 1;
    for (i = 0; i < n; i++) {
        y[i] = t->x[i];
        y[n + i] = t->v[i];
        finite_ = finite_ && isfinite(t->x[i]) && isfinite(t->v[i]);
    }
    if (!finite_)
        return 0;
    for (mo = 0; mo < m->n_motors; mo++)
        y[2 * n + mo] = t->cur[mo];
    return 1;
}

/* One step from tnow to t1 of a model with n free coordinates, the ledger booked
 * into acc (NULL: none); `forces`: the elements' torques are wanted (the ledger's,
 * or a sample's), `last`: the call's last step. Returns the status. */
VSJ_ALWAYS_INLINE int step_sized(const vsj_model *m, vsj_work *w, double tnow, double t1,
                                 double h, int on_grid, int last, double *acc, int forces,
                                 int64_t n) {
    ts_work *t = &w->ts;
    double hs = t1 - tnow, q_end;
    int status;
    step_inputs(m, w, tnow, t1, hs, n);
    assemble_step(m, w, hs, h, n);
    status = factor_step(t, hs, h, n);
    if (status == VSJ_OK)
        status = impulse_step(m, w, hs, n);
    if (status != VSJ_OK)
        return status;
    step_end(m, t, hs, n);
    element_forces(m, t, hs, forces || acc, n);
    q_end = pivot_end(m, w, acc || last); /* at t1, for the ledger */
    if (acc)
        vsj__ts_book(m, t, acc, hs, q_end);
    advance_state(m, w, t1, on_grid, q_end);
    return VSJ_OK;
}

/* One step (step_sized), compiled for two free coordinates (the wrist's two rings, when
 * its motors and pivot are driven by speed), where the loops over the coordinates
 * unroll, and for any number. */
static int one_step(const vsj_model *m, vsj_work *w, double tnow, double t1, double h,
                    int on_grid, int last, double *acc, int forces) {
    if (m->n == 2)
        return step_sized(m, w, tnow, t1, h, on_grid, last, acc, forces, 2);
    return step_sized(m, w, tnow, t1, h, on_grid, last, acc, forces, m->n);
}

/* ---- the run ----------------------------------------------------------------- */

/* The steps from t->t to t_end: steps end on the grid origin + k h (the first time
 * plus whole steps), so that a run advanced in several calls takes the very steps of
 * one advanced at once; a call whose end lies off the grid ends with one shortened
 * step. *whole receives the number on the grid. */
static int64_t count_steps(const ts_work *t, double t_end, double h, int64_t *whole) {
    double k_end = floor((t_end - t->origin) / h + 1e-9);
    *whole = (int64_t)k_end - t->k;
    if (*whole < 0)
        *whole = 0;
    return *whole + (t_end - (t->origin + k_end * h) > 1e-9 * h ? 1 : 0);
}

static void repair_history(const vsj_model *m, vsj_work *w);

vsj_report vsj__ts_advance(const vsj_model *m, vsj_work *w, double *y, double t_end, double h,
                          int64_t max_steps, int ledger, const vsj_samples *smp) {
    ts_work *t = &w->ts;
    vsj_report rep;
    int64_t n_state, n_acc, n_out, n_col, i_out = 0, steps_total, step, whole, i;
    int status = VSJ_OK;
    double t0 = t->t, tnow = t0;
    rep.status = VSJ_OK;
    rep.t = t0;
    rep.steps = 0;
    rep.rejected = 0;
    if (!vsj__ts_prepared_for(m, w) || !(h > 0.0) || !(t_end >= t0)) { /* w fits m */
        rep.status = VSJ_BAD_ARGUMENT;
        return rep;
    }
    n_state = 2 * m->n + m->n_motors;
    n_acc = ledger ? vsj_n_acc(m) : 0;
    n_out = smp ? smp->n : 0;
    n_col = smp ? (smp->out_cols < n_state + n_acc ? smp->out_cols : n_state + n_acc) : 0;
    /* at least one step (shortened) when t_end > t0; the count is compared as a
     * double first, so that an absurd one cannot overflow the conversion */
    if (!((t_end - t0) / h - 1e-9 <= (double)max_steps)) {
        rep.status = VSJ_TOO_MANY_STEPS;
        return rep;
    }
    steps_total = count_steps(t, t_end, h, &whole);
    if (w->status != VSJ_OK) {
        status = w->status;
        steps_total = 0;
    } else if (steps_total > max_steps) {
        status = VSJ_TOO_MANY_STEPS;
        steps_total = 0;
    }
    while (i_out < n_out && smp->t[i_out] <= t0) {
        sample(m, w, smp, i_out, y, n_col);
        i_out++;
    }
    for (step = 0; step < steps_total; step++) {
        double t1 = step < whole ? t->origin + (double)(t->k + 1) * h : t_end;
        /* the elements' torques are wanted by the ledger and at the samples only */
        int sample_now = i_out < n_out && smp->t[i_out] <= t1 + 0.5 * h;
        status = one_step(m, w, tnow, t1, h, step < whole, step == steps_total - 1,
                          ledger ? y + n_state : NULL, sample_now);
        if (status != VSJ_OK)
            break;
        tnow = t1;
        rep.steps = step + 1;
        if (w->status != VSJ_OK) {
            status = w->status;
            break;
        }
        if (!put_state(m, t, y)) {
            status = VSJ_NOT_FINITE;
            break;
        }
        if (w->ctl_on && tnow >= w->ctl_next - 0.5 * h) /* on the grid (vsj_begin) */
            vsj__control_sample(m, w, tnow, y);
        while (i_out < n_out && smp->t[i_out] <= tnow + 0.5 * h) {
            sample(m, w, smp, i_out, y, n_col);
            i_out++;
        }
    }
    if (status == VSJ_OK && ledger) /* the energy accumulators too */
        for (i = n_state; i < n_state + n_acc; i++)
            if (!isfinite(y[i]))
                status = VSJ_NOT_FINITE;
    if (status != VSJ_OK)
        repair_history(m, w);
    rep.status = status;
    rep.t = tnow;
    return rep;
}

void vsj_ts_transitions(const vsj_work *w, int64_t *transitions) {
    memcpy(transitions, w->ts.transitions, (size_t)w->f * sizeof(int64_t));
}

int64_t vsj_ts_stuck(const vsj_model *m, const vsj_work *w, unsigned char *stuck) {
    int64_t e, count = 0;
    for (e = 0; e < m->n_frictions; e++) {
        int held = (w->ts.active[e] || w->ts.driven[e]) && holding(m, w, e);
        if (stuck)
            stuck[e] = (unsigned char)held;
        count += held;
    }
    return count;
}

/* ---- the history, as bytes --------------------------------------------------- */

/* What a part of the history holds, for checking bytes from outside (an FMU state):
 * reals that are finite, reals that may also be NaN (none yet: the last step's length
 * and pivot angle, as clear_history leaves them), whole numbers from 0,
 * flags (-1, 0 or 1), a status (enum vsj_status) and impulse states (-1, 0, 1, 2). */
enum { REALS, MARKER, COUNTS, FLAG, STATUS, STATES };

#define MAX_SPANS 32 /* the parts of the history (history_spans) */

typedef struct span {
    void *data;
    size_t bytes;
    int kind;
    const char *name;
} span;

/* The parts of the history, in order; with w NULL only their sizes. */
static int64_t history_spans(const vsj_model *m, const vsj_work *w, span *out) {
    const ts_work *t = w ? &w->ts : NULL;
    int64_t n = m->n, f = m->n_frictions, s = m->n_sources, nm = m->n_motors, count = 0;
    int64_t nr = n + 2 * m->n_springs, mu = f + 2 * m->n_springs;
    size_t d = sizeof(double), l = sizeof(int64_t), i = sizeof(int);
#define SPAN(ptr, size, what)                                                                     \
    do {                                                                                          \
        out[count].data = t ? (void *)(ptr) : NULL;                                               \
        out[count].bytes = (size);                                                                \
        out[count].kind = (what);                                                                 \
        out[count].name = #ptr;                                                                   \
        count++;                                                                                  \
    } while (0)
    SPAN(t->x, (size_t)n * d, REALS);
    SPAN(t->v, (size_t)n * d, REALS);
    SPAN(t->cur, (size_t)nm * d, REALS);
    SPAN(t->u0, (size_t)s * d, REALS);
    SPAN(t->sg0, (size_t)s * d, REALS);
    SPAN(&t->t, d, REALS);
    SPAN(&t->origin, d, REALS);
    SPAN(&t->k, l, COUNTS);
    SPAN(&t->q_prev, d, REALS);
    SPAN(&t->angle_prev, d, MARKER);
    SPAN(&t->angle_mid, d, REALS);
    SPAN(&t->q_mid, d, REALS);
    SPAN(&t->factored, i, FLAG);
    SPAN(&w->status, i, STATUS);
    SPAN(&t->hs_prev, d, MARKER);
    SPAN(&t->memo_full, i, FLAG);
    SPAN(t->H_last, (size_t)(n * n) * d, REALS);
    SPAN(t->Lc, (size_t)(n * n) * d, REALS);
    SPAN(t->YlT, (size_t)(nr * mu) * d, REALS);
    SPAN(t->Gc, (size_t)(nr * nr) * d, REALS);
    SPAN(t->Lk, (size_t)(nr * nr) * d, REALS);
    SPAN(t->p, (size_t)mu * d, REALS);
    SPAN(t->state, (size_t)mu * l, STATES);
    SPAN(t->memo, (size_t)(mu + 1) * d, REALS);
    SPAN(t->slip, (size_t)f * d, REALS);
    SPAN(t->lev, (size_t)f * d, REALS);
    SPAN(t->levs, (size_t)f * d, REALS);
    SPAN(t->share, (size_t)f * d, REALS);
    SPAN(t->level, (size_t)f * d, REALS);
    SPAN(t->hold, (size_t)f * d, REALS);
    SPAN(t->held, (size_t)f * l, COUNTS);
    SPAN(t->transitions, (size_t)f * l, COUNTS);
#undef SPAN
    return count;
}

/* After a failed call: a history that holds numbers no step can start from (the failed
 * step's non-finite ones) made one vsj_ts_save can save and vsj_ts_restore take back. The
 * next call sets the positions, speeds, inputs and slips anew from its state, so those
 * are zeroed; the factor, the impulses and their memo, which it would reuse, are
 * forgotten. A history of finite numbers is left as it is. */
static void repair_history(const vsj_model *m, vsj_work *w) {
    span spans[MAX_SPANS];
    int64_t count = history_spans(m, w, spans), i;
    int repaired = 0;
    size_t k;
    for (i = 0; i < count; i++) {
        double *x = (double *)spans[i].data;
        if (spans[i].kind != REALS && spans[i].kind != MARKER)
            continue;
        for (k = 0; k < spans[i].bytes / sizeof(double); k++)
            if (!isfinite(x[k]) && !(spans[i].kind == MARKER && isnan(x[k]))) {
                x[k] = 0.0;
                repaired = 1;
            }
    }
    if (repaired)
        forget_numbers(m, &w->ts);
}

/* Whether one value of a part of kind `kind` at `at` is one the stepper can hold. */
static int plausible(int kind, const unsigned char *at) {
    double x;
    int64_t c;
    int flag;
    if (kind == REALS || kind == MARKER) {
        memcpy(&x, at, sizeof x);
        return isfinite(x) || (kind == MARKER && isnan(x));
    }
    if (kind == COUNTS || kind == STATES) {
        memcpy(&c, at, sizeof c);
        /* counts stay below 2^53: they count steps, and far from overflowing */
        return kind == COUNTS ? c >= 0 && c <= ((int64_t)1 << 53) : c >= -1 && c <= 2;
    }
    memcpy(&flag, at, sizeof flag);
    return kind == FLAG ? flag >= -1 && flag <= 1 : flag >= VSJ_OK && flag <= VSJ_NO_MEMORY;
}

int vsj_ts_history_check(const vsj_model *m, const unsigned char *buffer, char *message,
                         size_t size) {
    span spans[MAX_SPANS];
    int64_t count = history_spans(m, NULL, spans), i;
    for (i = 0; i < count; i++) {
        size_t item = spans[i].kind == REALS || spans[i].kind == MARKER ? sizeof(double)
                      : spans[i].kind == COUNTS || spans[i].kind == STATES ? sizeof(int64_t)
                                                                          : sizeof(int);
        size_t k;
        for (k = 0; k < spans[i].bytes / item; k++)
            if (!plausible(spans[i].kind, buffer + k * item)) {
                if (message && size)
                    snprintf(message, size, "entry %lld of the time-stepper's %s is not a "
                             "value it can hold", (long long)k, strrchr(spans[i].name, '>') + 1);
                return VSJ_BAD_ARGUMENT;
            }
        buffer += spans[i].bytes;
    }
    return VSJ_OK;
}


size_t vsj_ts_history_size(const vsj_model *m) {
    span spans[MAX_SPANS];
    int64_t count = history_spans(m, NULL, spans), i;
    size_t total = 0;
    for (i = 0; i < count; i++)
        total += spans[i].bytes;
    return total;
}

void vsj_ts_save(const vsj_model *m, const vsj_work *w, unsigned char *buffer) {
    span spans[MAX_SPANS];
    int64_t count = history_spans(m, w, spans), i;
    for (i = 0; i < count; i++) {
        memcpy(buffer, spans[i].data, spans[i].bytes);
        buffer += spans[i].bytes;
    }
}

void vsj_ts_restore(const vsj_model *m, vsj_work *w, const unsigned char *buffer) {
    span spans[MAX_SPANS];
    int64_t count = history_spans(m, w, spans), i;
    for (i = 0; i < count; i++) {
        memcpy(spans[i].data, buffer, spans[i].bytes);
        buffer += spans[i].bytes;
    }
}
