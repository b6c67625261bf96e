/* The reclaimer of one scene, stepped a control period at a time: what the twin's plant does for a
   run of a path scene (bwr_twin/sim/plant.py, lockstep.py, encoders.py, disturbances.py), in C.

   The FMI layers (fmi2.c, fmi3.c) keep nothing of their own: the variables, the FMI state
   machine and the run live here, and every refusal is logged through `log` with its reason. */
#ifndef RECLAIMER_H
#define RECLAIMER_H

#include <stddef.h>

#include "variables.h" /* written by python -m bwr_twin.export fmu from the variable table */

/* The FMI states both versions share (FMI 2.0 section 4.2.4, FMI 3.0 section 4.2). */
typedef enum {
    STATE_INSTANTIATED = 1,
    STATE_INITIALIZATION = 2,
    STATE_STEP = 4,
    STATE_TERMINATED = 8,
    STATE_ERROR = 16 /* the run failed (it diverged): only reads, a reset and freeing remain */
} State;

#define STATES_ANY (STATE_INSTANTIATED | STATE_INITIALIZATION | STATE_STEP | STATE_TERMINATED | STATE_ERROR)
#define STATES_READ (STATE_INITIALIZATION | STATE_STEP | STATE_TERMINATED | STATE_ERROR)

/* error: nonzero for a refusal or a failure (FMI's Error), zero for information (OK). */
typedef void (*Logger)(void *owner, int error, const char *message);

typedef struct Reclaimer Reclaimer;

/* A reclaimer from the FMU's resources folder (a path); NULL, with `log` told why, if it cannot
   be read. `owner` is passed back to `log`. */
Reclaimer *reclaimer_new(const char *resources, Logger log, void *owner, int log_info);
void reclaimer_free(Reclaimer *r);

State reclaimer_state(const Reclaimer *r);
void reclaimer_set_state(Reclaimer *r, State state);
void reclaimer_log_info(Reclaimer *r, int on);

/* Nonzero if `call` is allowed in the current state (a bitmask of States); else logs why. */
int reclaimer_allowed(Reclaimer *r, const char *call, unsigned states);
/* Log a refusal of `call`; always returns 0. */
int reclaimer_refuse(Reclaimer *r, const char *call, const char *format, ...);

/* Values by value reference. The setters check every value first and change nothing on a
   refusal; each returns nonzero on success. */
int reclaimer_get_real(Reclaimer *r, const char *call, const unsigned *vr, size_t n, double *out);
int reclaimer_get_integer(Reclaimer *r, const char *call, const unsigned *vr, size_t n, int *out);
int reclaimer_get_boolean(Reclaimer *r, const char *call, const unsigned *vr, size_t n, int *out);
int reclaimer_set_real(Reclaimer *r, const char *call, const unsigned *vr, size_t n, const double *values);
int reclaimer_set_integer(Reclaimer *r, const char *call, const unsigned *vr, size_t n, const int *values);
int reclaimer_set_boolean(Reclaimer *r, const char *call, const unsigned *vr, size_t n, const int *values);

/* The run anew with the parameters as set (leaving initialisation mode). */
void reclaimer_start(Reclaimer *r);
/* Parameters and inputs back to their start values, the run anew, state instantiated. */
void reclaimer_reset(Reclaimer *r);
/* Advance from time `t` by `h` s, a whole number of control periods: 1 on success, 0 if refused
   (nothing changed), -1 if the run failed (state error). */
int reclaimer_step(Reclaimer *r, const char *call, double t, double h);
/* Nonzero once the path's last control period has been advanced. */
int reclaimer_done(const Reclaimer *r);
double reclaimer_time(const Reclaimer *r);

#endif
