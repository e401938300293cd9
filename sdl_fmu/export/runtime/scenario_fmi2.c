/* The scenario FMU's FMI 2.0 API (co-simulation) over the generic instance layer, in the shape of the ego FMUs'
 * fmi2Functions.c: each function checks the calling sequence of the standard and answers misuse with fmi2Error and
 * a log message. Model-exchange functions exist (some importers resolve every symbol) and refuse: the FMU is for
 * co-simulation only. */
#include "fmi2Functions.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "scenario_fmi.h"

typedef struct {
    Scenario *scenario;
    fmi2CallbackFunctions callbacks;
} Component;

#define ANY_MODE                                                                                               \
    (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP | MODE_TERMINATED |   \
     MODE_ERROR)
/* The FMI 2.0 state table (section 4.2.4, co-simulation) in one place: the states in which each function is allowed
 * (elsewhere it returns fmi2Error with a log message). tests/test_state_tables.py compares it with the standard's. */
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

static Instance *checked(fmi2Component c, const char *function, int allowed_modes) {
    Component *component = (Component *)c;
    Instance *instance;
    if (!component || !component->scenario) return NULL;
    instance = component->scenario->instance;
    if (!(instance->now.mode & allowed_modes)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s must not be called in the current state",
                     function);
        return NULL;
    }
    return instance;
}

static Scenario *scenario_of(fmi2Component c) { return ((Component *)c)->scenario; }

/* a model-exchange function: there is no model-exchange instance of this FMU */
static fmi2Status model_exchange_only(fmi2Component c, const char *function) {
    Instance *instance = checked(c, function, ANY_MODE);
    if (!instance) return fmi2Error;
    instance_log(instance, STATUS_ERROR, "logStatusError", "%s needs a model-exchange instance (this FMU is for "
                 "co-simulation only)", function);
    return fmi2Error;
}

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

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Component *component;
    char reason[600], path[4096];
    (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory) return NULL;
    if (!instanceName || !instanceName[0]) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, "?", fmi2Error, "logStatusError", "%s",
                              "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError", "%s",
                              fmuType == fmi2ModelExchange
                                  ? "fmi2Instantiate: the scenario FMU is for co-simulation only"
                                  : "fmi2Instantiate: unknown fmuType");
        return NULL;
    }
    component = (Component *)functions->allocateMemory(1, sizeof(Component));
    if (!component) return NULL;
    component->callbacks = *functions;
    component->scenario = NULL;
    if (scenario_uri_to_path(fmuResourceLocation, path, sizeof(path), reason, sizeof(reason)))
        component->scenario = scenario_instantiate(instanceName, fmuGUID, path, functions->allocateMemory,
                                                   functions->freeMemory, log_to_importer, &component->callbacks,
                                                   reason, sizeof(reason));
    if (!component->scenario) {
        char message[700];
        snprintf(message, sizeof(message), "fmi2Instantiate: %s", reason);
        if (functions->logger) /* the text as the argument of "%s": a '%' in it is no format */
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError", "%s",
                              message);
        functions->freeMemory(component);
        return NULL;
    }
    component->scenario->instance->environment = functions->componentEnvironment;
    component->scenario->instance->logging_on = loggingOn ? 1 : 0;
    return component;
}

void fmi2FreeInstance(fmi2Component c) {
    Component *component = (Component *)c;
    fmi2CallbackFreeMemory release;
    if (!component) return;
    release = component->callbacks.freeMemory;
    scenario_free(component->scenario);
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
    scenario_set_start_time(scenario_of(c), startTime);
    instance->initial_state_valid = 0;
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
    if (!instance) return fmi2Error;
    return finish(instance, scenario_exit_initialization(scenario_of(c)));
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *instance = checked(c, "fmi2Terminate", MASK_fmi2Terminate);
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
    return (fmi2Status)scenario_set_state(scenario_of(c), FMUstate, "fmi2SetFMUstate");
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
        return fmi2Error; /* a handle this instance did not issue, or freed: refused, as the ego FMUs do */
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
    return (fmi2Status)scenario_deserialize_state(scenario_of(c), serializedState, size, FMUstate, 0,
                                                  "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    Instance *instance = checked(c, "fmi2GetDirectionalDerivative", MASK_fmi2GetDirectionalDerivative);
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    if (!instance) return fmi2Error;
    instance_log(instance, STATUS_ERROR, "logStatusError",
                 "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=\"false\")");
    return fmi2Error;
}

/* ---- model exchange: not this FMU --------------------------------------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) { return model_exchange_only(c, "fmi2EnterEventMode"); }

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    (void)eventInfo;
    return model_exchange_only(c, "fmi2NewDiscreteStates");
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    return model_exchange_only(c, "fmi2EnterContinuousTimeMode");
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    (void)enterEventMode;
    (void)terminateSimulation;
    return model_exchange_only(c, "fmi2CompletedIntegratorStep");
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    (void)time;
    return model_exchange_only(c, "fmi2SetTime");
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    (void)x;
    (void)nx;
    return model_exchange_only(c, "fmi2SetContinuousStates");
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    (void)derivatives;
    (void)nx;
    return model_exchange_only(c, "fmi2GetDerivatives");
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    (void)eventIndicators;
    (void)ni;
    return model_exchange_only(c, "fmi2GetEventIndicators");
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    (void)x;
    (void)nx;
    return model_exchange_only(c, "fmi2GetContinuousStates");
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    (void)x_nominal;
    (void)nx;
    return model_exchange_only(c, "fmi2GetNominalsOfContinuousStates");
}

/* ---- co-simulation ---------------------------------------------------------------------------- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Instance *instance = checked(c, "fmi2SetRealInputDerivatives", MASK_fmi2SetRealInputDerivatives);
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
    Instance *instance = checked(c, "fmi2GetRealOutputDerivatives", MASK_fmi2GetRealOutputDerivatives);
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
    Instance *instance = checked(c, "fmi2DoStep", MASK_fmi2DoStep);
    int early;
    Status status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!instance) return fmi2Error;
    /* wrong arguments change nothing, so the instance stays usable */
    if (scenario_check_step_arguments(scenario_of(c), currentCommunicationPoint, communicationStepSize,
                                      "fmi2DoStep") != STATUS_OK)
        return fmi2Error;
    status = scenario_do_step(scenario_of(c), currentCommunicationPoint, communicationStepSize, 0, &early);
    return finish(instance, status);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    Instance *instance = checked(c, "fmi2CancelStep", MASK_fmi2CancelStep);
    if (!instance) return fmi2Error;
    instance_log(instance, STATUS_ERROR, "logStatusError", "fmi2DoStep always completes: nothing to cancel");
    return fmi2Error;
}

static fmi2Status status_not_available(Instance *instance, const char *function, fmi2StatusKind s) {
    instance_log(instance, STATUS_DISCARD, "logStatusWarning",
                 "%s: status kind %d is not available (fmi2DoStep always completes; reported are fmi2GetStatus("
                 "fmi2DoStepStatus), fmi2GetRealStatus(fmi2LastSuccessfulTime) and fmi2GetBooleanStatus("
                 "fmi2Terminated))",
                 function, (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    Instance *instance = checked(c, "fmi2GetStatus", MASK_fmi2GetStatus);
    if (!instance || !present(instance, "fmi2GetStatus", value, "value")) return fmi2Error;
    if (s == fmi2DoStepStatus) {
        *value = fmi2OK;
        return fmi2OK;
    }
    return status_not_available(instance, "fmi2GetStatus", s);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *instance = checked(c, "fmi2GetRealStatus", MASK_fmi2GetRealStatus);
    if (!instance || !present(instance, "fmi2GetRealStatus", value, "value")) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) {
        *value = instance->now.time;
        return fmi2OK;
    }
    return status_not_available(instance, "fmi2GetRealStatus", s);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    Instance *instance = checked(c, "fmi2GetIntegerStatus", MASK_fmi2GetIntegerStatus);
    (void)value;
    return instance ? status_not_available(instance, "fmi2GetIntegerStatus", s) : fmi2Error;
}

/* fmi2Terminated: true once the scenario has ended (ES or the run's end): the FMU asks the master to stop */
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    Instance *instance = checked(c, "fmi2GetBooleanStatus", MASK_fmi2GetBooleanStatus);
    if (!instance || !present(instance, "fmi2GetBooleanStatus", value, "value")) return fmi2Error;
    if (s == fmi2Terminated) {
        *value = scenario_ended(scenario_of(c)) ? fmi2True : fmi2False;
        return fmi2OK;
    }
    return status_not_available(instance, "fmi2GetBooleanStatus", s);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    Instance *instance = checked(c, "fmi2GetStringStatus", MASK_fmi2GetStringStatus);
    (void)value;
    return instance ? status_not_available(instance, "fmi2GetStringStatus", s) : fmi2Error;
}
