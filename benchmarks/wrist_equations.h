/* The fig 4.15 wrist's equations written out by hand in C, for the benchmarks'
 * compiled baselines (wrist_rk4.c, wrist_cvodes.c): the same equations as
 * wrist_reference.py (derived there from the kinematics, independently of vsj's
 * network elimination). The constants come in one array, laid out by
 * wrist_reference.constants.
 */
#ifndef WRIST_EQUATIONS_H
#define WRIST_EQUATIONS_H

#include <math.h>

static void fade(double t, double T, double out[3]) {
    double z;
    if (t >= T) {
        out[0] = 1.0;
        out[1] = 0.0;
        out[2] = 0.0;
        return;
    }
    z = t / T;
    out[0] = z * z * z * (10.0 - 15.0 * z + 6.0 * z * z);
    out[1] = 30.0 * z * z * (1.0 - z) * (1.0 - z) / T;
    out[2] = 60.0 * z * (1.0 - z) * (1.0 - 2.0 * z) / (T * T);
}

static double arctan_law(double b, double k, double kb, double s) {
    return b * s + k * atan(kb * s);
}

static void derivatives(double t, const double *y, const double *c, double *dy) {
    double r_rc = c[0], r_sc = c[1], g = c[2], h = c[3], K = c[4];
    const double *Minv = c + 5, *Mu = c + 9;
    double k1 = c[13], kb1 = c[14], x = c[15];
    double bR = c[16], kR = c[17], bC = c[18], kC = c[19], bL = c[20], kL = c[21];
    double bT = c[22], kT = c[23], bD = c[24], kD = c[25], sharp = c[26];
    double A = c[27], om = c[28], T = c[29];
    double e[3], u[2], du[2], F[2], theta_y, f_diff;
    int i;
    fade(t, T, e);
    for (i = 0; i < 2; i++) {
        double phase = om * t + (i == 0 ? 0.25 : -0.25) * 3.14159265358979323846;
        double sn = sin(phase), cs = cos(phase);
        u[i] = A * (e[1] * sn + e[0] * om * cs);
        du[i] = A * (e[2] * sn + 2.0 * e[1] * om * cs - e[0] * om * om * sn);
    }
    theta_y = 0.5 * (g * (y[2] - y[3]) + h * (u[0] - u[1]));
    f_diff = arctan_law(bD, kD, sharp, theta_y);
    for (i = 0; i < 2; i++) {
        double w = y[2 + i], wc = r_rc * w + r_sc * u[i];
        F[i] = -K * y[i];
        F[i] += arctan_law(0.0, k1, kb1, u[i] - wc) * r_rc;              /* mesh, sun */
        F[i] -= arctan_law(0.0, x * k1, kb1 / x, w - wc) * (1.0 - r_rc); /* mesh, ring */
        F[i] -= arctan_law(bR, kR, sharp, w);                            /* ring bearing */
        F[i] -= arctan_law(bC, kC, sharp, wc) * r_rc;                    /* carrier bearing */
        F[i] -= arctan_law(bL, kL, sharp, w);                            /* lever, pivot */
        F[i] -= arctan_law(bT, kT, sharp, wc) * r_rc;                    /* transmission */
        F[i] -= f_diff * g * (i == 0 ? 0.5 : -0.5);                      /* differential */
        F[i] -= Mu[2 * i] * du[0] + Mu[2 * i + 1] * du[1];
    }
    dy[0] = y[2];
    dy[1] = y[3];
    dy[2] = Minv[0] * F[0] + Minv[1] * F[1];
    dy[3] = Minv[2] * F[0] + Minv[3] * F[1];
}

#endif
