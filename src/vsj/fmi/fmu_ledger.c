/* The energy ledger of a run of vsj's FMU (see vsj_fmu.c), from initialization
 * to fmi2Terminate, kept as vsj.simulate.ledger keeps a run's: the work each step
 * books, the energy stored at the start and now, and the energy the importer puts
 * in between steps.
 */
#include <math.h>
#include <string.h>

#include "fmu_internal.h"

/* Deflection [rad] of spring k in stepper state s. */
double fmu__deflection(const fmu *f, const double *s, int64_t k) {
    const vsj_model *m = &f->model;
    int64_t r = m->n_frictions + k, i;
    double value = 0.0;
    for (i = m->xp[r]; i < m->xp[r + 1]; i++)
        value += m->xv[i] * s[m->xc[i]];
    for (i = m->up[r]; i < m->up[r + 1]; i++)
        value += m->uv[i] * s[2 * m->n + m->n_motors + m->uc[i]];
    return value;
}

/* Kinetic energy [J] of stepper state s with the source speeds of `inputs`. */
static double kinetic(fmu *f, const double *s, const double *inputs) {
    const vsj_model *m = &f->model;
    int64_t n = m->n, sz = n + m->n_sources, i, r;
    double energy = 0.0;
    vsj_step_speeds(m, s, inputs, f->speeds);
    for (i = 0; i < sz; i++) {
        double a = i < n ? f->speeds[i] : inputs[m->src_ch[i - n]];
        for (r = 0; r < sz; r++)
            energy += 0.5 * a * m->mass[sz * i + r]
                      * (r < n ? f->speeds[r] : inputs[m->src_ch[r - n]]);
    }
    return energy;
}

/* Kinetic, spring and inductor energy [J] of the current state, as vsj_stored_energy
 * gives them; `springs` (n_springs) receives each spring's. */
void fmu__stored(fmu *f, const double *inputs, double energy[3], double *springs) {
    const vsj_model *m = &f->model;
    int64_t k, mo, base = m->n_frictions + m->n_springs + m->n_loads;
    double q = vsj_step_pivot_position(m, f->s), law[4];
    energy[0] = kinetic(f, f->s, inputs);
    energy[1] = 0.0;
    energy[2] = 0.0;
    for (k = 0; k < m->n_springs; k++) {
        int64_t row = m->n_frictions + k;
        vsj_spring_law((int)m->code[row], f->par + VSJ_NPAR * row,
                       fmu__deflection(f, f->s, k), q, law);
        springs[k] = law[2];
        energy[1] += law[2];
    }
    for (mo = 0; mo < m->n_motors; mo++) {
        double current = f->s[2 * m->n + mo];
        energy[2] += 0.5 * f->par[VSJ_NPAR * (base + mo) + 1] * current * current;
    }
}

/* A run starts: the ledger's totals cleared, the energy at the start and the
 * inputs taken, nothing warned about yet. */
void fmu__start_run(fmu *f) {
    memset(f->record, 0, (size_t)f->at.size * sizeof(double));
    fmu__stored(f, f->inputs, f->record + f->at.start, f->record + f->at.springs);
    memcpy(f->record + f->at.applied, f->inputs, (size_t)f->ni * sizeof(double));
    memcpy(f->record + f->at.reference, f->inputs, (size_t)f->ni * sizeof(double));
}

/* Held source speeds that jump between steps change the kinetic energy, work that
 * no step's integrator sees. With the momenta p of the free coordinates, the
 * kinetic energy is p' Minv p / 2 + u' S u / 2 (S: the sources' own inertia,
 * f->schur), and a jump of u leaves p as it is: so the jumps of a run add up to
 * the change of u' S u / 2 from the inputs at its start to those of its last
 * step, put in by the importer, as long as S stays. [J] */
static double source_energy(const fmu *f, const double *inputs) {
    const vsj_model *m = &f->model;
    int64_t ns = m->n_sources, a, b;
    double energy = 0.0;
    for (a = 0; a < ns; a++)
        for (b = 0; b < ns; b++)
            energy += 0.5 * inputs[m->src_ch[a]] * f->schur[ns * a + b] * inputs[m->src_ch[b]];
    return energy;
}

double fmu__source_jumps(const fmu *f) {
    return source_energy(f, f->record + f->at.applied)
           - source_energy(f, f->record + f->at.reference);
}

/* Energy that the importer puts in between steps, no integrator seeing it: held
 * source speeds that jumped (fmu__source_jumps), or a parameter changed. It moves the
 * run's energy at the start, as if the run had started with it, so that the ledger
 * weighs what the steps did. `before` and `after` are the stored energies (3
 * values, then one per spring) either side of the change. */
void fmu__shift_start(fmu *f, const double *before, const double *after) {
    int64_t k, nk = f->model.n_springs;
    for (k = 0; k < 3; k++)
        f->record[f->at.start + k] += after[k] - before[k];
    for (k = 0; k < nk; k++)
        f->record[f->at.springs + k] += after[3 + k] - before[3 + k];
}

/* The work put in and the work lost in ledger values v (a step's or the run's), and
 * the sums of their terms' sizes: sums = {in, lost, |in|, |lost|}. In: the sources, loads
 * and motor supplies, and a moving pivot's work on the springs; lost: friction, armature
 * resistance and the end stops. The springs' own work is stored, neither. */
static void in_and_lost(const fmu *f, const double *v, double sums[4]) {
    const vsj_model *m = &f->model;
    int64_t nk = m->n_springs, i, at = m->n_sources + m->n_loads + m->n_motors;
    double pivot = 0.0;
    sums[0] = sums[1] = sums[2] = sums[3] = 0.0;
    for (i = 0; i < at; i++) {
        sums[0] += v[i];
        sums[2] += fabs(v[i]);
    }
    for (; i < at + m->n_frictions + m->n_motors; i++) {
        sums[1] += v[i];
        sums[3] += fabs(v[i]);
    }
    at = i + nk; /* past the springs' own work: the pivot's on them, then their stops' */
    for (i = 0; i < nk; i++)
        pivot += v[at + i];
    if (pivot_row(f)[2] > 0.0) {
        sums[0] += pivot;
        sums[2] += fabs(pivot);
    }
    for (i = 0; i < nk; i++) {
        sums[1] += v[at + nk + i];
        sums[3] += fabs(v[at + nk + i]);
    }
}

/* The energy ledger of the run so far, as vsj.simulate.ledger keeps a run's:
 * the residual of work in = stored change + dissipated, and the energy in play. */
void fmu__run_ledger(fmu *f, double *residual, double *scale) {
    const vsj_model *m = &f->model;
    int64_t nf = m->n_frictions, nk = m->n_springs, i;
    int64_t at = m->n_sources + m->n_loads + m->n_motors + nf + m->n_motors;
    const double *total = f->record + f->at.totals, *start = f->record + f->at.start;
    const double *start_springs = f->record + f->at.springs;
    double *now = f->energy, *springs = f->energy + 3, change, held, kinetic0, sums[4];
    fmu__stored(f, f->record + f->at.applied, now, springs);
    in_and_lost(f, total, sums);
    /* eq 3.8 is not a potential force: what its spring does not store is lost */
    for (i = 0; i < nk; i++)
        if (m->code[nf + i] == VSJ_GEOMETRIC_REPORT)
            sums[1] += total[at + nk + i] - total[at + i] - (springs[i] - start_springs[i])
                       - total[at + 2 * nk + i];
    kinetic0 = start[0] + fmu__source_jumps(f);
    change = (now[0] - kinetic0) + (now[1] - start[1]) + (now[2] - start[2]);
    held = fmax(fabs(kinetic0) + fabs(start[1]) + fabs(start[2]),
                fabs(now[0]) + fabs(now[1]) + fabs(now[2]));
    *residual = sums[0] - change - sums[1];
    *scale = fmax(fmax(fmax(sums[2], sums[3]), fmax(fabs(change), held)), 1e-300);
}

/* A step of length h taken: its ledger (in f->ledger) becomes the booked one and is
 * added to the run's. Its power outputs wait for fmu__powers: an importer that reads
 * them at every step pays for their sums then, one that does not never does. */
void fmu__book(fmu *f, double h) {
    double *step = f->ledger, *total = f->record + f->at.totals;
    int64_t i;
    f->ledger = f->booked;
    f->booked = step;
    f->booked_h = h;
    for (i = 0; i < f->nacc; i++)
        total[i] += step[i];
}

/* The power outputs of the booked step, if not yet worked out: the work put in
 * (sources, loads, motor supplies, a moving pivot's on the springs) and the work lost
 * (friction, armature resistance, end stops), each over the step's length. */
void fmu__powers(fmu *f) {
    double sums[4];
    if (!(f->booked_h > 0.0))
        return;
    in_and_lost(f, f->booked, sums);
    f->power_in = sums[0] / f->booked_h;
    f->power_dissipated = sums[1] / f->booked_h;
    f->booked_h = 0.0;
}
