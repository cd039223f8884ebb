/* vsj's wrist as an FMI 2.0 co-simulation FMU, on the C engine (vsj.h).
 *
 * The FMU's resources hold the wrist exported by vsj (`model.json`, read by
 * vsj_load_model) and `fmu.txt`, written by vsj.fmu beside modelDescription.xml:
 *
 *     vsj-fmu 1
 *     parameters P
 *     then, per tunable parameter (value reference 100 + its index):
 *       start min max count, and count lines "array index slope"
 *     pivot q0 q0_min q0_max
 *
 * A tunable parameter changes engine arrays affinely: entry `index` of array
 * `array` (0: the kinetic energy matrix, 1: the element parameters) is its
 * exported value plus slope times the parameter's change (vsj.fmu checks at
 * export that this holds for each parameter and for all of them together).
 * The inverse of the mass matrix's free block is recomputed from the result.
 *
 * Value references. Real: inputs 0..4 (motor commands, then the external
 * torques tau_x, tau_y, in the model file's order); outputs 10..22 (see
 * `enum output`); 99 the initial pivot position; 100.. the parameters.
 * Integer: 0 the number of stuck friction elements.
 *
 * Every call checks its instance and its arguments; a bad call returns
 * fmi2Error and says why through the importer's logger. Instances share
 * nothing: any number may run at once, each from one thread at a time.
 */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2.h"
#include "vsj.h"

#define GUID_MAX 64
#define VR_INPUT 0
#define VR_OUTPUT 10
#define VR_Q0 99
#define VR_PARAMETER 100
#define VR_STUCK 0
#define STATE_MAGIC 0x76736a31u /* "vsj1" */

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
    double start, min, max;
    int64_t first, count;
} parameter;

/* what fmi2GetFMUstate keeps: everything that a later step depends on */
typedef struct {
    double time, power_in, power_dissipated;
    int mode;
    double *s, *inputs, *values;
    unsigned char *history;
} snapshot;

typedef struct {
    char *name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging;
    vsj_loaded *loaded;
    vsj_model model; /* the loaded one with this instance's mass, Minv and par */
    double *mass, *minv, *par;
    int64_t n_mass, n_par_values;
    int64_t n_parameters;
    parameter *parameters;
    entry *entries;
    double *values; /* current parameter values */
    double q0, q0_min, q0_max, q0_start;
    int64_t pivot_index; /* entry of the stepper state that sets the pivot angle */
    double pivot_coef;
    vsj_work *work;
    int64_t ns, ni, nacc;
    double *s, *inputs, *ledger, setting[3];
    int method;
    int64_t rows[5];
    unsigned char *stuck;
    double time, power_in, power_dissipated;
    int mode, rebuild;
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

static int read_map(fmu *f, const char *path, char *why, size_t size) {
    FILE *file = fopen(path, "r");
    char word[32];
    int version;
    long long count, p, k, total = 0;
    if (!file) {
        snprintf(why, size, "cannot open %s", path);
        return 0;
    }
    if (fscanf(file, "%31s %d", word, &version) != 2 || strcmp(word, "vsj-fmu") != 0
        || version != 1 || fscanf(file, "%31s %lld", word, &count) != 2
        || strcmp(word, "parameters") != 0 || count < 0 || count > 100000) {
        snprintf(why, size, "%s: not a vsj-fmu 1 map", path);
        fclose(file);
        return 0;
    }
    f->n_parameters = count;
    f->parameters = (parameter *)calloc((size_t)(count ? count : 1), sizeof(parameter));
    f->values = (double *)calloc((size_t)(count ? count : 1), sizeof(double));
    f->entries = NULL;
    if (!f->parameters || !f->values) {
        fclose(file);
        snprintf(why, size, "out of memory");
        return 0;
    }
    for (p = 0; p < count; p++) {
        parameter *par = f->parameters + p;
        long long entries;
        entry *grown;
        if (fscanf(file, "%lf %lf %lf %lld", &par->start, &par->min, &par->max, &entries) != 4
            || entries < 0 || entries > 1000000) {
            snprintf(why, size, "%s: parameter %lld unreadable", path, p);
            fclose(file);
            return 0;
        }
        par->first = total;
        par->count = entries;
        grown = (entry *)realloc(f->entries, (size_t)(total + entries + 1) * sizeof(entry));
        if (!grown) {
            fclose(file);
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
                snprintf(why, size, "%s: parameter %lld has a bad entry", path, p);
                fclose(file);
                return 0;
            }
            e->array = array;
            e->index = index;
        }
        total += entries;
        f->values[p] = par->start;
    }
    if (fscanf(file, "%31s %lf %lf %lf", word, &f->q0_start, &f->q0_min, &f->q0_max) != 4
        || strcmp(word, "pivot") != 0) {
        snprintf(why, size, "%s: no pivot line", path);
        fclose(file);
        return 0;
    }
    fclose(file);
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
    free(f->s);
    free(f->inputs);
    free(f->ledger);
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

/* The engine arrays for the current parameter values, checked; the stepper
 * prepared for them. */
static fmi2Status rebuild(fmu *f) {
    char why[512];
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
    if (!invert_free_block(f))
        return fail(f, "the parameters make the mass matrix singular%s", "");
    if (vsj_check_model(&f->model, why, sizeof why) != VSJ_OK)
        return fail(f, "the parameters give an invalid model: %s", why);
    if (f->method == VSJ_STEP_TIMESTEP && vsj_ts_prepare(&f->model, f->work) != VSJ_OK)
        return fail(f, "the time-stepper cannot be prepared for these parameters%s", "");
    f->rebuild = 0;
    return fmi2OK;
}

static void initial_state(fmu *f) {
    const double *p = f->par + VSJ_NPAR * (f->model.n_rows - 1);
    double amplitude = p[0];
    memcpy(f->s, f->loaded->initial_state, (size_t)f->ns * sizeof(double));
    if (p[2] > 0.0 && amplitude > 0.0)
        f->s[f->pivot_index] = asin(f->q0 / amplitude) / f->pivot_coef;
    f->time = 0.0;
    f->power_in = 0.0;
    f->power_dissipated = 0.0;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    fmu *f;
    char why[512], *path;
    int64_t k, j;
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
    if (fmuType != fmi2CoSimulation) {
        fail(f, "vsj's FMU is for co-simulation only%s", "");
        free_fmu(f);
        return NULL;
    }
    if (!fmuResourceLocation) {
        fail(f, "no resource location given%s", "");
        free_fmu(f);
        return NULL;
    }
    path = resource_path(fmuResourceLocation, "model.json");
    f->loaded = path ? vsj_load_model(path, why, sizeof why) : NULL;
    free(path);
    if (!f->loaded) {
        fail(f, "cannot load the model: %s", path ? why : "out of memory");
        free_fmu(f);
        return NULL;
    }
    (void)fmuGUID; /* the importer checks it against modelDescription.xml */
    f->model = f->loaded->model;
    f->n_mass = (f->model.n + f->model.n_sources) * (f->model.n + f->model.n_sources);
    f->n_par_values = f->model.n_rows * VSJ_NPAR;
    path = resource_path(fmuResourceLocation, "fmu.txt");
    if (!path || !read_map(f, path, why, sizeof why)) {
        fail(f, "cannot read the parameter map: %s", path ? why : "out of memory");
        free(path);
        free_fmu(f);
        return NULL;
    }
    free(path);
    f->ns = vsj_step_state_size(&f->model);
    f->ni = f->loaded->n_inputs;
    f->nacc = vsj_n_acc(&f->model);
    f->mass = (double *)malloc((size_t)f->n_mass * sizeof(double));
    f->minv = (double *)malloc((size_t)(f->model.n * f->model.n + 1) * sizeof(double));
    f->par = (double *)malloc((size_t)f->n_par_values * sizeof(double));
    f->s = (double *)calloc((size_t)f->ns + 1, sizeof(double));
    f->inputs = (double *)calloc((size_t)f->ni + 1, sizeof(double));
    f->ledger = (double *)calloc((size_t)f->nacc + 1, sizeof(double));
    f->stuck = (unsigned char *)calloc((size_t)f->model.n_frictions + 1, 1);
    f->work = vsj_work_new(&f->model);
    if (!f->mass || !f->minv || !f->par || !f->s || !f->inputs || !f->ledger || !f->stuck
        || !f->work) {
        fail(f, "out of memory%s", "");
        free_fmu(f);
        return NULL;
    }
    f->model.mass = f->mass;
    f->model.Minv = f->minv;
    f->model.par = f->par;
    if (f->ni != 5) {
        fail(f, "the model file must have 5 inputs (three motors, tau_x, tau_y)%s", "");
        free_fmu(f);
        return NULL;
    }
    for (k = 0; k < 5; k++) {
        f->rows[k] = -1;
        for (j = 0; j < f->loaded->n_outputs; j++)
            if (strcmp(f->loaded->output_names[j], ROW_NAMES[k]) == 0)
                f->rows[k] = j;
        if (f->rows[k] < 0) {
            fail(f, "the model file has no output %s", ROW_NAMES[k]);
            free_fmu(f);
            return NULL;
        }
    }
    if (f->model.n_springs != 2 || !find_pivot(f)) {
        fail(f, "the model file is not a wrist (two springs and one pivot drive)%s", "");
        free_fmu(f);
        return NULL;
    }
    f->method = f->loaded->solver;
    if (f->method == VSJ_STEP_DOPRI) {
        f->setting[0] = f->loaded->rtol;
        f->setting[1] = f->loaded->atol;
        f->setting[2] = 1e7;
    } else if (f->method == VSJ_STEP_TIMESTEP) {
        f->setting[0] = f->loaded->step;
    } else {
        fail(f, "the model file's solver must be dopri or the time-stepper%s", "");
        free_fmu(f);
        return NULL;
    }
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
    (void)stopTimeDefined;
    (void)stopTime;
    if (!f)
        return fmi2Error;
    if (f->mode != INSTANTIATED)
        return fail(f, "fmi2SetupExperiment: only after fmi2Instantiate or fmi2Reset%s", "");
    if (!isfinite(startTime))
        return fail(f, "fmi2SetupExperiment: the start time must be finite%s", "");
    f->time = startTime;
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

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    fmu *f = (fmu *)c;
    double start;
    if (!f)
        return fmi2Error;
    if (f->mode != INITIALIZING)
        return fail(f, "fmi2ExitInitializationMode: not in initialization mode%s", "");
    start = f->time;
    if (f->rebuild && rebuild(f) != fmi2OK) {
        f->mode = FAILED;
        return fmi2Error;
    }
    initial_state(f);
    f->time = start;
    f->mode = STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    fmu *f = (fmu *)c;
    if (!f)
        return fmi2Error;
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

static double deflection(const fmu *f, int64_t k) {
    const vsj_model *m = &f->model;
    int64_t r = m->n_frictions + k, i;
    double value = 0.0;
    for (i = m->xp[r]; i < m->xp[r + 1]; i++)
        value += m->xv[i] * f->s[m->xc[i]];
    for (i = m->up[r]; i < m->up[r + 1]; i++)
        value += m->uv[i] * f->s[2 * m->n + m->n_motors + m->uc[i]];
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
    case DEFLECTION_1: return deflection(f, 0);
    case DEFLECTION_2: return deflection(f, 1);
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

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    fmu *f = (fmu *)c;
    size_t k;
    char text[160];
    if (!f)
        return fmi2Error;
    if (nvr && (!vr || !value))
        return fail(f, "fmi2SetReal: null array%s", "");
    for (k = 0; k < nvr; k++) { /* all checked before any is set */
        fmi2ValueReference r = vr[k];
        double x = value[k];
        if (!isfinite(x)) {
            snprintf(text, sizeof text, "%u", r);
            return fail(f, "fmi2SetReal: value reference %s: the value is not finite", text);
        }
        if (r < (fmi2ValueReference)f->ni)
            continue;
        if (r == VR_Q0) {
            if (f->mode != INSTANTIATED && f->mode != INITIALIZING)
                return fail(f, "fmi2SetReal: the initial pivot position is set before "
                               "initialization ends%s", "");
            if (x < f->q0_min || x > f->q0_max) {
                snprintf(text, sizeof text, "%g m is outside [%g, %g] m", x, f->q0_min,
                         f->q0_max);
                return fail(f, "fmi2SetReal: pivot_q0: %s", text);
            }
        } else if (r >= VR_PARAMETER && r < VR_PARAMETER + (fmi2ValueReference)f->n_parameters) {
            const parameter *p = f->parameters + (r - VR_PARAMETER);
            if (x < p->min || x > p->max) {
                snprintf(text, sizeof text, "%u: %g is outside its range [%g, %g]", r, x,
                         p->min, p->max);
                return fail(f, "fmi2SetReal: parameter %s", text);
            }
        } else {
            snprintf(text, sizeof text, "%u", r);
            return fail(f, "fmi2SetReal: value reference %s is not an input or a parameter",
                        text);
        }
    }
    for (k = 0; k < nvr; k++) {
        fmi2ValueReference r = vr[k];
        if (r < (fmi2ValueReference)f->ni)
            f->inputs[r] = value[k];
        else if (r == VR_Q0)
            f->q0 = value[k];
        else if (f->values[r - VR_PARAMETER] != value[k]) {
            f->values[r - VR_PARAMETER] = value[k];
            f->rebuild = 1;
        }
    }
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
        value[k] = f->method == VSJ_STEP_TIMESTEP && f->mode == STEPPING
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

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    fmu *f = (fmu *)c;
    const vsj_model *m;
    int64_t i, s_n, nl, nm, nf, nk, at;
    int status;
    double work_in = 0.0, lost = 0.0, h = communicationStepSize;
    char text[160];
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!f)
        return fmi2Error;
    if (f->mode != STEPPING)
        return fail(f, "fmi2DoStep: not after initialization (or after an error)%s", "");
    if (!(h > 0.0) || !isfinite(h))
        return fail(f, "fmi2DoStep: the communication step must be positive and finite%s", "");
    if (fabs(currentCommunicationPoint - f->time) > 1e-9 * (1.0 + fabs(f->time))) {
        snprintf(text, sizeof text, "%.17g s, but the FMU is at %.17g s",
                 currentCommunicationPoint, f->time);
        return fail(f, "fmi2DoStep: the communication point is %s", text);
    }
    if (f->rebuild && rebuild(f) != fmi2OK)
        return fmi2Error;
    m = &f->model;
    status = vsj_step_period(m, f->work, f->s, f->inputs, h, f->method, f->setting, f->ledger);
    if (status != VSJ_OK) {
        snprintf(text, sizeof text, "at t = %.9g s: %s", f->time, vsj_status_text(status));
        f->mode = FAILED;
        return fail(f, "fmi2DoStep: the step failed %s", text);
    }
    s_n = m->n_sources;
    nl = m->n_loads;
    nm = m->n_motors;
    nf = m->n_frictions;
    nk = m->n_springs;
    for (i = 0; i < s_n + nl + nm; i++) /* sources, loads, motor supplies */
        work_in += f->ledger[i];
    at = s_n + nl + nm;
    for (i = 0; i < nf + nm; i++) /* friction, then armature resistance */
        lost += f->ledger[at + i];
    at += nf + nm + nk; /* past the springs' own work: the pivot's, then the stops' */
    if (f->par[VSJ_NPAR * (m->n_rows - 1) + 2] > 0.0)
        for (i = 0; i < nk; i++)
            work_in += f->ledger[at + i];
    at += nk;
    for (i = 0; i < nk; i++)
        lost += f->ledger[at + i];
    f->power_in = work_in / h;
    f->power_dissipated = lost / h;
    f->time += h;
    return fmi2OK;
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

static snapshot *new_snapshot(const fmu *f) {
    snapshot *st = (snapshot *)calloc(1, sizeof(snapshot));
    if (!st)
        return NULL;
    st->s = (double *)malloc((size_t)(f->ns + 1) * sizeof(double));
    st->inputs = (double *)malloc((size_t)(f->ni + 1) * sizeof(double));
    st->values = (double *)malloc((size_t)(f->n_parameters + 1) * sizeof(double));
    st->history = (unsigned char *)malloc(f->history_size + 1);
    if (!st->s || !st->inputs || !st->values || !st->history) {
        free(st->s);
        free(st->inputs);
        free(st->values);
        free(st->history);
        free(st);
        return NULL;
    }
    return st;
}

static void free_snapshot(snapshot *st) {
    if (!st)
        return;
    free(st->s);
    free(st->inputs);
    free(st->values);
    free(st->history);
    free(st);
}

static void take(const fmu *f, snapshot *st) {
    st->time = f->time;
    st->power_in = f->power_in;
    st->power_dissipated = f->power_dissipated;
    st->mode = f->mode;
    memcpy(st->s, f->s, (size_t)f->ns * sizeof(double));
    memcpy(st->inputs, f->inputs, (size_t)f->ni * sizeof(double));
    memcpy(st->values, f->values, (size_t)f->n_parameters * sizeof(double));
    if (f->method == VSJ_STEP_TIMESTEP)
        vsj_ts_save(&f->model, f->work, st->history);
}

static fmi2Status give(fmu *f, const snapshot *st) {
    int changed = memcmp(st->values, f->values, (size_t)f->n_parameters * sizeof(double)) != 0;
    memcpy(f->values, st->values, (size_t)f->n_parameters * sizeof(double));
    if ((changed || f->rebuild) && rebuild(f) != fmi2OK)
        return fmi2Error;
    f->time = st->time;
    f->power_in = st->power_in;
    f->power_dissipated = st->power_dissipated;
    f->mode = st->mode;
    memcpy(f->s, st->s, (size_t)f->ns * sizeof(double));
    memcpy(f->inputs, st->inputs, (size_t)f->ni * sizeof(double));
    if (f->method == VSJ_STEP_TIMESTEP)
        vsj_ts_restore(&f->model, f->work, st->history);
    return fmi2OK;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    fmu *f = (fmu *)c;
    snapshot *st;
    if (!f || !FMUstate)
        return f ? fail(f, "fmi2GetFMUstate: null pointer%s", "") : fmi2Error;
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
    return give(f, (const snapshot *)FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    if (!c)
        return fmi2Error;
    if (FMUstate) {
        free_snapshot((snapshot *)*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

/* serialized: magic, sizes (ns, ni, parameters, history), then the fields */
static size_t serialized_size(const fmu *f) {
    return sizeof(uint32_t) + 4 * sizeof(int64_t) + 3 * sizeof(double) + sizeof(int)
           + (size_t)(f->ns + f->ni + f->n_parameters) * sizeof(double) + f->history_size;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    fmu *f = (fmu *)c;
    if (!f || !FMUstate || !size)
        return f ? fail(f, "fmi2SerializedFMUstateSize: null argument%s", "") : fmi2Error;
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
    uint32_t magic = STATE_MAGIC;
    int64_t sizes[4];
    if (!f || !st || !serializedState)
        return f ? fail(f, "fmi2SerializeFMUstate: null argument%s", "") : fmi2Error;
    if (size < serialized_size(f))
        return fail(f, "fmi2SerializeFMUstate: the buffer is too small%s", "");
    sizes[0] = f->ns;
    sizes[1] = f->ni;
    sizes[2] = f->n_parameters;
    sizes[3] = (int64_t)f->history_size;
    PUT(&magic, sizeof magic);
    PUT(sizes, sizeof sizes);
    PUT(&st->time, sizeof(double));
    PUT(&st->power_in, sizeof(double));
    PUT(&st->power_dissipated, sizeof(double));
    PUT(&st->mode, sizeof(int));
    PUT(st->s, (size_t)f->ns * sizeof(double));
    PUT(st->inputs, (size_t)f->ni * sizeof(double));
    PUT(st->values, (size_t)f->n_parameters * sizeof(double));
    PUT(st->history, f->history_size);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    fmu *f = (fmu *)c;
    const char *at = serializedState;
    uint32_t magic;
    int64_t sizes[4];
    snapshot *st;
    if (!f || !serializedState || !FMUstate)
        return f ? fail(f, "fmi2DeSerializeFMUstate: null argument%s", "") : fmi2Error;
    if (size != serialized_size(f))
        return fail(f, "fmi2DeSerializeFMUstate: the bytes are not a state of this FMU%s", "");
    GET(&magic, sizeof magic);
    GET(sizes, sizeof sizes);
    if (magic != STATE_MAGIC || sizes[0] != f->ns || sizes[1] != f->ni
        || sizes[2] != f->n_parameters || sizes[3] != (int64_t)f->history_size)
        return fail(f, "fmi2DeSerializeFMUstate: the bytes are not a state of this FMU%s", "");
    st = new_snapshot(f);
    if (!st)
        return fail(f, "fmi2DeSerializeFMUstate: out of memory%s", "");
    GET(&st->time, sizeof(double));
    GET(&st->power_in, sizeof(double));
    GET(&st->power_dissipated, sizeof(double));
    GET(&st->mode, sizeof(int));
    GET(st->s, (size_t)f->ns * sizeof(double));
    GET(st->inputs, (size_t)f->ni * sizeof(double));
    GET(st->values, (size_t)f->n_parameters * sizeof(double));
    GET(st->history, f->history_size);
    if (st->mode < INSTANTIATED || st->mode > FAILED) {
        free_snapshot(st);
        return fail(f, "fmi2DeSerializeFMUstate: the bytes are not a state of this FMU%s", "");
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
