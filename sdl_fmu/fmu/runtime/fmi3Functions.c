/* The FMI 3.0 API (model exchange and co-simulation) over the generic instance, the sibling of
 * fmi2Functions.c: the same instance layer (instance.c), in-step solver (cosimulation.c) and partial
 * derivatives (derivatives.c) behind the FMI 3.0 calling sequence, for every FMU of sdl-fmu (the ego models and the
 * scenario FMU alike). Each function checks the state machine of the standard and answers misuse with fmi3Error and
 * a log message; nothing here knows the model. What a model does differently is its data and hooks (ModelHooks,
 * instance.h): an FMU without model exchange refuses its functions in every state, a model with its own step may
 * return early (earlyReturnAllowed) and end the simulation (terminateSimulation).
 * The independent variable `time` has value reference 0; the model's variables are numbered 1..n. */
#if defined(__MINGW32__) && !defined(__USE_MINGW_ANSI_STDIO)
#define __USE_MINGW_ANSI_STDIO 1
#endif
#include "fmi3Functions.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "derivatives.h"
#include "instance.h"

#define TIME_REFERENCE 0u

typedef struct {
    Instance *instance;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log_message;
} Component;

#define ANY_MODE                                                                                               \
    (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED |   \
     MODE_ERROR)
#define GET_MODES ANY_MODE
#define SET_REAL_MODES (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP)
/* discrete variables (Int32, Boolean) do not change in continuous-time mode */
/* The FMI 3.0 state tables (sections 3.2 and 4.2) in one place, as the Reference-FMUs keep them: the states
 * in which each function is allowed (elsewhere it returns fmi3Error with a log message). A test compares this
 * table with the standard's (tests/fmu/test_state_tables.py). */
#define MASK_fmi3SetDebugLogging               ANY_MODE
#define MASK_fmi3EnterInitializationMode       MODE_INSTANTIATED
#define MASK_fmi3ExitInitializationMode        MODE_INITIALIZATION
#define MASK_fmi3EnterEventMode                MODE_CONTINUOUS_TIME
#define MASK_fmi3Terminate                     (MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP)
#define MASK_fmi3Reset                         ANY_MODE
#define MASK_fmi3GetFloat64                    ANY_MODE
#define MASK_fmi3GetInt32                      ANY_MODE
#define MASK_fmi3GetBoolean                    ANY_MODE
#define MASK_fmi3SetFloat64                    (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP)
#define MASK_fmi3SetInt32                      (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_STEP)
#define MASK_fmi3SetBoolean                    (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_STEP)
#define MASK_fmi3GetFMUState                   (ANY_MODE & ~MODE_ERROR)
#define MASK_fmi3SetFMUState                   ANY_MODE
#define MASK_fmi3FreeFMUState                  ANY_MODE
#define MASK_fmi3SerializedFMUStateSize        ANY_MODE
#define MASK_fmi3SerializeFMUState             ANY_MODE
#define MASK_fmi3DeserializeFMUState           ANY_MODE
#define MASK_fmi3GetDirectionalDerivative      (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED)
#define MASK_fmi3GetAdjointDerivative          (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED)
#define MASK_fmi3UpdateDiscreteStates          MODE_EVENT
#define MASK_fmi3EnterContinuousTimeMode       MODE_EVENT
#define MASK_fmi3CompletedIntegratorStep       MODE_CONTINUOUS_TIME
#define MASK_fmi3SetTime                       MODE_CONTINUOUS_TIME
#define MASK_fmi3SetContinuousStates           MODE_CONTINUOUS_TIME
#define MASK_fmi3GetContinuousStateDerivatives (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_TERMINATED)
#define MASK_fmi3GetEventIndicators            (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_TERMINATED)
#define MASK_fmi3GetContinuousStates           (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_TERMINATED)
#define MASK_fmi3GetNominalsOfContinuousStates (MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_TERMINATED)
#define MASK_fmi3GetNumberOfEventIndicators    (MODE_INSTANTIATED | MODE_EVENT)
#define MASK_fmi3GetNumberOfContinuousStates   (MODE_INSTANTIATED | MODE_EVENT)
#define MASK_fmi3DoStep                        MODE_STEP

static void log_to_importer(void *instance_pointer, Status status, const char *category, const char *message) {
    Instance *instance = (Instance *)instance_pointer;
    const Component *component = (const Component *)instance->log_context;
    if (!component || !component->log_message) return;
    component->log_message(component->environment, (fmi3Status)status, category, message);
}

static void *allocate_zeroed(size_t count, size_t size) { return calloc(count, size); }

static void release(void *pointer) { free(pointer); }

static Instance *checked(fmi3Instance c, const char *function, int allowed_modes) {
    Component *component = (Component *)c;
    Instance *instance;
    if (!component || !component->instance) return NULL;
    instance = component->instance;
    if (!(instance->now.mode & allowed_modes)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s must not be called in the current state",
                     function);
        return NULL;
    }
    return instance;
}

/* The hooks of the instance's model (of this binary's model without an instance: its check refuses that). */
static const ModelHooks *hooks_of(fmi3Instance c) {
    const Component *component = (const Component *)c;
    return model_hooks(component && component->instance ? component->instance->info : &model_info);
}

/* A model-exchange function of an FMU without model exchange (ModelHooks.model_exchange = 0): refused in every state
 * (1, with a message; 0 otherwise, also without an instance: its check refuses that). */
static int without_model_exchange(fmi3Instance c, const char *function) {
    Component *component = (Component *)c;
    if (!component || !component->instance || hooks_of(c)->model_exchange) return 0;
    instance_log(component->instance, STATUS_ERROR, "logStatusError",
                 "%s: needs a model-exchange instance (this FMU is for co-simulation only)", function);
    return 1;
}

/* A model-exchange function an importer may also call on a co-simulation instance. */
static Instance *checked_model_exchange(fmi3Instance c, const char *function, int allowed_modes) {
    return without_model_exchange(c, function) ? NULL : checked(c, function, allowed_modes);
}

/* A function that exists only for one interface type (model exchange or co-simulation). */
static Instance *checked_type(fmi3Instance c, const char *function, int allowed_modes, int cosimulation) {
    Instance *instance = !cosimulation && without_model_exchange(c, function) ? NULL : checked(c, function, allowed_modes);
    if (instance && instance->is_cosimulation != cosimulation) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s needs a %s instance", function,
                     cosimulation ? "co-simulation" : "model exchange");
        return NULL;
    }
    return instance;
}

static fmi3Status finish(Instance *instance, Status status) {
    if (status >= STATUS_ERROR) instance->now.mode = MODE_ERROR;
    return (fmi3Status)status;
}

static fmi3Status unsupported(fmi3Instance c, const char *function, const char *reason) {
    Instance *instance = checked(c, function, ANY_MODE);
    if (!instance) return fmi3Error;
    instance_log(instance, STATUS_ERROR, "logStatusError", "%s: %s", function, reason);
    return fmi3Error;
}

/* A refused null output argument, with its log message. */
static int present(Instance *instance, const char *function, const void *pointer, const char *name) {
    if (pointer) return 1;
    instance_log(instance, STATUS_ERROR, "logStatusError", "%s: %s is a null pointer", function, name);
    return 0;
}

/* Scalar variables only: one value per value reference. */
static int counts_match(Instance *instance, const char *function, size_t nValueReferences, size_t nValues) {
    if (nValueReferences == nValues) return 1;
    instance_log(instance, STATUS_ERROR, "logStatusError",
                 "%s: %lu values for %lu value references (all variables are scalars)", function,
                 (unsigned long)nValues, (unsigned long)nValueReferences);
    return 0;
}

/* ---- common functions ----------------------------------------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    Instance *instance = checked(c, "fmi3SetDebugLogging", MASK_fmi3SetDebugLogging);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_set_debug_logging(instance, loggingOn ? 1 : 0, nCategories, categories,
                                                  "fmi3SetDebugLogging");
}

static fmi3Instance instantiate(fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
                                fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                fmi3LogMessageCallback logMessage, int cosimulation) {
    const ModelHooks *hooks = model_hooks(&model_info);
    Component *component;
    char reason[700], message[800];
    if (!instanceName || !instanceName[0]) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "fmi3Instantiate: missing instance name");
        return NULL;
    }
    if (!hooks->instantiate && (!instantiationToken || strcmp(instantiationToken, model_info.guid) != 0)) {
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       "fmi3Instantiate: the instantiation token does not match this binary's modelDescription.xml");
        return NULL;
    }
    component = (Component *)calloc(1, sizeof(Component));
    if (!component) return NULL;
    component->environment = instanceEnvironment;
    component->log_message = logMessage;
    if (hooks->instantiate) { /* the model reads its resources and checks the token itself */
        reason[0] = '\0';
        component->instance = hooks->instantiate(instanceName, instantiationToken, resourcePath, cosimulation,
                                                 allocate_zeroed, release, log_to_importer, component, reason,
                                                 sizeof(reason));
    } else {
        component->instance = instance_create(&model_info, instanceName, cosimulation, allocate_zeroed, release,
                                              log_to_importer, component);
        snprintf(reason, sizeof(reason), "out of memory");
    }
    if (!component->instance) {
        snprintf(message, sizeof(message), "fmi3Instantiate: %s", reason[0] ? reason : "failed");
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", message);
        free(component);
        return NULL;
    }
    component->instance->environment = instanceEnvironment;
    component->instance->logging_on = loggingOn ? 1 : 0;
    return component;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    char message[300];
    (void)visible;
    if (!model_hooks(&model_info)->model_exchange) {
        snprintf(message, sizeof(message),
                 "fmi3InstantiateModelExchange: %s is for co-simulation only (it has no model-exchange interface)",
                 model_info.model_identifier);
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", message);
        return NULL;
    }
    return instantiate(instanceName, instantiationToken, resourcePath, loggingOn, instanceEnvironment, logMessage, 0);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    const ModelHooks *hooks = model_hooks(&model_info);
    Component *component;
    (void)visible;
    (void)requiredIntermediateVariables;
    (void)intermediateUpdate;
    if (eventModeUsed) {
        /* hasEventMode="false": events are located and handled inside the step, as in FMI 2.0 */
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       hooks->early_return
                           ? "fmi3InstantiateCoSimulation: event mode is not supported (hasEventMode=\"false\"); "
                             "events are located and handled inside fmi3DoStep (earlyReturnAllowed: it returns at "
                             "their instants)"
                           : "fmi3InstantiateCoSimulation: event mode is not supported (hasEventMode=\"false\"); "
                             "events are handled inside fmi3DoStep");
        return NULL;
    }
    if (nRequiredIntermediateVariables > 0) { /* providesIntermediateUpdate="false" */
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       "fmi3InstantiateCoSimulation: the FMU provides no intermediate variables");
        return NULL;
    }
    component = (Component *)instantiate(instanceName, instantiationToken, resourcePath, loggingOn, instanceEnvironment,
                                         logMessage, 1);
    /* the model's own step may return early; the in-step solver never does (events are handled inside doStep) */
    if (component) component->instance->early_return_allowed = earlyReturnAllowed && hooks->early_return;
    return component;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   model_hooks(&model_info)->model_exchange
                       ? "fmi3InstantiateScheduledExecution: the FMU supports model exchange and co-simulation only"
                       : "fmi3InstantiateScheduledExecution: the FMU is for co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance c) {
    Component *component = (Component *)c;
    if (!component) return;
    instance_free(component->instance);
    free(component);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Instance *instance = checked(c, "fmi3EnterInitializationMode", MASK_fmi3EnterInitializationMode);
    (void)toleranceDefined;
    (void)tolerance;
    if (!instance) return fmi3Error;
    if (!isfinite(startTime) || (stopTimeDefined && (!isfinite(stopTime) || stopTime < startTime))) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "fmi3EnterInitializationMode: start time %g and stop time %g must be finite, stop >= start",
                     startTime, stopTime);
        return fmi3Error;
    }
    instance->start_time = startTime;
    instance->now.time = startTime;
    instance->stop_time_defined = stopTimeDefined ? 1 : 0;
    instance->stop_time = stopTime;
    if (model_hooks(instance->info)->start_time_parameter >= 0) /* a parameter of the initial state */
        instance->now.p[model_hooks(instance->info)->start_time_parameter] = startTime;
    instance->now.mode = MODE_INITIALIZATION;
    instance->initial_state_valid = 0;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Instance *instance = checked(c, "fmi3ExitInitializationMode", MASK_fmi3ExitInitializationMode);
    int states_changed, discrete_changed;
    Status status;
    if (!instance) return fmi3Error;
    status = instance_apply_initial_state(instance);
    if (status == STATUS_OK) status = instance_event_iteration(instance, &states_changed, &discrete_changed);
    instance->now.mode = instance->is_cosimulation ? MODE_STEP : MODE_EVENT;
    return finish(instance, status);
}

fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    Instance *instance = checked_type(c, "fmi3EnterEventMode", MASK_fmi3EnterEventMode, 0);
    if (!instance) return fmi3Error;
    instance->now.mode = MODE_EVENT;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance c) {
    Instance *instance = checked(c, "fmi3Terminate", MASK_fmi3Terminate);
    if (!instance) return fmi3Error;
    instance->now.mode = MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c) {
    Instance *instance = checked(c, "fmi3Reset", MASK_fmi3Reset);
    if (!instance) return fmi3Error;
    instance_reset(instance);
    return fmi3OK;
}

/* ---- variables -------------------------------------------------------------------------------- */

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues) {
    Instance *instance = checked(c, "fmi3GetFloat64", MASK_fmi3GetFloat64);
    size_t i, start = 0;
    if (!instance || !counts_match(instance, "fmi3GetFloat64", nValueReferences, nValues)) return fmi3Error;
    if (nValueReferences > 0 && (!valueReferences || !values)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "fmi3GetFloat64: null argument");
        return fmi3Error;
    }
    /* runs of model variables go to the instance in one call; time is answered here */
    for (i = 0; i <= nValueReferences; i++) {
        if (i < nValueReferences && valueReferences[i] != TIME_REFERENCE) continue;
        if (i > start && instance_get(instance, valueReferences + start, i - start, KIND_REAL, values + start) !=
                             STATUS_OK)
            return fmi3Error;
        if (i < nValueReferences) values[i] = instance->now.time;
        start = i + 1;
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Int32 values[], size_t nValues) {
    Instance *instance = checked(c, "fmi3GetInt32", MASK_fmi3GetInt32);
    if (!instance || !counts_match(instance, "fmi3GetInt32", nValueReferences, nValues)) return fmi3Error;
    /* fmi3Int32 is the runtime's int on every platform FMI 3.0 supports */
    return (fmi3Status)instance_get(instance, valueReferences, nValueReferences, KIND_INTEGER, values);
}

#define BOOLEAN_CHUNK 64

fmi3Status fmi3GetBoolean(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Boolean values[], size_t nValues) {
    Instance *instance = checked(c, "fmi3GetBoolean", MASK_fmi3GetBoolean);
    int chunk[BOOLEAN_CHUNK];
    size_t start, i;
    if (!instance || !counts_match(instance, "fmi3GetBoolean", nValueReferences, nValues)) return fmi3Error;
    if (nValueReferences > 0 && (!valueReferences || !values)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "fmi3GetBoolean: null argument");
        return fmi3Error;
    }
    /* the instance stores Booleans as int, fmi3Boolean is bool */
    for (start = 0; start < nValueReferences; start += BOOLEAN_CHUNK) {
        size_t n = nValueReferences - start < BOOLEAN_CHUNK ? nValueReferences - start : BOOLEAN_CHUNK;
        if (instance_get(instance, valueReferences + start, n, KIND_BOOLEAN, chunk) != STATUS_OK) return fmi3Error;
        for (i = 0; i < n; i++) values[start + i] = chunk[i] ? fmi3True : fmi3False;
    }
    return fmi3OK;
}

static int sets_time(Instance *instance, const char *function, const fmi3ValueReference valueReferences[],
                     size_t nValueReferences) {
    size_t i;
    for (i = 0; valueReferences && i < nValueReferences; i++)
        if (valueReferences[i] == TIME_REFERENCE) {
            instance_log(instance, STATUS_ERROR, "logStatusError", "%s: time (value reference 0) cannot be set",
                         function);
            return 1;
        }
    return 0;
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues) {
    Instance *instance = checked(c, "fmi3SetFloat64", MASK_fmi3SetFloat64);
    if (!instance || !counts_match(instance, "fmi3SetFloat64", nValueReferences, nValues) ||
        sets_time(instance, "fmi3SetFloat64", valueReferences, nValueReferences))
        return fmi3Error;
    return (fmi3Status)instance_set(instance, valueReferences, nValueReferences, KIND_REAL, values);
}

fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Int32 values[], size_t nValues) {
    Instance *instance = checked(c, "fmi3SetInt32", MASK_fmi3SetInt32);
    if (!instance || !counts_match(instance, "fmi3SetInt32", nValueReferences, nValues)) return fmi3Error;
    return (fmi3Status)instance_set(instance, valueReferences, nValueReferences, KIND_INTEGER, values);
}

fmi3Status fmi3SetBoolean(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Boolean values[], size_t nValues) {
    Instance *instance = checked(c, "fmi3SetBoolean", MASK_fmi3SetBoolean);
    int chunk[BOOLEAN_CHUNK];
    size_t start, i;
    if (!instance || !counts_match(instance, "fmi3SetBoolean", nValueReferences, nValues)) return fmi3Error;
    if (nValueReferences > 0 && (!valueReferences || !values)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "fmi3SetBoolean: null argument");
        return fmi3Error;
    }
    for (start = 0; start < nValueReferences; start += BOOLEAN_CHUNK) {
        size_t n = nValueReferences - start < BOOLEAN_CHUNK ? nValueReferences - start : BOOLEAN_CHUNK;
        for (i = 0; i < n; i++) chunk[i] = values[start + i] ? 1 : 0;
        if (instance_set(instance, valueReferences + start, n, KIND_BOOLEAN, chunk) != STATUS_OK) return fmi3Error;
    }
    return fmi3OK;
}

/* The model has variables of types Float64, Int32 and Boolean only: any value reference given to another
 * type's getter or setter is a misuse. */
static fmi3Status no_such_type(fmi3Instance c, const char *function, int allowed_modes, size_t nValueReferences,
                               const char *type) {
    Instance *instance = checked(c, function, allowed_modes);
    if (!instance) return fmi3Error;
    if (nValueReferences == 0) return fmi3OK;
    instance_log(instance, STATUS_ERROR, "logStatusError", "%s: the model has no %s variables", function, type);
    return fmi3Error;
}

#define OTHER_TYPE(TYPE, CTYPE)                                                                                    \
    fmi3Status fmi3Get##TYPE(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                             CTYPE values[], size_t nValues) {                                                    \
        (void)valueReferences;                                                                                    \
        (void)values;                                                                                             \
        (void)nValues;                                                                                            \
        return no_such_type(c, "fmi3Get" #TYPE, GET_MODES, nValueReferences, #TYPE);                            \
    }                                                                                                             \
    fmi3Status fmi3Set##TYPE(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                             const CTYPE values[], size_t nValues) {                                              \
        (void)valueReferences;                                                                                    \
        (void)values;                                                                                             \
        (void)nValues;                                                                                            \
        return no_such_type(c, "fmi3Set" #TYPE, SET_REAL_MODES, nValueReferences, #TYPE);                       \
    }

OTHER_TYPE(Float32, fmi3Float32)
OTHER_TYPE(Int8, fmi3Int8)
OTHER_TYPE(UInt8, fmi3UInt8)
OTHER_TYPE(Int16, fmi3Int16)
OTHER_TYPE(UInt16, fmi3UInt16)
OTHER_TYPE(UInt32, fmi3UInt32)
OTHER_TYPE(Int64, fmi3Int64)
OTHER_TYPE(UInt64, fmi3UInt64)
OTHER_TYPE(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    (void)valueReferences;
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return no_such_type(c, "fmi3GetBinary", GET_MODES, nValueReferences, "Binary");
}

fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)valueReferences;
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return no_such_type(c, "fmi3SetBinary", SET_REAL_MODES, nValueReferences, "Binary");
}

fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[]) {
    (void)valueReferences;
    (void)values;
    return no_such_type(c, "fmi3GetClock", ANY_MODE, nValueReferences, "Clock");
}

fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[]) {
    (void)valueReferences;
    (void)values;
    return no_such_type(c, "fmi3SetClock", ANY_MODE, nValueReferences, "Clock");
}

/* ---- variable dependencies: declared in the ModelStructure (providesPerElementDependencies="false") ---- */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference;
    (void)nDependencies;
    return unsupported(c, "fmi3GetNumberOfVariableDependencies",
                       "the dependencies are declared in the modelDescription.xml ModelStructure");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    return unsupported(c, "fmi3GetVariableDependencies",
                       "the dependencies are declared in the modelDescription.xml ModelStructure");
}

/* ---- FMU state -------------------------------------------------------------------------------- */

fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *FMUState) {
    Instance *instance = checked(c, "fmi3GetFMUState", MASK_fmi3GetFMUState);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_get_state(instance, FMUState, "fmi3GetFMUState");
}

fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState FMUState) {
    Instance *instance = checked(c, "fmi3SetFMUState", MASK_fmi3SetFMUState);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_set_state(instance, FMUState, "fmi3SetFMUState");
}

fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *FMUState) {
    Instance *instance = checked(c, "fmi3FreeFMUState", MASK_fmi3FreeFMUState);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_free_state(instance, FMUState, "fmi3FreeFMUState");
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState FMUState, size_t *size) {
    Instance *instance = checked(c, "fmi3SerializedFMUStateSize", MASK_fmi3SerializedFMUStateSize);
    if (!instance || !present(instance, "fmi3SerializedFMUStateSize", size, "size") ||
        !snapshot_handle_valid(instance, FMUState, "fmi3SerializedFMUStateSize"))
        return fmi3Error;
    *size = snapshot_serialized_size(instance);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size) {
    Instance *instance = checked(c, "fmi3SerializeFMUState", MASK_fmi3SerializeFMUState);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_serialize_state(instance, FMUState, (char *)serializedState, size,
                                                "fmi3SerializeFMUState");
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    Instance *instance = checked(c, "fmi3DeserializeFMUState", MASK_fmi3DeserializeFMUState);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_deserialize_state(instance, (const char *)serializedState, size, FMUState, 1,
                                                  "fmi3DeserializeFMUState");
}

/* ---- partial derivatives ---------------------------------------------------------------------- */

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    Instance *instance;
    if (!hooks_of(c)->partial_derivatives)
        return unsupported(c, "fmi3GetDirectionalDerivative", "not provided (providesDirectionalDerivatives=\"false\")");
    instance = checked(c, "fmi3GetDirectionalDerivative", MASK_fmi3GetDirectionalDerivative);
    if (!instance) return fmi3Error;
    if (nSeed != nKnowns || nSensitivity != nUnknowns) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "fmi3GetDirectionalDerivative: expected %lu seeds and %lu sensitivities",
                     (unsigned long)nKnowns, (unsigned long)nUnknowns);
        return fmi3Error;
    }
    return (fmi3Status)instance_directional_derivative(instance, unknowns, nUnknowns, knowns, nKnowns, seed,
                                                       sensitivity);
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    Instance *instance;
    if (!hooks_of(c)->partial_derivatives)
        return unsupported(c, "fmi3GetAdjointDerivative", "not provided (providesAdjointDerivatives=\"false\")");
    instance = checked(c, "fmi3GetAdjointDerivative", MASK_fmi3GetAdjointDerivative);
    if (!instance) return fmi3Error;
    if (nSeed != nUnknowns || nSensitivity != nKnowns) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "fmi3GetAdjointDerivative: expected %lu seeds and %lu sensitivities",
                     (unsigned long)nUnknowns, (unsigned long)nKnowns);
        return fmi3Error;
    }
    return (fmi3Status)instance_adjoint_derivative(instance, unknowns, nUnknowns, knowns, nKnowns, seed,
                                                   sensitivity);
}

/* ---- configuration mode, clocks: the model has no structural parameters and no clocks ---------- */

fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) {
    return unsupported(c, "fmi3EnterConfigurationMode", "the model has no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) {
    return unsupported(c, "fmi3ExitConfigurationMode", "the model has no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences;
    (void)intervals;
    (void)qualifiers;
    return no_such_type(c, "fmi3GetIntervalDecimal", ANY_MODE, nValueReferences, "Clock");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)valueReferences;
    (void)counters;
    (void)resolutions;
    (void)qualifiers;
    return no_such_type(c, "fmi3GetIntervalFraction", ANY_MODE, nValueReferences, "Clock");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                               fmi3Float64 shifts[]) {
    (void)valueReferences;
    (void)shifts;
    return no_such_type(c, "fmi3GetShiftDecimal", ANY_MODE, nValueReferences, "Clock");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)valueReferences;
    (void)counters;
    (void)resolutions;
    return no_such_type(c, "fmi3GetShiftFraction", ANY_MODE, nValueReferences, "Clock");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[]) {
    (void)valueReferences;
    (void)intervals;
    return no_such_type(c, "fmi3SetIntervalDecimal", ANY_MODE, nValueReferences, "Clock");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    (void)valueReferences;
    (void)counters;
    (void)resolutions;
    return no_such_type(c, "fmi3SetIntervalFraction", ANY_MODE, nValueReferences, "Clock");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                               const fmi3Float64 shifts[]) {
    (void)valueReferences;
    (void)shifts;
    return no_such_type(c, "fmi3SetShiftDecimal", ANY_MODE, nValueReferences, "Clock");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)valueReferences;
    (void)counters;
    (void)resolutions;
    return no_such_type(c, "fmi3SetShiftFraction", ANY_MODE, nValueReferences, "Clock");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference;
    (void)activationTime;
    return unsupported(c, "fmi3ActivateModelPartition", "the FMU supports no scheduled execution");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) {
    return unsupported(c, "fmi3EvaluateDiscreteStates", "not provided (providesEvaluateDiscreteStates=\"false\")");
}

/* ---- model exchange --------------------------------------------------------------------------- */

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    const char *function = "fmi3UpdateDiscreteStates";
    Instance *instance = checked_type(c, "fmi3UpdateDiscreteStates", MASK_fmi3UpdateDiscreteStates, 0);
    int states_changed = 0, discrete_changed = 0;
    Status status;
    /* every output is required, as fmi2NewDiscreteStates' eventInfo: a null one is refused before any work */
    if (!instance || !present(instance, function, discreteStatesNeedUpdate, "discreteStatesNeedUpdate") ||
        !present(instance, function, terminateSimulation, "terminateSimulation") ||
        !present(instance, function, nominalsOfContinuousStatesChanged, "nominalsOfContinuousStatesChanged") ||
        !present(instance, function, valuesOfContinuousStatesChanged, "valuesOfContinuousStatesChanged") ||
        !present(instance, function, nextEventTimeDefined, "nextEventTimeDefined") ||
        !present(instance, function, nextEventTime, "nextEventTime"))
        return fmi3Error;
    /* the event iteration runs to its fixed point here, so no further update is needed */
    status = instance_event_iteration(instance, &states_changed, &discrete_changed);
    states_changed |= instance_take_input_jump(instance);
    *discreteStatesNeedUpdate = fmi3False;
    *terminateSimulation = fmi3False;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = states_changed ? fmi3True : fmi3False;
    *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0.0;
    return finish(instance, status);
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    Instance *instance = checked_type(c, "fmi3EnterContinuousTimeMode", MASK_fmi3EnterContinuousTimeMode, 0);
    if (!instance) return fmi3Error;
    instance->now.mode = MODE_CONTINUOUS_TIME;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    Instance *instance = checked_type(c, "fmi3CompletedIntegratorStep", MASK_fmi3CompletedIntegratorStep, 0);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!instance || !present(instance, "fmi3CompletedIntegratorStep", enterEventMode, "enterEventMode") ||
        !present(instance, "fmi3CompletedIntegratorStep", terminateSimulation, "terminateSimulation"))
        return fmi3Error;
    *enterEventMode = fmi3False;
    *terminateSimulation = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    Instance *instance = checked_type(c, "fmi3SetTime", MASK_fmi3SetTime, 0);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_set_time(instance, time);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 continuousStates[], size_t nContinuousStates) {
    Instance *instance = checked_type(c, "fmi3SetContinuousStates", MASK_fmi3SetContinuousStates, 0);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_set_states(instance, continuousStates, nContinuousStates);
}

/* Checks a state or event indicator vector argument; applies the initial state in initialization. */
static Instance *checked_vector(fmi3Instance c, const char *function, int allowed_modes, const void *vector, size_t n,
                                int expected) {
    Instance *instance = checked_type(c, function, allowed_modes, 0);
    if (!instance) return NULL;
    if (n != (size_t)expected || (n > 0 && !vector)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: expected a vector of %d", function, expected);
        return NULL;
    }
    if ((instance->now.mode & MODE_INITIALIZATION) && !instance->initial_state_valid &&
        instance_apply_initial_state(instance) != STATUS_OK)
        return NULL;
    return instance;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 derivatives[], size_t nContinuousStates) {
    Instance *instance = checked_type(c, "fmi3GetContinuousStateDerivatives", MASK_fmi3GetContinuousStateDerivatives, 0);
    if (!instance) return fmi3Error;
    instance = checked_vector(c, "fmi3GetContinuousStateDerivatives", MASK_fmi3GetContinuousStateDerivatives, derivatives, nContinuousStates,
                              instance->info->nx);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_derivatives(instance, instance->now.x, instance->now.d, derivatives);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    Instance *instance = checked_type(c, "fmi3GetEventIndicators", MASK_fmi3GetEventIndicators, 0);
    if (!instance) return fmi3Error;
    instance = checked_vector(c, "fmi3GetEventIndicators", MASK_fmi3GetEventIndicators, eventIndicators, nEventIndicators,
                              instance->info->nz);
    if (!instance) return fmi3Error;
    return (fmi3Status)instance_event_indicators(instance, instance->now.x, instance->now.d, eventIndicators);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    Instance *instance = checked_type(c, "fmi3GetContinuousStates", MASK_fmi3GetContinuousStates, 0);
    if (!instance) return fmi3Error;
    instance = checked_vector(c, "fmi3GetContinuousStates", MASK_fmi3GetContinuousStates, continuousStates, nContinuousStates,
                              instance->info->nx);
    if (!instance) return fmi3Error;
    memcpy(continuousStates, instance->now.x, sizeof(double) * nContinuousStates);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[], size_t nContinuousStates) {
    Instance *instance = checked_type(c, "fmi3GetNominalsOfContinuousStates", MASK_fmi3GetNominalsOfContinuousStates, 0);
    if (!instance) return fmi3Error;
    instance = checked_vector(c, "fmi3GetNominalsOfContinuousStates", MASK_fmi3GetNominalsOfContinuousStates, nominals,
                              nContinuousStates,
                              instance->info->nx);
    if (!instance) return fmi3Error;
    memcpy(nominals, instance->info->state_nominal, sizeof(double) * nContinuousStates);
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *nEventIndicators) {
    Instance *instance = checked_model_exchange(c, "fmi3GetNumberOfEventIndicators", MASK_fmi3GetNumberOfEventIndicators);
    if (!instance || !present(instance, "fmi3GetNumberOfEventIndicators", nEventIndicators, "nEventIndicators"))
        return fmi3Error;
    *nEventIndicators = (size_t)instance->info->nz;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *nContinuousStates) {
    Instance *instance = checked_model_exchange(c, "fmi3GetNumberOfContinuousStates", MASK_fmi3GetNumberOfContinuousStates);
    if (!instance || !present(instance, "fmi3GetNumberOfContinuousStates", nContinuousStates, "nContinuousStates"))
        return fmi3Error;
    *nContinuousStates = (size_t)instance->info->nx;
    return fmi3OK;
}

/* ---- co-simulation ---------------------------------------------------------------------------- */

fmi3Status fmi3EnterStepMode(fmi3Instance c) {
    /* only reachable with event mode, which the FMU does not offer */
    return unsupported(c, "fmi3EnterStepMode", "event mode is not supported (hasEventMode=\"false\")");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) {
    (void)valueReferences;
    (void)nValueReferences;
    (void)orders;
    (void)values;
    (void)nValues;
    return unsupported(c, "fmi3GetOutputDerivatives", "the FMU provides no output derivatives");
}

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    Instance *instance = checked_type(c, "fmi3DoStep", MASK_fmi3DoStep, 1);
    const ModelHooks *hooks;
    Status status;
    int early = 0;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!instance) return fmi3Error;
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "fmi3DoStep: null argument");
        return fmi3Error;
    }
    hooks = model_hooks(instance->info);
    /* wrong arguments change nothing, so the instance stays usable */
    if (hooks->step) { /* the model's own step: it may return early at an event's instant if the importer allows */
        if (hooks->check_step(instance, currentCommunicationPoint, communicationStepSize, "fmi3DoStep") != STATUS_OK)
            return fmi3Error;
        status = hooks->step(instance, currentCommunicationPoint, communicationStepSize, &early);
    } else {
        if (instance_check_step(instance, currentCommunicationPoint, communicationStepSize) != STATUS_OK)
            return fmi3Error;
        if (instance->stop_time_defined && currentCommunicationPoint + communicationStepSize >
                                               instance->stop_time + 1e-9 * (1.0 + instance->stop_time)) {
            instance_log(instance, STATUS_ERROR, "logStatusError", "fmi3DoStep would pass the stop time %.17g",
                         instance->stop_time);
            return fmi3Error;
        }
        /* events inside the step are located and handled by the in-step solver, exactly as in FMI 2.0 */
        status = instance_do_step(instance, currentCommunicationPoint, communicationStepSize);
    }
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = status == STATUS_OK && instance_ended(instance) ? fmi3True : fmi3False;
    *earlyReturn = early ? fmi3True : fmi3False;
    *lastSuccessfulTime = instance->now.time;
    return finish(instance, status);
}
