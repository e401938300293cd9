/* The scenario FMU's FMI-independent part (see scenario_fmi.h). */
#if defined(__MINGW32__) && !defined(__USE_MINGW_ANSI_STDIO)
#define __USE_MINGW_ANSI_STDIO 1
#endif
#include "scenario_fmi.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static int hex_value(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

int scenario_uri_to_path(const char *uri, char *path, size_t size, char *reason, size_t reason_size) {
    const char *p;
    size_t n = 0;
    if (!uri || !uri[0]) {
        snprintf(reason, reason_size, "no resource location given (the scenario is read from the FMU's resources/)");
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

Scenario *scenario_instantiate(const char *name, const char *token, const char *directory,
                               void *(*allocate)(size_t, size_t), void (*release)(void *), LogFn log,
                               void *log_context, char *reason, size_t reason_size) {
    char path[4200];
    size_t length = 0, data_size = 0, n = directory ? strlen(directory) : 0;
    char *text, *guid = NULL, **names = NULL;
    double *data, parameters[N_PARAMETERS];
    Scenario *scenario;
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
    scenario = (Scenario *)allocate(1, sizeof(Scenario));
    if (scenario) {
        memset(scenario, 0, sizeof(*scenario));
        scenario->allocate = allocate;
        scenario->release = release;
        scenario->guid = guid;
        scenario->names = names;
        scenario->n_names = vehicles;
        scenario->info = scenario_model_info(data, data_size, parameters, guid, allocate, release);
        if (scenario->info)
            scenario->instance = instance_create(scenario->info, name, 1, allocate, release, log, log_context);
    }
    if (!scenario || !scenario->info || !scenario->instance) {
        snprintf(reason, reason_size, "out of memory");
        if (scenario) {
            scenario_free(scenario);
        } else {
            release(guid);
            scenario_free_names(names, vehicles, release);
        }
        release(data);
        return NULL;
    }
    release(data);
    return scenario;
}

void scenario_free(Scenario *scenario) {
    void (*release)(void *);
    if (!scenario) return;
    release = scenario->release;
    if (scenario->instance) instance_free(scenario->instance);
    if (scenario->info) scenario_model_free(scenario->info, release);
    scenario_free_names(scenario->names, scenario->n_names, release);
    if (scenario->guid) release(scenario->guid);
    release(scenario);
}

void scenario_set_start_time(Scenario *scenario, double start_time) {
    scenario->instance->now.p[HIDDEN_START_TIME] = start_time;
}

static Logger logger_of(const Scenario *scenario) {
    Logger logger;
    logger.instance = scenario->instance;
    logger.model_names = (const char *const *)scenario->names;
    return logger;
}

Status scenario_exit_initialization(Scenario *scenario) {
    Instance *instance = scenario->instance;
    View view;
    view_make(&view, instance->now.p);
    /* the start from the inputs as they are; the first doStep takes it again from its own and logs its events */
    scenario_begin(&view, instance->now.u, instance->now.d, NULL);
    instance->initial_state_valid = 1;
    instance->now.mode = MODE_STEP;
    instance_invalidate(instance);
    return STATUS_OK;
}

int scenario_ended(const Scenario *scenario) {
    return scenario->instance->now.d[D_FINISHED] != 0.0;
}

Status scenario_check_step_arguments(Scenario *scenario, double t, double h, const char *function) {
    Instance *instance = scenario->instance;
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

Status scenario_do_step(Scenario *scenario, double t, double h, int early, int *returned_early) {
    Instance *instance = scenario->instance;
    Logger logger = logger_of(scenario);
    double reached;
    int result;
    View view;
    view_make(&view, instance->now.p);
    *returned_early = 0;
    result = scenario_step(&view, instance->now.u, instance->now.d, t, h, early, &logger, &reached);
    instance_invalidate(instance);
    if (result < 0) return STATUS_ERROR;
    instance->now.time = reached;
    *returned_early = result == 1;
    return STATUS_OK;
}

/* ---- FMU states ------------------------------------------------------------------------------------------------ */

/* Whether a state holds this scenario's data and a consistent scenario state (else logs why). */
static int state_fits(Scenario *scenario, const Snapshot *snapshot, const char *function) {
    const ModelInfo *info = scenario->info;
    char reason[200];
    View view;
    if (!isfinite(snapshot->p[HIDDEN_START_TIME]) ||
        memcmp(snapshot->p + DATA_START, info->parameter_start + DATA_START,
               sizeof(double) * (size_t)(info->np - DATA_START)) != 0) {
        instance_log(scenario->instance, STATUS_ERROR, "logStatusError",
                     "%s: the FMU state holds another scenario's data", function);
        return 0;
    }
    view_make(&view, snapshot->p);
    if (state_check(&view, snapshot->d, reason, sizeof(reason))) {
        instance_log(scenario->instance, STATUS_ERROR, "logStatusError", "%s: the FMU state is inconsistent: %s",
                     function, reason);
        return 0;
    }
    return 1;
}

Status scenario_set_state(Scenario *scenario, const void *state, const char *function) {
    Instance *instance = scenario->instance;
    if (!snapshot_handle_valid(instance, state, function)) return STATUS_ERROR;
    if (snapshot_check(instance, (const Snapshot *)state) != STATUS_OK) return STATUS_ERROR;
    if (!state_fits(scenario, (const Snapshot *)state, function)) return STATUS_ERROR;
    return instance_set_state(instance, state, function);
}

Status scenario_deserialize_state(Scenario *scenario, const char *bytes, size_t size, void **state,
                                  int reuse_existing, const char *function) {
    Instance *instance = scenario->instance;
    void *fresh = NULL;
    Status status;
    if (!state) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: null state pointer", function);
        return STATUS_ERROR;
    }
    if (reuse_existing && *state && !snapshot_handle_valid(instance, *state, function)) return STATUS_ERROR;
    status = instance_deserialize_state(instance, bytes, size, &fresh, 0, function);
    if (status != STATUS_OK) return status;
    if (!state_fits(scenario, (const Snapshot *)fresh, function)) {
        instance_free_state(instance, &fresh, function);
        return STATUS_ERROR;
    }
    if (reuse_existing && *state) {
        snapshot_copy(instance, (Snapshot *)*state, (const Snapshot *)fresh);
        instance_free_state(instance, &fresh, function);
        return STATUS_OK;
    }
    *state = fresh;
    return STATUS_OK;
}
