/* The reclaimer of one scene in C: see reclaimer.h. Its resources, written by
   python -m bwr_twin.export fmu:
     model.mjb   the machine as the twin's plant compiles it (bwr_twin/model/spec.py's edits, the
                 scene's friction loss), saved by MuJoCo: the same compiled model, bit for bit
     path.bin    the path: per control period, position, velocity, acceleration of the three
                 axes (9 float64, little-endian)
     plant.txt   the run's numbers: "name value..." lines, and "start VR VALUE" for the
                 parameters' and inputs' start values */
#define VARIABLE_TABLES /* this file reads the variable table of variables.h */
#include "reclaimer.h"

#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <mujoco/mujoco.h>

#define MESSAGE 1024
#define STEP_TOLERANCE 1e-9 /* relative: a step this close to a whole number of periods counts as one */

struct Reclaimer {
    Logger log;
    void *owner;
    int log_info;
    State state;
    mjModel *model;
    mjData *data;
    /* the run's numbers (plant.txt) */
    double period;
    int substeps;
    long samples;
    double *path; /* samples x 9 */
    int actuator[3];
    double gear[3], start_q[3], low[3], high[3], wind_direction[3];
    int velocity_estimated;
    double velocity_filter;
    /* the variables by value reference, and their start values */
    double real[VARIABLE_COUNT], real_start[VARIABLE_COUNT];
    int integer[VARIABLE_COUNT], integer_start[VARIABLE_COUNT];
    int boolean[VARIABLE_COUNT];
    /* the run */
    long k;
    double resolution[3], filter_gain, q_previous[3], qd_estimate[3];
    double amplitude[3], hold;
    int disturbed;
    uint64_t rng[4];
    long drawn; /* hold intervals drawn so far */
    double disturbance[3];
};

/* -- MuJoCo's errors and warnings ------------------------------------------------------------- */
/* MuJoCo's handlers are the process's, shared with whatever else in the host uses MuJoCo. Ours
   are installed while an instance lives and chain to the host's: an error or a warning in a call
   of this file (`hearing`, per thread) is this file's, any other goes where it went before. The
   last instance freed puts the host's back, so unloading this library leaves no handler behind. */

#if defined(_MSC_VER)
#include <windows.h>
#define THREAD_LOCAL __declspec(thread) /* MSVC's C has no _Thread_local */
static volatile LONG live_instances;
#define ADD_INSTANCES(n) InterlockedExchangeAdd(&live_instances, (n))
#else
#include <stdatomic.h>
#define THREAD_LOCAL _Thread_local
static atomic_int live_instances;
#define ADD_INSTANCES(n) atomic_fetch_add(&live_instances, (n))
#endif

static THREAD_LOCAL int hearing;
static THREAD_LOCAL jmp_buf *mujoco_error_exit;
static THREAD_LOCAL char mujoco_error_text[256];
static void (*host_error)(const char *), (*host_warning)(const char *);

static void on_mujoco_error(const char *text) {
    if (hearing && mujoco_error_exit) {
        snprintf(mujoco_error_text, sizeof mujoco_error_text, "%s", text);
        longjmp(*mujoco_error_exit, 1);
    }
    if (host_error) host_error(text);
    else { /* MuJoCo's own behaviour without a handler */
        fprintf(stderr, "ERROR: %s\n", text);
        exit(EXIT_FAILURE);
    }
}

static void on_mujoco_warning(const char *text) {
    if (hearing) return; /* the data's warning counters say it: read after each period */
    if (host_warning) host_warning(text);
    else fprintf(stderr, "WARNING: %s\n", text);
}

static void install_handlers(void) {
    void (*error)(const char *) = mju_user_error, (*warning)(const char *) = mju_user_warning;
    if (error != on_mujoco_error) host_error = error, mju_user_error = on_mujoco_error;
    if (warning != on_mujoco_warning) host_warning = warning, mju_user_warning = on_mujoco_warning;
}

static void remove_handlers(void) {
    if (mju_user_error == on_mujoco_error) mju_user_error = host_error;
    if (mju_user_warning == on_mujoco_warning) mju_user_warning = host_warning;
}

/* This thread's MuJoCo calls are the FMU's until stop_hearing(); ours installed again if the host
   replaced them since. */
static void hear_mujoco(void) {
    install_handlers();
    hearing = 1;
}

static void stop_hearing(void) { hearing = 0; }

/* -- logging ----------------------------------------------------------------------------- */

static void say(Reclaimer *r, int error, const char *format, va_list args) {
    char message[MESSAGE];
    vsnprintf(message, sizeof message, format, args);
    if (r->log && (error || r->log_info)) r->log(r->owner, error, message);
}

int reclaimer_refuse(Reclaimer *r, const char *call, const char *format, ...) {
    char text[MESSAGE];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    char message[MESSAGE + 64];
    snprintf(message, sizeof message, "%s: %s", call, text);
    if (r->log) r->log(r->owner, 1, message);
    return 0;
}

static void inform(Reclaimer *r, const char *format, ...) {
    va_list args;
    va_start(args, format);
    say(r, 0, format, args);
    va_end(args);
}

static const char *state_name(State state) {
    switch (state) {
    case STATE_INSTANTIATED: return "instantiated";
    case STATE_INITIALIZATION: return "initialization mode";
    case STATE_STEP: return "step mode (initialised)";
    case STATE_TERMINATED: return "terminated";
    case STATE_ERROR: return "error (the run failed; reset or free the instance)";
    }
    return "unknown";
}

int reclaimer_allowed(Reclaimer *r, const char *call, unsigned states) {
    if (states & r->state) return 1;
    char allowed[256] = "";
    for (unsigned s = STATE_INSTANTIATED; s <= STATE_ERROR; s <<= 1) {
        if (!(states & s)) continue;
        if (allowed[0]) strncat(allowed, ", ", sizeof allowed - strlen(allowed) - 1);
        strncat(allowed, state_name((State)s), sizeof allowed - strlen(allowed) - 1);
    }
    return reclaimer_refuse(r, call, "not allowed in state %s; allowed in: %s", state_name(r->state),
                            allowed[0] ? allowed : "none (not supported by this FMU)");
}

State reclaimer_state(const Reclaimer *r) { return r->state; }
void reclaimer_set_state(Reclaimer *r, State state) { r->state = state; }
void reclaimer_log_info(Reclaimer *r, int on) { r->log_info = on; }
int reclaimer_done(const Reclaimer *r) { return r->k >= r->samples; }
double reclaimer_time(const Reclaimer *r) { return r->k * r->period; }

/* -- reading the resources ------------------------------------------------------------------ */

static char *joined(const char *folder, const char *name) {
    size_t n = strlen(folder) + strlen(name) + 2;
    char *path = malloc(n);
    if (path) snprintf(path, n, "%s/%s", folder, name);
    return path;
}

static int read_numbers(FILE *file, double *out, int count) {
    for (int i = 0; i < count; i++)
        if (fscanf(file, "%lf", &out[i]) != 1) return 0;
    return 1;
}

/* plant.txt; 0 with `why` filled on a missing or bad line. */
static int read_plant(Reclaimer *r, const char *path, char *why, size_t n) {
    FILE *file = fopen(path, "r");
    if (!file) {
        snprintf(why, n, "%s: cannot be read", path);
        return 0;
    }
    char name[64];
    int seen = 0, ok = 1;
    while (ok && fscanf(file, "%63s", name) == 1) {
        double v[3];
        if (!strcmp(name, "period")) ok = read_numbers(file, &r->period, 1), seen |= 1;
        else if (!strcmp(name, "substeps")) ok = read_numbers(file, v, 1), r->substeps = (int)v[0], seen |= 2;
        else if (!strcmp(name, "actuators")) {
            ok = read_numbers(file, v, 3);
            for (int j = 0; j < 3; j++) r->actuator[j] = (int)v[j];
            seen |= 4;
        } else if (!strcmp(name, "gear")) ok = read_numbers(file, r->gear, 3), seen |= 8;
        else if (!strcmp(name, "start")) ok = read_numbers(file, r->start_q, 3), seen |= 16;
        else if (!strcmp(name, "low")) ok = read_numbers(file, r->low, 3), seen |= 32;
        else if (!strcmp(name, "high")) ok = read_numbers(file, r->high, 3), seen |= 64;
        else if (!strcmp(name, "wind_direction")) ok = read_numbers(file, r->wind_direction, 3), seen |= 128;
        else if (!strcmp(name, "velocity_estimated"))
            ok = read_numbers(file, v, 1), r->velocity_estimated = v[0] != 0, seen |= 256;
        else if (!strcmp(name, "velocity_filter")) ok = read_numbers(file, &r->velocity_filter, 1), seen |= 512;
        else if (!strcmp(name, "value")) {
            ok = read_numbers(file, v, 2);
            long vr = (long)v[0];
            if (ok && (vr < 0 || vr >= VARIABLE_COUNT)) ok = 0;
            if (ok) r->real_start[vr] = v[1], r->integer_start[vr] = (int)v[1];
        } else ok = 0;
    }
    fclose(file);
    if (!ok || seen != 1023) {
        snprintf(why, n, "%s: %s", path, ok ? "a line is missing" : "a line is not understood");
        return 0;
    }
    if (!(r->period > 0) || r->substeps < 1) {
        snprintf(why, n, "%s: period and substeps must be positive", path);
        return 0;
    }
    return 1;
}

static int read_path(Reclaimer *r, const char *path, char *why, size_t n) {
    FILE *file = fopen(path, "rb");
    if (!file) {
        snprintf(why, n, "%s: cannot be read", path);
        return 0;
    }
    fseek(file, 0, SEEK_END);
    long bytes = ftell(file);
    fseek(file, 0, SEEK_SET);
    long row = 9 * (long)sizeof(double);
    if (bytes <= 0 || bytes % row) {
        fclose(file);
        snprintf(why, n, "%s: %ld bytes, not whole rows of 9 float64", path, bytes);
        return 0;
    }
    r->samples = bytes / row;
    r->path = malloc((size_t)bytes);
    size_t got = r->path ? fread(r->path, 1, (size_t)bytes, file) : 0;
    fclose(file);
    if (got != (size_t)bytes) {
        snprintf(why, n, "%s: cannot be read whole", path);
        return 0;
    }
    return 1;
}

static int load_model(Reclaimer *r, const char *path, char *why, size_t n) {
    hear_mujoco();
    jmp_buf escape;
    mujoco_error_exit = &escape;
    if (setjmp(escape)) {
        mujoco_error_exit = NULL;
        stop_hearing();
        snprintf(why, n, "%s: MuJoCo: %s", path, mujoco_error_text);
        return 0;
    }
    r->model = mj_loadModel(path, NULL);
    if (r->model) r->data = mj_makeData(r->model);
    mujoco_error_exit = NULL;
    stop_hearing();
    if (!r->model || !r->data) {
        snprintf(why, n, "%s: MuJoCo %s cannot load it (a model saved by another MuJoCo version?)", path,
                 mj_versionString());
        return 0;
    }
    if (r->model->nq < 3 || r->model->nv < 3) {
        snprintf(why, n, "%s: the model has fewer than the three joints travel, slew, luff", path);
        return 0;
    }
    for (int j = 0; j < 3; j++)
        if (r->actuator[j] < 0 || r->actuator[j] >= r->model->nu || r->gear[j] == 0) {
            snprintf(why, n, "%s: actuator %d of the plant's numbers is not the model's", path, r->actuator[j]);
            return 0;
        }
    return 1;
}

Reclaimer *reclaimer_new(const char *resources, Logger log, void *owner, int log_info) {
    Reclaimer *r = calloc(1, sizeof *r);
    if (!r) return NULL;
    if (ADD_INSTANCES(1) == 0) install_handlers();
    r->log = log, r->owner = owner, r->log_info = log_info;
    char why[MESSAGE] = "";
    char *plant = joined(resources, "plant.txt"), *path = joined(resources, "path.bin"),
         *model = joined(resources, "model.mjb");
    int ok = plant && path && model && read_plant(r, plant, why, sizeof why) && read_path(r, path, why, sizeof why) &&
             load_model(r, model, why, sizeof why);
    free(plant), free(path), free(model);
    if (!ok) {
        if (log) log(owner, 1, why[0] ? why : "out of memory");
        reclaimer_free(r);
        return NULL;
    }
    reclaimer_reset(r);
    inform(r, "MuJoCo %s, %ld control periods of %g s, %d physics steps each", mj_versionString(), r->samples,
           r->period, r->substeps);
    return r;
}

void reclaimer_free(Reclaimer *r) {
    if (!r) return;
    if (ADD_INSTANCES(-1) == 1) remove_handlers();
    if (r->data) mj_deleteData(r->data);
    if (r->model) mj_deleteModel(r->model);
    free(r->path);
    free(r);
}

/* -- the disturbances: uniform in [-amplitude, amplitude], redrawn every hold time ------------ */
/* xoshiro256** seeded through splitmix64: the seed alone decides the stream. numpy's stream
   (bwr_twin/sim/disturbances.py) is not reproduced; its statistics are. */

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

static uint64_t next(uint64_t s[4]) {
    uint64_t result = rotl(s[1] * 5, 7) * 9, t = s[1] << 17;
    s[2] ^= s[0], s[3] ^= s[1], s[1] ^= s[2], s[0] ^= s[3], s[2] ^= t, s[3] = rotl(s[3], 45);
    return result;
}

static double uniform(uint64_t s[4]) { return (double)(next(s) >> 11) * 0x1.0p-53 * 2.0 - 1.0; }

static void sample_disturbance(Reclaimer *r) {
    if (!r->disturbed) return; /* all zero: nothing drawn, as the twin */
    /* the draw period k holds: one per hold time (1e-9 absorbs k * period / hold rounding) */
    long index = (long)floor((double)r->k * r->period / r->hold + 1e-9);
    while (r->drawn <= index) {
        for (int j = 0; j < 3; j++) r->disturbance[j] = uniform(r->rng) * r->amplitude[j];
        r->drawn++;
    }
}

/* -- the run --------------------------------------------------------------------------------- */

/* The encoders, the reference and the limit switches of period k (once a period: the velocity
   filter has state), as bwr_twin/sim/twin.py's _measure. */
static void measure(Reclaimer *r) {
    const double *q = r->data->qpos, *qd = r->data->qvel, *row = r->path + 9 * r->k;
    for (int j = 0; j < 3; j++) {
        double measured = nearbyint(q[j] / r->resolution[j]) * r->resolution[j]; /* halves to even, as numpy */
        double velocity = qd[j];
        if (r->velocity_estimated) {
            double difference = (measured - r->q_previous[j]) / r->period;
            r->qd_estimate[j] += (difference - r->qd_estimate[j]) * r->filter_gain;
            r->q_previous[j] = measured;
            velocity = r->qd_estimate[j];
        }
        r->real[VR_ENCODER_POSITION + j] = measured;
        r->real[VR_ENCODER_VELOCITY + j] = velocity;
        r->real[VR_REFERENCE_POSITION + j] = row[j];
        r->real[VR_REFERENCE_VELOCITY + j] = row[3 + j];
        r->real[VR_REFERENCE_ACCELERATION + j] = row[6 + j];
        r->boolean[VR_AT_LIMIT + j] = q[j] <= r->low[j] || q[j] >= r->high[j];
    }
}

static void read_outputs(Reclaimer *r) {
    for (int j = 0; j < 3; j++) {
        r->real[VR_DRIVE_APPLIED + j] = r->k > 0 ? r->data->qfrc_actuator[j] : 0.0;
        r->real[VR_DISTURBANCE_FORCE + j] = r->k > 0 ? r->disturbance[j] : 0.0;
    }
    r->integer[VR_PERIODS_LEFT] = (int)(r->samples - r->k);
    r->real[VR_TIME] = r->k * r->period;
}

void reclaimer_start(Reclaimer *r) {
    mjModel *m = r->model;
    mjData *d = r->data;
    mj_resetData(m, d);
    for (int j = 0; j < 3; j++) d->qpos[j] = r->start_q[j];
    hear_mujoco();
    mj_forward(m, d);
    stop_hearing();
    r->k = 0;
    for (int j = 0; j < 3; j++) {
        r->resolution[j] = r->real[VR_ENCODER_RESOLUTION + j];
        r->q_previous[j] = nearbyint(r->start_q[j] / r->resolution[j]) * r->resolution[j];
        r->qd_estimate[j] = 0.0;
        r->amplitude[j] = r->real[VR_DISTURBANCE_AMPLITUDE + j];
        r->disturbance[j] = 0.0;
    }
    r->filter_gain = r->period / (r->velocity_filter + r->period);
    r->hold = r->real[VR_DISTURBANCE_HOLD_TIME];
    r->disturbed = r->amplitude[0] != 0 || r->amplitude[1] != 0 || r->amplitude[2] != 0;
    uint64_t seed = (uint64_t)(int64_t)r->integer[VR_SEED];
    for (int i = 0; i < 4; i++) r->rng[i] = splitmix64(&seed);
    r->drawn = 0;
    measure(r);
    read_outputs(r);
}

void reclaimer_reset(Reclaimer *r) {
    memcpy(r->real, r->real_start, sizeof r->real);
    memcpy(r->integer, r->integer_start, sizeof r->integer);
    memset(r->boolean, 0, sizeof r->boolean);
    r->real[VR_CONTROL_PERIOD] = r->period;
    r->state = STATE_INSTANTIATED;
    reclaimer_start(r);
}

static const char *warning_meaning(int kind) {
    switch (kind) {
    case mjWARN_INERTIA: return "a body's inertia is too small";
    case mjWARN_CONTACTFULL: return "too many contacts";
    case mjWARN_CNSTRFULL: return "too many constraints";
    case mjWARN_BADQPOS: return "bad joint positions";
    case mjWARN_BADQVEL: return "bad joint velocities";
    case mjWARN_BADQACC: return "bad joint accelerations";
    case mjWARN_BADCTRL: return "bad controls";
    }
    return "a warning";
}

/* One control period under the drive setpoints and the period's disturbance, as the twin's
   lockstep advances it: the drives' controls (force over gear; the actuators' force ranges are
   the drives' ratings), the disturbance through qfrc_applied, the wind, the physics steps. */
static int advance(Reclaimer *r, const char *call) {
    mjModel *m = r->model;
    mjData *d = r->data;
    sample_disturbance(r);
    for (int j = 0; j < 3; j++) {
        d->ctrl[r->actuator[j]] = r->real[VR_DRIVE_SETPOINT + j] / r->gear[j];
        d->qfrc_applied[j] = r->disturbance[j];
    }
    m->opt.density = r->real[VR_AIR_DENSITY];
    for (int i = 0; i < 3; i++) m->opt.wind[i] = r->real[VR_WIND_SPEED] * r->wind_direction[i];
    hear_mujoco();
    jmp_buf escape;
    mujoco_error_exit = &escape;
    if (setjmp(escape)) {
        mujoco_error_exit = NULL;
        stop_hearing();
        return reclaimer_refuse(r, call, "the run failed: MuJoCo: %s, near t = %.2f s", mujoco_error_text,
                                d->time);
    }
    for (int s = 0; s < r->substeps; s++) mj_step(m, d);
    mujoco_error_exit = NULL;
    stop_hearing();
    for (int w = 0; w < mjNWARNING; w++)
        if (d->warning[w].number > 0)
            return reclaimer_refuse(r, call, "the run diverged: MuJoCo: %s, near t = %.2f s", warning_meaning(w),
                                    d->time);
    for (int j = 0; j < 3; j++)
        if (!isfinite(d->qpos[j]) || !isfinite(d->qvel[j]))
            return reclaimer_refuse(r, call, "the run diverged: non-finite state, near t = %.2f s", d->time);
    r->k++;
    if (r->k < r->samples) measure(r); /* at the end, the last period's encoders stay */
    return 1;
}

int reclaimer_step(Reclaimer *r, const char *call, double t, double h) {
    double periods = h / r->period, whole = nearbyint(periods);
    if (!isfinite(h) || whole < 1 || fabs(periods - whole) > STEP_TOLERANCE * whole)
        return reclaimer_refuse(r, call, "a communication step of %.17g s is not a whole number of control periods "
                                "(%.17g s); step by n x %.17g s, n >= 1", h, r->period, r->period);
    double now = r->k * r->period;
    if (!isfinite(t) || fabs(t - now) > STEP_TOLERANCE * fmax(1.0, fabs(t)))
        return reclaimer_refuse(r, call, "the step starts at t = %.17g s, the machine is at t = %.17g s; steps "
                                "follow each other without gaps", t, now);
    if (whole > (double)(r->samples - r->k))
        return reclaimer_refuse(r, call, "a step of %.0f control periods passes the path's end at t = %g s (%ld "
                                "periods left)", whole, r->samples * r->period, r->samples - r->k);
    for (long i = 0; i < (long)whole; i++)
        if (!advance(r, call)) {
            r->state = STATE_ERROR;
            read_outputs(r);
            return -1;
        }
    read_outputs(r);
    return 1;
}

/* -- the variables ----------------------------------------------------------------------------- */

static const char *type_name(char type) {
    return type == 'r' ? "Real (Float64)" : type == 'i' ? "Integer (Int32)" : "Boolean";
}

static int check_references(Reclaimer *r, const char *call, const unsigned *vr, size_t n, const void *values,
                            char type) {
    if (n > 0 && (!vr || !values)) return reclaimer_refuse(r, call, "a null array for %zu values", n);
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= VARIABLE_COUNT)
            return reclaimer_refuse(r, call, "value reference %u is not a variable of this FMU", vr[i]);
        if (VARIABLE_TYPE[vr[i]] != type)
            return reclaimer_refuse(r, call, "value reference %u (%s) is a %s, not a %s", vr[i], VARIABLE_NAME[vr[i]],
                                    type_name(VARIABLE_TYPE[vr[i]]), type_name(type));
    }
    return 1;
}

/* May variable `vr` be set now? Inputs: before and after initialisation; fixed parameters: only
   before leaving initialisation mode; outputs and calculated parameters: never. */
static int settable(Reclaimer *r, const char *call, unsigned vr) {
    char kind = VARIABLE_KIND[vr];
    if (kind == 'i') return 1;
    if (kind == 'p') {
        if (r->state & (STATE_INSTANTIATED | STATE_INITIALIZATION)) return 1;
        return reclaimer_refuse(r, call, "%s is a fixed parameter: it is set before fmiExitInitializationMode, "
                                "not in state %s", VARIABLE_NAME[vr], state_name(r->state));
    }
    return reclaimer_refuse(r, call, "%s is %s: it cannot be set", VARIABLE_NAME[vr],
                            kind == 'o' ? "an output" : kind == 'c' ? "a calculated parameter" : "the independent variable");
}

static int in_range(Reclaimer *r, const char *call, unsigned vr, double value) {
    /* as the OPC UA server answers a non-finite setpoint (BadOutOfRange): refused, not applied */
    if (!isfinite(value))
        return reclaimer_refuse(r, call, "%s = %g: must be a finite number; the call is refused and no value "
                                "of it applied", VARIABLE_NAME[vr], value);
    double low = VARIABLE_MIN[vr];
    if (VARIABLE_MIN_OPEN[vr] == '1' ? !(value > low) : !(value >= low))
        return reclaimer_refuse(r, call, "%s = %.17g: must be %s %g; the call is refused and no value of it "
                                "applied", VARIABLE_NAME[vr], value, VARIABLE_MIN_OPEN[vr] == '1' ? ">" : ">=", low);
    return 1;
}

int reclaimer_get_real(Reclaimer *r, const char *call, const unsigned *vr, size_t n, double *out) {
    if (!check_references(r, call, vr, n, out, 'r')) return 0;
    for (size_t i = 0; i < n; i++) out[i] = r->real[vr[i]];
    return 1;
}

int reclaimer_get_integer(Reclaimer *r, const char *call, const unsigned *vr, size_t n, int *out) {
    if (!check_references(r, call, vr, n, out, 'i')) return 0;
    for (size_t i = 0; i < n; i++) out[i] = r->integer[vr[i]];
    return 1;
}

int reclaimer_get_boolean(Reclaimer *r, const char *call, const unsigned *vr, size_t n, int *out) {
    if (!check_references(r, call, vr, n, out, 'b')) return 0;
    for (size_t i = 0; i < n; i++) out[i] = r->boolean[vr[i]];
    return 1;
}

int reclaimer_set_real(Reclaimer *r, const char *call, const unsigned *vr, size_t n, const double *values) {
    if (!check_references(r, call, vr, n, values, 'r')) return 0;
    for (size_t i = 0; i < n; i++)
        if (!settable(r, call, vr[i]) || !in_range(r, call, vr[i], values[i])) return 0;
    for (size_t i = 0; i < n; i++) r->real[vr[i]] = values[i];
    return 1;
}

int reclaimer_set_integer(Reclaimer *r, const char *call, const unsigned *vr, size_t n, const int *values) {
    if (!check_references(r, call, vr, n, values, 'i')) return 0;
    for (size_t i = 0; i < n; i++)
        if (!settable(r, call, vr[i]) || !in_range(r, call, vr[i], values[i])) return 0;
    for (size_t i = 0; i < n; i++) r->integer[vr[i]] = values[i];
    return 1;
}

int reclaimer_set_boolean(Reclaimer *r, const char *call, const unsigned *vr, size_t n, const int *values) {
    if (!check_references(r, call, vr, n, values, 'b')) return 0;
    for (size_t i = 0; i < n; i++)
        if (!settable(r, call, vr[i])) return 0;
    return 1; /* no Boolean is settable: settable() refused above */
}
