/* The fig 4.15 wrist written out by hand in C (wrist_equations.h), integrated by
 * classical RK4 with a fixed step: what an engineer would write by hand for this
 * one model, the benchmark's compiled baseline. Built by benchmarks/run.py with the
 * compiler flags of vsj's own extension.
 */
#include <math.h>

#include "wrist_equations.h"

/* Classical RK4 with step h from rest; the state every `every` steps into out
 * (rows of 4). Returns the number of rows written. */
long rk4(const double *c, double h, double t_end, long every, double *out) {
    long steps = lround(t_end / h), n, rows = 1;
    double y[4] = {0.0, 0.0, 0.0, 0.0}, k1[4], k2[4], k3[4], k4[4], yt[4];
    int i;
    for (i = 0; i < 4; i++)
        out[i] = y[i];
    for (n = 0; n < steps; n++) {
        double t = (double)n * h;
        derivatives(t, y, c, k1);
        for (i = 0; i < 4; i++)
            yt[i] = y[i] + 0.5 * h * k1[i];
        derivatives(t + 0.5 * h, yt, c, k2);
        for (i = 0; i < 4; i++)
            yt[i] = y[i] + 0.5 * h * k2[i];
        derivatives(t + 0.5 * h, yt, c, k3);
        for (i = 0; i < 4; i++)
            yt[i] = y[i] + h * k3[i];
        derivatives(t + h, yt, c, k4);
        for (i = 0; i < 4; i++)
            y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        if ((n + 1) % every == 0) {
            for (i = 0; i < 4; i++)
                out[4 * rows + i] = y[i];
            rows++;
        }
    }
    return rows;
}
