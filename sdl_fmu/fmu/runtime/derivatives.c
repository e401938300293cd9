/* Exact partial derivatives: CasADi's forward (J w) and reverse (J^T v) sweeps of the unknowns
 * U = [x; d; xdot; y; z] with respect to the knowns K = [x; u; p] (model.h). The FMI layers map value
 * references onto positions in U and K here; nothing in this file knows the model. */
#include "derivatives.h"

#include <math.h>
#include <string.h>

typedef enum { FORWARD, ADJOINT } Direction;

static int in_initialization(const Instance *instance) {
    return (instance->now.mode & (MODE_INSTANTIATED | MODE_INITIALIZATION)) != 0;
}

static int unknown_count(const ModelInfo *info) { return 2 * info->nx + info->nd + info->ny + info->nz; }

static int known_count(const ModelInfo *info) { return info->nx + info->nu + info->np; }

static const ModelVariable *real_variable(Instance *instance, unsigned int vr, const char *role) {
    const ModelInfo *info = instance->info;
    const ModelVariable *variable;
    if (!(vr >= 1 && vr <= (unsigned int)info->n_variables && info->variables[vr - 1].value_reference == vr)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "partial derivative: unknown value reference %u (%s)",
                     vr, role);
        return NULL;
    }
    variable = &info->variables[vr - 1];
    if (variable->kind != KIND_REAL) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "partial derivative: %s (value reference %u) is not a Real variable", variable->name, vr);
        return NULL;
    }
    return variable;
}

/* Position of an unknown in U, or -1 (logged). */
static int unknown_position(Instance *instance, unsigned int vr, int log) {
    const ModelInfo *info = instance->info;
    const ModelVariable *variable = real_variable(instance, vr, "unknown");
    if (!variable) return -1;
    switch (variable->store) {
    case STORE_STATE: return variable->index;
    case STORE_DISCRETE: return info->nx + variable->index;
    case STORE_DERIVATIVE: return info->nx + info->nd + variable->index;
    case STORE_OUTPUT: return 2 * info->nx + info->nd + variable->index;
    case STORE_EVENT_INDICATOR: return 2 * info->nx + info->nd + info->ny + variable->index;
    case STORE_INPUT:
    case STORE_PARAMETER: break;
    }
    if (log)
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "partial derivative: %s (value reference %u) is an input or parameter, not an unknown",
                     variable->name, vr);
    return -1;
}

/* Position of a known in K, or -1 (logged). */
static int known_position(Instance *instance, unsigned int vr) {
    const ModelInfo *info = instance->info;
    const ModelVariable *variable = real_variable(instance, vr, "known");
    if (!variable) return -1;
    switch (variable->store) {
    case STORE_STATE:
        if (!in_initialization(instance)) return variable->index;
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "partial derivative: the state %s is calculated in initialization, not a known", variable->name);
        return -1;
    case STORE_INPUT: return info->nx + variable->index;
    case STORE_PARAMETER: return info->nx + info->nu + variable->index;
    case STORE_DISCRETE:
    case STORE_DERIVATIVE:
    case STORE_OUTPUT:
    case STORE_EVENT_INDICATOR: break;
    }
    instance_log(instance, STATUS_ERROR, "logStatusError",
                 "partial derivative: %s (value reference %u) is not a state, input or parameter", variable->name, vr);
    return -1;
}

/* Runs one of the derivative functions with its own work arrays: (x, d, u, p, seed) -> result. */
static Status evaluate(Instance *instance, const ModelFunction *function, const double *seed, double *result) {
    casadi_int_t sizes[4] = {0, 0, 0, 0};
    const double **arg;
    double **res, *w;
    casadi_int_t *iw;
    int failed;
    function->work(&sizes[0], &sizes[1], &sizes[2], &sizes[3]);
    if (sizes[0] < 5) sizes[0] = 5;
    if (sizes[1] < 1) sizes[1] = 1;
    arg = (const double **)instance->allocate((size_t)sizes[0] + 1, sizeof(double *));
    res = (double **)instance->allocate((size_t)sizes[1] + 1, sizeof(double *));
    iw = (casadi_int_t *)instance->allocate((size_t)sizes[2] + 1, sizeof(casadi_int_t));
    w = (double *)instance->allocate((size_t)sizes[3] + 1, sizeof(double));
    failed = !arg || !res || !iw || !w;
    if (!failed) {
        arg[0] = instance->now.x;
        arg[1] = instance->now.d;
        arg[2] = instance->now.u;
        arg[3] = instance->now.p;
        arg[4] = seed;
        res[0] = result;
        failed = function->eval(arg, res, iw, w, 0) != 0;
    }
    instance->release((void *)arg);
    instance->release(res);
    instance->release(iw);
    instance->release(w);
    if (failed) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "evaluation of the partial derivatives failed");
        return STATUS_ERROR;
    }
    return STATUS_OK;
}

static Status partial_derivative(Instance *instance, Direction direction, const unsigned int unknowns[],
                                 size_t n_unknowns, const unsigned int knowns[], size_t n_knowns,
                                 const double seed[], double sensitivity[]) {
    const ModelInfo *info = instance->info;
    int initialization = in_initialization(instance);
    size_t n_in = (size_t)(direction == FORWARD ? known_count(info) : unknown_count(info));
    size_t n_out = (size_t)(direction == FORWARD ? unknown_count(info) : known_count(info));
    size_t i;
    int j;
    double *seed_vector, *result, *chained;
    Status status;

    if ((n_unknowns > 0 && !unknowns) || (n_knowns > 0 && !knowns) ||
        ((direction == FORWARD ? n_knowns : n_unknowns) > 0 && !seed) ||
        ((direction == FORWARD ? n_unknowns : n_knowns) > 0 && !sensitivity)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "partial derivative: null argument");
        return STATUS_ERROR;
    }
    /* check every value reference before anything is computed */
    for (i = 0; i < n_unknowns; i++)
        if (unknown_position(instance, unknowns[i], 1) < 0) return STATUS_ERROR;
    for (i = 0; i < n_knowns; i++)
        if (known_position(instance, knowns[i]) < 0) return STATUS_ERROR;
    if (n_unknowns == 0 || n_knowns == 0) {
        if (direction == FORWARD) memset(sensitivity, 0, sizeof(double) * n_unknowns);
        else memset(sensitivity, 0, sizeof(double) * n_knowns);
        return STATUS_OK;
    }

    if (initialization && !instance->initial_state_valid && instance_apply_initial_state(instance) != STATUS_OK)
        return STATUS_ERROR;
    seed_vector = (double *)instance->allocate(n_in + 1, sizeof(double));
    result = (double *)instance->allocate(n_out + 1, sizeof(double));
    chained = (double *)instance->allocate((size_t)known_count(info) + 1, sizeof(double));
    if (!seed_vector || !result || !chained) {
        instance->release(seed_vector);
        instance->release(result);
        instance->release(chained);
        instance_log(instance, STATUS_ERROR, "logStatusError", "partial derivative: out of memory");
        return STATUS_ERROR;
    }
    memset(seed_vector, 0, sizeof(double) * n_in);
    /* a value reference given twice adds its seeds, as the sum of two directions would */
    if (direction == FORWARD)
        for (i = 0; i < n_knowns; i++) seed_vector[known_position(instance, knowns[i])] += seed[i];
    else
        for (i = 0; i < n_unknowns; i++) seed_vector[unknown_position(instance, unknowns[i], 0)] += seed[i];

    /* In initialization x = x0(u, p): forward, the states' seeds are dx0 = (dx0/dK) w; reverse, the states'
     * sensitivities flow on through (dx0/dK)^T into the inputs' and parameters'. */
    if (direction == FORWARD) {
        status = STATUS_OK;
        if (initialization) {
            status = evaluate(instance, &info->initial_forward, seed_vector, chained);
            if (status == STATUS_OK) memcpy(seed_vector, chained, sizeof(double) * (size_t)info->nx);
        }
        if (status == STATUS_OK) status = evaluate(instance, &info->unknowns_forward, seed_vector, result);
    } else {
        status = evaluate(instance, &info->unknowns_adjoint, seed_vector, result);
        if (status == STATUS_OK && initialization) {
            status = evaluate(instance, &info->initial_adjoint, result, chained);
            for (j = info->nx; status == STATUS_OK && j < known_count(info); j++) result[j] += chained[j];
        }
    }
    if (status == STATUS_OK) {
        size_t n = direction == FORWARD ? n_unknowns : n_knowns;
        if (direction == FORWARD)
            for (i = 0; i < n_unknowns; i++) sensitivity[i] = result[unknown_position(instance, unknowns[i], 0)];
        else
            for (i = 0; i < n_knowns; i++) sensitivity[i] = result[known_position(instance, knowns[i])];
        for (i = 0; i < n; i++)
            if (!isfinite(sensitivity[i])) {
                instance_log(instance, STATUS_WARNING, "logStatusWarning",
                             "partial derivative: the %s sensitivity %lu is not finite at t = %.17g",
                             direction == FORWARD ? "directional" : "adjoint", (unsigned long)i, instance->now.time);
                status = STATUS_WARNING;
                break;
            }
    }
    instance->release(seed_vector);
    instance->release(result);
    instance->release(chained);
    return status;
}

Status instance_directional_derivative(Instance *instance, const unsigned int unknowns[], size_t n_unknowns,
                                       const unsigned int knowns[], size_t n_knowns, const double seed[],
                                       double sensitivity[]) {
    return partial_derivative(instance, FORWARD, unknowns, n_unknowns, knowns, n_knowns, seed, sensitivity);
}

Status instance_adjoint_derivative(Instance *instance, const unsigned int unknowns[], size_t n_unknowns,
                                   const unsigned int knowns[], size_t n_knowns, const double seed[],
                                   double sensitivity[]) {
    return partial_derivative(instance, ADJOINT, unknowns, n_unknowns, knowns, n_knowns, seed, sensitivity);
}
