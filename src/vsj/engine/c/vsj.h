/*
 * vsj: the simulation engine of the 2-DOF variable stiffness joint, in C99.
 *
 * The engine integrates an assembled network (vsj.network in Python): the
 * rigid constraints are already eliminated, so every flange speed is
 * omega = A v + B u, with v the generalised speeds and u the prescribed speeds
 * of the velocity sources. What the engine needs of the network is a handful of
 * arrays, described by `vsj_model`. The model is plain data owned by the
 * caller; the run-time state of a computation lives in a `vsj_work`, allocated
 * once per model and passed explicitly to every function. Nothing is global:
 * any number of models and works may be used at once, from any number of
 * threads, as long as each work is used by one thread at a time. A work also
 * holds one computation at a time: a run (vsj_begin to its last vsj_advance) or a
 * step function keeps its state in it between calls, and a one-shot call
 * (vsj_derivatives, vsj_jacobian, ...) on the same work in between overwrites that
 * state; give such calls a work of their own.
 *
 * State vector y = [x (n), v (n), i (motors), accumulators (optional)]:
 * generalised angles and speeds, armature currents, then the energy
 * accumulators of the ledger (see vsj_n_acc).
 *
 * Element rows (one per friction element, spring, load, motor, and the pivot
 * last) are stored in compressed sparse row form, split into the part that
 * multiplies the generalised coordinates (xp, xc, xv) and the part that
 * multiplies the sources (up, uc, uv). Row order: the friction elements, the
 * springs, the loads, the motors, the pivot.
 *
 * Units are SI throughout. Report: J.D. Zult, "Modeling and characterization
 * of a 2-DOF variable stiffness joint", University of Twente, 2016.
 */
#ifndef VSJ_H
#define VSJ_H

#include <stddef.h>
#include <stdint.h>

#include "vsj_layout.h"

/* The C type of each kind of array in vsj_layout.h. */
#define VSJ_TYPE_VSJ_REAL double
#define VSJ_TYPE_VSJ_INT int64_t

#ifdef __cplusplus
extern "C" {
#endif

#define VSJ_VERSION_MAJOR 1
#define VSJ_VERSION_MINOR 0

/* Columns of a row of `vsj_model.par`. */
#define VSJ_NPAR 9

/* ---- the controller (control.c) ----------------------------------------------
 * A model may carry a sampled controller: every `ctl[VSJ_CTL_PERIOD]` seconds from a
 * run's start it reads its sensors, runs its blocks in order and sets its actuators,
 * whose values then hold until the next sample (zero-order hold) while the plant
 * runs on its own scheme. Its signals sit on one bus: the references (input channels
 * ref_ch, evaluated at the sample), the measurements, then each block's outputs. A
 * block's inputs and an actuator's command are rows over the bus; a block reads the
 * outputs of earlier blocks only. An actuator replaces the input channel it drives (a
 * load's torque or a motor's voltage) and is clipped to its limits; a motor's current
 * limit bounds its voltage so that (V - k_t omega) / R stays within it. */
#define VSJ_NCTL 2
enum vsj_ctl_par { VSJ_CTL_PERIOD = 0, VSJ_CTL_SEED = 1 };
/* What a sensor measures: an angle (meas_row times the generalised and source
 * angles), a speed (the same row times their speeds), a motor's current, the pivot
 * position q [m]. */
enum vsj_sensor { VSJ_SENSE_ANGLE = 0, VSJ_SENSE_SPEED = 1, VSJ_SENSE_CURRENT = 2,
                  VSJ_SENSE_PIVOT = 3, VSJ_N_SENSORS };
/* A sensor's row of meas_par: resolution (the reading is the nearest multiple; 0:
 * exact), standard deviation of its Gaussian noise, delay in samples (whole), motor
 * (VSJ_SENSE_CURRENT: index among the motors). */
#define VSJ_NMEAS 4
enum vsj_meas_par { VSJ_M_RESOLUTION = 0, VSJ_M_NOISE = 1, VSJ_M_DELAY = 2, VSJ_M_MOTOR = 3 };
/* A block's row of blk: kind, inputs, outputs, states, first parameter, first input row. */
#define VSJ_NBLK 6
enum vsj_blk { VSJ_B_KIND = 0, VSJ_B_IN = 1, VSJ_B_OUT = 2, VSJ_B_STATES = 3, VSJ_B_PAR = 4,
               VSJ_B_ROW = 5 };
/* PID (Modelica's LimPID, sampled): inputs set-point, measurement, feed-forward; one
 * output; states: integrator, derivative filter. Linear: x+ = A x + B u, y = C x + D u. */
enum vsj_block_kind { VSJ_BLOCK_PID = 0, VSJ_BLOCK_LINEAR = 1, VSJ_N_BLOCKS };
/* A PID's parameters: gain k, integral time Ti (inf: none), derivative time Td (0: none),
 * Nd (derivative filter: time constant Td / Nd), set-point weights wp (proportional) and
 * wd (derivative), output limits, Ni (back-calculation's tracking time Ni Ti), anti-windup
 * (0 none, 1 back-calculation, 2 clamping). */
#define VSJ_NPID 10
enum vsj_pid { VSJ_PID_K = 0, VSJ_PID_TI = 1, VSJ_PID_TD = 2, VSJ_PID_ND = 3, VSJ_PID_WP = 4,
               VSJ_PID_WD = 5, VSJ_PID_YMIN = 6, VSJ_PID_YMAX = 7, VSJ_PID_NI = 8,
               VSJ_PID_WINDUP = 9 };
/* An actuator's row of act_par: offset added to its command, lower and upper limit
 * (the channel's unit), current limit [A] (inf: none) and its motor (index among the
 * motors, -1: none). */
#define VSJ_NACT 5
enum vsj_act { VSJ_A_OFFSET = 0, VSJ_A_LO = 1, VSJ_A_HI = 2, VSJ_A_CURRENT = 3, VSJ_A_MOTOR = 4 };

/* Status of a computation. */
enum vsj_status {
    VSJ_OK = 0,
    VSJ_NOT_FINITE = 1,      /* the state or a force became non-finite */
    VSJ_PIVOT_RANGE = 2,     /* the pivot position left its allowed range */
    VSJ_TOO_MANY_STEPS = 3,  /* the solver reached its maximum number of steps */
    VSJ_STEP_TOO_SMALL = 4,  /* the adaptive step fell below the round-off limit */
    VSJ_FRICTION_SOLVER = 5, /* the stiction impulse solver did not converge */
    VSJ_BAD_ARGUMENT = 6,    /* an argument is out of range (see vsj_check_model) */
    VSJ_NO_MEMORY = 7
};

/* Friction laws (vsj.friction): the resistive torque f(s) of a relative speed s; and
 * spring laws (vsj.springs). Each is one line of vsj_layout.h's tables. */
#define VSJ_LAW_CODE(NAME, name, description) VSJ_##NAME,
enum vsj_friction_law { VSJ_FRICTION_LAWS(VSJ_LAW_CODE) VSJ_N_FRICTION_LAWS };
enum vsj_spring_law { VSJ_SPRING_LAWS(VSJ_LAW_CODE) VSJ_N_SPRING_LAWS };

/* The compiled form of an assembled network: its sizes and arrays, each declared
 * once in vsj_layout.h (VSJ_SIZES, VSJ_ARRAYS), which says what each holds. Every
 * pointer refers to memory the caller owns and keeps alive while the model is used;
 * the engine never writes through them. Matrices are row-major. The rows of `par`:
 *   friction element: viscous b, stiction k, arctan sharpness k_b, slope width w, peak
 *                     (static over kinetic level, >= 1), normal-force channel (-1:
 *                     none), first row and rows of its friction table (0 rows: none);
 *                     Coulomb level k pi/2 f(t) mu(|s|) with f the channel's value
 *                     clipped to [0, 1] and mu the table's coefficient at the slip
 *                     speed, peak times that at zero speed while the element is stuck;
 *                     1 if the time-stepper integrates its viscous part with the
 *                     trapezoidal rule (a damper), 0 for implicit Euler (friction)
 *   spring:           the law's parameters (enum vsj_spring_law)
 *   motor:            resistance, inductance, torque constant
 *   pivot:            amplitude, fixed q, moving (1 or 0), q_min, q_max
 * Input channel c is a cubic spline: pieces first[c] .. first[c] + count[c] - 1 with
 * coefficients c0 + c1 tau + c2 tau^2 + c3 tau^3 and knots at first[c] + c + j; before
 * its first knot it holds its first value, after its last its last value or, where
 * period[2 c] > 0, it repeats its last period[2 c] seconds (period[2 c + 1]: the
 * integral over one period). Friction tables are rows of (slip speed >= 0, coefficient
 * >= 0), speeds increasing within a table; linear between rows, constant beyond. */
typedef struct vsj_model {
#define VSJ_SIZE_FIELD(name, doc) int64_t name;
    VSJ_SIZES(VSJ_SIZE_FIELD)
#undef VSJ_SIZE_FIELD
#define VSJ_ARRAY_FIELD(name, kind, count, doc) const VSJ_TYPE_##kind *name;
    VSJ_ARRAYS(VSJ_ARRAY_FIELD)
#undef VSJ_ARRAY_FIELD
} vsj_model;

/* Run-time state of one computation (opaque; one per thread). */
typedef struct vsj_work vsj_work;

/* A model as bytes (blob.c): vsj_model_write writes m's versioned binary form into
 * `out` if it holds `capacity` bytes, and returns the bytes it needs (call it with NULL
 * to ask). vsj_model_read makes a model of its own from such bytes (checked: format,
 * version, layout, sizes, checksum, then vsj_check_model), or returns NULL with the
 * reason in `message`; free it with vsj_model_free. */
size_t vsj_model_write(const vsj_model *m, unsigned char *out, size_t capacity);
vsj_model *vsj_model_read(const unsigned char *data, size_t length, char *message,
                          size_t size);
void vsj_model_free(vsj_model *m);

/* Checks sizes, indices, codes and finiteness of a model. Returns VSJ_OK, or
 * VSJ_BAD_ARGUMENT with a message in `message` (of `size` bytes). */
int vsj_check_model(const vsj_model *m, char *message, size_t size);

/* A work for models of the sizes of `m` (NULL if out of memory). Any model of
 * the same sizes may be used with it. */
vsj_work *vsj_work_new(const vsj_model *m);
void vsj_work_free(vsj_work *w);

/* Columns a sample row gains with a controller (0 without): its bus (n_bus) and its
 * actuators' values (n_acts), as they hold from the sample's time on. */
int64_t vsj_control_width(const vsj_model *m);

/* The controller's signals as they hold now: its bus and its actuators' values
 * (vsj_control_width of them into out; returns that number, 0 without a controller). */
int64_t vsj_control_values(const vsj_model *m, const vsj_work *w, double *out);
/* Restart the step function's controller: its next vsj_step samples it afresh (block
 * states zero, delay lines refilled, the noise from its seed). A run (vsj_begin)
 * always starts it afresh. */
void vsj_control_reset(vsj_work *w);

/* Lengths of the state vector without and with the ledger's accumulators. */
int64_t vsj_n_state(const vsj_model *m);
int64_t vsj_n_acc(const vsj_model *m);

/* Accumulators, in this order after the state (counts in parentheses): work
 * done by the sources (n_sources), loads (n_loads), motor supplies
 * (n_motors); dissipation in friction (n_frictions) and armature resistance
 * (n_motors); work done by the springs on the mechanism (n_springs) and by
 * the pivot on the springs (n_springs); energy the springs' end stops take
 * out of the mechanism (n_springs: impacts on a stop and the implicit
 * treatment of a compliant one, in the time-stepper). */

/* Status text for enum vsj_status. */
const char *vsj_status_text(int status);

/* ---- element laws -------------------------------------------------------- */

/* Columns of a friction element's parameter row (see vsj_model.par). */
enum vsj_friction_par {
    VSJ_F_VISCOUS = 0, VSJ_F_STICTION = 1, VSJ_F_SHARPNESS = 2, VSJ_F_WIDTH = 3,
    VSJ_F_PEAK = 4, VSJ_F_CHANNEL = 5, VSJ_F_TABLE = 6, VSJ_F_ROWS = 7, VSJ_F_TRAPEZOIDAL = 8
};
/* A contact's row (law VSJ_CONTACT: an element of the environment, vsj.environment):
 * its row is the contact's penetration in metres per unit of its coordinates, positive
 * into the contact; its force [N] is the "torque" the element resists with, its slip the
 * penetration's rate. Columns: damping lambda [s/m], stiffness k [N/m^n], exponent n >= 1,
 * gap [m] (the penetration is the row's position minus the gap); the rest as a friction
 * element's defaults (peak 1, no channel, no table). */
enum vsj_contact_par {
    VSJ_C_DAMPING = 0, VSJ_C_STIFFNESS = 1, VSJ_C_EXPONENT = 2, VSJ_C_GAP = 3
};

/* Smooth part of a friction law at slip speed s: returns f(s), with its slope
 * in *slope if not NULL. For VSJ_STICTION this is the viscous part only; for
 * VSJ_CONTACT 0 (its force depends on its penetration too: vsj_derivatives). */
double vsj_friction_torque(int law, double b, double k, double kb, double w, double s,
                           double *slope);

/* Spring law at deflection phi and pivot position q: out = (torque on the
 * ring, stiffness -dtorque/dphi, stored energy V, dV/dq). Returns VSJ_OK, or
 * VSJ_BAD_ARGUMENT for an unknown law. */
int vsj_spring_law(int law, const double par[VSJ_NPAR], double phi, double q, double out[4]);

/* Both geometric models at one point: out = (V, dV/dphi, d2V/dphi2, dV/dq,
 * T_phi of eq 3.8, dT_phi/dphi). */
void vsj_spring_geometry(const double par[VSJ_NPAR], double phi, double q, double out[6]);

/* Extensions l - s0 [m] of springs a and b of the geometric element (negative: slack). */
void vsj_spring_extensions(const double par[VSJ_NPAR], double phi, double q, double out[2]);

/* ---- evaluation ---------------------------------------------------------- */

/* dy/dt at (t, y). ny is 2n + n_motors (state only) or that plus vsj_n_acc
 * (state, accumulators, and the torque each source supplies). Returns the
 * status (VSJ_PIVOT_RANGE if the pivot is outside its range, VSJ_NOT_FINITE). */
int vsj_derivatives(const vsj_model *m, vsj_work *w, double t, const double *y, int64_t ny,
                    double *dy);
/* The Jacobian of the derivatives at (t, y) in the state (y: ny values, the state,
 * vsj_n_state of them, or the state and the ledger's accumulators; J: row-major
 * ny x vsj_n_state, as the accumulators' rates do not depend on the accumulators)
 * and their partial derivative in time, ft (ny values): the Rosenbrock scheme's
 * linearisation, friction levels that follow speed tables or normal-force inputs
 * included. At a corner of an input (a table's knot) time derivatives are those after
 * it. Returns the status of the evaluation at (t, y). */
int vsj_jacobian(const vsj_model *m, vsj_work *w, double t, const double *y, int64_t ny,
                 double *J, double *ft);

/* Source angles and speeds at each of n_out times: arrays of n_out * n_sources. */
void vsj_source_signals(const vsj_model *m, vsj_work *w, const double *t_out, int64_t n_out,
                        double *angles, double *speeds);

/* Kinetic, spring and inductor energy [J] at (t, y) (y: the state, 2n + n_motors).
 * `springs` (n_springs, may be NULL) receives each spring's energy. */
void vsj_stored_energy(const vsj_model *m, vsj_work *w, double t, const double *y,
                       double energy[3], double *springs);

/* Number of columns of vsj_observe's rows. */
int64_t vsj_observation_width(const vsj_model *m);

/* Every internal signal at n_out samples: states from `out` (rows of ny,
 * leading 2n + n_motors used), Coulomb torques of stiction elements from
 * `coulomb` (n_out * n_frictions, or NULL); rows of vsj_observation_width
 * columns into `raw`: x, v, i, a, source angles, speeds and accelerations, q,
 * dq/dt, friction slips and torques, spring deflections, rates, torques,
 * energies and stiffnesses, source torques, load torques and speeds, motor
 * speeds and voltages. A model with a controller: each row ends with the
 * vsj_control_width columns a run's samples carry (ny counts them), whose actuator
 * values the driven channels take. */
int vsj_observe(const vsj_model *m, vsj_work *w, const double *t_out, int64_t n_out,
                const double *out, int64_t ny, const double *coulomb, double *raw);

/* ---- integration --------------------------------------------------------- */

/* What an integration did. */
typedef struct vsj_report {
    int status;
    double t;            /* time reached (of the failure, if any) */
    int64_t steps;
    int64_t rejected;    /* adaptive solver: rejected steps */
} vsj_report;

/* Samples of a run: state rows (out_cols leading components; a model with a
 * controller writes its vsj_control_width columns after the state's) and,
 * if `coulomb` is not NULL, the Coulomb torque of each friction element and
 * whether it held (rows of n_frictions). */
typedef struct vsj_samples {
    const double *t;     /* n times, multiples of the step */
    int64_t n;
    double *out;         /* n * out_cols */
    int64_t out_cols;
    double *coulomb;     /* n * n_frictions, or NULL */
    unsigned char *stuck;
} vsj_samples;

/* ---- one entry point for runs (run.c) ------------------------------------------ */

/* The integration schemes. */
enum vsj_method {
    VSJ_METHOD_DOPRI = 0,    /* adaptive Dormand-Prince 5(4): smooth friction laws */
    VSJ_METHOD_TIMESTEP = 1, /* the time-stepper: true stiction, rigid end stops, any law */
    VSJ_METHOD_RK4 = 2,      /* classical Runge-Kutta, fixed substeps: held periods only */
    VSJ_METHOD_ROSENBROCK = 3 /* adaptive linearly implicit Rosenbrock 4(3): smooth laws
                               * with steep slopes (stiff) */
};

/* A scheme and its settings. */
typedef struct vsj_scheme {
    int method;              /* enum vsj_method */
    double rtol, atol, h_max; /* dopri, rosenbrock: tolerances and largest step [s] */
    int64_t n_err;           /* dopri, rosenbrock: leading components of y in the error
                              * norm (rosenbrock: at most vsj_n_state) */
    double h;                /* time-stepper: the step [s] */
    int64_t max_steps;       /* most steps of the whole run (vsj_step: of one period) */
    int ledger;              /* time-stepper: book the energy ledger into y's accumulators
                              * (dopri integrates them when y carries them) */
    int64_t substeps;        /* rk4: steps per held period */
} vsj_scheme;

/* Starts a run of `scheme` (dopri, rosenbrock or the time-stepper) from y0 (ny values: the state, or the state and the
 * ledger's accumulators, see vsj_n_acc) at time t0, to end at t_end. The run takes
 * which friction elements share a slip from the element rows as they stand here:
 * change the rows between runs (or a step function's periods), not within one. */
int vsj_begin(const vsj_model *m, vsj_work *w, const vsj_scheme *scheme, const double *y0,
              int64_t ny, double t0, double t_end);
/* Samples the run at samples->t (increasing, after earlier calls' samples, none past
 * t_until; NULL for none), and with `finish` integrates on to the run's end; y
 * receives the state where the run stands. The steps do not depend on how the samples
 * are split between calls. The report counts the run's steps so far. */
vsj_report vsj_advance(const vsj_model *m, vsj_work *w, double *y, double t_until, int finish,
                       const vsj_samples *samples);

/* The time-stepper's analysis of a model (report section 4.1.3: true sticking; end
 * stops are unilateral constraints solved with the friction impulses): vsj_begin and
 * vsj_step make it for a work that has none for this model; call it again after
 * changing a model's parameters in place. It clears the stick/slip history. */
int vsj_ts_prepare(const vsj_model *m, vsj_work *w);
/* Per element: the stick-phase transitions counted since vsj_ts_prepare, and
 * whether it holds now. Arrays of n_frictions. */
void vsj_ts_transitions(const vsj_work *w, int64_t *transitions);
int64_t vsj_ts_stuck(const vsj_model *m, const vsj_work *w, unsigned char *stuck);
/* The time-stepper's whole history (state, warm start, stick counters) as
 * bytes, for FMU state get/set: size, save into `buffer`, restore. */
size_t vsj_ts_history_size(const vsj_model *m);
void vsj_ts_save(const vsj_model *m, const vsj_work *w, unsigned char *buffer);
void vsj_ts_restore(const vsj_model *m, vsj_work *w, const unsigned char *buffer);
/* Whether saved history bytes (vsj_ts_history_size of them) hold values the
 * time-stepper can: finite reals (a marker of "none yet" may be NaN), counts from 0,
 * flags, a status and impulse states in their ranges. VSJ_OK, or VSJ_BAD_ARGUMENT
 * with the first value that is not in `message` (of `size` bytes; NULL for none).
 * Bytes from outside (an FMU state) are checked before vsj_ts_restore takes them. */
int vsj_ts_history_check(const vsj_model *m, const unsigned char *buffer, char *message,
                         size_t size);

/* A tridiagonal system of order n: sub-diagonal dl (n - 1), diagonal d (n), super-
 * diagonal du (n - 1), right-hand side b (n), solved by Gaussian elimination with
 * partial pivoting (two rows exchanged where the sub-diagonal entry is the larger);
 * b receives the solution, dl, d, du and du2 (n - 2, the fill) are overwritten.
 * Returns 0, or -1 for a singular system. */
int vsj_solve_tridiagonal(int64_t n, double *dl, double *d, double *du, double *du2, double *b);

/* The time-stepper's joint Coulomb impulse problem on its own: for each of
 * `count` right-hand sides q (rows of qs, m values), impulses p with
 * |p_e| <= cap_e such that the slips s = q - Y^T Y p (Y: the n x m matrix YT)
 * satisfy the Coulomb conditions (s_e = 0 where |p_e| < cap_e, p_e = cap_e
 * sign(s_e) where s_e != 0); unknowns with active[e] == 0 take no impulse.
 * Each problem is warm-started from the previous solution. Writes ps and
 * states (rows of m: -1, +1 slipping, 0 stuck, 2 not involved) and the
 * active-set iterations of each (0: last pattern held, -1: no convergence). */
int vsj_solve_impulses(int64_t n, int64_t m, const double *YT, int64_t count, const double *qs,
                       const double *cap, const unsigned char *active, double *ps,
                       int64_t *states, int64_t *iterations);

/* ---- the step function --------------------------------------------------- */

/* Inputs held over one control period (zero-order hold), one value per input
 * channel. The stepper's state is s = [x (n), p (n), i (motors), sigma
 * (sources)] with p = M v + M_su u the generalised momenta (continuous when a
 * source speed jumps between periods) and sigma the source angles. */
int64_t vsj_step_state_size(const vsj_model *m);

/* The most steps (rk4 substeps, time-stepper steps) one call may take. */
#define VSJ_MAX_PERIOD_STEPS 10000000

/* Advance s in place by one period dt with `inputs` held, by `scheme`. A model with a
 * controller samples it at the period's start and every controller period within (dt
 * a whole number of them; rk4: one; the time-stepper's step dividing each), its
 * actuators overriding the inputs they drive, its references the inputs' values; its
 * state lives in the work and goes on from one call to the next (vsj_control_reset).
 * Schemes: dopri or rosenbrock (rtol in [1e-14, 1e-2], atol in [1e-20, 1e-2],
 * max_steps), rk4 (substeps; no rigid end stops, no ledger) or the time-stepper (h, a
 * step longer than dt being one shortened step; max_steps; its stick/slip history is
 * kept in the work from one period to the next). A finite dt > 0 and max_steps >= 1
 * always; VSJ_BAD_ARGUMENT otherwise. If
 * `ledger` is not NULL it receives the energy ledger over the period (vsj_n_acc
 * values, each accumulator's change). s is unchanged on failure, and the next call
 * steps it as a fresh work would: a failed period's impulses are no warm start. */
int vsj_step(const vsj_model *m, vsj_work *w, const vsj_scheme *scheme, double *s,
             const double *inputs, double dt, double *ledger);
/* ds/dt at s for held inputs (the source speeds' derivatives drop out). */
int vsj_step_rate(const vsj_model *m, vsj_work *w, const double *s, const double *inputs,
                  double *ds);
/* Generalised speeds v = M^-1 (p - M_su u) of state s for inputs. */
void vsj_step_speeds(const vsj_model *m, const double *s, const double *inputs, double *v);
/* Pivot position q [m] of state s. */
double vsj_step_pivot_position(const vsj_model *m, const double *s);

/* ---- models from files ----------------------------------------------------- */

/* A model read from a file written by `vsj export-model` (binary, see load.c), with
 * the memory behind it, the names of its inputs and its default initial stepper
 * state, and output rows: output k = sum_j rows[k * state_size + j] s[j]. */
typedef struct vsj_loaded {
    vsj_model model;
    int64_t n_inputs;
    char **input_names;
    double *initial_state;      /* vsj_step_state_size values */
    int64_t n_outputs;
    char **output_names;
    double *output_rows;        /* n_outputs * vsj_step_state_size */
    vsj_scheme scheme;          /* the scheme it was exported with (for vsj_step) */
    double period;              /* the control period it was exported for [s] */
    vsj_model *owned;           /* the memory of `model`'s arrays */
} vsj_loaded;

/* Reads a model file; NULL on failure with the reason in `message`. */
vsj_loaded *vsj_load_model(const char *path, char *message, size_t size);
/* The same from the file's bytes in memory (`length` bytes). */
vsj_loaded *vsj_parse_model(const char *data, size_t length, char *message, size_t size);
void vsj_free_loaded(vsj_loaded *loaded);

#ifdef __cplusplus
}
#endif

#endif /* VSJ_H */
