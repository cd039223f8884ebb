/* The tunable parameters of vsj's FMU (see vsj_fmu.c, and fmu_setup.c for how
 * each moves the engine's arrays): what a parameter file allows them, and setting
 * them. fmi2SetReal refuses a parameter value that a parameter file refuses (its
 * bounds, and the relations between keys of vsj.params.RELATIONS: the sum of
 * weight times value, in order, > 0 if strict, else >= 0).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmu_internal.h"

/* Why parameter p may not take x, as vsj.params.Spec.check says it (NULL: it may). */
const char *fmu__refusal(const parameter *p, double x, char *why, size_t size) {
    const char *space = p->unit[0] ? " " : "";
    if (!isfinite(x))
        snprintf(why, size, "must be finite");
    else if ((p->flags & MIN_EXCLUDED) && !(x > p->min))
        snprintf(why, size, "must be > %.6g%s%s", p->min, space, p->unit);
    else if (!(p->flags & MIN_EXCLUDED) && !(x >= p->min))
        snprintf(why, size, "must be >= %.6g%s%s", p->min, space, p->unit);
    else if (!(x <= p->max))
        snprintf(why, size, "must be <= %.6g%s%s", p->max, space, p->unit);
    else if ((p->flags & ZERO_EXCLUDED) && x == 0.0)
        snprintf(why, size, "must be nonzero");
    else
        return NULL;
    return why;
}

/* The first relation between keys that `values` break, or -1. */
int64_t fmu__broken_relation(const fmu *f, const double *values) {
    int64_t r, k;
    for (r = 0; r < f->n_relations; r++) {
        const relation *rel = f->relations + r;
        double margin = 0.0;
        for (k = 0; k < rel->count; k++) {
            const term *e = f->terms + rel->first + k;
            margin += e->weight * (e->parameter < 0 ? e->value : values[e->parameter]);
        }
        if (rel->strict ? !(margin > 0.0) : !(margin >= 0.0))
            return r;
    }
    return -1;
}

/* Why q0 [m] is not a pivot position the current parameters allow (NULL: it is). */
const char *fmu__bad_q0(const fmu *f, double q0, char *why, size_t size) {
    const double *p = pivot_row(f);
    if (q0 >= p[3] && q0 <= p[4])
        return NULL;
    snprintf(why, size, "pivot_q0 = %g m is outside the pivot's range [%g, %g] m", q0, p[3], p[4]);
    return why;
}

/* What relation r says, with the values of the parameters it involves. */
static void relation_text(const fmu *f, int64_t r, char *text, size_t size) {
    const relation *rel = f->relations + r;
    size_t used;
    int64_t k;
    snprintf(text, size, "%s (", rel->text);
    for (k = 0; k < rel->count; k++) {
        const term *e = f->terms + rel->first + k;
        used = strlen(text);
        snprintf(text + used, size - used, "%s%s = %g%s%s%s", k ? ", " : "", e->key,
                 e->parameter < 0 ? e->value : f->values[e->parameter], e->unit[0] ? " " : "",
                 e->unit, e->parameter < 0 ? " (fixed by the export)" : "");
    }
    used = strlen(text);
    snprintf(text + used, size - used, ")");
}

/* The parameter values from before a refused call, and their arrays. */
void fmu__restore(fmu *f, int rebuild_before) {
    char why[512];
    memcpy(f->values, f->previous, (size_t)f->n_parameters * sizeof(double));
    fmu__assemble(f, why, sizeof why); /* they were assembled before: the same arrays again */
    f->rebuild = rebuild_before;
}

/* The parameter values of a call, set if the model they make is one a parameter file
 * allows (the relations between keys) and the engine takes, and if pivot_q0 (`q0`,
 * when `sets_q0`) stays in the pivot's range; else nothing changes. Returns whether a
 * parameter changed (1), stayed (0) or the call is refused (-1, said why). */
int fmu__set_parameters(fmu *f, const fmi2ValueReference vr[], size_t nvr,
                        const fmi2Real value[], int sets_q0, double q0) {
    char why[512], text[900];
    size_t k;
    int changed = 0, rebuild_before = f->rebuild;
    int64_t r;
    for (k = 0; k < nvr; k++)
        if (vr[k] >= VR_PARAMETER && f->values[vr[k] - VR_PARAMETER] != value[k])
            changed = 1;
    if (!changed) {
        if (sets_q0 && fmu__bad_q0(f, q0, why, sizeof why)) {
            fmu__fail(f, "fmi2SetReal: %s", why);
            return -1;
        }
        return 0;
    }
    memcpy(f->previous, f->values, (size_t)f->n_parameters * sizeof(double));
    for (k = 0; k < nvr; k++)
        if (vr[k] >= VR_PARAMETER)
            f->values[vr[k] - VR_PARAMETER] = value[k];
    r = fmu__broken_relation(f, f->values);
    if (r >= 0) {
        relation_text(f, r, text, sizeof text);
        fmu__restore(f, rebuild_before);
        fmu__fail(f, "fmi2SetReal: %s", text);
        return -1;
    }
    if (!fmu__assemble(f, why, sizeof why)) {
        fmu__restore(f, rebuild_before);
        fmu__fail(f, "fmi2SetReal: %s", why);
        return -1;
    }
    if (sets_q0 && fmu__bad_q0(f, q0, why, sizeof why)) {
        fmu__restore(f, rebuild_before);
        fmu__fail(f, "fmi2SetReal: %s", why);
        return -1;
    }
    if (f->mode == STEPPING) { /* a run under way: the pivot where it stands stays in range */
        const double *p = pivot_row(f);
        double q = vsj_step_pivot_position(&f->model, f->s);
        if (!(q >= p[3] && q <= p[4])) {
            snprintf(why, sizeof why, "the pivot stands at q = %g m, outside the range [%g, "
                     "%g] m these values give it", q, p[3], p[4]);
            fmu__restore(f, rebuild_before);
            fmu__fail(f, "fmi2SetReal: %s", why);
            return -1;
        }
    }
    f->rebuild = 1; /* the stepper is prepared before the next step */
    return 1;
}
