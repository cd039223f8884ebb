/* Private declarations shared by the engine's source files. */
#ifndef VSJ_INTERNAL_H
#define VSJ_INTERNAL_H

#include "vsj.h"

/* columns of the work arrays */
enum { U = 0, UD = 1, SG = 2, SRCF = 3, SRCTAU = 4, SRCW = 5 };        /* srcw, per source */
enum { SLIP = 0, TORQUE = 1, EXTRA = 2, FRW = 3 };                     /* frw, per friction */
enum { DEFL = 0, RATE = 1, SPTAU = 2, STIFF = 3, ENERGY = 4, DVDQ = 5, SPW = 6 }; /* spw */

/* Scratch of the time-stepper (timestep.c); sized for the model at vsj_work_new. */
typedef struct ts_work {
    int prepared;
    int64_t na;            /* impulse unknowns (groups of parallel stiction elements) */
    int64_t n_nonlinear, n_watched, n_mid_ch, n_mid_src, n_end_ch;
    int factored;          /* H_last and its factor are valid */
    double t;              /* time reached */
    double q_prev;         /* pivot position at t */
    double angle_mid, q_mid;
    /* n x n */
    double *H, *H_last, *Lc, *Bx, *G, *Lg, *Gc, *Kc;
    /* n */
    double *x, *v, *r, *vfree, *v1, *x1, *col, *drow, *tv, *cv, *z;
    double *Bu;            /* n x s */
    double *DxT, *DuT;     /* n x (f + k), s x (f + k) */
    double *DxA, *DuA, *YlT; /* n x f, s x f, n x f (first na columns used) */
    /* per impulse unknown (f) */
    double *qv, *cap, *p, *mask, *d, *g, *level, *memo; /* memo: f + 1 */
    int64_t *state;
    unsigned char *involved;
    /* per friction element */
    double *slip, *s0, *f0, *df0, *force, *share, *ratio;
    int64_t *held, *slot, *lead, *transitions, *nonlinear, *watched;
    unsigned char *active, *driven, *linear;
    /* springs, sources, loads, motors, channels */
    double *sp_c, *sp_kap, *u0, *sg0, *u1, *sg1, *um, *srcF, *ldm, *vm, *cur, *i1;
    int64_t *mid_ch, *mid_src, *end_ch;
    unsigned char *wanted;
} ts_work;

struct vsj_work {
    /* sizes the work was made for */
    int64_t n, s, f, k, nl, nm, nch, rows;
    int64_t *hint;         /* nch: last spline piece used */
    double *chan;          /* nch x 3: value, derivative, integral */
    double *srcw;          /* s x SRCW */
    double *frw;           /* f x FRW */
    double *spw;           /* k x SPW */
    double *ldw;           /* nl x 2: torque, speed */
    double *mow;           /* nm x 2: rotor speed, voltage */
    double *gen;           /* n: generalised force */
    double q, qdot;        /* pivot position and rate */
    int status;
    const double *held;    /* NULL: inputs from the splines; else held values (stepper) */
    double *pos0;          /* s: source angles at t = 0 with held inputs */
    /* dopri scratch, ny_max each (K: 7 ny_max) */
    int64_t ny_max;
    double *K, *yt, *y1, *err, *r3, *r4, *r5, *y, *dy;
    /* stepper scratch */
    double *sy, *sk, *sacc;
    ts_work ts;
    void *block;           /* the one allocation behind all of the above */
};

/* evaluation (eval.c) */
void vsj__eval_channel(const vsj_model *m, vsj_work *w, int64_t c, double t);
void vsj__eval_source(const vsj_model *m, vsj_work *w, int64_t j);
void vsj__eval_inputs(const vsj_model *m, vsj_work *w, double t);
double vsj__xdot(const vsj_model *m, int64_t r, const double *vec);
double vsj__udot(const vsj_model *m, int64_t r, const double *srcw, int col);
double vsj__udotv(const vsj_model *m, int64_t r, const double *vec);
void vsj__xadd(const vsj_model *m, int64_t r, double *vec, double scale);
void vsj__uaddv(const vsj_model *m, int64_t r, double *vec, double scale);
double vsj__pivot_at(const vsj_model *m, vsj_work *w, double angle);
double vsj__pivot_angle(const vsj_model *m, const vsj_work *w, const double *x);
double vsj__pivot_position(const vsj_model *m, vsj_work *w, const double *x);
void vsj__eval_derivatives(const vsj_model *m, vsj_work *w, double t, const double *y,
                           int64_t ny, double *dy);

/* laws (laws.c) */
double vsj__spring(int64_t law, const double *p, double phi, double q, double *stiff,
                   double *energy, double *dvdq);

static inline const double *vsj__row(const vsj_model *m, int64_t r) {
    return m->par + r * VSJ_NPAR;
}

#define VSJ_PI 3.14159265358979323846

#endif
