/* FMI 3.0 co-simulation over the reclaimer (reclaimer.h): every function of fmi3Functions.h,
   each either valid in the instance's state or answered fmi3Error with its reason logged.
   Variables: Float64 (FMI 2.0's Real), Int32 (Integer) and Boolean; no other type. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "reclaimer.h"

typedef struct {
    Reclaimer *reclaimer;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log;
} Instance;

static void log_fmi3(void *owner, int error, const char *message) {
    Instance *c = owner;
    if (c->log) c->log(c->environment, error ? fmi3Error : fmi3OK, error ? "logStatusError" : "logEvents", message);
}

#define INSTANCE(call, states)                         \
    Instance *c = (Instance *)instance;                 \
    if (!c) return fmi3Error;                           \
    Reclaimer *r = c->reclaimer;                        \
    if (!reclaimer_allowed(r, call, states)) return fmi3Error;

/* What this FMU does not offer (its model description says so): refused in every state. */
#define UNSUPPORTED(call, why)                                                               \
    if (!instance) return fmi3Error;                                                          \
    reclaimer_refuse(((Instance *)instance)->reclaimer, call, "not supported: %s", why);     \
    return fmi3Error;

#define SETTERS (STATE_INSTANTIATED | STATE_INITIALIZATION | STATE_STEP)

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)visible, (void)earlyReturnAllowed, (void)requiredIntermediateVariables, (void)intermediateUpdate;
    char why[512] = "";
    if (!instanceName || !instanceName[0]) snprintf(why, sizeof why, "the instance name is empty");
    else if (!instantiationToken || strcmp(instantiationToken, MODEL_GUID))
        snprintf(why, sizeof why, "instantiation token %s is not this FMU's (%s)",
                 instantiationToken ? instantiationToken : "(null)", MODEL_GUID);
    else if (eventModeUsed) snprintf(why, sizeof why, "this FMU has no event mode (hasEventMode is false)");
    else if (nRequiredIntermediateVariables > 0) snprintf(why, sizeof why, "this FMU provides no intermediate update");
    else if (!resourcePath || !resourcePath[0]) snprintf(why, sizeof why, "no resource path");
    if (why[0]) {
        if (logMessage) {
            char message[600];
            snprintf(message, sizeof message, "fmi3InstantiateCoSimulation: %s", why);
            logMessage(instanceEnvironment, fmi3Error, "logStatusError", message);
        }
        return NULL;
    }
    Instance *c = calloc(1, sizeof *c);
    char *folder = malloc(strlen(resourcePath) + 1);
    if (!c || !folder) {
        free(c), free(folder);
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "out of memory");
        return NULL;
    }
    strcpy(folder, resourcePath);
    for (size_t n = strlen(folder); n > 1 && (folder[n - 1] == '/' || folder[n - 1] == '\\'); n--) folder[n - 1] = 0;
    c->environment = instanceEnvironment;
    c->log = logMessage;
    c->reclaimer = reclaimer_new(folder, log_fmi3, c, loggingOn);
    free(folder);
    if (!c->reclaimer) {
        free(c);
        return NULL;
    }
    return c;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateModelExchange: this FMU is for co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: this FMU is for co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    Instance *c = (Instance *)instance;
    if (!c) return;
    reclaimer_free(c->reclaimer);
    free(c);
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    INSTANCE("fmi3SetDebugLogging", STATES_ANY)
    if (nCategories > 0 && !categories) return reclaimer_refuse(r, "fmi3SetDebugLogging", "null categories"), fmi3Error;
    for (size_t i = 0; i < nCategories; i++)
        if (!categories[i] || (strcmp(categories[i], "logStatusError") && strcmp(categories[i], "logEvents"))) {
            reclaimer_refuse(r, "fmi3SetDebugLogging", "category %s is not this FMU's (logStatusError, logEvents)",
                             categories[i] ? categories[i] : "(null)");
            return fmi3Error;
        }
    reclaimer_log_info(r, loggingOn);
    return fmi3OK;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    INSTANCE("fmi3EnterInitializationMode", STATE_INSTANTIATED)
    if (startTime != 0.0)
        return reclaimer_refuse(r, "fmi3EnterInitializationMode", "the run starts at t = 0 s, not %g s", startTime),
               fmi3Error;
    reclaimer_set_state(r, STATE_INITIALIZATION);
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    INSTANCE("fmi3ExitInitializationMode", STATE_INITIALIZATION)
    reclaimer_start(r);
    reclaimer_set_state(r, STATE_STEP);
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    INSTANCE("fmi3Terminate", STATE_STEP)
    reclaimer_set_state(r, STATE_TERMINATED);
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    INSTANCE("fmi3Reset", STATES_ANY)
    reclaimer_reset(r);
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    (void)noSetFMUStatePriorToCurrentPoint;
    INSTANCE("fmi3DoStep", STATE_STEP)
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime)
        return reclaimer_refuse(r, "fmi3DoStep", "a null pointer for a result"), fmi3Error;
    int done = reclaimer_step(r, "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    *eventHandlingNeeded = fmi3False;
    *earlyReturn = fmi3False;
    *terminateSimulation = reclaimer_done(r) || done < 0;
    *lastSuccessfulTime = reclaimer_time(r);
    return done == 1 ? fmi3OK : fmi3Error;
}

/* -- values: with one value per reference (every variable is a scalar) -------------------------- */

static int scalars(Reclaimer *r, const char *call, size_t nvr, size_t nValues) {
    if (nvr == nValues) return 1;
    return reclaimer_refuse(r, call, "%zu values for %zu value references: every variable is a scalar", nValues, nvr);
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues) {
    INSTANCE("fmi3GetFloat64", STATES_READ)
    return scalars(r, "fmi3GetFloat64", nvr, nValues) && reclaimer_get_real(r, "fmi3GetFloat64", vr, nvr, values)
               ? fmi3OK : fmi3Error;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues) {
    INSTANCE("fmi3SetFloat64", SETTERS)
    return scalars(r, "fmi3SetFloat64", nvr, nValues) && reclaimer_set_real(r, "fmi3SetFloat64", vr, nvr, values)
               ? fmi3OK : fmi3Error;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[],
                        size_t nValues) {
    INSTANCE("fmi3GetInt32", STATES_READ)
    return scalars(r, "fmi3GetInt32", nvr, nValues) && reclaimer_get_integer(r, "fmi3GetInt32", vr, nvr, values)
               ? fmi3OK : fmi3Error;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 values[],
                        size_t nValues) {
    INSTANCE("fmi3SetInt32", SETTERS)
    return scalars(r, "fmi3SetInt32", nvr, nValues) && reclaimer_set_integer(r, "fmi3SetInt32", vr, nvr, values)
               ? fmi3OK : fmi3Error;
}

#define BOOLEANS_AT_ONCE 64 /* converted between fmi3Boolean (bool) and int in chunks of this many */

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean values[],
                          size_t nValues) {
    INSTANCE("fmi3GetBoolean", STATES_READ)
    if (!scalars(r, "fmi3GetBoolean", nvr, nValues)) return fmi3Error;
    if (nvr > 0 && !values) return reclaimer_refuse(r, "fmi3GetBoolean", "a null array for %zu values", nvr), fmi3Error;
    for (size_t first = 0; first < nvr; first += BOOLEANS_AT_ONCE) {
        int got[BOOLEANS_AT_ONCE];
        size_t n = nvr - first < BOOLEANS_AT_ONCE ? nvr - first : BOOLEANS_AT_ONCE;
        if (!reclaimer_get_boolean(r, "fmi3GetBoolean", vr + first, n, got)) return fmi3Error;
        for (size_t i = 0; i < n; i++) values[first + i] = got[i] != 0;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Boolean values[], size_t nValues) {
    INSTANCE("fmi3SetBoolean", SETTERS)
    if (!scalars(r, "fmi3SetBoolean", nvr, nValues)) return fmi3Error;
    if (nvr > 0 && !values) return reclaimer_refuse(r, "fmi3SetBoolean", "a null array for %zu values", nvr), fmi3Error;
    int given[BOOLEANS_AT_ONCE];
    size_t n = nvr < BOOLEANS_AT_ONCE ? nvr : BOOLEANS_AT_ONCE;
    for (size_t i = 0; i < n; i++) given[i] = values[i];
    return reclaimer_set_boolean(r, "fmi3SetBoolean", vr, n, given) ? fmi3OK : fmi3Error; /* none is settable */
}

/* The types this FMU has no variable of: an empty call is valid, any reference is refused. */
static fmi3Status none_of_type(fmi3Instance instance, const char *call, unsigned states, size_t nvr, const char *type) {
    INSTANCE(call, states)
    if (nvr == 0) return fmi3OK;
    return reclaimer_refuse(r, call, "this FMU has no %s variables", type), fmi3Error;
}

#define NO_VARIABLES(type, name)                                                                             \
    fmi3Status fmi3Get##name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, type values[],  \
                             size_t nValues) {                                                               \
        (void)vr, (void)values, (void)nValues;                                                               \
        return none_of_type(instance, "fmi3Get" #name, STATES_READ, nvr, #name);                             \
    }                                                                                                        \
    fmi3Status fmi3Set##name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,               \
                             const type values[], size_t nValues) {                                          \
        (void)vr, (void)values, (void)nValues;                                                               \
        return none_of_type(instance, "fmi3Set" #name, SETTERS, nvr, #name);                                 \
    }

NO_VARIABLES(fmi3Float32, Float32)
NO_VARIABLES(fmi3Int8, Int8)
NO_VARIABLES(fmi3UInt8, UInt8)
NO_VARIABLES(fmi3Int16, Int16)
NO_VARIABLES(fmi3UInt16, UInt16)
NO_VARIABLES(fmi3UInt32, UInt32)
NO_VARIABLES(fmi3Int64, Int64)
NO_VARIABLES(fmi3UInt64, UInt64)
NO_VARIABLES(fmi3String, String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    (void)vr, (void)valueSizes, (void)values, (void)nValues;
    return none_of_type(instance, "fmi3GetBinary", STATES_READ, nvr, "Binary");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)vr, (void)valueSizes, (void)values, (void)nValues;
    return none_of_type(instance, "fmi3SetBinary", SETTERS, nvr, "Binary");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    (void)vr, (void)values;
    return none_of_type(instance, "fmi3GetClock", STATES_READ, nvr, "Clock");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    (void)vr, (void)values;
    return none_of_type(instance, "fmi3SetClock", SETTERS, nvr, "Clock");
}

/* -- what this FMU does not offer ----------------------------------------------------------------- */

fmi3Status fmi3EnterEventMode(fmi3Instance instance) { UNSUPPORTED("fmi3EnterEventMode", "hasEventMode is false") }
fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3EnterStepMode", "hasEventMode is false: step mode follows fmi3ExitInitializationMode")
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3EnterConfigurationMode", "no structural parameters")
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3ExitConfigurationMode", "no structural parameters")
}
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference, (void)nDependencies;
    UNSUPPORTED("fmi3GetNumberOfVariableDependencies", "providesPerElementDependencies is false")
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent, (void)elementIndicesOfDependent, (void)independents, (void)elementIndicesOfIndependents;
    (void)dependencyKinds, (void)nDependencies;
    UNSUPPORTED("fmi3GetVariableDependencies", "providesPerElementDependencies is false")
}
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    (void)FMUState;
    UNSUPPORTED("fmi3GetFMUState", "canGetAndSetFMUState is false")
}
fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    (void)FMUState;
    UNSUPPORTED("fmi3SetFMUState", "canGetAndSetFMUState is false")
}
fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    (void)FMUState;
    UNSUPPORTED("fmi3FreeFMUState", "canGetAndSetFMUState is false")
}
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    (void)FMUState, (void)size;
    UNSUPPORTED("fmi3SerializedFMUStateSize", "canSerializeFMUState is false")
}
fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    (void)FMUState, (void)serializedState, (void)size;
    UNSUPPORTED("fmi3SerializeFMUState", "canSerializeFMUState is false")
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    (void)FMUState, (void)serializedState, (void)size;
    UNSUPPORTED("fmi3DeserializeFMUState", "canSerializeFMUState is false")
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed, (void)sensitivity;
    (void)nSensitivity;
    UNSUPPORTED("fmi3GetDirectionalDerivative", "providesDirectionalDerivatives is false")
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed, (void)sensitivity;
    (void)nSensitivity;
    UNSUPPORTED("fmi3GetAdjointDerivative", "providesAdjointDerivatives is false")
}
fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr, (void)nvr, (void)intervals, (void)qualifiers;
    UNSUPPORTED("fmi3GetIntervalDecimal", "no clocks")
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions, (void)qualifiers;
    UNSUPPORTED("fmi3GetIntervalFraction", "no clocks")
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)vr, (void)nvr, (void)shifts;
    UNSUPPORTED("fmi3GetShiftDecimal", "no clocks")
}
fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    UNSUPPORTED("fmi3GetShiftFraction", "no clocks")
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    (void)vr, (void)nvr, (void)intervals;
    UNSUPPORTED("fmi3SetIntervalDecimal", "no clocks")
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    UNSUPPORTED("fmi3SetIntervalFraction", "no clocks")
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)vr, (void)nvr, (void)shifts;
    UNSUPPORTED("fmi3SetShiftDecimal", "no clocks")
}
fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    UNSUPPORTED("fmi3SetShiftFraction", "no clocks")
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    UNSUPPORTED("fmi3EvaluateDiscreteStates", "co-simulation without event mode")
}
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    (void)discreteStatesNeedUpdate, (void)terminateSimulation, (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged, (void)nextEventTimeDefined, (void)nextEventTime;
    UNSUPPORTED("fmi3UpdateDiscreteStates", "co-simulation without event mode")
}
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3EnterContinuousTimeMode", "co-simulation only")
}
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    UNSUPPORTED("fmi3CompletedIntegratorStep", "co-simulation only")
}
fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    UNSUPPORTED("fmi3SetTime", "co-simulation only")
}
fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    UNSUPPORTED("fmi3SetContinuousStates", "co-simulation only")
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives, (void)nContinuousStates;
    UNSUPPORTED("fmi3GetContinuousStateDerivatives", "co-simulation only")
}
fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    (void)eventIndicators, (void)nEventIndicators;
    UNSUPPORTED("fmi3GetEventIndicators", "co-simulation only")
}
fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    UNSUPPORTED("fmi3GetContinuousStates", "co-simulation only")
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals, (void)nContinuousStates;
    UNSUPPORTED("fmi3GetNominalsOfContinuousStates", "co-simulation only")
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    (void)nEventIndicators;
    UNSUPPORTED("fmi3GetNumberOfEventIndicators", "co-simulation only")
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    (void)nContinuousStates;
    UNSUPPORTED("fmi3GetNumberOfContinuousStates", "co-simulation only")
}
fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr, (void)nvr, (void)orders, (void)values, (void)nValues;
    UNSUPPORTED("fmi3GetOutputDerivatives", "maxOutputDerivativeOrder is 0")
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference, (void)activationTime;
    UNSUPPORTED("fmi3ActivateModelPartition", "scheduled execution is not offered")
}
