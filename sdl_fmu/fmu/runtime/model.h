/* The small model API between the generic FMI layer and one model.
 *
 * A model is only data: the generated variable table and the CasADi functions of its equations.
 * Every function has the same signature (x, d, u, p) -> ..., where
 *   x  continuous states          d  discrete states (modes, held between events)
 *   u  inputs (Integer inputs are carried as doubles)
 *   p  parameters
 * The runtime (instance.c, cosimulation.c, derivatives.c, fmi2Functions.c, fmi3Functions.c) knows nothing of
 * vehicles. A model that is more than equations (the scenario FMU: co-simulation only, its data read from the FMU's
 * resources, its own step) adds hooks (ModelHooks, instance.h); the ego models have none.
 */
#ifndef SDL_FMU_MODEL_H
#define SDL_FMU_MODEL_H

#include <stddef.h>

typedef long long int casadi_int_t;

struct ModelHooks; /* instance.h */

typedef int (*CasadiEval)(const double **arg, double **res, casadi_int_t *iw, double *w, int mem);
typedef int (*CasadiWork)(casadi_int_t *sz_arg, casadi_int_t *sz_res, casadi_int_t *sz_iw, casadi_int_t *sz_w);

typedef struct {
    CasadiEval eval;
    CasadiWork work;
} ModelFunction;

/* Where a variable's value lives. */
typedef enum {
    STORE_INPUT,      /* u[index] */
    STORE_PARAMETER,  /* p[index] */
    STORE_STATE,      /* x[index] */
    STORE_DERIVATIVE, /* der(x[index]) */
    STORE_DISCRETE,   /* d[index] */
    STORE_OUTPUT,     /* y[index], computed by the outputs function */
    STORE_EVENT_INDICATOR /* z[index], computed by the event indicators function */
} Store;

typedef enum { KIND_REAL, KIND_INTEGER, KIND_BOOLEAN } Kind;

/* When the importer may set a variable (FMI 2.0 table of allowed calls). */
typedef enum {
    SET_NEVER,    /* outputs, locals, states */
    SET_FIXED,    /* fixed parameters: instantiated and initialization mode */
    SET_TUNABLE,  /* tunable parameters: also event and step mode */
    SET_INPUT     /* inputs: any mode after instantiation */
} Settable;

typedef struct {
    unsigned int value_reference;
    const char *name;
    Kind kind;
    Store store;
    int index;
    Settable settable;
    double min, max; /* declared range (modelDescription min/max; +-INFINITY where none): set refuses values outside */
} ModelVariable;

typedef struct {
    const char *model_identifier;
    const char *guid;
    int nx, nd, nu, np, ny, nz;
    const double *input_start;      /* nu */
    const double *parameter_start;  /* np */
    const double *state_nominal;    /* nx */
    const ModelVariable *variables;
    int n_variables;
    int solver_step_parameter;      /* index in p of the internal step size [s] (the longest, with error control) */
    int solver_tolerance_parameter; /* index in p of the internal solver's error tolerance (0: fixed steps) */
    int model_exchange_parameter;   /* index in p the runtime sets to 1 in model-exchange instances, 0 in
                                     * co-simulation ones (-1: none); after the declared parameters, no variable */
    ModelFunction derivatives;      /* (x,d,u,p) -> xdot[nx] */
    ModelFunction jacobian;         /* (x,d,u,p) -> d xdot / d x, dense nx*nx, column-major */
    ModelFunction outputs;          /* (x,d,u,p) -> y[ny] */
    ModelFunction event_indicators; /* (x,d,u,p) -> z[nz] */
    ModelFunction discrete_update;  /* (x,d,u,p) -> x+[nx], d+[nd]: what happens at an event */
    ModelFunction initial_state;    /* (x,d,u,p) -> x0[nx], d0[nd] from the parameters */
    /* Exact derivatives (derivatives.c) of the unknowns U = [x; d; xdot; y; z] (nU = 2 nx + nd + ny + nz) with
     * respect to the knowns K = [x; u; p] (nK = nx + nu + np), from CasADi's forward and reverse sweeps. */
    ModelFunction unknowns_forward; /* (x,d,u,p,seed[nK]) -> (dU/dK) seed [nU] */
    ModelFunction unknowns_adjoint; /* (x,d,u,p,seed[nU]) -> (dU/dK)^T seed [nK] */
    ModelFunction initial_forward;  /* (x,d,u,p,seed[nK]) -> (dx0/dK) seed [nx], x0 = initial state */
    ModelFunction initial_adjoint;  /* (x,d,u,p,seed[nx]) -> (dx0/dK)^T seed [nK] */
    const struct ModelHooks *hooks; /* what the model does in the generic layer's place (NULL: nothing) */
} ModelInfo;

/* Defined by the generated per-model file. */
extern const ModelInfo model_info;

#endif
