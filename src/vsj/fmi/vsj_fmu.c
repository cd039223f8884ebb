/* vsj's wrist as an FMI 2.0 co-simulation FMU, on the C engine (vsj.h).
 *
 * The FMU's resources hold the wrist exported by vsj (`model.vsjm`, read by
 * vsj_load_model) and `fmu.txt`, written by vsj.fmu beside modelDescription.xml:
 *
 *     vsj-fmu 2
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
 * A tunable parameter changes engine arrays affinely: entry `index` of array
 * `array` (0: the kinetic energy matrix, 1: the element parameters) is its
 * exported value plus slope times the parameter's change (vsj.fmu checks at
 * export that this holds for each parameter and for all of them together).
 * The inverse of the mass matrix's free block is recomputed from the result.
 * fmi2SetReal refuses a parameter value that a parameter file refuses (its
 * bounds, and the relations between keys of vsj.params.RELATIONS: the sum of
 * weight times value, in order, > 0 if strict, else >= 0).
 *
 * Value references. Real: inputs 0..4 (motor commands, then the external
 * torques tau_x, tau_y, in the model file's order); outputs 10..22 (see
 * `enum output`); 99 the initial pivot position; 100.. the parameters.
 * Integer: 0 the number of stuck friction elements.
 *
 * Every call checks its instance and its arguments; a bad call returns
 * fmi2Error and says why through the importer's logger. Each step is checked
 * as vsj simulate checks a run (vsj.simulate.checks): a spring `diverged`
 * past its end stop ends the run (fmi2Error, the instance in the error state,
 * from which fmi2SetFMUstate or fmi2Reset take it back); a spring `into_stop`
 * past its stop or a motor above its voltage limit gives fmi2Warning, once
 * per spring and motor and run. The energy ledger of the run (initialization
 * to fmi2Terminate) is judged at fmi2Terminate. Instances share nothing: any
 * number may run at once, each from one thread at a time.
 */
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2.h"
#include "vsj.h"

#define GUID_MAX 64
#define KEY_MAX 80
#define TEXT_MAX 256
#define VR_INPUT 0
#define VR_OUTPUT 10
#define VR_Q0 99
#define VR_PARAMETER 100
#define VR_STUCK 0
#define MIN_EXCLUDED 1
#define ZERO_EXCLUDED 2
#define SNAPSHOT_MAGIC 0x736a7376u /* an fmi2FMUstate of this FMU */
#define STATE_MAGIC 0x53736a76u    /* "vjsS": a serialized one */
#define STATE_FORMAT 2u            /* its layout (1: vsj 1.x, no fingerprint) */

enum output {
    THETA_X, THETA_Y, DEFLECTION_1, DEFLECTION_2, PIVOT_Q, MOTOR_1_ANGLE, MOTOR_2_ANGLE,
    MOTOR_S_ANGLE, MOTOR_1_SPEED, MOTOR_2_SPEED, MOTOR_S_SPEED, POWER_IN, POWER_DISSIPATED,
    N_OUTPUTS
};
static const char *const ROW_NAMES[5] = {"theta_x", "theta_y", "motor_1", "motor_2", "motor_s"};

enum mode { INSTANTIATED, INITIALIZING, STEPPING, TERMINATED, FAILED };

typedef struct {
    int64_t array, index;
    double slope;
} entry;

typedef struct {
    char key[KEY_MAX];
    char unit[KEY_MAX]; /* SI, empty for none */
    double start, min, max;
    int flags;
    int64_t first, count;
} parameter;

typedef struct {
    int64_t parameter; /* -1: a constant */
    double weight, value;
    char key[KEY_MAX], unit[KEY_MAX];
} term;

typedef struct {
    int strict;
    int64_t first, count;
    char text[TEXT_MAX];
} relation;

typedef struct {
    char name[KEY_MAX];
    int64_t stop_column; /* -1: no end stop */
} spring;

typedef struct {
    int64_t input;
    double limit;
    char motor[KEY_MAX];
} limit;

/* The run's record: what the checks of a run keep from one step to the next,
 * one array of doubles at offsets set at instantiation. */
typedef struct {
    int64_t totals;  /* nacc: the ledger's accumulators summed over the run */
    int64_t start;   /* 3: kinetic, spring and inductor energy at the start [J] */
    int64_t springs; /* n_springs: each spring's energy at the start [J] */
    int64_t applied; /* ni: the inputs of the last step */
    int64_t reference; /* ni: the inputs up to which source jumps are in `start` */
    int64_t warned;  /* n_springs + ni: 1 once a spring or an input was warned about */
    int64_t size;
} record_layout;

/* what fmi2GetFMUstate keeps: everything that a later step depends on */
typedef struct {
    uint32_t magic;
    char guid[GUID_MAX];
    double time, power_in, power_dissipated;
    int mode;
    double *s, *inputs, *values, *record;
    unsigned char *history;
} snapshot;

typedef struct {
    char *name;
    char guid[GUID_MAX];
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging;
    vsj_loaded *loaded;
    vsj_model model; /* the loaded one with this instance's mass, Minv and par */
    double *mass, *minv, *par;
    int64_t n_mass, n_par_values;
    int64_t n_parameters, n_relations;
    parameter *parameters;
    entry *entries;
    relation *relations;
    term *terms;
    double *values;   /* current parameter values */
    double *previous; /* their values before a call that changes them */
    double q0, q0_start;
    int64_t pivot_index; /* entry of the stepper state that sets the pivot angle */
    double pivot_coef;
    spring *springs;
    int64_t n_limits;
    limit *limits; /* the inputs with a voltage limit */
    double into_stop, diverged, ledger_tolerance;
    vsj_work *work;
    int64_t ns, ni, nacc;
    double *s, *inputs, *ledger;
    double *speeds; /* scratch: n generalised speeds */
    double *schur;  /* n_sources^2: M_ss - M_sf Minv M_fs, the sources' own inertia */
    double *energy; /* scratch: two sets of stored energies (3 + n_springs each) */
    record_layout at;
    double *record;
    vsj_scheme scheme; /* the model file's scheme (dopri or the time-stepper) */
    int64_t rows[5];
    unsigned char *stuck;
    double time, power_in, power_dissipated, stop_time;
    int mode, rebuild, stop_defined;
    size_t history_size;
} fmu;

static void say(const fmu *f, fmi2Status status, const char *category, const char *format, ...) {
    char text[1024];
    va_list args;
    if (!f || !f->logger || (status == fmi2OK && !f->logging))
        return;
    char escaped[2 * sizeof text];
    size_t i, j = 0;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    /* the logger takes a format: the message is passed as one, '%' doubled */
    for (i = 0; text[i] && j + 2 < sizeof escaped; i++) {
        if (text[i] == '%')
            escaped[j++] = '%';
        escaped[j++] = text[i];
    }
    escaped[j] = 0;
    f->logger(f->env, f->name, status, category, escaped);
}

static fmi2Status fail(fmu *f, const char *format, const char *detail) {
    say(f, fmi2Error, "logStatusError", format, detail);
    return fmi2Error;
}

/* ---- set-up ------------------------------------------------------------------ */

static char *copy_text(const char *text) {
    size_t size = strlen(text) + 1;
    char *out = (char *)malloc(size);
    if (out)
        memcpy(out, text, size);
    return out;
}

/* fmuResourceLocation is a file URI (file:///dir or file:/dir); a plain path is taken too */
static char *resource_path(const char *location, const char *file) {
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

/* The tunable parameters of the map, with the entries each moves. */
static int read_parameters(fmu *f, FILE *file, char *why, size_t size) {
    char word[32];
    long long count, p, k, total = 0;
    if (fscanf(file, "%31s %lld", word, &count) != 2 || strcmp(word, "parameters") != 0
        || count < 0 || count > 100000) {
        snprintf(why, size, "no parameters line");
        return 0;
    }
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
        if (fscanf(file, "%79s %79s %lf %lf %lf %d %lld", par->key, par->unit, &par->start,
                   &par->min, &par->max, &par->flags, &entries) != 7
            || entries < 0 || entries > 1000000 || par->flags < 0 || par->flags > 3) {
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
            if (fscanf(file, "%lld %lld %lf", &array, &index, &e->slope) != 3
                || (array != 0 && array != 1) || index < 0
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
    char word[32];
    long long count, r, k, total = 0;
    if (fscanf(file, "%31s %lld", word, &count) != 2 || strcmp(word, "relations") != 0
        || count < 0 || count > 1000) {
        snprintf(why, size, "no relations line");
        return 0;
    }
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
            if (fscanf(file, "%lld %lf %lf %79s %79s", &index, &e->weight, &e->value, e->key,
                       e->unit) != 5
                || index < -1 || index >= f->n_parameters || !isfinite(e->weight)
                || !isfinite(e->value)) {
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
    double value;
    if (fscanf(file, "%31s %lld %lf %lf", word, &count, &f->into_stop, &f->diverged) != 4
        || strcmp(word, "springs") != 0 || count != f->model.n_springs
        || !(f->into_stop > 0.0) || !(f->diverged > f->into_stop) || !isfinite(f->diverged)) {
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
    if (fscanf(file, "%31s %lld", word, &count) != 2 || strcmp(word, "limits") != 0
        || count < 0 || count > f->ni) {
        snprintf(why, size, "no limits line");
        return 0;
    }
    f->n_limits = count;
    for (k = 0; k < count; k++) {
        limit *lim = f->limits + k;
        if (fscanf(file, "%lld %lf %79s", &input, &value, lim->motor) != 3 || input < 0
            || input >= f->ni || !(value > 0.0)) {
            snprintf(why, size, "limit %lld unreadable", k);
            return 0;
        }
        lim->input = input;
        lim->limit = value;
    }
    if (fscanf(file, "%31s %lf", word, &f->ledger_tolerance) != 2 || strcmp(word, "ledger") != 0
        || !(f->ledger_tolerance > 0.0) || !(f->ledger_tolerance <= 1.0)) {
        snprintf(why, size, "no ledger line");
        return 0;
    }
    return 1;
}

static int read_map(fmu *f, const char *path, char *why, size_t size) {
    FILE *file = fopen(path, "r");
    char word[32], reason[200];
    int version, ok;
    if (!file) {
        snprintf(why, size, "cannot open %s", path);
        return 0;
    }
    ok = fscanf(file, "%31s %d", word, &version) == 2 && strcmp(word, "vsj-fmu") == 0
         && version == 2 && fscanf(file, "%31s %63s", word, f->guid) == 2
         && strcmp(word, "guid") == 0;
    if (!ok)
        snprintf(reason, sizeof reason, "not a vsj-fmu 2 map");
    ok = ok && read_parameters(f, file, reason, sizeof reason)
         && read_relations(f, file, reason, sizeof reason);
    if (ok && (fscanf(file, "%31s %lf", word, &f->q0_start) != 2 || strcmp(word, "pivot") != 0
               || !isfinite(f->q0_start))) {
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

static void free_fmu(fmu *f) {
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
static int assemble(fmu *f, char *why, size_t size) {
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

/* assemble, then the stepper prepared for the new arrays */
static fmi2Status rebuild(fmu *f) {
    char why[512];
    if (!assemble(f, why, sizeof why))
        return fail(f, "%s", why);
    if (f->scheme.method == VSJ_METHOD_TIMESTEP && vsj_ts_prepare(&f->model, f->work) != VSJ_OK)
        return fail(f, "the time-stepper cannot be prepared for these parameters%s", "");
    f->rebuild = 0;
    return fmi2OK;
}

/* Why parameter p may not take x, as vsj.params.Spec.check says it (NULL: it may). */
static const char *refusal(const parameter *p, double x, char *why, size_t size) {
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
static int64_t broken_relation(const fmu *f, const double *values) {
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

static const double *pivot_row(const fmu *f) {
    return f->par + VSJ_NPAR * (f->model.n_rows - 1);
}

static void initial_state(fmu *f) {
    const double *p = pivot_row(f);
    double amplitude = p[0];
    memcpy(f->s, f->loaded->initial_state, (size_t)f->ns * sizeof(double));
    if (p[2] > 0.0 && amplitude > 0.0)
        f->s[f->pivot_index] = asin(f->q0 / amplitude) / f->pivot_coef;
    f->time = 0.0;
    f->power_in = 0.0;
    f->power_dissipated = 0.0;
}

/* ---- energy ------------------------------------------------------------------ */

/* Deflection [rad] of spring k in stepper state s. */
static double deflection(const fmu *f, const double *s, int64_t k) {
    const vsj_model *m = &f->model;
    int64_t r = m->n_frictions + k, i;
    double value = 0.0;
    for (i = m->xp[r]; i < m->xp[r + 1]; i++)
        value += m->xv[i] * s[m->xc[i]];
    for (i = m->up[r]; i < m->up[r + 1]; i++)
        value += m->uv[i] * s[2 * m->n + m->n_motors + m->uc[i]];
    return value;
}

/* Kinetic energy [J] of stepper state s with the source speeds of `inputs`. */
static double kinetic(fmu *f, const double *s, const double *inputs) {
    const vsj_model *m = &f->model;
    int64_t n = m->n, sz = n + m->n_sources, i, r;
    double energy = 0.0;
    vsj_step_speeds(m, s, inputs, f->speeds);
    for (i = 0; i < sz; i++) {
        double a = i < n ? f->speeds[i] : inputs[m->src_ch[i - n]];
        for (r = 0; r < sz; r++)
            energy += 0.5 * a * m->mass[sz * i + r]
                      * (r < n ? f->speeds[r] : inputs[m->src_ch[r - n]]);
    }
    return energy;
}

/* Kinetic, spring and inductor energy [J] of the current state, as vsj_stored_energy
 * gives them; `springs` (n_springs) receives each spring's. */
static void stored(fmu *f, const double *inputs, double energy[3], double *springs) {
    const vsj_model *m = &f->model;
    int64_t k, mo, base = m->n_frictions + m->n_springs + m->n_loads;
    double q = vsj_step_pivot_position(m, f->s), law[4];
    energy[0] = kinetic(f, f->s, inputs);
    energy[1] = 0.0;
    energy[2] = 0.0;
    for (k = 0; k < m->n_springs; k++) {
        int64_t row = m->n_frictions + k;
        vsj_spring_law((int)m->code[row], f->par + VSJ_NPAR * row, deflection(f, f->s, k), q,
                       law);
        springs[k] = law[2];
        energy[1] += law[2];
    }
    for (mo = 0; mo < m->n_motors; mo++) {
        double current = f->s[2 * m->n + mo];
        energy[2] += 0.5 * f->par[VSJ_NPAR * (base + mo) + 1] * current * current;
    }
}

/* A run starts: the ledger's totals cleared, the energy at the start and the
 * inputs taken, nothing warned about yet. */
static void start_run(fmu *f) {
    memset(f->record, 0, (size_t)f->at.size * sizeof(double));
    stored(f, f->inputs, f->record + f->at.start, f->record + f->at.springs);
    memcpy(f->record + f->at.applied, f->inputs, (size_t)f->ni * sizeof(double));
    memcpy(f->record + f->at.reference, f->inputs, (size_t)f->ni * sizeof(double));
}

/* Held source speeds that jump between steps change the kinetic energy, work that
 * no step's integrator sees. With the momenta p of the free coordinates, the
 * kinetic energy is p' Minv p / 2 + u' S u / 2 (S: the sources' own inertia,
 * f->schur), and a jump of u leaves p as it is: so the jumps of a run add up to
 * the change of u' S u / 2 from the inputs at its start to those of its last
 * step, put in by the importer, as long as S stays. [J] */
static double source_energy(const fmu *f, const double *inputs) {
    const vsj_model *m = &f->model;
    int64_t ns = m->n_sources, a, b;
    double energy = 0.0;
    for (a = 0; a < ns; a++)
        for (b = 0; b < ns; b++)
            energy += 0.5 * inputs[m->src_ch[a]] * f->schur[ns * a + b] * inputs[m->src_ch[b]];
    return energy;
}

static double source_jumps(const fmu *f) {
    return source_energy(f, f->record + f->at.applied)
           - source_energy(f, f->record + f->at.reference);
}

/* Energy that the importer puts in between steps, no integrator seeing it: held
 * source speeds that jumped (source_jumps), or a parameter changed. It moves the
 * run's energy at the start, as if the run had started with it, so that the ledger
 * weighs what the steps did. `before` and `after` are the stored energies (3
 * values, then one per spring) either side of the change. */
static void shift_start(fmu *f, const double *before, const double *after) {
    int64_t k, nk = f->model.n_springs;
    for (k = 0; k < 3; k++)
        f->record[f->at.start + k] += after[k] - before[k];
    for (k = 0; k < nk; k++)
        f->record[f->at.springs + k] += after[3 + k] - before[3 + k];
}

/* The energy ledger of the run so far, as vsj.simulate.ledger keeps a run's:
 * the residual of work in = stored change + dissipated, and the energy in play. */
static void run_ledger(fmu *f, double *residual, double *scale) {
    const vsj_model *m = &f->model;
    int64_t s_n = m->n_sources, nl = m->n_loads, nm = m->n_motors, nf = m->n_frictions;
    int64_t nk = m->n_springs, i, at;
    const double *total = f->record + f->at.totals, *start = f->record + f->at.start;
    const double *start_springs = f->record + f->at.springs;
    double *now = f->energy, *springs = f->energy + 3, change, held, kinetic0;
    double in = 0.0, in_size = 0.0, lost = 0.0, lost_size = 0.0, pivot = 0.0;
    stored(f, f->record + f->at.applied, now, springs);
    for (i = 0; i < s_n + nl + nm; i++) { /* sources, loads, motor supplies */
        in += total[i];
        in_size += fabs(total[i]);
    }
    at = s_n + nl + nm;
    for (i = 0; i < nf + nm; i++) { /* friction, then armature resistance */
        lost += total[at + i];
        lost_size += fabs(total[at + i]);
    }
    at += nf + nm; /* the springs' work, the pivot's on them, their stops' */
    for (i = 0; i < nk; i++)
        pivot += total[at + nk + i];
    if (pivot_row(f)[2] > 0.0) { /* a moving pivot does work on the springs */
        in += pivot;
        in_size += fabs(pivot);
    }
    for (i = 0; i < nk; i++) {
        double stops = total[at + 2 * nk + i];
        lost += stops;
        lost_size += fabs(stops);
        /* eq 3.8 is not a potential force: what its spring does not store is lost */
        if (m->code[nf + i] == VSJ_GEOMETRIC_REPORT)
            lost += total[at + nk + i] - total[at + i] - (springs[i] - start_springs[i]) - stops;
    }
    kinetic0 = start[0] + source_jumps(f);
    change = (now[0] - kinetic0) + (now[1] - start[1]) + (now[2] - start[2]);
    held = fmax(fabs(kinetic0) + fabs(start[1]) + fabs(start[2]),
                fabs(now[0]) + fabs(now[1]) + fabs(now[2]));
    *residual = in - change - lost;
    *scale = fmax(fmax(fmax(in_size, lost_size), fmax(fabs(change), held)), 1e-300);
}

/* ---- instantiation ----------------------------------------------------------- */

/* The parts of an instance that need the model and the map. */
static int allocate(fmu *f) {
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
    f->speeds = (double *)calloc((size_t)f->model.n + 1, sizeof(double));
    f->schur = (double *)calloc((size_t)(f->model.n_sources * f->model.n_sources + 1),
                                sizeof(double));
    f->energy = (double *)calloc((size_t)(2 * (3 + nk)), sizeof(double));
    f->record = (double *)calloc((size_t)f->at.size, sizeof(double));
    f->stuck = (unsigned char *)calloc((size_t)f->model.n_frictions + 1, 1);
    f->work = vsj_work_new(&f->model);
    return f->mass && f->minv && f->par && f->s && f->inputs && f->ledger && f->speeds
           && f->schur && f->energy && f->record && f->stuck && f->work;
}

/* Why the loaded model is not a wrist this FMU can run (NULL: it is one). */
static const char *not_a_wrist(fmu *f) {
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
    if (f->scheme.method != VSJ_METHOD_DOPRI && f->scheme.method != VSJ_METHOD_TIMESTEP) {
        return "the model file's solver must be dopri or the time-stepper";
    }
    return NULL;
}

static fmi2Component refuse(fmu *f, const char *format, const char *detail) {
    fail(f, format, detail);
    free_fmu(f);
    return NULL;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    fmu *f;
    char why[512], text[2 * GUID_MAX + 600], *path;
    const char *problem;
    (void)visible;
    if (!functions || !functions->logger)
        return NULL;
    f = (fmu *)calloc(1, sizeof(fmu));
    if (!f)
        return NULL;
    f->logger = functions->logger;
    f->env = functions->componentEnvironment;
    f->logging = loggingOn;
    f->name = copy_text(instanceName && instanceName[0] ? instanceName : "vsj");
    if (!f->name) {
        free(f);
        return NULL;
    }
    if (fmuType != fmi2CoSimulation)
        return refuse(f, "vsj's FMU is for co-simulation only%s", "");
    if (!fmuResourceLocation)
        return refuse(f, "no resource location given%s", "");
    path = resource_path(fmuResourceLocation, "model.vsjm");
    if (!path)
        return refuse(f, "out of memory%s", "");
    f->loaded = vsj_load_model(path, why, sizeof why);
    free(path);
    if (!f->loaded)
        return refuse(f, "cannot load the model: %s", why);
    f->model = f->loaded->model;
    f->n_mass = (f->model.n + f->model.n_sources) * (f->model.n + f->model.n_sources);
    f->n_par_values = f->model.n_rows * VSJ_NPAR;
    f->ns = vsj_step_state_size(&f->model);
    f->ni = f->loaded->n_inputs;
    f->nacc = vsj_n_acc(&f->model);
    path = resource_path(fmuResourceLocation, "fmu.txt");
    if (!path)
        return refuse(f, "out of memory%s", "");
    if (!read_map(f, path, why, sizeof why)) {
        free(path);
        return refuse(f, "cannot read the parameter map: %s", why);
    }
    free(path);
    /* FMI 2.0: the FMU checks that the importer read its own modelDescription.xml */
    if (!fmuGUID || !fmuGUID[0]) {
        snprintf(text, sizeof text, "fmi2Instantiate: no GUID given; this FMU's GUID is %s",
                 f->guid);
        return refuse(f, "%s", text);
    }
    if (strcmp(fmuGUID, f->guid) != 0) {
        snprintf(text, sizeof text, "fmi2Instantiate: the GUID given, %.*s, is not this FMU's "
                 "GUID %s: the modelDescription.xml read belongs to another FMU",
                 GUID_MAX, fmuGUID, f->guid);
        return refuse(f, "%s", text);
    }
    if (!allocate(f))
        return refuse(f, "out of memory%s", "");
    f->model.mass = f->mass;
    f->model.Minv = f->minv;
    f->model.par = f->par;
    problem = not_a_wrist(f);
    if (problem)
        return refuse(f, "%s", problem);
    f->history_size = vsj_ts_history_size(&f->model);
    f->rebuild = 1;
    f->mode = INSTANTIATED;
    if (rebuild(f) != fmi2OK) {
        free_fmu(f);
        return NULL;
    }
    initial_state(f);
    say(f, fmi2OK, "logAll", "instantiated: %lld parameters", (long long)f->n_parameters);
    return f;
}

void fmi2FreeInstance(fmi2Component c) { free_fmu((fmu *)c); }

/* ---- life cycle ---------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return "default"; }
const char *fmi2GetVersion(void) { return "2.0"; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    fmu *f = (fmu *)c;
    (void)nCategories;
    (void)categories;
    if (!f)
        return fmi2Error;
    f->logging = loggingOn;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    fmu *f = (fmu *)c;
    (void)toleranceDefined;
    (void)tolerance;
    if (!f)
        return fmi2Error;
    if (f->mode != INSTANTIATED)
        return fail(f, "fmi2SetupExperiment: only after fmi2Instantiate or fmi2Reset%s", "");
    if (!isfinite(startTime))
        return fail(f, "fmi2SetupExperiment: the start time must be finite%s", "");
    if (stopTimeDefined && !(isfinite(stopTime) && stopTime >= startTime))
        return fail(f, "fmi2SetupExperiment: the stop time must be finite and not before the "
                       "start time%s", "");
    f->time = startTime;
    f->stop_defined = stopTimeDefined != fmi2False;
    f->stop_time = stopTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    fmu *f = (fmu *)c;
    if (!f)
        return fmi2Error;
    if (f->mode != INSTANTIATED)
        return fail(f, "fmi2EnterInitializationMode: not after fmi2Instantiate%s", "");
    f->mode = INITIALIZING;
    return fmi2OK;
}

/* Why q0 [m] is not a pivot position the current parameters allow (NULL: it is). */
static const char *bad_q0(const fmu *f, double q0, char *why, size_t size) {
    const double *p = pivot_row(f);
    if (q0 >= p[3] && q0 <= p[4])
        return NULL;
    snprintf(why, size, "pivot_q0 = %g m is outside the pivot's range [%g, %g] m", q0, p[3], p[4]);
    return why;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    fmu *f = (fmu *)c;
    char why[200];
    double start;
    if (!f)
        return fmi2Error;
    if (f->mode != INITIALIZING)
        return fail(f, "fmi2ExitInitializationMode: not in initialization mode%s", "");
    if (bad_q0(f, f->q0, why, sizeof why)) /* the range moved with pivot.q_min, q_max */
        return fail(f, "fmi2ExitInitializationMode: %s", why);
    start = f->time;
    if (f->rebuild && rebuild(f) != fmi2OK) {
        f->mode = FAILED;
        return fmi2Error;
    }
    initial_state(f);
    f->time = start;
    start_run(f);
    f->mode = STEPPING;
    return fmi2OK;
}

/* The run from initialization to fmi2Terminate is judged by its energy ledger,
 * as vsj simulate judges a run (vsj.simulate.checks.judge). */
fmi2Status fmi2Terminate(fmi2Component c) {
    fmu *f = (fmu *)c;
    double residual, scale, relative;
    char text[400];
    if (!f)
        return fmi2Error;
    if (f->mode != STEPPING) {
        f->mode = f->mode == FAILED ? FAILED : TERMINATED;
        return fmi2OK;
    }
    run_ledger(f, &residual, &scale);
    relative = fabs(residual) / scale;
    if (!(relative <= f->ledger_tolerance)) {
        snprintf(text, sizeof text, "its residual is %.6g of the energy in play, above the "
                 "ledger tolerance %g (the numerical settings are too coarse for this run: "
                 "export the FMU with a shorter step, vsj fmu --step)", relative, f->ledger_tolerance);
        f->mode = FAILED;
        return fail(f, "fmi2Terminate: the run cannot be trusted: its energy ledger does not "
                       "close: %s", text);
    }
    say(f, fmi2OK, "logAll", "fmi2Terminate: the energy ledger of the run closes: its residual "
        "is %.6g of the energy in play (tolerance %g)", relative, f->ledger_tolerance);
    f->mode = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    fmu *f = (fmu *)c;
    int64_t p;
    if (!f)
        return fmi2Error;
    for (p = 0; p < f->n_parameters; p++)
        f->values[p] = f->parameters[p].start;
    f->q0 = f->q0_start;
    f->stop_defined = 0;
    memset(f->inputs, 0, (size_t)f->ni * sizeof(double));
    f->rebuild = 1;
    if (rebuild(f) != fmi2OK) {
        f->mode = FAILED;
        return fmi2Error;
    }
    initial_state(f);
    f->mode = INSTANTIATED;
    return fmi2OK;
}

/* ---- values ------------------------------------------------------------------- */

static double row_value(const fmu *f, int64_t row, const double *v) {
    const double *c = f->loaded->output_rows + f->ns * row;
    int64_t i, n = f->model.n, nm = f->model.n_motors, j;
    double value = 0.0;
    if (!v) {
        for (i = 0; i < f->ns; i++)
            value += c[i] * f->s[i];
        return value;
    }
    for (i = 0; i < n; i++) /* the same row gives the speed from [v, u] */
        value += c[i] * v[i];
    for (j = 0; j < f->model.n_sources; j++)
        value += c[2 * n + nm + j] * f->inputs[f->model.src_ch[j]];
    return value;
}

static double output(fmu *f, int which) {
    double v[64];
    int64_t n = f->model.n;
    if (which >= MOTOR_1_SPEED && which <= MOTOR_S_SPEED) {
        double *speeds = n <= 64 ? v : (double *)malloc((size_t)n * sizeof(double));
        double value;
        if (!speeds)
            return NAN;
        vsj_step_speeds(&f->model, f->s, f->inputs, speeds);
        value = row_value(f, f->rows[2 + which - MOTOR_1_SPEED], speeds);
        if (speeds != v)
            free(speeds);
        return value;
    }
    switch (which) {
    case THETA_X: return row_value(f, f->rows[0], NULL);
    case THETA_Y: return row_value(f, f->rows[1], NULL);
    case DEFLECTION_1: return deflection(f, f->s, 0);
    case DEFLECTION_2: return deflection(f, f->s, 1);
    case PIVOT_Q: return vsj_step_pivot_position(&f->model, f->s);
    case MOTOR_1_ANGLE: return row_value(f, f->rows[2], NULL);
    case MOTOR_2_ANGLE: return row_value(f, f->rows[3], NULL);
    case MOTOR_S_ANGLE: return row_value(f, f->rows[4], NULL);
    case POWER_IN: return f->power_in;
    case POWER_DISSIPATED: return f->power_dissipated;
    default: return NAN;
    }
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    fmu *f = (fmu *)c;
    size_t k;
    if (!f)
        return fmi2Error;
    if (nvr && (!vr || !value))
        return fail(f, "fmi2GetReal: null array%s", "");
    for (k = 0; k < nvr; k++) {
        fmi2ValueReference r = vr[k];
        if (r < (fmi2ValueReference)f->ni)
            value[k] = f->inputs[r];
        else if (r >= VR_OUTPUT && r < VR_OUTPUT + N_OUTPUTS)
            value[k] = output(f, (int)(r - VR_OUTPUT));
        else if (r == VR_Q0)
            value[k] = f->q0;
        else if (r >= VR_PARAMETER && r < VR_PARAMETER + (fmi2ValueReference)f->n_parameters)
            value[k] = f->values[r - VR_PARAMETER];
        else {
            char text[32];
            snprintf(text, sizeof text, "%u", r);
            return fail(f, "fmi2GetReal: no Real variable has value reference %s", text);
        }
    }
    return fmi2OK;
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
static void restore(fmu *f, int rebuild_before) {
    char why[512];
    memcpy(f->values, f->previous, (size_t)f->n_parameters * sizeof(double));
    assemble(f, why, sizeof why); /* they were assembled before: the same arrays again */
    f->rebuild = rebuild_before;
}

/* The parameter values of a call, set if the model they make is one a parameter file
 * allows (the relations between keys) and the engine takes, and if pivot_q0 (`q0`,
 * when `sets_q0`) stays in the pivot's range; else nothing changes. Returns whether a
 * parameter changed (1), stayed (0) or the call is refused (-1, said why). */
static int set_parameters(fmu *f, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Real value[], int sets_q0, double q0) {
    char why[512], text[900];
    size_t k;
    int changed = 0, rebuild_before = f->rebuild;
    int64_t r;
    for (k = 0; k < nvr; k++)
        if (vr[k] >= VR_PARAMETER && f->values[vr[k] - VR_PARAMETER] != value[k])
            changed = 1;
    if (!changed) {
        if (sets_q0 && bad_q0(f, q0, why, sizeof why)) {
            fail(f, "fmi2SetReal: %s", why);
            return -1;
        }
        return 0;
    }
    memcpy(f->previous, f->values, (size_t)f->n_parameters * sizeof(double));
    for (k = 0; k < nvr; k++)
        if (vr[k] >= VR_PARAMETER)
            f->values[vr[k] - VR_PARAMETER] = value[k];
    r = broken_relation(f, f->values);
    if (r >= 0) {
        relation_text(f, r, text, sizeof text);
        restore(f, rebuild_before);
        fail(f, "fmi2SetReal: %s", text);
        return -1;
    }
    if (!assemble(f, why, sizeof why)) {
        restore(f, rebuild_before);
        fail(f, "fmi2SetReal: %s", why);
        return -1;
    }
    if (sets_q0 && bad_q0(f, q0, why, sizeof why)) {
        restore(f, rebuild_before);
        fail(f, "fmi2SetReal: %s", why);
        return -1;
    }
    f->rebuild = 1; /* the stepper is prepared before the next step */
    return 1;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    fmu *f = (fmu *)c;
    size_t k;
    char text[400], why[200];
    int sets_q0 = 0, differs = 0, stepping, changed;
    double q0 = 0.0, *before, *after;
    if (!f)
        return fmi2Error;
    if (nvr && (!vr || !value))
        return fail(f, "fmi2SetReal: null array%s", "");
    for (k = 0; k < nvr; k++) { /* each value checked before any is set */
        fmi2ValueReference r = vr[k];
        double x = value[k];
        if (r < (fmi2ValueReference)f->ni) {
            if (!isfinite(x)) {
                snprintf(text, sizeof text, "%s = %g", f->loaded->input_names[r], x);
                return fail(f, "fmi2SetReal: input %s: the value is not finite", text);
            }
            continue;
        }
        if (r == VR_Q0) {
            if (!isfinite(x))
                return fail(f, "fmi2SetReal: pivot_q0: the value is not finite%s", "");
            if (f->mode != INSTANTIATED && f->mode != INITIALIZING)
                return fail(f, "fmi2SetReal: the initial pivot position is set before "
                               "initialization ends%s", "");
            sets_q0 = 1;
            q0 = x;
        } else if (r >= VR_PARAMETER && r < VR_PARAMETER + (fmi2ValueReference)f->n_parameters) {
            const parameter *p = f->parameters + (r - VR_PARAMETER);
            if (refusal(p, x, why, sizeof why)) {
                snprintf(text, sizeof text, "%s = %g%s%s is outside its range: %s", p->key, x,
                         p->unit[0] ? " " : "", p->unit, why);
                return fail(f, "fmi2SetReal: %s", text);
            }
            differs |= f->values[r - VR_PARAMETER] != x;
        } else {
            snprintf(text, sizeof text, "%u", r);
            return fail(f, "fmi2SetReal: value reference %s is not an input or a parameter",
                        text);
        }
    }
    /* a parameter changed while stepping changes the stored energy: the ledger's
     * start moves with it (see shift_start) */
    stepping = f->mode == STEPPING && differs;
    before = f->energy;
    after = f->energy + 3 + f->model.n_springs;
    if (stepping) { /* the jumps so far, with the sources' inertia before the change */
        f->record[f->at.start] += source_jumps(f);
        memcpy(f->record + f->at.reference, f->record + f->at.applied,
               (size_t)f->ni * sizeof(double));
        stored(f, f->record + f->at.applied, before, before + 3);
    }
    changed = differs || sets_q0 ? set_parameters(f, vr, nvr, value, sets_q0, q0) : 0;
    if (changed < 0)
        return fmi2Error;
    if (changed && stepping) {
        stored(f, f->record + f->at.applied, after, after + 3);
        shift_start(f, before, after);
    }
    for (k = 0; k < nvr; k++)
        if (vr[k] < (fmi2ValueReference)f->ni)
            f->inputs[vr[k]] = value[k];
    if (sets_q0)
        f->q0 = q0;
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    fmu *f = (fmu *)c;
    size_t k;
    if (!f)
        return fmi2Error;
    if (nvr && (!vr || !value))
        return fail(f, "fmi2GetInteger: null array%s", "");
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_STUCK)
            return fail(f, "fmi2GetInteger: the only Integer is n_stuck (value reference 0)%s",
                        "");
        value[k] = f->scheme.method == VSJ_METHOD_TIMESTEP && f->mode == STEPPING
                       ? (fmi2Integer)vsj_ts_stuck(&f->model, f->work, f->stuck)
                       : 0;
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    (void)vr;
    (void)value;
    if (!c)
        return fmi2Error;
    return nvr ? fail((fmu *)c, "fmi2SetInteger: the FMU has no Integer to set%s", "") : fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    if (!c)
        return fmi2Error;
    return nvr ? fail((fmu *)c, "fmi2GetBoolean: the FMU has no Boolean%s", "") : fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    if (!c)
        return fmi2Error;
    return nvr ? fail((fmu *)c, "fmi2SetBoolean: the FMU has no Boolean%s", "") : fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    (void)vr;
    (void)value;
    if (!c)
        return fmi2Error;
    return nvr ? fail((fmu *)c, "fmi2GetString: the FMU has no String%s", "") : fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    (void)vr;
    (void)value;
    if (!c)
        return fmi2Error;
    return nvr ? fail((fmu *)c, "fmi2SetString: the FMU has no String%s", "") : fmi2OK;
}

/* ---- stepping ------------------------------------------------------------------ */

/* The step's power outputs, and its ledger added to the run's (one pass). */
static void account(fmu *f, double h) {
    const vsj_model *m = &f->model;
    const double *step = f->ledger;
    double work_in = 0.0, lost = 0.0, *total = f->record + f->at.totals;
    int64_t i = 0, nk = m->n_springs, end;
    int moving = pivot_row(f)[2] > 0.0;
    for (end = m->n_sources + m->n_loads + m->n_motors; i < end; i++) {
        total[i] += step[i]; /* sources, loads, motor supplies */
        work_in += step[i];
    }
    for (end += m->n_frictions + m->n_motors; i < end; i++) {
        total[i] += step[i]; /* friction, then armature resistance */
        lost += step[i];
    }
    for (end += nk; i < end; i++)
        total[i] += step[i]; /* the springs' own work */
    for (end += nk; i < end; i++) {
        total[i] += step[i]; /* the pivot's on them: work in if it moves */
        if (moving)
            work_in += step[i];
    }
    for (end += nk; i < end; i++) {
        total[i] += step[i]; /* their end stops' */
        lost += step[i];
    }
    f->power_in = work_in / h;
    f->power_dissipated = lost / h;
}

/* The checks vsj simulate makes of a run (vsj.simulate.checks), at the end of a
 * step: fmi2Error for a spring that diverged past its end stop, fmi2Warning the
 * first time a spring goes into_stop past it or an input exceeds a motor's
 * voltage limit, else fmi2OK. */
static fmi2Status judge_step(fmu *f, double t_start) {
    const vsj_model *m = &f->model;
    double *warned = f->record + f->at.warned;
    fmi2Status status = fmi2OK;
    char text[400];
    int64_t k;
    for (k = 0; k < m->n_springs; k++) {
        const spring *sp = f->springs + k;
        double stop, angle, past;
        if (sp->stop_column < 0)
            continue;
        stop = f->par[VSJ_NPAR * (m->n_frictions + k) + sp->stop_column];
        if (!(stop > 0.0))
            continue;
        angle = deflection(f, f->s, k);
        past = fabs(angle) - stop;
        if (past > f->diverged) {
            snprintf(text, sizeof text, "at t = %.9g s spring %s deflected %.4g rad, more "
                     "than %.4g rad past its %.4g rad end stop: the run diverged", f->time,
                     sp->name, angle, f->diverged, stop);
            f->mode = FAILED;
            return fail(f, "fmi2DoStep: %s", text);
        }
        if (past > f->into_stop && warned[k] == 0.0) {
            warned[k] = 1.0;
            say(f, fmi2Warning, "logStatusWarning", "fmi2DoStep: spring %s was driven to %.4g "
                "rad at t = %.9g s, %.3g rad past its %.4g rad end stop: the loads exceed what "
                "the mechanism takes", sp->name, angle, f->time, past, stop);
            status = fmi2Warning;
        }
    }
    for (k = 0; k < f->n_limits; k++) {
        const limit *lim = f->limits + k;
        double volts = f->inputs[lim->input];
        if (fabs(volts) > lim->limit && warned[m->n_springs + lim->input] == 0.0) {
            warned[m->n_springs + lim->input] = 1.0;
            say(f, fmi2Warning, "logStatusWarning", "fmi2DoStep: motor %s was driven at %.4g V "
                "at t = %.9g s, beyond its %g V limit", lim->motor, volts, t_start, lim->limit);
            status = fmi2Warning;
        }
    }
    return status;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    fmu *f = (fmu *)c;
    int status;
    double h = communicationStepSize, point = currentCommunicationPoint;
    char text[160];
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!f)
        return fmi2Error;
    if (f->mode != STEPPING)
        return fail(f, "fmi2DoStep: not after initialization (or after an error)%s", "");
    if (!(h > 0.0) || !isfinite(h))
        return fail(f, "fmi2DoStep: the communication step must be positive and finite%s", "");
    if (!(fabs(point - f->time) <= 1e-9 * (1.0 + fabs(f->time)))) { /* NaN included */
        snprintf(text, sizeof text, "%.17g s, but the FMU is at %.17g s", point, f->time);
        return fail(f, "fmi2DoStep: the communication point is %s", text);
    }
    if (f->stop_defined && point + h > f->stop_time + 1e-9 * (1.0 + fabs(f->stop_time))) {
        snprintf(text, sizeof text, "%.17g s would pass the stop time %.17g s", point + h,
                 f->stop_time);
        return fail(f, "fmi2DoStep: a step to %s set by fmi2SetupExperiment", text);
    }
    if (f->rebuild && rebuild(f) != fmi2OK)
        return fmi2Error;
    status = vsj_step(&f->model, f->work, &f->scheme, f->s, f->inputs, h, f->ledger);
    if (status != VSJ_OK) {
        snprintf(text, sizeof text, "at t = %.9g s: %s", f->time, vsj_status_text(status));
        f->mode = FAILED;
        return fail(f, "fmi2DoStep: the step failed %s", text);
    }
    memcpy(f->record + f->at.applied, f->inputs, (size_t)f->ni * sizeof(double));
    account(f, h);
    f->time += h;
    return judge_step(f, point);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return c ? fail((fmu *)c, "fmi2CancelStep: steps are never asynchronous%s", "") : fmi2Error;
}

static fmi2Status no_status(fmi2Component c, const char *what) {
    return c ? fail((fmu *)c, "%s: steps are never asynchronous", what) : fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return no_status(c, "fmi2GetStatus");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    fmu *f = (fmu *)c;
    if (f && s == fmi2LastSuccessfulTime && value) {
        *value = f->time;
        return fmi2OK;
    }
    return no_status(c, "fmi2GetRealStatus");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s;
    (void)value;
    return no_status(c, "fmi2GetIntegerStatus");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    fmu *f = (fmu *)c;
    if (f && s == fmi2Terminated && value) {
        *value = fmi2False;
        return fmi2OK;
    }
    return no_status(c, "fmi2GetBooleanStatus");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s;
    (void)value;
    return no_status(c, "fmi2GetStringStatus");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return c ? fail((fmu *)c, "fmi2SetRealInputDerivatives: inputs are held over each "
                              "communication step (canInterpolateInputs is false)%s", "")
             : fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return c ? fail((fmu *)c, "fmi2GetRealOutputDerivatives: not provided "
                              "(maxOutputDerivativeOrder is 0)%s", "")
             : fmi2Error;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return c ? fail((fmu *)c, "fmi2GetDirectionalDerivative: not provided%s", "") : fmi2Error;
}

/* ---- FMU state ---------------------------------------------------------------- */

static void free_snapshot(snapshot *st) {
    if (!st)
        return;
    free(st->s);
    free(st->inputs);
    free(st->values);
    free(st->record);
    free(st->history);
    free(st);
}

static snapshot *new_snapshot(const fmu *f) {
    snapshot *st = (snapshot *)calloc(1, sizeof(snapshot));
    if (!st)
        return NULL;
    st->magic = SNAPSHOT_MAGIC;
    memcpy(st->guid, f->guid, sizeof st->guid);
    st->s = (double *)malloc((size_t)(f->ns + 1) * sizeof(double));
    st->inputs = (double *)malloc((size_t)(f->ni + 1) * sizeof(double));
    st->values = (double *)malloc((size_t)(f->n_parameters + 1) * sizeof(double));
    st->record = (double *)malloc((size_t)f->at.size * sizeof(double));
    st->history = (unsigned char *)malloc(f->history_size + 1);
    if (!st->s || !st->inputs || !st->values || !st->record || !st->history) {
        free_snapshot(st);
        return NULL;
    }
    return st;
}

static void take(const fmu *f, snapshot *st) {
    st->time = f->time;
    st->power_in = f->power_in;
    st->power_dissipated = f->power_dissipated;
    st->mode = f->mode;
    memcpy(st->s, f->s, (size_t)f->ns * sizeof(double));
    memcpy(st->inputs, f->inputs, (size_t)f->ni * sizeof(double));
    memcpy(st->values, f->values, (size_t)f->n_parameters * sizeof(double));
    memcpy(st->record, f->record, (size_t)f->at.size * sizeof(double));
    if (f->scheme.method == VSJ_METHOD_TIMESTEP)
        vsj_ts_save(&f->model, f->work, st->history);
}

static fmi2Status give(fmu *f, const snapshot *st) {
    int changed = memcmp(st->values, f->values, (size_t)f->n_parameters * sizeof(double)) != 0;
    memcpy(f->previous, f->values, (size_t)f->n_parameters * sizeof(double));
    memcpy(f->values, st->values, (size_t)f->n_parameters * sizeof(double));
    if ((changed || f->rebuild) && rebuild(f) != fmi2OK) {
        restore(f, 1);
        return fmi2Error;
    }
    f->time = st->time;
    f->power_in = st->power_in;
    f->power_dissipated = st->power_dissipated;
    f->mode = st->mode;
    memcpy(f->s, st->s, (size_t)f->ns * sizeof(double));
    memcpy(f->inputs, st->inputs, (size_t)f->ni * sizeof(double));
    memcpy(f->record, st->record, (size_t)f->at.size * sizeof(double));
    if (f->scheme.method == VSJ_METHOD_TIMESTEP)
        vsj_ts_restore(&f->model, f->work, st->history);
    return fmi2OK;
}

/* Whether `FMUstate` is a state this FMU (any of its instances) took. */
static int ours(const fmu *f, const snapshot *st) {
    return st->magic == SNAPSHOT_MAGIC && strncmp(st->guid, f->guid, GUID_MAX) == 0;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    fmu *f = (fmu *)c;
    snapshot *st;
    if (!f || !FMUstate)
        return f ? fail(f, "fmi2GetFMUstate: null pointer%s", "") : fmi2Error;
    if (*FMUstate && !ours(f, (const snapshot *)*FMUstate))
        return fail(f, "fmi2GetFMUstate: the state to reuse is another FMU's%s", "");
    st = *FMUstate ? (snapshot *)*FMUstate : new_snapshot(f);
    if (!st)
        return fail(f, "fmi2GetFMUstate: out of memory%s", "");
    take(f, st);
    *FMUstate = st;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    fmu *f = (fmu *)c;
    if (!f || !FMUstate)
        return f ? fail(f, "fmi2SetFMUstate: null state%s", "") : fmi2Error;
    if (!ours(f, (const snapshot *)FMUstate))
        return fail(f, "fmi2SetFMUstate: the state is another FMU's (another model, vsj "
                       "version or export), not one this FMU took%s", "");
    return give(f, (const snapshot *)FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    fmu *f = (fmu *)c;
    if (!f)
        return fmi2Error;
    if (FMUstate && *FMUstate) {
        if (!ours(f, (const snapshot *)*FMUstate))
            return fail(f, "fmi2FreeFMUstate: the state is another FMU's%s", "");
        free_snapshot((snapshot *)*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

/* Serialized: a header (magic, format, the GUID that fingerprints the model, the
 * sizes: ns, ni, parameters, record, history), the snapshot's fields, then the
 * 64-bit FNV-1a checksum of everything before it. Native byte order: a state is
 * read back on the platform that wrote it. */
#define HEADER_SIZE (2 * sizeof(uint32_t) + GUID_MAX + 5 * sizeof(int64_t))

static size_t serialized_size(const fmu *f) {
    return HEADER_SIZE + 3 * sizeof(double) + sizeof(int32_t)
           + (size_t)(f->ns + f->ni + f->n_parameters + f->at.size) * sizeof(double)
           + f->history_size + sizeof(uint64_t);
}

static uint64_t checksum(const fmi2Byte *bytes, size_t size) {
    uint64_t h = 0xcbf29ce484222325u;
    size_t i;
    for (i = 0; i < size; i++) {
        h ^= (unsigned char)bytes[i];
        h *= 0x100000001b3u;
    }
    return h;
}

static void sizes_of(const fmu *f, int64_t sizes[5]) {
    sizes[0] = f->ns;
    sizes[1] = f->ni;
    sizes[2] = f->n_parameters;
    sizes[3] = f->at.size;
    sizes[4] = (int64_t)f->history_size;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    fmu *f = (fmu *)c;
    if (!f || !FMUstate || !size)
        return f ? fail(f, "fmi2SerializedFMUstateSize: null argument%s", "") : fmi2Error;
    if (!ours(f, (const snapshot *)FMUstate))
        return fail(f, "fmi2SerializedFMUstateSize: the state is another FMU's%s", "");
    *size = serialized_size(f);
    return fmi2OK;
}

#define PUT(ptr, bytes)                                                                          \
    do {                                                                                         \
        memcpy(at, (ptr), (bytes));                                                              \
        at += (bytes);                                                                           \
    } while (0)
#define GET(ptr, bytes)                                                                          \
    do {                                                                                         \
        memcpy((ptr), at, (bytes));                                                              \
        at += (bytes);                                                                           \
    } while (0)

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    fmu *f = (fmu *)c;
    const snapshot *st = (const snapshot *)FMUstate;
    char *at = serializedState;
    uint32_t word[2] = {STATE_MAGIC, STATE_FORMAT};
    int32_t mode;
    int64_t sizes[5];
    uint64_t sum;
    if (!f || !st || !serializedState)
        return f ? fail(f, "fmi2SerializeFMUstate: null argument%s", "") : fmi2Error;
    if (!ours(f, st))
        return fail(f, "fmi2SerializeFMUstate: the state is another FMU's%s", "");
    if (size < serialized_size(f))
        return fail(f, "fmi2SerializeFMUstate: the buffer is too small%s", "");
    sizes_of(f, sizes);
    mode = (int32_t)st->mode;
    PUT(word, sizeof word);
    PUT(f->guid, GUID_MAX);
    PUT(sizes, sizeof sizes);
    PUT(&st->time, sizeof(double));
    PUT(&st->power_in, sizeof(double));
    PUT(&st->power_dissipated, sizeof(double));
    PUT(&mode, sizeof mode);
    PUT(st->s, (size_t)f->ns * sizeof(double));
    PUT(st->inputs, (size_t)f->ni * sizeof(double));
    PUT(st->values, (size_t)f->n_parameters * sizeof(double));
    PUT(st->record, (size_t)f->at.size * sizeof(double));
    PUT(st->history, f->history_size);
    sum = checksum(serializedState, (size_t)(at - serializedState));
    PUT(&sum, sizeof sum);
    return fmi2OK;
}

/* Why the header of a serialized state is not this FMU's (NULL: it is). */
static const char *foreign_header(const fmu *f, const fmi2Byte *bytes, size_t size, char *why,
                                  size_t why_size) {
    uint32_t word[2];
    char guid[GUID_MAX + 1];
    int64_t sizes[5], mine[5];
    uint64_t sum;
    if (size < HEADER_SIZE + sizeof(uint64_t))
        return "it is too short to be a state of a vsj FMU";
    memcpy(word, bytes, sizeof word);
    memcpy(guid, bytes + sizeof word, GUID_MAX);
    guid[GUID_MAX] = 0;
    memcpy(sizes, bytes + sizeof word + GUID_MAX, sizeof sizes);
    if (word[0] != STATE_MAGIC)
        return "it is not a state of a vsj FMU";
    if (word[1] != STATE_FORMAT) {
        snprintf(why, why_size, "it is a state in format %u, this FMU reads format %u (another "
                 "version of vsj)", (unsigned)word[1], (unsigned)STATE_FORMAT);
        return why;
    }
    if (strcmp(guid, f->guid) != 0) {
        snprintf(why, why_size, "it is a state of another FMU (GUID %.40s; this FMU's is %s: "
                 "another model, vsj version or export)", guid, f->guid);
        return why;
    }
    sizes_of(f, mine);
    if (memcmp(sizes, mine, sizeof sizes) != 0 || size != serialized_size(f))
        return "its sizes are not this FMU's";
    memcpy(&sum, bytes + size - sizeof sum, sizeof sum);
    if (checksum(bytes, size - sizeof sum) != sum)
        return "it is damaged (its checksum does not match)";
    return NULL;
}

/* Why a state's fields cannot be this FMU's (NULL: they can). */
static const char *bad_fields(const fmu *f, const snapshot *st, char *why, size_t size) {
    static const char *const names[4] = {"state", "inputs", "parameters", "run record"};
    const double *arrays[4];
    int64_t counts[4], a, k;
    char reason[200];
    arrays[0] = st->s;
    arrays[1] = st->inputs;
    arrays[2] = st->values;
    arrays[3] = st->record;
    counts[0] = f->ns;
    counts[1] = f->ni;
    counts[2] = f->n_parameters;
    counts[3] = f->at.size;
    if (!isfinite(st->time) || !isfinite(st->power_in) || !isfinite(st->power_dissipated))
        return "its time or power is not finite";
    if (st->mode < INSTANTIATED || st->mode > FAILED)
        return "its mode is not one of this FMU's";
    for (a = 0; a < 4; a++)
        for (k = 0; k < counts[a]; k++)
            if (!isfinite(arrays[a][k])) {
                snprintf(why, size, "entry %lld of its %s is not finite", (long long)k,
                         names[a]);
                return why;
            }
    for (k = 0; k < f->n_parameters; k++)
        if (refusal(f->parameters + k, st->values[k], reason, sizeof reason)) {
            snprintf(why, size, "its %s = %g is outside the parameter's range: %s",
                     f->parameters[k].key, st->values[k], reason);
            return why;
        }
    if (broken_relation(f, st->values) >= 0)
        return "its parameters break a relation between keys";
    return NULL;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    fmu *f = (fmu *)c;
    const char *at = serializedState, *problem;
    char why[400];
    int32_t mode;
    snapshot *st;
    if (!f || !serializedState || !FMUstate)
        return f ? fail(f, "fmi2DeSerializeFMUstate: null argument%s", "") : fmi2Error;
    if (*FMUstate && !ours(f, (const snapshot *)*FMUstate))
        return fail(f, "fmi2DeSerializeFMUstate: the state to reuse is another FMU's%s", "");
    problem = foreign_header(f, serializedState, size, why, sizeof why);
    if (problem)
        return fail(f, "fmi2DeSerializeFMUstate: the bytes are refused: %s", problem);
    st = new_snapshot(f);
    if (!st)
        return fail(f, "fmi2DeSerializeFMUstate: out of memory%s", "");
    at += HEADER_SIZE;
    GET(&st->time, sizeof(double));
    GET(&st->power_in, sizeof(double));
    GET(&st->power_dissipated, sizeof(double));
    GET(&mode, sizeof mode);
    st->mode = (int)mode;
    GET(st->s, (size_t)f->ns * sizeof(double));
    GET(st->inputs, (size_t)f->ni * sizeof(double));
    GET(st->values, (size_t)f->n_parameters * sizeof(double));
    GET(st->record, (size_t)f->at.size * sizeof(double));
    GET(st->history, f->history_size);
    problem = bad_fields(f, st, why, sizeof why);
    if (problem) {
        free_snapshot(st);
        return fail(f, "fmi2DeSerializeFMUstate: the bytes are refused: %s", problem);
    }
    if (*FMUstate)
        free_snapshot((snapshot *)*FMUstate);
    *FMUstate = st;
    return fmi2OK;
}

/* ---- model exchange: not this FMU's interface ---------------------------------- */

static fmi2Status not_me(fmi2Component c, const char *what) {
    return c ? fail((fmu *)c, "%s: vsj's FMU is for co-simulation only", what) : fmi2Error;
}

fmi2Status fmi2EnterEventMode(fmi2Component c) { return not_me(c, "fmi2EnterEventMode"); }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    (void)eventInfo;
    return not_me(c, "fmi2NewDiscreteStates");
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    return not_me(c, "fmi2EnterContinuousTimeMode");
}
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c,
                                       fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    (void)enterEventMode;
    (void)terminateSimulation;
    return not_me(c, "fmi2CompletedIntegratorStep");
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    (void)time;
    return not_me(c, "fmi2SetTime");
}
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    (void)x;
    (void)nx;
    return not_me(c, "fmi2SetContinuousStates");
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    (void)derivatives;
    (void)nx;
    return not_me(c, "fmi2GetDerivatives");
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    (void)eventIndicators;
    (void)ni;
    return not_me(c, "fmi2GetEventIndicators");
}
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    (void)x;
    (void)nx;
    return not_me(c, "fmi2GetContinuousStates");
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    (void)x_nominal;
    (void)nx;
    return not_me(c, "fmi2GetNominalsOfContinuousStates");
}
