/* The time-stepper's energy ledger: each step's work and losses added to the
 * accumulators (vsj_n_acc, in the order vsj.h gives).
 *
 * Every force is booked against the speed the scheme moves with over the step,
 * the mid-step speed (v0 + v1)/2, so that the ledger closes up to the springs'
 * linearisation: the friction elements' torques (their smooth parts as the step
 * took them, plus their share of the Coulomb impulse), the springs' trapezoidal
 * torque, the end stops' impulses, the loads' mid-step torques, and the motors'
 * supply V Q and Joule heat R int i^2, exact over the step. What the sources
 * supply is the rest: the torque each must apply (srcF, summed from every
 * element on it) plus the change of its coupling momentum. The timestep.c scheme
 * fills the step's quantities (ts_work) before the booking.
 */
#include <math.h>

#include "internal.h"

/* Offsets of the accumulators' groups (counts in vsj.h's order). */
typedef struct offsets {
    int64_t src, load, elec, fric, res, spr, piv, stop;
} offsets;

static offsets offsets_of(const vsj_model *m) {
    offsets a;
    a.src = 0;
    a.load = a.src + m->n_sources;
    a.elec = a.load + m->n_loads;
    a.fric = a.elec + m->n_motors;
    a.res = a.fric + m->n_frictions;
    a.spr = a.res + m->n_motors;
    a.piv = a.spr + m->n_springs;
    a.stop = a.piv + m->n_springs;
    return a;
}

/* The energy of spring row rr at deflection d and pivot position q (its end stop's
 * included). */
static double spring_energy(const vsj_model *m, int64_t rr, double d, double q) {
    double stiff, energy, dvdq;
    vsj__spring(m->code[rr], vsj__row(m, rr), d, q, &stiff, &energy, &dvdq, NULL, 1);
    return energy;
}

/* Friction: each element's torque (t->force) over its mid-step slip. */
static void book_friction(const vsj_model *m, ts_work *t, double *acc, const offsets *a,
                          double hs) {
    int64_t e;
    for (e = 0; e < m->n_frictions; e++) {
        double fe = t->force[e];
        acc[a->fric + e] += hs * fe * 0.5 * (t->s0[e] + t->slip[e]);
        vsj__uaddv(m, e, t->srcF, -fe);
    }
}

/* Springs: the step's torque (at the mid-step pivot q_mid) over the deflection's
 * change; a pivot that moved (q_prev to q_end) changes their energy by the rest,
 * V(d1, q_end) - V(d1, q_mid) + V(d0, q_mid) - V(d0, q_prev), so that the two add up
 * to V(d1, q_end) - V(d0, q_prev) where the torque is exact at q_mid. */
static void book_springs(const vsj_model *m, ts_work *t, double *acc, const offsets *a,
                         double hs, double q_end) {
    int64_t k, rr, nf = m->n_frictions;
    for (k = 0; k < m->n_springs; k++) {
        double tau_avg, dd;
        rr = nf + k;
        tau_avg = t->sp_c[k] - 0.25 * t->sp_kap[k] * hs * vsj__xdot(m, rr, t->v1);
        dd = (vsj__xdot(m, rr, t->x1) - vsj__xdot(m, rr, t->x)
              + vsj__udotv(m, rr, t->sg1) - vsj__udotv(m, rr, t->sg0));
        acc[a->spr + k] += tau_avg * dd;
        vsj__uaddv(m, rr, t->srcF, tau_avg);
        if (q_end != t->q_prev) {
            double d1 = vsj__xdot(m, rr, t->x1) + vsj__udotv(m, rr, t->sg1);
            double d0 = vsj__xdot(m, rr, t->x) + vsj__udotv(m, rr, t->sg0);
            acc[a->piv + k] += spring_energy(m, rr, d1, q_end) - spring_energy(m, rr, d1, t->q_mid)
                               + spring_energy(m, rr, d0, t->q_mid)
                               - spring_energy(m, rr, d0, t->q_prev);
        }
    }
}

/* End stops: the work their impulses take from the mechanism (booked against the
 * mid-step speed, as every force), less the change of the energy a compliant stop
 * stores, is what they dissipate: at impacts, and by the implicit step. */
static void book_stops(const vsj_model *m, ts_work *t, double *acc, const offsets *a,
                       double hs) {
    int64_t n = m->n, s_n = m->n_sources, nf = m->n_frictions, cols = nf + m->n_springs;
    int64_t c, k, rr, i, j;
    for (c = 0; c < t->nc; c++) {
        double side = t->csign[c], push = t->p[t->na + c], rate0 = 0.0, rate1 = 0.0;
        double work;
        k = t->cspring[c];
        rr = nf + k;
        if (push != 0.0) { /* a stop that pushed this step */
            for (i = 0; i < n; i++) {
                rate0 += t->DxT[cols * i + rr] * t->v[i];
                rate1 += t->DxT[cols * i + rr] * t->v1[i];
            }
            for (j = 0; j < s_n; j++) {
                rate0 += t->DuT[cols * j + rr] * t->u0[j];
                rate1 += t->DuT[cols * j + rr] * t->u1[j];
            }
            work = push * side * 0.5 * (rate0 + rate1);
            acc[a->stop + k] += work;
            acc[a->spr + k] -= work;
            vsj__uaddv(m, rr, t->srcF, -side * push / hs);
        }
        if (side > 0.0 && isfinite(t->ckstop[c])) { /* once per spring */
            double d0 = vsj__xdot(m, rr, t->x) + vsj__udotv(m, rr, t->sg0);
            double d1 = vsj__xdot(m, rr, t->x1) + vsj__udotv(m, rr, t->sg1);
            double e0 = vsj__dmax(fabs(d0) - t->cstop[c], 0.0);
            double e1 = vsj__dmax(fabs(d1) - t->cstop[c], 0.0);
            acc[a->stop + k] -= 0.5 * t->ckstop[c] * (e1 * e1 - e0 * e0);
        }
    }
}

/* Loads at their mid-step torque; motors exact over the step: supply V Q, heat
 * R int i^2, and the torque k Q / h on the sources. */
static void book_loads_and_motors(const vsj_model *m, ts_work *t, double *acc,
                                  const offsets *a, double hs) {
    int64_t ld, mo, rr, r_load = m->n_frictions + m->n_springs, r_mot = r_load + m->n_loads;
    for (ld = 0; ld < m->n_loads; ld++) {
        double omega;
        rr = r_load + ld;
        omega = 0.5 * (vsj__xdot(m, rr, t->v) + vsj__xdot(m, rr, t->v1));
        omega += vsj__udotv(m, rr, t->um);
        acc[a->load + ld] += hs * t->ldm[ld] * omega;
        vsj__uaddv(m, rr, t->srcF, t->ldm[ld]);
    }
    for (mo = 0; mo < m->n_motors; mo++) {
        rr = r_mot + mo;
        acc[a->elec + mo] += t->vm[mo] * t->charge[mo];
        acc[a->res + mo] += t->heat[mo];
        vsj__uaddv(m, rr, t->srcF, vsj__row(m, rr)[2] * t->charge[mo] / hs);
    }
}

/* Sources: their mid-step speed times the impulse they apply, the torque they hold
 * against (srcF) plus the change of their coupling momentum. */
static void book_sources(const vsj_model *m, const ts_work *t, double *acc, const offsets *a,
                         double hs) {
    int64_t n = m->n, s_n = m->n_sources, i, j, c;
    for (j = 0; j < s_n; j++) {
        double impulse = -hs * t->srcF[j];
        for (i = 0; i < n; i++)
            impulse += m->mass[(n + s_n) * (n + j) + i] * (t->v1[i] - t->v[i]);
        for (c = 0; c < s_n; c++)
            impulse += m->mass[(n + s_n) * (n + j) + n + c] * (t->u1[c] - t->u0[c]);
        acc[a->src + j] += t->um[j] * impulse;
    }
}

void vsj__ts_book(const vsj_model *m, ts_work *t, double *acc, double hs, double q_end) {
    offsets a = offsets_of(m);
    int64_t j;
    for (j = 0; j < m->n_sources; j++) { /* the sources' mid-step speeds; their torques
                                          * are summed below */
        t->um[j] = 0.5 * (t->u0[j] + t->u1[j]);
        t->srcF[j] = 0.0;
    }
    book_friction(m, t, acc, &a, hs);
    book_springs(m, t, acc, &a, hs, q_end);
    book_stops(m, t, acc, &a, hs);
    book_loads_and_motors(m, t, acc, &a, hs);
    book_sources(m, t, acc, &a, hs);
}
