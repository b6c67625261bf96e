/* FMI 2.0 co-simulation over the reclaimer (reclaimer.h): every function of fmi2Functions.h,
   each either valid in the instance's state or answered fmi2Error with its reason logged. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "reclaimer.h"

typedef struct {
    Reclaimer *reclaimer;
    fmi2CallbackFunctions functions;
    char *name;
} Instance;

static void log_fmi2(void *owner, int error, const char *message) {
    Instance *c = owner;
    if (c->functions.logger)  /* the host formats the message: passed as an argument, never as the format */
        c->functions.logger(c->functions.componentEnvironment, c->name, error ? fmi2Error : fmi2OK,
                            error ? "logStatusError" : "logEvents", "%s", message);
}

#define INSTANCE(call, states)                                                              \
    Instance *c = (Instance *)component;                                                     \
    if (!c) return fmi2Error;                                                                \
    Reclaimer *r = c->reclaimer;                                                             \
    if (!reclaimer_allowed(r, call, states)) return fmi2Error;

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)visible;
    if (!functions || !functions->logger) return NULL; /* FMI 2.0 requires a logger: nothing to tell why to */
    const char *name = instanceName ? instanceName : "";
#define REFUSE(...) return functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError", \
                                             __VA_ARGS__), NULL
    if (!instanceName || !instanceName[0]) REFUSE("fmi2Instantiate: the instance name is empty");
    if (fmuType != fmi2CoSimulation) REFUSE("fmi2Instantiate: this FMU is for co-simulation only");
    if (!fmuGUID || strcmp(fmuGUID, MODEL_GUID))
        REFUSE("fmi2Instantiate: GUID %s is not this FMU's (%s)", fmuGUID ? fmuGUID : "(null)", MODEL_GUID);
    if (!fmuResourceLocation) REFUSE("fmi2Instantiate: no resource location");
    /* a file URI: file:///path, file:/path or file://host/path; percent escapes decoded */
    const char *p = fmuResourceLocation;
    if (!strncmp(p, "file://", 7)) {
        p += 7;
        if (*p != '/') p = strchr(p, '/') ? strchr(p, '/') : p;
    } else if (!strncmp(p, "file:", 5)) p += 5;
    else REFUSE("fmi2Instantiate: the resource location %s is not a file URI", fmuResourceLocation);
#ifdef _WIN32
    if (p[0] == '/' && p[1] && p[2] == ':') p++; /* file:///C:/... names C:/... */
#endif
    char *folder = malloc(strlen(p) + 1);
    if (!folder) REFUSE("fmi2Instantiate: out of memory");
    size_t n = 0;
    for (; *p; p++) {
        unsigned code;
        if (*p == '%' && sscanf(p + 1, "%2x", &code) == 1) folder[n++] = (char)code, p += 2;
        else folder[n++] = *p;
    }
    folder[n] = 0;
    while (n > 1 && folder[n - 1] == '/') folder[--n] = 0;
    Instance *c = calloc(1, sizeof *c);
    char *copy = malloc(strlen(name) + 1);
    if (!c || !copy) {
        free(c), free(copy), free(folder);
        REFUSE("fmi2Instantiate: out of memory");
    }
    strcpy(copy, name);
    c->name = copy;
    c->functions = *functions;
    c->reclaimer = reclaimer_new(folder, log_fmi2, c, loggingOn);
    free(folder);
    if (!c->reclaimer) {
        free(c->name), free(c);
        return NULL;
    }
#undef REFUSE
    return c;
}

void fmi2FreeInstance(fmi2Component component) {
    Instance *c = (Instance *)component;
    if (!c) return;
    reclaimer_free(c->reclaimer);
    free(c->name);
    free(c);
}

fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    INSTANCE("fmi2SetDebugLogging", STATES_ANY)
    if (nCategories > 0 && !categories) return reclaimer_refuse(r, "fmi2SetDebugLogging", "null categories"), fmi2Error;
    for (size_t i = 0; i < nCategories; i++)
        if (!categories[i] || (strcmp(categories[i], "logStatusError") && strcmp(categories[i], "logEvents"))) {
            reclaimer_refuse(r, "fmi2SetDebugLogging", "category %s is not this FMU's (logStatusError, logEvents)",
                             categories[i] ? categories[i] : "(null)");
            return fmi2Error;
        }
    reclaimer_log_info(r, loggingOn);
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component component, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined, (void)tolerance;
    INSTANCE("fmi2SetupExperiment", STATE_INSTANTIATED)
    if (startTime != 0.0)
        return reclaimer_refuse(r, "fmi2SetupExperiment", "the run starts at t = 0 s, not %g s", startTime), fmi2Error;
    (void)stopTimeDefined, (void)stopTime; /* a step past the path's end is refused when it comes */
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component component) {
    INSTANCE("fmi2EnterInitializationMode", STATE_INSTANTIATED)
    reclaimer_set_state(r, STATE_INITIALIZATION);
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component component) {
    INSTANCE("fmi2ExitInitializationMode", STATE_INITIALIZATION)
    reclaimer_start(r);
    reclaimer_set_state(r, STATE_STEP);
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component component) {
    INSTANCE("fmi2Terminate", STATE_STEP)
    reclaimer_set_state(r, STATE_TERMINATED);
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component component) {
    INSTANCE("fmi2Reset", STATES_ANY)
    reclaimer_reset(r);
    return fmi2OK;
}

#define SETTERS (STATE_INSTANTIATED | STATE_INITIALIZATION | STATE_STEP)

fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    INSTANCE("fmi2GetReal", STATES_READ)
    return reclaimer_get_real(r, "fmi2GetReal", vr, nvr, value) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    INSTANCE("fmi2GetInteger", STATES_READ)
    return reclaimer_get_integer(r, "fmi2GetInteger", vr, nvr, value) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    INSTANCE("fmi2GetBoolean", STATES_READ)
    return reclaimer_get_boolean(r, "fmi2GetBoolean", vr, nvr, value) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    INSTANCE("fmi2GetString", STATES_READ)
    (void)vr, (void)value;
    if (nvr == 0) return fmi2OK;
    return reclaimer_refuse(r, "fmi2GetString", "this FMU has no String variables"), fmi2Error;
}

fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    INSTANCE("fmi2SetReal", SETTERS)
    return reclaimer_set_real(r, "fmi2SetReal", vr, nvr, value) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    INSTANCE("fmi2SetInteger", SETTERS)
    return reclaimer_set_integer(r, "fmi2SetInteger", vr, nvr, value) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    INSTANCE("fmi2SetBoolean", SETTERS)
    return reclaimer_set_boolean(r, "fmi2SetBoolean", vr, nvr, value) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    INSTANCE("fmi2SetString", SETTERS)
    (void)vr, (void)value;
    if (nvr == 0) return fmi2OK;
    return reclaimer_refuse(r, "fmi2SetString", "this FMU has no String variables"), fmi2Error;
}

/* What this FMU does not offer (its model description says so): refused in every state. */
#define UNSUPPORTED(call, why)                                                   \
    if (!component) return fmi2Error;                                            \
    reclaimer_refuse(((Instance *)component)->reclaimer, call, "not supported: %s", why); \
    return fmi2Error;

fmi2Status fmi2GetFMUstate(fmi2Component component, fmi2FMUstate *state) {
    (void)state;
    UNSUPPORTED("fmi2GetFMUstate", "canGetAndSetFMUstate is false")
}
fmi2Status fmi2SetFMUstate(fmi2Component component, fmi2FMUstate state) {
    (void)state;
    UNSUPPORTED("fmi2SetFMUstate", "canGetAndSetFMUstate is false")
}
fmi2Status fmi2FreeFMUstate(fmi2Component component, fmi2FMUstate *state) {
    (void)state;
    UNSUPPORTED("fmi2FreeFMUstate", "canGetAndSetFMUstate is false")
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component component, fmi2FMUstate state, size_t *size) {
    (void)state, (void)size;
    UNSUPPORTED("fmi2SerializedFMUstateSize", "canSerializeFMUstate is false")
}
fmi2Status fmi2SerializeFMUstate(fmi2Component component, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    (void)state, (void)bytes, (void)size;
    UNSUPPORTED("fmi2SerializeFMUstate", "canSerializeFMUstate is false")
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component component, const fmi2Byte bytes[], size_t size,
                                   fmi2FMUstate *state) {
    (void)state, (void)bytes, (void)size;
    UNSUPPORTED("fmi2DeSerializeFMUstate", "canSerializeFMUstate is false")
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component component, const fmi2ValueReference unknown[], size_t nUnknown,
                                        const fmi2ValueReference known[], size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)unknown, (void)nUnknown, (void)known, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    UNSUPPORTED("fmi2GetDirectionalDerivative", "providesDirectionalDerivative is false")
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    UNSUPPORTED("fmi2SetRealInputDerivatives", "canInterpolateInputs is false")
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    UNSUPPORTED("fmi2GetRealOutputDerivatives", "maxOutputDerivativeOrder is 0")
}
fmi2Status fmi2CancelStep(fmi2Component component) {
    UNSUPPORTED("fmi2CancelStep", "canRunAsynchronuously is false: a step is over when fmi2DoStep returns")
}

fmi2Status fmi2DoStep(fmi2Component component, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    INSTANCE("fmi2DoStep", STATE_STEP)
    return reclaimer_step(r, "fmi2DoStep", currentCommunicationPoint, communicationStepSize) == 1 ? fmi2OK
                                                                                                : fmi2Error;
}

/* The status of a finished step: every step finishes within fmi2DoStep, so only fmi2Terminated
   (the path's end reached) and fmi2LastSuccessfulTime have an answer. */
fmi2Status fmi2GetStatus(fmi2Component component, const fmi2StatusKind s, fmi2Status *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetStatus", "no step runs asynchronously")
}
fmi2Status fmi2GetRealStatus(fmi2Component component, const fmi2StatusKind s, fmi2Real *value) {
    INSTANCE("fmi2GetRealStatus", STATE_STEP | STATE_ERROR)
    if (s != fmi2LastSuccessfulTime || !value)
        return reclaimer_refuse(r, "fmi2GetRealStatus", "only fmi2LastSuccessfulTime is answered"), fmi2Error;
    *value = reclaimer_time(r);
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component component, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetIntegerStatus", "no Integer status")
}
fmi2Status fmi2GetBooleanStatus(fmi2Component component, const fmi2StatusKind s, fmi2Boolean *value) {
    INSTANCE("fmi2GetBooleanStatus", STATE_STEP | STATE_ERROR)
    if (s != fmi2Terminated || !value)
        return reclaimer_refuse(r, "fmi2GetBooleanStatus", "only fmi2Terminated is answered"), fmi2Error;
    *value = reclaimer_done(r) || reclaimer_state(r) == STATE_ERROR;
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component component, const fmi2StatusKind s, fmi2String *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetStringStatus", "no String status")
}
