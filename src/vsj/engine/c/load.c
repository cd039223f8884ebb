/* Models from files: what `vsj export-model` writes (and the FMU carries).
 *
 * A program file is little-endian binary, every field 8 bytes:
 *   "VSJP", format version (uint32), 0 (uint64): 16 bytes
 *   method (enum vsj_method), period, rtol, atol, step, substeps, max_steps
 *   inputs: count, then per input its name (length, UTF-8 bytes padded to 8)
 *   the initial stepper state: count, values
 *   outputs: count, then per output its name, then the rows (count x state values)
 *   the model: length in bytes, then the model's binary form (blob.c), padded to 8
 *   an FNV-1a 64-bit checksum of everything before it
 * Every length is checked against the bytes at hand before it is used; no parser
 * of text is involved, so the locale of a host program cannot change a number.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

enum { PROGRAM_VERSION = 3, MAX_NAME = 4096 };

typedef struct reader {
    const unsigned char *data;
    size_t length, at;
    char *message;
    size_t size;
    int failed;
} reader;

static void rfail(reader *r, const char *what) {
    if (!r->failed && r->message && r->size)
        snprintf(r->message, r->size, "model file: %s", what);
    r->failed = 1;
}

static int little(void) {
    const uint32_t one = 1;
    unsigned char first;
    memcpy(&first, &one, 1);
    return first == 1;
}

static void take8(reader *r, void *value) {
    unsigned char raw[8];
    int i;
    if (r->failed || r->length - r->at < 8 || r->at > r->length) {
        rfail(r, "truncated");
        memset(value, 0, 8);
        return;
    }
    for (i = 0; i < 8; i++)
        raw[little() ? i : 7 - i] = r->data[r->at + (size_t)i];
    memcpy(value, raw, 8);
    r->at += 8;
}

static double real(reader *r) {
    double v;
    take8(r, &v);
    return v;
}

static int64_t count(reader *r, int64_t limit, const char *what) {
    int64_t v;
    take8(r, &v);
    if (!r->failed && (v < 0 || v > limit)) {
        char text[128];
        snprintf(text, sizeof text, "%s: %lld is outside 0..%lld", what, (long long)v,
                 (long long)limit);
        rfail(r, text);
        return 0;
    }
    return v;
}

/* A name: its length, its bytes, padded to 8; a string of its own (NUL-terminated). */
static char *name(reader *r) {
    int64_t len = count(r, MAX_NAME, "a name's length");
    size_t padded = ((size_t)len + 7) / 8 * 8;
    char *out;
    if (r->failed)
        return NULL;
    if (r->length - r->at < padded) {
        rfail(r, "truncated (a name)");
        return NULL;
    }
    out = (char *)malloc((size_t)len + 1);
    if (!out) {
        rfail(r, "out of memory");
        return NULL;
    }
    memcpy(out, r->data + r->at, (size_t)len);
    out[len] = '\0';
    if (memchr(out, '\0', (size_t)len)) {
        free(out);
        rfail(r, "a name holds a NUL byte");
        return NULL;
    }
    r->at += padded;
    return out;
}

static double *reals(reader *r, int64_t n) {
    double *out = (double *)calloc((size_t)(n > 0 ? n : 1), sizeof(double));
    int64_t i;
    if (!out) {
        rfail(r, "out of memory");
        return NULL;
    }
    for (i = 0; i < n && !r->failed; i++)
        out[i] = real(r);
    return out;
}

void vsj_free_loaded(vsj_loaded *l) {
    int64_t i;
    if (!l)
        return;
    for (i = 0; l->input_names && i < l->n_inputs; i++)
        free(l->input_names[i]);
    for (i = 0; l->output_names && i < l->n_outputs; i++)
        free(l->output_names[i]);
    free(l->input_names);
    free(l->output_names);
    free(l->initial_state);
    free(l->output_rows);
    vsj_model_free(l->owned);
    free(l);
}

static char **names(reader *r, int64_t n) {
    char **out = (char **)calloc((size_t)(n > 0 ? n : 1), sizeof(char *));
    int64_t i;
    if (!out) {
        rfail(r, "out of memory");
        return NULL;
    }
    for (i = 0; i < n && !r->failed; i++)
        out[i] = name(r);
    return out;
}

/* The program's fields, then its model. */
static void read_program(reader *r, vsj_loaded *l) {
    int64_t method, state, blob, substeps, max_steps, i;
    double rtol, atol, step;
    char inner[256];
    take8(r, &method);
    l->period = real(r);
    rtol = real(r);
    atol = real(r);
    step = real(r);
    take8(r, &substeps);
    take8(r, &max_steps);
    if (r->failed)
        return;
    /* the period always, and the settings of its method (the tolerances within the
     * ranges vsj.simulate.RANGES gives them; steps a period may take: a step longer
     * than the period is one shortened step, as vsj_step takes it) */
    if (method != VSJ_METHOD_DOPRI && method != VSJ_METHOD_RK4 && method != VSJ_METHOD_TIMESTEP
        && method != VSJ_METHOD_ROSENBROCK)
        rfail(r, "its solver is not one of dopri, rk4, timestep and rosenbrock");
    else if (!(l->period > 0.0 && l->period < 1e9))
        rfail(r, "its period is not a time in (0, 1e9) s");
    else if (max_steps < 1)
        rfail(r, "its max_steps is not a whole number >= 1");
    else if ((method == VSJ_METHOD_DOPRI || method == VSJ_METHOD_ROSENBROCK)
             && !vsj__tolerances_ok(rtol, atol))
        rfail(r, "its tolerances are out of range (rtol in [1e-14, 1e-2], atol in "
                 "[1e-20, 1e-2])");
    else if (method == VSJ_METHOD_RK4 && (substeps < 1 || substeps > VSJ_MAX_PERIOD_STEPS))
        rfail(r, "its rk4 substeps are not a whole number in [1, VSJ_MAX_PERIOD_STEPS]");
    else if (method == VSJ_METHOD_TIMESTEP
             && !(step > 0.0 && l->period / step <= VSJ_MAX_PERIOD_STEPS))
        rfail(r, "its time step is not > 0 s, or a period takes more than "
                 "VSJ_MAX_PERIOD_STEPS of them");
    if (r->failed)
        return;
    memset(&l->scheme, 0, sizeof l->scheme);
    l->scheme.method = (int)method;
    l->scheme.rtol = rtol;
    l->scheme.atol = atol;
    l->scheme.h_max = INFINITY;
    l->scheme.h = step;
    l->scheme.substeps = substeps;
    l->scheme.max_steps = max_steps; /* dopri, rosenbrock: the most steps a period takes */
    l->n_inputs = count(r, 1 << 20, "inputs");
    l->input_names = names(r, l->n_inputs);
    state = count(r, 1 << 24, "the state's size");
    l->initial_state = reals(r, state);
    for (i = 0; i < state && !r->failed; i++)
        if (!isfinite(l->initial_state[i])) {
            rfail(r, "its initial state is not finite");
            return;
        }
    l->n_outputs = count(r, 1 << 20, "outputs");
    l->output_names = names(r, l->n_outputs);
    if (r->failed || (state > 0 && l->n_outputs > (int64_t)((r->length - r->at) / 8) / state)) {
        rfail(r, "truncated (the output rows)");
        return;
    }
    l->output_rows = reals(r, l->n_outputs * state);
    for (i = 0; i < l->n_outputs * state && !r->failed; i++)
        if (!isfinite(l->output_rows[i])) {
            rfail(r, "its output rows are not finite");
            return;
        }
    take8(r, &blob);
    if (r->failed)
        return;
    if (blob < 0 || (size_t)blob > r->length - r->at) {
        char text[128];
        snprintf(text, sizeof text, "truncated (the model needs %lld bytes, %lld remain)",
                 (long long)blob, (long long)(r->length - r->at));
        rfail(r, text);
        return;
    }
    l->owned = vsj_model_read(r->data + r->at, (size_t)blob, inner, sizeof inner);
    if (!l->owned) {
        rfail(r, inner);
        return;
    }
    r->at += ((size_t)blob + 7) / 8 * 8;
    l->model = *l->owned;
    if (state != vsj_step_state_size(&l->model)) {
        rfail(r, "its initial state does not fit its model");
        return;
    }
    if (l->n_inputs != l->model.n_channels)
        rfail(r, "its inputs do not fit its model's input channels");
}

vsj_loaded *vsj_parse_model(const char *text, size_t length, char *message, size_t size) {
    const unsigned char *data = (const unsigned char *)text;
    reader r;
    vsj_loaded *l;
    uint64_t sum = 0;
    int i;
    r.data = data;
    r.length = length;
    r.at = 16;
    r.message = message;
    r.size = size;
    r.failed = 0;
    if (!data || length < 32 || memcmp(data, "VSJP", 4) != 0) {
        rfail(&r, "not a vsj model file (no VSJP header; export it with vsj export-model)");
        return NULL;
    }
    if (((uint32_t)data[4] | (uint32_t)data[5] << 8 | (uint32_t)data[6] << 16
         | (uint32_t)data[7] << 24) != PROGRAM_VERSION) {
        rfail(&r, "of another format version; export it again with this version of vsj");
        return NULL;
    }
    for (i = 0; i < 8; i++)
        sum |= (uint64_t)data[length - 8 + (size_t)i] << (8 * i);
    if (vsj__fnv1a(data, length - 8) != sum) {
        rfail(&r, "damaged (its checksum does not match)");
        return NULL;
    }
    r.length = length - 8;
    l = (vsj_loaded *)calloc(1, sizeof(vsj_loaded));
    if (!l) {
        rfail(&r, "out of memory");
        return NULL;
    }
    read_program(&r, l);
    if (!r.failed && r.at != r.length)
        rfail(&r, "has bytes after its model");
    if (r.failed) {
        vsj_free_loaded(l);
        return NULL;
    }
    return l;
}

vsj_loaded *vsj_load_model(const char *path, char *message, size_t size) {
    FILE *file = fopen(path, "rb");
    unsigned char *data = NULL;
    size_t used = 0, cap = 0;
    vsj_loaded *l;
    if (!file) {
        if (message && size)
            snprintf(message, size, "%s: cannot open (%s)", path, strerror(errno));
        return NULL;
    }
    for (;;) {
        size_t got;
        if (used + 4096 > cap) {
            unsigned char *grown;
            cap = cap ? 2 * cap : 65536;
            grown = (unsigned char *)realloc(data, cap);
            if (!grown) {
                free(data);
                fclose(file);
                if (message && size)
                    snprintf(message, size, "%s: out of memory", path);
                return NULL;
            }
            data = grown;
        }
        got = fread(data + used, 1, cap - used, file);
        used += got;
        if (got == 0)
            break;
    }
    if (ferror(file)) {
        free(data);
        fclose(file);
        if (message && size)
            snprintf(message, size, "%s: read error", path);
        return NULL;
    }
    fclose(file);
    l = vsj_parse_model((const char *)data, used, message, size);
    free(data);
    if (!l && message && size) { /* prefix the file's name */
        char inner[512];
        snprintf(inner, sizeof inner, "%s", message);
        snprintf(message, size, "%s: %s", path, inner);
    }
    return l;
}
