/* The FMI 2.0 API (model exchange and co-simulation) over the generic instance, for every FMU of sdl-fmu (the ego
 * models and the scenario FMU alike). Each function checks the calling sequence of the standard and answers misuse
 * with fmi2Error and a log message; nothing here knows the model. What a model does differently is its data and
 * hooks (ModelHooks, instance.h): an FMU without model exchange refuses its functions in every state, a model that
 * reads its resources gets their folder, a model with its own step is stepped by it. */
#if defined(__MINGW32__) && !defined(__USE_MINGW_ANSI_STDIO)
#define __USE_MINGW_ANSI_STDIO 1
#endif
#include "fmi2Functions.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "derivatives.h"
#include "instance.h"

typedef struct {
    Instance *instance;
    fmi2CallbackFunctions callbacks;
} Component;

#define ANY_MODE                                                                                               \
    (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED |   \
     MODE_ERROR)
/* The FMI 2.0 state tables (sections 3.2.3 and 4.2.4) in one place, as the Reference-FMUs keep them: the states
 * in which each function is allowed (elsewhere it returns fmi2Error with a log message). A test compares this
 * table with the standard's (tests/fmu/test_state_tables.py). */
#define MASK_fmi2SetDebugLogging               ANY_MODE
#define MASK_fmi2SetupExperiment               MODE_INSTANTIATED
#define MASK_fmi2EnterInitializationMode       MODE_INSTANTIATED
#define MASK_fmi2ExitInitializationMode        MODE_INITIALIZATION
#define MASK_fmi2Terminate                     (MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP)
#define MASK_fmi2Reset                         ANY_MODE
#define MASK_fmi2GetReal                       (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2GetInteger                    (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2GetBoolean                    (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2GetString                     (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2SetReal                       (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP)
#define MASK_fmi2SetInteger                    (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_STEP)
#define MASK_fmi2SetBoolean                    (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_STEP)
#define MASK_fmi2SetString                     (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_STEP)
#define MASK_fmi2GetFMUstate                   (ANY_MODE & ~MODE_ERROR)
#define MASK_fmi2SetFMUstate                   ANY_MODE
#define MASK_fmi2FreeFMUstate                  ANY_MODE
#define MASK_fmi2SerializedFMUstateSize        ANY_MODE
#define MASK_fmi2SerializeFMUstate             ANY_MODE
#define MASK_fmi2DeSerializeFMUstate           ANY_MODE
#define MASK_fmi2GetDirectionalDerivative      (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2EnterEventMode                (MODE_EVENT | MODE_CONTINUOUS_TIME)
#define MASK_fmi2NewDiscreteStates             MODE_EVENT
#define MASK_fmi2EnterContinuousTimeMode       MODE_EVENT
#define MASK_fmi2CompletedIntegratorStep       MODE_CONTINUOUS_TIME
#define MASK_fmi2SetTime                       (MODE_EVENT | MODE_CONTINUOUS_TIME)
#define MASK_fmi2SetContinuousStates           MODE_CONTINUOUS_TIME
#define MASK_fmi2GetDerivatives                (MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2GetEventIndicators            (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2GetContinuousStates           (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2GetNominalsOfContinuousStates (MODE_INSTANTIATED | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2SetRealInputDerivatives       (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP)
#define MASK_fmi2GetRealOutputDerivatives      (MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define MASK_fmi2DoStep                        MODE_STEP
#define MASK_fmi2CancelStep                    0 /* stepInProgress: doStep never returns pending */
#define MASK_fmi2GetStatus                     (MODE_STEP | MODE_TERMINATED)
#define MASK_fmi2GetRealStatus                 (MODE_STEP | MODE_TERMINATED)
#define MASK_fmi2GetIntegerStatus              (MODE_STEP | MODE_TERMINATED)
#define MASK_fmi2GetBooleanStatus              (MODE_STEP | MODE_TERMINATED)
#define MASK_fmi2GetStringStatus               (MODE_STEP | MODE_TERMINATED)

static void log_to_importer(void *instance_pointer, Status status, const char *category, const char *message) {
    Instance *instance = (Instance *)instance_pointer;
    const fmi2CallbackFunctions *callbacks = (const fmi2CallbackFunctions *)instance->log_context;
    char safe[1024];
    size_t i;
    if (!callbacks || !callbacks->logger) return;
    /* the logger treats the message as a format string */
    for (i = 0; message[i] && i + 1 < sizeof(safe); i++) safe[i] = message[i] == '%' ? '_' : message[i];
    safe[i] = '\0';
    callbacks->logger(callbacks->componentEnvironment, instance->name, (fmi2Status)status, category, "%s", safe);
}

/* The FMI 2.0 state tables (sections 3.2.3 and 4.2.4): a function is allowed in some modes and, for the
 * model-exchange and co-simulation functions, only on an instance of that type. */
typedef enum { ANY_TYPE, MODEL_EXCHANGE_ONLY, CO_SIMULATION_ONLY } InstanceType;

static Instance *checked_type(fmi2Component c, const char *function, int allowed_modes, InstanceType type) {
    Component *component = (Component *)c;
    Instance *instance;
    if (!component || !component->instance) return NULL;
    instance = component->instance;
    if (type == MODEL_EXCHANGE_ONLY && !model_hooks(instance->info)->model_exchange) { /* refused in every state */
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "%s needs a model-exchange instance (this FMU is for co-simulation only)", function);
        return NULL;
    }
    if ((type == MODEL_EXCHANGE_ONLY && instance->is_cosimulation) ||
        (type == CO_SIMULATION_ONLY && !instance->is_cosimulation)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s needs a %s instance", function,
                     type == MODEL_EXCHANGE_ONLY ? "model-exchange" : "co-simulation");
        return NULL;
    }
    if (!(instance->now.mode & allowed_modes)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s must not be called in the current state",
                     function);
        return NULL;
    }
    return instance;
}

static Instance *checked(fmi2Component c, const char *function, int allowed_modes) {
    return checked_type(c, function, allowed_modes, ANY_TYPE);
}

static Instance *checked_me(fmi2Component c, const char *function, int allowed_modes) {
    return checked_type(c, function, allowed_modes, MODEL_EXCHANGE_ONLY);
}

static Instance *checked_cs(fmi2Component c, const char *function, int allowed_modes) {
    return checked_type(c, function, allowed_modes, CO_SIMULATION_ONLY);
}

/* A refused null output argument, with its log message. */
static int present(Instance *instance, const char *function, const void *pointer, const char *name) {
    if (pointer) return 1;
    instance_log(instance, STATUS_ERROR, "logStatusError", "%s: %s is a null pointer", function, name);
    return 0;
}

static fmi2Status finish(Instance *instance, Status status) {
    if (status >= STATUS_ERROR) instance->now.mode = MODE_ERROR;
    return (fmi2Status)status;
}

/* ---- common functions ----------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Instance *instance = checked(c, "fmi2SetDebugLogging", MASK_fmi2SetDebugLogging);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_set_debug_logging(instance, loggingOn ? 1 : 0, nCategories, categories,
                                                  "fmi2SetDebugLogging");
}

static int hex_value(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* fmuResourceLocation (a file: URI) as a native folder path, for a model that reads its resources; 0 and a reason if
 * it is none. */
static int resource_path(const char *uri, char *path, size_t size, char *reason, size_t reason_size) {
    const char *p;
    size_t n = 0;
    if (!uri || !uri[0]) {
        snprintf(reason, reason_size, "no resource location given (the model is read from the FMU's resources/)");
        return 0;
    }
    if (strncmp(uri, "file:", 5) != 0 && strncmp(uri, "FILE:", 5) != 0) {
        snprintf(reason, reason_size, "the resource location '%.200s' is not a file: URI", uri);
        return 0;
    }
    p = uri + 5;
    if (p[0] == '/' && p[1] == '/') { /* an authority: empty or localhost */
        p += 2;
        if (strncmp(p, "localhost/", 10) == 0) p += 9;
        if (*p != '/') {
            snprintf(reason, reason_size, "the resource location '%.200s' names another host", uri);
            return 0;
        }
    }
#if defined(_WIN32)
    if (p[0] == '/' && ((p[1] >= 'A' && p[1] <= 'Z') || (p[1] >= 'a' && p[1] <= 'z')) && (p[2] == ':' || p[2] == '|'))
        p++; /* file:///C:/dir -> C:/dir */
#endif
    for (; *p; p++) {
        char c = *p;
        if (c == '%') {
            int high = hex_value(p[1]), low = high >= 0 ? hex_value(p[2]) : -1;
            if (high < 0 || low < 0 || (high == 0 && low == 0)) {
                snprintf(reason, reason_size, "the resource location '%.200s' has a bad %%-escape", uri);
                return 0;
            }
            c = (char)(high * 16 + low);
            p += 2;
        }
        if (n + 1 >= size) {
            snprintf(reason, reason_size, "the resource location is too long");
            return 0;
        }
        path[n++] = c;
    }
    path[n] = '\0';
    return 1;
}

/* A refused instantiation's one line (as the argument of "%s": a '%' in it is no format). */
static void instantiation_refused(const fmi2CallbackFunctions *functions, const char *name, const char *reason) {
    char message[800];
    snprintf(message, sizeof(message), "fmi2Instantiate: %s", reason);
    if (functions->logger)
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError", "%s", message);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    const ModelHooks *hooks = model_hooks(&model_info);
    Component *component;
    char reason[700], path[4096];
    (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory) return NULL;
    if (!instanceName || !instanceName[0]) {
        instantiation_refused(functions, "?", "missing instance name");
        return NULL;
    }
    if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) {
        instantiation_refused(functions, instanceName, "unknown fmuType");
        return NULL;
    }
    if (fmuType == fmi2ModelExchange && !hooks->model_exchange) {
        snprintf(reason, sizeof(reason), "%s is for co-simulation only (it has no model-exchange interface)",
                 model_info.model_identifier);
        instantiation_refused(functions, instanceName, reason);
        return NULL;
    }
    component = (Component *)functions->allocateMemory(1, sizeof(Component));
    if (!component) return NULL;
    component->callbacks = *functions;
    component->instance = NULL;
    if (hooks->instantiate) { /* the model reads its resources and checks the GUID itself */
        if (resource_path(fmuResourceLocation, path, sizeof(path), reason, sizeof(reason)))
            component->instance = hooks->instantiate(instanceName, fmuGUID, path, fmuType == fmi2CoSimulation,
                                                     functions->allocateMemory, functions->freeMemory,
                                                     log_to_importer, &component->callbacks, reason, sizeof(reason));
    } else if (!fmuGUID || strcmp(fmuGUID, model_info.guid) != 0) {
        snprintf(reason, sizeof(reason), "wrong GUID %.200s, expected %s", fmuGUID ? fmuGUID : "(null)",
                 model_info.guid);
    } else {
        component->instance = instance_create(&model_info, instanceName, fmuType == fmi2CoSimulation,
                                              functions->allocateMemory, functions->freeMemory, log_to_importer,
                                              &component->callbacks);
        if (!component->instance) snprintf(reason, sizeof(reason), "out of memory");
    }
    if (!component->instance) {
        instantiation_refused(functions, instanceName, reason);
        functions->freeMemory(component);
        return NULL;
    }
    component->instance->environment = functions->componentEnvironment;
    component->instance->logging_on = loggingOn ? 1 : 0;
    return component;
}

void fmi2FreeInstance(fmi2Component c) {
    Component *component = (Component *)c;
    fmi2CallbackFreeMemory release;
    if (!component) return;
    release = component->callbacks.freeMemory;
    instance_free(component->instance);
    release(component);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *instance = checked(c, "fmi2SetupExperiment", MASK_fmi2SetupExperiment);
    (void)toleranceDefined;
    (void)tolerance;
    if (!instance) return fmi2Error;
    if (!isfinite(startTime) || (stopTimeDefined && (!isfinite(stopTime) || stopTime < startTime))) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "fmi2SetupExperiment: start time %g and stop time %g must be finite, stop >= start", startTime,
                     stopTime);
        return fmi2Error;
    }
    instance->start_time = startTime;
    instance->now.time = startTime;
    instance->stop_time_defined = stopTimeDefined ? 1 : 0;
    instance->stop_time = stopTime;
    if (model_hooks(instance->info)->start_time_parameter >= 0) { /* a parameter of the initial state */
        instance->now.p[model_hooks(instance->info)->start_time_parameter] = startTime;
        instance->initial_state_valid = 0;
    }
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *instance = checked(c, "fmi2EnterInitializationMode", MASK_fmi2EnterInitializationMode);
    if (!instance) return fmi2Error;
    instance->now.mode = MODE_INITIALIZATION;
    instance->initial_state_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *instance = checked(c, "fmi2ExitInitializationMode", MASK_fmi2ExitInitializationMode);
    int states_changed, discrete_changed;
    Status status;
    if (!instance) return fmi2Error;
    status = instance_apply_initial_state(instance);
    if (status == STATUS_OK) status = instance_event_iteration(instance, &states_changed, &discrete_changed);
    instance->now.mode = instance->is_cosimulation ? MODE_STEP : MODE_EVENT;
    return finish(instance, status);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *instance =
        checked(c, "fmi2Terminate", MASK_fmi2Terminate);
    if (!instance) return fmi2Error;
    instance->now.mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *instance = checked(c, "fmi2Reset", MASK_fmi2Reset);
    if (!instance) return fmi2Error;
    instance_reset(instance);
    return fmi2OK;
}

/* ---- variables -------------------------------------------------------------------------------- */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *instance = checked(c, "fmi2GetReal", MASK_fmi2GetReal);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_get(instance, vr, nvr, KIND_REAL, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    Instance *instance = checked(c, "fmi2GetInteger", MASK_fmi2GetInteger);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_get(instance, vr, nvr, KIND_INTEGER, value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    Instance *instance = checked(c, "fmi2GetBoolean", MASK_fmi2GetBoolean);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_get(instance, vr, nvr, KIND_BOOLEAN, value);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    Instance *instance = checked(c, "fmi2GetString", MASK_fmi2GetString);
    (void)vr;
    (void)value;
    if (!instance) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    instance_log(instance, STATUS_ERROR, "logStatusError", "the model has no String variables");
    return fmi2Error;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *instance = checked(c, "fmi2SetReal", MASK_fmi2SetReal);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_set(instance, vr, nvr, KIND_REAL, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    Instance *instance = checked(c, "fmi2SetInteger", MASK_fmi2SetInteger);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_set(instance, vr, nvr, KIND_INTEGER, value);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    Instance *instance = checked(c, "fmi2SetBoolean", MASK_fmi2SetBoolean);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_set(instance, vr, nvr, KIND_BOOLEAN, value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    Instance *instance = checked(c, "fmi2SetString", MASK_fmi2SetString);
    (void)vr;
    (void)value;
    if (!instance) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    instance_log(instance, STATUS_ERROR, "logStatusError", "the model has no String variables");
    return fmi2Error;
}

/* ---- FMU state -------------------------------------------------------------------------------- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *instance = checked(c, "fmi2GetFMUstate", MASK_fmi2GetFMUstate);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_get_state(instance, FMUstate, "fmi2GetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Instance *instance = checked(c, "fmi2SetFMUstate", MASK_fmi2SetFMUstate);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_set_state(instance, FMUstate, "fmi2SetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *instance = checked(c, "fmi2FreeFMUstate", MASK_fmi2FreeFMUstate);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_free_state(instance, FMUstate, "fmi2FreeFMUstate");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    Instance *instance = checked(c, "fmi2SerializedFMUstateSize", MASK_fmi2SerializedFMUstateSize);
    if (!instance || !present(instance, "fmi2SerializedFMUstateSize", size, "size") ||
        !snapshot_handle_valid(instance, FMUstate, "fmi2SerializedFMUstateSize"))
        return fmi2Error;
    *size = snapshot_serialized_size(instance);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    Instance *instance = checked(c, "fmi2SerializeFMUstate", MASK_fmi2SerializeFMUstate);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_serialize_state(instance, FMUstate, serializedState, size, "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    Instance *instance = checked(c, "fmi2DeSerializeFMUstate", MASK_fmi2DeSerializeFMUstate);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_deserialize_state(instance, serializedState, size, FMUstate, 0,
                                                  "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    Instance *instance = checked(c, "fmi2GetDirectionalDerivative", MASK_fmi2GetDirectionalDerivative);
    if (!instance) return fmi2Error;
    if (!model_hooks(instance->info)->partial_derivatives) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=\"false\")");
        return fmi2Error;
    }
    return (fmi2Status)instance_directional_derivative(instance, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown,
                                                       dvUnknown);
}

/* ---- model exchange --------------------------------------------------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    Instance *instance = checked_me(c, "fmi2EnterEventMode", MASK_fmi2EnterEventMode);
    if (!instance) return fmi2Error;
    instance->now.mode = MODE_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    Instance *instance = checked_me(c, "fmi2NewDiscreteStates", MASK_fmi2NewDiscreteStates);
    int states_changed = 0, discrete_changed = 0;
    Status status;
    if (!instance || !present(instance, "fmi2NewDiscreteStates", eventInfo, "eventInfo")) return fmi2Error;
    status = instance_event_iteration(instance, &states_changed, &discrete_changed);
    states_changed |= instance_take_input_jump(instance);
    eventInfo->newDiscreteStatesNeeded = fmi2False;
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = states_changed ? fmi2True : fmi2False;
    eventInfo->nextEventTimeDefined = fmi2False;
    eventInfo->nextEventTime = 0.0;
    return finish(instance, status);
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    Instance *instance = checked_me(c, "fmi2EnterContinuousTimeMode", MASK_fmi2EnterContinuousTimeMode);
    if (!instance) return fmi2Error;
    instance->now.mode = MODE_CONTINUOUS_TIME;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    Instance *instance = checked_me(c, "fmi2CompletedIntegratorStep", MASK_fmi2CompletedIntegratorStep);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!instance || !present(instance, "fmi2CompletedIntegratorStep", enterEventMode, "enterEventMode") ||
        !present(instance, "fmi2CompletedIntegratorStep", terminateSimulation, "terminateSimulation"))
        return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    Instance *instance = checked_me(c, "fmi2SetTime", MASK_fmi2SetTime);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_set_time(instance, time);
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Instance *instance = checked_me(c, "fmi2SetContinuousStates", MASK_fmi2SetContinuousStates);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_set_states(instance, x, nx);
}

typedef enum { STATE_VECTOR, INDICATOR_VECTOR } VectorKind;

static Instance *checked_vector(fmi2Component c, const char *function, int allowed_modes, const void *vector,
                                size_t n, VectorKind kind) {
    Instance *instance = checked_me(c, function, allowed_modes);
    int expected;
    if (!instance) return NULL;
    expected = kind == STATE_VECTOR ? instance->info->nx : instance->info->nz;
    if (n != (size_t)expected || (n > 0 && !vector)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: expected a vector of %d", function, expected);
        return NULL;
    }
    if ((instance->now.mode & MODE_INITIALIZATION) && !instance->initial_state_valid &&
        instance_apply_initial_state(instance) != STATUS_OK)
        return NULL;
    return instance;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    Instance *instance =
        checked_vector(c, "fmi2GetDerivatives", MASK_fmi2GetDerivatives, derivatives, nx, STATE_VECTOR);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_derivatives(instance, instance->now.x, instance->now.d, derivatives);
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    Instance *instance = checked_vector(c, "fmi2GetEventIndicators", MASK_fmi2GetEventIndicators, eventIndicators, ni, INDICATOR_VECTOR);
    if (!instance) return fmi2Error;
    return (fmi2Status)instance_event_indicators(instance, instance->now.x, instance->now.d, eventIndicators);
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Instance *instance =
        checked_vector(c, "fmi2GetContinuousStates", MASK_fmi2GetContinuousStates, x, nx, STATE_VECTOR);
    if (!instance) return fmi2Error;
    memcpy(x, instance->now.x, sizeof(double) * nx);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    Instance *instance = checked_vector(c, "fmi2GetNominalsOfContinuousStates", MASK_fmi2GetNominalsOfContinuousStates, x_nominal, nx, STATE_VECTOR);
    if (!instance) return fmi2Error;
    memcpy(x_nominal, instance->info->state_nominal, sizeof(double) * nx);
    return fmi2OK;
}

/* ---- co-simulation ---------------------------------------------------------------------------- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Instance *instance = checked_cs(c, "fmi2SetRealInputDerivatives", MASK_fmi2SetRealInputDerivatives);
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (!instance) return fmi2Error;
    instance_log(instance, STATUS_ERROR, "logStatusError", "the FMU does not interpolate inputs");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    Instance *instance = checked_cs(c, "fmi2GetRealOutputDerivatives", MASK_fmi2GetRealOutputDerivatives);
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (!instance) return fmi2Error;
    instance_log(instance, STATUS_ERROR, "logStatusError", "the FMU provides no output derivatives");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *instance = checked_cs(c, "fmi2DoStep", MASK_fmi2DoStep);
    const ModelHooks *hooks;
    int early;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!instance) return fmi2Error;
    hooks = model_hooks(instance->info);
    /* wrong arguments change nothing, so the instance stays usable */
    if (hooks->step) { /* the model's own step (FMI 2.0 has no early return: instance->early_return_allowed is 0) */
        if (hooks->check_step(instance, currentCommunicationPoint, communicationStepSize, "fmi2DoStep") != STATUS_OK)
            return fmi2Error;
        return finish(instance, hooks->step(instance, currentCommunicationPoint, communicationStepSize, &early));
    }
    if (instance_check_step(instance, currentCommunicationPoint, communicationStepSize) != STATUS_OK)
        return fmi2Error;
    if (instance->stop_time_defined &&
        currentCommunicationPoint + communicationStepSize > instance->stop_time + 1e-9 * (1.0 + instance->stop_time)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "fmi2DoStep would pass the stop time %.17g",
                     instance->stop_time);
        return fmi2Error;
    }
    return finish(instance, instance_do_step(instance, currentCommunicationPoint, communicationStepSize));
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    Instance *instance = checked_cs(c, "fmi2CancelStep", MASK_fmi2CancelStep);
    if (!instance) return fmi2Error;
    instance_log(instance, STATUS_ERROR, "logStatusError", "fmi2DoStep always completes: nothing to cancel");
    return fmi2Error;
}

/* fmi2Get*Status for a kind this FMU does not report: Discard, with the message every non-OK return carries */
static fmi2Status status_not_available(Instance *instance, const char *function, fmi2StatusKind s) {
    instance_log(instance, STATUS_DISCARD, "logStatusWarning",
                 "%s: status kind %d is not available (fmi2DoStep always completes; reported are fmi2GetStatus("
                 "fmi2DoStepStatus), fmi2GetRealStatus(fmi2LastSuccessfulTime) and fmi2GetBooleanStatus("
                 "fmi2Terminated))",
                 function, (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    Instance *instance = checked_cs(c, "fmi2GetStatus", MASK_fmi2GetStatus);
    if (!instance || !present(instance, "fmi2GetStatus", value, "value")) return fmi2Error;
    if (s == fmi2DoStepStatus) {
        *value = fmi2OK;
        return fmi2OK;
    }
    return status_not_available(instance, "fmi2GetStatus", s);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *instance = checked_cs(c, "fmi2GetRealStatus", MASK_fmi2GetRealStatus);
    if (!instance || !present(instance, "fmi2GetRealStatus", value, "value")) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) {
        *value = instance->now.time;
        return fmi2OK;
    }
    return status_not_available(instance, "fmi2GetRealStatus", s);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    Instance *instance = checked_cs(c, "fmi2GetIntegerStatus", MASK_fmi2GetIntegerStatus);
    (void)value;
    return instance ? status_not_available(instance, "fmi2GetIntegerStatus", s) : fmi2Error;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    Instance *instance = checked_cs(c, "fmi2GetBooleanStatus", MASK_fmi2GetBooleanStatus);
    if (!instance || !present(instance, "fmi2GetBooleanStatus", value, "value")) return fmi2Error;
    if (s == fmi2Terminated) { /* true once the model has ended (the scenario: ES or the run's end) */
        *value = instance_ended(instance) ? fmi2True : fmi2False;
        return fmi2OK;
    }
    return status_not_available(instance, "fmi2GetBooleanStatus", s);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    Instance *instance = checked_cs(c, "fmi2GetStringStatus", MASK_fmi2GetStringStatus);
    (void)value;
    return instance ? status_not_available(instance, "fmi2GetStringStatus", s) : fmi2Error;
}
