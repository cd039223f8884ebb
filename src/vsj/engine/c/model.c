/* Checking a model, and the work a computation runs in. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

int vsj__fail(char *message, size_t size, const char *format, ...) {
    if (message && size) {
        va_list args;
        va_start(args, format);
        vsnprintf(message, size, format, args);
        va_end(args);
    }
    return VSJ_BAD_ARGUMENT;
}

static int finite_array(const double *a, int64_t len, const char *name, char *message,
                        size_t size) {
    int64_t i;
    for (i = 0; i < len; i++)
        if (!isfinite(a[i]))
            return vsj__fail(message, size, "model array %s: entry %lld is %g (not finite)", name,
                        (long long)i, a[i]);
    return VSJ_OK;
}

/* A CSR matrix: the pointers are checked whole before any column is read (the
 * columns array holds ptr[rows] entries, which only sane pointers promise). */
static int csr(const int64_t *ptr, const int64_t *col, const double *val, int64_t rows,
               int64_t cols, const char *name, char *message, size_t size) {
    int64_t r, k;
    if (ptr[0] != 0)
        return vsj__fail(message, size, "model array %sp: first pointer must be 0, got %lld", name,
                    (long long)ptr[0]);
    for (r = 0; r < rows; r++)
        if (ptr[r + 1] < ptr[r])
            return vsj__fail(message, size, "model array %sp: pointers must not decrease (row %lld)",
                        name, (long long)r);
    for (r = 0; r < rows; r++)
        for (k = ptr[r]; k < ptr[r + 1]; k++)
            if (col[k] < 0 || col[k] >= cols)
                return vsj__fail(message, size,
                            "model array %sc: column %lld of row %lld is outside 0..%lld", name,
                            (long long)col[k], (long long)r, (long long)(cols - 1));
    return finite_array(val, ptr[rows], name[0] == 'x' ? "xv" : "uv", message, size);
}

/* The kinetic energy matrix: symmetric, its free block positive definite, and Minv
 * its inverse (to round-off). */
static int mass_matrix(const vsj_model *m, char *message, size_t size) {
    int64_t n = m->n, sz = n + m->n_sources, i, j, r;
    double big = 0.0;
    for (i = 0; i < sz * sz; i++)
        big = fabs(m->mass[i]) > big ? fabs(m->mass[i]) : big;
    for (i = 0; i < sz; i++)
        for (j = 0; j < i; j++)
            if (fabs(m->mass[sz * i + j] - m->mass[sz * j + i]) > 1e-12 * big)
                return vsj__fail(message, size, "model array mass: not symmetric (entries %lld, %lld)",
                            (long long)i, (long long)j);
    for (i = 0; i < n; i++) {
        double inv_big = 0.0;
        if (!(m->mass[sz * i + i] > 0.0))
            return vsj__fail(message, size, "model array mass: diagonal entry %lld must be > 0 (a "
                        "free coordinate without inertia)", (long long)i);
        for (j = 0; j < n; j++)
            inv_big = fabs(m->Minv[n * i + j]) > inv_big ? fabs(m->Minv[n * i + j]) : inv_big;
        for (j = 0; j < n; j++) {
            double product = 0.0, scale = 0.0;
            for (r = 0; r < n; r++) {
                product += m->mass[sz * i + r] * m->Minv[n * r + j];
                scale += fabs(m->mass[sz * i + r] * m->Minv[n * r + j]);
            }
            if (fabs(product - (i == j ? 1.0 : 0.0)) > 1e-8 * (1.0 + scale))
                return vsj__fail(message, size, "model arrays mass and Minv: Minv is not the inverse "
                            "of mass's free block (row %lld, column %lld)", (long long)i,
                            (long long)j);
        }
    }
    return VSJ_OK;
}

int vsj_check_model(const vsj_model *m, char *message, size_t size) {
    int64_t n, s, f, k, nl, nm, nch, rows, sz, i, c, r;
    int status;
    if (!m)
        return vsj__fail(message, size, "no model");
    n = m->n;
    s = m->n_sources;
    f = m->n_frictions;
    k = m->n_springs;
    nl = m->n_loads;
    nm = m->n_motors;
    nch = m->n_channels;
    rows = m->n_rows;
    if (n < 0 || s < 0 || f < 0 || k < 0 || nl < 0 || nm < 0 || nch < 0 || m->n_pieces < 0)
        return vsj__fail(message, size, "model sizes must be >= 0");
    if (rows != f + k + nl + nm + 1)
        return vsj__fail(message, size,
                    "model: n_rows must be n_frictions + n_springs + n_loads + n_motors + 1 = "
                    "%lld, got %lld", (long long)(f + k + nl + nm + 1), (long long)rows);
    if (m->n_pieces < nch)
        return vsj__fail(message, size, "model: %lld spline pieces for %lld channels",
                    (long long)m->n_pieces, (long long)nch);
    if (!m->mass || !m->Minv || !m->xp || !m->xc || !m->xv || !m->up || !m->uc || !m->uv
        || !m->par || !m->code || !m->src_ch || !m->src_pos0 || !m->knots || !m->coef
        || !m->cum || !m->first || !m->count)
        return vsj__fail(message, size, "model: an array pointer is NULL");
    sz = n + s;
    if ((status = finite_array(m->mass, sz * sz, "mass", message, size)) != VSJ_OK)
        return status;
    if ((status = finite_array(m->Minv, n * n, "Minv", message, size)) != VSJ_OK)
        return status;
    if ((status = mass_matrix(m, message, size)) != VSJ_OK)
        return status;
    if ((status = csr(m->xp, m->xc, m->xv, rows, n, "x", message, size)) != VSJ_OK)
        return status;
    if ((status = csr(m->up, m->uc, m->uv, rows, s, "u", message, size)) != VSJ_OK)
        return status;
    /* parameters: finite, except the pivot range, which may be unbounded */
    for (r = 0; r < rows; r++)
        for (c = 0; c < VSJ_NPAR; c++) {
            double v = m->par[VSJ_NPAR * r + c];
            /* unbounded: the pivot's range; a rigid end stop (infinite stiffness) */
            int range = r == rows - 1 && (c == 3 || c == 4);
            int law = r >= f && r < f + k ? (int)m->code[r] : -1;
            int rigid = v == INFINITY && ((law == VSJ_EXPONENTIAL && c == 4)
                                          || ((law == VSJ_GEOMETRIC
                                               || law == VSJ_GEOMETRIC_REPORT) && c == 8));
            if (rigid)
                continue;
            if (range ? isnan(v) : !isfinite(v))
                return vsj__fail(message, size, "model array par: row %lld column %lld is %g",
                            (long long)r, (long long)c, v);
        }
    if (m->n_table < 0 || (m->n_table > 0 && !m->table))
        return vsj__fail(message, size, "model: the friction table is missing");
    if ((status = finite_array(m->table, 2 * m->n_table, "table", message, size)) != VSJ_OK)
        return status;
    for (r = 0; r < f; r++) {
        const double *p = m->par + VSJ_NPAR * r;
        double first = p[VSJ_F_TABLE], count = p[VSJ_F_ROWS], ch = p[VSJ_F_CHANNEL];
        if (m->code[r] < VSJ_VISCOUS || m->code[r] >= VSJ_N_FRICTION_LAWS)
            return vsj__fail(message, size, "model: friction row %lld has unknown law %lld",
                        (long long)r, (long long)m->code[r]);
        if (m->code[r] == VSJ_CONTACT
            && (!(p[VSJ_C_DAMPING] >= 0.0) || !(p[VSJ_C_STIFFNESS] >= 0.0)
                || !(p[VSJ_C_EXPONENT] >= 1.0) || p[VSJ_F_PEAK] != 1.0 || ch != -1.0
                || count != 0.0))
            return vsj__fail(message, size, "model: contact row %lld: needs damping >= 0, "
                             "stiffness >= 0, exponent >= 1, peak 1, no channel and no table",
                             (long long)r);
        if (m->code[r] == VSJ_SLOPE && !(p[VSJ_F_WIDTH] > 0.0))
            return vsj__fail(message, size, "model: friction row %lld: slope width must be > 0",
                        (long long)r);
        if (!(p[VSJ_F_PEAK] >= 1.0))
            return vsj__fail(message, size, "model: friction row %lld: peak must be >= 1, got %g",
                        (long long)r, p[VSJ_F_PEAK]);
        if (p[VSJ_F_TRAPEZOIDAL] != 0.0 && p[VSJ_F_TRAPEZOIDAL] != 1.0)
            return vsj__fail(message, size, "model: friction row %lld: the trapezoidal flag must be "
                        "0 or 1, got %g", (long long)r, p[VSJ_F_TRAPEZOIDAL]);
        if (ch != floor(ch) || ch < -1.0 || ch >= (double)nch)
            return vsj__fail(message, size, "model: friction row %lld reads input channel %g of "
                        "%lld", (long long)r, ch, (long long)nch);
        if (first != floor(first) || count != floor(count) || first < 0.0 || count < 0.0
            || count > (double)m->n_table || first > (double)m->n_table - count)
            return vsj__fail(message, size, "model: friction row %lld: table rows %g..%g outside "
                        "0..%lld", (long long)r, first, first + count - 1,
                        (long long)(m->n_table - 1));
        for (i = (int64_t)first; i < (int64_t)(first + count); i++) {
            const double *row = m->table + 2 * i;
            if (row[0] < 0.0 || row[1] < 0.0 || (i > (int64_t)first && !(row[0] > row[-2])))
                return vsj__fail(message, size, "model: friction row %lld: its table needs speeds "
                            ">= 0 that increase and coefficients >= 0 (table row %lld)",
                            (long long)r, (long long)i);
        }
    }
    for (r = f; r < f + k; r++)
        if (m->code[r] < VSJ_LINEAR || m->code[r] >= VSJ_N_SPRING_LAWS)
            return vsj__fail(message, size, "model: spring row %lld has unknown law %lld",
                        (long long)r, (long long)m->code[r]);
    for (r = f + k; r < f + k + nl + nm; r++)
        if (m->code[r] < 0 || m->code[r] >= nch)
            return vsj__fail(message, size, "model: row %lld reads input channel %lld of %lld",
                        (long long)r, (long long)m->code[r], (long long)nch);
    for (r = f + k + nl; r < f + k + nl + nm; r++)
        if (!(m->par[VSJ_NPAR * r + 1] > 0.0))
            return vsj__fail(message, size, "model: motor row %lld: inductance must be > 0",
                        (long long)r);
    for (i = 0; i < s; i++)
        if (m->src_ch[i] < 0 || m->src_ch[i] >= nch)
            return vsj__fail(message, size, "model: source %lld reads input channel %lld of %lld",
                        (long long)i, (long long)m->src_ch[i], (long long)nch);
    if ((status = finite_array(m->src_pos0, s, "src_pos0", message, size)) != VSJ_OK)
        return status;
    if ((status = finite_array(m->coef, 4 * m->n_pieces, "coef", message, size)) != VSJ_OK)
        return status;
    if ((status = finite_array(m->knots, m->n_pieces + nch, "knots", message, size)) != VSJ_OK)
        return status;
    if ((status = finite_array(m->cum, m->n_pieces + nch, "cum", message, size)) != VSJ_OK)
        return status;
    for (c = 0; c < nch; c++) {
        int64_t p0 = m->first[c], cnt = m->count[c], j;
        if (cnt < 1 || p0 < 0 || cnt > m->n_pieces || p0 > m->n_pieces - cnt)
            return vsj__fail(message, size,
                        "model: channel %lld has %lld pieces from piece %lld, outside 0..%lld",
                        (long long)c, (long long)cnt, (long long)p0,
                        (long long)(m->n_pieces - 1));
        for (j = 0; j < cnt; j++)
            if (!(m->knots[p0 + c + j + 1] > m->knots[p0 + c + j]))
                return vsj__fail(message, size, "model: knots of channel %lld must increase",
                            (long long)c);
    }
    return vsj__control_check(m, message, size);
}

/* ---- the work -------------------------------------------------------------- */

/* Under AddressSanitizer, a poisoned gap follows every array carved out of the
 * work's block, so that an overrun into the next array is reported. */
#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/asan_interface.h>
#define GUARD 32u
#else
#define GUARD 0u
#endif

/* Carves arrays out of one block: first with base NULL to size it, then for real. */
typedef struct carver {
    unsigned char *base;
    size_t used;
} carver;

static void *carve(carver *cv, int64_t count, size_t item) {
    size_t bytes = (size_t)(count > 0 ? count : 1) * item;
    void *p;
    cv->used = (cv->used + 31u) & ~(size_t)31u;
    p = cv->base ? cv->base + cv->used : NULL;
    cv->used += bytes;
#if defined(__SANITIZE_ADDRESS__)
    if (cv->base) {
        size_t end = (cv->used + 7u) & ~(size_t)7u;
        ASAN_POISON_MEMORY_REGION(cv->base + end, GUARD);
    }
#endif
    cv->used += GUARD;
    return p;
}

#define DOUBLES(n) ((double *)carve(cv, (n), sizeof(double)))
#define INTS(n) ((int64_t *)carve(cv, (n), sizeof(int64_t)))
#define BYTES(n) ((unsigned char *)carve(cv, (n), 1))

static void layout(vsj_work *w, carver *cv) {
    int64_t n = w->n, s = w->s, f = w->f, k = w->k, nl = w->nl, nm = w->nm, nch = w->nch;
    int64_t nr = n + 2 * k, mu = f + 2 * k; /* the impulse problem's rows and unknowns */
    int64_t ns = 2 * n + nm;                /* the state */
    ts_work *t = &w->ts;
    w->hint = INTS(nch);
    w->chan = DOUBLES(3 * nch);
    w->chan_dd = DOUBLES(nch);
    w->brk = DOUBLES(nch);
    w->srcw = DOUBLES(SRCW * s);
    w->frw = DOUBLES(FRW * f);
    w->ev_list = INTS(f);
    w->ev_same = INTS(f);
    w->ev_share = INTS(f);
    w->ev_arc[0] = INTS(f);
    w->ev_arc[1] = INTS(f);
    w->ev_oth[0] = INTS(f);
    w->ev_oth[1] = INTS(f);
    w->ev_vary = BYTES(f);
    w->ev_const = BYTES(nch);
    w->ev_atan = DOUBLES(f);
    w->spw = DOUBLES(SPW * k);
    w->ldw = DOUBLES(2 * nl);
    w->mow = DOUBLES(2 * nm);
    w->gen = DOUBLES(n);
    w->spcache = DOUBLES(4 * k);
    w->pos0 = DOUBLES(s);
    w->K = DOUBLES(VSJ_K_ROWS * w->ny_max);
    w->yt = DOUBLES(w->ny_max);
    w->y1 = DOUBLES(w->ny_max);
    w->err = DOUBLES(w->ny_max);
    w->r3 = DOUBLES(w->ny_max);
    w->r4 = DOUBLES(w->ny_max);
    w->r5 = DOUBLES(w->ny_max);
    w->y = DOUBLES(w->ny_max);
    w->yo = DOUBLES(w->ny_max);
    w->dy = DOUBLES(w->ny_max);
    w->sy = DOUBLES(w->ny_max);
    w->sk = DOUBLES(w->ny_max);
    w->sacc = DOUBLES(w->ny_max);
    w->jac = DOUBLES(ns * ns);
    w->lu = DOUBLES(ns * ns);
    w->ft = DOUBLES(ns);
    w->jg = DOUBLES(n * (ns + 1));
    w->jacc = DOUBLES((w->ny_max - ns) * (ns + 1));
    w->jac_new = DOUBLES(ns * ns);
    w->ft_new = DOUBLES(ns);
    w->jacc_new = DOUBLES((w->ny_max - ns) * (ns + 1));
    w->jsrc = DOUBLES(s * (ns + 1));
    w->piv = INTS(ns);
    t->H = DOUBLES(n * n);
    t->H_last = DOUBLES(n * n);
    t->Lc = DOUBLES(n * n);
    t->Bx = DOUBLES(n * n);
    t->G = DOUBLES(nr * nr);
    t->Lg = DOUBLES(nr * nr);
    t->Gc = DOUBLES(nr * nr);
    t->Lk = DOUBLES(nr * nr);
    t->x = DOUBLES(n);
    t->v = DOUBLES(n);
    t->r = DOUBLES(n);
    t->vfree = DOUBLES(n);
    t->v1 = DOUBLES(n);
    t->x1 = DOUBLES(n);
    t->col = DOUBLES(n);
    t->drow = DOUBLES(n);
    t->tv = DOUBLES(nr);
    t->cv = DOUBLES(nr);
    t->z = DOUBLES(nr);
    t->Bu = DOUBLES(n * s);
    t->DxT = DOUBLES(n * (f + k));
    t->DuT = DOUBLES(s * (f + k));
    t->DxA = DOUBLES(n * mu);
    t->DuA = DOUBLES(s * mu);
    t->YlT = DOUBLES(nr * mu);
    t->qv = DOUBLES(mu);
    t->lo = DOUBLES(mu);
    t->hi = DOUBLES(mu);
    t->p = DOUBLES(mu);
    t->mask = DOUBLES(mu);
    t->d = DOUBLES(mu);
    t->g = DOUBLES(mu);
    t->level = DOUBLES(f);
    t->hold = DOUBLES(f);
    t->memo = DOUBLES(mu + 1);
    t->state = INTS(mu);
    t->involved = BYTES(mu);
    t->cspring = INTS(2 * k);
    t->ccomp = INTS(2 * k);
    t->csign = DOUBLES(2 * k);
    t->cstop = DOUBLES(2 * k);
    t->ckstop = DOUBLES(2 * k);
    t->cb = DOUBLES(2 * k);
    t->has_stop = BYTES(k);
    t->slip = DOUBLES(f);
    t->s0 = DOUBLES(f);
    t->f0 = DOUBLES(f);
    t->df0 = DOUBLES(f);
    t->force = DOUBLES(f);
    t->share = DOUBLES(f);
    t->ratio = DOUBLES(f);
    t->lev = DOUBLES(f);
    t->levs = DOUBLES(f);
    t->theta = DOUBLES(f);
    t->damper = INTS(f);
    t->held = INTS(f);
    t->slot = INTS(f);
    t->lead = INTS(f);
    t->transitions = INTS(f);
    t->nonlinear = INTS(f);
    t->watched = INTS(f);
    t->active = BYTES(f);
    t->driven = BYTES(f);
    t->linear = BYTES(f);
    t->sp_c = DOUBLES(k);
    t->sp_kap = DOUBLES(k);
    t->u0 = DOUBLES(s);
    t->sg0 = DOUBLES(s);
    t->u1 = DOUBLES(s);
    t->sg1 = DOUBLES(s);
    t->um = DOUBLES(s);
    t->srcF = DOUBLES(s);
    t->ldm = DOUBLES(nl);
    t->vm = DOUBLES(nm);
    t->cur = DOUBLES(nm);
    t->i1 = DOUBLES(nm);
    t->rl_e = DOUBLES(nm);
    t->rl_decay = DOUBLES(nm);
    t->rl_gain = DOUBLES(nm);
    t->rl_half = DOUBLES(nm);
    t->om0 = DOUBLES(nm);
    t->charge = DOUBLES(nm);
    t->heat = DOUBLES(nm);
    w->ctl_bus = DOUBLES(w->nbus);
    w->ctl_x = DOUBLES(w->ncs);
    w->ctl_x1 = DOUBLES(w->ncs);
    w->ctl_in = DOUBLES(w->nbi); /* a block's inputs: at most all blocks' input rows */
    w->ctl_delay = DOUBLES(w->ndel);
    w->ctl_u = DOUBLES(w->nact);
    w->ctl_before = DOUBLES(w->nbus + w->nact);
    w->ctl_drive = INTS(nch);
    t->mid_ch = INTS(nch);
    t->mid_src = INTS(s);
    t->end_ch = INTS(nch);
    t->wanted = BYTES(nch);
}

vsj_work *vsj_work_new(const vsj_model *m) {
    vsj_work *w;
    carver cv = {NULL, 0};
    if (!m || m->n < 0 || m->n_sources < 0 || m->n_frictions < 0 || m->n_springs < 0
        || m->n_loads < 0 || m->n_motors < 0 || m->n_channels < 0 || m->n_refs < 0
        || m->n_meas < 0 || m->n_blocks < 0 || m->n_acts < 0 || m->n_bus < 0 || m->n_cstate < 0
        || m->n_delay < 0 || m->n_blk_in < 0)
        return NULL;
    w = (vsj_work *)calloc(1, sizeof(vsj_work));
    if (!w)
        return NULL;
    w->n = m->n;
    w->s = m->n_sources;
    w->f = m->n_frictions;
    w->k = m->n_springs;
    w->nl = m->n_loads;
    w->nm = m->n_motors;
    w->nch = m->n_channels;
    w->rows = m->n_rows;
    w->nref = m->n_refs;
    w->nmeas = m->n_meas;
    w->nblk = m->n_blocks;
    w->nact = m->n_acts;
    w->nbus = m->n_bus;
    w->ncs = m->n_cstate;
    w->ndel = m->n_delay;
    w->nbi = m->n_blk_in;
    w->ny_max = vsj_n_state(m) + vsj_n_acc(m) + m->n_sources;
    layout(w, &cv);
    w->block = calloc(1, cv.used + 32u);
    if (!w->block) {
        free(w);
        return NULL;
    }
    cv.base = (unsigned char *)w->block;
    cv.base += (32u - ((size_t)cv.base & 31u)) & 31u;
    cv.used = 0;
    layout(w, &cv);
    {
        /* caches start empty: NaN equals nothing */
        int64_t i;
        for (i = 0; i < 4 * w->k; i++)
            w->spcache[i] = NAN;
        for (i = 0; i < 4; i++)
            w->pivot_key[i] = NAN;
    }
    return w;
}

void vsj_work_free(vsj_work *w) {
    if (!w)
        return;
#if defined(__SANITIZE_ADDRESS__)
    {
        carver cv = {NULL, 0};
        layout(w, &cv); /* the block's size */
        ASAN_UNPOISON_MEMORY_REGION(w->block, cv.used + 32u);
    }
#endif
    free(w->block);
    free(w);
}
