/* Generic instance handling: memory, variable access, evaluation of the model's functions, events,
 * FMU state. Knows the model only through ModelInfo (model.h). */
#if defined(__MINGW32__) && !defined(__USE_MINGW_ANSI_STDIO)
#define __USE_MINGW_ANSI_STDIO 1 /* Windows: mingw-w64's C99 vsnprintf (static), not msvcrt's: %zu in messages */
#endif
#include "instance.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define MAX_EVENT_ITERATIONS 20

static void *allocate_array(Instance *instance, size_t count, size_t size) {
    /* one extra element: CasADi and memcpy get a valid pointer even for empty vectors */
    return instance->allocate(count + 1, size);
}

/* The log categories declared in the modelDescription.xml (sdl_fmu/fmu/xml.py LOG_CATEGORIES, same order). */
static const char *const LOG_CATEGORIES[] = {"logEvents", "logStatusWarning", "logStatusError"};
#define N_LOG_CATEGORIES (sizeof(LOG_CATEGORIES) / sizeof(LOG_CATEGORIES[0]))
#define ALL_CATEGORIES ((1u << N_LOG_CATEGORIES) - 1u)

static int category_index(const char *category) {
    size_t i;
    for (i = 0; category && i < N_LOG_CATEGORIES; i++)
        if (strcmp(category, LOG_CATEGORIES[i]) == 0) return (int)i;
    return -1;
}

Status instance_set_debug_logging(Instance *instance, int logging_on, size_t n, const char *const categories[],
                                  const char *function) {
    unsigned mask = 0;
    size_t i;
    if (n > 0 && !categories) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: categories is a null pointer", function);
        return STATUS_ERROR;
    }
    for (i = 0; i < n; i++) {
        int index = category_index(categories[i]);
        if (index < 0) {
            instance_log(instance, STATUS_ERROR, "logStatusError",
                         "%s: unknown log category \"%s\" (declared: logEvents, logStatusWarning, logStatusError)",
                         function, categories[i] ? categories[i] : "(null)");
            return STATUS_ERROR;
        }
        mask |= 1u << index;
    }
    if (n == 0) {
        instance->logging_on = logging_on;
        instance->categories_on = logging_on ? ALL_CATEGORIES : 0u;
    } else {
        /* on: exactly the named categories; off: the named ones off, the others as they were */
        instance->categories_on = logging_on ? mask : (instance->categories_on & ~mask);
        instance->logging_on = instance->categories_on != 0u;
    }
    return STATUS_OK;
}

void instance_log(Instance *instance, Status status, const char *category, const char *format, ...) {
    char message[1024];
    va_list args;
    int index;
    if (!instance || !instance->log) return;
    index = category_index(category);
    if (status == STATUS_OK && (!instance->logging_on || index < 0 || !(instance->categories_on & (1u << index))))
        return;
    va_start(args, format);
    vsnprintf(message, sizeof(message), format, args);
    va_end(args);
    instance->log(instance, status, category, message);
}

/* the hooks of a model without any: every FMI function generic, no function of the model's own */
static const ModelHooks GENERIC_MODEL = {1, 1, 0, -1, -1, NULL, NULL, NULL, NULL, NULL};

const ModelHooks *model_hooks(const ModelInfo *info) { return info->hooks ? info->hooks : &GENERIC_MODEL; }

int instance_ended(const Instance *instance) {
    int index = model_hooks(instance->info)->ended_state;
    return index >= 0 && instance->now.d[index] != 0.0;
}

static void grow_work(const ModelFunction *function, casadi_int_t size[4]) {
    casadi_int_t sz[4] = {0, 0, 0, 0};
    int i;
    function->work(&sz[0], &sz[1], &sz[2], &sz[3]);
    for (i = 0; i < 4; i++)
        if (sz[i] > size[i]) size[i] = sz[i];
}

Instance *instance_create(const ModelInfo *info, const char *name, int is_cosimulation, AllocateFn allocate,
                          FreeFn release, LogFn log, void *log_context) {
    Instance *instance;
    casadi_int_t work[4] = {4, 2, 0, 0}; /* every function takes 4 arguments and gives at most 2 results */
    int n = info->nx, i;
    size_t name_length;

    if (!allocate || !release) return NULL;
    instance = (Instance *)allocate(1, sizeof(Instance));
    if (!instance) return NULL;
    instance->info = info;
    instance->allocate = allocate;
    instance->release = release;
    instance->log = log;
    instance->log_context = log_context;
    instance->is_cosimulation = is_cosimulation;
    instance->categories_on = ALL_CATEGORIES;
    instance->issued = NULL;
    instance->n_issued = instance->issued_capacity = 0;
    name_length = strlen(name ? name : "");
    instance->name = (char *)allocate(name_length + 1, 1);
    if (instance->name && name) memcpy(instance->name, name, name_length + 1);

    instance->now.x = (double *)allocate_array(instance, (size_t)info->nx, sizeof(double));
    instance->now.d = (double *)allocate_array(instance, (size_t)info->nd, sizeof(double));
    instance->now.u = (double *)allocate_array(instance, (size_t)info->nu, sizeof(double));
    instance->now.p = (double *)allocate_array(instance, (size_t)info->np, sizeof(double));
    instance->y = (double *)allocate_array(instance, (size_t)info->ny, sizeof(double));
    instance->z = (double *)allocate_array(instance, (size_t)info->nz, sizeof(double));
    instance->xdot = (double *)allocate_array(instance, (size_t)n, sizeof(double));

    grow_work(&info->derivatives, work);
    grow_work(&info->jacobian, work);
    grow_work(&info->outputs, work);
    grow_work(&info->event_indicators, work);
    grow_work(&info->discrete_update, work);
    grow_work(&info->initial_state, work);
    instance->arg = (const double **)allocate_array(instance, (size_t)work[0], sizeof(double *));
    instance->res = (double **)allocate_array(instance, (size_t)work[1], sizeof(double *));
    instance->iw = (casadi_int_t *)allocate_array(instance, (size_t)work[2], sizeof(casadi_int_t));
    instance->w = (double *)allocate_array(instance, (size_t)work[3], sizeof(double));

    instance->jac = (double *)allocate_array(instance, (size_t)(n * n), sizeof(double));
    instance->matrix = (double *)allocate_array(instance, (size_t)(n * n), sizeof(double));
    for (i = 0; i < 6; i++) instance->stage[i] = (double *)allocate_array(instance, (size_t)n, sizeof(double));
    instance->x_stage = (double *)allocate_array(instance, (size_t)n, sizeof(double));
    instance->rhs = (double *)allocate_array(instance, (size_t)n, sizeof(double));
    instance->x_start = (double *)allocate_array(instance, (size_t)n, sizeof(double));
    instance->x_trial = (double *)allocate_array(instance, (size_t)n, sizeof(double));
    instance->z_start = (double *)allocate_array(instance, (size_t)info->nz, sizeof(double));
    instance->z_trial = (double *)allocate_array(instance, (size_t)info->nz, sizeof(double));
    instance->d_trial = (double *)allocate_array(instance, (size_t)info->nd, sizeof(double));
    instance->pivots = (int *)allocate_array(instance, (size_t)n, sizeof(int));

    if (!instance->name || !instance->now.x || !instance->now.d || !instance->now.u || !instance->now.p ||
        !instance->y || !instance->z || !instance->xdot || !instance->arg || !instance->res || !instance->iw ||
        !instance->w || !instance->jac || !instance->matrix || !instance->stage[0] || !instance->stage[1] ||
        !instance->stage[2] || !instance->stage[3] || !instance->stage[4] || !instance->stage[5] ||
        !instance->x_stage || !instance->rhs || !instance->x_start || !instance->x_trial || !instance->z_start ||
        !instance->z_trial || !instance->d_trial || !instance->pivots) {
        instance_free(instance);
        return NULL;
    }
    instance_reset(instance);
    return instance;
}

void instance_free(Instance *instance) {
    FreeFn release;
    const ModelHooks *hooks;
    void *model_data;
    int i;
    if (!instance) return;
    release = instance->release;
    hooks = model_hooks(instance->info);
    model_data = instance->model_data; /* it may hold the ModelInfo: freed last */
    release(instance->name);
    release(instance->now.x);
    release(instance->now.d);
    release(instance->now.u);
    release(instance->now.p);
    release(instance->y);
    release(instance->z);
    release(instance->xdot);
    release((void *)instance->arg);
    release(instance->res);
    release(instance->iw);
    release(instance->w);
    release(instance->jac);
    release(instance->matrix);
    for (i = 0; i < 6; i++) release(instance->stage[i]);
    release(instance->x_stage);
    release(instance->rhs);
    release(instance->x_start);
    release(instance->x_trial);
    release(instance->z_start);
    release(instance->z_trial);
    release(instance->d_trial);
    release(instance->pivots);
    while (instance->n_issued > 0) snapshot_free(instance, instance->issued[instance->n_issued - 1]);
    release(instance->issued);
    release(instance);
    if (model_data && hooks->free_model) hooks->free_model(model_data);
}

void instance_reset(Instance *instance) {
    const ModelInfo *info = instance->info;
    instance->now.time = 0.0;
    instance->now.mode = MODE_INSTANTIATED;
    instance->now.solver_step_next = 0.0;
    memcpy(instance->now.u, info->input_start, sizeof(double) * (size_t)info->nu);
    memcpy(instance->now.p, info->parameter_start, sizeof(double) * (size_t)info->np);
    if (info->model_exchange_parameter >= 0) instance->now.p[info->model_exchange_parameter] = !instance->is_cosimulation;
    memset(instance->now.x, 0, sizeof(double) * (size_t)info->nx);
    memset(instance->now.d, 0, sizeof(double) * (size_t)info->nd);
    instance->start_time = 0.0;
    instance->stop_time = 0.0;
    instance->stop_time_defined = 0;
    instance->steps = 0;
    instance->event_count = 0;
    instance->input_jumped = 0;
    instance_invalidate(instance);
    instance->initial_state_valid = 0;
}

void instance_invalidate(Instance *instance) {
    instance->outputs_valid = 0;
    instance->derivatives_valid = 0;
}

static Status evaluate(Instance *instance, const ModelFunction *function, const double *x, const double *d,
                       double *result0, double *result1) {
    instance->arg[0] = x;
    instance->arg[1] = d;
    instance->arg[2] = instance->now.u;
    instance->arg[3] = instance->now.p;
    instance->res[0] = result0;
    instance->res[1] = result1;
    if (function->eval(instance->arg, instance->res, instance->iw, instance->w, 0) != 0) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "evaluation of the model equations failed");
        return STATUS_ERROR;
    }
    return STATUS_OK;
}

Status instance_apply_initial_state(Instance *instance) {
    /* results go through scratch vectors: CasADi's outputs must not alias its inputs */
    Status status = evaluate(instance, &instance->info->initial_state, instance->now.x, instance->now.d,
                             instance->x_trial, instance->d_trial);
    if (status != STATUS_OK) return status;
    memcpy(instance->now.x, instance->x_trial, sizeof(double) * (size_t)instance->info->nx);
    memcpy(instance->now.d, instance->d_trial, sizeof(double) * (size_t)instance->info->nd);
    instance->initial_state_valid = 1;
    instance_invalidate(instance);
    return STATUS_OK;
}

Status instance_derivatives(Instance *instance, const double *x, const double *d, double *xdot) {
    return evaluate(instance, &instance->info->derivatives, x, d, xdot, NULL);
}

Status instance_event_indicators(Instance *instance, const double *x, const double *d, double *z) {
    return evaluate(instance, &instance->info->event_indicators, x, d, z, NULL);
}

Status instance_event_iteration(Instance *instance, int *states_changed, int *discrete_changed) {
    const ModelInfo *info = instance->info;
    size_t x_bytes = sizeof(double) * (size_t)info->nx, d_bytes = sizeof(double) * (size_t)info->nd;
    int iteration;
    *states_changed = 0;
    *discrete_changed = 0;
    for (iteration = 0; iteration < MAX_EVENT_ITERATIONS; iteration++) {
        Status status = evaluate(instance, &info->discrete_update, instance->now.x, instance->now.d,
                                 instance->x_trial, instance->d_trial);
        int x_same, d_same;
        if (status != STATUS_OK) return status;
        x_same = memcmp(instance->x_trial, instance->now.x, x_bytes) == 0;
        d_same = memcmp(instance->d_trial, instance->now.d, d_bytes) == 0;
        if (x_same && d_same) return STATUS_OK;
        if (!x_same) *states_changed = 1;
        if (!d_same) *discrete_changed = 1;
        memcpy(instance->now.x, instance->x_trial, x_bytes);
        memcpy(instance->now.d, instance->d_trial, d_bytes);
        instance_invalidate(instance);
        instance->event_count++;
        instance_log(instance, STATUS_OK, "logEvents", "event at t = %.17g (iteration %d)", instance->now.time,
                     iteration + 1);
    }
    instance_log(instance, STATUS_ERROR, "logStatusError",
                 "event iteration did not converge in %d iterations at t = %.17g", MAX_EVENT_ITERATIONS,
                 instance->now.time);
    return STATUS_ERROR;
}

static const ModelVariable *find_variable(Instance *instance, unsigned int vr) {
    const ModelInfo *info = instance->info;
    /* the generator numbers value references 1..n in table order */
    if (vr >= 1 && vr <= (unsigned int)info->n_variables && info->variables[vr - 1].value_reference == vr)
        return &info->variables[vr - 1];
    instance_log(instance, STATUS_ERROR, "logStatusError", "unknown value reference %u", vr);
    return NULL;
}

static const char *kind_name(Kind kind) {
    return kind == KIND_REAL ? "Real" : kind == KIND_INTEGER ? "Integer" : "Boolean";
}

/* The variable of a value reference, if it exists and has the given type (else logs and NULL). */
static const ModelVariable *typed_variable(Instance *instance, unsigned int vr, Kind kind) {
    const ModelVariable *variable = find_variable(instance, vr);
    if (variable && variable->kind != kind) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s (value reference %u) is %s, not %s",
                     variable->name, vr, kind_name(variable->kind), kind_name(kind));
        return NULL;
    }
    return variable;
}

static Status ensure_computed(Instance *instance, Store store) {
    Status status = STATUS_OK;
    if ((instance->now.mode & (MODE_INSTANTIATED | MODE_INITIALIZATION)) && !instance->initial_state_valid) {
        status = instance_apply_initial_state(instance);
        if (status != STATUS_OK) return status;
    }
    if (store == STORE_OUTPUT && !instance->outputs_valid) {
        status = evaluate(instance, &instance->info->outputs, instance->now.x, instance->now.d, instance->y, NULL);
        instance->outputs_valid = status == STATUS_OK;
    } else if (store == STORE_DERIVATIVE && !instance->derivatives_valid) {
        status = instance_derivatives(instance, instance->now.x, instance->now.d, instance->xdot);
        instance->derivatives_valid = status == STATUS_OK;
    } else if (store == STORE_EVENT_INDICATOR) {
        status = instance_event_indicators(instance, instance->now.x, instance->now.d, instance->z);
    }
    return status;
}

static double stored_value(const Instance *instance, const ModelVariable *variable) {
    switch (variable->store) {
    case STORE_INPUT: return instance->now.u[variable->index];
    case STORE_PARAMETER: return instance->now.p[variable->index];
    case STORE_STATE: return instance->now.x[variable->index];
    case STORE_DERIVATIVE: return instance->xdot[variable->index];
    case STORE_DISCRETE: return instance->now.d[variable->index];
    case STORE_OUTPUT: return instance->y[variable->index];
    case STORE_EVENT_INDICATOR: return instance->z[variable->index];
    }
    return 0.0;
}

Status instance_get(Instance *instance, const unsigned int vr[], size_t nvr, Kind kind, void *values) {
    size_t i;
    if (nvr > 0 && (!vr || !values)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "get %s: null argument", kind_name(kind));
        return STATUS_ERROR;
    }
    for (i = 0; i < nvr; i++) {
        const ModelVariable *variable = typed_variable(instance, vr[i], kind);
        double value;
        if (!variable) return STATUS_ERROR;
        if (ensure_computed(instance, variable->store) != STATUS_OK) return STATUS_ERROR;
        value = stored_value(instance, variable);
        if (kind == KIND_REAL)
            ((double *)values)[i] = value;
        else if (kind == KIND_INTEGER)
            ((int *)values)[i] = (int)llround(value);
        else
            ((int *)values)[i] = value > 0.5;
    }
    return STATUS_OK;
}

static int may_set(const Instance *instance, const ModelVariable *variable) {
    Mode mode = instance->now.mode;
    switch (variable->settable) {
    case SET_NEVER: return 0;
    case SET_FIXED: return (mode & (MODE_INSTANTIATED | MODE_INITIALIZATION)) != 0;
    case SET_TUNABLE: return (mode & (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_STEP)) != 0;
    case SET_INPUT:
        /* FMI 2.0 3.2.3: in Continuous-Time Mode only continuous (Real) inputs may change; discrete ones
         * change in Event Mode */
        if (mode & MODE_CONTINUOUS_TIME) return variable->kind == KIND_REAL;
        return (mode & (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_STEP)) != 0;
    }
    return 0;
}

/* The one range rule: a value outside the declared [min, max] (or not finite) is refused. */
static int in_range(const ModelVariable *variable, double value) {
    return isfinite(value) && value >= variable->min && value <= variable->max;
}

static double given_value(Kind kind, const void *values, size_t i) {
    if (kind == KIND_REAL) return ((const double *)values)[i];
    if (kind == KIND_INTEGER) return (double)((const int *)values)[i];
    return ((const int *)values)[i] ? 1.0 : 0.0;
}

Status instance_set(Instance *instance, const unsigned int vr[], size_t nvr, Kind kind, const void *values) {
    size_t i;
    if (nvr > 0 && (!vr || !values)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "set %s: null argument", kind_name(kind));
        return STATUS_ERROR;
    }
    /* check every value first: a refused call changes nothing */
    for (i = 0; i < nvr; i++) {
        const ModelVariable *variable = typed_variable(instance, vr[i], kind);
        double value;
        if (!variable) return STATUS_ERROR;
        if (!may_set(instance, variable)) {
            instance_log(instance, STATUS_ERROR, "logStatusError",
                         variable->settable == SET_NEVER ? "%s (value reference %u) cannot be set"
                                                         : "%s (value reference %u) cannot be set in this state",
                         variable->name, vr[i]);
            return STATUS_ERROR;
        }
        value = given_value(kind, values, i);
        if (!in_range(variable, value)) {
            instance_log(instance, STATUS_ERROR, "logStatusError",
                         "%s: value %.17g is outside its declared range [%g, %g]", variable->name, value,
                         variable->min, variable->max);
            return STATUS_ERROR;
        }
    }
    for (i = 0; i < nvr; i++) {
        const ModelVariable *variable = &instance->info->variables[vr[i] - 1];
        double value = given_value(kind, values, i);
        if (variable->store == STORE_INPUT) {
            if ((instance->now.mode & MODE_EVENT) && instance->now.u[variable->index] != value)
                instance->input_jumped = 1;
            instance->now.u[variable->index] = value;
        }
        else
            instance->now.p[variable->index] = value;
    }
    if (nvr > 0 && (instance->now.mode & (MODE_INSTANTIATED | MODE_INITIALIZATION)))
        instance->initial_state_valid = 0;
    instance_invalidate(instance);
    return STATUS_OK;
}

Status instance_set_time(Instance *instance, double time) {
    if (!isfinite(time)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "SetTime: time %g is not finite", time);
        return STATUS_ERROR;
    }
    instance->now.time = time;
    instance_invalidate(instance);
    return STATUS_OK;
}

Status instance_set_states(Instance *instance, const double x[], size_t nx) {
    size_t i;
    if (nx != (size_t)instance->info->nx || (nx > 0 && !x)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "SetContinuousStates: expected %d states",
                     instance->info->nx);
        return STATUS_ERROR;
    }
    for (i = 0; i < nx; i++)
        if (!isfinite(x[i])) {
            instance_log(instance, STATUS_ERROR, "logStatusError", "SetContinuousStates: x[%lu] is not finite",
                         (unsigned long)i);
            return STATUS_ERROR;
        }
    memcpy(instance->now.x, x, sizeof(double) * nx);
    instance_invalidate(instance);
    return STATUS_OK;
}

int instance_take_input_jump(Instance *instance) {
    int jumped = instance->input_jumped;
    instance->input_jumped = 0;
    return jumped;
}

/* ---- FMU state ---------------------------------------------------------------------------- */

/* The registry of issued handles: an array of pointers, searched by comparison (a few handles at most). */
static long issued_index(const Instance *instance, const void *state) {
    size_t i;
    for (i = 0; i < instance->n_issued; i++)
        if ((const void *)instance->issued[i] == state) return (long)i;
    return -1;
}

static int register_issued(Instance *instance, Snapshot *snapshot) {
    if (instance->n_issued == instance->issued_capacity) {
        size_t capacity = instance->issued_capacity ? 2 * instance->issued_capacity : 8;
        Snapshot **grown = (Snapshot **)instance->allocate(capacity, sizeof(Snapshot *));
        if (!grown) return 0;
        if (instance->n_issued) memcpy(grown, instance->issued, sizeof(Snapshot *) * instance->n_issued);
        instance->release(instance->issued);
        instance->issued = grown;
        instance->issued_capacity = capacity;
    }
    instance->issued[instance->n_issued++] = snapshot;
    return 1;
}

Snapshot *snapshot_create(Instance *instance) {
    const ModelInfo *info = instance->info;
    Snapshot *snapshot = (Snapshot *)instance->allocate(1, sizeof(Snapshot));
    if (!snapshot) return NULL;
    if (!register_issued(instance, snapshot)) {
        instance->release(snapshot);
        return NULL;
    }
    snapshot->tag = SNAPSHOT_TAG;
    snapshot->x = (double *)allocate_array(instance, (size_t)info->nx, sizeof(double));
    snapshot->d = (double *)allocate_array(instance, (size_t)info->nd, sizeof(double));
    snapshot->u = (double *)allocate_array(instance, (size_t)info->nu, sizeof(double));
    snapshot->p = (double *)allocate_array(instance, (size_t)info->np, sizeof(double));
    if (!snapshot->x || !snapshot->d || !snapshot->u || !snapshot->p) {
        snapshot_free(instance, snapshot);
        return NULL;
    }
    return snapshot;
}

void snapshot_copy(const Instance *instance, Snapshot *to, const Snapshot *from) {
    const ModelInfo *info = instance->info;
    to->time = from->time;
    to->mode = from->mode;
    to->solver_step_next = from->solver_step_next;
    memcpy(to->x, from->x, sizeof(double) * (size_t)info->nx);
    memcpy(to->d, from->d, sizeof(double) * (size_t)info->nd);
    memcpy(to->u, from->u, sizeof(double) * (size_t)info->nu);
    memcpy(to->p, from->p, sizeof(double) * (size_t)info->np);
}

void snapshot_free(Instance *instance, Snapshot *snapshot) {
    long index;
    if (!snapshot) return;
    index = issued_index(instance, snapshot);
    if (index >= 0) instance->issued[index] = instance->issued[--instance->n_issued];
    snapshot->tag = 0;
    instance->release(snapshot->x);
    instance->release(snapshot->d);
    instance->release(snapshot->u);
    instance->release(snapshot->p);
    instance->release(snapshot);
}

int snapshot_handle_valid(Instance *instance, const void *state, const char *function) {
    if (state && issued_index(instance, state) >= 0) return 1;
    if (!state)
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: null FMU state", function);
    else
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "%s: %p is not an FMU state of this instance (never issued by it, from another instance, or "
                     "already freed)",
                     function, state);
    return 0;
}

/* The modes an instance of this interface type can be saved in (never the error state). */
static int saveable_mode(const Instance *instance, int mode) {
    int allowed = instance->is_cosimulation
                      ? (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED)
                      : (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME |
                         MODE_TERMINATED);
    return mode != 0 && (mode & (mode - 1)) == 0 && (mode & allowed) != 0; /* exactly one allowed bit */
}

static int all_finite(const double *values, int n) {
    int i;
    for (i = 0; i < n; i++)
        if (!isfinite(values[i])) return 0;
    return 1;
}

Status snapshot_check(Instance *instance, const Snapshot *snapshot) {
    const ModelInfo *info = instance->info;
    int i;
    if (!snapshot || snapshot->tag != SNAPSHOT_TAG) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "FMU state: not a state of this FMU");
        return STATUS_ERROR;
    }
    if (!saveable_mode(instance, (int)snapshot->mode)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "FMU state: invalid mode word 0x%x for a %s instance",
                     (unsigned int)snapshot->mode, instance->is_cosimulation ? "co-simulation" : "model-exchange");
        return STATUS_ERROR;
    }
    if (!isfinite(snapshot->time)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "FMU state: time is not finite");
        return STATUS_ERROR;
    }
    if (!(snapshot->solver_step_next >= 0.0) || !isfinite(snapshot->solver_step_next)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "FMU state: the solver's next step %g is not >= 0",
                     snapshot->solver_step_next);
        return STATUS_ERROR;
    }
    if (!all_finite(snapshot->x, info->nx) || !all_finite(snapshot->d, info->nd)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "FMU state: a state value is not finite");
        return STATUS_ERROR;
    }
    for (i = 0; i < info->n_variables; i++) {
        const ModelVariable *variable = &info->variables[i];
        double value;
        if (variable->store == STORE_INPUT)
            value = snapshot->u[variable->index];
        else if (variable->store == STORE_PARAMETER)
            value = snapshot->p[variable->index];
        else
            continue;
        if (!in_range(variable, value)) {
            instance_log(instance, STATUS_ERROR, "logStatusError",
                         "FMU state: %s = %.17g is outside its declared range [%g, %g]", variable->name, value,
                         variable->min, variable->max);
            return STATUS_ERROR;
        }
    }
    return STATUS_OK;
}

/* Serialized layout (native byte order, 8-byte fields):
 *   "SDLFMU2\0" | FNV-1a hash of the GUID | nx nd nu np | mode | time | solver's next step | x d u p |
 *   FNV-1a checksum of all before.
 * The hash ties a state to this model build; the checksum catches corruption; the fields are then checked
 * one by one (snapshot_check) before anything reaches the instance. */
#define SERIAL_MAGIC "SDLFMU2"
#define SERIAL_HEADER_WORDS 9 /* magic, guid hash, nx, nd, nu, np, mode, time, solver's next step */

static unsigned long long fnv1a(const unsigned char *bytes, size_t n) {
    unsigned long long hash = 14695981039346656037ull;
    size_t i;
    for (i = 0; i < n; i++) {
        hash ^= bytes[i];
        hash *= 1099511628211ull;
    }
    return hash;
}

static unsigned long long guid_hash(const ModelInfo *info) {
    return fnv1a((const unsigned char *)info->guid, strlen(info->guid));
}

static size_t vector_count(const ModelInfo *info) { return (size_t)(info->nx + info->nd + info->nu + info->np); }

size_t snapshot_serialized_size(const Instance *instance) {
    return 8 * (SERIAL_HEADER_WORDS + vector_count(instance->info) + 1);
}

static char *put_word(char *cursor, unsigned long long word) {
    memcpy(cursor, &word, 8);
    return cursor + 8;
}

static char *put_doubles(char *cursor, const double *values, int n) {
    memcpy(cursor, values, sizeof(double) * (size_t)n);
    return cursor + sizeof(double) * (size_t)n;
}

void snapshot_serialize(const Instance *instance, const Snapshot *snapshot, char *bytes) {
    const ModelInfo *info = instance->info;
    char *cursor = bytes;
    memset(cursor, 0, 8);
    memcpy(cursor, SERIAL_MAGIC, sizeof(SERIAL_MAGIC));
    cursor += 8;
    cursor = put_word(cursor, guid_hash(info));
    cursor = put_word(cursor, (unsigned long long)info->nx);
    cursor = put_word(cursor, (unsigned long long)info->nd);
    cursor = put_word(cursor, (unsigned long long)info->nu);
    cursor = put_word(cursor, (unsigned long long)info->np);
    cursor = put_word(cursor, (unsigned long long)snapshot->mode);
    cursor = put_doubles(cursor, &snapshot->time, 1);
    cursor = put_doubles(cursor, &snapshot->solver_step_next, 1);
    cursor = put_doubles(cursor, snapshot->x, info->nx);
    cursor = put_doubles(cursor, snapshot->d, info->nd);
    cursor = put_doubles(cursor, snapshot->u, info->nu);
    cursor = put_doubles(cursor, snapshot->p, info->np);
    put_word(cursor, fnv1a((const unsigned char *)bytes, (size_t)(cursor - bytes)));
}

static const char *get_word(const char *cursor, unsigned long long *word) {
    memcpy(word, cursor, 8);
    return cursor + 8;
}

static const char *get_doubles(const char *cursor, double *values, int n) {
    memcpy(values, cursor, sizeof(double) * (size_t)n);
    return cursor + sizeof(double) * (size_t)n;
}

Status snapshot_deserialize(Instance *instance, const char *bytes, size_t size, Snapshot *snapshot) {
    const ModelInfo *info = instance->info;
    size_t expected = snapshot_serialized_size(instance);
    unsigned long long hash, nx, nd, nu, np, mode, checksum;
    const char *cursor = bytes;
    if (!bytes || size != expected) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "serialized FMU state has %lu bytes, this model's have %lu", (unsigned long)size,
                     (unsigned long)expected);
        return STATUS_ERROR;
    }
    get_word(bytes + expected - 8, &checksum);
    if (memcmp(cursor, SERIAL_MAGIC, sizeof(SERIAL_MAGIC)) != 0 ||
        checksum != fnv1a((const unsigned char *)bytes, expected - 8)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "serialized FMU state is corrupted (checksum)");
        return STATUS_ERROR;
    }
    cursor = get_word(cursor + 8, &hash);
    cursor = get_word(cursor, &nx);
    cursor = get_word(cursor, &nd);
    cursor = get_word(cursor, &nu);
    cursor = get_word(cursor, &np);
    if (hash != guid_hash(info) || nx != (unsigned long long)info->nx || nd != (unsigned long long)info->nd ||
        nu != (unsigned long long)info->nu || np != (unsigned long long)info->np) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "serialized FMU state is from another model or build (GUID %s expected)", info->guid);
        return STATUS_ERROR;
    }
    cursor = get_word(cursor, &mode);
    if (mode > 0xffffu) mode = 0; /* snapshot_check reports it */
    snapshot->mode = (Mode)mode;
    cursor = get_doubles(cursor, &snapshot->time, 1);
    cursor = get_doubles(cursor, &snapshot->solver_step_next, 1);
    cursor = get_doubles(cursor, snapshot->x, info->nx);
    cursor = get_doubles(cursor, snapshot->d, info->nd);
    cursor = get_doubles(cursor, snapshot->u, info->nu);
    get_doubles(cursor, snapshot->p, info->np);
    return snapshot_check(instance, snapshot);
}

/* ---- the FMU-state calls of both FMI versions ---------------------------------------------- */

Status instance_get_state(Instance *instance, void **state, const char *function) {
    Snapshot *snapshot;
    if (!state) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: null state pointer", function);
        return STATUS_ERROR;
    }
    snapshot = (Snapshot *)*state;
    if (snapshot && !snapshot_handle_valid(instance, snapshot, function)) return STATUS_ERROR;
    if (!snapshot) snapshot = snapshot_create(instance);
    if (!snapshot) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: out of memory", function);
        return STATUS_ERROR;
    }
    snapshot_copy(instance, snapshot, &instance->now);
    *state = snapshot;
    return STATUS_OK;
}

Status instance_set_state(Instance *instance, const void *state, const char *function) {
    const ModelHooks *hooks = model_hooks(instance->info);
    if (!snapshot_handle_valid(instance, state, function) || snapshot_check(instance, (const Snapshot *)state) != STATUS_OK)
        return STATUS_ERROR;
    if (hooks->state_fits && !hooks->state_fits(instance, (const Snapshot *)state, function)) return STATUS_ERROR;
    snapshot_copy(instance, &instance->now, (const Snapshot *)state);
    instance->initial_state_valid = !(instance->now.mode & (MODE_INSTANTIATED | MODE_INITIALIZATION));
    instance_invalidate(instance);
    return STATUS_OK;
}

Status instance_free_state(Instance *instance, void **state, const char *function) {
    if (!state) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: null state pointer", function);
        return STATUS_ERROR;
    }
    if (*state && !snapshot_handle_valid(instance, *state, function)) return STATUS_ERROR;
    snapshot_free(instance, (Snapshot *)*state);
    *state = NULL;
    return STATUS_OK;
}

Status instance_serialize_state(Instance *instance, const void *state, char *bytes, size_t size, const char *function) {
    if (!bytes) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: null buffer", function);
        return STATUS_ERROR;
    }
    if (!snapshot_handle_valid(instance, state, function)) return STATUS_ERROR;
    if (size < snapshot_serialized_size(instance)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: buffer too small", function);
        return STATUS_ERROR;
    }
    snapshot_serialize(instance, (const Snapshot *)state, bytes);
    return STATUS_OK;
}

Status instance_deserialize_state(Instance *instance, const char *bytes, size_t size, void **state, int reuse_existing,
                                  const char *function) {
    const ModelHooks *hooks = model_hooks(instance->info);
    Snapshot *snapshot;
    if (!state) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: null state pointer", function);
        return STATUS_ERROR;
    }
    if (reuse_existing && *state && !snapshot_handle_valid(instance, *state, function)) return STATUS_ERROR;
    snapshot = snapshot_create(instance);
    if (!snapshot) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "%s: out of memory", function);
        return STATUS_ERROR;
    }
    if (snapshot_deserialize(instance, bytes, size, snapshot) != STATUS_OK ||
        (hooks->state_fits && !hooks->state_fits(instance, snapshot, function))) {
        snapshot_free(instance, snapshot);
        return STATUS_ERROR;
    }
    if (reuse_existing && *state) { /* an existing state is overwritten */
        snapshot_copy(instance, (Snapshot *)*state, snapshot);
        snapshot_free(instance, snapshot);
    } else {
        *state = snapshot;
    }
    return STATUS_OK;
}
