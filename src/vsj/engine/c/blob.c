/* A model as bytes: the versioned binary form of `vsj_model`.
 *
 * Layout (little-endian; every value 8 bytes):
 *   "VSJM", format version (uint32), number of sizes, number of arrays (uint32)
 *   the sizes of VSJ_SIZES, in table order (int64)
 *   the arrays of VSJ_ARRAYS, in table order, each its count of values
 *   an FNV-1a 64-bit checksum of everything before it
 * Both directions walk the tables of vsj_layout.h, so a new array needs no code
 * here. Reading checks the magic, the version, the table's shape, every count
 * against the bytes at hand and the checksum before it trusts anything, then
 * vsj_check_model. No global state: the memory of a read model is its own.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

#define N_SIZES_ (0 VSJ_SIZES(VSJ__COUNT_SIZE))
#define VSJ__COUNT_SIZE(name, doc) +1
#define VSJ__COUNT_ARRAY(name, kind, count, doc) +1
#define N_ARRAYS_ (0 VSJ_ARRAYS(VSJ__COUNT_ARRAY))

enum { HEADER = 16, VERSION = 1 };

static int little_endian(void) {
    const uint32_t one = 1;
    unsigned char first;
    memcpy(&first, &one, 1);
    return first == 1;
}

/* 8 bytes in file order <-> a host value */
static void put8(unsigned char *out, const void *value) {
    unsigned char raw[8];
    int i;
    memcpy(raw, value, 8);
    for (i = 0; i < 8; i++)
        out[i] = raw[little_endian() ? i : 7 - i];
}

static void get8(const unsigned char *in, void *value) {
    unsigned char raw[8];
    int i;
    for (i = 0; i < 8; i++)
        raw[little_endian() ? i : 7 - i] = in[i];
    memcpy(value, raw, 8);
}

static void put4(unsigned char *out, uint32_t v) {
    int i;
    for (i = 0; i < 4; i++)
        out[i] = (unsigned char)(v >> (8 * i));
}

static uint32_t get4(const unsigned char *in) {
    return (uint32_t)in[0] | (uint32_t)in[1] << 8 | (uint32_t)in[2] << 16
           | (uint32_t)in[3] << 24;
}

uint64_t vsj__fnv1a(const unsigned char *data, size_t len) {
    uint64_t h = 14695981039346656037ULL;
    size_t i;
    for (i = 0; i < len; i++) {
        h ^= data[i];
        h *= 1099511628211ULL;
    }
    return h;
}

/* The number of values of each array of m (the table's count expressions). */
static void counts(const vsj_model *M, int64_t *out) {
    int k = 0;
#define VSJ__COUNT(name, kind, count, doc) out[k++] = (int64_t)(count);
    VSJ_ARRAYS(VSJ__COUNT)
#undef VSJ__COUNT
}

size_t vsj_model_write(const vsj_model *m, unsigned char *out, size_t capacity) {
    int64_t cnt[N_ARRAYS_ > 0 ? N_ARRAYS_ : 1], total = 0, v;
    size_t need, at = HEADER;
    int k = 0;
    counts(m, cnt);
    for (k = 0; k < N_ARRAYS_; k++)
        total += cnt[k];
    need = HEADER + 8 * ((size_t)N_SIZES_ + (size_t)total) + 8;
    if (!out || capacity < need)
        return need;
    memcpy(out, "VSJM", 4);
    put4(out + 4, VERSION);
    put4(out + 8, (uint32_t)N_SIZES_);
    put4(out + 12, (uint32_t)N_ARRAYS_);
#define VSJ__PUT_SIZE(name, doc)      \
    v = m->name;                      \
    put8(out + at, &v);               \
    at += 8;
    VSJ_SIZES(VSJ__PUT_SIZE)
#undef VSJ__PUT_SIZE
    k = 0;
#define VSJ__PUT_ARRAY(name, kind, count, doc)           \
    {                                                    \
        int64_t i_;                                      \
        for (i_ = 0; i_ < cnt[k]; i_++, at += 8)         \
            put8(out + at, m->name + i_);                \
        k++;                                             \
    }
    VSJ_ARRAYS(VSJ__PUT_ARRAY)
#undef VSJ__PUT_ARRAY
    {
        uint64_t sum = vsj__fnv1a(out, at);
        put8(out + at, &sum);
    }
    return need;
}

static vsj_model *fail(char *message, size_t size, const char *text) {
    if (message && size)
        snprintf(message, size, "model data: %s", text);
    return NULL;
}

vsj_model *vsj_model_read(const unsigned char *data, size_t length, char *message,
                          size_t size) {
    int64_t sizes[N_SIZES_], cnt[N_ARRAYS_ > 0 ? N_ARRAYS_ : 1], total = 0;
    size_t at = HEADER, need;
    vsj_model probe, *m;
    unsigned char *memory;
    double *values;
    int k;
    uint64_t sum;
    if (!data || length < HEADER + 8 || memcmp(data, "VSJM", 4) != 0)
        return fail(message, size, "not a vsj model (no VSJM header)");
    if (get4(data + 4) != VERSION)
        return fail(message, size, "a model of another format version; export it again with "
                                   "this version of vsj");
    if (get4(data + 8) != (uint32_t)N_SIZES_ || get4(data + 12) != (uint32_t)N_ARRAYS_)
        return fail(message, size, "its layout differs from this engine's (vsj_layout.h)");
    get8(data + length - 8, &sum);
    if (vsj__fnv1a(data, length - 8) != sum)
        return fail(message, size, "damaged (its checksum does not match)");
    if (length < HEADER + 8 * (size_t)N_SIZES_ + 8)
        return fail(message, size, "truncated");
    memset(&probe, 0, sizeof probe);
    for (k = 0; k < N_SIZES_; k++, at += 8) {
        get8(data + at, &sizes[k]);
        if (sizes[k] < 0 || sizes[k] > 100000000)
            return fail(message, size, "a size is outside 0..1e8");
    }
    k = 0;
#define VSJ__GET_SIZE(name, doc) probe.name = sizes[k++];
    VSJ_SIZES(VSJ__GET_SIZE)
#undef VSJ__GET_SIZE
    /* the counts, table order: a count may read an earlier array (the CSR pointers),
     * so the arrays are read one by one into memory of their own */
    need = sizeof(vsj_model) + 8 * ((length - at) / 8) + 64;
    memory = (unsigned char *)calloc(1, need);
    if (!memory)
        return fail(message, size, "out of memory");
    m = (vsj_model *)memory;
    *m = probe;
    values = (double *)(memory + ((sizeof(vsj_model) + 63) / 64) * 64);
    k = 0;
#define VSJ__GET_ARRAY(name, kind, count, doc)                                           \
    {                                                                                    \
        const vsj_model *M = m;                                                          \
        int64_t i_;                                                                      \
        cnt[k] = (int64_t)(count);                                                       \
        if (cnt[k] < 0 || (size_t)cnt[k] > (length - 8 - at) / 8) {                     \
            free(memory);                                                                \
            return fail(message, size, "truncated (array " #name ")");                   \
        }                                                                                \
        for (i_ = 0; i_ < cnt[k]; i_++)                                                 \
            get8(data + at + 8 * (size_t)i_, (unsigned char *)values + 8 * (total + i_)); \
        m->name = (const VSJ_TYPE_##kind *)(values + total);                             \
        at += 8 * (size_t)cnt[k];                                                        \
        total += cnt[k];                                                                 \
        k++;                                                                             \
        (void)M;                                                                         \
    }
    VSJ_ARRAYS(VSJ__GET_ARRAY)
#undef VSJ__GET_ARRAY
    if (at != length - 8) {
        free(memory);
        return fail(message, size, "has bytes after its last array");
    }
    if (vsj_check_model(m, message, size) != VSJ_OK) {
        free(memory);
        return NULL;
    }
    return m;
}

void vsj_model_free(vsj_model *m) { free(m); }
