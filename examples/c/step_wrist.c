/* step_wrist: a controller's loop around the vsj engine, in plain C.
 *
 * Loads a wrist written by `vsj export-model` and advances it one control
 * period at a time with the inputs it sets, as an estimator or a controller
 * on the robot would. Prints one CSV row per period: the time, every output
 * of the model file (angles, in rad) and the pivot position q (m).
 *
 * Build it with the engine's C files (src/vsj/engine/c; nothing else is
 * needed), from the repository root:
 *     cc -std=c99 -O2 -I src/vsj/engine/c -o step_wrist examples/c/step_wrist.c \
 *        src/vsj/engine/c/[a-z]*.c -lm
 * Run:
 *     vsj export-model --out wrist.vsjm --q=-1cm
 *     ./step_wrist wrist.vsjm 1000 inputs.csv > outputs.csv
 *
 * inputs.csv (optional) holds one line per period with a value for each input
 * channel, in the order the model file lists them (commas or spaces between);
 * after its last line the last inputs are held. Without it the inputs are 0.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vsj.h"

/* Reads the next line of inputs into u (n values); returns 1 if it did. */
static int read_inputs(FILE *file, double *u, int64_t n) {
    char line[4096], *at, *end;
    int64_t k;
    if (!file || !fgets(line, sizeof line, file))
        return 0;
    at = line;
    for (k = 0; k < n; k++) {
        while (*at == ',' || *at == ' ' || *at == '\t')
            at++;
        u[k] = strtod(at, &end);
        if (end == at) {
            fprintf(stderr, "step_wrist: an input line needs %lld values\n", (long long)n);
            exit(2);
        }
        at = end;
    }
    return 1;
}

static void print_row(const vsj_loaded *w, double t, const double *s) {
    int64_t k, j, size = vsj_step_state_size(&w->model);
    printf("%.17g", t);
    for (k = 0; k < w->n_outputs; k++) {
        double value = 0.0;
        for (j = 0; j < size; j++)
            value += w->output_rows[k * size + j] * s[j];
        printf(",%.17g", value);
    }
    printf(",%.17g\n", vsj_step_pivot_position(&w->model, s));
}

int main(int argc, char **argv) {
    char message[512];
    vsj_loaded *wrist;
    vsj_work *work;
    double *state, *inputs;
    FILE *input_file = NULL;
    long periods, p;
    int64_t k, status = VSJ_OK;
    if (argc < 3) {
        fprintf(stderr, "usage: step_wrist MODEL.vsjm PERIODS [INPUTS.csv]\n");
        return 2;
    }
    wrist = vsj_load_model(argv[1], message, sizeof message);
    if (!wrist) {
        fprintf(stderr, "step_wrist: %s\n", message);
        return 2;
    }
    periods = strtol(argv[2], NULL, 10);
    if (argc > 3 && !(input_file = fopen(argv[3], "r"))) {
        fprintf(stderr, "step_wrist: cannot open %s\n", argv[3]);
        vsj_free_loaded(wrist);
        return 2;
    }
    /* the model is plain data; the run-time state lives in a work of its own */
    work = vsj_work_new(&wrist->model);
    state = malloc((size_t)vsj_step_state_size(&wrist->model) * sizeof(double));
    inputs = calloc((size_t)wrist->n_inputs + 1, sizeof(double));
    if (!work || !state || !inputs) {
        fprintf(stderr, "step_wrist: out of memory\n");
        return 1;
    }
    memcpy(state, wrist->initial_state,
           (size_t)vsj_step_state_size(&wrist->model) * sizeof(double));

    printf("time [s]");
    for (k = 0; k < wrist->n_outputs; k++)
        printf(",%s [rad]", wrist->output_names[k]);
    printf(",q [m]\n");
    print_row(wrist, 0.0, state);
    for (p = 0; p < periods && status == VSJ_OK; p++) {
        read_inputs(input_file, inputs, wrist->n_inputs); /* else: hold the last ones */
        status = vsj_step(&wrist->model, work, &wrist->scheme, state, inputs, wrist->period,
                          NULL);
        if (status == VSJ_OK)
            print_row(wrist, (double)(p + 1) * wrist->period, state);
    }
    if (status != VSJ_OK)
        fprintf(stderr, "step_wrist: period %ld failed: %s\n", p, vsj_status_text((int)status));
    if (input_file)
        fclose(input_file);
    free(state);
    free(inputs);
    vsj_work_free(work);
    vsj_free_loaded(wrist);
    return status == VSJ_OK ? 0 : 1;
}
