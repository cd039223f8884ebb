/* The sampled controller a model may carry (vsj.h: the controller).
 *
 * At each sample the controller reads its sensors from the state, runs its blocks in
 * order over one bus of signals, and sets its actuators, which then hold until the
 * next sample. The adaptive schemes end a step on every sample time (breaks.c: it is
 * the next break) and the time-stepper's grid holds them (the period is a whole number
 * of steps), so that the plant sees each held value over exactly its period.
 */
#include <math.h>
#include <string.h>

#include "internal.h"

/* ---- checks ------------------------------------------------------------------ */

/* Parameters a block of kind `kind` with these sizes takes. */
static int64_t block_par_count(int64_t kind, int64_t nin, int64_t nout, int64_t ns) {
    if (kind == VSJ_BLOCK_PID)
        return VSJ_NPID;
    return ns * ns + ns * nin + nout * ns + nout * nin;
}

static int check_pid(const double *p, int64_t b, char *message, size_t size) {
    int64_t c;
    for (c = 0; c < VSJ_NPID; c++) {
        int may_be_infinite = c == VSJ_PID_TI || c == VSJ_PID_YMIN || c == VSJ_PID_YMAX;
        if (isnan(p[c]) || (!may_be_infinite && !isfinite(p[c])))
            return vsj__fail(message, size, "controller block %lld: PID parameter %lld is %g",
                             (long long)b, (long long)c, p[c]);
    }
    if (!(p[VSJ_PID_TI] > 0.0) || p[VSJ_PID_TD] < 0.0 || !(p[VSJ_PID_ND] > 0.0)
        || !(p[VSJ_PID_NI] > 0.0) || !(p[VSJ_PID_YMIN] <= p[VSJ_PID_YMAX]))
        return vsj__fail(message, size, "controller block %lld: a PID needs Ti > 0, Td >= 0, "
                         "Nd > 0, Ni > 0 and ymin <= ymax", (long long)b);
    if (p[VSJ_PID_WINDUP] != 0.0 && p[VSJ_PID_WINDUP] != 1.0 && p[VSJ_PID_WINDUP] != 2.0)
        return vsj__fail(message, size, "controller block %lld: anti-windup must be 0, 1 or 2, "
                         "got %g", (long long)b, p[VSJ_PID_WINDUP]);
    return VSJ_OK;
}

/* The blocks: kinds, sizes that add up, parameters, and inputs that read only the
 * references, the measurements and earlier blocks' outputs. */
static int check_blocks(const vsj_model *m, char *message, size_t size) {
    int64_t b, c, r, n_in = 0, n_par = 0, n_state = 0;
    int64_t avail = m->n_refs + m->n_meas; /* bus entries a block may read */
    for (b = 0; b < m->n_blocks; b++) {
        const int64_t *d = m->blk + VSJ_NBLK * b;
        int64_t kind = d[VSJ_B_KIND], nin = d[VSJ_B_IN], nout = d[VSJ_B_OUT];
        int64_t ns = d[VSJ_B_STATES];
        if (kind < 0 || kind >= VSJ_N_BLOCKS)
            return vsj__fail(message, size, "controller block %lld: unknown kind %lld",
                             (long long)b, (long long)kind);
        if (nin < 0 || nout < 1 || ns < 0 || nin > m->n_blk_in - n_in || nout > m->n_bus
            || ns > m->n_cstate - n_state
            || (kind == VSJ_BLOCK_PID && (nin != 3 || nout != 1 || ns != 2)))
            return vsj__fail(message, size, "controller block %lld: sizes %lld inputs, %lld "
                             "outputs, %lld states do not fit its kind or the model's sizes",
                             (long long)b,
                             (long long)nin, (long long)nout, (long long)ns);
        if (d[VSJ_B_PAR] != n_par || d[VSJ_B_ROW] != n_in)
            return vsj__fail(message, size, "controller block %lld: its parameters and input "
                             "rows must follow the previous block's", (long long)b);
        n_par += block_par_count(kind, nin, nout, ns);
        n_in += nin;
        n_state += ns;
        if (n_par > m->n_blk_par || n_in > m->n_blk_in)
            break;
        for (r = d[VSJ_B_ROW]; r < n_in; r++)
            for (c = 0; c < m->n_bus; c++) {
                double v = m->blk_in[m->n_bus * r + c];
                if (!isfinite(v) || (c >= avail && v != 0.0))
                    return vsj__fail(message, size, "controller block %lld: input row %lld "
                                     "reads bus entry %lld (%g); a block reads references, "
                                     "measurements and earlier blocks' outputs only",
                                     (long long)b, (long long)(r - d[VSJ_B_ROW]), (long long)c,
                                     v);
            }
        if (kind == VSJ_BLOCK_PID) {
            int status = check_pid(m->blk_par + d[VSJ_B_PAR], b, message, size);
            if (status != VSJ_OK)
                return status;
        } else {
            for (c = d[VSJ_B_PAR]; c < n_par; c++)
                if (!isfinite(m->blk_par[c]))
                    return vsj__fail(message, size, "controller block %lld: parameter %lld is "
                                     "%g", (long long)b, (long long)(c - d[VSJ_B_PAR]),
                                     m->blk_par[c]);
        }
        avail += nout;
    }
    if (n_par != m->n_blk_par || n_in != m->n_blk_in || n_state != m->n_cstate
        || avail != m->n_bus)
        return vsj__fail(message, size, "controller: its blocks need %lld parameters, %lld "
                         "input rows, %lld states and a bus of %lld; the model has %lld, %lld, "
                         "%lld and %lld", (long long)n_par, (long long)n_in, (long long)n_state,
                         (long long)avail, (long long)m->n_blk_par, (long long)m->n_blk_in,
                         (long long)m->n_cstate, (long long)m->n_bus);
    return VSJ_OK;
}

static int check_sensors(const vsj_model *m, char *message, size_t size) {
    int64_t i, c, delays = 0, width = m->n + m->n_sources;
    for (i = 0; i < m->n_meas; i++) {
        const double *p = m->meas_par + VSJ_NMEAS * i;
        int64_t kind = m->meas_kind[i];
        if (kind < 0 || kind >= VSJ_N_SENSORS)
            return vsj__fail(message, size, "controller sensor %lld: unknown kind %lld",
                             (long long)i, (long long)kind);
        for (c = 0; c < width; c++)
            if (!isfinite(m->meas_row[width * i + c]))
                return vsj__fail(message, size, "controller sensor %lld: its row is not finite",
                                 (long long)i);
        if (!(p[VSJ_M_RESOLUTION] >= 0.0) || !isfinite(p[VSJ_M_RESOLUTION])
            || !(p[VSJ_M_NOISE] >= 0.0) || !isfinite(p[VSJ_M_NOISE])
            || !(p[VSJ_M_DELAY] >= 0.0) || p[VSJ_M_DELAY] != floor(p[VSJ_M_DELAY])
            || p[VSJ_M_DELAY] > 1e9)
            return vsj__fail(message, size, "controller sensor %lld: resolution and noise must "
                             "be finite and >= 0, the delay a whole number of samples >= 0",
                             (long long)i);
        if (kind == VSJ_SENSE_CURRENT
            && !(p[VSJ_M_MOTOR] >= 0.0 && p[VSJ_M_MOTOR] < (double)m->n_motors
                 && p[VSJ_M_MOTOR] == floor(p[VSJ_M_MOTOR])))
            return vsj__fail(message, size, "controller sensor %lld: motor %g of %lld",
                             (long long)i, p[VSJ_M_MOTOR], (long long)m->n_motors);
        delays += (int64_t)p[VSJ_M_DELAY];
    }
    if (delays != m->n_delay)
        return vsj__fail(message, size, "controller: the sensors' delays add up to %lld samples, "
                         "n_delay is %lld", (long long)delays, (long long)m->n_delay);
    return VSJ_OK;
}

static int check_actuators(const vsj_model *m, char *message, size_t size) {
    int64_t a, b, c;
    for (a = 0; a < m->n_acts; a++) {
        const double *p = m->act_par + VSJ_NACT * a;
        c = m->act_ch[a];
        /* a velocity source reads its channel's integral: a controller drives none */
        if (c < 0 || c >= m->n_channels || vsj__among(m->src_ch, m->n_sources, c))
            return vsj__fail(message, size, "controller actuator %lld: channel %lld is not a "
                             "load's or a motor's input", (long long)a, (long long)c);
        for (b = 0; b < a; b++)
            if (m->act_ch[b] == c)
                return vsj__fail(message, size, "controller: actuators %lld and %lld drive the "
                                 "same channel %lld", (long long)b, (long long)a, (long long)c);
        for (b = 0; b < m->n_refs; b++)
            if (m->ref_ch[b] == c)
                return vsj__fail(message, size, "controller actuator %lld drives channel %lld, "
                                 "which is reference %lld", (long long)a, (long long)c,
                                 (long long)b);
        for (b = 0; b < m->n_bus; b++)
            if (!isfinite(m->act_row[m->n_bus * a + b]))
                return vsj__fail(message, size, "controller actuator %lld: its row is not finite",
                                 (long long)a);
        if (!isfinite(p[VSJ_A_OFFSET]) || isnan(p[VSJ_A_LO]) || isnan(p[VSJ_A_HI])
            || !(p[VSJ_A_LO] <= p[VSJ_A_HI]) || !(p[VSJ_A_CURRENT] > 0.0))
            return vsj__fail(message, size, "controller actuator %lld: needs a finite offset, "
                             "lower limit <= upper limit and a current limit > 0",
                             (long long)a);
        if (p[VSJ_A_MOTOR] != -1.0
            && !(p[VSJ_A_MOTOR] >= 0.0 && p[VSJ_A_MOTOR] < (double)m->n_motors
                 && p[VSJ_A_MOTOR] == floor(p[VSJ_A_MOTOR])))
            return vsj__fail(message, size, "controller actuator %lld: motor %g of %lld",
                             (long long)a, p[VSJ_A_MOTOR], (long long)m->n_motors);
    }
    return VSJ_OK;
}

int vsj__control_check(const vsj_model *m, char *message, size_t size) {
    int64_t i;
    int status;
    if (m->n_refs < 0 || m->n_meas < 0 || m->n_blocks < 0 || m->n_acts < 0 || m->n_bus < 0
        || m->n_cstate < 0 || m->n_delay < 0 || m->n_blk_in < 0 || m->n_blk_par < 0)
        return vsj__fail(message, size, "model: the controller's sizes must be >= 0");
    if (m->n_acts == 0) {
        if (m->n_refs || m->n_meas || m->n_blocks || m->n_bus || m->n_cstate || m->n_delay
            || m->n_blk_in || m->n_blk_par)
            return vsj__fail(message, size, "model: a controller needs an actuator");
        return VSJ_OK;
    }
    if (!m->ctl || (m->n_refs && !m->ref_ch) || (m->n_meas && (!m->meas_kind || !m->meas_row
                                                               || !m->meas_par))
        || (m->n_blocks && (!m->blk || !m->blk_in || !m->blk_par))
        || !m->act_ch || !m->act_row || !m->act_par)
        return vsj__fail(message, size, "model: a controller array pointer is NULL");
    if (!(isfinite(m->ctl[VSJ_CTL_PERIOD]) && m->ctl[VSJ_CTL_PERIOD] > 0.0)
        || !(m->ctl[VSJ_CTL_SEED] >= 0.0 && m->ctl[VSJ_CTL_SEED] < 9007199254740992.0))
        return vsj__fail(message, size, "controller: the period must be finite and > 0 s, the "
                         "seed a whole number in 0 .. 2^53");
    for (i = 0; i < m->n_refs; i++)
        if (m->ref_ch[i] < 0 || m->ref_ch[i] >= m->n_channels)
            return vsj__fail(message, size, "controller reference %lld: channel %lld of %lld",
                             (long long)i, (long long)m->ref_ch[i], (long long)m->n_channels);
    if ((status = check_sensors(m, message, size)) != VSJ_OK)
        return status;
    if ((status = check_blocks(m, message, size)) != VSJ_OK)
        return status;
    return check_actuators(m, message, size);
}

int64_t vsj_control_width(const vsj_model *m) {
    return m && m->n_acts > 0 ? m->n_bus + m->n_acts : 0;
}

/* ---- the sensors --------------------------------------------------------------- */

/* splitmix64 (Steele, Lea and Flood 2014): the noise generator's next 64 bits. */
static uint64_t next_bits(uint64_t *state) {
    uint64_t z = (*state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

/* A standard normal deviate (Box-Muller, one of the pair). */
static double normal(uint64_t *state) {
    double u1 = ((double)(next_bits(state) >> 11) + 1.0) * 0x1.0p-53; /* (0, 1] */
    double u2 = (double)(next_bits(state) >> 11) * 0x1.0p-53;
    return sqrt(-2.0 * log(u1)) * cos(2.0 * VSJ_PI * u2);
}

/* The true value sensor i measures at the state y (inputs evaluated at its time). */
static double sensed(const vsj_model *m, vsj_work *w, int64_t i, const double *y) {
    int64_t n = m->n, s = m->n_sources, j, kind = m->meas_kind[i];
    const double *row = m->meas_row + (n + s) * i;
    double v = 0.0;
    if (kind == VSJ_SENSE_CURRENT)
        return y[2 * n + (int64_t)m->meas_par[VSJ_NMEAS * i + VSJ_M_MOTOR]];
    if (kind == VSJ_SENSE_PIVOT) {
        int status = w->status;
        double q = vsj__pivot_position(m, w, y);
        w->status = status; /* a range violation is the schemes' to report */
        return q;
    }
    for (j = 0; j < n; j++)
        v += row[j] * y[(kind == VSJ_SENSE_SPEED ? n : 0) + j];
    for (j = 0; j < s; j++)
        v += row[n + j] * w->srcw[SRCW * j + (kind == VSJ_SENSE_SPEED ? U : SG)];
    return v;
}

/* Each sensor's reading into the bus: quantised, with noise, through its delay line
 * (a reading d samples old; before d samples, the first). */
static void read_sensors(const vsj_model *m, vsj_work *w, const double *y) {
    int64_t i, line = 0;
    for (i = 0; i < m->n_meas; i++) {
        const double *p = m->meas_par + VSJ_NMEAS * i;
        int64_t d = (int64_t)p[VSJ_M_DELAY];
        double v = sensed(m, w, i, y);
        if (p[VSJ_M_RESOLUTION] > 0.0)
            v = p[VSJ_M_RESOLUTION] * floor(v / p[VSJ_M_RESOLUTION] + 0.5);
        if (p[VSJ_M_NOISE] > 0.0)
            v += p[VSJ_M_NOISE] * normal(&w->ctl_rng);
        if (d > 0) {
            double *buf = w->ctl_delay + line;
            int64_t slot = w->ctl_k % d, j;
            if (w->ctl_k == 0)
                for (j = 0; j < d; j++)
                    buf[j] = v;
            w->ctl_bus[m->n_refs + i] = buf[slot];
            buf[slot] = v;
        } else {
            w->ctl_bus[m->n_refs + i] = v;
        }
        line += d;
    }
}

/* ---- the blocks ---------------------------------------------------------------- */

/* A sampled LimPID: in = (set-point, measurement, feed-forward), x = (integral,
 * derivative filter state); the limited output. The derivative acts on wd times the
 * set-point minus the measurement through the first-order filter Td s / (1 + s Td/Nd),
 * sampled exactly with the error held; the integrator is a forward Euler sum whose
 * input gains the back-calculation term (limited - unlimited) / (k Ni), or (clamping)
 * stops while the output is held at a limit and the error would push it further. */
static double pid(const double *p, const double *in, double *x, double *x1, double dt,
                  int first) {
    double k = p[VSJ_PID_K], e = in[0] - in[1];
    double ep = p[VSJ_PID_WP] * in[0] - in[1], ed = p[VSJ_PID_WD] * in[0] - in[1];
    double d = 0.0, y, ylim, rate;
    if (first)
        x[1] = ed; /* no derivative kick from the initial error */
    if (p[VSJ_PID_TD] > 0.0) {
        double nd = p[VSJ_PID_ND], decay = exp(-dt * nd / p[VSJ_PID_TD]);
        d = nd * (ed - x[1]);
        x1[1] = ed + (x[1] - ed) * decay;
    } else {
        x1[1] = ed;
    }
    y = k * (ep + x[0] + d) + in[2];
    ylim = y < p[VSJ_PID_YMIN] ? p[VSJ_PID_YMIN] : (y > p[VSJ_PID_YMAX] ? p[VSJ_PID_YMAX] : y);
    rate = 0.0;
    if (isfinite(p[VSJ_PID_TI])) {
        rate = e;
        if (p[VSJ_PID_WINDUP] == 1.0 && k != 0.0)
            rate += (ylim - y) / (k * p[VSJ_PID_NI]);
        else if (p[VSJ_PID_WINDUP] == 2.0 && ylim != y && (y - ylim) * k * e > 0.0)
            rate = 0.0;
        rate /= p[VSJ_PID_TI];
    }
    x1[0] = x[0] + dt * rate;
    return ylim;
}

/* Block b's outputs onto the bus at `out`, its next states into x1. */
static void run_block(const vsj_model *m, vsj_work *w, int64_t b, int64_t out, double dt) {
    const int64_t *d = m->blk + VSJ_NBLK * b;
    int64_t nin = d[VSJ_B_IN], nout = d[VSJ_B_OUT], ns = d[VSJ_B_STATES], i, j;
    const double *p = m->blk_par + d[VSJ_B_PAR], *rows = m->blk_in + m->n_bus * d[VSJ_B_ROW];
    double *in = w->ctl_in, *bus = w->ctl_bus;
    int64_t state0 = 0;
    for (j = 0; j < b; j++)
        state0 += m->blk[VSJ_NBLK * j + VSJ_B_STATES];
    for (i = 0; i < nin; i++) {
        double v = 0.0;
        for (j = 0; j < out; j++) /* only the entries before its own outputs */
            v += rows[m->n_bus * i + j] * bus[j];
        in[i] = v;
    }
    if (d[VSJ_B_KIND] == VSJ_BLOCK_PID) {
        bus[out] = pid(p, in, w->ctl_x + state0, w->ctl_x1 + state0, dt, w->ctl_k == 0);
        return;
    }
    {
        const double *A = p, *B = A + ns * ns, *C = B + ns * nin, *D = C + nout * ns;
        const double *x = w->ctl_x + state0;
        double *x1 = w->ctl_x1 + state0;
        for (i = 0; i < nout; i++) {
            double v = 0.0;
            for (j = 0; j < ns; j++)
                v += C[ns * i + j] * x[j];
            for (j = 0; j < nin; j++)
                v += D[nin * i + j] * in[j];
            bus[out + i] = v;
        }
        for (i = 0; i < ns; i++) {
            double v = 0.0;
            for (j = 0; j < ns; j++)
                v += A[ns * i + j] * x[j];
            for (j = 0; j < nin; j++)
                v += B[nin * i + j] * in[j];
            x1[i] = v;
        }
    }
}

/* The actuators' commands from the bus: driving a motor with a current limit, clipped
 * to the voltages that keep the steady current (V - k_t omega) / R within it at the
 * motor's speed now, then to the actuator's limits (which win where the two disagree). */
static void set_actuators(const vsj_model *m, vsj_work *w, const double *y) {
    int64_t a, j, f = m->n_frictions + m->n_springs + m->n_loads;
    for (a = 0; a < m->n_acts; a++) {
        const double *p = m->act_par + VSJ_NACT * a, *row = m->act_row + m->n_bus * a;
        double u = p[VSJ_A_OFFSET];
        for (j = 0; j < m->n_bus; j++)
            u += row[j] * w->ctl_bus[j];
        if (p[VSJ_A_MOTOR] >= 0.0 && isfinite(p[VSJ_A_CURRENT])) {
            int64_t r = f + (int64_t)p[VSJ_A_MOTOR];
            const double *mp = vsj__row(m, r);
            double omega = vsj__xdot(m, r, y + m->n) + vsj__udot(m, r, w->srcw, U);
            double emf = mp[2] * omega, span = mp[0] * p[VSJ_A_CURRENT];
            u = u < emf - span ? emf - span : (u > emf + span ? emf + span : u);
        }
        /* the limits last: no supply gives more, whatever a back-driven motor's emf */
        u = u < p[VSJ_A_LO] ? p[VSJ_A_LO] : (u > p[VSJ_A_HI] ? p[VSJ_A_HI] : u);
        w->ctl_u[a] = u;
    }
}

/* ---- samples --------------------------------------------------------------------- */

void vsj__control_sample(const vsj_model *m, vsj_work *w, double t, const double *y) {
    int64_t i, b, out = m->n_refs + m->n_meas;
    double dt = m->ctl[VSJ_CTL_PERIOD];
    int left = w->left;
    vsj__control_record(w, INFINITY, w->ctl_before); /* what held up to now */
    w->ctl_last = t;
    w->left = 0;
    vsj__eval_inputs(m, w, t); /* references and sources at the sample, from the right */
    w->left = left;
    for (i = 0; i < m->n_refs; i++)
        w->ctl_bus[i] = w->chan[3 * m->ref_ch[i]];
    read_sensors(m, w, y);
    for (b = 0; b < m->n_blocks; b++) {
        run_block(m, w, b, out, dt);
        out += m->blk[VSJ_NBLK * b + VSJ_B_OUT];
    }
    if (m->n_cstate > 0)
        memcpy(w->ctl_x, w->ctl_x1, (size_t)m->n_cstate * sizeof(double));
    set_actuators(m, w, y);
    w->ctl_k++;
    w->ctl_next = w->ctl_t0 + (double)(w->ctl_k - w->ctl_k0) * dt;
    if (w->ctl_next >= w->ctl_stop - w->ctl_tol)
        w->ctl_next = INFINITY;
}

/* A fresh controller: block states zero, the first sample next (its delay lines then
 * fill with its readings), the noise from the seed. */
static void restart(const vsj_model *m, vsj_work *w) {
    vsj__control_hold(m, w, NULL);
    memset(w->ctl_x, 0, (size_t)m->n_cstate * sizeof(double));
    memset(w->ctl_bus, 0, (size_t)m->n_bus * sizeof(double));
    w->ctl_rng = (uint64_t)m->ctl[VSJ_CTL_SEED];
    w->ctl_k = 0;
    w->ctl_tol = 1e-9 * m->ctl[VSJ_CTL_PERIOD];
    w->ctl_started = 1;
}

void vsj__control_period(const vsj_model *m, vsj_work *w, const double *y, double dt) {
    int64_t c, a;
    if (!w->ctl_started)
        restart(m, w);
    for (c = 0; c < m->n_channels; c++) /* this model's actuators (the work may have */
        w->ctl_drive[c] = -1;             /* stepped another of the same sizes) */
    for (a = 0; a < m->n_acts; a++)
        w->ctl_drive[m->act_ch[a]] = a;
    w->ctl_on = 1;
    w->ctl_t0 = 0.0;
    w->ctl_k0 = w->ctl_k;
    w->ctl_stop = dt;
    w->ctl_last = -INFINITY;
    vsj__control_sample(m, w, 0.0, y);
}

void vsj_control_reset(vsj_work *w) {
    if (w)
        w->ctl_started = 0;
}

int64_t vsj_control_values(const vsj_model *m, const vsj_work *w, double *out) {
    int64_t width = vsj_control_width(m);
    if (!vsj__fits(m, w) || width == 0)
        return 0;
    memcpy(out, w->ctl_bus, (size_t)m->n_bus * sizeof(double));
    memcpy(out + m->n_bus, w->ctl_u, (size_t)m->n_acts * sizeof(double));
    return width;
}

void vsj__control_hold(const vsj_model *m, vsj_work *w, const double *u) {
    int64_t c, a;
    w->ctl_on = m->n_acts > 0;
    for (c = 0; c < m->n_channels; c++)
        w->ctl_drive[c] = -1;
    for (a = 0; a < m->n_acts; a++) {
        w->ctl_drive[m->act_ch[a]] = a;
        w->ctl_u[a] = u ? u[a] : 0.0;
    }
}

void vsj__control_begin(const vsj_model *m, vsj_work *w, double t0, const double *y) {
    w->ctl_next = INFINITY;
    vsj__control_hold(m, w, NULL);
    if (!w->ctl_on)
        return;
    restart(m, w);
    w->ctl_started = 0; /* a step function's controller starts afresh after a run */
    w->ctl_t0 = t0;
    w->ctl_k0 = 0;
    w->ctl_stop = INFINITY;
    w->ctl_last = -INFINITY;
    vsj__control_sample(m, w, t0, y);
}

void vsj__control_record(const vsj_work *w, double t, double *row) {
    if (!w->ctl_on)
        return;
    if (t < w->ctl_last - w->ctl_tol) { /* inside the step that ended on the last sample */
        memcpy(row, w->ctl_before, (size_t)(w->nbus + w->nact) * sizeof(double));
        return;
    }
    memcpy(row, w->ctl_bus, (size_t)w->nbus * sizeof(double));
    memcpy(row + w->nbus, w->ctl_u, (size_t)w->nact * sizeof(double));
}
