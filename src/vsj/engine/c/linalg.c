/* Dense linear algebra: the LU factorisation of a general matrix (the Rosenbrock
 * steps' I/(gamma h) - J), and the tridiagonal solve behind the input splines
 * (vsj.inputs.spline_pieces). The Cholesky kernels of the time-stepper are inline,
 * in linalg.h. */
#include <math.h>

#include "internal.h"

int vsj_solve_tridiagonal(int64_t n, double *dl, double *d, double *du, double *du2, double *b) {
    int64_t i;
    for (i = 0; i + 1 < n; i++) {
        if (fabs(d[i]) >= fabs(dl[i])) { /* the pivot stays on the diagonal */
            double f;
            if (d[i] == 0.0)
                return -1;
            f = dl[i] / d[i];
            d[i + 1] -= f * du[i];
            b[i + 1] -= f * b[i];
            if (i + 2 < n)
                du2[i] = 0.0;
        } else { /* rows i and i + 1 exchanged: row i + 1 is the pivot row */
            double f = d[i] / dl[i], next_d = d[i + 1], old_b = b[i];
            d[i] = dl[i];
            d[i + 1] = du[i] - f * next_d;
            du[i] = next_d;
            if (i + 2 < n) {
                du2[i] = du[i + 1];
                du[i + 1] = -f * du2[i];
            }
            b[i] = b[i + 1];
            b[i + 1] = old_b - f * b[i + 1];
        }
    }
    if (n < 1 || d[n - 1] == 0.0)
        return -1;
    b[n - 1] /= d[n - 1];
    if (n > 1)
        b[n - 2] = (b[n - 2] - du[n - 2] * b[n - 1]) / d[n - 2];
    for (i = n - 3; i >= 0; i--)
        b[i] = (b[i] - du[i] * b[i + 1] - du2[i] * b[i + 2]) / d[i];
    return 0;
}

int vsj__lu(double *A, int64_t *piv, int64_t n) {
    int64_t i, j, r;
    for (j = 0; j < n; j++) {
        int64_t best = j;
        for (i = j + 1; i < n; i++)
            if (fabs(A[n * i + j]) > fabs(A[n * best + j]))
                best = i;
        piv[j] = best;
        if (A[n * best + j] == 0.0 || !isfinite(A[n * best + j]))
            return 0;
        if (best != j)
            for (r = 0; r < n; r++) {
                double tmp = A[n * j + r];
                A[n * j + r] = A[n * best + r];
                A[n * best + r] = tmp;
            }
        for (i = j + 1; i < n; i++) {
            double l = A[n * i + j] / A[n * j + j];
            A[n * i + j] = l;
            for (r = j + 1; r < n; r++)
                A[n * i + r] -= l * A[n * j + r];
        }
    }
    return 1;
}

void vsj__lu_solve(const double *LU, const int64_t *piv, const double *b, double *x, int64_t n) {
    int64_t i, r;
    if (x != b)
        for (i = 0; i < n; i++)
            x[i] = b[i];
    for (i = 0; i < n; i++) { /* the row swaps in order, then L */
        double tmp = x[piv[i]];
        x[piv[i]] = x[i];
        x[i] = tmp;
    }
    for (i = 0; i < n; i++)
        for (r = 0; r < i; r++)
            x[i] -= LU[n * i + r] * x[r];
    for (i = n - 1; i >= 0; i--) {
        for (r = i + 1; r < n; r++)
            x[i] -= LU[n * i + r] * x[r];
        x[i] /= LU[n * i + i];
    }
}
