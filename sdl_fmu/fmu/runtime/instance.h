/* One FMU instance: the generic state the FMI layer works on (no model knowledge here). */
#ifndef SDL_FMU_INSTANCE_H
#define SDL_FMU_INSTANCE_H

#include "model.h"

typedef enum {
    STATUS_OK = 0,
    STATUS_WARNING = 1,
    STATUS_DISCARD = 2,
    STATUS_ERROR = 3,
    STATUS_FATAL = 4
} Status;

typedef enum {
    MODE_INSTANTIATED = 1 << 0,
    MODE_INITIALIZATION = 1 << 1,
    MODE_EVENT = 1 << 2,
    MODE_CONTINUOUS_TIME = 1 << 3,
    MODE_STEP = 1 << 4,
    MODE_TERMINATED = 1 << 5,
    MODE_ERROR = 1 << 6
} Mode;

typedef void *(*AllocateFn)(size_t count, size_t size);
typedef void (*FreeFn)(void *pointer);
/* status, category, message: the FMI layer turns this into the importer's logger call */
typedef void (*LogFn)(void *instance, Status status, const char *category, const char *message);

#define SNAPSHOT_TAG 0x53444c46u /* "SDLF": marks memory that snapshot_create made */

/* The part of an instance that fmi2GetFMUstate saves and fmi2SetFMUstate restores. */
typedef struct {
    unsigned int tag; /* set by snapshot_create: SetFMUstate refuses anything else */
    double time;
    Mode mode;
    double solver_step_next; /* the error-controlled solver's next internal step [s] (0: none yet) */
    double *x, *d, *u, *p;
} Snapshot;

typedef struct Instance {
    const ModelInfo *info;
    void *model_data;      /* the model's own per-instance data (ModelHooks.instantiate; NULL for the ego models) */
    char *name;
    int is_cosimulation;
    int logging_on;        /* debug logging (OK-status messages) on */
    unsigned categories_on; /* bit i: LOG_CATEGORIES[i] enabled for debug messages */
    void *environment;
    AllocateFn allocate;
    FreeFn release;
    LogFn log;
    void *log_context;

    Snapshot now;          /* time, mode and all values that define the instance */
    double *y, *z, *xdot;  /* cached results */
    int outputs_valid, derivatives_valid, initial_state_valid;
    /* an input changed its value in Event Mode: the next event iteration reports the continuous states as
     * changed, so an integrator that restarts only on that flag does not carry its history across the jump */
    int input_jumped;
    double start_time;
    double stop_time;
    int stop_time_defined;
    int early_return_allowed; /* FMI 3.0: the importer allows doStep to return early (ModelHooks.step may) */

    /* CasADi work arrays, sized for the largest function */
    const double **arg;
    double **res;
    casadi_int_t *iw;
    double *w;

    /* solver scratch */
    double *jac, *matrix, *stage[6], *x_stage, *rhs, *x_start, *x_trial, *z_start, *z_trial, *d_trial;
    int *pivots;
    long long steps, event_count;

    /* The FMU-state handles this instance issued and has not freed: a handle from the importer is checked by
     * looking it up here, never by reading through it. */
    Snapshot **issued;
    size_t n_issued, issued_capacity;
} Instance;

/* What a model that is more than equations does in the generic FMI layers' place (fmi2Functions.c,
 * fmi3Functions.c, instance.c), as data and functions; ModelInfo.hooks, NULL for the ego models: everything
 * generic. The scenario FMU (sdl_fmu/export/runtime/scenario_model.c) is such a model. */
typedef struct ModelHooks {
    int model_exchange;      /* 0: co-simulation only: no model-exchange instance, and every model-exchange
                              * function refuses in every state, with a message */
    int partial_derivatives; /* 0: GetDirectionalDerivative (and fmi3GetAdjointDerivative) refuse: not provided */
    int early_return;        /* FMI 3.0: step may return at an event's instant when the importer allows it */
    int start_time_parameter; /* index in p set to the start time at SetupExperiment (FMI 3.0: EnterInitializationMode),
                               * -1: none */
    int ended_state;          /* index in d, nonzero once the model has ended: fmi2GetBooleanStatus(fmi2Terminated)
                               * and fmi3DoStep's terminateSimulation report it (-1: never) */
    /* The instance, from the FMU's resources folder (a native path, '/'-terminated or not) and the GUID or
     * instantiation token, in place of the generic GUID check and instance_create: NULL and a one-line reason on
     * failure. The instance's model_data is then the model's, freed by free_model after the instance. */
    Instance *(*instantiate)(const char *name, const char *token, const char *resources, int is_cosimulation,
                             AllocateFn allocate, FreeFn release, LogFn log, void *log_context, char *reason,
                             size_t reason_size);
    void (*free_model)(void *model_data);
    /* doStep in place of the in-step solver (cosimulation.c): its arguments (refused: nothing changes, the
     * instance stays usable; `function` names the caller in messages), then the step, which sets the time it
     * reached and whether it returned early (only with early_return_allowed). */
    Status (*check_step)(Instance *instance, double t, double h, const char *function);
    Status (*step)(Instance *instance, double t, double h, int *returned_early);
    /* An FMU state the layer checked (snapshot_check) that the model must accept as well (else logs why, 0). */
    int (*state_fits)(Instance *instance, const Snapshot *snapshot, const char *function);
} ModelHooks;

/* The model's hooks; those of a model without any (generic everything, no function) for the ego models. */
const ModelHooks *model_hooks(const ModelInfo *info);

Instance *instance_create(const ModelInfo *info, const char *name, int is_cosimulation, AllocateFn allocate,
                          FreeFn release, LogFn log, void *log_context);
void instance_free(Instance *instance);
void instance_reset(Instance *instance);
/* fmi2/3SetDebugLogging: no categories switches all; else on enables exactly the named ones, off disables them;
 * each must be declared
 * (an unknown name is refused with a message and nothing changes). Messages with a non-OK status are always
 * passed to the importer's logger; OK-status (debug) messages only when their category is on. */
Status instance_set_debug_logging(Instance *instance, int logging_on, size_t n, const char *const categories[],
                                  const char *function);
void instance_log(Instance *instance, Status status, const char *category, const char *format, ...)
#if defined(__MINGW32__)
    __attribute__((format(gnu_printf, 4, 5))) /* instance.c formats with mingw-w64's C99 printf */
#elif defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

/* Whether the model has ended (ModelHooks.ended_state): the importer is asked to stop. */
int instance_ended(const Instance *instance);

/* Variable access by value reference; kind must match the variable's type. */
Status instance_get(Instance *instance, const unsigned int vr[], size_t nvr, Kind kind, void *values);
Status instance_set(Instance *instance, const unsigned int vr[], size_t nvr, Kind kind, const void *values);

/* Model exchange: time and continuous states from the importer (finite, the right number, or refused). */
Status instance_set_time(Instance *instance, double time);
Status instance_set_states(Instance *instance, const double x[], size_t nx);

/* Equations */
void instance_invalidate(Instance *instance);
Status instance_apply_initial_state(Instance *instance);
Status instance_derivatives(Instance *instance, const double *x, const double *d, double *xdot);
Status instance_event_indicators(Instance *instance, const double *x, const double *d, double *z);
/* Applies the discrete update until nothing changes; reports whether x or d changed. */
Status instance_event_iteration(Instance *instance, int *states_changed, int *discrete_changed);
int instance_take_input_jump(Instance *instance);

/* Co-simulation: check the arguments of a step (nothing changes), then advance the instance's time by h
 * with its internal solver. */
Status instance_check_step(Instance *instance, double current_time, double h);
Status instance_do_step(Instance *instance, double current_time, double h);

/* FMU state */
Snapshot *snapshot_create(Instance *instance);
void snapshot_copy(const Instance *instance, Snapshot *to, const Snapshot *from);
void snapshot_free(Instance *instance, Snapshot *snapshot);
size_t snapshot_serialized_size(const Instance *instance);
void snapshot_serialize(const Instance *instance, const Snapshot *snapshot, char *bytes);
/* Whether an FMU state handle from the importer is one this instance issued and has not freed (found in its
 * registry by pointer comparison only; else logs and 0). */
int snapshot_handle_valid(Instance *instance, const void *state, const char *function);
/* Checks a state field by field (mode word, finite time and values, inputs and parameters in range) before
 * it may touch an instance; deserialize also checks size, GUID hash and checksum. */
Status snapshot_check(Instance *instance, const Snapshot *snapshot);
Status snapshot_deserialize(Instance *instance, const char *bytes, size_t size, Snapshot *snapshot);

/* The FMU-state calls of FMI 2.0 and 3.0 (fmi2GetFMUstate ... fmi3DeserializeFMUState) over the snapshots;
 * `function` names the caller in log messages. Deserializing into an existing state overwrites it when
 * `reuse_existing` (FMI 3.0), else always creates a new one (FMI 2.0: the handle is an output only). */
Status instance_get_state(Instance *instance, void **state, const char *function);
Status instance_set_state(Instance *instance, const void *state, const char *function);
Status instance_free_state(Instance *instance, void **state, const char *function);
Status instance_serialize_state(Instance *instance, const void *state, char *bytes, size_t size, const char *function);
Status instance_deserialize_state(Instance *instance, const char *bytes, size_t size, void **state, int reuse_existing,
                                  const char *function);

#endif
