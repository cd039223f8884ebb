/* Set-up of an instance of vsj's FMU (see vsj_fmu.c): the resources read, the
 * engine arrays assembled for the current parameter values, the initial state.
 *
 * The FMU's resources hold the wrist exported by vsj (`model.vsjm`, read by
 * vsj_load_model) and `fmu.txt`, written by vsj.fmu beside modelDescription.xml:
 *
 *     vsj-fmu 3
 *     guid G                       the GUID of modelDescription.xml
 *     parameters P
 *     then, per tunable parameter (value reference 100 + its index):
 *       key unit start min max flags count, and count lines "array index slope"
 *       (SI unit, "1" for none; flags: 1 the minimum is excluded, 2 zero is excluded)
 *     relations R
 *     then, per relation between keys: strict count text, and count lines
 *       "parameter weight value key unit" (parameter -1: a constant, `value`)
 *     pivot q0
 *     springs K into_stop diverged
 *     then, per spring (in the model's order): name, column of its end-stop angle
 *       in its row of `par` (-1: none)
 *     limits L
 *     then, per limited input: input index, limit, name of the motor
 *     ledger tolerance
 *
 * Every real number is written as the 16 hexadecimal digits of its IEEE 754 bits
 * (read with %llx, which no locale changes: a host that set a decimal comma would
 * misread a decimal point).
 *
 * A tunable parameter changes engine arrays affinely: entry `index` of array
 * `array` (0: the kinetic energy matrix, 1: the element parameters) is its
 * exported value plus slope times the parameter's change (vsj.fmu checks at
 * export that this holds for each parameter and for all of them together).
 * The inverse of the mass matrix's free block is recomputed from the result.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmu_internal.h"

static const char *const ROW_NAMES[5] = {"theta_x", "theta_y", "motor_1", "motor_2", "motor_s"};

/* The real number whose IEEE 754 bits are `bits` (as the map writes them). */
static double real_of(unsigned long long bits) {
    uint64_t b = (uint64_t)bits;
    double x;
    memcpy(&x, &b, sizeof x);
    return x;
}

char *fmu__copy_text(const char *text) {
    size_t size = strlen(text) + 1;
    char *out = (char *)malloc(size);
    if (out)
        memcpy(out, text, size);
    return out;
}

/* fmuResourceLocation is a file URI (file:///dir or file:/dir); a plain path is taken too */
char *fmu__resource_path(const char *location, const char *file) {
    const char *path = location;
    size_t size;
    char *out, *at;
    if (strncmp(path, "file://", 7) == 0) {
        path += 7;
        if (strncmp(path, "localhost/", 10) == 0)
            path += 9;
    } else if (strncmp(path, "file:", 5) == 0) {
        path += 5;
    }
#if defined(_WIN32)
    if (path[0] == '/' && path[1] && path[2] == ':')
        path++;
#endif
    size = strlen(path) + strlen(file) + 2;
    out = (char *)malloc(size);
    if (!out)
        return NULL;
    snprintf(out, size, "%s%s%s", path,
             (strlen(path) && path[strlen(path) - 1] == '/') ? "" : "/", file);
    /* percent-escapes of the URI (a space is %20) */
    for (at = out; *at; at++)
        if (at[0] == '%' && at[1] && at[2]) {
            char hex[3] = {at[1], at[2], 0};
            *at = (char)strtol(hex, NULL, 16);
            memmove(at + 1, at + 3, strlen(at + 3) + 1);
        }
    return out;
}

/* A section's heading line, "<name> <count>", with 0 <= count <= most; 0 if it is not
 * there (the reason in `why`). */
static int section_count(FILE *file, const char *name, long long most, long long *count,
                         char *why, size_t size) {
    char word[32];
    if (fscanf(file, "%31s %lld", word, count) != 2 || strcmp(word, name) != 0 || *count < 0
        || *count > most) {
        snprintf(why, size, "no %s line", name);
        return 0;
    }
    return 1;
}

/* The tunable parameters of the map, with the entries each moves. */
static int read_parameters(fmu *f, FILE *file, char *why, size_t size) {
    long long count, p, k, total = 0;
    if (!section_count(file, "parameters", 100000, &count, why, size))
        return 0;
    f->n_parameters = count;
    f->parameters = (parameter *)calloc((size_t)(count ? count : 1), sizeof(parameter));
    f->values = (double *)calloc((size_t)(count ? count : 1), sizeof(double));
    f->previous = (double *)calloc((size_t)(count ? count : 1), sizeof(double));
    if (!f->parameters || !f->values || !f->previous) {
        snprintf(why, size, "out of memory");
        return 0;
    }
    for (p = 0; p < count; p++) {
        parameter *par = f->parameters + p;
        long long entries;
        entry *grown;
        unsigned long long start, low, high;
        if (fscanf(file, "%79s %79s %llx %llx %llx %d %lld", par->key, par->unit, &start, &low,
                   &high, &par->flags, &entries) != 7
            || entries < 0 || entries > 1000000 || par->flags < 0 || par->flags > 3
            || !isfinite(par->start = real_of(start)) || !isfinite(par->min = real_of(low))
            || !isfinite(par->max = real_of(high))) {
            snprintf(why, size, "parameter %lld unreadable", p);
            return 0;
        }
        if (strcmp(par->unit, "1") == 0)
            par->unit[0] = 0;
        par->first = total;
        par->count = entries;
        grown = (entry *)realloc(f->entries, (size_t)(total + entries + 1) * sizeof(entry));
        if (!grown) {
            snprintf(why, size, "out of memory");
            return 0;
        }
        f->entries = grown;
        for (k = 0; k < entries; k++) {
            entry *e = f->entries + total + k;
            long long array, index;
            unsigned long long slope;
            if (fscanf(file, "%lld %lld %llx", &array, &index, &slope) != 3
                || !isfinite(e->slope = real_of(slope)) || (array != 0 && array != 1) || index < 0
                || index >= (array == 0 ? f->n_mass : f->n_par_values)) {
                snprintf(why, size, "parameter %s has a bad entry", par->key);
                return 0;
            }
            e->array = array;
            e->index = index;
        }
        total += entries;
        f->values[p] = par->start;
    }
    return 1;
}

/* The relations between keys, over the tunable parameters and constants. */
static int read_relations(fmu *f, FILE *file, char *why, size_t size) {
    long long count, r, k, total = 0;
    if (!section_count(file, "relations", 1000, &count, why, size))
        return 0;
    f->n_relations = count;
    f->relations = (relation *)calloc((size_t)(count ? count : 1), sizeof(relation));
    if (!f->relations) {
        snprintf(why, size, "out of memory");
        return 0;
    }
    for (r = 0; r < count; r++) {
        relation *rel = f->relations + r;
        long long terms;
        term *grown;
        if (fscanf(file, "%d %lld %255[^\n]", &rel->strict, &terms, rel->text) != 3
            || terms < 1 || terms > 64) {
            snprintf(why, size, "relation %lld unreadable", r);
            return 0;
        }
        rel->first = total;
        rel->count = terms;
        grown = (term *)realloc(f->terms, (size_t)(total + terms) * sizeof(term));
        if (!grown) {
            snprintf(why, size, "out of memory");
            return 0;
        }
        f->terms = grown;
        for (k = 0; k < terms; k++) {
            term *e = f->terms + total + k;
            long long index;
            unsigned long long weight, value;
            if (fscanf(file, "%lld %llx %llx %79s %79s", &index, &weight, &value, e->key,
                       e->unit) != 5
                || index < -1 || index >= f->n_parameters
                || !isfinite(e->weight = real_of(weight)) || !isfinite(e->value = real_of(value))) {
                snprintf(why, size, "relation %lld has a bad term", r);
                return 0;
            }
            e->parameter = index;
            if (strcmp(e->unit, "1") == 0)
                e->unit[0] = 0;
        }
        total += terms;
    }
    return 1;
}

/* What the physical checks of a step need: end stops, voltage limits, the
 * ledger's tolerance. */
static int read_checks(fmu *f, FILE *file, char *why, size_t size) {
    char word[32];
    long long count, k, input;
    unsigned long long into_stop, diverged, bits;
    double value;
    if (fscanf(file, "%31s %lld %llx %llx", word, &count, &into_stop, &diverged) != 4
        || strcmp(word, "springs") != 0 || count != f->model.n_springs
        || !((f->into_stop = real_of(into_stop)) > 0.0)
        || !((f->diverged = real_of(diverged)) > f->into_stop)
        || !isfinite(f->diverged)) {
        snprintf(why, size, "no springs line for the model's %lld springs",
                 (long long)f->model.n_springs);
        return 0;
    }
    f->springs = (spring *)calloc((size_t)(count ? count : 1), sizeof(spring));
    f->limits = (limit *)calloc((size_t)(f->ni ? f->ni : 1), sizeof(limit));
    if (!f->springs || !f->limits) {
        snprintf(why, size, "out of memory");
        return 0;
    }
    for (k = 0; k < count; k++) {
        long long column;
        if (fscanf(file, "%79s %lld", f->springs[k].name, &column) != 2 || column < -1
            || column >= VSJ_NPAR) {
            snprintf(why, size, "spring %lld unreadable", k);
            return 0;
        }
        f->springs[k].stop_column = column;
    }
    if (!section_count(file, "limits", f->ni, &count, why, size))
        return 0;
    f->n_limits = count;
    for (k = 0; k < count; k++) {
        limit *lim = f->limits + k;
        if (fscanf(file, "%lld %llx %79s", &input, &bits, lim->motor) != 3 || input < 0
            || input >= f->ni || !((value = real_of(bits)) > 0.0)) {
            snprintf(why, size, "limit %lld unreadable", k);
            return 0;
        }
        lim->input = input;
        lim->limit = value;
    }
    if (fscanf(file, "%31s %llx", word, &bits) != 2 || strcmp(word, "ledger") != 0
        || !((f->ledger_tolerance = real_of(bits)) > 0.0) || !(f->ledger_tolerance <= 1.0)) {
        snprintf(why, size, "no ledger line");
        return 0;
    }
    return 1;
}

int fmu__read_map(fmu *f, const char *path, char *why, size_t size) {
    FILE *file = fopen(path, "r");
    char word[32], reason[200];
    unsigned long long q0;
    int version, ok;
    if (!file) {
        snprintf(why, size, "cannot open %s", path);
        return 0;
    }
    ok = fscanf(file, "%31s %d", word, &version) == 2 && strcmp(word, "vsj-fmu") == 0
         && version == 3 && fscanf(file, "%31s %63s", word, f->guid) == 2
         && strcmp(word, "guid") == 0;
    if (!ok)
        snprintf(reason, sizeof reason, "not a vsj-fmu 3 map");
    ok = ok && read_parameters(f, file, reason, sizeof reason)
         && read_relations(f, file, reason, sizeof reason);
    if (ok && (fscanf(file, "%31s %llx", word, &q0) != 2 || strcmp(word, "pivot") != 0
               || !isfinite(f->q0_start = real_of(q0)))) {
        snprintf(reason, sizeof reason, "no pivot line");
        ok = 0;
    }
    ok = ok && read_checks(f, file, reason, sizeof reason);
    fclose(file);
    if (!ok) {
        snprintf(why, size, "%s: %s", path, reason);
        return 0;
    }
    f->q0 = f->q0_start;
    return 1;
}

/* The stepper-state entry whose value sets the pivot mechanism's angle (the
 * pivot row's one coefficient on the angles and source angles). */
static int find_pivot(fmu *f) {
    const vsj_model *m = &f->model;
    int64_t r = m->n_rows - 1, k, nm = m->n_motors, found = 0;
    for (k = m->xp[r]; k < m->xp[r + 1]; k++)
        if (m->xv[k] != 0.0) {
            f->pivot_index = m->xc[k];
            f->pivot_coef = m->xv[k];
            found++;
        }
    for (k = m->up[r]; k < m->up[r + 1]; k++)
        if (m->uv[k] != 0.0) {
            f->pivot_index = 2 * m->n + nm + m->uc[k];
            f->pivot_coef = m->uv[k];
            found++;
        }
    return found == 1;
}

void fmu__free(fmu *f) {
    if (!f)
        return;
    vsj_work_free(f->work);
    vsj_free_loaded(f->loaded);
    free(f->mass);
    free(f->minv);
    free(f->par);
    free(f->parameters);
    free(f->entries);
    free(f->values);
    free(f->previous);
    free(f->relations);
    free(f->terms);
    free(f->springs);
    free(f->limits);
    free(f->s);
    free(f->inputs);
    free(f->ledger);
    free(f->booked);
    free(f->speeds);
    free(f->schur);
    free(f->energy);
    free(f->record);
    free(f->stuck);
    free(f->name);
    free(f);
}

/* Minv = inverse of the free block of mass (Gauss-Jordan with partial pivoting) */
static int invert_free_block(fmu *f) {
    int64_t n = f->model.n, sz = n + f->model.n_sources, i, j, k;
    double *a = (double *)malloc((size_t)(n > 0 ? n * n : 1) * sizeof(double));
    if (!a)
        return 0;
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++) {
            a[n * i + j] = f->mass[sz * i + j];
            f->minv[n * i + j] = i == j ? 1.0 : 0.0;
        }
    for (k = 0; k < n; k++) {
        int64_t pivot = k;
        double scale;
        for (i = k + 1; i < n; i++)
            if (fabs(a[n * i + k]) > fabs(a[n * pivot + k]))
                pivot = i;
        if (!(fabs(a[n * pivot + k]) > 0.0)) {
            free(a);
            return 0;
        }
        for (j = 0; j < n; j++) {
            double t = a[n * k + j];
            a[n * k + j] = a[n * pivot + j];
            a[n * pivot + j] = t;
            t = f->minv[n * k + j];
            f->minv[n * k + j] = f->minv[n * pivot + j];
            f->minv[n * pivot + j] = t;
        }
        scale = 1.0 / a[n * k + k];
        for (j = 0; j < n; j++) {
            a[n * k + j] *= scale;
            f->minv[n * k + j] *= scale;
        }
        for (i = 0; i < n; i++)
            if (i != k) {
                double factor = a[n * i + k];
                for (j = 0; j < n; j++) {
                    a[n * i + j] -= factor * a[n * k + j];
                    f->minv[n * i + j] -= factor * f->minv[n * k + j];
                }
            }
    }
    free(a);
    return 1;
}

/* The inertia the sources see with the free coordinates' momenta held: the Schur
 * complement M_ss - M_sf Minv M_fs of the kinetic energy matrix. */
static void source_inertia(fmu *f) {
    int64_t n = f->model.n, ns = f->model.n_sources, sz = n + ns, a, b, i, r;
    for (a = 0; a < ns; a++)
        for (b = 0; b < ns; b++) {
            double value = f->mass[sz * (n + a) + n + b];
            for (i = 0; i < n; i++)
                for (r = 0; r < n; r++)
                    value -= f->mass[sz * (n + a) + i] * f->minv[n * i + r]
                             * f->mass[sz * r + n + b];
            f->schur[ns * a + b] = value;
        }
}

/* The engine arrays for the current parameter values, checked (1), or why not
 * (0, the reason in `why`). */
int fmu__assemble(fmu *f, char *why, size_t size) {
    char text[400];
    int64_t p, k;
    memcpy(f->mass, f->loaded->model.mass, (size_t)f->n_mass * sizeof(double));
    memcpy(f->par, f->loaded->model.par, (size_t)f->n_par_values * sizeof(double));
    for (p = 0; p < f->n_parameters; p++) {
        double change = f->values[p] - f->parameters[p].start;
        if (change == 0.0)
            continue;
        for (k = 0; k < f->parameters[p].count; k++) {
            const entry *e = f->entries + f->parameters[p].first + k;
            (e->array == 0 ? f->mass : f->par)[e->index] += e->slope * change;
        }
    }
    if (!invert_free_block(f)) {
        snprintf(why, size, "the parameters make the mass matrix singular");
        return 0;
    }
    source_inertia(f);
    if (vsj_check_model(&f->model, text, sizeof text) != VSJ_OK) {
        snprintf(why, size, "the parameters give an invalid model: %s", text);
        return 0;
    }
    return 1;
}

/* fmu__assemble, then the stepper prepared for the new arrays */
fmi2Status fmu__rebuild(fmu *f) {
    char why[512];
    if (!fmu__assemble(f, why, sizeof why))
        return fmu__fail(f, "%s", why);
    if (f->scheme.method == VSJ_METHOD_TIMESTEP && vsj_ts_prepare(&f->model, f->work) != VSJ_OK)
        return fmu__fail(f, "the time-stepper cannot be prepared for these parameters%s", "");
    f->rebuild = 0;
    return fmi2OK;
}

void fmu__initial_state(fmu *f) {
    const double *p = pivot_row(f);
    double amplitude = p[0];
    memcpy(f->s, f->loaded->initial_state, (size_t)f->ns * sizeof(double));
    if (p[2] > 0.0 && amplitude > 0.0)
        f->s[f->pivot_index] = asin(f->q0 / amplitude) / f->pivot_coef;
    f->time = 0.0;
    f->power_in = 0.0;
    f->power_dissipated = 0.0;
    f->booked_h = 0.0;
}

/* The parts of an instance that need the model and the map. */
int fmu__allocate(fmu *f) {
    int64_t nk = f->model.n_springs;
    f->at.totals = 0;
    f->at.start = f->nacc;
    f->at.springs = f->at.start + 3;
    f->at.applied = f->at.springs + nk;
    f->at.reference = f->at.applied + f->ni;
    f->at.warned = f->at.reference + f->ni;
    f->at.size = f->at.warned + nk + f->ni;
    f->mass = (double *)malloc((size_t)f->n_mass * sizeof(double));
    f->minv = (double *)malloc((size_t)(f->model.n * f->model.n + 1) * sizeof(double));
    f->par = (double *)malloc((size_t)f->n_par_values * sizeof(double));
    f->s = (double *)calloc((size_t)f->ns + 1, sizeof(double));
    f->inputs = (double *)calloc((size_t)f->ni + 1, sizeof(double));
    f->ledger = (double *)calloc((size_t)f->nacc + 1, sizeof(double));
    f->booked = (double *)calloc((size_t)f->nacc + 1, sizeof(double));
    f->speeds = (double *)calloc((size_t)f->model.n + 1, sizeof(double));
    f->schur = (double *)calloc((size_t)(f->model.n_sources * f->model.n_sources + 1),
                                sizeof(double));
    f->energy = (double *)calloc((size_t)(2 * (3 + nk)), sizeof(double));
    f->record = (double *)calloc((size_t)f->at.size, sizeof(double));
    f->stuck = (unsigned char *)calloc((size_t)f->model.n_frictions + 1, 1);
    f->work = vsj_work_new(&f->model);
    return f->mass && f->minv && f->par && f->s && f->inputs && f->ledger && f->booked
           && f->speeds && f->schur && f->energy && f->record && f->stuck && f->work;
}

/* Why the loaded model is not a wrist this FMU can run (NULL: it is one). */
const char *fmu__not_a_wrist(fmu *f) {
    int64_t k, j;
    if (f->ni != 5)
        return "the model file must have 5 inputs (three motors, tau_x, tau_y)";
    for (k = 0; k < 5; k++) {
        f->rows[k] = -1;
        for (j = 0; j < f->loaded->n_outputs; j++)
            if (strcmp(f->loaded->output_names[j], ROW_NAMES[k]) == 0)
                f->rows[k] = j;
        if (f->rows[k] < 0)
            return "the model file lacks an output (theta_x, theta_y, motor_1, motor_2, motor_s)";
    }
    if (f->model.n_springs != 2 || !find_pivot(f))
        return "the model file is not a wrist (two springs and one pivot drive)";
    f->scheme = f->loaded->scheme;
    /* a communication step takes up to this many internal steps, whatever the step
     * function's bound in the file (c-api-fmu.md) */
    f->scheme.max_steps = VSJ_MAX_PERIOD_STEPS;
    if (f->scheme.method != VSJ_METHOD_DOPRI && f->scheme.method != VSJ_METHOD_ROSENBROCK
        && f->scheme.method != VSJ_METHOD_TIMESTEP) {
        return "the model file's solver must be dopri, rosenbrock or the time-stepper";
    }
    return NULL;
}
