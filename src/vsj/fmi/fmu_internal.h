/* Private declarations shared by the source files of vsj's FMU: vsj_fmu.c (the FMI 2.0
 * entry points), fmu_setup.c (reading the resources, assembling the model),
 * fmu_parameters.c (what a parameter file allows a tunable parameter),
 * fmu_ledger.c (the energy ledger of a run) and fmu_state.c (FMU states). The
 * instance (`fmu`) is the one piece of run-time state, passed to every function.
 * Nothing declared here is exported from the FMU's binary: only the fmi2 functions
 * of fmi2.h are.
 */
#ifndef VSJ_FMU_INTERNAL_H
#define VSJ_FMU_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

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

enum output {
    THETA_X, THETA_Y, DEFLECTION_1, DEFLECTION_2, PIVOT_Q, MOTOR_1_ANGLE, MOTOR_2_ANGLE,
    MOTOR_S_ANGLE, MOTOR_1_SPEED, MOTOR_2_SPEED, MOTOR_S_SPEED, POWER_IN, POWER_DISSIPATED,
    N_OUTPUTS
};

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

typedef struct {
    char *name;
    char guid[GUID_MAX];
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging;       /* debug logging on (fmi2Instantiate, fmi2SetDebugLogging) */
    int log_info;      /* information (category logAll) wanted (vsj_fmu.c, fmu__say) */
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
    double *s, *inputs;
    double *ledger; /* scratch: the ledger of the step being taken (vsj_step's) */
    double *booked; /* the ledger of the last step taken, and its length booked_h (> 0:
                     * its power outputs not yet worked out: fmu__powers) */
    double booked_h;
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

/* Functions shared between the FMU's files: hidden in a shared library, so that the
 * FMU exports the fmi2 functions only (direct calls, no symbol interposition). */
#if defined(__GNUC__) && !defined(_WIN32)
#define FMU_INTERNAL __attribute__((visibility("hidden")))
#else
#define FMU_INTERNAL
#endif

static inline const double *pivot_row(const fmu *f) {
    return f->par + VSJ_NPAR * (f->model.n_rows - 1);
}

/* messages to the importer's logger (vsj_fmu.c) */
FMU_INTERNAL void fmu__say(const fmu *f, fmi2Status status, const char *category,
                           const char *format, ...);
FMU_INTERNAL fmi2Status fmu__fail(fmu *f, const char *format, const char *detail);

/* set-up (fmu_setup.c) */
FMU_INTERNAL char *fmu__copy_text(const char *text);
FMU_INTERNAL char *fmu__resource_path(const char *location, const char *file);
FMU_INTERNAL int fmu__read_map(fmu *f, const char *path, char *why, size_t size);
FMU_INTERNAL int fmu__allocate(fmu *f);
FMU_INTERNAL const char *fmu__not_a_wrist(fmu *f);
FMU_INTERNAL void fmu__free(fmu *f);
FMU_INTERNAL int fmu__assemble(fmu *f, char *why, size_t size);
FMU_INTERNAL fmi2Status fmu__rebuild(fmu *f);
FMU_INTERNAL void fmu__initial_state(fmu *f);

/* tunable parameters (fmu_parameters.c) */
FMU_INTERNAL const char *fmu__refusal(const parameter *p, double x, char *why, size_t size);
FMU_INTERNAL int64_t fmu__broken_relation(const fmu *f, const double *values);
FMU_INTERNAL const char *fmu__bad_q0(const fmu *f, double q0, char *why, size_t size);
FMU_INTERNAL void fmu__restore(fmu *f, int rebuild_before);
FMU_INTERNAL int fmu__set_parameters(fmu *f, const fmi2ValueReference vr[], size_t nvr,
                                     const fmi2Real value[], int sets_q0, double q0);

/* the energy ledger (fmu_ledger.c) */
FMU_INTERNAL double fmu__deflection(const fmu *f, const double *s, int64_t k);
FMU_INTERNAL void fmu__stored(fmu *f, const double *inputs, double energy[3], double *springs);
FMU_INTERNAL void fmu__start_run(fmu *f);
FMU_INTERNAL double fmu__source_jumps(const fmu *f);
FMU_INTERNAL void fmu__shift_start(fmu *f, const double *before, const double *after);
FMU_INTERNAL void fmu__run_ledger(fmu *f, double *residual, double *scale);
FMU_INTERNAL void fmu__book(fmu *f, double h);
FMU_INTERNAL void fmu__powers(fmu *f);

#endif
