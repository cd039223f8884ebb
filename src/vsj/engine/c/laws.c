/* Element laws: friction (vsj.friction) and springs (vsj.springs).
 *
 * Friction laws give the resistive torque f(s) of a relative speed s, which
 * the element applies against s; every law saturates at the Coulomb level
 * k pi/2 (the report's k read as in section 4.1.3).
 *
 * Spring laws give the torque on the ring (restoring), the stiffness
 * -dtorque/dphi, the stored energy V and dV/dq. The geometric element is that
 * of report section 3.2.1 (eq 3.1-3.8); the potential form differentiates the
 * springs' energy, eq 3.8 is the report's moment balance about the pivot.
 */
#include <math.h>

#include "internal.h"

double vsj_friction_torque(int law, double b, double k, double kb, double w, double s,
                           double *slope) {
    if (law == VSJ_CONTACT) { /* its force needs the penetration: vsj_derivatives */
        if (slope)
            *slope = 0.0;
        return 0.0;
    }
    return vsj__friction(law, b, k, kb, w, s, slope);
}

/* Lever of eq 3.1: sines and cosines of phi and alpha, dalpha/dphi, dalpha/dq,
 * d2alpha/dphi2 and the pin-pivot distance r2. */
typedef struct lever {
    double sp, cp, sa, ca, a_phi, a_q, a_pp, r2;
} lever;

static lever lever_at(double phi, double q, double R) {
    lever l;
    double n, d, r2sq, inv_sq, inv;
    l.sp = sin(phi);
    l.cp = cos(phi);
    n = R * l.sp;
    d = q + R * l.cp;
    r2sq = n * n + d * d;
    inv_sq = 1.0 / r2sq;
    l.r2 = sqrt(r2sq);
    inv = 1.0 / l.r2;
    l.sa = n * inv;
    l.ca = d * inv;
    l.a_phi = R * (R + q * l.cp) * inv_sq;
    l.a_q = -R * l.sp * inv_sq;
    l.a_pp = R * q * l.sp * (R * R - q * q) * inv_sq * inv_sq;
    return l;
}

/* Lever end where spring `side` (+1: a, -1: b) attaches (eq 3.4). */
static void lever_end(double R, double L, double W, const lever *l, double side, double *X,
                      double *Y) {
    *X = R * l->sp - L * l->sa + side * W * l->ca;
    *Y = -R * l->cp + L * l->ca + side * W * l->sa;
}

void vsj_spring_extensions(const double p[VSJ_NPAR], double phi, double q, double out[2]) {
    double R = p[0], L = p[1], W = p[2], x0 = p[3], y0 = p[4], s0 = p[5];
    lever l = lever_at(phi, q, R);
    double Xa, Ya, Xb, Yb;
    lever_end(R, L, W, &l, 1.0, &Xa, &Ya);
    lever_end(R, L, W, &l, -1.0, &Xb, &Yb);
    out[0] = sqrt((Xa - x0) * (Xa - x0) + (Ya - y0) * (Ya - y0)) - s0;
    out[1] = sqrt((Xb + x0) * (Xb + x0) + (Yb - y0) * (Yb - y0)) - s0;
}

/* What to compute of the geometric element: the potential form, eq 3.8, or both. */
enum { POTENTIAL = 1, REPORT = 2 };

static void geometry(const double p[VSJ_NPAR], double phi, double q, int which, double out[6]) {
    double R = p[0], L = p[1], W = p[2], x0 = p[3], y0 = p[4], s0 = p[5], k = p[6];
    lever l = lever_at(phi, q, R);
    double V = 0.0, dV = 0.0, d2V = 0.0, dVq = 0.0, t_sum = 0.0, dt_sum = 0.0;
    int half;
    for (half = 0; half < 2; half++) {
        double side = 1.0 - 2.0 * half; /* spring a (+1), then spring b (-1) */
        /* derivatives of the lever end with u_L = (-sa, ca), u_W = (ca, sa) */
        double lx = -L * l.ca + side * W * (-l.sa);
        double ly = -L * l.sa + side * W * l.ca;
        double X, Y, Xp, Yp, Xq, Yq, ax, gx, gy, ell, inv, e, gxp, gxp_l;
        lever_end(R, L, W, &l, side, &X, &Y);
        ax = side * x0;
        gx = X - ax;
        gy = Y - y0;
        ell = sqrt(gx * gx + gy * gy);
        e = ell - s0;
        if (e <= 0.0)
            continue; /* slack: a spring only pulls */
        inv = 1.0 / ell;
        Xp = R * l.cp + lx * l.a_phi;
        Yp = R * l.sp + ly * l.a_phi;
        Xq = lx * l.a_q;
        Yq = ly * l.a_q;
        gxp = gx * Xp + gy * Yp;
        gxp_l = gxp * inv; /* the spring's rate of extension per unit phi */
        V += 0.5 * k * e * e;
        dVq += k * e * (gx * Xq + gy * Yq) * inv;
        if (which & POTENTIAL) {
            double mx = L * l.sa - side * W * l.ca;
            double my = -L * l.ca - side * W * l.sa;
            double Xpp = -R * l.sp + mx * l.a_phi * l.a_phi + lx * l.a_pp;
            double Ypp = R * l.cp + my * l.a_phi * l.a_phi + ly * l.a_pp;
            dV += k * e * gxp_l;
            d2V += k * (gxp_l * gxp_l
                        + e * ((Xp * Xp + Yp * Yp + gx * Xpp + gy * Ypp) - gxp_l * gxp_l) * inv);
        }
        if (which & REPORT) {
            /* eq 3.5-3.7: moment arm of the spring force about the pivot (0, q) */
            double c = gy * ax - gx * (y0 - q);
            double dc = Yp * ax - Xp * (y0 - q);
            double arm = c * inv;
            double darm = (dc - c * gxp_l * inv) * inv;
            t_sum += k * e * arm;
            dt_sum += k * (gxp_l * arm + e * darm);
        }
    }
    out[0] = V;
    out[1] = dV;
    out[2] = d2V;
    out[3] = dVq;
    out[4] = out[5] = 0.0;
    if (which & REPORT) {
        double scale = R / l.r2; /* sin(alpha) / sin(phi) of eq 3.8 */
        out[4] = t_sum * scale;
        out[5] = dt_sum * scale + t_sum * R * q * R * l.sp / (l.r2 * l.r2 * l.r2);
    }
}

void vsj_spring_geometry(const double p[VSJ_NPAR], double phi, double q, double out[6]) {
    geometry(p, phi, q, POTENTIAL | REPORT, out);
}

int vsj__stop(int64_t law, const double *p, double *angle, double *stiffness) {
    if (law == VSJ_EXPONENTIAL) {
        *angle = p[3];
        *stiffness = p[4];
    } else if (law == VSJ_GEOMETRIC || law == VSJ_GEOMETRIC_REPORT) {
        *angle = p[7];
        *stiffness = p[8];
    } else {
        return 0;
    }
    return *angle > 0.0 && isfinite(*angle) && *stiffness > 0.0;
}

double vsj__spring(int64_t law, const double *p, double phi, double q, double *stiff,
                   double *energy, double *dvdq, double *cache, int with_stop) {
    double tau, k_, en, dvq, stop, k_stop, excess;
    if (law == VSJ_LINEAR) {
        double k = p[0];
        *stiff = k;
        *energy = 0.5 * k * phi * phi;
        *dvdq = 0.0;
        return -k * phi;
    }
    if (law == VSJ_EXPONENTIAL) {
        double growth;
        /* a1 exp(a2 q) depends on the pivot only: cached while q and a1, a2 stay */
        if (cache && cache[0] == q && cache[1] == p[0] && cache[2] == p[1]) {
            growth = cache[3];
        } else {
            growth = p[0] * exp(p[1] * q);
            if (cache) {
                cache[0] = q;
                cache[1] = p[0];
                cache[2] = p[1];
                cache[3] = growth;
            }
        }
        k_ = growth + p[2];
        tau = -k_ * phi;
        en = 0.5 * k_ * phi * phi;
        dvq = 0.5 * growth * p[1] * phi * phi;
        stop = p[3];
        k_stop = p[4];
    } else {
        double g[6];
        geometry(p, phi, q, law == VSJ_GEOMETRIC ? POTENTIAL : REPORT, g);
        if (law == VSJ_GEOMETRIC) {
            tau = -g[1];
            k_ = g[2];
        } else {
            tau = -g[4];
            k_ = g[5];
        }
        en = g[0];
        dvq = g[3];
        stop = p[7];
        k_stop = p[8];
    }
    excess = fabs(phi) - stop;
    /* a rigid stop (infinite stiffness) is a constraint of the time-stepper, not a
     * force: it stores no energy */
    if (with_stop && excess > 0.0 && isfinite(k_stop)) {
        double sign = phi > 0.0 ? 1.0 : -1.0;
        tau -= k_stop * excess * sign;
        k_ += k_stop;
        en += 0.5 * k_stop * excess * excess;
    }
    *stiff = k_;
    *energy = en;
    *dvdq = dvq;
    return tau;
}

int vsj_spring_law(int law, const double par[VSJ_NPAR], double phi, double q, double out[4]) {
    if (law < VSJ_LINEAR || law >= VSJ_N_SPRING_LAWS)
        return VSJ_BAD_ARGUMENT;
    out[0] = vsj__spring(law, par, phi, q, &out[1], &out[2], &out[3], NULL, 1);
    return VSJ_OK;
}
