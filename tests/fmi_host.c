/* A small FMI host in C, as Simulink, OMSimulator or TwinCAT load an FMU: dlopen the FMU's
   library, look its functions up, call them. No Python in the process. Compiled and run by
   tests/test_fmu_native.py with the FMI headers the FMU carries in sources/.

     fmi_host DIR run 2|3 PERIODS [quiet]   DIR an unzipped FMU: a PD on the encoders against the
                                            reference, PERIODS periods of one step each, the
                                            disturbances off; prints each period's encoder positions
                                            unless quiet, then "end PERIODS_LEFT"
     fmi_host DIR bench 2 PERIODS            as run, quiet, then the time of the periods' loop alone:
                                            "PERIODS SECONDS"
     fmi_host DIR states 2|3                every call in every state of a fresh instance: one
                                            line "STATE CALL STATUS LOGGED" each
     fmi_host DIR rules 2|3                 the FMI rules the FMU keeps, one line each: "RULE ok"
     fmi_host DIR disturbance 2 PERIODS SEED HOLD
                                            the setpoints at 0, the disturbance forces of each period

   The FMU's GUID (instantiation token) and its value references come from the environment, read
   from its model description by the caller: FMU_GUID, and VR_<name, its dots as underscores>
   (tests/test_fmu_native.py's host_environment). Exit 0 once everything asked has run; 1 if a
   call that must succeed did not. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"
#include "fmi3Functions.h"

static const char *GUID;
static char RESOURCES_URI[4096], RESOURCES_PATH[4096];
static int logged; /* messages the FMU logged since the last reset of this counter */
static char last_message[2048];

static void *library;
#define LOOKUP(name) name##TYPE *name = (name##TYPE *)dlsym(library, #name)

static void fail(const char *format, ...) {
    va_list args;
    va_start(args, format);
    vfprintf(stderr, format, args);
    va_end(args);
    fputc('\n', stderr);
    exit(1);
}

/* -- FMI 2.0 -------------------------------------------------------------------------------- */

static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    (void)env, (void)name, (void)category;
    va_list args;
    va_start(args, message);
    vsnprintf(last_message, sizeof last_message, message, args);
    va_end(args);
    logged++;
    if (getenv("FMI_HOST_VERBOSE")) fprintf(stderr, "[%d] %s\n", status, last_message);
}

static const fmi2CallbackFunctions CALLBACKS2 = {logger2, calloc, free, NULL, NULL};

/* Value references, read from the model description by the test and passed in the environment. */
static unsigned vr(const char *name) {
    char key[128];
    snprintf(key, sizeof key, "VR_%s", name);
    for (char *c = key; *c; c++)
        if (*c == '.') *c = '_';
    const char *value = getenv(key);
    if (!value) fail("no %s in the environment", key);
    return (unsigned)atoi(value);
}

typedef struct {
    unsigned setpoint[3], position[3], velocity[3], reference[3], reference_velocity[3], amplitude[3];
    unsigned disturbance[3], periods_left, seed, at_limit, period, hold;
} Refs;

static Refs refs(void) {
    const char *axes[3] = {"Travel", "Slew", "Luff"};
    Refs r;
    char name[64];
    for (int j = 0; j < 3; j++) {
#define AXIS(field, signal) snprintf(name, sizeof name, "%s.%s", axes[j], signal), r.field[j] = vr(name)
        AXIS(setpoint, "DriveSetpoint");
        AXIS(position, "EncoderPosition");
        AXIS(velocity, "EncoderVelocity");
        AXIS(reference, "ReferencePosition");
        AXIS(reference_velocity, "ReferenceVelocity");
        AXIS(amplitude, "DisturbanceAmplitude");
        AXIS(disturbance, "DisturbanceForce");
    }
    r.periods_left = vr("PeriodsLeft"), r.seed = vr("Seed"), r.at_limit = vr("Travel.AtLimit");
    r.period = vr("ControlPeriod"), r.hold = vr("DisturbanceHoldTime");
    return r;
}

/* A PD on each axis, examples/fmu_pid.py's gains without the integral: the law
   tests/test_fmu_native.py runs in process against the twin, operation for operation. */
static const double KP[3] = {28000.0, 7262500.0, 5000000.0}, KD[3] = {28000.0, 7262500.0, 5000000.0},
                    HOLD[3] = {0.0, 0.0, 490500.0};

static void pd(const double *values, double *force) {
    for (int j = 0; j < 3; j++)
        force[j] = HOLD[j] + KP[j] * (values[6 + j] - values[j]) + KD[j] * (values[9 + j] - values[3 + j]);
}

static double seconds(void) {
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return now.tv_sec + 1e-9 * now.tv_nsec;
}

static double loop_seconds; /* the last run's loop, instantiation and initialisation excluded */

static int run2(long periods, int quiet) {
    LOOKUP(fmi2Instantiate); LOOKUP(fmi2SetupExperiment); LOOKUP(fmi2EnterInitializationMode);
    LOOKUP(fmi2ExitInitializationMode); LOOKUP(fmi2SetReal); LOOKUP(fmi2GetReal); LOOKUP(fmi2GetInteger);
    LOOKUP(fmi2DoStep); LOOKUP(fmi2Terminate); LOOKUP(fmi2FreeInstance);
    Refs r = refs();
    fmi2Component c = fmi2Instantiate("host", fmi2CoSimulation, GUID, RESOURCES_URI, &CALLBACKS2, fmi2False, fmi2False);
    if (!c) fail("fmi2Instantiate failed: %s", last_message);
    double zero[3] = {0, 0, 0}, period;
    if (fmi2SetupExperiment(c, fmi2False, 0, 0, fmi2False, 0) || fmi2EnterInitializationMode(c) ||
        fmi2SetReal(c, r.amplitude, 3, zero) || fmi2ExitInitializationMode(c) ||
        fmi2GetReal(c, &r.period, 1, &period))
        fail("initialisation failed: %s", last_message);
    unsigned measured[12];
    memcpy(measured, r.position, sizeof r.position), memcpy(measured + 3, r.velocity, sizeof r.velocity);
    memcpy(measured + 6, r.reference, sizeof r.reference);
    memcpy(measured + 9, r.reference_velocity, sizeof r.reference_velocity);
    double start = seconds();
    for (long k = 0; k < periods; k++) {
        double values[12], force[3];
        if (fmi2GetReal(c, measured, 12, values)) fail("fmi2GetReal failed: %s", last_message);
        if (!quiet) printf("%.17g %.17g %.17g\n", values[0], values[1], values[2]);
        pd(values, force);
        if (fmi2SetReal(c, r.setpoint, 3, force)) fail("fmi2SetReal failed: %s", last_message);
        if (fmi2DoStep(c, k * period, period, fmi2True)) fail("fmi2DoStep %ld failed: %s", k, last_message);
    }
    loop_seconds = seconds() - start;
    int left;
    if (fmi2GetInteger(c, &r.periods_left, 1, &left) || fmi2Terminate(c)) fail("the end failed: %s", last_message);
    fmi2FreeInstance(c);
    printf("end %d\n", left);
    return 0;
}

static int disturbance2(long periods, int seed, double hold) {
    LOOKUP(fmi2Instantiate); LOOKUP(fmi2EnterInitializationMode); LOOKUP(fmi2ExitInitializationMode);
    LOOKUP(fmi2SetReal); LOOKUP(fmi2SetInteger); LOOKUP(fmi2GetReal); LOOKUP(fmi2DoStep); LOOKUP(fmi2FreeInstance);
    Refs r = refs();
    fmi2Component c = fmi2Instantiate("host", fmi2CoSimulation, GUID, RESOURCES_URI, &CALLBACKS2, fmi2False, fmi2False);
    if (!c || fmi2EnterInitializationMode(c) || fmi2SetInteger(c, &r.seed, 1, &seed) ||
        fmi2SetReal(c, &r.hold, 1, &hold) || fmi2ExitInitializationMode(c))
        fail("initialisation failed: %s", last_message);
    for (long k = 0; k < periods; k++) {
        double force[3];
        if (fmi2DoStep(c, k * 0.01, 0.01, fmi2True) || fmi2GetReal(c, r.disturbance, 3, force))
            fail("period %ld failed: %s", k, last_message);
        printf("%.17g %.17g %.17g\n", force[0], force[1], force[2]);
    }
    fmi2FreeInstance(c);
    return 0;
}

/* Every call of FMI 2.0's co-simulation interface, on an instance in `state`. */
static const char *STATES[] = {"instantiated", "initialization", "step", "terminated", "error"};
#define CALLS2 31

static fmi2Component reach2(int state, const Refs *r) {
    LOOKUP(fmi2Instantiate); LOOKUP(fmi2EnterInitializationMode); LOOKUP(fmi2ExitInitializationMode);
    LOOKUP(fmi2Terminate); LOOKUP(fmi2DoStep); LOOKUP(fmi2SetReal);
    fmi2Component c = fmi2Instantiate("host", fmi2CoSimulation, GUID, RESOURCES_URI, &CALLBACKS2, fmi2False, fmi2False);
    if (!c) fail("fmi2Instantiate failed: %s", last_message);
    double huge[3] = {1e300, 1e300, 1e300};
    if (state >= 1 && fmi2EnterInitializationMode(c)) fail("enter");
    if (state == 4 && fmi2SetReal(c, r->amplitude, 3, huge)) fail("a huge disturbance refused");
    if (state >= 2 && fmi2ExitInitializationMode(c)) fail("exit");
    if (state == 3 && fmi2Terminate(c)) fail("terminate");
    if (state == 4 && fmi2DoStep(c, 0, 0.01, fmi2True) != fmi2Error) fail("a huge disturbance did not fail the run");
    return c;
}

static int call2(int which, fmi2Component c, const Refs *r, const char **name) {
    LOOKUP(fmi2SetDebugLogging); LOOKUP(fmi2SetupExperiment); LOOKUP(fmi2EnterInitializationMode);
    LOOKUP(fmi2ExitInitializationMode); LOOKUP(fmi2Terminate); LOOKUP(fmi2Reset); LOOKUP(fmi2GetReal);
    LOOKUP(fmi2GetInteger); LOOKUP(fmi2GetBoolean); LOOKUP(fmi2GetString); LOOKUP(fmi2SetReal); LOOKUP(fmi2SetInteger);
    LOOKUP(fmi2SetBoolean); LOOKUP(fmi2SetString); LOOKUP(fmi2GetFMUstate); LOOKUP(fmi2SetFMUstate);
    LOOKUP(fmi2FreeFMUstate); LOOKUP(fmi2SerializedFMUstateSize); LOOKUP(fmi2SerializeFMUstate);
    LOOKUP(fmi2DeSerializeFMUstate); LOOKUP(fmi2GetDirectionalDerivative); LOOKUP(fmi2SetRealInputDerivatives);
    LOOKUP(fmi2GetRealOutputDerivatives); LOOKUP(fmi2DoStep); LOOKUP(fmi2CancelStep); LOOKUP(fmi2GetStatus);
    LOOKUP(fmi2GetRealStatus); LOOKUP(fmi2GetIntegerStatus); LOOKUP(fmi2GetBooleanStatus);
    LOOKUP(fmi2GetStringStatus);
    double real[3] = {1, 2, 3};
    int integer = 5, boolean = 1;
    fmi2String string = "x";
    fmi2FMUstate state = NULL;
    fmi2Byte bytes[8] = {0};
    size_t size;
    fmi2Status status;
    fmi2String category = "logEvents";
    const fmi2ValueReference one = 0;
    const fmi2Integer order = 1;
    switch (which) {
#define CALL(number, text, expression) case number: *name = text; return expression;
    CALL(0, "SetDebugLogging", fmi2SetDebugLogging(c, fmi2True, 1, &category))
    CALL(1, "SetupExperiment", fmi2SetupExperiment(c, fmi2False, 0, 0, fmi2False, 0))
    CALL(2, "EnterInitializationMode", fmi2EnterInitializationMode(c))
    CALL(3, "ExitInitializationMode", fmi2ExitInitializationMode(c))
    CALL(4, "Terminate", fmi2Terminate(c))
    CALL(5, "Reset", fmi2Reset(c))
    CALL(6, "GetReal", fmi2GetReal(c, r->position, 3, real))
    CALL(7, "GetInteger", fmi2GetInteger(c, &r->periods_left, 1, &integer))
    CALL(8, "GetBoolean", fmi2GetBoolean(c, &r->at_limit, 1, &boolean))
    CALL(9, "GetString", fmi2GetString(c, &one, 1, &string))
    CALL(10, "SetReal(input)", fmi2SetReal(c, r->setpoint, 3, real))
    CALL(11, "SetReal(parameter)", fmi2SetReal(c, r->amplitude, 3, real))
    CALL(12, "SetInteger(parameter)", fmi2SetInteger(c, &r->seed, 1, &integer))
    CALL(13, "SetBoolean(output)", fmi2SetBoolean(c, &r->at_limit, 1, &boolean))
    CALL(14, "SetString", fmi2SetString(c, &one, 1, &string))
    CALL(15, "GetFMUstate", fmi2GetFMUstate(c, &state))
    CALL(16, "SetFMUstate", fmi2SetFMUstate(c, state))
    CALL(17, "FreeFMUstate", fmi2FreeFMUstate(c, &state))
    CALL(18, "SerializedFMUstateSize", fmi2SerializedFMUstateSize(c, state, &size))
    CALL(19, "SerializeFMUstate", fmi2SerializeFMUstate(c, state, bytes, sizeof bytes))
    CALL(20, "DeSerializeFMUstate", fmi2DeSerializeFMUstate(c, bytes, sizeof bytes, &state))
    CALL(21, "GetDirectionalDerivative", fmi2GetDirectionalDerivative(c, r->position, 1, r->setpoint, 1, real, real))
    CALL(22, "SetRealInputDerivatives", fmi2SetRealInputDerivatives(c, r->setpoint, 1, &order, real))
    CALL(23, "GetRealOutputDerivatives", fmi2GetRealOutputDerivatives(c, r->position, 1, &order, real))
    CALL(24, "DoStep", fmi2DoStep(c, 0, 0.01, fmi2True))
    CALL(25, "CancelStep", fmi2CancelStep(c))
    CALL(26, "GetStatus", fmi2GetStatus(c, fmi2DoStepStatus, &status))
    CALL(27, "GetRealStatus", fmi2GetRealStatus(c, fmi2LastSuccessfulTime, real))
    CALL(28, "GetIntegerStatus", fmi2GetIntegerStatus(c, fmi2DoStepStatus, &integer))
    CALL(29, "GetBooleanStatus", fmi2GetBooleanStatus(c, fmi2Terminated, &boolean))
    CALL(30, "GetStringStatus", fmi2GetStringStatus(c, fmi2PendingStatus, &string))
#undef CALL
    }
    return -1;
}

static int states2(void) {
    LOOKUP(fmi2FreeInstance);
    Refs r = refs();
    for (int state = 0; state < 5; state++)
        for (int which = 0; which < CALLS2; which++) {
            fmi2Component c = reach2(state, &r);
            const char *name = "";
            logged = 0;
            int status = call2(which, c, &r, &name);
            printf("%s %s %d %d\n", STATES[state], name, status, logged);
            fmi2FreeInstance(c);
        }
    for (int which = 0; which < CALLS2; which++) { /* no instance at all: an error, and nobody to log to */
        const char *name = "";
        logged = 0;
        int status = call2(which, NULL, &r, &name);
        printf("null %s %d %d\n", name, status, logged);
    }
    fmi2FreeInstance(NULL); /* allowed: nothing to free */
    return 0;
}

/* The rules the issue found broken in the Python FMU, each checked on a fresh instance. */
static int rules2(void) {
    LOOKUP(fmi2Instantiate); LOOKUP(fmi2EnterInitializationMode); LOOKUP(fmi2ExitInitializationMode);
    LOOKUP(fmi2SetReal); LOOKUP(fmi2GetReal); LOOKUP(fmi2DoStep); LOOKUP(fmi2FreeInstance); LOOKUP(fmi2GetInteger);
    Refs r = refs();
    fmi2Component c = fmi2Instantiate("host", fmi2CoSimulation, GUID, RESOURCES_URI, &CALLBACKS2, fmi2False, fmi2False);
    fmi2EnterInitializationMode(c);
    fmi2ExitInitializationMode(c);
    double nan = NAN, inf = INFINITY, got[3], before[3], value = 12.0;
    /* two refused SetReal calls, then DoStep: refused values not applied, the step goes on */
    logged = 0;
    int first = fmi2SetReal(c, r.setpoint, 1, &nan), second = fmi2SetReal(c, r.setpoint + 1, 1, &inf);
    fmi2GetReal(c, r.setpoint, 2, got);
    int step = fmi2DoStep(c, 0, 0.01, fmi2True);
    printf("nan-and-inf-refused %s %d %s\n", first == fmi2Error && second == fmi2Error && logged == 2 &&
           got[0] == 0 && got[1] == 0 && step == fmi2OK ? "ok" : "FAILED", logged, last_message);
    /* a call with one bad value applies none of its values */
    double mixed[2] = {5.0, NAN};
    fmi2SetReal(c, r.setpoint, 2, mixed);
    fmi2GetReal(c, r.setpoint, 1, got);
    printf("a-refused-call-applies-nothing %s\n", got[0] == 0 ? "ok" : "FAILED");
    /* a fixed parameter after initialisation */
    fmi2GetReal(c, r.amplitude, 1, before);
    logged = 0;
    int parameter = fmi2SetReal(c, r.amplitude, 1, &value);
    fmi2GetReal(c, r.amplitude, 1, got);
    printf("fixed-parameter-after-init-refused %s %s\n",
           parameter == fmi2Error && logged == 1 && got[0] == before[0] ? "ok" : "FAILED", last_message);
    /* a step of 1.5 periods, then a whole one from where the machine is */
    int left_before, left_after;
    fmi2GetInteger(c, &r.periods_left, 1, &left_before);
    logged = 0;
    int half = fmi2DoStep(c, 0.01, 0.015, fmi2True);
    printf("non-whole-step-refused %s %s\n", half == fmi2Error && logged == 1 ? "ok" : "FAILED", last_message);
    int whole = fmi2DoStep(c, 0.01, 0.02, fmi2True);
    fmi2GetInteger(c, &r.periods_left, 1, &left_after);
    printf("whole-step-after-it %s %d\n", whole == fmi2OK && left_before - left_after == 2 ? "ok" : "FAILED",
           left_before - left_after);
    /* a negative amplitude before initialisation: out of range */
    fmi2FreeInstance(c);
    c = fmi2Instantiate("host", fmi2CoSimulation, GUID, RESOURCES_URI, &CALLBACKS2, fmi2False, fmi2False);
    double negative = -1.0;
    logged = 0;
    int range = fmi2SetReal(c, r.amplitude, 1, &negative);
    printf("out-of-range-parameter-refused %s %s\n", range == fmi2Error && logged == 1 ? "ok" : "FAILED", last_message);
    fmi2FreeInstance(c);
    /* a wrong GUID */
    logged = 0;
    c = fmi2Instantiate("host", fmi2CoSimulation, "{not-this-one}", RESOURCES_URI, &CALLBACKS2, fmi2False, fmi2False);
    printf("wrong-guid-refused %s %s\n", !c && logged == 1 ? "ok" : "FAILED", last_message);
    return 0;
}

/* -- FMI 3.0 -------------------------------------------------------------------------------- */

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env, (void)category;
    snprintf(last_message, sizeof last_message, "%s", message);
    logged++;
    if (getenv("FMI_HOST_VERBOSE")) fprintf(stderr, "[%d] %s\n", status, message);
}

static fmi3Instance instantiate3(void) {
    LOOKUP(fmi3InstantiateCoSimulation);
    fmi3Instance c = fmi3InstantiateCoSimulation("host", GUID, RESOURCES_PATH, fmi3False, fmi3False, fmi3False,
                                                 fmi3False, NULL, 0, NULL, logger3, NULL);
    if (!c) fail("fmi3InstantiateCoSimulation failed: %s", last_message);
    return c;
}

static int run3(long periods, int quiet) {
    LOOKUP(fmi3EnterInitializationMode); LOOKUP(fmi3ExitInitializationMode); LOOKUP(fmi3SetFloat64);
    LOOKUP(fmi3GetFloat64); LOOKUP(fmi3GetInt32); LOOKUP(fmi3DoStep); LOOKUP(fmi3Terminate); LOOKUP(fmi3FreeInstance);
    Refs r = refs();
    fmi3Instance c = instantiate3();
    double zero[3] = {0, 0, 0}, period;
    if (fmi3EnterInitializationMode(c, fmi3False, 0, 0, fmi3False, 0) || fmi3SetFloat64(c, r.amplitude, 3, zero, 3) ||
        fmi3ExitInitializationMode(c) || fmi3GetFloat64(c, &r.period, 1, &period, 1))
        fail("initialisation failed: %s", last_message);
    unsigned measured[12];
    memcpy(measured, r.position, sizeof r.position), memcpy(measured + 3, r.velocity, sizeof r.velocity);
    memcpy(measured + 6, r.reference, sizeof r.reference);
    memcpy(measured + 9, r.reference_velocity, sizeof r.reference_velocity);
    fmi3Boolean event, terminate, early;
    double last;
    for (long k = 0; k < periods; k++) {
        double values[12], force[3];
        if (fmi3GetFloat64(c, measured, 12, values, 12)) fail("fmi3GetFloat64 failed: %s", last_message);
        if (!quiet) printf("%.17g %.17g %.17g\n", values[0], values[1], values[2]);
        pd(values, force);
        if (fmi3SetFloat64(c, r.setpoint, 3, force, 3)) fail("fmi3SetFloat64 failed: %s", last_message);
        if (fmi3DoStep(c, k * period, period, fmi3True, &event, &terminate, &early, &last))
            fail("fmi3DoStep %ld failed: %s", k, last_message);
    }
    int left;
    if (fmi3GetInt32(c, &r.periods_left, 1, &left, 1) || fmi3Terminate(c)) fail("the end failed: %s", last_message);
    fmi3FreeInstance(c);
    printf("end %d terminate %d\n", left, terminate);
    return 0;
}

#define CALLS3 27

static fmi3Instance reach3(int state, const Refs *r) {
    LOOKUP(fmi3EnterInitializationMode); LOOKUP(fmi3ExitInitializationMode); LOOKUP(fmi3Terminate);
    LOOKUP(fmi3DoStep); LOOKUP(fmi3SetFloat64);
    fmi3Instance c = instantiate3();
    double huge[3] = {1e300, 1e300, 1e300}, last;
    fmi3Boolean event, terminate, early;
    if (state >= 1 && fmi3EnterInitializationMode(c, fmi3False, 0, 0, fmi3False, 0)) fail("enter");
    if (state == 4 && fmi3SetFloat64(c, r->amplitude, 3, huge, 3)) fail("a huge disturbance refused");
    if (state >= 2 && fmi3ExitInitializationMode(c)) fail("exit");
    if (state == 3 && fmi3Terminate(c)) fail("terminate");
    if (state == 4 && fmi3DoStep(c, 0, 0.01, fmi3True, &event, &terminate, &early, &last) != fmi3Error)
        fail("a huge disturbance did not fail the run");
    return c;
}

static int call3(int which, fmi3Instance c, const Refs *r, const char **name) {
    LOOKUP(fmi3SetDebugLogging); LOOKUP(fmi3EnterInitializationMode); LOOKUP(fmi3ExitInitializationMode);
    LOOKUP(fmi3Terminate); LOOKUP(fmi3Reset); LOOKUP(fmi3GetFloat64); LOOKUP(fmi3GetInt32); LOOKUP(fmi3GetBoolean);
    LOOKUP(fmi3GetString); LOOKUP(fmi3SetFloat64); LOOKUP(fmi3SetInt32); LOOKUP(fmi3SetBoolean); LOOKUP(fmi3GetFloat32);
    LOOKUP(fmi3GetFMUState); LOOKUP(fmi3GetDirectionalDerivative); LOOKUP(fmi3DoStep); LOOKUP(fmi3EnterEventMode);
    LOOKUP(fmi3EnterStepMode); LOOKUP(fmi3EnterConfigurationMode); LOOKUP(fmi3ExitConfigurationMode);
    LOOKUP(fmi3UpdateDiscreteStates); LOOKUP(fmi3GetClock); LOOKUP(fmi3SetTime); LOOKUP(fmi3GetNumberOfContinuousStates);
    LOOKUP(fmi3GetOutputDerivatives); LOOKUP(fmi3GetIntervalDecimal); LOOKUP(fmi3GetNumberOfVariableDependencies);
    double real[3] = {1, 2, 3}, last;
    float single;
    int integer = 5;
    fmi3Boolean boolean = true, b1, b2, b3, b4, b5;
    fmi3String string, category = "logEvents";
    fmi3FMUState state = NULL;
    fmi3Clock clock;
    fmi3IntervalQualifier qualifier;
    size_t count;
    const fmi3ValueReference one = 0;
    const fmi3Int32 order = 1;
    switch (which) {
#define CALL(number, text, expression) case number: *name = text; return expression;
    CALL(0, "SetDebugLogging", fmi3SetDebugLogging(c, fmi3True, 1, &category))
    CALL(1, "EnterInitializationMode", fmi3EnterInitializationMode(c, fmi3False, 0, 0, fmi3False, 0))
    CALL(2, "ExitInitializationMode", fmi3ExitInitializationMode(c))
    CALL(3, "Terminate", fmi3Terminate(c))
    CALL(4, "Reset", fmi3Reset(c))
    CALL(5, "GetFloat64", fmi3GetFloat64(c, r->position, 3, real, 3))
    CALL(6, "GetInt32", fmi3GetInt32(c, &r->periods_left, 1, &integer, 1))
    CALL(7, "GetBoolean", fmi3GetBoolean(c, &r->at_limit, 1, &boolean, 1))
    CALL(8, "GetString", fmi3GetString(c, &one, 1, &string, 1))
    CALL(9, "SetFloat64(input)", fmi3SetFloat64(c, r->setpoint, 3, real, 3))
    CALL(10, "SetFloat64(parameter)", fmi3SetFloat64(c, r->amplitude, 3, real, 3))
    CALL(11, "SetInt32(parameter)", fmi3SetInt32(c, &r->seed, 1, &integer, 1))
    CALL(12, "SetBoolean(output)", fmi3SetBoolean(c, &r->at_limit, 1, &boolean, 1))
    CALL(13, "GetFloat32", fmi3GetFloat32(c, &one, 1, &single, 1))
    CALL(14, "GetFMUState", fmi3GetFMUState(c, &state))
    CALL(15, "GetDirectionalDerivative",
         fmi3GetDirectionalDerivative(c, r->position, 1, r->setpoint, 1, real, 1, real, 1))
    CALL(16, "DoStep", fmi3DoStep(c, 0, 0.01, fmi3True, &b1, &b2, &b3, &last))
    CALL(17, "EnterEventMode", fmi3EnterEventMode(c))
    CALL(18, "EnterStepMode", fmi3EnterStepMode(c))
    CALL(19, "EnterConfigurationMode", fmi3EnterConfigurationMode(c))
    CALL(20, "ExitConfigurationMode", fmi3ExitConfigurationMode(c))
    CALL(21, "UpdateDiscreteStates", fmi3UpdateDiscreteStates(c, &b1, &b2, &b3, &b4, &b5, &last))
    CALL(22, "GetClock", fmi3GetClock(c, &one, 1, &clock))
    CALL(23, "SetTime", fmi3SetTime(c, 1.0))
    CALL(24, "GetNumberOfContinuousStates", fmi3GetNumberOfContinuousStates(c, &count))
    CALL(25, "GetOutputDerivatives", fmi3GetOutputDerivatives(c, r->position, 1, &order, real, 1))
    CALL(26, "GetIntervalDecimal", fmi3GetIntervalDecimal(c, &one, 1, real, &qualifier))
#undef CALL
    }
    (void)fmi3GetNumberOfVariableDependencies;
    return -1;
}

static int states3(void) {
    LOOKUP(fmi3FreeInstance);
    Refs r = refs();
    for (int state = 0; state < 5; state++)
        for (int which = 0; which < CALLS3; which++) {
            fmi3Instance c = reach3(state, &r);
            const char *name = "";
            logged = 0;
            int status = call3(which, c, &r, &name);
            printf("%s %s %d %d\n", STATES[state], name, status, logged);
            fmi3FreeInstance(c);
        }
    for (int which = 0; which < CALLS3; which++) {
        const char *name = "";
        logged = 0;
        int status = call3(which, NULL, &r, &name);
        printf("null %s %d %d\n", name, status, logged);
    }
    fmi3FreeInstance(NULL);
    return 0;
}

static int rules3(void) {
    LOOKUP(fmi3EnterInitializationMode); LOOKUP(fmi3ExitInitializationMode); LOOKUP(fmi3SetFloat64);
    LOOKUP(fmi3GetFloat64); LOOKUP(fmi3DoStep); LOOKUP(fmi3FreeInstance);
    Refs r = refs();
    fmi3Instance c = instantiate3();
    fmi3EnterInitializationMode(c, fmi3False, 0, 0, fmi3False, 0);
    fmi3ExitInitializationMode(c);
    double nan = NAN, got[3], before[3], value = 12.0, last;
    fmi3Boolean event, terminate, early;
    logged = 0;
    int first = fmi3SetFloat64(c, r.setpoint, 1, &nan, 1);
    fmi3GetFloat64(c, r.setpoint, 1, got, 1);
    int step = fmi3DoStep(c, 0, 0.01, fmi3True, &event, &terminate, &early, &last);
    printf("nan-refused %s %s\n", first == fmi3Error && logged == 1 && got[0] == 0 && step == fmi3OK ? "ok" : "FAILED",
           last_message);
    fmi3GetFloat64(c, r.amplitude, 1, before, 1);
    logged = 0;
    int parameter = fmi3SetFloat64(c, r.amplitude, 1, &value, 1);
    fmi3GetFloat64(c, r.amplitude, 1, got, 1);
    printf("fixed-parameter-after-init-refused %s %s\n",
           parameter == fmi3Error && logged == 1 && got[0] == before[0] ? "ok" : "FAILED", last_message);
    logged = 0;
    int half = fmi3DoStep(c, 0.01, 0.015, fmi3True, &event, &terminate, &early, &last);
    printf("non-whole-step-refused %s %s\n", half == fmi3Error && logged == 1 && last == 0.01 ? "ok" : "FAILED",
           last_message);
    fmi3FreeInstance(c);
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 4) fail("usage: fmi_host DIR run|states|rules 2|3 [PERIODS [quiet]]");
    const char *dir = argv[1], *mode = argv[2];
    int fmi = atoi(argv[3]);
    char path[4096];
    snprintf(path, sizeof path, "%s/binaries/%s/BwrReclaimer.so", dir, fmi == 2 ? "linux64" : "x86_64-linux");
    library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) fail("dlopen: %s", dlerror());
    GUID = getenv("FMU_GUID");
    if (!GUID) fail("no FMU_GUID in the environment");
    snprintf(RESOURCES_URI, sizeof RESOURCES_URI, "file://%s/resources", dir);
    snprintf(RESOURCES_PATH, sizeof RESOURCES_PATH, "%s/resources/", dir);
    int status;
    if (!strcmp(mode, "bench") && fmi == 2 && argc == 5) {
        status = run2(atol(argv[4]), 1);
        printf("%ld %.9f\n", atol(argv[4]), loop_seconds);
    } else if (!strcmp(mode, "run")) {
        long periods = argc > 4 ? atol(argv[4]) : 1;
        int quiet = argc > 5 && !strcmp(argv[5], "quiet");
        status = fmi == 2 ? run2(periods, quiet) : run3(periods, quiet);
    } else if (!strcmp(mode, "states")) status = fmi == 2 ? states2() : states3();
    else if (!strcmp(mode, "rules")) status = fmi == 2 ? rules2() : rules3();
    else if (!strcmp(mode, "disturbance") && argc == 7) status = disturbance2(atol(argv[4]), atoi(argv[5]), atof(argv[6]));
    else fail("unknown mode %s", mode);
    dlclose(library);
    return status;
}
