/* Generic instance handling: memory, variable access, evaluation of the model's functions, events,
 * FMU state. Knows the model only through ModelInfo (model.h). */
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

void instance_log(Instance *instance, Status status, const char *category, const char *format, ...) {
    char message[1024];
    va_list args;
    if (!instance || !instance->log) return;
    if (status == STATUS_OK && !instance->logging_on) return;
    va_start(args, format);
    vsnprintf(message, sizeof(message), format, args);
    va_end(args);
    instance->log(instance, status, category, message);
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
    int i;
    if (!instance) return;
    release = instance->release;
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
    release(instance);
}

void instance_reset(Instance *instance) {
    const ModelInfo *info = instance->info;
    instance->now.time = 0.0;
    instance->now.mode = MODE_INSTANTIATED;
    memcpy(instance->now.u, info->input_start, sizeof(double) * (size_t)info->nu);
    memcpy(instance->now.p, info->parameter_start, sizeof(double) * (size_t)info->np);
    memset(instance->now.x, 0, sizeof(double) * (size_t)info->nx);
    memset(instance->now.d, 0, sizeof(double) * (size_t)info->nd);
    instance->start_time = 0.0;
    instance->stop_time = 0.0;
    instance->stop_time_defined = 0;
    instance->steps = 0;
    instance->event_count = 0;
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

static int may_set(const Instance *instance, Settable settable) {
    Mode mode = instance->now.mode;
    switch (settable) {
    case SET_NEVER: return 0;
    case SET_FIXED: return (mode & (MODE_INSTANTIATED | MODE_INITIALIZATION)) != 0;
    case SET_TUNABLE: return (mode & (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_STEP)) != 0;
    case SET_INPUT:
        return (mode & (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME | MODE_STEP)) !=
               0;
    }
    return 0;
}

Status instance_set(Instance *instance, const unsigned int vr[], size_t nvr, Kind kind, const void *values) {
    size_t i;
    if (nvr > 0 && (!vr || !values)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "set %s: null argument", kind_name(kind));
        return STATUS_ERROR;
    }
    for (i = 0; i < nvr; i++) {
        const ModelVariable *variable = typed_variable(instance, vr[i], kind);
        double value;
        if (!variable) return STATUS_ERROR;
        if (!may_set(instance, variable->settable)) {
            instance_log(instance, STATUS_ERROR, "logStatusError",
                         variable->settable == SET_NEVER ? "%s (value reference %u) cannot be set"
                                                         : "%s (value reference %u) cannot be set in this state",
                         variable->name, vr[i]);
            return STATUS_ERROR;
        }
        if (kind == KIND_REAL) {
            value = ((const double *)values)[i];
            if (!isfinite(value)) {
                instance_log(instance, STATUS_ERROR, "logStatusError", "%s: value %g is not finite",
                             variable->name, value);
                return STATUS_ERROR;
            }
        } else if (kind == KIND_INTEGER) {
            value = (double)((const int *)values)[i];
        } else {
            value = ((const int *)values)[i] ? 1.0 : 0.0;
        }
        if (variable->store == STORE_PARAMETER && (value < variable->min || value > variable->max)) {
            instance_log(instance, STATUS_ERROR, "logStatusError",
                         value < variable->min ? "%s: value %g is below its declared minimum %g"
                                               : "%s: value %g is above its declared maximum %g",
                         variable->name, value, value < variable->min ? variable->min : variable->max);
            return STATUS_ERROR;
        }
        if (variable->store == STORE_INPUT)
            instance->now.u[variable->index] = value;
        else
            instance->now.p[variable->index] = value;
        if (instance->now.mode & (MODE_INSTANTIATED | MODE_INITIALIZATION)) instance->initial_state_valid = 0;
    }
    instance_invalidate(instance);
    return STATUS_OK;
}

/* ---- FMU state ---------------------------------------------------------------------------- */

Snapshot *snapshot_create(Instance *instance) {
    const ModelInfo *info = instance->info;
    Snapshot *snapshot = (Snapshot *)instance->allocate(1, sizeof(Snapshot));
    if (!snapshot) return NULL;
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
    memcpy(to->x, from->x, sizeof(double) * (size_t)info->nx);
    memcpy(to->d, from->d, sizeof(double) * (size_t)info->nd);
    memcpy(to->u, from->u, sizeof(double) * (size_t)info->nu);
    memcpy(to->p, from->p, sizeof(double) * (size_t)info->np);
}

void snapshot_free(Instance *instance, Snapshot *snapshot) {
    if (!snapshot) return;
    instance->release(snapshot->x);
    instance->release(snapshot->d);
    instance->release(snapshot->u);
    instance->release(snapshot->p);
    instance->release(snapshot);
}

/* Serialized layout: guid-checked header, then time, mode and the four vectors. */
typedef struct {
    char magic[8];
    int nx, nd, nu, np;
    double time;
    int mode;
} SerializedHeader;

static size_t vector_bytes(const ModelInfo *info) {
    return sizeof(double) * (size_t)(info->nx + info->nd + info->nu + info->np);
}

size_t snapshot_serialized_size(const Instance *instance) {
    return sizeof(SerializedHeader) + vector_bytes(instance->info);
}

void snapshot_serialize(const Instance *instance, const Snapshot *snapshot, char *bytes) {
    const ModelInfo *info = instance->info;
    SerializedHeader header;
    char *cursor = bytes + sizeof(header);
    memset(&header, 0, sizeof(header));
    memcpy(header.magic, "SDLFMU1", 8);
    header.nx = info->nx;
    header.nd = info->nd;
    header.nu = info->nu;
    header.np = info->np;
    header.time = snapshot->time;
    header.mode = (int)snapshot->mode;
    memcpy(bytes, &header, sizeof(header));
    memcpy(cursor, snapshot->x, sizeof(double) * (size_t)info->nx);
    cursor += sizeof(double) * (size_t)info->nx;
    memcpy(cursor, snapshot->d, sizeof(double) * (size_t)info->nd);
    cursor += sizeof(double) * (size_t)info->nd;
    memcpy(cursor, snapshot->u, sizeof(double) * (size_t)info->nu);
    cursor += sizeof(double) * (size_t)info->nu;
    memcpy(cursor, snapshot->p, sizeof(double) * (size_t)info->np);
}

Status snapshot_deserialize(Instance *instance, const char *bytes, size_t size, Snapshot *snapshot) {
    const ModelInfo *info = instance->info;
    SerializedHeader header;
    const char *cursor = bytes + sizeof(header);
    if (!bytes || size != snapshot_serialized_size(instance)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "serialized FMU state has the wrong size");
        return STATUS_ERROR;
    }
    memcpy(&header, bytes, sizeof(header));
    if (memcmp(header.magic, "SDLFMU1", 8) != 0 || header.nx != info->nx || header.nd != info->nd ||
        header.nu != info->nu || header.np != info->np) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "serialized FMU state is not from this model");
        return STATUS_ERROR;
    }
    snapshot->time = header.time;
    snapshot->mode = (Mode)header.mode;
    memcpy(snapshot->x, cursor, sizeof(double) * (size_t)info->nx);
    cursor += sizeof(double) * (size_t)info->nx;
    memcpy(snapshot->d, cursor, sizeof(double) * (size_t)info->nd);
    cursor += sizeof(double) * (size_t)info->nd;
    memcpy(snapshot->u, cursor, sizeof(double) * (size_t)info->nu);
    cursor += sizeof(double) * (size_t)info->nu;
    memcpy(snapshot->p, cursor, sizeof(double) * (size_t)info->np);
    return STATUS_OK;
}
