/* A discrete proportional position controller as an FMI 2.0 Co-Simulation FMU, built by
 * tests/python/test_importers.py to close a loop around EhsvActuator in an importer:
 *
 *     i_cmd = clamp(Kp * (x_set - x), -i_max, i_max)
 *
 * sampled at each communication point: doStep computes i_cmd from the input x held over
 * the step, so the output has no direct feedthrough (it changes only in doStep) and the
 * modelDescription declares it with dependencies="". Until the first doStep i_cmd is 0. */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

enum { X, X_SET, KP, I_MAX, I_CMD, N_VARS };

typedef struct {
    fmi2Real v[N_VARS];
} Controller;

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)c; (void)on; (void)n; (void)cats;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean logging) {
    (void)name; (void)guid; (void)resources; (void)functions; (void)visible; (void)logging;
    if (type != fmi2CoSimulation) return NULL;
    Controller *c = calloc(1, sizeof *c);
    if (c) { c->v[X_SET] = 0.01; c->v[KP] = 1.0; c->v[I_MAX] = 0.01; }
    return c;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    (void)c; (void)tolDef; (void)tol; (void)start; (void)stopDef; (void)stop;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2Reset(fmi2Component c) {
    Controller *k = c;
    memset(k, 0, sizeof *k);
    k->v[X_SET] = 0.01; k->v[KP] = 1.0; k->v[I_MAX] = 0.01;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Controller *k = c;
    for (size_t j = 0; j < n; j++) {
        if (vr[j] >= N_VARS) return fmi2Error;
        value[j] = k->v[vr[j]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Controller *k = c;
    for (size_t j = 0; j < n; j++) {
        if (vr[j] >= I_CMD) return fmi2Error; /* the output is not settable */
        k->v[vr[j]] = value[j];
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    (void)t; (void)h; (void)noSetPrior;
    Controller *k = c;
    fmi2Real u = k->v[KP] * (k->v[X_SET] - k->v[X]);
    k->v[I_CMD] = u > k->v[I_MAX] ? k->v[I_MAX] : u < -k->v[I_MAX] ? -k->v[I_MAX] : u;
    return fmi2OK;
}

/* Everything else this controller does not have. */
#define NOT_SUPPORTED(name, ...) fmi2Status name(__VA_ARGS__) { return fmi2Error; }
NOT_SUPPORTED(fmi2GetInteger, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[])
NOT_SUPPORTED(fmi2GetBoolean, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
NOT_SUPPORTED(fmi2GetString, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
NOT_SUPPORTED(fmi2SetInteger, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[])
NOT_SUPPORTED(fmi2SetBoolean, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
NOT_SUPPORTED(fmi2SetString, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
NOT_SUPPORTED(fmi2GetFMUstate, fmi2Component c, fmi2FMUstate *s)
NOT_SUPPORTED(fmi2SetFMUstate, fmi2Component c, fmi2FMUstate s)
NOT_SUPPORTED(fmi2FreeFMUstate, fmi2Component c, fmi2FMUstate *s)
NOT_SUPPORTED(fmi2SerializedFMUstateSize, fmi2Component c, fmi2FMUstate s, size_t *n)
NOT_SUPPORTED(fmi2SerializeFMUstate, fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
NOT_SUPPORTED(fmi2DeSerializeFMUstate, fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s)
NOT_SUPPORTED(fmi2GetDirectionalDerivative, fmi2Component c, const fmi2ValueReference u[], size_t nu,
              const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[])
NOT_SUPPORTED(fmi2SetRealInputDerivatives, fmi2Component c, const fmi2ValueReference vr[], size_t n,
              const fmi2Integer order[], const fmi2Real v[])
NOT_SUPPORTED(fmi2GetRealOutputDerivatives, fmi2Component c, const fmi2ValueReference vr[], size_t n,
              const fmi2Integer order[], fmi2Real v[])
NOT_SUPPORTED(fmi2CancelStep, fmi2Component c)
NOT_SUPPORTED(fmi2GetStatus, fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
NOT_SUPPORTED(fmi2GetRealStatus, fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
NOT_SUPPORTED(fmi2GetIntegerStatus, fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
NOT_SUPPORTED(fmi2GetBooleanStatus, fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v)
NOT_SUPPORTED(fmi2GetStringStatus, fmi2Component c, const fmi2StatusKind s, fmi2String *v)
