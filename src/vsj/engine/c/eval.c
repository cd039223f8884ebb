/* Evaluation of a model: inputs, element forces, accelerations, energies.
 *
 * Equations of motion (vsj.network): with flange speeds A v + B u and the
 * kinetic energy matrix [[M, Msu], [Mus, Mss]] over (v, u),
 *
 *     M a = sum over elements of A^T torque - Msu du/dt
 *     tau_sources = Mus a + Mss du/dt - sum over elements of B^T torque
 *
 * where tau_sources is the torque each velocity source supplies.
 */
#include <math.h>
#include <string.h>

#include "internal.h"

const char *vsj_status_text(int status) {
    switch (status) {
    case VSJ_OK: return "ok";
    case VSJ_NOT_FINITE: return "the state or a force became non-finite";
    case VSJ_PIVOT_RANGE: return "the pivot position left its allowed range";
    case VSJ_TOO_MANY_STEPS: return "the solver reached its maximum number of steps";
    case VSJ_STEP_TOO_SMALL:
        return "the step size fell below the round-off limit (stiff or discontinuous "
               "dynamics; try the time-stepping solver)";
    case VSJ_FRICTION_SOLVER: return "the stiction solver did not converge";
    case VSJ_BAD_ARGUMENT: return "an argument is out of range";
    case VSJ_NO_MEMORY: return "out of memory";
    default: return "unknown status";
    }
}

int64_t vsj_n_state(const vsj_model *m) { return 2 * m->n + m->n_motors; }

int64_t vsj_n_acc(const vsj_model *m) {
    return m->n_sources + m->n_loads + 2 * m->n_motors + m->n_frictions + 3 * m->n_springs;
}

/* Pivot position and, with `rates`, its rate; y holds the angles and then the speeds
 * (offset n). */
static double eval_pivot(const vsj_model *m, vsj_work *w, const double *y, int rates) {
    int64_t r = m->n_rows - 1;
    const double *p = vsj__row(m, r);
    double angle = vsj__pivot_angle(m, w, y);
    double q;
    /* a pivot held still (the usual case) costs no sine and cosine */
    if (angle == w->pivot_key[0] && p[0] == w->pivot_key[1] && p[1] == w->pivot_key[2]
        && p[2] == w->pivot_key[3]) {
        q = w->pivot_q;
        w->q = q;
        if ((q < p[3] - 1e-12 || q > p[4] + 1e-12) && w->status < VSJ_PIVOT_RANGE)
            w->status = VSJ_PIVOT_RANGE;
    } else {
        q = vsj__pivot_at(m, w, angle);
        w->pivot_key[0] = angle;
        w->pivot_key[1] = p[0];
        w->pivot_key[2] = p[1];
        w->pivot_key[3] = p[2];
        w->pivot_q = q;
        w->pivot_cos = cos(angle);
    }
    if (rates)
        w->qdot = p[2] * p[0] * w->pivot_cos
                  * (vsj__xdot(m, r, y + m->n) + vsj__udot(m, r, w->srcw, U));
    return q;
}

int vsj__rigid_stop(const vsj_model *m) {
    int64_t kk;
    for (kk = 0; kk < m->n_springs; kk++) {
        int64_t r = m->n_frictions + kk;
        double angle, stiffness;
        if (vsj__stop(m->code[r], vsj__row(m, r), &angle, &stiffness) && isinf(stiffness))
            return 1;
    }
    return 0;
}

/* ---- forces ----------------------------------------------------------------- */

/* The springs' deflections, torques, stiffnesses and energies at y and, with `rates`
 * (which only the energy ledger and the observations read), their rates of deflection
 * and the pivot's rate. */
static void eval_springs(const vsj_model *m, vsj_work *w, const double *y, int rates) {
    double q = eval_pivot(m, w, y, rates);
    int64_t kk, f = m->n_frictions, n = m->n;
    for (kk = 0; kk < m->n_springs; kk++) {
        int64_t r = f + kk;
        double *sp = w->spw + SPW * kk;
        double d = vsj__xdot(m, r, y) + vsj__udot(m, r, w->srcw, SG);
        double stiff, energy, dvq;
        double tau = vsj__spring(m->code[r], vsj__row(m, r), d, q, &stiff, &energy, &dvq,
                                 w->spcache + 4 * kk, 1);
        sp[DEFL] = d;
        if (rates)
            sp[RATE] = vsj__xdot(m, r, y + n) + vsj__udot(m, r, w->srcw, U);
        sp[SPTAU] = tau;
        sp[STIFF] = stiff;
        sp[ENERGY] = energy;
        sp[DVDQ] = dvq;
    }
}

/* Whether friction rows a and b have the same slip: the same entries in the same order
 * (so that the same sums give the same bits). */
static int same_row(const vsj_model *m, int64_t a, int64_t b) {
    int64_t i, na = m->xp[a + 1] - m->xp[a], ua = m->up[a + 1] - m->up[a];
    if (na != m->xp[b + 1] - m->xp[b] || ua != m->up[b + 1] - m->up[b])
        return 0;
    for (i = 0; i < na; i++)
        if (m->xc[m->xp[a] + i] != m->xc[m->xp[b] + i] || m->xv[m->xp[a] + i] != m->xv[m->xp[b] + i])
            return 0;
    for (i = 0; i < ua; i++)
        if (m->uc[m->up[a] + i] != m->uc[m->up[b] + i] || m->uv[m->up[a] + i] != m->uv[m->up[b] + i])
            return 0;
    return 1;
}

/* Whether element e's torque is the plain arctangent law b s + k atan(kb s): a
 * constant level, no extra torque. */
static int plain_arctan(const vsj_model *m, const vsj_work *w, int64_t e) {
    return m->code[e] == VSJ_ARCTAN && !w->ev_vary[e];
}

void vsj__eval_prepare(const vsj_model *m, vsj_work *w) {
    int64_t e, j, c, pass, f = m->n_frictions;
    w->ev_nd = 0;
    for (e = 0; e < f; e++) {
        int64_t first;
        if (m->xp[e + 1] > m->xp[e])
            w->ev_list[w->ev_nd++] = e;
        w->ev_same[e] = -1;
        for (j = 0; j < e && w->ev_same[e] < 0; j++)
            if (w->ev_same[j] < 0 && same_row(m, e, j))
                w->ev_same[e] = j;
        w->ev_vary[e] = (unsigned char)vsj__varying(m, e);
        first = w->ev_same[e];
        w->ev_share[e] = plain_arctan(m, w, e) && first >= 0 && m->code[first] == VSJ_ARCTAN
                                 && vsj__row(m, first)[2] == vsj__row(m, e)[2]
                             ? first
                             : -1;
    }
    for (pass = 0; pass < 2; pass++) {
        int64_t i, count = pass ? f : w->ev_nd;
        w->ev_narc[pass] = w->ev_noth[pass] = 0;
        for (i = 0; i < count; i++) {
            e = pass ? i : w->ev_list[i];
            if (plain_arctan(m, w, e))
                w->ev_arc[pass][w->ev_narc[pass]++] = e;
            else
                w->ev_oth[pass][w->ev_noth[pass]++] = e;
        }
    }
    for (c = 0; c < m->n_channels; c++) {
        const double *cf = m->coef + 4 * m->first[c];
        w->ev_const[c] = m->count[c] == 1 && !(m->period[2 * c] > 0.0) && cf[1] == 0.0
                         && cf[2] == 0.0 && cf[3] == 0.0;
    }
    w->ev_model = m;
}

/* The friction elements' slips and torques at y, into frw (SLIP, TORQUE), for pass
 * `full` (vsj__eval_prepare: 0 the elements the dynamics feel, 1 all). A row's later
 * elements take its first's slip and, for the same arctangent, its arctangent: the
 * elements that do not share theirs come first, the plain arctangents last, in a loop
 * of their own. */
static void eval_frictions(const vsj_model *m, vsj_work *w, const double *y, int full) {
    int64_t n = m->n, i, e, first;
    int64_t count = full ? m->n_frictions : w->ev_nd, narc = w->ev_narc[full];
    const int64_t *arc = w->ev_arc[full], *oth = w->ev_oth[full];
    double *frw = w->frw;
    for (i = 0; i < count; i++) {
        e = full ? i : w->ev_list[i];
        first = w->ev_same[e];
        frw[w->f * SLIP + e] = first >= 0 ? frw[w->f * SLIP + first]
                                          : vsj__xdot(m, e, y + n) + vsj__udot(m, e, w->srcw, U);
    }
    for (i = 0; i < w->ev_noth[full]; i++) {
        const double *p;
        double slip, torque, level;
        e = oth[i];
        p = vsj__row(m, e);
        slip = frw[w->f * SLIP + e];
        level = w->ev_vary[e] ? p[1] * vsj__normal(m, w, e, slip, 0) : p[1];
        if (m->code[e] == VSJ_ARCTAN) { /* vsj__friction's arctan law */
            w->ev_atan[e] = vsj__atan(p[2] * slip);
            torque = p[0] * slip + level * w->ev_atan[e];
        } else if (m->code[e] == VSJ_CONTACT)
            torque = vsj__contact(p, vsj__penetration(m, w, e, y), slip,
                                  &frw[w->f * DSLIP + e], &frw[w->f * DPOS + e]);
        else
            torque = vsj__friction(m->code[e], p[0], level, p[2], p[3], slip, NULL);
        if (m->code[e] == VSJ_STICTION)
            torque += frw[w->f * EXTRA + e];
        frw[w->f * TORQUE + e] = torque;
    }
    for (i = 0; i < narc; i++) { /* vsj__friction's arctan law, at its constant level */
        const double *p;
        double slip, atan_;
        e = arc[i];
        p = vsj__row(m, e);
        slip = frw[w->f * SLIP + e];
        first = w->ev_share[e];
        atan_ = first >= 0 ? w->ev_atan[first] : vsj__atan(p[2] * slip);
        w->ev_atan[e] = atan_;
        frw[w->f * TORQUE + e] = p[0] * slip + p[1] * atan_;
    }
}

/* All element torques at y, as generalised forces in w->gen and, with `full`,
 * as source forces in srcw[:, SRCF]. Without `full`, elements that only the
 * sources feel are skipped (the dynamics do not need them). */
static void eval_forces(const vsj_model *m, vsj_work *w, const double *y, int full) {
    int64_t n = m->n, s = m->n_sources, f = m->n_frictions, k = m->n_springs;
    int64_t nl = m->n_loads, i, j, kk, e, ld, mo, count;
    for (i = 0; i < n; i++)
        w->gen[i] = 0.0;
    for (j = 0; j < s; j++)
        w->srcw[SRCW * j + SRCF] = 0.0;
    eval_springs(m, w, y, full);
    for (kk = 0; kk < k; kk++) {
        int64_t r = f + kk;
        double tau = w->spw[SPW * kk + SPTAU];
        vsj__xadd(m, r, w->gen, tau);
        if (full)
            vsj__uadd(m, r, w->srcw, SRCF, tau);
    }
    eval_frictions(m, w, y, full);
    count = full ? f : w->ev_nd;
    /* the torques' sums apart from the laws: each sum is one chain of additions
     * through memory, which the laws' evaluations would otherwise wait on */
    for (i = 0; i < count; i++) {
        e = full ? i : w->ev_list[i];
        vsj__xadd(m, e, w->gen, -w->frw[w->f * TORQUE + e]);
        if (full)
            vsj__uadd(m, e, w->srcw, SRCF, -w->frw[w->f * TORQUE + e]);
    }
    for (ld = 0; ld < nl; ld++) {
        int64_t r = f + k + ld;
        double tau = w->chan[3 * m->code[r]];
        w->ldw[2 * ld] = tau;
        if (full) /* the load's speed, for the ledger */
            w->ldw[2 * ld + 1] = vsj__xdot(m, r, y + n) + vsj__udot(m, r, w->srcw, U);
        vsj__xadd(m, r, w->gen, tau);
        if (full)
            vsj__uadd(m, r, w->srcw, SRCF, tau);
    }
    for (mo = 0; mo < m->n_motors; mo++) {
        int64_t r = f + k + nl + mo;
        double torque = vsj__row(m, r)[2] * y[2 * n + mo];
        w->mow[2 * mo] = vsj__xdot(m, r, y + n) + vsj__udot(m, r, w->srcw, U);
        w->mow[2 * mo + 1] = w->chan[3 * m->code[r]];
        vsj__xadd(m, r, w->gen, torque);
        if (full)
            vsj__uadd(m, r, w->srcw, SRCF, torque);
    }
}

void vsj__eval_derivatives(const vsj_model *m, vsj_work *w, double t, const double *y,
                           int64_t ny, double *dy) {
    int64_t n = m->n, s = m->n_sources, nm = m->n_motors, i, j, r, mo, e, kk, ld, p;
    int64_t sz = n + s;
    int64_t base_m = m->n_frictions + m->n_springs + m->n_loads;
    int full = ny > 2 * n + nm;
    if (w->ev_model != m)
        vsj__eval_prepare(m, w);
    vsj__eval_inputs(m, w, t);
    eval_forces(m, w, y, full);
    for (i = 0; i < n; i++)
        for (j = 0; j < s; j++)
            w->gen[i] -= m->mass[sz * i + n + j] * w->srcw[SRCW * j + UD];
    for (i = 0; i < n; i++) {
        double total = 0.0;
        for (r = 0; r < n; r++)
            total += m->Minv[n * i + r] * w->gen[r];
        dy[n + i] = total;
        dy[i] = y[n + i];
    }
    if (full) {
        for (j = 0; j < s; j++) {
            double tau = -w->srcw[SRCW * j + SRCF];
            for (i = 0; i < n; i++)
                tau += m->mass[sz * (n + j) + i] * dy[n + i];
            for (r = 0; r < s; r++)
                tau += m->mass[sz * (n + j) + n + r] * w->srcw[SRCW * r + UD];
            w->srcw[SRCW * j + SRCTAU] = tau;
        }
    }
    for (mo = 0; mo < nm; mo++) {
        const double *pr = vsj__row(m, base_m + mo);
        dy[2 * n + mo] = (w->mow[2 * mo + 1] - pr[0] * y[2 * n + mo] - pr[2] * w->mow[2 * mo])
                         / pr[1];
    }
    if (full) {
        p = 2 * n + nm;
        for (j = 0; j < s; j++)
            dy[p++] = w->srcw[SRCW * j + U] * w->srcw[SRCW * j + SRCTAU];
        for (ld = 0; ld < m->n_loads; ld++)
            dy[p++] = w->ldw[2 * ld] * w->ldw[2 * ld + 1];
        for (mo = 0; mo < nm; mo++)
            dy[p++] = w->mow[2 * mo + 1] * y[2 * n + mo];
        for (e = 0; e < m->n_frictions; e++)
            dy[p++] = w->frw[w->f * TORQUE + e] * w->frw[w->f * SLIP + e];
        for (mo = 0; mo < nm; mo++)
            dy[p++] = vsj__row(m, base_m + mo)[0] * y[2 * n + mo] * y[2 * n + mo];
        for (kk = 0; kk < m->n_springs; kk++)
            dy[p++] = w->spw[SPW * kk + SPTAU] * w->spw[SPW * kk + RATE];
        for (kk = 0; kk < m->n_springs; kk++)
            dy[p++] = w->spw[SPW * kk + DVDQ] * w->qdot;
        for (kk = 0; kk < m->n_springs; kk++)
            dy[p++] = 0.0; /* end stops: here elastic forces of the springs, no constraints */
    }
    for (i = 0; i < ny; i++)
        if (!isfinite(dy[i]))
            w->status = VSJ_NOT_FINITE;
}

int vsj_derivatives(const vsj_model *m, vsj_work *w, double t, const double *y, int64_t ny,
                    double *dy) {
    w->status = VSJ_OK;
    w->in_model = w->ev_model = NULL;
    w->ctl_on = 0; /* the inputs from their splines */
    vsj__eval_derivatives(m, w, t, y, ny, dy);
    return w->status;
}

int vsj_jacobian(const vsj_model *m, vsj_work *w, double t, const double *y, int64_t ny,
                 double *J, double *ft) {
    int64_t ns = vsj_n_state(m), na = vsj_n_acc(m), i, c;
    double *rows;
    if (!vsj__fits(m, w) || !y || !J || !ft || (ny != ns && ny != ns + na))
        return VSJ_BAD_ARGUMENT;
    w->status = VSJ_OK;
    w->in_model = w->ev_model = NULL;
    w->ctl_on = 0;
    vsj__eval_derivatives(m, w, t, y, ny, w->dy);
    vsj__eval_jacobian(m, w, J, ft);
    if (ny > ns) {
        rows = w->jacc;
        vsj__eval_ledger_rows(m, w, y, J, ft, rows);
        for (i = 0; i < na; i++) {
            for (c = 0; c < ns; c++)
                J[ns * (ns + i) + c] = rows[(ns + 1) * i + c];
            ft[ns + i] = rows[(ns + 1) * i + ns];
        }
    }
    return w->status;
}

void vsj_source_signals(const vsj_model *m, vsj_work *w, const double *t_out, int64_t n_out,
                        double *angles, double *speeds) {
    int64_t i, j, s = m->n_sources;
    w->in_model = w->ev_model = NULL;
    w->ctl_on = 0;
    for (i = 0; i < n_out; i++) {
        vsj__eval_inputs(m, w, t_out[i]);
        for (j = 0; j < s; j++) {
            angles[s * i + j] = w->srcw[SRCW * j + SG];
            speeds[s * i + j] = w->srcw[SRCW * j + U];
        }
    }
}

void vsj_stored_energy(const vsj_model *m, vsj_work *w, double t, const double *y,
                       double energy[3], double *springs) {
    int64_t n = m->n, s = m->n_sources, nm = m->n_motors, sz = n + s, i, r, kk, mo;
    int64_t base_m = m->n_frictions + m->n_springs + m->n_loads;
    double kin = 0.0, pot = 0.0, ind = 0.0;
    w->in_model = w->ev_model = NULL;
    w->ctl_on = 0;
    vsj__eval_inputs(m, w, t);
    eval_springs(m, w, y, 0);
    for (i = 0; i < sz; i++) {
        double a = i < n ? y[n + i] : w->srcw[SRCW * (i - n) + U];
        for (r = 0; r < sz; r++) {
            double b = r < n ? y[n + r] : w->srcw[SRCW * (r - n) + U];
            kin += 0.5 * a * m->mass[sz * i + r] * b;
        }
    }
    for (kk = 0; kk < m->n_springs; kk++) {
        pot += w->spw[SPW * kk + ENERGY];
        if (springs)
            springs[kk] = w->spw[SPW * kk + ENERGY];
    }
    for (mo = 0; mo < nm; mo++)
        ind += 0.5 * vsj__row(m, base_m + mo)[1] * y[2 * n + mo] * y[2 * n + mo];
    energy[0] = kin;
    energy[1] = pot;
    energy[2] = ind;
}

int64_t vsj_observation_width(const vsj_model *m) {
    int64_t n = m->n, s = m->n_sources, f = m->n_frictions, k = m->n_springs;
    return 3 * n + m->n_motors + 3 * s + 2 + 2 * f + 5 * k + s + 2 * m->n_loads
           + 2 * m->n_motors;
}

int vsj_observe(const vsj_model *m, vsj_work *w, const double *t_out, int64_t n_out,
                const double *out, int64_t ny, const double *coulomb, double *raw) {
    int64_t n = m->n, nm = m->n_motors, ns = 2 * n + nm, s = m->n_sources;
    int64_t f = m->n_frictions, k = m->n_springs, nl = m->n_loads;
    int64_t width = vsj_observation_width(m), full = ns + vsj_n_acc(m), i, j, e, kk;
    static const int src_cols[3] = {SG, U, UD};
    static const int spring_cols[5] = {DEFL, RATE, SPTAU, ENERGY, STIFF};
    int status = VSJ_OK;
    if (ny < ns + vsj_control_width(m))
        return VSJ_BAD_ARGUMENT;
    w->in_model = w->ev_model = NULL;
    w->ctl_on = 0;
    for (i = 0; i < n_out; i++) {
        const double *y = out + ny * i;
        double *row = raw + width * i;
        int64_t p = 0, c;
        if (m->n_acts > 0) /* the actuators' values that held at the sample */
            vsj__control_hold(m, w, y + ny - m->n_acts);
        for (e = 0; e < f; e++)
            w->frw[w->f * EXTRA + e] = coulomb ? coulomb[f * i + e] : 0.0;
        /* evaluated at full length (source torques and every element), which
         * reads the state part of y only */
        w->status = VSJ_OK;
        vsj__eval_derivatives(m, w, t_out[i], y, full, w->dy);
        if (w->status == VSJ_NOT_FINITE)
            status = VSJ_NOT_FINITE;
        for (j = 0; j < ns; j++)
            row[p++] = y[j];
        for (j = 0; j < n; j++)
            row[p++] = w->dy[n + j];
        for (c = 0; c < 3; c++)
            for (j = 0; j < s; j++)
                row[p++] = w->srcw[SRCW * j + src_cols[c]];
        row[p++] = w->q;
        row[p++] = w->qdot;
        for (c = 0; c < 2; c++)
            for (e = 0; e < f; e++)
                row[p++] = w->frw[w->f * (c == 0 ? SLIP : TORQUE) + e];
        for (c = 0; c < 5; c++)
            for (kk = 0; kk < k; kk++)
                row[p++] = w->spw[SPW * kk + spring_cols[c]];
        for (j = 0; j < s; j++)
            row[p++] = w->srcw[SRCW * j + SRCTAU];
        for (c = 0; c < 2; c++)
            for (j = 0; j < nl; j++)
                row[p++] = w->ldw[2 * j + c];
        for (c = 0; c < 2; c++)
            for (j = 0; j < nm; j++)
                row[p++] = w->mow[2 * j + c];
    }
    return status;
}

/* ---- the Jacobian (for the Rosenbrock steps) --------------------------------- */

/* d gen / d(column col + X_r) += scale X_r X_r^T, over the n x (ns + 1) array jg. */
static void add_outer(const vsj_model *m, int64_t r, double *jg, int64_t cols, int64_t col,
                      double scale) {
    int64_t a, b;
    for (a = m->xp[r]; a < m->xp[r + 1]; a++)
        for (b = m->xp[r]; b < m->xp[r + 1]; b++)
            jg[cols * m->xc[a] + col + m->xc[b]] += scale * m->xv[a] * m->xv[b];
}

/* row[col + X_r] += scale X_r */
static void add_x(const vsj_model *m, int64_t r, double *row, int64_t col, double scale) {
    int64_t a;
    for (a = m->xp[r]; a < m->xp[r + 1]; a++)
        row[col + m->xc[a]] += scale * m->xv[a];
}

/* row += scale d(angle)/d(x, t) of the pivot mechanism's angle X_p x + U_p sigma
 * (the time in column ns) */
static void add_angle(const vsj_model *m, const vsj_work *w, double *row, int64_t ns,
                      double scale) {
    int64_t rp = m->n_rows - 1;
    if (scale == 0.0)
        return;
    add_x(m, rp, row, 0, scale);
    row[ns] += scale * vsj__udot(m, rp, w->srcw, U);
}

/* The pivot's motion where the last evaluation was: w->pivot_dq = dq/d(angle) (0 for
 * a fixed pivot) and, for a moving one, each spring's derivatives of its torque and of
 * dV/dq by q, and of dV/dq by its deflection, in spw (central differences of the law
 * alone, four evaluations of it, steps of cbrt(eps) of the scale). Every term they
 * enter is a multiple of the pivot angle's rate or of its derivative in the state, so
 * a pivot angle that depends on no state and stands still now (a pivot motor held)
 * needs none of them. */
static void pivot_motion(const vsj_model *m, vsj_work *w) {
    int64_t kk, rp = m->n_rows - 1;
    const double *pp = vsj__row(m, rp);
    const double step = 6.0554544523933395e-06; /* cbrt(eps) */
    int still = m->xp[rp + 1] == m->xp[rp] && vsj__udot(m, rp, w->srcw, U) == 0.0;
    w->pivot_dq = pp[2] * pp[0] * w->pivot_cos;
    for (kk = 0; kk < m->n_springs; kk++) {
        int64_t r = m->n_frictions + kk;
        double *sp = w->spw + SPW * kk, phi = sp[DEFL], q = w->q, hq, hp, st, en, a, b, ta, tb;
        sp[DTQ] = sp[DVQQ] = sp[DVQP] = 0.0;
        if (w->pivot_dq == 0.0 || still)
            continue;
        hq = step * vsj__dmax(fabs(q), 1e-3);
        hp = step * vsj__dmax(fabs(phi), 1e-3);
        ta = vsj__spring(m->code[r], vsj__row(m, r), phi, q + hq, &st, &en, &a, NULL, 1);
        tb = vsj__spring(m->code[r], vsj__row(m, r), phi, q - hq, &st, &en, &b, NULL, 1);
        sp[DTQ] = (ta - tb) / (2.0 * hq);
        sp[DVQQ] = (a - b) / (2.0 * hq);
        vsj__spring(m->code[r], vsj__row(m, r), phi + hp, q, &st, &en, &a, NULL, 1);
        vsj__spring(m->code[r], vsj__row(m, r), phi - hp, q, &st, &en, &b, NULL, 1);
        sp[DVQP] = (a - b) / (2.0 * hp);
    }
}

/* Friction element e's torque's derivatives at `slip`: in the slip (returned) and, at
 * a fixed slip, in time (*rate). A contact's slope is as its evaluation left it (it
 * depends on the penetration too; no rate). The laws are linear in their level
 * k N(slip, t), so a level that varies (vsj__normal: a normal force in time, a table's
 * coefficient in the speed |slip|) adds k shape(slip) dN, where shape is the law at
 * unit level without its viscous part. */
static double friction_slope(const vsj_model *m, const vsj_work *w, int64_t e, double slip,
                             double *rate) {
    const double *p = vsj__row(m, e), *fp = m->par + e * VSJ_NPAR;
    double slope, kshape, force = 1.0, coefficient = 1.0, dforce = 0.0, dcoefficient = 0.0;
    *rate = 0.0;
    if (m->code[e] == VSJ_CONTACT)
        return w->frw[w->f * DSLIP + e];
    if (!w->ev_vary[e])
        return vsj__friction_slope(m->code[e], p[0], p[1], p[2], p[3], slip);
    if (fp[VSJ_F_CHANNEL] >= 0.0) { /* clipped to [0, 1]: no rate where clipped */
        const double *ch = w->chan + 3 * (int64_t)fp[VSJ_F_CHANNEL];
        /* on a limit, the rate counts if the input is inside on the side the evaluation
         * looks at: after the time (a ramp leaving 0 or 1), or before it with w->left (a
         * ramp arriving there, at a step's end on the ramp's corner) */
        double ahead = w->left ? -ch[1] : ch[1];
        force = ch[0] < 0.0 ? 0.0 : (ch[0] > 1.0 ? 1.0 : ch[0]);
        if ((ch[0] > 0.0 && ch[0] < 1.0) || (ch[0] == 0.0 && ahead > 0.0)
            || (ch[0] == 1.0 && ahead < 0.0))
            dforce = ch[1];
    }
    if (fp[VSJ_F_ROWS] > 0.0) { /* of |slip|: its slope's sign is the slip's */
        int64_t first = (int64_t)fp[VSJ_F_TABLE], rows = (int64_t)fp[VSJ_F_ROWS];
        coefficient = vsj__table(m, first, rows, fabs(slip));
        dcoefficient = vsj__table_slope(m, first, rows, fabs(slip)) * (slip < 0.0 ? -1.0 : 1.0);
    }
    /* force * coefficient is vsj__normal's factor for a sliding element */
    slope = vsj__friction_slope(m->code[e], p[0], p[1] * (force * coefficient), p[2], p[3],
                                slip);
    kshape = vsj__friction(m->code[e], 0.0, p[1], p[2], p[3], slip, NULL);
    *rate = kshape * dforce * coefficient;
    return slope + kshape * force * dcoefficient;
}

/* The generalised forces' derivatives in the state (x, v, motor currents) and in
 * time, into jg (n x (ns + 1), the time in the last column). */
static void force_derivatives(const vsj_model *m, vsj_work *w, double *jg) {
    int64_t n = m->n, s = m->n_sources, f = m->n_frictions, k = m->n_springs;
    int64_t nl = m->n_loads, nm = m->n_motors, ns = 2 * n + nm, cols = ns + 1, sz = n + s;
    int64_t i, j, e, kk, ld, mo;
    memset(jg, 0, (size_t)(n * cols) * sizeof(double));
    for (kk = 0; kk < k; kk++) { /* torque -stiff d, d = X x + U sigma, and its q */
        int64_t r = f + kk;
        double stiff = w->spw[SPW * kk + STIFF], dtq = w->spw[SPW * kk + DTQ];
        add_outer(m, r, jg, cols, 0, -stiff);
        for (i = m->xp[r]; i < m->xp[r + 1]; i++) {
            jg[cols * m->xc[i] + ns] -= stiff * vsj__udot(m, r, w->srcw, U) * m->xv[i];
            add_angle(m, w, jg + cols * m->xc[i], ns, m->xv[i] * dtq * w->pivot_dq);
        }
    }
    for (e = 0; e < f; e++) { /* torque -f(s), s = X v + U u; a contact's, f(s, d) */
        double slip = w->frw[w->f * SLIP + e], slope, rate;
        if (m->xp[e + 1] == m->xp[e])
            continue;
        slope = friction_slope(m, w, e, slip, &rate);
        add_outer(m, e, jg, cols, n, -slope);
        for (i = m->xp[e]; i < m->xp[e + 1]; i++) {
            jg[cols * m->xc[i] + ns] -= slope * vsj__udot(m, e, w->srcw, UD) * m->xv[i];
            if (rate != 0.0)
                jg[cols * m->xc[i] + ns] -= rate * m->xv[i];
        }
        if (m->code[e] == VSJ_CONTACT) { /* and its position: d = X x + U sigma - gap */
            double dpos = w->frw[w->f * DPOS + e];
            add_outer(m, e, jg, cols, 0, -dpos);
            for (i = m->xp[e]; i < m->xp[e + 1]; i++)
                jg[cols * m->xc[i] + ns] -= dpos * vsj__udot(m, e, w->srcw, U) * m->xv[i];
        }
    }
    for (ld = 0; ld < nl; ld++) { /* a torque input */
        int64_t r = f + k + ld;
        double rate = w->chan[3 * m->code[r] + 1];
        for (i = m->xp[r]; i < m->xp[r + 1]; i++)
            jg[cols * m->xc[i] + ns] += rate * m->xv[i];
    }
    for (mo = 0; mo < nm; mo++) { /* torque constant times current */
        int64_t r = f + k + nl + mo;
        for (i = m->xp[r]; i < m->xp[r + 1]; i++)
            jg[cols * m->xc[i] + 2 * n + mo] += vsj__row(m, r)[2] * m->xv[i];
    }
    for (i = 0; i < n; i++) /* the sources' accelerations through the mass matrix */
        for (j = 0; j < s; j++)
            jg[cols * i + ns] -= m->mass[sz * i + n + j] * w->chan_dd[m->src_ch[j]];
}

void vsj__eval_jacobian(const vsj_model *m, vsj_work *w, double *J, double *ft) {
    int64_t n = m->n, nm = m->n_motors, ns = 2 * n + nm, cols = ns + 1, i, r, c, mo;
    int64_t base_m = m->n_frictions + m->n_springs + m->n_loads;
    double *jg = w->jg;
    pivot_motion(m, w);
    force_derivatives(m, w, jg);
    memset(J, 0, (size_t)(ns * ns) * sizeof(double));
    for (i = 0; i < n; i++) {
        J[ns * i + n + i] = 1.0; /* x' = v */
        ft[i] = 0.0;
        for (c = 0; c < cols; c++) {
            double total = 0.0;
            for (r = 0; r < n; r++)
                total += m->Minv[n * i + r] * jg[cols * r + c];
            if (c < ns)
                J[ns * (n + i) + c] = total;
            else
                ft[n + i] = total;
        }
    }
    for (mo = 0; mo < nm; mo++) { /* L i' = V - R i - Ke (X v + U u) */
        const double *pr = vsj__row(m, base_m + mo);
        int64_t row = 2 * n + mo, k;
        J[ns * row + row] = -pr[0] / pr[1];
        for (k = m->xp[base_m + mo]; k < m->xp[base_m + mo + 1]; k++)
            J[ns * row + n + m->xc[k]] -= pr[2] / pr[1] * m->xv[k];
        ft[row] = (w->chan[3 * m->code[base_m + mo] + 1]
                   - pr[2] * vsj__udot(m, base_m + mo, w->srcw, UD)) / pr[1];
    }
}

/* ---- the ledger's rows of the Jacobian ------------------------------------------ */

/* The derivatives of the sources' forces (srcw[:, SRCF]) in the state and in time,
 * into dF (s x (ns + 1)): every element's torque through its source columns. */
static void source_force_derivatives(const vsj_model *m, const vsj_work *w, double *dF) {
    int64_t n = m->n, s = m->n_sources, f = m->n_frictions, k = m->n_springs;
    int64_t nl = m->n_loads, ns = 2 * n + m->n_motors, cols = ns + 1, e, kk, ld, mo, c;
    memset(dF, 0, (size_t)(s * cols) * sizeof(double));
    for (kk = 0; kk < k; kk++) { /* + tau, tau = -stiff d, and its q */
        int64_t r = f + kk;
        double stiff = w->spw[SPW * kk + STIFF], dtq = w->spw[SPW * kk + DTQ];
        for (c = m->up[r]; c < m->up[r + 1]; c++) {
            double *row = dF + cols * m->uc[c];
            add_x(m, r, row, 0, -stiff * m->uv[c]);
            row[ns] -= stiff * vsj__udot(m, r, w->srcw, U) * m->uv[c];
            add_angle(m, w, row, ns, m->uv[c] * dtq * w->pivot_dq);
        }
    }
    for (e = 0; e < f; e++) { /* - tau, tau = f(slip) */
        double slip = w->frw[w->f * SLIP + e], slope, rate;
        if (m->up[e + 1] == m->up[e])
            continue;
        slope = friction_slope(m, w, e, slip, &rate);
        for (c = m->up[e]; c < m->up[e + 1]; c++) {
            double *row = dF + cols * m->uc[c];
            add_x(m, e, row, n, -slope * m->uv[c]);
            row[ns] -= slope * vsj__udot(m, e, w->srcw, UD) * m->uv[c];
            if (rate != 0.0)
                row[ns] -= rate * m->uv[c];
            if (m->code[e] == VSJ_CONTACT) {
                double dpos = w->frw[w->f * DPOS + e];
                add_x(m, e, row, 0, -dpos * m->uv[c]);
                row[ns] -= dpos * vsj__udot(m, e, w->srcw, U) * m->uv[c];
            }
        }
    }
    for (ld = 0; ld < nl; ld++) { /* + a torque input */
        int64_t r = f + k + ld;
        for (c = m->up[r]; c < m->up[r + 1]; c++)
            dF[cols * m->uc[c] + ns] += w->chan[3 * m->code[r] + 1] * m->uv[c];
    }
    for (mo = 0; mo < m->n_motors; mo++) { /* + torque constant times current */
        int64_t r = f + k + nl + mo;
        for (c = m->up[r]; c < m->up[r + 1]; c++)
            dF[cols * m->uc[c] + 2 * n + mo] += vsj__row(m, r)[2] * m->uv[c];
    }
}

/* The rows of the pivot's work on the springs, dV/dq q', q' = dq/da (X_p v + U_p u)
 * with dq/da = A cos(angle) for a moving pivot (all zero for a fixed one). */
static void pivot_work_rows(const vsj_model *m, const vsj_work *w, const double *y,
                            double *row) {
    int64_t n = m->n, ns = 2 * n + m->n_motors, cols = ns + 1, rp = m->n_rows - 1, kk;
    const double *pp = vsj__row(m, rp);
    double rate, curvature;
    if (w->pivot_dq == 0.0)
        return;
    rate = vsj__xdot(m, rp, y + n) + vsj__udot(m, rp, w->srcw, U); /* the angle's speed */
    curvature = -pp[2] * pp[0] * sin(w->pivot_key[0]); /* d(dq/da)/da */
    for (kk = 0; kk < m->n_springs; kk++, row += cols) {
        int64_t r = m->n_frictions + kk;
        const double *sp = w->spw + SPW * kk;
        add_x(m, r, row, 0, sp[DVQP] * w->qdot);
        row[ns] += sp[DVQP] * vsj__udot(m, r, w->srcw, U) * w->qdot;
        add_angle(m, w, row, ns, sp[DVQQ] * w->pivot_dq * w->qdot + sp[DVDQ] * curvature * rate);
        add_x(m, rp, row, n, sp[DVDQ] * w->pivot_dq);
        row[ns] += sp[DVDQ] * w->pivot_dq * vsj__udot(m, rp, w->srcw, UD);
    }
}

void vsj__eval_ledger_rows(const vsj_model *m, vsj_work *w, const double *y, const double *J,
                           const double *ft, double *rows) {
    int64_t n = m->n, s = m->n_sources, f = m->n_frictions, k = m->n_springs;
    int64_t nl = m->n_loads, nm = m->n_motors, ns = 2 * n + nm, cols = ns + 1, sz = n + s;
    int64_t base_m = f + k + nl, j, i, c, r, e, kk, ld, mo;
    double *row = rows, *dF = w->jsrc;
    memset(rows, 0, (size_t)(vsj_n_acc(m) * cols) * sizeof(double));
    for (j = 0; j < s; j++, row += cols) { /* u tau_source, tau = -F + M a + M ud */
        const double *mrow = m->mass + sz * (n + j);
        double u = w->srcw[SRCW * j + U];
        if (j == 0)
            source_force_derivatives(m, w, dF);
        for (c = 0; c < cols; c++) {
            double total = -dF[cols * j + c];
            for (i = 0; i < n; i++)
                total += mrow[i] * (c < ns ? J[ns * (n + i) + c] : ft[n + i]);
            row[c] = u * total;
        }
        for (r = 0; r < s; r++)
            row[ns] += u * mrow[n + r] * w->chan_dd[m->src_ch[r]];
        row[ns] += w->srcw[SRCW * j + UD] * w->srcw[SRCW * j + SRCTAU];
    }
    for (ld = 0; ld < nl; ld++, row += cols) { /* tau omega */
        int64_t rr = f + k + ld;
        double tau = w->ldw[2 * ld];
        add_x(m, rr, row, n, tau);
        row[ns] = w->chan[3 * m->code[rr] + 1] * w->ldw[2 * ld + 1]
                  + tau * vsj__udot(m, rr, w->srcw, UD);
    }
    for (mo = 0; mo < nm; mo++, row += cols) { /* V i */
        row[2 * n + mo] = w->mow[2 * mo + 1];
        row[ns] = w->chan[3 * m->code[base_m + mo] + 1] * y[2 * n + mo];
    }
    for (e = 0; e < f; e++, row += cols) { /* tau slip */
        double slip = w->frw[w->f * SLIP + e], slope, dp, rate;
        slope = friction_slope(m, w, e, slip, &rate);
        dp = slope * slip + w->frw[w->f * TORQUE + e];
        add_x(m, e, row, n, dp);
        row[ns] = dp * vsj__udot(m, e, w->srcw, UD);
        if (rate != 0.0)
            row[ns] += rate * slip;
        if (m->code[e] == VSJ_CONTACT) { /* the force's position: slip dF/dd */
            double dpos = w->frw[w->f * DPOS + e];
            add_x(m, e, row, 0, slip * dpos);
            row[ns] += slip * dpos * vsj__udot(m, e, w->srcw, U);
        }
    }
    for (mo = 0; mo < nm; mo++, row += cols) /* R i^2 */
        row[2 * n + mo] = 2.0 * vsj__row(m, base_m + mo)[0] * y[2 * n + mo];
    for (kk = 0; kk < k; kk++, row += cols) { /* tau rate */
        int64_t rr = f + kk;
        const double *sp = w->spw + SPW * kk;
        add_x(m, rr, row, 0, -sp[STIFF] * sp[RATE]);
        add_x(m, rr, row, n, sp[SPTAU]);
        row[ns] = -sp[STIFF] * vsj__udot(m, rr, w->srcw, U) * sp[RATE]
                  + sp[SPTAU] * vsj__udot(m, rr, w->srcw, UD);
        add_angle(m, w, row, ns, sp[RATE] * sp[DTQ] * w->pivot_dq);
    }
    pivot_work_rows(m, w, y, row);
    /* the end stops' rows stay zero */
}
