/* Small dense linear algebra for the time-stepper and its impulse solver: the
 * Cholesky factor of a symmetric positive definite matrix and the triangular
 * solves with it. Each works on the leading k x k block of a row-major n x n
 * array, so that one allocation serves problems of every size up to n. */
#include <math.h>

#include "internal.h"

int vsj__cholesky(const double *H, double *L, int64_t k, int64_t n, int floor) {
    int64_t i, j, r;
    for (i = 0; i < k; i++)
        for (j = 0; j <= i; j++) {
            double acc = H[n * i + j];
            for (r = 0; r < j; r++)
                acc -= L[n * i + r] * L[n * j + r];
            if (i == j) {
                if (acc <= 0.0) {
                    if (!floor)
                        return 0;
                    acc = 1e-300;
                }
                L[n * i + i] = sqrt(acc);
            } else {
                L[n * i + j] = acc / L[n * j + j];
            }
        }
    return 1;
}

void vsj__forward(const double *L, const double *b, double *out, int64_t k, int64_t n) {
    int64_t i, r;
    for (i = 0; i < k; i++) {
        double acc = b[i];
        for (r = 0; r < i; r++)
            acc -= L[n * i + r] * out[r];
        out[i] = acc / L[n * i + i];
    }
}

/* L^T out = b; out may be b */
void vsj__backward(const double *L, const double *b, double *out, int64_t k, int64_t n) {
    int64_t i, r;
    for (i = k - 1; i >= 0; i--) {
        double acc = b[i];
        for (r = i + 1; r < k; r++)
            acc -= L[n * r + i] * out[r];
        out[i] = acc / L[n * i + i];
    }
}

void vsj__solve(const double *L, const double *b, double *out, int64_t n) {
    vsj__forward(L, b, out, n, n);
    vsj__backward(L, out, out, n, n);
}
