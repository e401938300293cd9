/* One scenario as a model of the generic instance layer (instance.c, shared with the ego FMUs): the variable table
 * (the interface's fixed variables and the traffic slots), the start values (the declared parameters' and, hidden
 * after them, the start time and the scenario's data block), and the model functions in the layer's (x, d, u, p)
 * form: the outputs and the initial state. There are no continuous states and no event indicators: the scenario
 * advances in scenario_step (scenario.c), called by the FMI layers' doStep. */
#if defined(__MINGW32__) && !defined(__USE_MINGW_ANSI_STDIO)
#define __USE_MINGW_ANSI_STDIO 1
#endif
#include "scenario.h"

#include <stdio.h>
#include <string.h>

typedef struct {
    ModelInfo info;             /* first: the instance layer sees this */
    ModelVariable *variables;
    char *slot_names;
    double *input_start, *parameter_start, nominal[1];
} ScenarioModel;

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

ModelInfo *scenario_model_info(const double *data, size_t data_size, const double *parameters, const char *guid,
                               void *(*allocate)(size_t, size_t), void (*release)(void *)) {
    ScenarioModel *model = (ScenarioModel *)allocate(1, sizeof(ScenarioModel));
    ModelInfo *info;
    View view;
    int n_slots, i, j;
    size_t name_size = 24;
    const ModelFunction none = {nothing, no_work};
    if (!model) return NULL;
    n_slots = (int)data[H_N_SLOTS];
    model->variables =
        (ModelVariable *)allocate((size_t)(N_SCENARIO_VARIABLES + n_slots * N_SLOT_OUTPUTS) + 1, sizeof(ModelVariable));
    model->slot_names = (char *)allocate((size_t)(n_slots * N_SLOT_OUTPUTS) * name_size + 1, 1);
    model->input_start = (double *)allocate(N_INPUTS + 1, sizeof(double));
    model->parameter_start = (double *)allocate(DATA_START + data_size + 1, sizeof(double));
    if (!model->variables || !model->slot_names || !model->input_start || !model->parameter_start) {
        scenario_model_free(&model->info, release);
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
    info->guid = guid;
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
    return info;
}

void scenario_model_free(ModelInfo *info, void (*release)(void *)) {
    ScenarioModel *model = (ScenarioModel *)info;
    if (!model) return;
    if (model->variables) release(model->variables);
    if (model->slot_names) release(model->slot_names);
    if (model->input_start) release(model->input_start);
    if (model->parameter_start) release(model->parameter_start);
    release(model);
}
