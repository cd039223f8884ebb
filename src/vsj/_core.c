/* vsj._core: the Python binding of the C engine (engine/c/vsj.h), a leaf of the
 * package: it adds no physics and imports nothing of vsj.
 *
 * Thin: it checks what it hands to C (buffer types, shapes, model indices)
 * and adds no physics. Arrays are taken through the buffer protocol, so the
 * binding needs no NumPy headers. A Model copies its arrays into memory of its
 * own (a later change of the Python arrays cannot invalidate what was
 * checked); a Work is the run-time state of one computation at a time. Long
 * computations release the GIL, so that threads can run models side by side.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "engine/c/vsj.h"

/* ---- buffers ------------------------------------------------------------------ */

enum kind { DOUBLES, INTS, BOOLS };

typedef struct arg {
    Py_buffer view;
    int held;
} arg;

static void release(arg *a) {
    if (a->held) {
        PyBuffer_Release(&a->view);
        a->held = 0;
    }
}

static int format_is(const Py_buffer *v, enum kind kind) {
    const char *f = v->format ? v->format : "B";
    if (*f == '@' || *f == '=' || *f == '<')
        f++;
    if (kind == DOUBLES)
        return v->itemsize == 8 && strcmp(f, "d") == 0;
    if (kind == INTS)
        return v->itemsize == 8 && (strcmp(f, "q") == 0 || strcmp(f, "l") == 0);
    return v->itemsize == 1 && strcmp(f, "?") == 0;
}

static const char *kind_name(enum kind kind) {
    return kind == DOUBLES ? "float64" : kind == INTS ? "int64" : "bool";
}

/* A C-contiguous buffer of `kind` with `expected` items (-1: any). */
static int get(PyObject *obj, arg *a, enum kind kind, int writable, Py_ssize_t expected,
               const char *name) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    a->held = 0;
    if (PyObject_GetBuffer(obj, &a->view, flags) != 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "%s: expected a %scontiguous %s array, got %.80s", name,
                     writable ? "writable " : "", kind_name(kind), Py_TYPE(obj)->tp_name);
        return -1;
    }
    a->held = 1;
    if (!format_is(&a->view, kind)) {
        PyErr_Format(PyExc_TypeError, "%s: expected %s items, got format %.20s", name,
                     kind_name(kind), a->view.format ? a->view.format : "B");
        release(a);
        return -1;
    }
    if (expected >= 0 && a->view.len / a->view.itemsize != expected) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd items, got %zd", name, expected,
                     a->view.len / a->view.itemsize);
        release(a);
        return -1;
    }
    return 0;
}

static Py_ssize_t items(const arg *a) { return a->view.len / a->view.itemsize; }

/* ---- Model --------------------------------------------------------------------- */

/* A model of its own: made from Python arrays (named as in vsj_layout.h) or from
 * bytes, through the model's binary form (c/blob.c), so that every model the engine
 * runs was checked by the same reader. */
typedef struct {
    PyObject_HEAD
    vsj_model *model; /* the memory it owns (its arrays, or a retuned one's new arrays) */
    vsj_model m;      /* its sizes and arrays, for the functions below */
    PyObject *parent; /* a retuned model: the model whose other arrays it shares */
} ModelObject;

static void model_dealloc(ModelObject *self) {
    if (self->parent)
        free(self->model);
    else
        vsj_model_free(self->model);
    Py_XDECREF(self->parent);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

#define VSJ__COUNT_ONE(...) +1
static const char *const SIZE_NAMES[] = {
#define VSJ__SIZE_NAME(name, doc) #name,
    VSJ_SIZES(VSJ__SIZE_NAME)
#undef VSJ__SIZE_NAME
};
static const char *const ARRAY_NAMES[] = {
#define VSJ__ARRAY_NAME(name, kind, count, doc) #name,
    VSJ_ARRAYS(VSJ__ARRAY_NAME)
#undef VSJ__ARRAY_NAME
};
static const int ARRAY_KINDS[] = {
#define VSJ__ARRAY_KIND(name, kind, count, doc) kind,
    VSJ_ARRAYS(VSJ__ARRAY_KIND)
#undef VSJ__ARRAY_KIND
};
static const char *const ARRAY_DOCS[] = {
#define VSJ__ARRAY_DOC(name, kind, count, doc) doc,
    VSJ_ARRAYS(VSJ__ARRAY_DOC)
#undef VSJ__ARRAY_DOC
};
#define N_SIZES ((int)(sizeof SIZE_NAMES / sizeof SIZE_NAMES[0]))
#define N_ARRAYS ((int)(sizeof ARRAY_NAMES / sizeof ARRAY_NAMES[0]))

static ModelObject *model_of_bytes(PyTypeObject *type, const unsigned char *data, size_t len) {
    char message[256];
    ModelObject *self;
    vsj_model *model = vsj_model_read(data, len, message, sizeof message);
    if (!model) {
        PyErr_SetString(PyExc_ValueError, message);
        return NULL;
    }
    self = (ModelObject *)type->tp_alloc(type, 0);
    if (!self) {
        vsj_model_free(model);
        return NULL;
    }
    self->model = model;
    self->m = *model;
    return self;
}

/* Model(sizes, arrays): sizes in the order of vsj_layout.h's VSJ_SIZES, arrays a
 * mapping from each VSJ_ARRAYS name to a contiguous float64 or int64 array */
static PyObject *model_new(PyTypeObject *type, PyObject *args, PyObject *kwds) {
    static char *keywords[] = {"sizes", "arrays", NULL};
    PyObject *osizes, *oarrays, *result = NULL;
    arg sizes, held[N_ARRAYS];
    vsj_model probe;
    int64_t values[N_SIZES];
    unsigned char *bytes = NULL;
    size_t need;
    int i, k, taken = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "OO!:Model", keywords, &osizes, &PyDict_Type,
                                     &oarrays))
        return NULL;
    if (get(osizes, &sizes, INTS, 0, N_SIZES, "sizes") < 0)
        return NULL;
    memcpy(values, sizes.view.buf, sizeof values);
    release(&sizes);
    for (i = 0; i < N_SIZES; i++)
        if (values[i] < 0 || values[i] > 100000000) {
            PyErr_Format(PyExc_ValueError, "sizes: %s is %lld, outside 0..1e8", SIZE_NAMES[i],
                         (long long)values[i]);
            return NULL;
        }
    memset(&probe, 0, sizeof probe);
    k = 0;
#define VSJ__SET_SIZE(name, doc) probe.name = values[k++];
    VSJ_SIZES(VSJ__SET_SIZE)
#undef VSJ__SET_SIZE
    if (probe.n_rows != probe.n_frictions + probe.n_springs + probe.n_loads + probe.n_motors + 1) {
        PyErr_SetString(PyExc_ValueError,
                        "sizes: n_rows must be n_frictions + n_springs + n_loads + n_motors + 1");
        return NULL;
    }
    k = 0;
    /* each array in table order: its count may read an earlier one (CSR pointers) */
#define VSJ__TAKE(name, kind, count, doc)                                                   \
    {                                                                                       \
        const vsj_model *M = &probe;                                                        \
        PyObject *o = PyDict_GetItemString(oarrays, #name);                                 \
        Py_ssize_t want;                                                                    \
        if (!o) {                                                                           \
            PyErr_SetString(PyExc_KeyError, "arrays: no array " #name);                     \
            goto done;                                                                      \
        }                                                                                   \
        want = (Py_ssize_t)(count);                                                         \
        if (get(o, &held[k], kind == VSJ_REAL ? DOUBLES : INTS, 0, want, #name) < 0)        \
            goto done;                                                                      \
        taken = k + 1;                                                                      \
        probe.name = (const VSJ_TYPE_##kind *)held[k].view.buf;                             \
        if (kind == VSJ_INT && (k == 2 || k == 5)) { /* CSR pointers, before they size */   \
            const int64_t *p_ = (const int64_t *)probe.name;                                \
            int64_t r_;                                                                     \
            for (r_ = 0; r_ < probe.n_rows; r_++)                                           \
                if (p_[0] != 0 || p_[r_ + 1] < p_[r_] || p_[probe.n_rows] > 100000000) {    \
                    PyErr_SetString(PyExc_ValueError, "model array " #name                  \
                                    ": pointers must start at 0 and not decrease");         \
                    goto done;                                                              \
                }                                                                           \
        }                                                                                   \
        k++;                                                                                \
        (void)M;                                                                            \
    }
    VSJ_ARRAYS(VSJ__TAKE)
#undef VSJ__TAKE
    need = vsj_model_write(&probe, NULL, 0);
    bytes = (unsigned char *)malloc(need);
    if (!bytes) {
        PyErr_NoMemory();
        goto done;
    }
    vsj_model_write(&probe, bytes, need);
    result = (PyObject *)model_of_bytes(type, bytes, need);
done:
    for (i = 0; i < taken; i++)
        release(&held[i]);
    free(bytes);
    return result;
}

/* Model.from_bytes(data): a model from its binary form */
static PyObject *model_from_bytes(PyObject *cls, PyObject *arg_) {
    Py_buffer view;
    PyObject *result;
    if (PyObject_GetBuffer(arg_, &view, PyBUF_SIMPLE) != 0)
        return NULL;
    result = (PyObject *)model_of_bytes((PyTypeObject *)cls, (const unsigned char *)view.buf,
                                        (size_t)view.len);
    PyBuffer_Release(&view);
    return result;
}

/* model.to_bytes(): its binary form */
static PyObject *model_to_bytes(ModelObject *self, PyObject *Py_UNUSED(ignored)) {
    size_t need = vsj_model_write(&self->m, NULL, 0);
    PyObject *out = PyBytes_FromStringAndSize(NULL, (Py_ssize_t)need);
    if (out)
        vsj_model_write(&self->m, (unsigned char *)PyBytes_AS_STRING(out), need);
    return out;
}

static PyObject *model_sizes(ModelObject *self, PyObject *Py_UNUSED(ignored)) {
    PyObject *out = PyDict_New();
    if (!out)
        return NULL;
#define VSJ__SIZE_ITEM(name, doc)                                                   \
    {                                                                               \
        PyObject *v_ = PyLong_FromLongLong((long long)self->m.name);                \
        if (!v_ || PyDict_SetItemString(out, #name, v_) < 0) {                      \
            Py_XDECREF(v_);                                                         \
            Py_DECREF(out);                                                         \
            return NULL;                                                            \
        }                                                                           \
        Py_DECREF(v_);                                                              \
    }
    VSJ_SIZES(VSJ__SIZE_ITEM)
#undef VSJ__SIZE_ITEM
    return out;
}

/* model.retuned(arrays): a model with some real arrays replaced (same sizes), sharing
 * the others with this one (kept alive by it); checked as a whole. A batch of runs of
 * one network with other inertias and parameters copies only what differs. */
static PyObject *model_retuned(ModelObject *self, PyObject *oarrays) {
    ModelObject *out;
    PyObject *key, *value;
    Py_ssize_t pos = 0;
    size_t total = 0;
    unsigned char *memory;
    char message[256];
    vsj_model m = self->m;
    int pass;
    if (!PyDict_Check(oarrays)) {
        PyErr_SetString(PyExc_TypeError, "retuned: a dict of arrays");
        return NULL;
    }
    /* pass 0 sizes the memory, pass 1 copies each array into it */
    memory = NULL;
    for (pass = 0; pass < 2; pass++) {
        size_t at = 0;
        pos = 0;
        while (PyDict_Next(oarrays, &pos, &key, &value)) {
            const char *name = PyUnicode_Check(key) ? PyUnicode_AsUTF8(key) : NULL;
            const double **slot = NULL;
            Py_ssize_t want = 0;
            arg a;
            if (!name) {
                free(memory);
                PyErr_SetString(PyExc_TypeError, "retuned: array names are strings");
                return NULL;
            }
#define VSJ__SLOT(field, kind, count, doc)                                                  \
            if (kind == VSJ_REAL && strcmp(name, #field) == 0) {                             \
                const vsj_model *M = &self->m;                                               \
                slot = (const double **)(void *)&m.field;                                    \
                want = (Py_ssize_t)(count);                                                  \
                (void)M;                                                                     \
            }
            VSJ_ARRAYS(VSJ__SLOT)
#undef VSJ__SLOT
            if (!slot) {
                free(memory);
                PyErr_Format(PyExc_KeyError, "retuned: %s is not a real array of the model",
                             name);
                return NULL;
            }
            if (get(value, &a, DOUBLES, 0, want, name) < 0) {
                free(memory);
                return NULL;
            }
            if (pass == 1) {
                memcpy(memory + at, a.view.buf, (size_t)want * sizeof(double));
                *slot = (const double *)(void *)(memory + at);
            }
            at += (size_t)want * sizeof(double);
            release(&a);
        }
        total = at;
        if (pass == 0 && !(memory = (unsigned char *)malloc(total + 1)))
            return PyErr_NoMemory();
    }
    if (vsj_check_model(&m, message, sizeof message) != VSJ_OK) {
        free(memory);
        PyErr_SetString(PyExc_ValueError, message);
        return NULL;
    }
    out = (ModelObject *)Py_TYPE(self)->tp_alloc(Py_TYPE(self), 0);
    if (!out) {
        free(memory);
        return NULL;
    }
    out->model = (vsj_model *)(void *)memory;
    out->m = m;
    out->parent = (PyObject *)self; /* whose arrays (its own, or its parent's) m shares */
    Py_INCREF(out->parent);
    return (PyObject *)out;
}

static PyMethodDef model_methods[] = {
    {"sizes", (PyCFunction)model_sizes, METH_NOARGS, "The model's sizes, by name."},
    {"retuned", (PyCFunction)model_retuned, METH_O,
     "retuned(arrays): this model with some real arrays replaced (same sizes), sharing the "
     "others; checked."},
    {"to_bytes", (PyCFunction)model_to_bytes, METH_NOARGS, "The model's binary form."},
    {"from_bytes", (PyCFunction)model_from_bytes, METH_O | METH_CLASS,
     "A model from its binary form (checked)."},
    {NULL, NULL, 0, NULL}};

static PyTypeObject ModelType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "vsj._core.Model",
    .tp_basicsize = sizeof(ModelObject),
    .tp_dealloc = (destructor)model_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "A checked model of the engine: Model(sizes, arrays), or Model.from_bytes.",
    .tp_methods = model_methods,
    .tp_new = model_new,
};

#define LAW_NAME(NAME, name, description) name,
static const char *const FRICTION_LAW_NAMES[] = {VSJ_FRICTION_LAWS(LAW_NAME)};
static const char *const SPRING_LAW_NAMES[] = {VSJ_SPRING_LAWS(LAW_NAME)};

/* The names of a table of laws, in the order of their codes. */
static PyObject *law_names(const char *const *names, int count) {
    PyObject *out = PyTuple_New(count);
    int i;
    for (i = 0; out && i < count; i++)
        PyTuple_SET_ITEM(out, i, PyUnicode_FromString(names[i]));
    return out;
}

/* The layout, for Python: {"sizes": (names...), "arrays": ((name, kind, doc), ...),
 * "friction_laws": (names...), "spring_laws": (names...)} with kind "float64" or
 * "int64" and each law's code its index. */
static PyObject *layout_object(void) {
    PyObject *sizes = PyTuple_New(N_SIZES), *arrays = PyTuple_New(N_ARRAYS), *out;
    PyObject *friction = law_names(FRICTION_LAW_NAMES, VSJ_N_FRICTION_LAWS);
    PyObject *spring = law_names(SPRING_LAW_NAMES, VSJ_N_SPRING_LAWS);
    int i;
    if (!sizes || !arrays || !friction || !spring) {
        Py_XDECREF(sizes);
        Py_XDECREF(arrays);
        Py_XDECREF(friction);
        Py_XDECREF(spring);
        return NULL;
    }
    for (i = 0; i < N_SIZES; i++)
        PyTuple_SET_ITEM(sizes, i, PyUnicode_FromString(SIZE_NAMES[i]));
    for (i = 0; i < N_ARRAYS; i++)
        PyTuple_SET_ITEM(arrays, i, Py_BuildValue("(sss)", ARRAY_NAMES[i],
                                                  ARRAY_KINDS[i] == VSJ_REAL ? "float64"
                                                                             : "int64",
                                                  ARRAY_DOCS[i]));
    out = Py_BuildValue("{sNsNsNsN}", "sizes", sizes, "arrays", arrays, "friction_laws",
                        friction, "spring_laws", spring);
    return out;
}

/* ---- Work ----------------------------------------------------------------------- */

typedef struct {
    PyObject_HEAD
    vsj_work *w;
    vsj_model sizes; /* the model sizes it was made for */
    int busy;        /* in use by a computation (possibly without the GIL) */
} WorkObject;

static void work_dealloc(WorkObject *self) {
    vsj_work_free(self->w);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *work_new(PyTypeObject *type, PyObject *args, PyObject *kwds) {
    static char *keywords[] = {"model", NULL};
    ModelObject *model;
    WorkObject *self;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O!:Work", keywords, &ModelType, &model))
        return NULL;
    self = (WorkObject *)type->tp_alloc(type, 0);
    if (!self)
        return NULL;
    self->w = vsj_work_new(&model->m);
    if (!self->w) {
        Py_DECREF(self);
        return PyErr_NoMemory();
    }
    self->sizes = model->m;
    return (PyObject *)self;
}

static PyTypeObject WorkType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "vsj._core.Work",
    .tp_basicsize = sizeof(WorkObject),
    .tp_dealloc = (destructor)work_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Run-time state of the engine for one model's sizes; one computation at a time.",
    .tp_new = work_new,
};

/* Takes a work for a computation on model m; release with `give_back`. */
static int take(WorkObject *w, const vsj_model *m) {
    const vsj_model *s = &w->sizes;
    if (s->n != m->n || s->n_sources != m->n_sources || s->n_frictions != m->n_frictions
        || s->n_springs != m->n_springs || s->n_loads != m->n_loads
        || s->n_motors != m->n_motors || s->n_channels != m->n_channels
        || s->n_rows != m->n_rows) {
        PyErr_SetString(PyExc_ValueError, "work: made for a model of other sizes");
        return -1;
    }
    if (w->busy) {
        PyErr_SetString(PyExc_RuntimeError,
                        "work: in use by another computation (use one work per thread)");
        return -1;
    }
    w->busy = 1;
    return 0;
}

static void give_back(WorkObject *w) { w->busy = 0; }

static int finite_scalar(double v, const char *name) {
    if (!isfinite(v)) {
        PyErr_Format(PyExc_ValueError, "%s must be finite", name);
        return -1;
    }
    return 0;
}

/* ---- integration ------------------------------------------------------------------- */

static PyObject *report_tuple(vsj_report r) {
    return Py_BuildValue("(idLL)", r.status, r.t, (long long)r.steps, (long long)r.rejected);
}

static int increasing(const double *t, Py_ssize_t n, const char *name) {
    Py_ssize_t i;
    for (i = 0; i < n; i++)
        if (!isfinite(t[i]) || (i > 0 && t[i] < t[i - 1])) {
            PyErr_Format(PyExc_ValueError, "%s: times must be finite and non-decreasing", name);
            return -1;
        }
    return 0;
}

/* The time-stepper samples at whole steps: the times must be multiples of h. */
static int multiples(const double *t, Py_ssize_t n, double h) {
    Py_ssize_t i;
    for (i = 0; i < n; i++) {
        double k = t[i] / h;
        if (!isfinite(k) || fabs(k - floor(k + 0.5)) > 1e-6 * (1.0 + fabs(k))) {
            PyErr_SetString(PyExc_ValueError, "t_out: sample times must be multiples of the step");
            return -1;
        }
    }
    return 0;
}

/* Optional samples of the time-stepper. */
typedef struct ts_args {
    arg t_out, out, coulomb, stuck;
    vsj_samples samples;
} ts_args;

static void ts_release(ts_args *a) {
    release(&a->t_out);
    release(&a->out);
    release(&a->coulomb);
    release(&a->stuck);
}

static int ts_samples(ts_args *a, const vsj_model *m, PyObject *ot, PyObject *oout,
                      PyObject *oc, PyObject *os, double h) {
    Py_ssize_t n_out;
    const double *t;
    memset(a, 0, sizeof *a);
    if (get(ot, &a->t_out, DOUBLES, 0, -1, "t_out") < 0)
        return -1;
    n_out = items(&a->t_out);
    t = (const double *)a->t_out.view.buf;
    if (increasing(t, n_out, "t_out") < 0)
        return -1;
    if (h > 0.0 && multiples(t, n_out, h) < 0)
        return -1;
    if (get(oout, &a->out, DOUBLES, 1, -1, "out") < 0)
        return -1;
    a->samples.t = t;
    a->samples.n = n_out;
    a->samples.out = (double *)a->out.view.buf;
    a->samples.out_cols = n_out ? items(&a->out) / n_out : 0;
    if (a->samples.out_cols * n_out != items(&a->out)) {
        PyErr_SetString(PyExc_ValueError, "out: needs one row per sample");
        return -1;
    }
    if (oc != Py_None) {
        if (get(oc, &a->coulomb, DOUBLES, 1, n_out * (Py_ssize_t)m->n_frictions,
                "coulomb") < 0
            || get(os, &a->stuck, BOOLS, 1, n_out * (Py_ssize_t)m->n_frictions, "stuck") < 0)
            return -1;
        a->samples.coulomb = (double *)a->coulomb.view.buf;
        a->samples.stuck = (unsigned char *)a->stuck.view.buf;
    }
    return 0;
}

static int step_args(ModelObject *model, PyObject *os, PyObject *ou, arg *s, arg *u,
                     int writable) {
    Py_ssize_t i;
    const double *v;
    if (get(os, s, DOUBLES, writable, (Py_ssize_t)vsj_step_state_size(&model->m), "state") < 0)
        return -1;
    if (get(ou, u, DOUBLES, 0, (Py_ssize_t)model->m.n_channels, "inputs") < 0) {
        release(s);
        return -1;
    }
    v = (const double *)u->view.buf;
    for (i = 0; i < items(u); i++)
        if (!isfinite(v[i])) {
            PyErr_Format(PyExc_ValueError, "inputs: value %zd is not finite", i);
            release(s);
            release(u);
            return -1;
        }
    v = (const double *)s->view.buf;
    for (i = 0; i < items(s); i++)
        if (!isfinite(v[i])) {
            PyErr_Format(PyExc_ValueError, "state: value %zd is not finite", i);
            release(s);
            release(u);
            return -1;
        }
    return 0;
}

/* ---- runs: the one entry point of every driver ------------------------------------- */

/* A scheme from its tuple (method, rtol, atol, h_max, n_err, h, max_steps, ledger,
 * substeps); method 0 dopri, 1 time-stepper, 2 rk4 (a held period only), 3 rosenbrock. */
static int scheme_of(PyObject *o, vsj_scheme *sc) {
    long long method, n_err, max_steps, substeps;
    int ledger;
    if (!PyArg_ParseTuple(o, "LdddLdLpL:scheme", &method, &sc->rtol, &sc->atol, &sc->h_max,
                          &n_err, &sc->h, &max_steps, &ledger, &substeps))
        return -1;
    if ((method != VSJ_METHOD_DOPRI && method != VSJ_METHOD_TIMESTEP && method != VSJ_METHOD_RK4
         && method != VSJ_METHOD_ROSENBROCK)
        || !(sc->rtol > 0.0) || !(sc->atol > 0.0) || !(sc->h_max > 0.0)
        || !(isfinite(sc->h) && sc->h > 0.0) || max_steps < 1 || n_err < 0 || substeps < 1
        || substeps > VSJ_MAX_PERIOD_STEPS) {
        PyErr_SetString(PyExc_ValueError, "scheme: method 0, 1, 2 or 3; rtol, atol, h_max and h "
                                          "> 0; max_steps and substeps >= 1; n_err >= 0");
        return -1;
    }
    sc->method = (int)method;
    sc->n_err = n_err;
    sc->max_steps = max_steps;
    sc->ledger = ledger;
    sc->substeps = substeps;
    return 0;
}

/* A held period of the step function: y is its state [x, p, i, sigma] (vsj.h). */
static PyObject *held_period(ModelObject *model, WorkObject *work, PyObject *oy, PyObject *oheld,
                             const vsj_scheme *sc, double dt) {
    arg s, u;
    int status;
    if (!(isfinite(dt) && dt > 0.0)
        || (sc->method == VSJ_METHOD_TIMESTEP && !(dt / sc->h <= VSJ_MAX_PERIOD_STEPS))) {
        PyErr_Format(PyExc_ValueError, "run: a held period needs dt > 0 and at most %d steps",
                     VSJ_MAX_PERIOD_STEPS);
        return NULL;
    }
    if (step_args(model, oy, oheld, &s, &u, 1) < 0)
        return NULL;
    if (take(work, &model->m) < 0) {
        release(&s);
        release(&u);
        return NULL;
    }
    status = vsj_step(&model->m, work->w, sc, (double *)s.view.buf,
                      (const double *)u.view.buf, dt, NULL);
    give_back(work);
    release(&s);
    release(&u);
    return Py_BuildValue("(idLL)", status, dt, 0LL, 0LL);
}

/* run(model, work, y, scheme, until, begin=None, finish=False, t_out=None, out=None,
 *     coulomb=None, stuck=None, held=None) -> (status, t, steps, rejected)
 * The engine's one entry point for integrating (c/run.c). With `begin` = (t0, t_end)
 * a run starts from y; it is then sampled at t_out (rows into out; the time-stepper's
 * Coulomb torques and stick states into coulomb, stuck), and with `finish` integrated to
 * its end; y receives the state where it stands. With `held` (one value per input
 * channel) y is the step function's state instead, advanced by one period of `until`
 * seconds with those inputs held. Releases the GIL while it integrates. */
static PyObject *py_run(PyObject *mod, PyObject *args, PyObject *kwds) {
    static char *keywords[] = {"model", "work", "y", "scheme", "until", "begin", "finish",
                               "t_out", "out", "coulomb", "stuck", "held", NULL};
    ModelObject *model;
    WorkObject *work;
    PyObject *oy, *oscheme, *obegin = Py_None, *ot = Py_None, *oout = Py_None;
    PyObject *oc = Py_None, *os = Py_None, *oheld = Py_None;
    int finish = 0, status = VSJ_OK;
    double until;
    vsj_scheme sc;
    arg y;
    ts_args a;
    Py_ssize_t ny, state, full;
    vsj_report r;
    (void)mod;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O!O!OOd|OpOOOOO:run", keywords, &ModelType,
                                     &model, &WorkType, &work, &oy, &oscheme, &until, &obegin,
                                     &finish, &ot, &oout, &oc, &os, &oheld))
        return NULL;
    if (scheme_of(oscheme, &sc) < 0)
        return NULL;
    if (oheld != Py_None)
        return held_period(model, work, oy, oheld, &sc, until);
    if (sc.method == VSJ_METHOD_RK4) {
        PyErr_SetString(PyExc_ValueError, "run: rk4 steps held periods only");
        return NULL;
    }
    if (!isfinite(until)) {
        PyErr_SetString(PyExc_ValueError, "run: `until` must be finite");
        return NULL;
    }
    if (get(oy, &y, DOUBLES, 1, -1, "y") < 0)
        return NULL;
    ny = items(&y);
    state = (Py_ssize_t)vsj_n_state(&model->m);
    full = state + (Py_ssize_t)vsj_n_acc(&model->m);
    if (ny != state && ny != full) {
        PyErr_Format(PyExc_ValueError, "y: expected %zd or %zd values, got %zd", state, full, ny);
        release(&y);
        return NULL;
    }
    memset(&a, 0, sizeof a);
    if (ot != Py_None
        && ts_samples(&a, &model->m, ot, oout, oc, os,
                      sc.method == VSJ_METHOD_TIMESTEP ? sc.h : 0.0) < 0) {
        ts_release(&a);
        release(&y);
        return NULL;
    }
    if (a.samples.n > 0 && a.samples.t[a.samples.n - 1] > until) {
        PyErr_SetString(PyExc_ValueError, "run: t_out beyond `until`");
        ts_release(&a);
        release(&y);
        return NULL;
    }
    if (take(work, &model->m) < 0) {
        ts_release(&a);
        release(&y);
        return NULL;
    }
    if (obegin != Py_None) {
        double t0, t_end;
        if (!PyArg_ParseTuple(obegin, "dd:begin", &t0, &t_end)) {
            give_back(work);
            ts_release(&a);
            release(&y);
            return NULL;
        }
        if (sc.method == VSJ_METHOD_DOPRI && sc.n_err > ny)
            sc.n_err = ny;
        if (sc.method == VSJ_METHOD_ROSENBROCK && sc.n_err > vsj_n_state(&model->m))
            sc.n_err = vsj_n_state(&model->m);
        status = vsj_begin(&model->m, work->w, &sc, (const double *)y.view.buf, ny, t0, t_end);
        if (status != VSJ_OK) {
            give_back(work);
            ts_release(&a);
            release(&y);
            return Py_BuildValue("(idLL)", status, t0, 0LL, 0LL);
        }
    }
    Py_BEGIN_ALLOW_THREADS
    r = vsj_advance(&model->m, work->w, (double *)y.view.buf, until, finish,
                    ot != Py_None ? &a.samples : NULL);
    Py_END_ALLOW_THREADS
    give_back(work);
    ts_release(&a);
    release(&y);
    return report_tuple(r);
}

/* transitions(model, work, out): the time-stepper's stick-phase counts since begin */
static PyObject *py_transitions(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    PyObject *oo;
    arg o;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!O:transitions", &ModelType, &model, &WorkType, &work, &oo))
        return NULL;
    if (get(oo, &o, INTS, 1, (Py_ssize_t)model->m.n_frictions, "out") < 0)
        return NULL;
    if (take(work, &model->m) < 0) {
        release(&o);
        return NULL;
    }
    vsj_ts_transitions(work->w, (int64_t *)o.view.buf);
    give_back(work);
    release(&o);
    Py_RETURN_NONE;
}

/* control_values(model, work, out): a controller's bus and actuators as they hold now
 * (vsj_control_width values); control_reset(model, work): the step function's
 * controller starts afresh at the next step */
static PyObject *py_control_values(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    PyObject *oo;
    arg o;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!O:control_values", &ModelType, &model, &WorkType, &work,
                          &oo))
        return NULL;
    if (get(oo, &o, DOUBLES, 1, (Py_ssize_t)vsj_control_width(&model->m), "out") < 0)
        return NULL;
    if (take(work, &model->m) < 0) {
        release(&o);
        return NULL;
    }
    vsj_control_values(&model->m, work->w, (double *)o.view.buf);
    give_back(work);
    release(&o);
    Py_RETURN_NONE;
}

static PyObject *py_control_reset(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!:control_reset", &ModelType, &model, &WorkType, &work))
        return NULL;
    if (take(work, &model->m) < 0)
        return NULL;
    vsj_control_reset(work->w);
    give_back(work);
    Py_RETURN_NONE;
}

/* observe(model, work, t_out, out, coulomb or None, raw) */
static PyObject *py_observe(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    PyObject *ot, *oout, *oc, *oraw;
    arg t_out, out, coulomb, raw;
    Py_ssize_t n_out, ny;
    int status;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!OOOO:observe", &ModelType, &model, &WorkType, &work, &ot,
                          &oout, &oc, &oraw))
        return NULL;
    coulomb.held = 0;
    if (get(ot, &t_out, DOUBLES, 0, -1, "t_out") < 0)
        return NULL;
    n_out = items(&t_out);
    {
        Py_ssize_t i;
        for (i = 0; i < n_out; i++)
            if (!isfinite(((const double *)t_out.view.buf)[i])) {
                PyErr_SetString(PyExc_ValueError, "t_out: times must be finite");
                release(&t_out);
                return NULL;
            }
    }
    if (get(oout, &out, DOUBLES, 0, -1, "out") < 0) {
        release(&t_out);
        return NULL;
    }
    ny = n_out ? items(&out) / n_out
               : vsj_n_state(&model->m) + vsj_control_width(&model->m);
    if (ny * n_out != items(&out)
        || ny < vsj_n_state(&model->m) + vsj_control_width(&model->m)) {
        PyErr_SetString(PyExc_ValueError, "out: needs one row of at least the state per sample "
                                          "(and a controller's columns last)");
        goto fail2;
    }
    if (oc != Py_None
        && get(oc, &coulomb, DOUBLES, 0, n_out * (Py_ssize_t)model->m.n_frictions, "coulomb") < 0)
        goto fail2;
    if (get(oraw, &raw, DOUBLES, 1, n_out * (Py_ssize_t)vsj_observation_width(&model->m),
            "raw") < 0)
        goto fail3;
    if (take(work, &model->m) < 0)
        goto fail4;
    Py_BEGIN_ALLOW_THREADS
    status = vsj_observe(&model->m, work->w, (const double *)t_out.view.buf, n_out,
                         (const double *)out.view.buf, ny,
                         coulomb.held ? (const double *)coulomb.view.buf : NULL,
                         (double *)raw.view.buf);
    Py_END_ALLOW_THREADS
    give_back(work);
    release(&raw);
    release(&coulomb);
    release(&out);
    release(&t_out);
    return PyLong_FromLong(status);
fail4:
    release(&raw);
fail3:
    release(&coulomb);
fail2:
    release(&out);
    release(&t_out);
    return NULL;
}

/* derivatives(model, work, t, y, dy) -> status */
static PyObject *py_derivatives(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    PyObject *oy, *ody;
    double t;
    arg y, dy;
    Py_ssize_t ny;
    int status;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!dOO:derivatives", &ModelType, &model, &WorkType, &work, &t,
                          &oy, &ody))
        return NULL;
    if (finite_scalar(t, "t") < 0 || get(oy, &y, DOUBLES, 0, -1, "y") < 0)
        return NULL;
    ny = items(&y);
    if (ny != vsj_n_state(&model->m) && ny != vsj_n_state(&model->m) + vsj_n_acc(&model->m)) {
        PyErr_SetString(PyExc_ValueError, "y: expected the state, or the state and accumulators");
        release(&y);
        return NULL;
    }
    if (get(ody, &dy, DOUBLES, 1, ny, "dy") < 0) {
        release(&y);
        return NULL;
    }
    if (take(work, &model->m) < 0) {
        release(&y);
        release(&dy);
        return NULL;
    }
    status = vsj_derivatives(&model->m, work->w, t, (const double *)y.view.buf, ny,
                             (double *)dy.view.buf);
    give_back(work);
    release(&y);
    release(&dy);
    return PyLong_FromLong(status);
}

/* jacobian(model, work, t, y, J, ft) -> status (vsj_jacobian); y the state, or the state
 * and the accumulators (J then has their rows too) */
static PyObject *py_jacobian(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    PyObject *oy, *oj, *oft;
    double t;
    arg y, J, ft;
    Py_ssize_t ns, ny;
    int status;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!dOOO:jacobian", &ModelType, &model, &WorkType, &work, &t,
                          &oy, &oj, &oft))
        return NULL;
    ns = (Py_ssize_t)vsj_n_state(&model->m);
    if (finite_scalar(t, "t") < 0 || get(oy, &y, DOUBLES, 0, -1, "y") < 0)
        return NULL;
    ny = items(&y);
    if (ny != ns && ny != ns + (Py_ssize_t)vsj_n_acc(&model->m)) {
        PyErr_SetString(PyExc_ValueError, "y: expected the state, or the state and accumulators");
        release(&y);
        return NULL;
    }
    if (get(oj, &J, DOUBLES, 1, ny * ns, "J") < 0) {
        release(&y);
        return NULL;
    }
    if (get(oft, &ft, DOUBLES, 1, ny, "ft") < 0) {
        release(&y);
        release(&J);
        return NULL;
    }
    if (take(work, &model->m) < 0) {
        release(&y);
        release(&J);
        release(&ft);
        return NULL;
    }
    status = vsj_jacobian(&model->m, work->w, t, (const double *)y.view.buf, (int64_t)ny,
                          (double *)J.view.buf, (double *)ft.view.buf);
    give_back(work);
    release(&y);
    release(&J);
    release(&ft);
    return PyLong_FromLong(status);
}

/* source_signals(model, work, t_out, angles, speeds) */
static PyObject *py_source_signals(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    PyObject *ot, *oa, *os;
    arg t, a, s;
    Py_ssize_t n, ns;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!OOO:source_signals", &ModelType, &model, &WorkType, &work,
                          &ot, &oa, &os))
        return NULL;
    if (get(ot, &t, DOUBLES, 0, -1, "t_out") < 0)
        return NULL;
    n = items(&t);
    ns = (Py_ssize_t)model->m.n_sources;
    if (increasing((const double *)t.view.buf, n, "t_out") < 0) {
        release(&t);
        return NULL;
    }
    if (get(oa, &a, DOUBLES, 1, n * ns, "angles") < 0) {
        release(&t);
        return NULL;
    }
    if (get(os, &s, DOUBLES, 1, n * ns, "speeds") < 0) {
        release(&t);
        release(&a);
        return NULL;
    }
    if (take(work, &model->m) < 0) {
        release(&t);
        release(&a);
        release(&s);
        return NULL;
    }
    vsj_source_signals(&model->m, work->w, (const double *)t.view.buf, n, (double *)a.view.buf,
                       (double *)s.view.buf);
    give_back(work);
    release(&t);
    release(&a);
    release(&s);
    Py_RETURN_NONE;
}

/* stored_energy(model, work, t, y, springs or None) -> (kinetic, springs, inductors) */
static PyObject *py_stored_energy(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    PyObject *oy, *osp;
    double t, e[3];
    arg y, sp;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!dOO:stored_energy", &ModelType, &model, &WorkType, &work,
                          &t, &oy, &osp))
        return NULL;
    sp.held = 0;
    if (finite_scalar(t, "t") < 0
        || get(oy, &y, DOUBLES, 0, (Py_ssize_t)vsj_n_state(&model->m), "y") < 0)
        return NULL;
    if (osp != Py_None
        && get(osp, &sp, DOUBLES, 1, (Py_ssize_t)model->m.n_springs, "springs") < 0) {
        release(&y);
        return NULL;
    }
    if (take(work, &model->m) < 0) {
        release(&y);
        release(&sp);
        return NULL;
    }
    vsj_stored_energy(&model->m, work->w, t, (const double *)y.view.buf, e,
                      sp.held ? (double *)sp.view.buf : NULL);
    give_back(work);
    release(&y);
    release(&sp);
    return Py_BuildValue("(ddd)", e[0], e[1], e[2]);
}

/* ---- the step function --------------------------------------------------------------- */

/* The state and the inputs of a step, checked. */

/* ts_prepare(model, work) -> status: the time-stepper's analysis, its history cleared */
static PyObject *py_ts_prepare(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    int status;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!:ts_prepare", &ModelType, &model, &WorkType, &work))
        return NULL;
    if (take(work, &model->m) < 0)
        return NULL;
    status = vsj_ts_prepare(&model->m, work->w);
    give_back(work);
    return PyLong_FromLong(status);
}

/* step_rate(model, work, state, inputs, dstate) -> status */
static PyObject *py_step_rate(PyObject *mod, PyObject *args) {
    ModelObject *model;
    WorkObject *work;
    PyObject *os, *ou, *od;
    arg s, u, d;
    int status;
    (void)mod;
    if (!PyArg_ParseTuple(args, "O!O!OOO:step_rate", &ModelType, &model, &WorkType, &work, &os,
                          &ou, &od))
        return NULL;
    if (step_args(model, os, ou, &s, &u, 0) < 0)
        return NULL;
    if (get(od, &d, DOUBLES, 1, (Py_ssize_t)vsj_step_state_size(&model->m), "dstate") < 0) {
        release(&s);
        release(&u);
        return NULL;
    }
    if (take(work, &model->m) < 0) {
        release(&s);
        release(&u);
        release(&d);
        return NULL;
    }
    status = vsj_step_rate(&model->m, work->w, (const double *)s.view.buf,
                           (const double *)u.view.buf, (double *)d.view.buf);
    give_back(work);
    release(&s);
    release(&u);
    release(&d);
    return PyLong_FromLong(status);
}

/* solve_tridiagonal(lower, diagonal, upper, rhs): vsj_solve_tridiagonal, rhs receiving
 * the solution (every array overwritten); 0, or -1 for a singular system. */
static PyObject *py_solve_tridiagonal(PyObject *mod, PyObject *args) {
    PyObject *o[4];
    arg a[4];
    const char *names[4] = {"lower", "diagonal", "upper", "rhs"};
    Py_ssize_t n, i, k;
    double *fill;
    int status = 0, ok = 1;
    (void)mod;
    if (!PyArg_ParseTuple(args, "OOOO:solve_tridiagonal", &o[0], &o[1], &o[2], &o[3]))
        return NULL;
    for (i = 0; i < 4; i++)
        a[i].held = 0;
    for (i = 0; ok && i < 4; i++)
        ok = get(o[i], &a[i], DOUBLES, 1, -1, names[i]) == 0;
    n = ok ? items(&a[1]) : 0;
    if (ok && (n < 1 || items(&a[0]) != n - 1 || items(&a[2]) != n - 1 || items(&a[3]) != n)) {
        PyErr_SetString(PyExc_ValueError, "solve_tridiagonal: a diagonal of n >= 1 values, "
                                          "lower and upper of n - 1, rhs of n");
        ok = 0;
    }
    for (k = 0; ok && k < 4; k++) {
        const double *v = (const double *)a[k].view.buf;
        for (i = 0; ok && i < items(&a[k]); i++)
            if (!isfinite(v[i])) {
                PyErr_Format(PyExc_ValueError, "solve_tridiagonal: %s[%zd] is not finite",
                             names[k], i);
                ok = 0;
            }
    }
    fill = ok ? (double *)malloc((size_t)(n > 2 ? n - 2 : 1) * sizeof(double)) : NULL;
    if (ok && !fill) {
        PyErr_NoMemory();
        ok = 0;
    }
    if (ok) {
        Py_BEGIN_ALLOW_THREADS
        status = vsj_solve_tridiagonal((int64_t)n, (double *)a[0].view.buf,
                                       (double *)a[1].view.buf, (double *)a[2].view.buf, fill,
                                       (double *)a[3].view.buf);
        Py_END_ALLOW_THREADS
    }
    free(fill);
    for (i = 0; i < 4; i++)
        release(&a[i]);
    return ok ? PyLong_FromLong(status) : NULL;
}

/* solve_impulses(YT, qs, cap, active, ps, states, iterations): vsj_solve_impulses */
static PyObject *py_solve_impulses(PyObject *mod, PyObject *args) {
    PyObject *o[7];
    arg a[7];
    Py_ssize_t n, m, count, i;
    int status = VSJ_OK, ok = 1;
    (void)mod;
    if (!PyArg_ParseTuple(args, "OOOOOOO:solve_impulses", &o[0], &o[1], &o[2], &o[3], &o[4],
                          &o[5], &o[6]))
        return NULL;
    for (i = 0; i < 7; i++)
        a[i].held = 0;
    if (get(o[2], &a[2], DOUBLES, 0, -1, "cap") < 0)
        return NULL;
    m = items(&a[2]);
    if (get(o[0], &a[0], DOUBLES, 0, -1, "YT") < 0 || get(o[1], &a[1], DOUBLES, 0, -1, "qs") < 0)
        ok = 0;
    n = ok && m ? items(&a[0]) / m : 0;
    count = ok && m ? items(&a[1]) / m : 0;
    if (ok && (m < 1 || n * m != items(&a[0]) || count * m != items(&a[1]) || n > 1024
               || m > 65536)) {
        PyErr_SetString(PyExc_ValueError, "solve_impulses: YT needs m columns (at most 65536) "
                                          "and at most 1024 rows, qs rows of m");
        ok = 0;
    }
    if (ok) {
        const double *y = (const double *)a[0].view.buf, *q = (const double *)a[1].view.buf;
        const double *cap = (const double *)a[2].view.buf;
        for (i = 0; ok && i < items(&a[0]); i++)
            ok = isfinite(y[i]);
        for (i = 0; ok && i < items(&a[1]); i++)
            ok = isfinite(q[i]);
        for (i = 0; ok && i < m; i++)
            ok = isfinite(cap[i]) && cap[i] >= 0.0;
        if (!ok)
            PyErr_SetString(PyExc_ValueError, "solve_impulses: YT and qs must be finite, the "
                                              "caps finite and >= 0");
    }
    if (ok && (get(o[3], &a[3], BOOLS, 0, m, "active") < 0
               || get(o[4], &a[4], DOUBLES, 1, count * m, "ps") < 0
               || get(o[5], &a[5], INTS, 1, count * m, "states") < 0
               || get(o[6], &a[6], INTS, 1, count, "iterations") < 0))
        ok = 0;
    if (ok) {
        Py_BEGIN_ALLOW_THREADS
        status = vsj_solve_impulses(n, m, (const double *)a[0].view.buf, count,
                                    (const double *)a[1].view.buf, (const double *)a[2].view.buf,
                                    (const unsigned char *)a[3].view.buf,
                                    (double *)a[4].view.buf, (int64_t *)a[5].view.buf,
                                    (int64_t *)a[6].view.buf);
        Py_END_ALLOW_THREADS
    }
    for (i = 0; i < 7; i++)
        release(&a[i]);
    if (!ok)
        return NULL;
    if (status == VSJ_NO_MEMORY)
        return PyErr_NoMemory();
    Py_RETURN_NONE;
}

/* ---- element laws ------------------------------------------------------------------------ */

static int par_row(PyObject *o, double p[VSJ_NPAR]) {
    arg a;
    Py_ssize_t i, n;
    if (get(o, &a, DOUBLES, 0, -1, "par") < 0)
        return -1;
    n = items(&a);
    if (n > VSJ_NPAR) {
        PyErr_Format(PyExc_ValueError, "par: at most %d values, got %zd", VSJ_NPAR, n);
        release(&a);
        return -1;
    }
    for (i = 0; i < VSJ_NPAR; i++)
        p[i] = i < n ? ((const double *)a.view.buf)[i] : 0.0;
    release(&a);
    return 0;
}

/* spring_law(law, par, phis, q, out): out[i] = (torque, stiffness, energy, dV/dq) */
static PyObject *py_spring_law(PyObject *mod, PyObject *args) {
    int law;
    PyObject *opar, *ophi, *oout;
    double q, p[VSJ_NPAR];
    arg phi, out;
    Py_ssize_t i, n;
    (void)mod;
    if (!PyArg_ParseTuple(args, "iOOdO:spring_law", &law, &opar, &ophi, &q, &oout))
        return NULL;
    if (law < VSJ_LINEAR || law >= VSJ_N_SPRING_LAWS) {
        PyErr_Format(PyExc_ValueError, "unknown spring law %d", law);
        return NULL;
    }
    if (par_row(opar, p) < 0 || get(ophi, &phi, DOUBLES, 0, -1, "phi") < 0)
        return NULL;
    n = items(&phi);
    if (get(oout, &out, DOUBLES, 1, 4 * n, "out") < 0) {
        release(&phi);
        return NULL;
    }
    for (i = 0; i < n; i++)
        vsj_spring_law(law, p, ((const double *)phi.view.buf)[i], q,
                       (double *)out.view.buf + 4 * i);
    release(&phi);
    release(&out);
    Py_RETURN_NONE;
}

/* spring_geometry(par, phi, q) -> (V, dV/dphi, d2V/dphi2, dV/dq, T_phi, dT_phi/dphi) */
static PyObject *py_spring_geometry(PyObject *mod, PyObject *args) {
    PyObject *opar;
    double phi, q, p[VSJ_NPAR], out[6];
    (void)mod;
    if (!PyArg_ParseTuple(args, "Odd:spring_geometry", &opar, &phi, &q) || par_row(opar, p) < 0)
        return NULL;
    vsj_spring_geometry(p, phi, q, out);
    return Py_BuildValue("(dddddd)", out[0], out[1], out[2], out[3], out[4], out[5]);
}

/* spring_extensions(par, phi, q) -> (extension a, extension b) */
static PyObject *py_spring_extensions(PyObject *mod, PyObject *args) {
    PyObject *opar;
    double phi, q, p[VSJ_NPAR], out[2];
    (void)mod;
    if (!PyArg_ParseTuple(args, "Odd:spring_extensions", &opar, &phi, &q) || par_row(opar, p) < 0)
        return NULL;
    vsj_spring_extensions(p, phi, q, out);
    return Py_BuildValue("(dd)", out[0], out[1]);
}

/* friction_torque(law, b, k, kb, w, speeds, out) */
static PyObject *py_friction_torque(PyObject *mod, PyObject *args) {
    int law;
    double b, k, kb, w;
    PyObject *os, *oout;
    arg s, out;
    Py_ssize_t i, n;
    (void)mod;
    if (!PyArg_ParseTuple(args, "iddddOO:friction_torque", &law, &b, &k, &kb, &w, &os, &oout))
        return NULL;
    if (law < VSJ_VISCOUS || law >= VSJ_N_FRICTION_LAWS) {
        PyErr_Format(PyExc_ValueError, "unknown friction law %d", law);
        return NULL;
    }
    if (get(os, &s, DOUBLES, 0, -1, "speeds") < 0)
        return NULL;
    n = items(&s);
    if (get(oout, &out, DOUBLES, 1, n, "out") < 0) {
        release(&s);
        return NULL;
    }
    for (i = 0; i < n; i++)
        ((double *)out.view.buf)[i] =
            vsj_friction_torque(law, b, k, kb, w, ((const double *)s.view.buf)[i], NULL);
    release(&s);
    release(&out);
    Py_RETURN_NONE;
}

static PyObject *py_status_text(PyObject *mod, PyObject *arg_) {
    long long status = PyLong_AsLongLong(arg_);
    (void)mod;
    if (status == -1 && PyErr_Occurred())
        return NULL;
    return PyUnicode_FromString(vsj_status_text(status < 0 || status > 1000 ? -1 : (int)status));
}

static PyObject *py_observation_width(PyObject *mod, PyObject *arg_) {
    (void)mod;
    if (!PyObject_TypeCheck(arg_, &ModelType)) {
        PyErr_SetString(PyExc_TypeError, "observation_width: needs a Model");
        return NULL;
    }
    return PyLong_FromLongLong((long long)vsj_observation_width(&((ModelObject *)arg_)->m));
}

static PyMethodDef methods[] = {
    {"run", (PyCFunction)(void (*)(void))py_run, METH_VARARGS | METH_KEYWORDS,
     "The engine's one entry point for integrating: start, sample and finish a run, or "
     "advance the step function by a held period."},
    {"transitions", py_transitions, METH_VARARGS, "The time-stepper's stick-phase counts."},
    {"control_values", py_control_values, METH_VARARGS,
     "A controller's bus and actuators as they hold now."},
    {"control_reset", py_control_reset, METH_VARARGS,
     "Start the step function's controller afresh at its next step."},
    {"observe", py_observe, METH_VARARGS, "Every internal signal at samples (vsj_observe)."},
    {"derivatives", py_derivatives, METH_VARARGS, "dy/dt (vsj_derivatives)."},
    {"jacobian", py_jacobian, METH_VARARGS,
     "d(dy/dt)/dy and d(dy/dt)/dt of the state (vsj_jacobian)."},
    {"source_signals", py_source_signals, METH_VARARGS, "Source angles and speeds."},
    {"stored_energy", py_stored_energy, METH_VARARGS, "Kinetic, spring and inductor energy."},
    {"ts_prepare", py_ts_prepare, METH_VARARGS, "Analyse a model for the time-stepper."},
    {"step_rate", py_step_rate, METH_VARARGS, "ds/dt of the step function's state."},
    {"solve_tridiagonal", py_solve_tridiagonal, METH_VARARGS,
     "solve_tridiagonal(lower, diagonal, upper, rhs): rhs receives the solution (0, or -1 "
     "if singular); every array is overwritten"},
    {"solve_impulses", py_solve_impulses, METH_VARARGS,
     "The joint Coulomb impulse problem for a sequence of right-hand sides."},
    {"spring_law", py_spring_law, METH_VARARGS, "Spring law at many deflections."},
    {"spring_geometry", py_spring_geometry, METH_VARARGS, "Both geometric models at a point."},
    {"spring_extensions", py_spring_extensions, METH_VARARGS, "Spring extensions l - s0."},
    {"friction_torque", py_friction_torque, METH_VARARGS, "Friction law at many speeds."},
    {"status_text", py_status_text, METH_O, "Text of an engine status."},
    {"observation_width", py_observation_width, METH_O, "Columns of observe's rows."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "vsj._core",
    "The compiled engine of vsj (C99 library vsj.h) behind a thin binding.", -1, methods,
    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__core(void) {
    PyObject *m;
    if (PyType_Ready(&ModelType) < 0 || PyType_Ready(&WorkType) < 0)
        return NULL;
    m = PyModule_Create(&module);
    if (!m)
        return NULL;
    Py_INCREF(&ModelType);
    if (PyModule_AddObject(m, "Model", (PyObject *)&ModelType) < 0) {
        Py_DECREF(&ModelType);
        Py_DECREF(m);
        return NULL;
    }
    Py_INCREF(&WorkType);
    if (PyModule_AddObject(m, "Work", (PyObject *)&WorkType) < 0) {
        Py_DECREF(&WorkType);
        Py_DECREF(m);
        return NULL;
    }
    if (PyModule_AddObject(m, "LAYOUT", layout_object()) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    PyModule_AddIntConstant(m, "NPAR", VSJ_NPAR);
    PyModule_AddIntConstant(m, "VERSION_MAJOR", VSJ_VERSION_MAJOR);
    return m;
}
