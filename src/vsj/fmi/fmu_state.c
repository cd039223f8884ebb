/* FMU states of vsj's FMU (see vsj_fmu.c): snapshots of an instance taken and
 * given back (fmi2GetFMUstate, fmi2SetFMUstate), and their serialized form.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmu_internal.h"
#include "internal.h" /* vsj__fnv1a */

#define SNAPSHOT_MAGIC 0x736a7376u /* an fmi2FMUstate of this FMU */
#define STATE_MAGIC 0x53736a76u    /* "vjsS": a serialized one */
#define STATE_FORMAT 5u /* its layout (1: no fingerprint; 2: no tolerances; 3: no pivot_q0,
                          * stop time; 4: the time-stepper's impulse memo held the stuck
                          * set's inverse squared, not its factor) */

/* what fmi2GetFMUstate keeps: everything that a later step depends on (the adaptive
 * schemes' tolerances and the stop time too, which fmi2SetupExperiment may have set, and
 * pivot_q0, which the next initialization starts from) */
typedef struct {
    uint32_t magic;
    char guid[GUID_MAX];
    double time, power_in, power_dissipated, rtol, atol, q0, stop_time;
    int mode, stop_defined;
    double *s, *inputs, *values, *record;
    unsigned char *history;
} snapshot;

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
    st->history = (unsigned char *)calloc(f->history_size + 1, 1); /* the adaptive schemes keep none: zeros */
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
    st->rtol = f->scheme.rtol;
    st->atol = f->scheme.atol;
    st->q0 = f->q0;
    st->stop_time = f->stop_time;
    st->stop_defined = f->stop_defined;
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
    if ((changed || f->rebuild) && fmu__rebuild(f) != fmi2OK) {
        fmu__restore(f, 1);
        return fmi2Error;
    }
    f->q0 = st->q0; /* checked against the pivot's range where it is used: at
                     * fmi2ExitInitializationMode */
    f->stop_time = st->stop_time;
    f->stop_defined = st->stop_defined;
    f->time = st->time;
    f->power_in = st->power_in;
    f->power_dissipated = st->power_dissipated;
    f->booked_h = 0.0; /* the state's power outputs are worked out */
    f->scheme.rtol = st->rtol;
    f->scheme.atol = st->atol;
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
        return f ? fmu__fail(f, "fmi2GetFMUstate: null pointer%s", "") : fmi2Error;
    if (*FMUstate && !ours(f, (const snapshot *)*FMUstate))
        return fmu__fail(f, "fmi2GetFMUstate: the state to reuse is another FMU's%s", "");
    st = *FMUstate ? (snapshot *)*FMUstate : new_snapshot(f);
    if (!st)
        return fmu__fail(f, "fmi2GetFMUstate: out of memory%s", "");
    fmu__powers(f);
    take(f, st);
    *FMUstate = st;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    fmu *f = (fmu *)c;
    if (!f || !FMUstate)
        return f ? fmu__fail(f, "fmi2SetFMUstate: null state%s", "") : fmi2Error;
    if (!ours(f, (const snapshot *)FMUstate))
        return fmu__fail(f, "fmi2SetFMUstate: the state is another FMU's (another model, vsj "
                            "version or export), not one this FMU took%s", "");
    return give(f, (const snapshot *)FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    fmu *f = (fmu *)c;
    if (!f)
        return fmi2Error;
    if (FMUstate && *FMUstate) {
        if (!ours(f, (const snapshot *)*FMUstate))
            return fmu__fail(f, "fmi2FreeFMUstate: the state is another FMU's%s", "");
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
#define REALS 7 /* time, power_in, power_dissipated, rtol, atol, q0, stop time */

static size_t serialized_size(const fmu *f) {
    return HEADER_SIZE + REALS * sizeof(double) + 2 * sizeof(int32_t)
           + (size_t)(f->ns + f->ni + f->n_parameters + f->at.size) * sizeof(double)
           + f->history_size + sizeof(uint64_t);
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
        return f ? fmu__fail(f, "fmi2SerializedFMUstateSize: null argument%s", "") : fmi2Error;
    if (!ours(f, (const snapshot *)FMUstate))
        return fmu__fail(f, "fmi2SerializedFMUstateSize: the state is another FMU's%s", "");
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
    int32_t flags[2];
    int64_t sizes[5];
    uint64_t sum;
    if (!f || !st || !serializedState)
        return f ? fmu__fail(f, "fmi2SerializeFMUstate: null argument%s", "") : fmi2Error;
    if (!ours(f, st))
        return fmu__fail(f, "fmi2SerializeFMUstate: the state is another FMU's%s", "");
    if (size < serialized_size(f))
        return fmu__fail(f, "fmi2SerializeFMUstate: the buffer is too small%s", "");
    sizes_of(f, sizes);
    flags[0] = (int32_t)st->mode;
    flags[1] = (int32_t)st->stop_defined;
    PUT(word, sizeof word);
    PUT(f->guid, GUID_MAX);
    PUT(sizes, sizeof sizes);
    PUT(&st->time, sizeof(double));
    PUT(&st->power_in, sizeof(double));
    PUT(&st->power_dissipated, sizeof(double));
    PUT(&st->rtol, sizeof(double));
    PUT(&st->atol, sizeof(double));
    PUT(&st->q0, sizeof(double));
    PUT(&st->stop_time, sizeof(double));
    PUT(flags, sizeof flags);
    PUT(st->s, (size_t)f->ns * sizeof(double));
    PUT(st->inputs, (size_t)f->ni * sizeof(double));
    PUT(st->values, (size_t)f->n_parameters * sizeof(double));
    PUT(st->record, (size_t)f->at.size * sizeof(double));
    PUT(st->history, f->history_size);
    sum = vsj__fnv1a((const unsigned char *)serializedState,
                     (size_t)(at - serializedState));
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
    if (vsj__fnv1a((const unsigned char *)bytes, size - sizeof sum) != sum)
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
    if (!isfinite(st->q0) || (st->stop_defined != 0 && st->stop_defined != 1)
        || (st->stop_defined && !isfinite(st->stop_time)))
        return "its pivot_q0 or stop time is not one an experiment can have";
    if (!(st->rtol > 0.0 && st->rtol <= 1e-2 && st->atol > 0.0 && st->atol <= 1e-2))
        return "its tolerances are outside vsj's ranges";
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
        if (fmu__refusal(f->parameters + k, st->values[k], reason, sizeof reason)) {
            snprintf(why, size, "its %s = %g is outside the parameter's range: %s",
                     f->parameters[k].key, st->values[k], reason);
            return why;
        }
    if (fmu__broken_relation(f, st->values) >= 0)
        return "its parameters break a relation between keys";
    if (f->scheme.method == VSJ_METHOD_TIMESTEP
        && vsj_ts_history_check(&f->model, st->history, reason, sizeof reason) != VSJ_OK) {
        snprintf(why, size, "%s", reason);
        return why;
    }
    return NULL;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    fmu *f = (fmu *)c;
    const char *at = serializedState, *problem;
    char why[400];
    int32_t flags[2];
    snapshot *st;
    if (!f || !serializedState || !FMUstate)
        return f ? fmu__fail(f, "fmi2DeSerializeFMUstate: null argument%s", "") : fmi2Error;
    if (*FMUstate && !ours(f, (const snapshot *)*FMUstate))
        return fmu__fail(f, "fmi2DeSerializeFMUstate: the state to reuse is another FMU's%s", "");
    problem = foreign_header(f, serializedState, size, why, sizeof why);
    if (problem)
        return fmu__fail(f, "fmi2DeSerializeFMUstate: the bytes are refused: %s", problem);
    st = new_snapshot(f);
    if (!st)
        return fmu__fail(f, "fmi2DeSerializeFMUstate: out of memory%s", "");
    at += HEADER_SIZE;
    GET(&st->time, sizeof(double));
    GET(&st->power_in, sizeof(double));
    GET(&st->power_dissipated, sizeof(double));
    GET(&st->rtol, sizeof(double));
    GET(&st->atol, sizeof(double));
    GET(&st->q0, sizeof(double));
    GET(&st->stop_time, sizeof(double));
    GET(flags, sizeof flags);
    st->mode = (int)flags[0];
    st->stop_defined = (int)flags[1];
    GET(st->s, (size_t)f->ns * sizeof(double));
    GET(st->inputs, (size_t)f->ni * sizeof(double));
    GET(st->values, (size_t)f->n_parameters * sizeof(double));
    GET(st->record, (size_t)f->at.size * sizeof(double));
    GET(st->history, f->history_size);
    problem = bad_fields(f, st, why, sizeof why);
    if (problem) {
        free_snapshot(st);
        return fmu__fail(f, "fmi2DeSerializeFMUstate: the bytes are refused: %s", problem);
    }
    if (*FMUstate)
        free_snapshot((snapshot *)*FMUstate);
    *FMUstate = st;
    return fmi2OK;
}
