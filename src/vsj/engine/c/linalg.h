/* Small dense linear algebra for the time-stepper and its impulse solver: the
 * Cholesky factor of a symmetric positive definite matrix and the triangular
 * solves with it, and the square-root-free L D L^T factor for matrices that are only
 * solved with. Each works on the leading k x k block of a row-major n x n array (the
 * L D L^T factor: the whole n x n), so that one allocation serves problems of every
 * size up to n.
 *
 * They are inline (VSJ_ALWAYS_INLINE): their sizes are the coordinates' count, two
 * on the wrist, and a caller compiled for a constant size (timestep.c, impulses.c)
 * gets them as straight-line code rather than as loops of one or two turns. Included
 * by internal.h; the other dense algebra is in linalg.c. */
#ifndef VSJ_LINALG_H
#define VSJ_LINALG_H

#include <math.h>
#include <stdint.h>

/* The Cholesky factor L of H (0 if H is not positive definite; with `floor` a pivot
 * at or below zero is replaced by a tiny positive one instead). */
VSJ_ALWAYS_INLINE int vsj__cholesky(const double *H, double *L, int64_t k, int64_t n,
                                    int floor) {
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

/* L out = b (out may be b) */
VSJ_ALWAYS_INLINE void vsj__forward(const double *L, const double *b, double *out, int64_t k,
                                    int64_t n) {
    int64_t i, r;
    for (i = 0; i < k; i++) {
        double acc = b[i];
        for (r = 0; r < i; r++)
            acc -= L[n * i + r] * out[r];
        out[i] = acc / L[n * i + i];
    }
}

/* L Y = B for `cols` right-hand sides at once: B and Y n x cols, rows `ld` apart (each
 * column as vsj__forward solves it, to the bit). */
VSJ_ALWAYS_INLINE void vsj__forward_block(const double *L, const double *B, double *Y,
                                          int64_t cols, int64_t ld, int64_t n) {
    int64_t i, r, a;
    for (i = 0; i < n; i++) {
        double *y = Y + ld * i, pivot = L[n * i + i];
        const double *b = B + ld * i;
        for (a = 0; a < cols; a++)
            y[a] = b[a];
        for (r = 0; r < i; r++) {
            const double *yr = Y + ld * r;
            double l = L[n * i + r];
            for (a = 0; a < cols; a++)
                y[a] -= l * yr[a];
        }
        for (a = 0; a < cols; a++)
            y[a] /= pivot;
    }
}

/* L^T out = b; out may be b */
VSJ_ALWAYS_INLINE void vsj__backward(const double *L, const double *b, double *out, int64_t k,
                                     int64_t n) {
    int64_t i, r;
    for (i = k - 1; i >= 0; i--) {
        double acc = b[i];
        for (r = i + 1; r < k; r++)
            acc -= L[n * r + i] * out[r];
        out[i] = acc / L[n * i + i];
    }
}

/* H = L D L^T, for the systems that are only solved (vsj__ldl_solve): no square roots
 * on the way, where Cholesky's would lengthen the chain of dependent operations. F
 * holds L's strict lower triangle, the reciprocals of D on its diagonal, and in its
 * strict upper triangle the products L D that the factorisation works with. A pivot at
 * or below zero becomes a tiny positive one (vsj__cholesky's `floor`). */
VSJ_ALWAYS_INLINE void vsj__ldl(const double *H, double *F, int64_t n) {
    int64_t i, j, r;
    for (i = 0; i < n; i++) {
        double d = H[n * i + i];
        for (j = 0; j < i; j++) {
            double u = H[n * i + j];
            for (r = 0; r < j; r++)
                u -= F[n * r + i] * F[n * j + r]; /* (L D)_ir L_jr */
            F[n * j + i] = u;                     /* (L D)_ij */
            F[n * i + j] = u * F[n * j + j];      /* L_ij */
            d -= u * F[n * i + j];
        }
        F[n * i + i] = 1.0 / (d <= 0.0 ? 1e-300 : d);
    }
}

/* H out = b with vsj__ldl's factor F of H (out may be b) */
VSJ_ALWAYS_INLINE void vsj__ldl_solve(const double *F, const double *b, double *out, int64_t n) {
    int64_t i, r;
    for (i = 0; i < n; i++) {
        double acc = b[i];
        for (r = 0; r < i; r++)
            acc -= F[n * i + r] * out[r];
        out[i] = acc;
    }
    for (i = n - 1; i >= 0; i--) {
        double acc = out[i] * F[n * i + i];
        for (r = i + 1; r < n; r++)
            acc -= F[n * r + i] * out[r];
        out[i] = acc;
    }
}

/* H out = b with H's factor L (k = n) */
VSJ_ALWAYS_INLINE void vsj__solve(const double *L, const double *b, double *out, int64_t n) {
    vsj__forward(L, b, out, n, n);
    vsj__backward(L, out, out, n, n);
}

#endif
