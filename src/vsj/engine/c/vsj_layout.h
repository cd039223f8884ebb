/*
 * The compiled model's layout, declared once.
 *
 * Every size and every array of `vsj_model` is one line of the tables below.
 * The struct (vsj.h), the Python binding (its constructor and the names it
 * gives Python), the checks of sizes, the binary model files that `vsj
 * export-model` and the FMU carry (blob.c) and their reader all expand these
 * tables with the preprocessor, so adding an array is one line here (the
 * MuJoCo way: its mjxmacro.h does the same for mjModel).
 *
 * VSJ_SIZES(X): X(name, description)
 * VSJ_ARRAYS(X): X(name, kind, count, description); kind is VSJ_REAL (double)
 *   or VSJ_INT (int64_t); count is an expression of the model M whose arrays
 *   earlier in the table are already set (the CSR columns count what their
 *   pointers say).
 */
#ifndef VSJ_LAYOUT_H
#define VSJ_LAYOUT_H

#define VSJ_SIZES(X)                                                                    \
    X(n, "generalised coordinates (free flanges after the constraints are eliminated)") \
    X(n_sources, "velocity sources")                                                    \
    X(n_frictions, "friction elements")                                                 \
    X(n_springs, "springs")                                                             \
    X(n_loads, "external torques")                                                      \
    X(n_motors, "DC motors")                                                            \
    X(n_channels, "input channels")                                                     \
    X(n_rows, "element rows: frictions, springs, loads, motors, then the pivot")        \
    X(n_pieces, "cubic spline pieces of all input channels")                            \
    X(n_table, "rows of the friction tables")                                          \
    X(n_refs, "controller: reference channels")                                          \
    X(n_meas, "controller: measured signals (sensors)")                                  \
    X(n_blocks, "controller: blocks (PID, discrete linear system)")                      \
    X(n_acts, "controller: actuators (input channels it drives)")                        \
    X(n_bus, "controller: signals on its bus: references, measurements, blocks' outputs") \
    X(n_cstate, "controller: states of its blocks")                                      \
    X(n_delay, "controller: samples its sensors' delay lines hold")                      \
    X(n_blk_in, "controller: input rows of all blocks")                                  \
    X(n_blk_par, "controller: parameters of all blocks")

#define VSJ_ARRAYS(X)                                                                          \
    X(mass, VSJ_REAL, (M->n + M->n_sources) * (M->n + M->n_sources),                           \
      "kinetic energy matrix over (v, u), row-major")                                          \
    X(Minv, VSJ_REAL, M->n * M->n, "inverse of the mass matrix's free block")                  \
    X(xp, VSJ_INT, M->n_rows + 1, "CSR pointers of the rows' free-coordinate part")            \
    X(xc, VSJ_INT, M->xp[M->n_rows], "their columns (< n)")                                    \
    X(xv, VSJ_REAL, M->xp[M->n_rows], "their values")                                          \
    X(up, VSJ_INT, M->n_rows + 1, "CSR pointers of the rows' source part")                     \
    X(uc, VSJ_INT, M->up[M->n_rows], "their columns (< n_sources)")                            \
    X(uv, VSJ_REAL, M->up[M->n_rows], "their values")                                          \
    X(par, VSJ_REAL, M->n_rows * VSJ_NPAR, "parameters of each row (see vsj.h)")               \
    X(code, VSJ_INT, M->n_rows, "law of each friction and spring row, input channel of each "  \
      "load and motor row, 0 for the pivot")                                                   \
    X(src_ch, VSJ_INT, M->n_sources, "input channel of each velocity source")                 \
    X(src_pos0, VSJ_REAL, M->n_sources, "source angles at t = 0")                             \
    X(knots, VSJ_REAL, M->n_pieces + M->n_channels,                                            \
      "knots of channel c at first[c] + c + j")                                                \
    X(coef, VSJ_REAL, 4 * M->n_pieces, "cubic coefficients of each piece")                     \
    X(cum, VSJ_REAL, M->n_pieces + M->n_channels,                                              \
      "integral of each channel from its first knot to each knot")                             \
    X(first, VSJ_INT, M->n_channels, "each channel's first spline piece")                      \
    X(count, VSJ_INT, M->n_channels, "each channel's number of pieces")                        \
    X(period, VSJ_REAL, 2 * M->n_channels,                                                     \
      "each channel's period once it repeats (0: it does not; its pieces end with one "        \
      "period) and its integral over one period")                                              \
    X(table, VSJ_REAL, 2 * M->n_table, "friction tables: rows of (slip speed, coefficient)")   \
    X(ctl, VSJ_REAL, M->n_acts > 0 ? VSJ_NCTL : 0,                                             \
      "controller: sample period [s], noise seed (control.c); none without actuators")        \
    X(ref_ch, VSJ_INT, M->n_refs, "input channel of each reference")                          \
    X(meas_kind, VSJ_INT, M->n_meas, "what each sensor measures (enum vsj_sensor)")           \
    X(meas_row, VSJ_REAL, M->n_meas * (M->n + M->n_sources),                                   \
      "sensor's angle (speed) as a row over the generalised and the source angles (speeds)")  \
    X(meas_par, VSJ_REAL, M->n_meas * VSJ_NMEAS,                                               \
      "sensor's resolution, noise, delay, motor (enum vsj_meas_par)")                         \
    X(blk, VSJ_INT, M->n_blocks * VSJ_NBLK, "each block's kind and sizes (enum vsj_blk)")     \
    X(blk_in, VSJ_REAL, M->n_blk_in * M->n_bus, "block inputs: rows over the bus")            \
    X(blk_par, VSJ_REAL, M->n_blk_par, "blocks' parameters (PID: enum vsj_pid; linear: A, B, " \
      "C, D row-major)")                                                                       \
    X(act_ch, VSJ_INT, M->n_acts, "input channel each actuator drives (a load or a motor)")   \
    X(act_row, VSJ_REAL, M->n_acts * M->n_bus, "each actuator's command as a row over the bus") \
    X(act_par, VSJ_REAL, M->n_acts * VSJ_NACT, "actuator's offset and limits (enum vsj_act)")

/* The laws, each one line, its code its place in the table (from 0):
 * X(NAME, name, description); the enums vsj_friction_law and vsj_spring_law (vsj.h)
 * and the names Python gives them (vsj.friction.LAWS, vsj.springs) follow from it.
 * A law's evaluation is in laws.c. */
#define VSJ_FRICTION_LAWS(X)                                                            \
    X(VISCOUS, "viscous", "b s")                                                        \
    X(ARCTAN, "arctan", "b s + k atan(k_b s), report eq 3.17")                          \
    X(SIGN, "sign", "b s + k pi/2 sign(s), eq 3.18")                                    \
    X(SLOPE, "slope", "b s + k pi/2 clip(s / w, -1, 1), fig 4.8")                       \
    X(STICTION, "stiction", "b s plus a Coulomb impulse decided by the time-stepper")      \
    X(CONTACT, "contact", "Hunt-Crossley contact: max(0, k d^n + lambda d^n s) for a "    \
      "penetration d > 0 (the row's position past its gap), 0 apart")

#define VSJ_SPRING_LAWS(X)                                                              \
    X(LINEAR, "linear", "par: k")                                                       \
    X(EXPONENTIAL, "exponential", "par: a1, a2, a3, phi_stop, k_stop (eq 4.5)")         \
    X(GEOMETRIC, "geometric", "par: R, L, W, x0, y0, s0, k, phi_stop, k_stop: -dV/dphi") \
    X(GEOMETRIC_REPORT, "geometric-report", "same parameters, the ring torque of eq 3.8")

#define VSJ_REAL 0
#define VSJ_INT 1

#endif /* VSJ_LAYOUT_H */
