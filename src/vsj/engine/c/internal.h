/* Private declarations shared by the engine's source files. */
#ifndef VSJ_INTERNAL_H
#define VSJ_INTERNAL_H

#include <math.h>

#include "vsj.h"

/* columns of the work arrays */
enum { U = 0, UD = 1, SG = 2, SRCF = 3, SRCTAU = 4, SRCW = 5 };        /* srcw, per source */
/* frw, per friction; DSLIP, DPOS: a contact's force's derivatives in its slip and its
 * penetration (the Jacobian's; other laws' slopes follow from their slip) */
enum { SLIP = 0, TORQUE = 1, EXTRA = 2, DSLIP = 3, DPOS = 4, FRW = 5 };
/* spw, per spring; DTQ, DVQQ, DVQP: d tau/dq, d(dV/dq)/dq, d(dV/dq)/dphi (the Jacobian's) */
enum { DEFL = 0, RATE = 1, SPTAU = 2, STIFF = 3, ENERGY = 4, DVDQ = 5, DTQ = 6, DVQQ = 7, DVQP = 8,
       SPW = 9 };

/* Scratch of the time-stepper (timestep.c); sized for the model at vsj_work_new. */
typedef struct ts_work {
    int prepared;
    const double *for_par, *for_rows, *for_mass; /* the model it was prepared for */
    int64_t na;            /* impulse unknowns of friction (groups of parallel elements) */
    int64_t nc;            /* impulse unknowns of end stops: two per spring with a stop */
    int64_t ncomp;         /* compliant ones among them: one extra row of YlT each */
    double hs_prev;        /* the previous step's length (the compliance rows depend on it) */
    int memo_full;         /* the impulse memo is for the problem with the stops (1) or
                            * without (0; -1 neither) */
    int64_t n_nonlinear, n_watched, n_mid_ch, n_mid_src, n_end_ch;
    int factored;          /* H_last and its factor are valid */
    int first;             /* the next step is a call's first (vsj__ts_begin) */
    int pivot_still;       /* the pivot's angle cannot move (its sources' inputs are 0) */
    double t;              /* time reached */
    double origin;         /* steps end at origin + k h (vsj__ts_advance) */
    int64_t k;
    double q_prev;         /* pivot position at t */
    double angle_prev;     /* pivot mechanism's angle at t */
    double angle_mid, q_mid;
    /* n x n; G, Lg, Gc, Lk: (n + 2 k)^2, the impulse problem's rows */
    double *H, *H_last, *Lc, *Bx, *G, *Lg, *Gc, *Lk;
    /* n; tv, cv, z: n + 2 k */
    double *x, *v, *r, *vfree, *v1, *x1, *col, *drow, *tv, *cv, *z;
    double *Bu;            /* n x s */
    double *DxT, *DuT;     /* n x (f + k), s x (f + k) */
    double *DxA, *DuA, *YlT; /* n x m, s x m, (n + 2 k) x m with m = f + 2 k (used: na + nc) */
    /* per end-stop unknown (2 k): spring, side (+1, -1), stop angle and stiffness, row
     * of its compliance (-1: rigid), and the largest end speed that keeps it closed */
    int64_t *cspring, *ccomp;
    double *csign, *cstop, *ckstop, *cb;
    unsigned char *has_stop; /* per spring */
    /* per impulse unknown (f + 2 k): friction groups, then end stops */
    double *qv, *lo, *hi, *p, *mask, *d, *g, *memo; /* memo: one more */
    /* per friction group: its kinetic level this step, and its static one */
    double *level, *hold;
    int64_t *state;
    unsigned char *involved;
    /* per friction element; lev: its Coulomb level this step, levs: its static
     * level (lev times the peak when it slips, lev when it is stuck) */
    double *slip, *s0, *f0, *df0, *force, *share, *ratio, *lev, *levs;
    double *theta;      /* weight of the step's end in the viscous part: 1 or 1/2 */
    int64_t *damper, n_damper; /* the elements with theta 1/2 */
    int any_varying;       /* an element's level changes (normal force, table, peak) */
    int64_t *held, *slot, *lead, *transitions, *nonlinear, *watched;
    unsigned char *active, *driven, *linear;
    /* springs, sources, loads, motors, channels */
    double *sp_c, *sp_kap, *u0, *sg0, *u1, *sg1, *um, *srcF, *ldm, *vm, *cur, *i1;
    /* motors: the armature circuit's exact step (rl_*, for steps of length rl_h), the
     * rotor speed at the step's start, and over the step the charge and Joule heat */
    double rl_h, *rl_e, *rl_decay, *rl_gain, *rl_half, *om0, *charge, *heat;
    int64_t *mid_ch, *mid_src, *end_ch;
    unsigned char *wanted;
} ts_work;

/* The state of a resumable adaptive integration: Dormand-Prince (dopri.c) or
 * Rosenbrock (rosenbrock.c). */
typedef struct dopri_state {
    int status;
    int rosenbrock;        /* which of the two steps this run */
    int64_t ny, n_err, max_steps, steps, rejected;
    double rtol, atol, h_max;
    double t, t_end, h;    /* where the integration stands, its end, the next step */
    double t_prev, h_prev; /* the last accepted step (for the samples it covers) */
    double err_old;        /* the step controller's memory (its last error; rosenbrock:
                            * 0 before the first accepted step) */
    double h_acc;          /* rosenbrock: the last accepted step */
    int rejected_last;
} dopri_state;

/* Rows of ny_max values in a work's K: dopri's stages take 7, Rosenbrock's
 * (rosenbrock.c: its stages and the interpolant's derivatives) 14. */
#define VSJ_K_ROWS 14
/* How closely the adaptive schemes locate the moment a physical limit is crossed (the
 * pivot leaving its range): a step that ends past it is halved until it is shorter than
 * this fraction of the time reached (and 1 ns), so that the run stops there, its samples
 * kept up to it, rather than at the end of a long step from rest. */
#define VSJ_LIMIT_RESOLUTION 1e-9
static inline int vsj__locating(double h, double t) {
    return h > VSJ_LIMIT_RESOLUTION * (fabs(t) > 1.0 ? fabs(t) : 1.0);
}

struct vsj_work {
    /* sizes the work was made for */
    int64_t n, s, f, k, nl, nm, nch, rows;
    int64_t *hint;         /* nch: last spline piece used */
    double *chan;          /* nch x 3: value, derivative, integral */
    double *chan_dd;       /* nch: second derivative (the Rosenbrock steps' time terms) */
    double *brk;           /* nch: each channel's next corner after the run's time */
    int left;              /* evaluate the inputs' left limits at a knot (a step's end
                            * on a corner) */
    /* the splines' last evaluation (chan, chan_dd and the sources' U, UD, SG in srcw)
     * was of model in_model at time in_t, from the left if in_left (NaN: none valid) */
    const vsj_model *in_model;
    double in_t;
    int in_left;
    double *srcw;          /* s x SRCW */
    double *frw;           /* FRW x f: each field (SLIP, TORQUE, ...) of every element */
    /* model ev_model analysed for evaluations (vsj__eval_prepare; NULL: none): the
     * friction elements the dynamics feel (ev_nd of them, in order, in ev_list); for each
     * element, the first element with the same slip row (-1: it is the first), whether
     * its level varies (vsj__varying) and, for a plain arctangent law, the earlier arctan
     * element of its row and sharpness whose arctangent it shares (ev_share, -1: none);
     * each input channel that is one constant piece (ev_const); and each element's
     * arctangent in the last evaluation (an arctan law). The elements of each pass over
     * the laws (index: 0 the dynamics' elements, 1 every element) are split by law, in
     * element order: the plain arctangents, a constant level and no extra torque (ev_arc,
     * ev_narc of them), and the others (ev_oth, ev_noth). */
    const vsj_model *ev_model;
    int64_t ev_nd, *ev_list, *ev_same, *ev_share;
    int64_t ev_narc[2], ev_noth[2], *ev_arc[2], *ev_oth[2];
    unsigned char *ev_vary, *ev_const;
    double *ev_atan;
    double *spw;           /* k x SPW */
    double *ldw;           /* nl x 2: torque, speed */
    double *mow;           /* nm x 2: rotor speed, voltage */
    double *gen;           /* n: generalised force */
    double q, qdot;        /* pivot position and rate */
    double pivot_dq;       /* dq/d(pivot angle) where the Jacobian was last taken */
    double pivot_key[4];   /* angle and pivot parameters of the cached q and cos(angle) */
    double pivot_q, pivot_cos;
    double *spcache;       /* k x 4: each spring law's cache (vsj__spring) */
    int status;
    const double *held;    /* NULL: inputs from the splines; else held values (stepper) */
    double *pos0;          /* s: source angles at t = 0 with held inputs */
    /* dopri scratch, ny_max each (K: 7 ny_max); y the current state, yo the start of
     * the last accepted step, r3..r5 its dense-output coefficients */
    int64_t ny_max;
    double *K, *yt, *y1, *err, *r3, *r4, *r5, *y, *yo, *dy;
    dopri_state dopri;
    /* Rosenbrock scratch (ns = vsj_n_state): the Jacobian J and the factor of
     * I/(gamma h) - J (ns x ns), its pivots, df/dt (ns), the generalised forces'
     * derivatives (n x (ns + 1)), the ledger's rates' derivatives in the state and in
     * time ((ny_max - ns) x (ns + 1)) and the sources' forces' (s x (ns + 1)); J, df/dt
     * and the ledger's rows again at a candidate step's end (_new) */
    double *jac, *lu, *ft, *jg, *jacc, *jsrc, *jac_new, *ft_new, *jacc_new;
    int64_t *piv;
    /* the run vsj_begin started (run.c) */
    vsj_scheme scheme;
    int64_t run_ny, run_steps;
    double run_end;
    int run_status;
    /* the controller (control.c): its sizes, whether the model has one, the samples
     * taken, the run's start and the next sample's time, the noise generator's state;
     * bus (nbus), block states (ncs) and their next values, a block's inputs (nbus at
     * most), the sensors' delay lines (ndel), the actuators' held values (nact), and
     * the actuator driving each input channel (-1: none) */
    int64_t nref, nmeas, nblk, nact, nbus, ncs, ndel, nbi;
    int ctl_on, ctl_started;
    int64_t ctl_k, ctl_k0; /* samples taken, and when the run (or period) began */
    double ctl_stop;       /* no sample at or after this time (a held period's end) */
    double ctl_t0, ctl_next, ctl_last; /* ctl_last: the last sample's time */
    double ctl_tol;        /* times this close to a sample's are the sample's */
    uint64_t ctl_rng;
    double *ctl_bus, *ctl_x, *ctl_x1, *ctl_in, *ctl_delay, *ctl_u;
    double *ctl_before;    /* bus and actuators as they held before the last sample */
    int64_t *ctl_drive;
    /* stepper scratch */
    double *sy, *sk, *sacc;
    ts_work ts;
    void *block;           /* the one allocation behind all of the above */
};

/* Internal functions shared between the engine's files: not exported from a
 * shared library (direct calls, no symbol interposition). */
#if defined(__GNUC__) && !defined(_WIN32)
#define VSJ_INTERNAL __attribute__((visibility("hidden")))
#else
#define VSJ_INTERNAL
#endif

/* Small kernels inlined wherever they are called (GCC and clang; elsewhere a plain
 * inline), so that a caller compiled for a constant size gets straight-line code. */
#if defined(__GNUC__)
#define VSJ_ALWAYS_INLINE static inline __attribute__((always_inline))
#else
#define VSJ_ALWAYS_INLINE static inline
#endif

/* the Cholesky kernels of the time-stepper and its impulse solver */
#include "linalg.h"

/* A model check's failure: the message formatted into `message` (of `size` bytes);
 * returns VSJ_BAD_ARGUMENT (model.c). */
VSJ_INTERNAL int vsj__fail(char *message, size_t size, const char *format, ...);

/* The controller (control.c): its part of vsj_check_model; at a run's start (t0, the
 * state y) its first sample; at a sample's time (w->ctl_next, which the schemes land
 * on) the next; and a sample row's controller columns (vsj_control_width). */
VSJ_INTERNAL int vsj__control_check(const vsj_model *m, char *message, size_t size);
VSJ_INTERNAL void vsj__control_begin(const vsj_model *m, vsj_work *w, double t0,
                                     const double *y);
VSJ_INTERNAL void vsj__control_sample(const vsj_model *m, vsj_work *w, double t,
                                      const double *y);
VSJ_INTERNAL void vsj__control_record(const vsj_work *w, double t, double *row);
/* The driven channels held at the actuators' values u (vsj_observe's rows end with them). */
VSJ_INTERNAL void vsj__control_hold(const vsj_model *m, vsj_work *w, const double *u);
/* A held period of the step function from the state y (engine form), dt long: the
 * controller samples at its start and every period within (its state goes on from
 * the last call's, or starts afresh after vsj_control_reset). */
VSJ_INTERNAL void vsj__control_period(const vsj_model *m, vsj_work *w, const double *y,
                                      double dt);

/* evaluation (eval.c); vsj__eval_prepare analyses the model's rows and inputs for it.
 * Every entry point that evaluates (vsj_begin, a step function's period, the one-off
 * evaluations) clears w->ev_model, so that each analyses the model it is given, even
 * one at another's freed addresses or with rows changed in place. */
VSJ_INTERNAL void vsj__eval_prepare(const vsj_model *m, vsj_work *w);
VSJ_INTERNAL void vsj__eval_derivatives(const vsj_model *m, vsj_work *w, double t, const double *y,
                           int64_t ny, double *dy);

/* The Jacobian of the state's derivatives (the first ns = vsj_n_state components
 * of y; row-major ns x ns in J) and their partial derivative in time (ft), at the
 * point (t, y) of the vsj__eval_derivatives call just before: it reads that call's
 * element speeds, stiffnesses, pivot and inputs, so it must follow it. The speed
 * dependence of friction tables and the time dependence of normal-force inputs are
 * left out. */
VSJ_INTERNAL void vsj__eval_jacobian(const vsj_model *m, vsj_work *w, double *J, double *ft);

/* The ledger's rows of the Jacobian: each accumulator's rate differentiated in the
 * state and (the last column) in time, vsj_n_acc rows of ns + 1, into rows; from the
 * full-length vsj__eval_derivatives at (t, y) just before and the state's J and ft
 * (vsj__eval_jacobian, which must come between). */
VSJ_INTERNAL void vsj__eval_ledger_rows(const vsj_model *m, vsj_work *w, const double *y,
                                        const double *J, const double *ft, double *rows);

/* The inputs' corners (breaks.c): the first time after t at which a channel's spline
 * jumps in value or slope, INFINITY if none (remembered per channel in w->brk, which
 * vsj__breaks_reset clears when a run begins); and the next step of an adaptive run,
 * its proposal d->h cut to end on the run's end (*end = 1) or on the next corner
 * (*end = 2), landing exactly at *t_land. */
VSJ_INTERNAL double vsj__next_break(const vsj_model *m, vsj_work *w, double t);
VSJ_INTERNAL void vsj__breaks_reset(const vsj_model *m, vsj_work *w);
VSJ_INTERNAL double vsj__step_length(const vsj_model *m, vsj_work *w,
                                     const struct dopri_state *d, int *end, double *t_land);

/* The 64-bit FNV-1a hash of `len` bytes: the checksum of the model files (blob.c,
 * load.c) and of the FMU's serialized states. */
VSJ_INTERNAL uint64_t vsj__fnv1a(const unsigned char *data, size_t len);

/* Whether a spring of m has a rigid end stop (only the time-stepper can run it). */
VSJ_INTERNAL int vsj__rigid_stop(const vsj_model *m);

/* Whether an adaptive scheme's tolerances lie in the ranges vsj.simulate.RANGES gives
 * them (the loader's and vsj_step's check). */
static inline int vsj__tolerances_ok(double rtol, double atol) {
    return rtol >= 1e-14 && rtol <= 1e-2 && atol >= 1e-20 && atol <= 1e-2;
}

/* The schemes behind vsj_begin/vsj_advance and vsj_step (dopri.c, timestep.c).
 * Dormand-Prince 5(4), resumable: begin sets the initial state (ny values) at t0 and
 * the settings; each advance writes the samples at t_out (increasing, after those of
 * earlier calls, not beyond t_end), stepping as far as they need and, with `finish`,
 * on to t_end; y_now (may be NULL) receives the state where it stands. The steps do
 * not depend on how the samples are split between calls. n_err leading components
 * enter the error norm. */
VSJ_INTERNAL int vsj__dopri_begin(const vsj_model *m, vsj_work *w, const double *y0, int64_t ny,
                                  double t0, double t_end, double rtol, double atol,
                                  double h_max, int64_t max_steps, int64_t n_err);
VSJ_INTERNAL vsj_report vsj__dopri_advance(const vsj_model *m, vsj_work *w, const double *t_out,
                                           int64_t n_out, double *out, int64_t out_cols,
                                           int finish, double *y_now);
/* The weighted RMS norm of the error e over the first n_err components (scale atol
 * + rtol max(|y|, |y2|)), and the initial step of an adaptive method of `order` from
 * (t0, y) with derivatives f0 (Hairer's estimate; one evaluation, into `scratch`). */
VSJ_INTERNAL double vsj__err_norm(const double *e, const double *y, const double *y2,
                                  double rtol, double atol, int64_t n_err);
VSJ_INTERNAL double vsj__initial_step(const vsj_model *m, vsj_work *w, const double *y,
                                      const double *f0, int64_t ny, double t0, double t_end,
                                      double order, double *scratch);
/* The Rosenbrock scheme (rosenbrock.c), resumable like dopri and advanced by
 * vsj__dopri_advance: begin sets the state and the settings. */
VSJ_INTERNAL int vsj__ros_begin(const vsj_model *m, vsj_work *w, const double *y0, int64_t ny,
                                double t0, double t_end, double rtol, double atol,
                                double h_max, int64_t max_steps, int64_t n_err);
VSJ_INTERNAL int vsj__ros_attempt(const vsj_model *m, vsj_work *w, dopri_state *d);
VSJ_INTERNAL void vsj__ros_sample(const vsj_work *w, const dopri_state *d, const double *t_out,
                                  int64_t n_out, int64_t *i_out, double *out,
                                  int64_t out_cols);
/* A whole adaptive run in one call: begin (dopri or rosenbrock, `method`) and a
 * finishing advance, the state where it ends into y. */
VSJ_INTERNAL vsj_report vsj__adaptive(const vsj_model *m, vsj_work *w, int method, double *y,
                                      int64_t ny, double t0, double t_end, double rtol,
                                      double atol, int64_t max_steps, int64_t n_err);
/* The time-stepper, resumable: begin sets the state at t0 (the work prepared for m,
 * vsj_ts_prepare); advance steps to t_end (the last step shortened to land on it),
 * booking the ledger into y's accumulators with `ledger`. The callers check that w
 * fits m (vsj__fits). */
VSJ_INTERNAL int vsj__ts_prepared_for(const vsj_model *m, const vsj_work *w);
VSJ_INTERNAL int vsj__ts_begin(const vsj_model *m, vsj_work *w, const double *y, double t0);
VSJ_INTERNAL vsj_report vsj__ts_advance(const vsj_model *m, vsj_work *w, double *y, double t_end,
                                        double h, int64_t max_steps, int ledger,
                                        const vsj_samples *samples);

/* laws (laws.c) */
/* A spring law (vsj_spring_law); `cache` (4 doubles, or NULL) keeps the
 * exponential law's pivot-dependent factor between calls; without `with_stop`
 * the end stop's torque, stiffness and energy are left out (the time-stepper
 * treats stops as constraints). A rigid stop never adds a force. */
VSJ_INTERNAL double vsj__spring(int64_t law, const double *p, double phi, double q,
                                double *stiff, double *energy, double *dvdq, double *cache,
                                int with_stop);
/* The end stop of a spring law: its angle [rad] and stiffness [N m/rad] (infinite:
 * rigid); 0 if the law has none. */
VSJ_INTERNAL int vsj__stop(int64_t law, const double *p, double *angle, double *stiffness);

/* LU factorisation with partial pivoting of the n x n row-major A in place (0 if
 * singular), and the solve of A x = b with it (x may be b). */
VSJ_INTERNAL int vsj__lu(double *A, int64_t *piv, int64_t n);
VSJ_INTERNAL void vsj__lu_solve(const double *LU, const int64_t *piv, const double *b,
                                double *x, int64_t n);


/* The joint Coulomb impulse problem (impulses.c): YT is n x m, one column L^-1 d_e
 * per unknown, so that the Delassus matrix is W = Y Y^T; the other arrays are its
 * scratch (mask, d, g: m; memo: m + 1; t, c, z: n; G, Lg, Gc, Lk: n x n). */
typedef struct impulses {
    const double *YT; /* row i of the n x m problem starts at YT + ld * i (ld >= m) */
    int64_t n, m, ld;
    double *mask, *G, *Lg, *t, *c, *d, *g, *z, *Gc, *Lk, *memo;
} impulses;

/* Exact impulses for slips s = q - W p, lo <= p <= hi: p at hi where s > 0, at lo
 * where s < 0, between where s = 0. state (-1, +1 at a bound, 0 stuck, 2 not
 * involved: unknowns with active[e] == 0) and p carry the previous solution as a
 * warm start. Returns 0 if the active-set method did not converge; im->z holds
 * Y^T p on return, *iterations the active-set iterations (0: the last pattern held).
 * im->memo keeps the stuck set's matrices between calls: set memo[m] = 0 when YT or
 * the problem changes. */
VSJ_INTERNAL int vsj__solve_impulses(impulses *im, const double *q, const double *lo,
                                     const double *hi, double *p, int64_t *state,
                                     const unsigned char *active, int64_t *iterations);

/* The time-stepper's energy ledger (ledger.c): one step's work and losses, from the
 * step's quantities in t, added to the accumulators `acc` (vsj_n_acc of them); hs is
 * the step's length, q_end the pivot position at its end. */
VSJ_INTERNAL void vsj__ts_book(const vsj_model *m, ts_work *t, double *acc, double hs,
                               double q_end);

#define VSJ_PI 3.14159265358979323846

static inline double vsj__dmax(double a, double b) { return a > b ? a : b; }
static inline double vsj__dmin(double a, double b) { return a < b ? a : b; }

static inline const double *vsj__row(const vsj_model *m, int64_t r) {
    return m->par + r * VSJ_NPAR;
}

/* Whether work w was made for models of the sizes of m. */
static inline int vsj__fits(const vsj_model *m, const vsj_work *w) {
    return m && w && m->n == w->n && m->n_sources == w->s && m->n_frictions == w->f
           && m->n_springs == w->k && m->n_loads == w->nl && m->n_motors == w->nm
           && m->n_channels == w->nch && m->n_rows == w->rows && m->n_refs == w->nref
           && m->n_meas == w->nmeas && m->n_blocks == w->nblk && m->n_acts == w->nact
           && m->n_bus == w->nbus && m->n_cstate == w->ncs && m->n_delay == w->ndel
           && m->n_blk_in == w->nbi;
}

/* The coefficient of a friction table (rows first .. first + rows - 1 of
 * m->table) at slip speed `speed` >= 0: linear between rows, constant beyond. */
static inline double vsj__table(const vsj_model *m, int64_t first, int64_t rows, double speed) {
    const double *row = m->table + 2 * first;
    int64_t i;
    if (speed <= row[0])
        return row[1];
    for (i = 1; i < rows; i++)
        if (speed < row[2 * i])
            return row[2 * i - 1] + (row[2 * i + 1] - row[2 * i - 1]) * (speed - row[2 * i - 2])
                                        / (row[2 * i] - row[2 * i - 2]);
    return row[2 * rows - 1];
}

/* Whether v is one of the n values of a. */
static inline int vsj__among(const int64_t *a, int64_t n, int64_t v) {
    int64_t i;
    for (i = 0; i < n; i++)
        if (a[i] == v)
            return 1;
    return 0;
}

/* The table's slope d(coefficient)/d(speed) at `speed` >= 0, where vsj__table reads
 * it: the slope of the row pair it interpolates between (the upper one at a row's
 * speed), zero below the first row and from the last on. */
static inline double vsj__table_slope(const vsj_model *m, int64_t first, int64_t rows,
                                      double speed) {
    const double *row = m->table + 2 * first;
    int64_t i;
    if (speed <= row[0])
        return 0.0;
    for (i = 1; i < rows; i++)
        if (speed < row[2 * i])
            return (row[2 * i + 1] - row[2 * i - 1]) / (row[2 * i] - row[2 * i - 2]);
    return 0.0;
}

/* The factor on friction element e's Coulomb level k pi/2: the normal force's
 * input (clipped to [0, 1]) times the table's coefficient at |slip|, or at zero
 * speed times the peak when `stuck`. 1 for an element without either. */
static inline double vsj__normal(const vsj_model *m, const vsj_work *w, int64_t e, double slip,
                                 int stuck) {
    const double *p = m->par + e * VSJ_NPAR;
    double factor = stuck ? p[VSJ_F_PEAK] : 1.0;
    if (p[VSJ_F_CHANNEL] >= 0.0) {
        double f = w->chan[3 * (int64_t)p[VSJ_F_CHANNEL]];
        factor *= f < 0.0 ? 0.0 : (f > 1.0 ? 1.0 : f);
    }
    if (p[VSJ_F_ROWS] > 0.0)
        factor *= vsj__table(m, (int64_t)p[VSJ_F_TABLE], (int64_t)p[VSJ_F_ROWS],
                             stuck ? 0.0 : fabs(slip));
    return factor;
}

/* Whether friction element e has a normal-force channel that is at or below zero. */
static inline int vsj__free(const vsj_model *m, const vsj_work *w, int64_t e) {
    double ch = m->par[e * VSJ_NPAR + VSJ_F_CHANNEL];
    return ch >= 0.0 && !(w->chan[3 * (int64_t)ch] > 0.0);
}

/* Whether friction element e's level changes in time or with its state. */
static inline int vsj__varying(const vsj_model *m, int64_t e) {
    const double *p = m->par + e * VSJ_NPAR;
    return p[VSJ_F_PEAK] != 1.0 || p[VSJ_F_CHANNEL] >= 0.0 || p[VSJ_F_ROWS] > 0.0;
}

/* A contact's force (VSJ_CONTACT; p its row: lambda, k, n, gap) at penetration d and
 * its rate s: Hunt and Crossley's k d^n + lambda d^n s, never pulling (0 where that is
 * negative, or apart, d <= 0), and its derivatives in s and d. */
static inline double vsj__contact(const double *p, double d, double s, double *dfds,
                                  double *dfdd) {
    double lam = p[VSJ_C_DAMPING], k = p[VSJ_C_STIFFNESS], n = p[VSJ_C_EXPONENT], dn, f;
    *dfds = *dfdd = 0.0;
    if (!(d > 0.0))
        return 0.0;
    dn = n == 1.0 ? d : pow(d, n);
    f = dn * (k + lam * s);
    if (!(f > 0.0))
        return 0.0;
    *dfds = lam * dn;
    *dfdd = n * dn / d * (k + lam * s);
    return f;
}

/* The arctangent, within an ulp of the exact value. glibc's atan guards the rounding
 * mode on every call, which is slow on x86, and the friction laws take a dozen
 * arctangents per evaluation. |x| is reduced about the centre c nearest it (0, 1/2, 1,
 * 3/2 or infinity) by atan(x) = atan(c) + atan(t), t = (x - c) / (1 + c x), or -1/x
 * about infinity. Each x - c is exact, so |t| <= 7/16 carries little error, and
 * atan(c) is added as a double and the double nearest to what it leaves out, the
 * latter to the small terms first. atan(t) = t + t^3 P(t^2) with the degree-10
 * polynomial of tools/atan_coefficients.py (evaluated in Estrin's order: shorter
 * chains of dependent operations); that script also measures this sequence of
 * operations against the exact arctangent on every interval. The comparisons are
 * quiet (a NaN raises no flag); for |x| below about 1e-19 or above 1e19 the polynomial
 * may raise the underflow flag, its term far below the result's last place. */
static inline double vsj__atan(double x) {
    static const double c[11] = {
        -0.33333333333333326, 0.1999999999998777, -0.1428571428314864, 0.11111110900560475,
        -0.09090900195560148, 0.07692087348767168, -0.06663239299107136, 0.05847724720645106,
        -0.05033942776485848, 0.03782521866106712, -0.017547235157290005};
    /* atan of each centre: the double nearest, and the double nearest the rest */
    static const double hi[5] = {0.0, 0.4636476090008061, 0.7853981633974483,
                                 0.982793723247329, 1.5707963267948966};
    static const double lo[5] = {0.0, 2.2698777452961687e-17, 3.061616997868383e-17,
                                 1.3903311031230998e-17, 6.123233995736766e-17};
    double a = fabs(x), t, u, u2, u4, p;
    int r = isgreater(a, 0.4375) + isgreater(a, 0.6875) + isgreater(a, 1.1875)
            + isgreater(a, 2.4375);
    if (r == 0)
        t = a;
    else if (r == 1)
        t = (a - 0.5) / (1.0 + 0.5 * a);
    else if (r == 2)
        t = (a - 1.0) / (a + 1.0);
    else if (r == 3)
        t = (a - 1.5) / (1.0 + 1.5 * a);
    else
        t = -1.0 / a;
    u = t * t;
    u2 = u * u;
    u4 = u2 * u2;
    p = (c[0] + c[1] * u) + u2 * (c[2] + c[3] * u)
        + u4 * ((c[4] + c[5] * u) + u2 * (c[6] + c[7] * u))
        + u4 * u4 * ((c[8] + c[9] * u) + u2 * c[10]);
    return copysign(hi[r] + (t + (lo[r] + t * u * p)), x);
}

/* The slope df/ds of a friction law at s (vsj__friction's, without its torque). */
static inline double vsj__friction_slope(int64_t law, double b, double k, double kb, double w,
                                         double s) {
    if (law == VSJ_ARCTAN)
        return b + k * kb / (1.0 + (kb * s) * (kb * s));
    if (law == VSJ_SLOPE && fabs(s) < w)
        return b + k * (0.5 * VSJ_PI) / w;
    return b;
}

/* The smooth part of a friction law (vsj_friction_torque). */
static inline double vsj__friction(int64_t law, double b, double k, double kb, double w, double s,
                                    double *slope) {
    double f = b * s;
    double df = b;
    if (law == VSJ_ARCTAN) {
        f += k * vsj__atan(kb * s);
        df += k * kb / (1.0 + (kb * s) * (kb * s));
    } else if (law == VSJ_SIGN) {
        if (s > 0.0)
            f += k * (0.5 * VSJ_PI);
        else if (s < 0.0)
            f -= k * (0.5 * VSJ_PI);
    } else if (law == VSJ_SLOPE) {
        double level = k * (0.5 * VSJ_PI);
        if (s >= w) {
            f += level;
        } else if (s <= -w) {
            f -= level;
        } else {
            f += level * s / w;
            df += level / w;
        }
    }
    if (slope)
        *slope = df;
    return f;
}


/* ---- inputs ---------------------------------------------------------------- */

static inline void vsj__eval_channel(const vsj_model *m, vsj_work *w, int64_t c, double t) {
    double *ch = w->chan + 3 * c;
    int64_t p0, npieces, koff, j, p;
    double t0, t_last, tau, c0, c1, c2, c3, base;
    if (w->ctl_on && w->ctl_drive[c] >= 0) { /* driven by the controller, held */
        ch[0] = w->ctl_u[w->ctl_drive[c]];
        ch[1] = 0.0;
        ch[2] = 0.0; /* no source is driven: the integral is never read */
        w->chan_dd[c] = 0.0;
        return;
    }
    if (w->held) { /* held over a control period, from t = 0 */
        double v = w->held[c];
        ch[0] = v;
        ch[1] = 0.0;
        ch[2] = t * v;
        w->chan_dd[c] = 0.0;
        return;
    }
    w->chan_dd[c] = 0.0;
    p0 = m->first[c];
    koff = p0 + c;
    t0 = m->knots[koff];
    if (w->ev_model == m && w->ev_const[c]) { /* one constant piece: the branches below */
        double v = m->coef[4 * p0];
        t_last = m->knots[koff + 1];
        ch[0] = v;
        ch[1] = 0.0;
        if (t < t0 || (w->left && t == t0))
            ch[2] = (t - t0) * v;
        else if (t > t_last || (t == t_last && !w->left))
            ch[2] = m->cum[koff + 1] + (t - t_last) * v;
        else
            ch[2] = m->cum[koff] + (t - t0) * v;
        return;
    }
    npieces = m->count[c];
    if (t < t0 || (w->left && t == t0)) {
        double v = m->coef[4 * p0];
        ch[0] = v;
        ch[1] = 0.0;
        ch[2] = (t - t0) * v;
        return;
    }
    t_last = m->knots[koff + npieces];
    base = 0.0;
    if (m->period[2 * c] > 0.0 && (t > t_last || (t == t_last && !w->left))) {
        /* a repeating channel: fold t into its last period, add the whole periods'
         * integral (a left limit at a period's end stays in the period before) */
        double period = m->period[2 * c];
        double turns = w->left ? ceil((t - t_last) / period) : floor((t - t_last) / period) + 1.0;
        t -= turns * period;
        if (t < t_last - period) /* round-off at a period's end */
            t = t_last - period;
        base = turns * m->period[2 * c + 1];
    }
    if (t > t_last || (t == t_last && !w->left)) {
        const double *cf;
        double v;
        p = p0 + npieces - 1;
        cf = m->coef + 4 * p;
        tau = t_last - m->knots[koff + npieces - 1];
        v = cf[0] + tau * (cf[1] + tau * (cf[2] + tau * cf[3]));
        ch[0] = v;
        ch[1] = 0.0;
        ch[2] = m->cum[koff + npieces] + (t - t_last) * v;
        return;
    }
    j = w->hint[c];
    if (j < 0 || j >= npieces)
        j = 0;
    while (j + 1 < npieces && m->knots[koff + j + 1] <= t) /* t may be t_last (left) */
        j++;
    while (m->knots[koff + j] > t)
        j--;
    if (w->left && j > 0 && m->knots[koff + j] == t) /* the piece that ends here */
        j--;
    w->hint[c] = j;
    tau = t - m->knots[koff + j];
    p = p0 + j;
    c0 = m->coef[4 * p];
    c1 = m->coef[4 * p + 1];
    c2 = m->coef[4 * p + 2];
    c3 = m->coef[4 * p + 3];
    ch[0] = c0 + tau * (c1 + tau * (c2 + tau * c3));
    ch[1] = c1 + tau * (2.0 * c2 + 3.0 * c3 * tau);
    w->chan_dd[c] = 2.0 * c2 + 6.0 * c3 * tau;
    ch[2] = base + m->cum[koff + j]
            + tau * (c0 + tau * (0.5 * c1 + tau * (c2 / 3.0 + 0.25 * c3 * tau)));
}

static inline void vsj__eval_source(const vsj_model *m, vsj_work *w, int64_t j) {
    const double *ch = w->chan + 3 * m->src_ch[j];
    double *sw = w->srcw + SRCW * j;
    sw[U] = ch[0];
    sw[UD] = ch[1];
    sw[SG] = (w->held ? w->pos0[j] : m->src_pos0[j]) + ch[2];
}

static inline void vsj__eval_inputs(const vsj_model *m, vsj_work *w, double t) {
    int64_t c, j;
    int splines = !w->held && !w->ctl_on;
    /* a Rosenbrock step evaluates its last stages and its end at one time: the
     * splines there are the ones already evaluated */
    if (splines && t == w->in_t && w->left == w->in_left && m == w->in_model)
        return;
    for (c = 0; c < m->n_channels; c++)
        vsj__eval_channel(m, w, c, t);
    for (j = 0; j < m->n_sources; j++)
        vsj__eval_source(m, w, j);
    w->in_model = m;
    w->in_t = splines ? t : NAN;
    w->in_left = w->left;
}

/* ---- sparse rows ----------------------------------------------------------- */

static inline double vsj__xdot(const vsj_model *m, int64_t r, const double *vec) {
    double acc = 0.0;
    int64_t k;
    for (k = m->xp[r]; k < m->xp[r + 1]; k++)
        acc += m->xv[k] * vec[m->xc[k]];
    return acc;
}

static inline double vsj__udot(const vsj_model *m, int64_t r, const double *srcw, int col) {
    double acc = 0.0;
    int64_t k;
    for (k = m->up[r]; k < m->up[r + 1]; k++)
        acc += m->uv[k] * srcw[SRCW * m->uc[k] + col];
    return acc;
}

static inline double vsj__udotv(const vsj_model *m, int64_t r, const double *vec) {
    double acc = 0.0;
    int64_t k;
    for (k = m->up[r]; k < m->up[r + 1]; k++)
        acc += m->uv[k] * vec[m->uc[k]];
    return acc;
}

/* The penetration of contact row e at the positions x (the sources' angles in srcw). */
static inline double vsj__penetration(const vsj_model *m, const vsj_work *w, int64_t e,
                                      const double *x) {
    return vsj__xdot(m, e, x) + vsj__udot(m, e, w->srcw, SG) - m->par[VSJ_NPAR * e + VSJ_C_GAP];
}

static inline void vsj__xadd(const vsj_model *m, int64_t r, double *vec, double scale) {
    int64_t k;
    for (k = m->xp[r]; k < m->xp[r + 1]; k++)
        vec[m->xc[k]] += scale * m->xv[k];
}

static inline void vsj__uadd(const vsj_model *m, int64_t r, double *srcw, int col, double scale) {
    int64_t k;
    for (k = m->up[r]; k < m->up[r + 1]; k++)
        srcw[SRCW * m->uc[k] + col] += scale * m->uv[k];
}

static inline void vsj__uaddv(const vsj_model *m, int64_t r, double *vec, double scale) {
    int64_t k;
    for (k = m->up[r]; k < m->up[r + 1]; k++)
        vec[m->uc[k]] += scale * m->uv[k];
}

/* ---- the pivot --------------------------------------------------------------- */

/* The pivot at position q: w->q, and VSJ_PIVOT_RANGE if q is outside its range. */
static inline double vsj__pivot_record(const vsj_model *m, vsj_work *w, double q) {
    const double *p = vsj__row(m, m->n_rows - 1);
    w->q = q;
    if ((q < p[3] - 1e-12 || q > p[4] + 1e-12) && w->status < VSJ_PIVOT_RANGE)
        w->status = VSJ_PIVOT_RANGE;
    return q;
}

static inline double vsj__pivot_at(const vsj_model *m, vsj_work *w, double angle) {
    const double *p = vsj__row(m, m->n_rows - 1);
    double moving = p[2]; /* 1 with a pivot mechanism, 0 for a fixed pivot */
    return vsj__pivot_record(m, w, moving * p[0] * sin(angle) + (1.0 - moving) * p[1]);
}

static inline double vsj__pivot_angle(const vsj_model *m, const vsj_work *w, const double *x) {
    int64_t r = m->n_rows - 1;
    return vsj__xdot(m, r, x) + vsj__udot(m, r, w->srcw, SG);
}

static inline double vsj__pivot_position(const vsj_model *m, vsj_work *w, const double *x) {
    return vsj__pivot_at(m, w, vsj__pivot_angle(m, w, x));
}



#endif
