/* What the FMI 2.0 and FMI 3.0 layers of the scenario FMU share (scenario_fmi.c): instantiation from the resources,
 * the exit from initialization mode, the step, and the FMU-state checks particular to a scenario. The state tables
 * (MASK_ per function) stay in each layer, as in the ego FMUs' runtime. */
#ifndef SDL_SCENARIO_FMI_H
#define SDL_SCENARIO_FMI_H

#include "scenario.h"

#define RESOURCE_FILE "scenario.sdlfmu"
#define MAX_RESOURCE_BYTES (64L * 1024 * 1024)

typedef void (*ImporterLog)(void *context, Status status, const char *category, const char *message);

typedef struct {
    Instance *instance;
    ModelInfo *info;
    char *guid;
    char **names;
    int n_names;
    void *(*allocate)(size_t, size_t);
    void (*release)(void *);
    int early_return_allowed; /* FMI 3.0: the importer allows early return */
} Scenario;

/* Reads resources/scenario.sdlfmu from `directory` (a native path), checks `token` against its GUID and creates
 * the instance. On failure returns NULL and writes the one-line reason. */
Scenario *scenario_instantiate(const char *name, const char *token, const char *directory,
                               void *(*allocate)(size_t, size_t), void (*release)(void *), LogFn log,
                               void *log_context, char *reason, size_t reason_size);
void scenario_free(Scenario *scenario);

/* An FMI 2.0 fmuResourceLocation (a file: URI) as a native folder path; 0 and a reason if it is none. */
int scenario_uri_to_path(const char *uri, char *path, size_t size, char *reason, size_t reason_size);

void scenario_set_start_time(Scenario *scenario, double start_time);
Status scenario_exit_initialization(Scenario *scenario);
/* doStep's arguments (a refused step changes nothing, the instance stays usable), then the step itself (a failure
 * there, the step's budget, is the error state); `early` (FMI 3.0) lets it return at the instant an event fired. */
Status scenario_check_step_arguments(Scenario *scenario, double t, double h, const char *function);
Status scenario_do_step(Scenario *scenario, double t, double h, int early, int *returned_early);
int scenario_ended(const Scenario *scenario);

/* The FMU-state calls with the scenario's own checks on top of the instance layer's: a state must hold this
 * scenario's data and a consistent scenario state (indices, flags, counts in range). */
Status scenario_set_state(Scenario *scenario, const void *state, const char *function);
Status scenario_deserialize_state(Scenario *scenario, const char *bytes, size_t size, void **state,
                                  int reuse_existing, const char *function);

#endif
