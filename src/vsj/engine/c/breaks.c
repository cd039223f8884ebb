/* Where the inputs have corners: the knots at which a channel's spline jumps in
 * value or slope (ramps and tables, the start and end of its pieces). A jump of the
 * curvature alone is no corner: the splines that follow smooth signals (Hermite
 * cubics through a sine) have small ones at every knot. Nor is the wrap of a
 * repeating channel, whose period is a smooth signal's: its small jump is the
 * spline's end condition, and a step may straddle it as it did before.
 *
 * A velocity source whose speed has a corner has a jump in its acceleration, which
 * the mass matrix passes to the state's derivatives: a step that straddles it is
 * only first order there, and at a tight tolerance the error control shrinks the
 * step to round-off. So the adaptive steps (dopri.c, rosenbrock.c) end on these
 * knots rather than straddle them (vsj__step_length).
 */
#include <math.h>

#include "internal.h"

/* relative size of a jump that makes a corner: the splines' continuity conditions
 * are solved to round-off (~1e-13 of the values), a corner jumps by order one */
#define CORNER 1e-8

/* Whether a and b (the left and right values of one derivative, times tau^k) differ
 * by a corner's jump against the scale s of the piece. */
static int jumps(double a, double b, double s) { return fabs(a - b) > CORNER * s; }

/* Whether channel c's spline has a corner (a jump of its value or slope) at its
 * interior knot j (between pieces j-1 and j; 1 <= j < count). */
static int corner(const vsj_model *m, int64_t c, int64_t j) {
    int64_t p = m->first[c] + j, koff = m->first[c] + c;
    const double *a = m->coef + 4 * (p - 1), *b = m->coef + 4 * p;
    double tau = m->knots[koff + j] - m->knots[koff + j - 1];
    double v = a[0] + tau * (a[1] + tau * (a[2] + tau * a[3]));
    double d1 = a[1] + tau * (2.0 * a[2] + 3.0 * a[3] * tau);
    double s = fabs(v) + fabs(d1 * tau) + fabs(b[0]) + fabs(b[1] * tau);
    return s > 0.0 && (jumps(v, b[0], s) || jumps(d1 * tau, b[1] * tau, s));
}

/* Whether the spline of channel c has a slope at its first knot (it is constant
 * before) or, with `end`, at its last (constant after). */
static int moving(const vsj_model *m, int64_t c, int end) {
    int64_t n = m->count[c], koff = m->first[c] + c;
    const double *a = m->coef + 4 * (m->first[c] + (end ? n - 1 : 0));
    double tau = end ? m->knots[koff + n] - m->knots[koff + n - 1] : 0.0;
    double span = m->knots[koff + n] - m->knots[koff];
    double d1 = a[1] + tau * (2.0 * a[2] + 3.0 * a[3] * tau);
    double v = a[0] + tau * (a[1] + tau * (a[2] + tau * a[3]));
    double s = fabs(v) + fabs(d1 * span);
    return s > 0.0 && fabs(d1 * span) > CORNER * s;
}

/* The first break of channel c after t (by more than `margin`), INFINITY if none. */
static double channel_break(const vsj_model *m, int64_t c, double t, double margin) {
    int64_t n = m->count[c], koff = m->first[c] + c, lo, hi;
    double t0 = m->knots[koff], t_last = m->knots[koff + n], period = m->period[2 * c];
    double shift = 0.0;
    if (period > 0.0 && t >= t_last - margin) { /* fold into the last period */
        double turns = floor((t + margin - t_last) / period) + 1.0;
        shift = turns * period;
        t = vsj__dmax(t - shift, t_last - period);
    }
    if (t < t0 - margin && moving(m, c, 0))
        return t0 + shift;
    /* the first knot after t + margin: knots[koff + lo], 1 <= lo <= n */
    lo = 1;
    hi = n;
    while (lo < hi) {
        int64_t mid = lo + (hi - lo) / 2;
        if (m->knots[koff + mid] > t + margin)
            hi = mid;
        else
            lo = mid + 1;
    }
    for (; lo < n; lo++)
        if (corner(m, c, lo))
            return m->knots[koff + lo] + shift;
    if (t_last > t + margin && period == 0.0 && moving(m, c, 1))
        return t_last + shift;
    return INFINITY;
}

double vsj__next_break(const vsj_model *m, vsj_work *w, double t) {
    double best = INFINITY, margin = 1e-12 * vsj__dmax(1.0, fabs(t));
    int64_t c;
    if (w->ctl_on) /* the controller's next sample */
        best = w->ctl_next;
    if (w->held) /* held inputs have no corners */
        return best;
    for (c = 0; c < m->n_channels; c++) {
        if (!(w->brk[c] > t + margin)) /* passed (or never found): look again */
            w->brk[c] = channel_break(m, c, t, margin);
        best = vsj__dmin(best, w->brk[c]);
    }
    return best;
}

void vsj__breaks_reset(const vsj_model *m, vsj_work *w) {
    int64_t c;
    for (c = 0; c < m->n_channels; c++)
        w->brk[c] = -INFINITY;
}

double vsj__step_length(const vsj_model *m, vsj_work *w, const dopri_state *d, int *end,
                        double *t_land) {
    double h = d->h, t_break = vsj__next_break(m, w, d->t);
    *end = 0;
    *t_land = d->t + h;
    if (d->t + h >= d->t_end) {
        h = d->t_end - d->t;
        *end = 1;
        *t_land = d->t_end;
    }
    if (t_break <= *t_land) { /* landing on it from the left: as if cut short */
        h = t_break - d->t;
        *end = 2;
        *t_land = t_break;
    }
    return h;
}
