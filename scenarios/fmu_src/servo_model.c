/* The servo-loop plant of fdd-campaign (PHYSICS §3). See servo_model.h.
 *
 * Rod speed, turbulent servo-valve flow with the adjacent actuator in damping mode
 * ([COMB] eq. 1-2, [CHEN] eq. 11):
 *     xdot = Kci·i·sqrt( clip(S·ΔP − sign(i)·F_aero, 0, 2·S·ΔP) / (S·ΔP_ref + Ka·(Kci·i)²) )
 * with the rod held inside the mechanical stops. Hinge moment and rod force (PHYSICS §3):
 *     HM = hm_0 + hm_delta·δ,   F_aero = −HM / (r·cos δ),   δ = asin(x/r).
 * A communication step h is integrated in n = ceil(h / h_max_s) equal sub-steps, each one
 * classical RK4 step with the current held (scenarios/servo.py rk4_step); h_max_s is a
 * parameter whose start value is the FCC period Ts = 0.01 s the model was designed for
 * (docs/physics.md §2), so a step of Ts is exactly one RK4 step, as in the built-in plant,
 * and longer communication steps (other tools) converge to the same trajectory.
 * Solid jam: the rod keeps its position ([CHEN] eq. 4). Disconnection: the rod is unloaded
 * and the surface floats, held only by the damping neighbour ([CHEN] eq. 5); the closed
 * form of scenarios/servo.py float_step advances it. */
#include <math.h>
#include "servo_model.h"
#include "servo_start.h"   /* start values, generated from scenarios/params.py at build */

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#define MM_PER_M 1000.0
#define P(s, vr) ((s)->par[(vr)])

static double sign_of(double v) {
    if (v > 0.0) return 1.0;
    if (v < 0.0) return -1.0;
    return v;                      /* 0 stays 0 and NaN stays NaN, as numpy.sign */
}

static double clip(double v, double lo, double hi) {
    if (v < lo) return lo;
    if (v > hi) return hi;
    return v;                      /* NaN passes through, as numpy.clip */
}

void servo_defaults(ServoState *s) {
    int k;
    for (k = 0; k < SERVO_N_PAR; k++) s->par[k] = 0.0;
    P(s, VR_KCI) = START_KCI;
    P(s, VR_SDP) = START_SDP;
    P(s, VR_SDP_REF) = START_SDP_REF;
    P(s, VR_KA) = START_KA;
    P(s, VR_R_MM) = START_R_MM;
    P(s, VR_X_MIN) = START_X_MIN;
    P(s, VR_X_MAX) = START_X_MAX;
    P(s, VR_HM_DELTA) = START_HM_DELTA;
    P(s, VR_HM_0) = START_HM_0;
    P(s, VR_STOP_MIN) = START_STOP_MIN;
    P(s, VR_STOP_MAX) = START_STOP_MAX;
    P(s, VR_X0) = START_X0;
    P(s, VR_H_MAX) = START_H_MAX;
    s->i_mA = 0.0;
    s->jam = 0;
    s->disc = 0;
    s->x = 0.0;
    s->delta = 0.0;
    s->time = 0.0;
}

int servo_initialize(ServoState *s) {
    double h_max = P(s, VR_H_MAX);
    if (!(h_max > 0.0) || isinf(h_max)) return 0;   /* also NaN */
    s->x = clip(P(s, VR_X0), P(s, VR_X_MIN), P(s, VR_X_MAX));
    s->delta = asin(s->x / P(s, VR_R_MM));
    return 1;
}

/* rod force created by the hinge moment [N]; positive opposes extension */
static double aero_force(const ServoState *s, double x) {
    double r = P(s, VR_R_MM);
    double sn = clip(x / r, -0.999, 0.999);
    double cos_d = sqrt(1.0 - sn * sn);
    double hm = P(s, VR_HM_0) + P(s, VR_HM_DELTA) * asin(sn);
    return -hm / (r / MM_PER_M * cos_d);
}

/* rod speed [mm/s] for the held current i [mA] ([COMB] eq. 2) */
static double rod_rate(const ServoState *s, double x, double i, int loaded) {
    double sdp = P(s, VR_SDP);
    double v0 = P(s, VR_KCI) * i;
    double f_aero = loaded ? aero_force(s, x) : 0.0;
    double ka = loaded ? P(s, VR_KA) : 0.0;
    double num = sdp - sign_of(i) * f_aero;
    double v;
    num = clip(num, 0.0, 2.0 * sdp);       /* stall at 0; aiding load capped */
    v = v0 * sqrt(num / (P(s, VR_SDP_REF) + ka * v0 * v0));
    if (x >= P(s, VR_X_MAX) && v > 0.0) v = 0.0;   /* no motion further into a stop */
    if (x <= P(s, VR_X_MIN) && v < 0.0) v = 0.0;
    return v;
}

static double rk4_step(const ServoState *s, double x, double i, int loaded, double h) {
    double k1 = rod_rate(s, x, i, loaded);
    double k2 = rod_rate(s, x + 0.5 * h * k1, i, loaded);
    double k3 = rod_rate(s, x + 0.5 * h * k2, i, loaded);
    double k4 = rod_rate(s, x + h * k3, i, loaded);
    double x_new = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    return clip(x_new, P(s, VR_X_MIN), P(s, VR_X_MAX));
}

/* sqrt(|∂HM/∂δ| / (Ka·r³·cos³δ)) of the floating-surface law */
static double float_rate_coef(const ServoState *s, double delta) {
    double r_m = P(s, VR_R_MM) / MM_PER_M;
    double ka_si = P(s, VR_KA) * (MM_PER_M * MM_PER_M);   /* N/(mm/s)² -> N/(m/s)² */
    double cos_d = cos(delta);
    return sqrt(fabs(P(s, VR_HM_DELTA)) / (ka_si * pow(r_m, 3.0) * pow(cos_d, 3.0)));
}

/* floating surface: sqrt|δ − δ_f| decreases by h·c/2 over the step (exact closed form) */
static double float_step(const ServoState *s, double delta, double h) {
    double delta_f = -P(s, VR_HM_0) / P(s, VR_HM_DELTA);
    double e = delta - delta_f;
    double root = sqrt(fabs(e)) - 0.5 * h * float_rate_coef(s, delta);
    double pos = isnan(root) ? root : (root > 0.0 ? root : 0.0);
    double e_new = sign_of(e) * (pos * pos);
    return clip(delta_f + e_new, P(s, VR_STOP_MIN), P(s, VR_STOP_MAX));
}

/* one sub-step h: the period step of scenarios/servo.py, in the same order of operations */
static void servo_substep(ServoState *s, double h) {
    int loaded = !s->disc;
    double x_next = rk4_step(s, s->x, s->i_mA, loaded, h);
    if (s->jam) x_next = s->x;
    if (loaded) s->delta = asin(x_next / P(s, VR_R_MM));
    else s->delta = float_step(s, s->delta, h);
    s->x = x_next;
}

/* The fewest equal sub-steps no longer than h_max_s; the relative slack of 1e-9 keeps a
 * step of m·h_max_s (up to the rounding of h) at exactly m sub-steps, so h = Ts is one.
 * 0 when h is not a positive finite step or needs more than SERVO_MAX_SUBSTEPS. */
int servo_substeps(const ServoState *s, double h) {
    double n;
    if (!(h > 0.0) || isinf(h)) return 0;
    n = ceil(h / P(s, VR_H_MAX) * (1.0 - 1e-9));
    if (!(n <= SERVO_MAX_SUBSTEPS)) return 0;
    return n < 1.0 ? 1 : (int)n;
}

void servo_step(ServoState *s, double h) {
    int k, n = servo_substeps(s, h);
    double hs = h / n;             /* n = 1: hs is h itself, today's single RK4 step */
    for (k = 0; k < n; k++) servo_substep(s, hs);
    s->time += h;
}

double servo_delta_deg(const ServoState *s) {
    return s->delta * (180.0 / M_PI);
}
