/* FMI 2.0 co-simulation interface of the fdd-campaign servo-loop plant (servo_model.c).
 * Built by `fdd-campaign fmu build` against the FMI 2.0 headers that fmpy ships. */
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include "fmi2Functions.h"
#include "servo_model.h"
#include "servo_start.h"   /* FDD_SERVO_GUID, generated at build */

typedef enum { M_INSTANTIATED, M_INIT, M_STEP, M_TERMINATED, M_ERROR } Mode;

typedef struct {
    ServoState s;
    Mode mode;
    char *name;
    fmi2CallbackFunctions cb;
} Instance;

static void logmsg(Instance *c, fmi2Status st, const char *msg) {
    if (c && c->cb.logger) c->cb.logger(c->cb.componentEnvironment, c->name, st, "error", msg);
}

static int is_parameter(fmi2ValueReference vr) { return vr >= VR_KCI && vr <= SERVO_LAST_PAR; }

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) {
    (void)c; (void)on; (void)n; (void)cat;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String resources, const fmi2CallbackFunctions *cb,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Instance *c;
    (void)resources; (void)visible; (void)loggingOn;
    if (type != fmi2CoSimulation) return NULL;
    if (!guid || strcmp(guid, FDD_SERVO_GUID) != 0) return NULL;
    c = (Instance *)calloc(1, sizeof(Instance));
    if (!c) return NULL;
    c->name = (char *)malloc(strlen(name ? name : "") + 1);
    if (!c->name) { free(c); return NULL; }
    strcpy(c->name, name ? name : "");
    if (cb) c->cb = *cb;
    servo_defaults(&c->s);
    c->mode = M_INSTANTIATED;
    return c;
}

void fmi2FreeInstance(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (!c) return;
    free(c->name);
    free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean tolDef, fmi2Real tol,
                               fmi2Real start, fmi2Boolean stopDef, fmi2Real stop) {
    Instance *c = (Instance *)comp;
    (void)tolDef; (void)tol; (void)stopDef; (void)stop;
    if (!c || c->mode != M_INSTANTIATED) return fmi2Error;
    c->s.time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (!c || c->mode != M_INSTANTIATED) return fmi2Error;
    c->mode = M_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (!c || c->mode != M_INIT) return fmi2Error;
    if (!servo_initialize(&c->s)) {
        logmsg(c, fmi2Error, "fmi2ExitInitializationMode: h_max_s must be a positive finite time step [s]");
        return fmi2Error;
    }
    c->mode = M_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (!c) return fmi2Error;
    c->mode = M_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (!c) return fmi2Error;
    servo_defaults(&c->s);
    c->mode = M_INSTANTIATED;
    return fmi2OK;
}

static fmi2Status get_real(Instance *c, fmi2ValueReference vr, fmi2Real *v) {
    if (is_parameter(vr)) { *v = c->s.par[vr]; return fmi2OK; }
    switch (vr) {
    case VR_I: *v = c->s.i_mA; return fmi2OK;
    case VR_X: *v = c->s.x; return fmi2OK;
    case VR_DELTA_DEG: *v = servo_delta_deg(&c->s); return fmi2OK;
    default: return fmi2Error;
    }
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Instance *c = (Instance *)comp;
    size_t k;
    if (!c) return fmi2Error;
    for (k = 0; k < n; k++)
        if (get_real(c, vr[k], &v[k]) != fmi2OK) { logmsg(c, fmi2Error, "fmi2GetReal: unknown value reference"); return fmi2Error; }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Instance *c = (Instance *)comp;
    size_t k;
    if (!c) return fmi2Error;
    for (k = 0; k < n; k++) {
        if (is_parameter(vr[k])) {
            if (c->mode != M_INSTANTIATED && c->mode != M_INIT) {
                logmsg(c, fmi2Error, "fmi2SetReal: parameters are fixed after initialization");
                return fmi2Error;
            }
            c->s.par[vr[k]] = v[k];
        } else if (vr[k] == VR_I) {
            c->s.i_mA = v[k];
        } else {
            logmsg(c, fmi2Error, "fmi2SetReal: not a settable real variable");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    (void)comp; (void)vr; (void)v;
    return n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    (void)comp; (void)vr; (void)v;
    return n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    Instance *c = (Instance *)comp;
    size_t k;
    if (!c) return fmi2Error;
    for (k = 0; k < n; k++) {
        if (vr[k] == VR_JAM) v[k] = c->s.jam ? fmi2True : fmi2False;
        else if (vr[k] == VR_DISC) v[k] = c->s.disc ? fmi2True : fmi2False;
        else return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) {
    Instance *c = (Instance *)comp;
    size_t k;
    if (!c) return fmi2Error;
    for (k = 0; k < n; k++) {
        if (vr[k] == VR_JAM) c->s.jam = v[k] ? 1 : 0;
        else if (vr[k] == VR_DISC) c->s.disc = v[k] ? 1 : 0;
        else return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)comp; (void)vr; (void)v;
    return n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)comp; (void)vr; (void)v;
    return n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) { (void)c; (void)st; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) { (void)c; (void)st; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) { (void)c; (void)st; return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *n) { (void)c; (void)st; (void)n; return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t n) { (void)c; (void)st; (void)b; (void)n; return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *st) { (void)c; (void)b; (void)n; (void)st; return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz,
                                        const fmi2Real du[], fmi2Real dz[]) {
    (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)du; (void)dz;
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real v[]) {
    (void)c; (void)vr; (void)n; (void)order; (void)v;
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real v[]) {
    (void)c; (void)vr; (void)n; (void)order; (void)v;
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    Instance *c = (Instance *)comp;
    (void)t; (void)noSetPrior;
    if (!c || c->mode != M_STEP) return fmi2Error;
    if (!(h > 0.0)) { logmsg(c, fmi2Error, "fmi2DoStep: step size must be positive"); return fmi2Error; }
    if (!servo_substeps(&c->s, h)) { logmsg(c, fmi2Error, "fmi2DoStep: step size is infinite or needs more than 1e8 sub-steps of h_max_s"); return fmi2Error; }
    servo_step(&c->s, h);
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind k, fmi2Real *v) {
    Instance *c = (Instance *)comp;
    if (!c || k != fmi2LastSuccessfulTime) return fmi2Discard;
    *v = c->s.time;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
