/* Models from files: the JSON that `vsj export-model` writes.
 *
 * A small JSON reader (RFC 8259; nesting limited to MAX_DEPTH) builds a tree,
 * from which the model's arrays, inputs, outputs, initial state and solver
 * settings are taken. Numbers are read independently of the C locale (a host
 * program may have set one whose decimal separator is a comma). Every problem
 * is reported with the place in the text or the key it concerns.
 */
#include <ctype.h>
#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

#define MAX_DEPTH 64

enum { J_NULL, J_BOOL, J_NUMBER, J_STRING, J_ARRAY, J_OBJECT };

typedef struct jnode {
    int type;
    double number;
    char *string;          /* J_STRING */
    char *key;             /* member name inside an object */
    struct jnode *child;   /* first element or member */
    struct jnode *next;    /* next sibling */
    int64_t count;         /* elements or members */
} jnode;

typedef struct parser {
    const char *text, *end, *at;
    char *message;
    size_t size;
    int failed;
} parser;

static void jfree(jnode *node) {
    while (node) {
        jnode *next = node->next;
        jfree(node->child);
        free(node->string);
        free(node->key);
        free(node);
        node = next;
    }
}

static void perr(parser *ps, const char *what) {
    int64_t line = 1, column = 1;
    const char *c;
    if (ps->failed)
        return;
    for (c = ps->text; c < ps->at && c < ps->end; c++) {
        if (*c == '\n') {
            line++;
            column = 1;
        } else {
            column++;
        }
    }
    ps->failed = 1;
    if (ps->message && ps->size)
        snprintf(ps->message, ps->size, "line %lld, column %lld: %s", (long long)line,
                 (long long)column, what);
}

static void skip_space(parser *ps) {
    while (ps->at < ps->end
           && (*ps->at == ' ' || *ps->at == '\t' || *ps->at == '\n' || *ps->at == '\r'))
        ps->at++;
}

static jnode *node_new(parser *ps, int type) {
    jnode *node = (jnode *)calloc(1, sizeof(jnode));
    if (!node)
        perr(ps, "out of memory");
    else
        node->type = type;
    return node;
}

static int hex4(const char *s, unsigned *out) {
    unsigned v = 0;
    int i;
    for (i = 0; i < 4; i++) {
        char c = s[i];
        v <<= 4;
        if (c >= '0' && c <= '9')
            v |= (unsigned)(c - '0');
        else if (c >= 'a' && c <= 'f')
            v |= (unsigned)(c - 'a' + 10);
        else if (c >= 'A' && c <= 'F')
            v |= (unsigned)(c - 'A' + 10);
        else
            return 0;
    }
    *out = v;
    return 1;
}

/* A string at ps->at (which is '"'), UTF-8 in and out; NULL on error. */
static char *parse_string(parser *ps) {
    const char *s = ps->at + 1;
    size_t cap = 16, len = 0;
    char *out = (char *)malloc(cap);
    if (!out) {
        perr(ps, "out of memory");
        return NULL;
    }
    while (s < ps->end && *s != '"') {
        unsigned cp;
        char buf[4];
        size_t n = 0, i;
        if ((unsigned char)*s < 0x20) {
            ps->at = s;
            perr(ps, "control character in a string");
            free(out);
            return NULL;
        }
        if (*s == '\\') {
            if (s + 1 >= ps->end)
                break;
            s++;
            switch (*s) {
            case '"': buf[n++] = '"'; break;
            case '\\': buf[n++] = '\\'; break;
            case '/': buf[n++] = '/'; break;
            case 'b': buf[n++] = '\b'; break;
            case 'f': buf[n++] = '\f'; break;
            case 'n': buf[n++] = '\n'; break;
            case 'r': buf[n++] = '\r'; break;
            case 't': buf[n++] = '\t'; break;
            case 'u':
                if (s + 4 >= ps->end || !hex4(s + 1, &cp)) {
                    ps->at = s;
                    perr(ps, "bad \\u escape");
                    free(out);
                    return NULL;
                }
                s += 4;
                if (cp >= 0xD800 && cp <= 0xDBFF) { /* a surrogate pair */
                    unsigned lo;
                    if (s + 6 < ps->end && s[1] == '\\' && s[2] == 'u' && hex4(s + 3, &lo)
                        && lo >= 0xDC00 && lo <= 0xDFFF) {
                        cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
                        s += 6;
                    } else {
                        cp = 0xFFFD;
                    }
                }
                if (cp < 0x80) {
                    buf[n++] = (char)cp;
                } else if (cp < 0x800) {
                    buf[n++] = (char)(0xC0 | (cp >> 6));
                    buf[n++] = (char)(0x80 | (cp & 0x3F));
                } else if (cp < 0x10000) {
                    buf[n++] = (char)(0xE0 | (cp >> 12));
                    buf[n++] = (char)(0x80 | ((cp >> 6) & 0x3F));
                    buf[n++] = (char)(0x80 | (cp & 0x3F));
                } else {
                    buf[n++] = (char)(0xF0 | (cp >> 18));
                    buf[n++] = (char)(0x80 | ((cp >> 12) & 0x3F));
                    buf[n++] = (char)(0x80 | ((cp >> 6) & 0x3F));
                    buf[n++] = (char)(0x80 | (cp & 0x3F));
                }
                break;
            default:
                ps->at = s;
                perr(ps, "unknown escape in a string");
                free(out);
                return NULL;
            }
        } else {
            buf[n++] = *s;
        }
        s++;
        if (len + n + 1 > cap) {
            char *grown;
            cap = 2 * cap + n;
            grown = (char *)realloc(out, cap);
            if (!grown) {
                free(out);
                perr(ps, "out of memory");
                return NULL;
            }
            out = grown;
        }
        for (i = 0; i < n; i++)
            out[len++] = buf[i];
    }
    if (s >= ps->end) {
        ps->at = s;
        perr(ps, "unterminated string");
        free(out);
        return NULL;
    }
    out[len] = '\0';
    ps->at = s + 1;
    return out;
}

/* A number, checked against JSON's grammar, converted whatever the C locale. */
static int parse_number(parser *ps, double *value) {
    const char *s = ps->at, *start = ps->at;
    char buf[64], *endp;
    const char *point = localeconv()->decimal_point;
    size_t len, i;
    if (s < ps->end && *s == '-')
        s++;
    if (s >= ps->end || !isdigit((unsigned char)*s))
        return 0;
    if (*s == '0')
        s++;
    else
        while (s < ps->end && isdigit((unsigned char)*s))
            s++;
    if (s < ps->end && *s == '.') {
        s++;
        if (s >= ps->end || !isdigit((unsigned char)*s))
            return 0;
        while (s < ps->end && isdigit((unsigned char)*s))
            s++;
    }
    if (s < ps->end && (*s == 'e' || *s == 'E')) {
        s++;
        if (s < ps->end && (*s == '+' || *s == '-'))
            s++;
        if (s >= ps->end || !isdigit((unsigned char)*s))
            return 0;
        while (s < ps->end && isdigit((unsigned char)*s))
            s++;
    }
    len = (size_t)(s - start);
    if (len >= sizeof buf)
        return 0;
    for (i = 0; i < len; i++)
        buf[i] = start[i] == '.' && point && point[0] ? point[0] : start[i];
    buf[len] = '\0';
    *value = strtod(buf, &endp);
    if (endp != buf + len)
        return 0;
    ps->at = s;
    return isfinite(*value) ? 1 : -1;
}

static jnode *parse_value(parser *ps, int depth);

static jnode *parse_container(parser *ps, int depth, int object) {
    jnode *node = node_new(ps, object ? J_OBJECT : J_ARRAY), *last = NULL;
    char close = object ? '}' : ']';
    if (!node)
        return NULL;
    ps->at++;
    skip_space(ps);
    if (ps->at < ps->end && *ps->at == close) {
        ps->at++;
        return node;
    }
    for (;;) {
        char *key = NULL;
        jnode *item;
        skip_space(ps);
        if (object) {
            if (ps->at >= ps->end || *ps->at != '"') {
                perr(ps, "expected a member name in quotes");
                jfree(node);
                return NULL;
            }
            key = parse_string(ps);
            if (!key) {
                jfree(node);
                return NULL;
            }
            skip_space(ps);
            if (ps->at >= ps->end || *ps->at != ':') {
                perr(ps, "expected ':' after a member name");
                free(key);
                jfree(node);
                return NULL;
            }
            ps->at++;
        }
        item = parse_value(ps, depth + 1);
        if (!item) {
            free(key);
            jfree(node);
            return NULL;
        }
        item->key = key;
        if (last)
            last->next = item;
        else
            node->child = item;
        last = item;
        node->count++;
        skip_space(ps);
        if (ps->at < ps->end && *ps->at == ',') {
            ps->at++;
            continue;
        }
        if (ps->at < ps->end && *ps->at == close) {
            ps->at++;
            return node;
        }
        perr(ps, object ? "expected ',' or '}'" : "expected ',' or ']'");
        jfree(node);
        return NULL;
    }
}

static int literal(parser *ps, const char *word) {
    size_t n = strlen(word);
    if ((size_t)(ps->end - ps->at) >= n && strncmp(ps->at, word, n) == 0) {
        ps->at += n;
        return 1;
    }
    return 0;
}

static jnode *parse_value(parser *ps, int depth) {
    jnode *node;
    skip_space(ps);
    if (depth > MAX_DEPTH) {
        perr(ps, "nested too deeply");
        return NULL;
    }
    if (ps->at >= ps->end) {
        perr(ps, "unexpected end of the text");
        return NULL;
    }
    switch (*ps->at) {
    case '{': return parse_container(ps, depth, 1);
    case '[': return parse_container(ps, depth, 0);
    case '"':
        node = node_new(ps, J_STRING);
        if (node && !(node->string = parse_string(ps))) {
            jfree(node);
            return NULL;
        }
        return node;
    default:
        break;
    }
    if (literal(ps, "true") || literal(ps, "false")) {
        node = node_new(ps, J_BOOL);
        if (node)
            node->number = ps->at[-2] == 'u'; /* "true" ends in "ue", "false" in "se" */
        return node;
    }
    if (literal(ps, "null"))
        return node_new(ps, J_NULL);
    node = node_new(ps, J_NUMBER);
    if (node) {
        int read = parse_number(ps, &node->number);
        if (read != 1) {
            perr(ps, read < 0 ? "number out of range" : "expected a value");
            jfree(node);
            return NULL;
        }
    }
    return node;
}

/* ---- from the tree to a model ---------------------------------------------- */

typedef struct loader {
    char *message;
    size_t size;
    int failed;
} loader;

static void lerr(loader *ld, const char *format, ...) {
    va_list args;
    if (ld->failed)
        return;
    ld->failed = 1;
    if (ld->message && ld->size) {
        va_start(args, format);
        vsnprintf(ld->message, ld->size, format, args);
        va_end(args);
    }
}

static const jnode *member(const jnode *object, const char *key) {
    const jnode *c;
    if (!object || object->type != J_OBJECT)
        return NULL;
    for (c = object->child; c; c = c->next)
        if (c->key && strcmp(c->key, key) == 0)
            return c;
    return NULL;
}

static const jnode *need(loader *ld, const jnode *object, const char *key, int type,
                         const char *where) {
    const jnode *node = member(object, key);
    static const char *const names[] = {"null", "a boolean", "a number", "a string",
                                        "an array", "an object"};
    if (!node)
        lerr(ld, "%s: missing key \"%s\"", where, key);
    else if (node->type != type)
        lerr(ld, "%s.%s: expected %s, got %s", where, key, names[type], names[node->type]);
    return ld->failed ? NULL : node;
}

/* Numbers of an array, nested arrays flattened in order; count only with out NULL. */
static int64_t flatten(loader *ld, const jnode *node, double *out, int64_t at,
                       const char *where) {
    const jnode *c;
    if (node->type == J_NUMBER) {
        if (out)
            out[at] = node->number;
        return at + 1;
    }
    if (node->type != J_ARRAY) {
        lerr(ld, "%s: expected numbers or arrays of numbers", where);
        return at;
    }
    for (c = node->child; c && !ld->failed; c = c->next)
        at = flatten(ld, c, out, at, where);
    return at;
}

/* A numeric array of `expected` values (-1: any; its length in *length). */
static double *doubles(loader *ld, const jnode *object, const char *key, int64_t expected,
                       int64_t *length, const char *where) {
    const jnode *node = need(ld, object, key, J_ARRAY, where);
    int64_t count;
    double *out;
    char place[96];
    if (!node)
        return NULL;
    snprintf(place, sizeof place, "%s.%s", where, key);
    count = flatten(ld, node, NULL, 0, place);
    if (ld->failed)
        return NULL;
    if (expected >= 0 && count != expected) {
        lerr(ld, "%s: expected %lld values, got %lld", place, (long long)expected,
             (long long)count);
        return NULL;
    }
    out = (double *)malloc((size_t)(count > 0 ? count : 1) * sizeof(double));
    if (!out) {
        lerr(ld, "out of memory");
        return NULL;
    }
    flatten(ld, node, out, 0, place);
    if (length)
        *length = count;
    return out;
}

static int64_t *ints(loader *ld, const jnode *object, const char *key, int64_t expected,
                     const char *where) {
    int64_t count, i;
    double *values = doubles(ld, object, key, expected, &count, where);
    int64_t *out;
    if (!values)
        return NULL;
    out = (int64_t *)malloc((size_t)(count > 0 ? count : 1) * sizeof(int64_t));
    if (!out) {
        free(values);
        lerr(ld, "out of memory");
        return NULL;
    }
    for (i = 0; i < count; i++) {
        if (!(values[i] == floor(values[i]) && fabs(values[i]) < 9.0e15)) {
            lerr(ld, "%s.%s: entry %lld is not an integer", where, key, (long long)i);
            break;
        }
        out[i] = (int64_t)values[i];
    }
    free(values);
    if (ld->failed) {
        free(out);
        return NULL;
    }
    return out;
}

static char *copy_text(loader *ld, const char *s) {
    size_t n = strlen(s) + 1;
    char *out = (char *)malloc(n);
    if (!out)
        lerr(ld, "out of memory");
    else
        memcpy(out, s, n);
    return out;
}

/* Names of an array of objects with a "name" each. */
static char **names(loader *ld, const jnode *array, const char *where) {
    char **out = (char **)calloc((size_t)(array->count + 1), sizeof(char *));
    const jnode *c;
    int64_t i = 0;
    if (!out) {
        lerr(ld, "out of memory");
        return NULL;
    }
    for (c = array->child; c && !ld->failed; c = c->next, i++) {
        char place[64];
        const jnode *name;
        snprintf(place, sizeof place, "%s[%lld]", where, (long long)i);
        name = need(ld, c, "name", J_STRING, place);
        if (name)
            out[i] = copy_text(ld, name->string);
    }
    return out;
}

static void free_names(char **list) {
    char **p;
    if (!list)
        return;
    for (p = list; *p; p++)
        free(*p);
    free(list);
}

void vsj_free_loaded(vsj_loaded *l) {
    if (!l)
        return;
    free((void *)l->model.mass);
    free((void *)l->model.Minv);
    free((void *)l->model.xp);
    free((void *)l->model.xc);
    free((void *)l->model.xv);
    free((void *)l->model.up);
    free((void *)l->model.uc);
    free((void *)l->model.uv);
    free((void *)l->model.par);
    free((void *)l->model.code);
    free((void *)l->model.src_ch);
    free((void *)l->model.src_pos0);
    free((void *)l->model.knots);
    free((void *)l->model.coef);
    free((void *)l->model.cum);
    free((void *)l->model.first);
    free((void *)l->model.count);
    free((void *)l->model.table);
    free_names(l->input_names);
    free_names(l->output_names);
    free(l->initial_state);
    free(l->output_rows);
    free(l);
}

static void read_engine(loader *ld, const jnode *engine, vsj_model *m) {
    const char *w = "engine";
    int64_t *dims = ints(ld, engine, "dims", 8, w), n, s, rows, pieces;
    if (!dims)
        return;
    m->n = dims[0];
    m->n_sources = dims[1];
    m->n_frictions = dims[2];
    m->n_springs = dims[3];
    m->n_loads = dims[4];
    m->n_motors = dims[5];
    m->n_channels = dims[6];
    m->n_rows = dims[7];
    free(dims);
    n = m->n;
    s = m->n_sources;
    rows = m->n_rows;
    if (n < 0 || s < 0 || rows < 1 || m->n_channels < 0 || n > 100000 || s > 100000
        || rows > 1000000 || m->n_channels > 100000) {
        lerr(ld, "engine.dims: sizes out of range");
        return;
    }
    m->mass = doubles(ld, engine, "mass", (n + s) * (n + s), NULL, w);
    m->Minv = doubles(ld, engine, "Minv", n * n, NULL, w);
    m->xp = ints(ld, engine, "xp", rows + 1, w);
    m->up = ints(ld, engine, "up", rows + 1, w);
    if (ld->failed)
        return;
    if (m->xp[rows] < 0 || m->up[rows] < 0 || m->xp[rows] > 100000000
        || m->up[rows] > 100000000) {
        lerr(ld, "engine.xp, engine.up: bad last pointer");
        return;
    }
    m->xc = ints(ld, engine, "xc", m->xp[rows], w);
    m->xv = doubles(ld, engine, "xv", m->xp[rows], NULL, w);
    m->uc = ints(ld, engine, "uc", m->up[rows], w);
    m->uv = doubles(ld, engine, "uv", m->up[rows], NULL, w);
    m->par = doubles(ld, engine, "par", rows * VSJ_NPAR, NULL, w);
    m->code = ints(ld, engine, "code", rows, w);
    m->src_ch = ints(ld, engine, "src_ch", s, w);
    m->src_pos0 = doubles(ld, engine, "src_pos0", s, NULL, w);
    m->coef = doubles(ld, engine, "coef", -1, &pieces, w);
    if (ld->failed)
        return;
    if (pieces % 4) {
        lerr(ld, "engine.coef: expected four coefficients per piece");
        return;
    }
    m->n_pieces = pieces / 4;
    m->knots = doubles(ld, engine, "knots", m->n_pieces + m->n_channels, NULL, w);
    m->cum = doubles(ld, engine, "cum", m->n_pieces + m->n_channels, NULL, w);
    m->first = ints(ld, engine, "first", m->n_channels, w);
    m->count = ints(ld, engine, "count", m->n_channels, w);
    m->table = doubles(ld, engine, "table", -1, &pieces, w);
    if (ld->failed)
        return;
    if (pieces % 2)
        lerr(ld, "engine.table: expected rows of two values (slip speed, coefficient)");
    m->n_table = pieces / 2;
}

static vsj_loaded *load_tree(const jnode *root, char *message, size_t size) {
    loader ld = {message, size, 0};
    vsj_loaded *l;
    const jnode *node, *engine, *inputs, *outputs, *solver, *c;
    int64_t n_state, i;
    char check[256];
    if (root->type != J_OBJECT) {
        lerr(&ld, "the model file must hold a JSON object");
        return NULL;
    }
    node = need(&ld, root, "format", J_STRING, "model");
    if (node && strcmp(node->string, "vsj-model") != 0)
        lerr(&ld, "model.format: expected \"vsj-model\", got \"%s\"", node->string);
    node = need(&ld, root, "version", J_NUMBER, "model");
    if (node && node->number != 2.0)
        lerr(&ld, "model.version: this library reads version 2, got %g", node->number);
    engine = need(&ld, root, "engine", J_OBJECT, "model");
    inputs = need(&ld, root, "inputs", J_ARRAY, "model");
    outputs = need(&ld, root, "outputs", J_ARRAY, "model");
    solver = need(&ld, root, "solver", J_OBJECT, "model");
    if (ld.failed)
        return NULL;
    l = (vsj_loaded *)calloc(1, sizeof(vsj_loaded));
    if (!l) {
        lerr(&ld, "out of memory");
        return NULL;
    }
    read_engine(&ld, engine, &l->model);
    if (!ld.failed && vsj_check_model(&l->model, check, sizeof check) != VSJ_OK)
        lerr(&ld, "engine: %s", check);
    if (!ld.failed && inputs->count != l->model.n_channels)
        lerr(&ld, "model.inputs: %lld names for %lld input channels", (long long)inputs->count,
             (long long)l->model.n_channels);
    if (!ld.failed) {
        l->n_inputs = inputs->count;
        l->input_names = names(&ld, inputs, "inputs");
    }
    n_state = ld.failed ? 0 : vsj_step_state_size(&l->model);
    if (!ld.failed)
        l->initial_state = doubles(&ld, root, "initial_state", n_state, NULL, "model");
    if (!ld.failed) {
        l->n_outputs = outputs->count;
        l->output_names = names(&ld, outputs, "outputs");
        l->output_rows = (double *)calloc((size_t)(outputs->count * n_state + 1),
                                          sizeof(double));
        if (!l->output_rows)
            lerr(&ld, "out of memory");
        for (c = outputs->child, i = 0; c && !ld.failed; c = c->next, i++) {
            char place[64];
            double *row;
            snprintf(place, sizeof place, "outputs[%lld]", (long long)i);
            row = doubles(&ld, c, "row", n_state, NULL, place);
            if (row) {
                memcpy(l->output_rows + i * n_state, row, (size_t)n_state * sizeof(double));
                free(row);
            }
        }
    }
    if (!ld.failed) {
        const jnode *method = need(&ld, solver, "method", J_STRING, "solver");
        const jnode *rtol = need(&ld, solver, "rtol", J_NUMBER, "solver");
        const jnode *atol = need(&ld, solver, "atol", J_NUMBER, "solver");
        const jnode *step = need(&ld, solver, "step", J_NUMBER, "solver");
        const jnode *substeps = need(&ld, solver, "substeps", J_NUMBER, "solver");
        const jnode *period = need(&ld, solver, "period", J_NUMBER, "solver");
        if (!ld.failed) {
            if (strcmp(method->string, "dopri") == 0)
                l->solver = 0;
            else if (strcmp(method->string, "rk4") == 0)
                l->solver = 1;
            else if (strcmp(method->string, "timestep") == 0)
                l->solver = 2;
            else
                lerr(&ld, "solver.method: expected dopri, rk4 or timestep, got \"%s\"",
                     method->string);
            l->rtol = rtol->number;
            l->atol = atol->number;
            l->step = step->number;
            l->period = period->number;
            if (!(l->rtol > 0.0 && l->atol > 0.0 && l->step > 0.0 && isfinite(l->step)
                  && l->period > 0.0 && isfinite(l->period)
                  && l->period / l->step <= VSJ_MAX_PERIOD_STEPS && substeps->number >= 1.0
                  && substeps->number <= VSJ_MAX_PERIOD_STEPS))
                lerr(&ld, "solver: rtol, atol, step and period must be > 0, substeps in 1..%d, "
                          "and a period at most %d steps", VSJ_MAX_PERIOD_STEPS,
                     VSJ_MAX_PERIOD_STEPS);
            else
                l->substeps = (int64_t)substeps->number;
        }
    }
    for (i = 0; !ld.failed && i < n_state; i++)
        if (!isfinite(l->initial_state[i]))
            lerr(&ld, "model.initial_state: entry %lld is not finite", (long long)i);
    if (ld.failed) {
        vsj_free_loaded(l);
        return NULL;
    }
    return l;
}

vsj_loaded *vsj_parse_model(const char *text, size_t length, char *message, size_t size) {
    parser ps;
    jnode *root;
    vsj_loaded *l;
    ps.text = text;
    ps.end = text + length;
    ps.at = text;
    ps.message = message;
    ps.size = size;
    ps.failed = 0;
    if (length >= 3 && (unsigned char)text[0] == 0xEF && (unsigned char)text[1] == 0xBB
        && (unsigned char)text[2] == 0xBF)
        ps.at += 3; /* a UTF-8 byte-order mark */
    root = parse_value(&ps, 0);
    if (root) {
        skip_space(&ps);
        if (ps.at != ps.end)
            perr(&ps, "text after the JSON value");
    }
    if (ps.failed) {
        jfree(root);
        return NULL;
    }
    l = load_tree(root, message, size);
    jfree(root);
    return l;
}

vsj_loaded *vsj_load_model(const char *path, char *message, size_t size) {
    FILE *file = fopen(path, "rb");
    char *text = NULL;
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
            char *grown;
            cap = cap ? 2 * cap : 65536;
            grown = (char *)realloc(text, cap);
            if (!grown) {
                free(text);
                fclose(file);
                if (message && size)
                    snprintf(message, size, "%s: out of memory", path);
                return NULL;
            }
            text = grown;
        }
        got = fread(text + used, 1, cap - used, file);
        used += got;
        if (got == 0)
            break;
    }
    if (ferror(file)) {
        free(text);
        fclose(file);
        if (message && size)
            snprintf(message, size, "%s: read error", path);
        return NULL;
    }
    fclose(file);
    l = vsj_parse_model(text, used, message, size);
    free(text);
    if (!l && message && size) { /* prefix the file's name */
        char inner[512];
        snprintf(inner, sizeof inner, "%s", message);
        snprintf(message, size, "%s: %s", path, inner);
    }
    return l;
}
