/* Cost of the step function called from C: the estimator's loop, timed.
 *
 *     step_loop MODEL.json INPUTS.csv REPEATS
 *
 * Steps the model over every line of INPUTS.csv (one period each, the inputs
 * changing every period), REPEATS times from the model's initial state, and
 * prints the best time per period in nanoseconds and the final state. Built
 * and run by benchmarks/step_cost.py.
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "vsj.h"

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv) {
    char message[512], line[4096];
    vsj_loaded *w;
    vsj_work *work;
    FILE *file;
    double *U = NULL, *state, best = 1e300;
    long rows = 0, cap = 0, r, k, repeats;
    int64_t size, j;
    if (argc != 4) {
        fprintf(stderr, "usage: step_loop MODEL.json INPUTS.csv REPEATS\n");
        return 2;
    }
    if (!(w = vsj_load_model(argv[1], message, sizeof message))) {
        fprintf(stderr, "step_loop: %s\n", message);
        return 2;
    }
    if (!(file = fopen(argv[2], "r"))) {
        fprintf(stderr, "step_loop: cannot open %s\n", argv[2]);
        return 2;
    }
    while (fgets(line, sizeof line, file)) {
        char *at = line, *end;
        if (rows == cap) {
            cap = cap ? 2 * cap : 1024;
            U = realloc(U, (size_t)(cap * w->n_inputs) * sizeof(double));
        }
        for (j = 0; j < w->n_inputs; j++) {
            while (*at == ',' || *at == ' ')
                at++;
            U[rows * w->n_inputs + j] = strtod(at, &end);
            at = end;
        }
        rows++;
    }
    fclose(file);
    repeats = strtol(argv[3], NULL, 10);
    size = vsj_step_state_size(&w->model);
    work = vsj_work_new(&w->model);
    state = malloc((size_t)size * sizeof(double));
    for (r = 0; r < repeats; r++) {
        double start;
        int status = VSJ_OK;
        memcpy(state, w->initial_state, (size_t)size * sizeof(double));
        if (w->scheme.method == VSJ_METHOD_TIMESTEP)
            vsj_ts_prepare(&w->model, work); /* each round from a cleared stick history */
        start = now();
        for (k = 0; k < rows && status == VSJ_OK; k++) {
            const double *u = U + k * w->n_inputs;
            status = vsj_step(&w->model, work, &w->scheme, state, u, w->period, NULL);
        }
        if (status != VSJ_OK) {
            fprintf(stderr, "step_loop: %s\n", vsj_status_text(status));
            return 1;
        }
        if ((now() - start) / (double)rows < best)
            best = (now() - start) / (double)rows;
    }
    printf("%.1f", best * 1e9);
    for (j = 0; j < size; j++)
        printf(" %.17g", state[j]);
    printf("\n");
    free(U);
    free(state);
    vsj_work_free(work);
    vsj_free_loaded(w);
    return 0;
}
