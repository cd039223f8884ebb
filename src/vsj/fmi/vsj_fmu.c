/* vsj's wrist as an FMI 2.0 co-simulation FMU, on the C engine (vsj.h).
 *
 * This file holds the FMI 2.0 entry points (instantiation, life cycle, values,
 * stepping, the model-exchange functions it refuses); the jobs behind them are
 * fmu_setup.c (the resources: the model, the parameter map `fmu.txt`, whose
 * layout is described there), fmu_parameters.c, fmu_ledger.c and fmu_state.c,
 * with fmu_internal.h.
 *
 * Value references. Real: inputs 0..4 (motor commands, then the external
 * torques tau_x, tau_y, in the model file's order); outputs 10..22 (see
 * `enum output`); 99 the initial pivot position; 100.. the parameters.
 * Integer: 0 the number of stuck friction elements.
 *
 * Every call checks its instance and its arguments; a bad call returns
 * fmi2Error and says why through the importer's logger. Each step is checked
 * as vsj simulate checks a run (vsj.simulate.checks): a spring `diverged`
 * past its end stop ends the run (fmi2Error, the instance in the error state,
 * from which fmi2SetFMUstate or fmi2Reset take it back); a spring `into_stop`
 * past its stop or a motor above its voltage limit gives fmi2Warning, once
 * per spring and motor and run. The energy ledger of the run (initialization
 * to fmi2Terminate) is judged at fmi2Terminate. Instances share nothing: any
 * number may run at once, each from one thread at a time.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmu_internal.h"

/* The log categories of the model description (fmu.py). Warnings and errors go to the
 * importer's logger always: FMI 2.0 (section 2.1.3) has the logger called for the status
 * they explain. The other messages are information, in category logAll, and go when
 * debug logging is on for it (fmu.log_info). */
static const char *const CATEGORIES[] = {"logStatusError", "logStatusWarning", "logAll"};
#define N_CATEGORIES (sizeof CATEGORIES / sizeof CATEGORIES[0])

void fmu__say(const fmu *f, fmi2Status status, const char *category, const char *format, ...) {
    char text[1024];
    va_list args;
    if (!f || !f->logger || (status < fmi2Warning && !(f->logging && f->log_info)))
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

fmi2Status fmu__fail(fmu *f, const char *format, const char *detail) {
    fmu__say(f, fmi2Error, "logStatusError", format, detail);
    return fmi2Error;
}

/* ---- instantiation ----------------------------------------------------------- */

static fmi2Component refuse(fmu *f, const char *format, const char *detail) {
    fmu__fail(f, format, detail);
    fmu__free(f);
    return NULL;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    fmu *f;
    char why[512], text[2 * GUID_MAX + 600], *path;
    const char *problem;
    (void)visible;
    if (!functions || !functions->logger)
        return NULL;
    f = (fmu *)calloc(1, sizeof(fmu));
    if (!f)
        return NULL;
    f->logger = functions->logger;
    f->env = functions->componentEnvironment;
    f->logging = loggingOn;
    f->log_info = 1; /* every category, until fmi2SetDebugLogging names some */
    f->name = fmu__copy_text(instanceName && instanceName[0] ? instanceName : "vsj");
    if (!f->name) {
        free(f);
        return NULL;
    }
    if (fmuType != fmi2CoSimulation)
        return refuse(f, "vsj's FMU is for co-simulation only%s", "");
    if (!fmuResourceLocation)
        return refuse(f, "no resource location given%s", "");
    path = fmu__resource_path(fmuResourceLocation, "model.vsjm");
    if (!path)
        return refuse(f, "out of memory%s", "");
    f->loaded = vsj_load_model(path, why, sizeof why);
    free(path);
    if (!f->loaded)
        return refuse(f, "cannot load the model: %s", why);
    f->model = f->loaded->model;
    f->n_mass = (f->model.n + f->model.n_sources) * (f->model.n + f->model.n_sources);
    f->n_par_values = f->model.n_rows * VSJ_NPAR;
    f->ns = vsj_step_state_size(&f->model);
    f->ni = f->loaded->n_inputs;
    f->nacc = vsj_n_acc(&f->model);
    path = fmu__resource_path(fmuResourceLocation, "fmu.txt");
    if (!path)
        return refuse(f, "out of memory%s", "");
    if (!fmu__read_map(f, path, why, sizeof why)) {
        free(path);
        return refuse(f, "cannot read the parameter map: %s", why);
    }
    free(path);
    /* FMI 2.0: the FMU checks that the importer read its own modelDescription.xml */
    if (!fmuGUID || !fmuGUID[0]) {
        snprintf(text, sizeof text, "fmi2Instantiate: no GUID given; this FMU's GUID is %s",
                 f->guid);
        return refuse(f, "%s", text);
    }
    if (strcmp(fmuGUID, f->guid) != 0) {
        snprintf(text, sizeof text, "fmi2Instantiate: the GUID given, %.*s, is not this FMU's "
                 "GUID %s: the modelDescription.xml read belongs to another FMU",
                 GUID_MAX, fmuGUID, f->guid);
        return refuse(f, "%s", text);
    }
    if (!fmu__allocate(f))
        return refuse(f, "out of memory%s", "");
    f->model.mass = f->mass;
    f->model.Minv = f->minv;
    f->model.par = f->par;
    problem = fmu__not_a_wrist(f);
    if (problem)
        return refuse(f, "%s", problem);
    f->history_size = vsj_ts_history_size(&f->model);
    f->rebuild = 1;
    f->mode = INSTANTIATED;
    if (fmu__rebuild(f) != fmi2OK) {
        fmu__free(f);
        return NULL;
    }
    fmu__initial_state(f);
    fmu__say(f, fmi2OK, "logAll", "instantiated: %lld parameters", (long long)f->n_parameters);
    return f;
}

void fmi2FreeInstance(fmi2Component c) { fmu__free((fmu *)c); }

/* ---- life cycle ---------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return "default"; }
const char *fmi2GetVersion(void) { return "2.0"; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    fmu *f = (fmu *)c;
    int info = nCategories == 0; /* none named: every category */
    size_t k, j;
    if (!f)
        return fmi2Error;
    if (nCategories > 0 && !categories)
        return fmu__fail(f, "fmi2SetDebugLogging: %s", "categories is a null pointer");
    for (k = 0; k < nCategories; k++) {
        for (j = 0; j < N_CATEGORIES; j++)
            if (categories[k] && strcmp(categories[k], CATEGORIES[j]) == 0)
                break;
        if (j == N_CATEGORIES) {
            char why[200];
            snprintf(why, sizeof why, "no log category \"%.60s\"; this FMU's are "
                     "logStatusError, logStatusWarning and logAll",
                     categories[k] ? categories[k] : "(null)");
            return fmu__fail(f, "fmi2SetDebugLogging: %s", why);
        }
        info = info || strcmp(categories[k], "logAll") == 0;
    }
    f->logging = loggingOn;
    f->log_info = info;
    return fmi2OK;
}

/* Whether the scheme has an error control (dopri, rosenbrock), which a tolerance from
 * the importer drives; the time-stepper's fixed step has none. */
static int adaptive(const fmu *f) {
    return f->scheme.method == VSJ_METHOD_DOPRI || f->scheme.method == VSJ_METHOD_ROSENBROCK;
}

/* The adaptive schemes' tolerances for the experiment being set up (fmi2SetupExperiment,
 * and fmi2Reset back to the model file's): the model file's, or, with the importer's
 * relative `tolerance` (defined), that one and the model file's absolute tolerance
 * scaled by the same factor, kept within vsj's range of atol. */
static void use_tolerance(fmu *f, int defined, double tolerance) {
    const vsj_scheme *own = &f->loaded->scheme;
    f->scheme.rtol = own->rtol;
    f->scheme.atol = own->atol;
    if (!defined || !adaptive(f))
        return;
    f->scheme.rtol = tolerance;
    f->scheme.atol = fmin(fmax(own->atol * (tolerance / own->rtol), 1e-20), 1e-2);
    fmu__say(f, fmi2OK, "logAll", "fmi2SetupExperiment: the importer's tolerance: relative "
             "%g, absolute %g (the model file's %g and %g)", f->scheme.rtol, f->scheme.atol,
             own->rtol, own->atol);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    fmu *f = (fmu *)c;
    int defined = toleranceDefined != fmi2False;
    if (!f)
        return fmi2Error;
    if (f->mode != INSTANTIATED)
        return fmu__fail(f, "fmi2SetupExperiment: only after fmi2Instantiate or fmi2Reset%s", "");
    if (!isfinite(startTime))
        return fmu__fail(f, "fmi2SetupExperiment: the start time must be finite%s", "");
    if (stopTimeDefined && !(isfinite(stopTime) && stopTime >= startTime))
        return fmu__fail(f, "fmi2SetupExperiment: the stop time must be finite and not before "
                            "the start time%s", "");
    if (defined && adaptive(f) && !(tolerance >= 1e-14 && tolerance <= 1e-2)) /* NaN too */
        return fmu__fail(f, "fmi2SetupExperiment: the tolerance (relative) must be from "
                            "1e-14 to 1e-2, as vsj's rtol%s", "");
    f->time = startTime;
    f->stop_defined = stopTimeDefined != fmi2False;
    f->stop_time = f->stop_defined ? stopTime : 0.0; /* (an undefined one may be inf, NaN) */
    use_tolerance(f, defined, tolerance);
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    fmu *f = (fmu *)c;
    if (!f)
        return fmi2Error;
    if (f->mode != INSTANTIATED)
        return fmu__fail(f, "fmi2EnterInitializationMode: not after fmi2Instantiate%s", "");
    f->mode = INITIALIZING;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    fmu *f = (fmu *)c;
    char why[200];
    double start;
    if (!f)
        return fmi2Error;
    if (f->mode != INITIALIZING)
        return fmu__fail(f, "fmi2ExitInitializationMode: not in initialization mode%s", "");
    if (fmu__bad_q0(f, f->q0, why, sizeof why)) /* the range moved with pivot.q_min, q_max */
        return fmu__fail(f, "fmi2ExitInitializationMode: %s", why);
    start = f->time;
    if (f->rebuild && fmu__rebuild(f) != fmi2OK) {
        f->mode = FAILED;
        return fmi2Error;
    }
    fmu__initial_state(f);
    f->time = start;
    fmu__start_run(f);
    f->mode = STEPPING;
    return fmi2OK;
}

/* The run from initialization to fmi2Terminate is judged by its energy ledger,
 * as vsj simulate judges a run (vsj.simulate.checks.judge). */
fmi2Status fmi2Terminate(fmi2Component c) {
    fmu *f = (fmu *)c;
    double residual, scale, relative;
    char text[400];
    if (!f)
        return fmi2Error;
    if (f->mode == INSTANTIATED || f->mode == INITIALIZING || f->mode == TERMINATED)
        return fmu__fail(f, "fmi2Terminate: only after initialization, once (FMI 2.0's state "
                            "machine)%s", "");
    if (f->mode == FAILED) /* a failed step ends the run: nothing to judge */
        return fmi2OK;
    fmu__run_ledger(f, &residual, &scale);
    relative = fabs(residual) / scale;
    if (!(relative <= f->ledger_tolerance)) {
        snprintf(text, sizeof text, "its residual is %.6g of the energy in play, above the "
                 "ledger tolerance %g (the numerical settings are too coarse for this run: %s)",
                 relative, f->ledger_tolerance,
                 adaptive(f) ? "set it up with a smaller tolerance (fmi2SetupExperiment), or "
                               "export the FMU with a smaller one, vsj fmu --rtol --atol"
                             : "export the FMU with a shorter step, vsj fmu --step");
        f->mode = FAILED;
        return fmu__fail(f, "fmi2Terminate: the run cannot be trusted: its energy ledger "
                            "does not close: %s", text);
    }
    fmu__say(f, fmi2OK, "logAll", "fmi2Terminate: the energy ledger of the run closes: its "
             "residual is %.6g of the energy in play (tolerance %g)", relative,
             f->ledger_tolerance);
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
    f->stop_defined = 0;
    use_tolerance(f, 0, 0.0);
    memset(f->inputs, 0, (size_t)f->ni * sizeof(double));
    f->rebuild = 1;
    if (fmu__rebuild(f) != fmi2OK) {
        f->mode = FAILED;
        return fmi2Error;
    }
    fmu__initial_state(f);
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
    case DEFLECTION_1: return fmu__deflection(f, f->s, 0);
    case DEFLECTION_2: return fmu__deflection(f, f->s, 1);
    case PIVOT_Q: return vsj_step_pivot_position(&f->model, f->s);
    case MOTOR_1_ANGLE: return row_value(f, f->rows[2], NULL);
    case MOTOR_2_ANGLE: return row_value(f, f->rows[3], NULL);
    case MOTOR_S_ANGLE: return row_value(f, f->rows[4], NULL);
    case POWER_IN: fmu__powers(f); return f->power_in;
    case POWER_DISSIPATED: fmu__powers(f); return f->power_dissipated;
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
        return fmu__fail(f, "fmi2GetReal: null array%s", "");
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
            return fmu__fail(f, "fmi2GetReal: no Real variable has value reference %s", text);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    fmu *f = (fmu *)c;
    size_t k;
    char text[400], why[200];
    int sets_q0 = 0, differs = 0, stepping, changed;
    double q0 = 0.0, *before, *after;
    if (!f)
        return fmi2Error;
    if (nvr && (!vr || !value))
        return fmu__fail(f, "fmi2SetReal: null array%s", "");
    if (f->mode == TERMINATED)
        return fmu__fail(f, "fmi2SetReal: the instance is terminated (fmi2Reset starts it "
                            "anew)%s", "");
    for (k = 0; k < nvr; k++) { /* each value checked before any is set */
        fmi2ValueReference r = vr[k];
        double x = value[k];
        if (r < (fmi2ValueReference)f->ni) {
            if (!isfinite(x)) {
                snprintf(text, sizeof text, "%s = %g", f->loaded->input_names[r], x);
                return fmu__fail(f, "fmi2SetReal: input %s: the value is not finite", text);
            }
            continue;
        }
        if (r == VR_Q0) {
            if (!isfinite(x))
                return fmu__fail(f, "fmi2SetReal: pivot_q0: the value is not finite%s", "");
            if (f->mode != INSTANTIATED && f->mode != INITIALIZING)
                return fmu__fail(f, "fmi2SetReal: pivot_q0, the initial pivot position, "
                                    "can only be set before initialization ends%s", "");
            sets_q0 = 1;
            q0 = x;
        } else if (r >= VR_PARAMETER && r < VR_PARAMETER + (fmi2ValueReference)f->n_parameters) {
            const parameter *p = f->parameters + (r - VR_PARAMETER);
            if (fmu__refusal(p, x, why, sizeof why)) {
                snprintf(text, sizeof text, "%s = %g%s%s is outside its range: %s", p->key, x,
                         p->unit[0] ? " " : "", p->unit, why);
                return fmu__fail(f, "fmi2SetReal: %s", text);
            }
            differs |= f->values[r - VR_PARAMETER] != x;
        } else {
            snprintf(text, sizeof text, "%u", r);
            return fmu__fail(f, "fmi2SetReal: value reference %s is not an input or a "
                             "parameter", text);
        }
    }
    /* a parameter changed while stepping changes the stored energy: the ledger's
     * start moves with it (see fmu__shift_start in fmu_ledger.c) */
    stepping = f->mode == STEPPING && differs;
    before = f->energy;
    after = f->energy + 3 + f->model.n_springs;
    if (stepping) { /* the jumps so far, with the sources' inertia before the change */
        f->record[f->at.start] += fmu__source_jumps(f);
        memcpy(f->record + f->at.reference, f->record + f->at.applied,
               (size_t)f->ni * sizeof(double));
        fmu__stored(f, f->record + f->at.applied, before, before + 3);
    }
    changed = differs || sets_q0 ? fmu__set_parameters(f, vr, nvr, value, sets_q0, q0) : 0;
    if (changed < 0)
        return fmi2Error;
    if (changed && stepping) {
        fmu__stored(f, f->record + f->at.applied, after, after + 3);
        fmu__shift_start(f, before, after);
    }
    for (k = 0; k < nvr; k++)
        if (vr[k] < (fmi2ValueReference)f->ni)
            f->inputs[vr[k]] = value[k];
    if (sets_q0)
        f->q0 = q0;
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    fmu *f = (fmu *)c;
    size_t k;
    if (!f)
        return fmi2Error;
    if (nvr && (!vr || !value))
        return fmu__fail(f, "fmi2GetInteger: null array%s", "");
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_STUCK)
            return fmu__fail(f, "fmi2GetInteger: the only Integer is n_stuck (value reference "
                             "0)%s", "");
        value[k] = f->scheme.method == VSJ_METHOD_TIMESTEP && f->mode == STEPPING
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
    return nvr ? fmu__fail((fmu *)c, "fmi2SetInteger: the FMU has no Integer to set%s", "")
               : fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    if (!c)
        return fmi2Error;
    return nvr ? fmu__fail((fmu *)c, "fmi2GetBoolean: the FMU has no Boolean%s", "") : fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    if (!c)
        return fmi2Error;
    return nvr ? fmu__fail((fmu *)c, "fmi2SetBoolean: the FMU has no Boolean%s", "") : fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    (void)vr;
    (void)value;
    if (!c)
        return fmi2Error;
    return nvr ? fmu__fail((fmu *)c, "fmi2GetString: the FMU has no String%s", "") : fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    (void)vr;
    (void)value;
    if (!c)
        return fmi2Error;
    return nvr ? fmu__fail((fmu *)c, "fmi2SetString: the FMU has no String%s", "") : fmi2OK;
}

/* ---- stepping ------------------------------------------------------------------ */

/* The checks vsj simulate makes of a run (vsj.simulate.checks), at the end of a
 * step: fmi2Error for a spring that diverged past its end stop, fmi2Warning the
 * first time a spring goes into_stop past it or an input exceeds a motor's
 * voltage limit, else fmi2OK. */
static fmi2Status judge_step(fmu *f, double t_start) {
    const vsj_model *m = &f->model;
    double *warned = f->record + f->at.warned;
    fmi2Status status = fmi2OK;
    char text[400];
    int64_t k;
    for (k = 0; k < m->n_springs; k++) {
        const spring *sp = f->springs + k;
        double stop, angle, past;
        if (sp->stop_column < 0)
            continue;
        stop = f->par[VSJ_NPAR * (m->n_frictions + k) + sp->stop_column];
        if (!(stop > 0.0))
            continue;
        angle = fmu__deflection(f, f->s, k);
        past = fabs(angle) - stop;
        if (past > f->diverged) {
            snprintf(text, sizeof text, "at t = %.9g s spring %s deflected %.4g rad, more "
                     "than %.4g rad past its %.4g rad end stop: the run diverged", f->time,
                     sp->name, angle, f->diverged, stop);
            f->mode = FAILED;
            return fmu__fail(f, "fmi2DoStep: %s", text);
        }
        if (past > f->into_stop && warned[k] == 0.0) {
            warned[k] = 1.0;
            fmu__say(f, fmi2Warning, "logStatusWarning", "fmi2DoStep: spring %s was driven to "
                "%.4g rad at t = %.9g s, %.3g rad past its %.4g rad end stop: the loads exceed "
                "what the mechanism takes", sp->name, angle, f->time, past, stop);
            status = fmi2Warning;
        }
    }
    for (k = 0; k < f->n_limits; k++) {
        const limit *lim = f->limits + k;
        double volts = f->inputs[lim->input];
        if (fabs(volts) > lim->limit && warned[m->n_springs + lim->input] == 0.0) {
            warned[m->n_springs + lim->input] = 1.0;
            fmu__say(f, fmi2Warning, "logStatusWarning", "fmi2DoStep: motor %s was driven at "
                "%.4g V at t = %.9g s, beyond its %g V limit", lim->motor, volts, t_start,
                lim->limit);
            status = fmi2Warning;
        }
    }
    return status;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    fmu *f = (fmu *)c;
    int status;
    double h = communicationStepSize, point = currentCommunicationPoint;
    char text[160];
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!f)
        return fmi2Error;
    if (f->mode != STEPPING)
        return fmu__fail(f, "fmi2DoStep: not after initialization (or after an error)%s", "");
    if (!(h > 0.0) || !isfinite(h))
        return fmu__fail(f, "fmi2DoStep: the communication step must be positive and finite%s", "");
    if (!(fabs(point - f->time) <= 1e-9 * (1.0 + fabs(f->time)))) { /* NaN included */
        snprintf(text, sizeof text, "%.17g s, but the FMU is at %.17g s", point, f->time);
        return fmu__fail(f, "fmi2DoStep: the communication point is %s", text);
    }
    if (f->stop_defined && point + h > f->stop_time + 1e-9 * (1.0 + fabs(f->stop_time))) {
        snprintf(text, sizeof text, "%.17g s would pass the stop time %.17g s", point + h,
                 f->stop_time);
        return fmu__fail(f, "fmi2DoStep: a step to %s set by fmi2SetupExperiment", text);
    }
    if (f->scheme.method == VSJ_METHOD_TIMESTEP && !(h / f->scheme.h <= VSJ_MAX_PERIOD_STEPS)) {
        snprintf(text, sizeof text, "%g s takes more than %d steps of %g s, the most one step "
                 "of the FMU takes: split it", h, VSJ_MAX_PERIOD_STEPS, f->scheme.h);
        return fmu__fail(f, "fmi2DoStep: a communication step of %s", text);
    }
    if (f->rebuild && fmu__rebuild(f) != fmi2OK)
        return fmi2Error;
    status = vsj_step(&f->model, f->work, &f->scheme, f->s, f->inputs, h, f->ledger);
    if (status == VSJ_TOO_MANY_STEPS) { /* the state is unchanged: the instance goes on */
        snprintf(text, sizeof text, "of %g s from t = %.9g s takes more than %d internal "
                 "steps, the most one step of the FMU takes: split it", h, f->time,
                 VSJ_MAX_PERIOD_STEPS);
        return fmu__fail(f, "fmi2DoStep: a communication step %s", text);
    }
    if (status != VSJ_OK) {
        snprintf(text, sizeof text, "at t = %.9g s: %s", f->time, vsj_status_text(status));
        f->mode = FAILED;
        return fmu__fail(f, "fmi2DoStep: the step failed %s", text);
    }
    memcpy(f->record + f->at.applied, f->inputs, (size_t)f->ni * sizeof(double));
    fmu__book(f, h);
    f->time += h;
    return judge_step(f, point);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return c ? fmu__fail((fmu *)c, "fmi2CancelStep: steps are never asynchronous%s", "")
             : fmi2Error;
}

static fmi2Status no_status(fmi2Component c, const char *what) {
    return c ? fmu__fail((fmu *)c, "%s: steps are never asynchronous", what) : fmi2Error;
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
    return c ? fmu__fail((fmu *)c, "fmi2SetRealInputDerivatives: inputs are held over each "
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
    return c ? fmu__fail((fmu *)c, "fmi2GetRealOutputDerivatives: not provided "
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
    return c ? fmu__fail((fmu *)c, "fmi2GetDirectionalDerivative: not provided%s", "") : fmi2Error;
}

/* ---- model exchange: not this FMU's interface ---------------------------------- */

static fmi2Status not_me(fmi2Component c, const char *what) {
    return c ? fmu__fail((fmu *)c, "%s: vsj's FMU is for co-simulation only", what) : fmi2Error;
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
