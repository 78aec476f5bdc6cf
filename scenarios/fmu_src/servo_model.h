/* The servo-loop plant of fdd-campaign (PHYSICS §3), shared by the FMI 2.0 and FMI 3.0
 * co-simulation wrappers. Units: rod position mm, current mA, force N, hinge moment N·m,
 * angles rad inside the model (the surface output is in deg), time s.
 *
 * The equations and their order of operations mirror scenarios/servo.py (rod_rate,
 * rk4_step, float_step) so that the FMU and the built-in plant agree to rounding. */
#ifndef FDD_SERVO_MODEL_H
#define FDD_SERVO_MODEL_H

/* value references: parameters (pushed by the engine at set-up), inputs, outputs */
enum {
    VR_KCI = 1,        /* servo-valve gain Kci [(mm/s)/mA] */
    VR_SDP = 2,        /* stall force S·ΔP [N] */
    VR_SDP_REF = 3,    /* S·ΔP_ref [N] */
    VR_KA = 4,         /* damping-mode neighbour coefficient Ka [N/(mm/s)²] */
    VR_R_MM = 5,       /* lever arm r [mm] */
    VR_X_MIN = 6,      /* rod position at the lower mechanical stop [mm] */
    VR_X_MAX = 7,      /* rod position at the upper mechanical stop [mm] */
    VR_HM_DELTA = 8,   /* ∂HM/∂δ [N·m/rad] */
    VR_HM_0 = 9,       /* HM at δ = 0 [N·m] */
    VR_STOP_MIN = 10,  /* lower mechanical stop [rad] (floating surface) */
    VR_STOP_MAX = 11,  /* upper mechanical stop [rad] */
    VR_X0 = 12,        /* initial (trimmed) rod position [mm] */
    VR_H_MAX = 13,     /* longest internal integration sub-step [s] (the FCC period Ts) */
    VR_I = 20,         /* input: servo-valve current held over the step [mA] */
    VR_JAM = 21,       /* input (Boolean): rod and surface seized (solid jam) */
    VR_DISC = 22,      /* input (Boolean): rod-surface link broken (disconnection) */
    VR_X = 30,         /* output: rod position [mm] */
    VR_DELTA_DEG = 31  /* output: surface deflection [deg] */
};

#define SERVO_N_PAR 14   /* parameters are stored at index = value reference (1..13) */
#define SERVO_LAST_PAR VR_H_MAX
#define SERVO_MAX_SUBSTEPS 100000000   /* 1e8 sub-steps: 1e6 s at h_max_s = 0.01 s */

typedef struct {
    double par[SERVO_N_PAR];
    double i_mA;
    int jam;
    int disc;
    double x;          /* rod position [mm] */
    double delta;      /* surface deflection [rad] */
    double time;       /* [s] */
} ServoState;

void servo_defaults(ServoState *s);                 /* start values of the model description */
int servo_initialize(ServoState *s);                /* trimmed state from x0; 0: bad h_max_s */
int servo_substeps(const ServoState *s, double h);  /* sub-steps of a communication step h */
void servo_step(ServoState *s, double h);           /* advance over a communication step h [s] */
double servo_delta_deg(const ServoState *s);

#endif
