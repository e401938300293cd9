/* One scenario as a model of the generic runtime (instance.c and the FMI layers fmi2Functions.c, fmi3Functions.c,
 * shared with the ego FMUs): the variable table (the interface's fixed variables and the traffic slots), the start
 * values (the declared parameters' and, hidden after them, the start time and the scenario's data block), the model
 * functions in the layer's (x, d, u, p) form (the outputs and the initial state; there are no continuous states and
 * no event indicators), and its hooks (ModelHooks, instance.h): co-simulation only, the scenario read from the FMU's
 * resources at instantiation, its own doStep (scenario_step in scenario.c, which may return early in FMI 3.0 and logs
 * the events), the end of the scenario as the importer's signal to stop, and an FMU state's checks particular to a
 * scenario. */
#if defined(__MINGW32__) && !defined(__USE_MINGW_ANSI_STDIO)
#define __USE_MINGW_ANSI_STDIO 1
#endif
#include "scenario.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define RESOURCE_FILE "scenario.sdlfmu"
#define MAX_RESOURCE_BYTES (64L * 1024 * 1024)

/* An instance's model: its ModelInfo and what the ModelInfo points to, and the vehicles' model names for the log
 * (Instance.model_data). */
typedef struct {
    ModelInfo info;             /* first: the instance layer sees this */
    ModelVariable *variables;
    char *slot_names;
    double *input_start, *parameter_start, nominal[1];
    char *guid;
    char **names;
    int n_names;
    FreeFn release;
} ScenarioModel;

static const ModelHooks SCENARIO_HOOKS;

static int no_work(casadi_int_t *sz_arg, casadi_int_t *sz_res, casadi_int_t *sz_iw, casadi_int_t *sz_w) {
    *sz_arg = 4;
    *sz_res = 2;
    *sz_iw = 0;
    *sz_w = 0;
    return 0;
}

/* derivatives, Jacobian, event indicators, directional derivatives: nothing (no states, no indicators) */
static int nothing(const double **arg, double **res, casadi_int_t *iw, double *w, int mem) {
    (void)arg;
    (void)res;
    (void)iw;
    (void)w;
    (void)mem;
    return 0;
}

static int outputs(const double **arg, double **res, casadi_int_t *iw, double *w, int mem) {
    View view;
    (void)iw;
    (void)w;
    (void)mem;
    view_make(&view, arg[3]);
    scenario_outputs(&view, arg[2], arg[1], res[0]);
    return 0;
}

/* the state after the first communication point, from the inputs as they are (no log: this is a pure function;
 * the FMI layer's exit from initialization mode logs the same events) */
static int initial_state(const double **arg, double **res, casadi_int_t *iw, double *w, int mem) {
    View view;
    (void)iw;
    (void)w;
    (void)mem;
    view_make(&view, arg[3]);
    scenario_begin(&view, arg[2], res[1], NULL);
    return 0;
}

/* nothing happens at an event of the instance layer: the scenario's events happen inside doStep */
static int discrete_update(const double **arg, double **res, casadi_int_t *iw, double *w, int mem) {
    View view;
    (void)iw;
    (void)w;
    (void)mem;
    view_make(&view, arg[3]);
    memcpy(res[1], arg[1], sizeof(double) * state_size(&view));
    return 0;
}

static void free_model(void *model_data);

/* The model of one scenario from its data block; it takes over `guid` and `names` (freed with it, or here on
 * failure: NULL). */
static ScenarioModel *scenario_model(const double *data, size_t data_size, const double *parameters, char *guid,
                                     char **names, int n_names, AllocateFn allocate, FreeFn release) {
    ScenarioModel *model = (ScenarioModel *)allocate(1, sizeof(ScenarioModel));
    ModelInfo *info;
    View view;
    int n_slots, i, j;
    size_t name_size = 24;
    const ModelFunction none = {nothing, no_work};
    if (!model) {
        release(guid);
        scenario_free_names(names, n_names, release);
        return NULL;
    }
    memset(model, 0, sizeof(*model));
    model->guid = guid;
    model->names = names;
    model->n_names = n_names;
    model->release = release;
    n_slots = (int)data[H_N_SLOTS];
    model->variables =
        (ModelVariable *)allocate((size_t)(N_SCENARIO_VARIABLES + n_slots * N_SLOT_OUTPUTS) + 1, sizeof(ModelVariable));
    model->slot_names = (char *)allocate((size_t)(n_slots * N_SLOT_OUTPUTS) * name_size + 1, 1);
    model->input_start = (double *)allocate(N_INPUTS + 1, sizeof(double));
    model->parameter_start = (double *)allocate(DATA_START + data_size + 1, sizeof(double));
    if (!model->variables || !model->slot_names || !model->input_start || !model->parameter_start) {
        free_model(model);
        return NULL;
    }
    info = &model->info;
    memcpy(model->variables, SCENARIO_VARIABLES, sizeof(ModelVariable) * N_SCENARIO_VARIABLES);
    for (i = 0; i < n_slots; i++)
        for (j = 0; j < N_SLOT_OUTPUTS; j++) {
            int k = N_SCENARIO_VARIABLES + i * N_SLOT_OUTPUTS + j;
            char *name = model->slot_names + (size_t)(i * N_SLOT_OUTPUTS + j) * name_size;
            ModelVariable variable = SLOT_VARIABLES[j];
            snprintf(name, name_size, "tv%d_%s", i + 1, SLOT_VARIABLES[j].name);
            variable.name = name;
            variable.value_reference = (unsigned int)k + 1;
            variable.index = N_OUTPUTS_FIXED + i * N_SLOT_OUTPUTS + j;
            model->variables[k] = variable;
        }
    for (i = 0; i < N_SCENARIO_VARIABLES; i++) {
        const ModelVariable *variable = &SCENARIO_VARIABLES[i];
        if (variable->store == STORE_INPUT) model->input_start[variable->index] = SCENARIO_STARTS[i];
        if (variable->store == STORE_PARAMETER) model->parameter_start[variable->index] = parameters[variable->index];
    }
    model->parameter_start[HIDDEN_START_TIME] = 0.0;
    memcpy(model->parameter_start + DATA_START, data, sizeof(double) * data_size);
    model->nominal[0] = 1.0;
    view_make(&view, model->parameter_start);

    info->model_identifier = MODEL_IDENTIFIER;
    info->guid = model->guid;
    info->nx = 0;
    info->nd = (int)state_size(&view);
    info->nu = N_INPUTS;
    info->np = (int)(DATA_START + data_size);
    info->ny = N_OUTPUTS_FIXED + n_slots * N_SLOT_OUTPUTS;
    info->nz = 0;
    info->input_start = model->input_start;
    info->parameter_start = model->parameter_start;
    info->state_nominal = model->nominal;
    info->variables = model->variables;
    info->n_variables = N_SCENARIO_VARIABLES + n_slots * N_SLOT_OUTPUTS;
    info->solver_step_parameter = -1;
    info->solver_tolerance_parameter = -1;
    info->model_exchange_parameter = -1;
    info->derivatives = none;
    info->jacobian = none;
    info->outputs.eval = outputs;
    info->outputs.work = no_work;
    info->event_indicators = none;
    info->discrete_update.eval = discrete_update;
    info->discrete_update.work = no_work;
    info->initial_state.eval = initial_state;
    info->initial_state.work = no_work;
    info->unknowns_forward = none;
    info->unknowns_adjoint = none;
    info->initial_forward = none;
    info->initial_adjoint = none;
    info->hooks = &SCENARIO_HOOKS;
    return model;
}

static void free_model(void *model_data) {
    ScenarioModel *model = (ScenarioModel *)model_data;
    FreeFn release = model->release;
    if (model->variables) release(model->variables);
    if (model->slot_names) release(model->slot_names);
    if (model->input_start) release(model->input_start);
    if (model->parameter_start) release(model->parameter_start);
    if (model->guid) release(model->guid);
    scenario_free_names(model->names, model->n_names, release);
    release(model);
}

/* The whole file, NUL-terminated, in memory from `allocate`; NULL and a reason on failure. */
static char *read_file(const char *path, void *(*allocate)(size_t, size_t), void (*release)(void *), size_t *length,
                       char *reason, size_t reason_size) {
    FILE *file = fopen(path, "rb");
    char *text = NULL;
    size_t capacity = 0, used = 0;
    if (!file) {
        snprintf(reason, reason_size, "cannot open %.300s", path);
        return NULL;
    }
    for (;;) {
        size_t got;
        if (used + 1 >= capacity) {
            size_t grown_capacity = capacity ? 2 * capacity : 65536;
            char *grown;
            if (grown_capacity > (size_t)MAX_RESOURCE_BYTES + 2) grown_capacity = (size_t)MAX_RESOURCE_BYTES + 2;
            if (used + 1 >= grown_capacity) {
                snprintf(reason, reason_size, "%.300s is larger than %ld bytes", path, MAX_RESOURCE_BYTES);
                break;
            }
            grown = (char *)allocate(grown_capacity, 1);
            if (!grown) {
                snprintf(reason, reason_size, "out of memory reading %.300s", path);
                break;
            }
            if (used) memcpy(grown, text, used);
            if (text) release(text);
            text = grown;
            capacity = grown_capacity;
        }
        got = fread(text + used, 1, capacity - 1 - used, file);
        used += got;
        if (got == 0) {
            if (ferror(file)) {
                snprintf(reason, reason_size, "cannot read %.300s", path);
                break;
            }
            fclose(file);
            text[used] = '\0';
            *length = used;
            return text;
        }
    }
    fclose(file);
    if (text) release(text);
    return NULL;
}

/* ModelHooks.instantiate: reads resources/scenario.sdlfmu from `directory` (a native path), checks `token` against
 * its GUID and creates the instance; NULL and the one-line reason on failure. */
static Instance *instantiate(const char *name, const char *token, const char *directory, int is_cosimulation,
                             AllocateFn allocate, FreeFn release, LogFn log, void *log_context, char *reason,
                             size_t reason_size) {
    char path[4200];
    size_t length = 0, data_size = 0, n = directory ? strlen(directory) : 0;
    char *text, *guid = NULL, **names = NULL;
    double *data, parameters[N_PARAMETERS];
    ScenarioModel *model;
    Instance *instance;
    int vehicles;
    if (!directory || !directory[0]) {
        snprintf(reason, reason_size, "no resource location given (the scenario is read from the FMU's resources/)");
        return NULL;
    }
    if (n + sizeof(RESOURCE_FILE) + 2 > sizeof(path)) {
        snprintf(reason, reason_size, "the resource location is too long");
        return NULL;
    }
    memcpy(path, directory, n);
    if (path[n - 1] != '/' && path[n - 1] != '\\') path[n++] = '/';
    memcpy(path + n, RESOURCE_FILE, sizeof(RESOURCE_FILE));
    text = read_file(path, allocate, release, &length, reason, reason_size);
    if (!text) return NULL;
    data = scenario_parse(text, length, "resources/" RESOURCE_FILE, allocate, release, &data_size, &guid, &names,
                          parameters, reason, reason_size);
    release(text);
    if (!data) return NULL;
    vehicles = (int)data[H_N_VEHICLES];
    if (!token || strcmp(token, guid) != 0) {
        snprintf(reason, reason_size, "wrong GUID %.100s: the scenario in resources/%s is %s", token ? token : "(null)",
                 RESOURCE_FILE, guid);
        release(data);
        release(guid);
        scenario_free_names(names, vehicles, release);
        return NULL;
    }
    model = scenario_model(data, data_size, parameters, guid, names, vehicles, allocate, release);
    release(data);
    instance = model ? instance_create(&model->info, name, is_cosimulation, allocate, release, log, log_context) : NULL;
    if (!instance) {
        snprintf(reason, reason_size, "out of memory");
        if (model) free_model(model);
        return NULL;
    }
    instance->model_data = model;
    return instance;
}

/* ModelHooks.check_step: doStep's arguments (a refused step changes nothing, the instance stays usable). */
static Status check_step(Instance *instance, double t, double h, const char *function) {
    char reason[400];
    View view;
    if (!isfinite(t)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: communication point %g is not finite", function, t);
        return STATUS_ERROR;
    }
    if (!(h > 0.0) || !isfinite(h)) { /* FMI 2.0.4 and 3.0: communicationStepSize > 0 */
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "%s: communication step size %g must be finite and > 0", function, h);
        return STATUS_ERROR;
    }
    if (fabs(t - instance->now.time) > 1e-9 * fmax(1.0, fabs(t))) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s at t = %.17g but the FMU is at t = %.17g",
                     function, t, instance->now.time);
        return STATUS_ERROR;
    }
    if (!(t + h > t)) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "%s: time cannot advance: at t = %.17g a step of %g s is lost to rounding", function, t, h);
        return STATUS_ERROR;
    }
    view_make(&view, instance->now.p);
    if (scenario_check_step(&view, h, reason, sizeof(reason))) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: %s", function, reason);
        return STATUS_ERROR;
    }
    if (instance->stop_time_defined && t + h > instance->stop_time + 1e-9 * (1.0 + fabs(instance->stop_time))) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s would pass the stop time %.17g", function,
                     instance->stop_time);
        return STATUS_ERROR;
    }
    return STATUS_OK;
}

/* ModelHooks.step: the step itself (a failure there, the step's budget, is the error state); with the importer's
 * earlyReturnAllowed (FMI 3.0) it returns at the instant an event fired. The events are logged with the vehicles'
 * model names. */
static Status step(Instance *instance, double t, double h, int *returned_early) {
    const ScenarioModel *model = (const ScenarioModel *)instance->model_data;
    Logger logger;
    double reached;
    int result;
    View view;
    logger.instance = instance;
    logger.model_names = (const char *const *)model->names;
    view_make(&view, instance->now.p);
    *returned_early = 0;
    result = scenario_step(&view, instance->now.u, instance->now.d, t, h, instance->early_return_allowed, &logger,
                           &reached);
    instance_invalidate(instance);
    if (result < 0) return STATUS_ERROR;
    instance->now.time = reached;
    *returned_early = result == 1;
    return STATUS_OK;
}

/* ModelHooks.state_fits: an FMU state must hold this scenario's data and a consistent scenario state (indices,
 * flags, counts, slots in range), else it is refused with a message. */
static int state_fits(Instance *instance, const Snapshot *snapshot, const char *function) {
    const ModelInfo *info = instance->info;
    char reason[200];
    View view;
    if (!isfinite(snapshot->p[HIDDEN_START_TIME]) ||
        memcmp(snapshot->p + DATA_START, info->parameter_start + DATA_START,
               sizeof(double) * (size_t)(info->np - DATA_START)) != 0) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: the FMU state holds another scenario's data",
                     function);
        return 0;
    }
    view_make(&view, snapshot->p);
    if (state_check(&view, snapshot->d, reason, sizeof(reason))) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: the FMU state is inconsistent: %s", function,
                     reason);
        return 0;
    }
    return 1;
}

static const ModelHooks SCENARIO_HOOKS = {
    0,                 /* model_exchange: co-simulation only */
    0,                 /* partial_derivatives: not provided */
    1,                 /* early_return (FMI 3.0) */
    HIDDEN_START_TIME, /* start_time_parameter: the clocks count from the start time */
    D_FINISHED,        /* ended_state: ES or the run's end */
    instantiate,
    free_model,
    check_step,
    step,
    state_fits,
};

/* The binary's model before instantiation: the scenario comes from the resources (no GUID of its own). */
const ModelInfo model_info = {.model_identifier = MODEL_IDENTIFIER, .guid = "", .hooks = &SCENARIO_HOOKS};
