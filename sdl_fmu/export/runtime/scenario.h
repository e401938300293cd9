/* The SDL scenario as a model: the rules of `sdl-fmu run` (traffic motion, closure times, BRK, RSA per wheel, the
 * driver, collisions, the lead-vehicle signals, the run's end) over data that describe one scenario.
 *
 * A model is data. The scenario FMU's binary is generic: the scenario is read from resources/scenario.sdlfmu at
 * instantiation (scenario_data.c) into a block of doubles that the instance keeps after its declared parameters
 * (hidden, fixed parameters: the generic instance layer, instance.c, saves, restores and serializes them with
 * everything else). Its dynamic state (fired events, BRK, the driver, the traffic vehicles, the counters) is the
 * instance's discrete-state vector d; the outputs are a pure function of (d, inputs, parameters).
 *
 * Every rule is the Python of sdl_fmu/cosim/ written again, operation for operation in the same order, so that the
 * FMU replaying a recorded run gives the same numbers bit for bit (compiled with -ffp-contract=off: no fused
 * multiply-add). Python's x**2 is pow(x, 2.0) here where Python computes it so, x*x where it multiplies.
 */
#ifndef SDL_SCENARIO_H
#define SDL_SCENARIO_H

#include <stddef.h>

#include "instance.h"
#include "scenario_interface.h"

/* ---- constants of `sdl-fmu run` (sdl_fmu/cosim) ------------------------------------------------------------ */
#define FOOT 0.3048                /* m */
#define STANDARD_GRAVITY 9.80665   /* m/s2 */
#define RUNOUT (1000 * FOOT)       /* m past the last event when neither ES nor until_* ends the run */
#define MAX_TIME 3600.0            /* s, a run never goes beyond */
#define MIN_LOOKAHEAD 1e-3         /* s, closer than this to a possible trigger the prediction is probed this often */
#define TRIGGER_TOLERANCE 1e-9     /* s, how exactly a trigger's instant is located on the predicted path */
#define TIE_TOLERANCE 1e-9         /* relative (of max(1 s, |t|)): an instant this close after a communication point
                                      belongs to the step that ends there (a tie: docs/scenario-fmu.md, Stepping) */
#define STOPPED_SPEED 0.01         /* m/s, the ego counts as stopped below this without an ego_stopped input */
#define DEFAULT_MU_SURFACE 8.0     /* RSA value of a lane nobody set, friction meaning: 10 x the nominal mu 0.8 */
#define DEFAULT_ATTRIBUTE 0.0      /* RSA value of a lane nobody set, attribute meaning */
#define RIGHT_SHOULDER 101
#define LEFT_SHOULDER (-101)
#define MAX_ACTIONS 5
#define NO_TTC 1000.0              /* s (cosim/signals.py) */
#define NO_GAP 1000.0              /* m */

/* the sample clocks (cosim/clocks.py): instants of different clocks closer than this are one instant */
#define MERGE 1e-9
/* the drivers (cosim/driver.py, cosim/follow.py) */
enum { DRIVER_LANE = 1, DRIVER_FOLLOW = 2 };
#define REACTION_TIME (2.0 / 3.0)
#define BRAKING 3.4
#define LEADER_BRAKING 3.2
#define STANDSTILL_GAP 2.0
#define HOLD_SPEED 0.1
#define HOLD_BRAKE 0.3
#define SPEED_GAIN 1.0
#define SPEED_INTEGRAL_GAIN 0.2
#define BRAKE_DEADBAND 0.5
#define PREVIEW_TIME 1.0
#define MIN_PREVIEW 5.0
#define MAX_STEER 0.5
#define YAW_RATE_GAIN 0.3

/* budgets of one doStep (bounded work whatever the arguments) */
#define MAX_SAMPLES_PER_STEP 100000.0 /* driver samples in one step: a longer step is refused up front */
#define MAX_PROBES_PER_STEP 2000000L  /* looks at the predicted path in one step: beyond, the step fails */

/* event codes and actions (the outputs last_event_code / last_event_action) */
enum { CODE_NONE = 0, CODE_A = 1, CODE_BRK = 2, CODE_RSA = 3, CODE_ES = 4 };
enum { ACTION_NONE = 0, ACTION_SPAWN, ACTION_MANEUVER, ACTION_COLLISION, ACTION_DESPAWN, ACTION_ON, ACTION_OFF,
       ACTION_SET, ACTION_END };
/* BRK thresholds (parameter 2) and the reasons a BRK ends */
enum { THRESHOLD_TIME = 0, THRESHOLD_DISTANCE = 1, THRESHOLD_VELOCITY = 2, THRESHOLD_RELATIVE_VELOCITY = 3 };
enum { REASON_NONE = 0, REASON_TIME, REASON_DISTANCE, REASON_VELOCITY, REASON_RELATIVE_VELOCITY, REASON_STOPPED,
       REASON_END };
/* why the run ended (end_reason) */
enum { END_NONE = 0, END_SCENARIO, END_UNTIL_DISTANCE, END_UNTIL_TIME, END_RUNOUT, END_TIME_LIMIT, END_COLLISION };
/* where a closure-time action may fire: either side, F (vehicle in front), B (behind) */
enum { WHERE_ANY = 0, WHERE_FRONT = 1, WHERE_BEHIND = 2 };
/* arbitration of a channel while request_active */
enum { ARBITRATION_DRIVER = 0, ARBITRATION_OVERRIDE = 1, ARBITRATION_MAX = 2 };

/* ---- the data block (scenario_data.c writes it, the hidden parameters hold it) ------------------------------- */
/* p = [declared parameters (N_PARAMETERS) | start time | data block]; the block starts with this header */
#define HIDDEN_START_TIME N_PARAMETERS
#define DATA_START (N_PARAMETERS + 1)
enum {
    H_FORMAT, H_N_EVENTS, H_N_VEHICLES, H_N_SLOTS, H_LANE_WIDTH, H_LANES_RIGHT, H_LANES_LEFT, H_HAS_ES,
    H_ES_DISTANCE, H_LAST_DISTANCE, H_START_LATERAL, H_EVENT_OFFSETS, H_VEHICLE_EVENTS, H_LANE_INDEX,
    H_N_SURFACE_LANES, H_SURFACES, H_SIZE, H_COUNT
};
#define DATA_FORMAT 1.0
#define LANE_INDEX_SIZE (2 * RIGHT_SHOULDER + 1) /* lanes -101..101 */
/* an event record: [code, line, distance, payload...] */
enum { E_CODE, E_LINE, E_DISTANCE, E_PAYLOAD };
/* A payload; the initial transition (a Scenario made in Python may start one at the spawn) */
enum { A_SPEED = E_PAYLOAD, A_SPEED_RELATIVE, A_GAP, A_LATERAL, A_LATERAL_RELATIVE, A_MODEL, A_LENGTH, A_WIDTH,
       A_INITIAL, A_INITIAL_LATERAL, A_INITIAL_LATERAL_RELATIVE, A_INITIAL_SPEED, A_INITIAL_SPEED_RELATIVE,
       A_INITIAL_DURATION, A_N_ACTIONS, A_ACTIONS };
/* an action record inside it */
enum { ACT_SECONDS, ACT_WHERE, ACT_LATERAL, ACT_LATERAL_RELATIVE, ACT_SPEED, ACT_SPEED_RELATIVE, ACT_DURATION,
       ACT_SIZE };
#define A_SIZE (A_ACTIONS + MAX_ACTIONS * ACT_SIZE)
/* BRK payload */
enum { BRK_PEDAL = E_PAYLOAD, BRK_THRESHOLD, BRK_MAGNITUDE, BRK_SIZE };
/* RSA payload: n, then (lane, value) pairs */
enum { RSA_COUNT = E_PAYLOAD, RSA_SETTINGS };
#define ES_SIZE E_PAYLOAD
/* a surface lane record: [lane, count, offset of its starts, offset of its values] */
enum { SL_LANE, SL_COUNT, SL_STARTS, SL_VALUES, SL_SIZE };

/* ---- the dynamic state d ----------------------------------------------------------------------------------- */
enum {
    D_TIME,                 /* the time the state describes: the FMU's time, or up to a tie's tolerance after
                               it when a step fired something there (scenario.c, ties) */
    D_STARTED,              /* 1 after the first communication point was processed */
    D_NEXT_EVENT,           /* index of the first event not yet fired */
    D_BRK_ACTIVE, D_BRK_EVENT, D_BRK_TIME_ON, D_BRK_DISTANCE_ON, D_BRK_SPEED_ON,
    D_INTEGRAL,             /* the driver's speed-error integral (m) */
    D_THROTTLE, D_BRAKE, D_STEER, /* the controls (driver or BRK) */
    D_SAMPLE,               /* k of the next driver sample at k * driver_period */
    D_FINISHED, D_END_REASON,
    D_COLLISIONS, D_EVENTS,
    D_LAST_CODE, D_LAST_ACTION, D_LAST_VEHICLE, D_LAST_LINE, D_LAST_TIME,
    D_SPAWNED,              /* vehicles spawned so far (vehicle i is the i-th A event) */
    D_ACTIVE,               /* vehicles on the road */
    D_EGO,                  /* the ego at D_TIME as the FMU believes it: E_* fields */
    D_MEMORY = D_EGO + 12,  /* the previous communication point, for the inputs that are not connected */
    D_BOUNDS_WARNED = D_MEMORY + 5,
    D_FOLLOW_K,             /* the follow driver: k of its next decision at k * REACTION_TIME */
    D_FOLLOW_LIMITED,       /* 1: a vehicle ahead at the last decision (the law's acceleration and speed hold) */
    D_FOLLOW_ACCELERATION,  /* m/s2, the law's, held since the last decision */
    D_FOLLOW_ALLOWED,       /* m/s, the law's safe speed at the last decision (with D_FOLLOW_LIMITED) */
    D_FOLLOW_LIMITING,      /* 1: the law set the last pedals (the lane driver's integral is then held) */
    D_START_PENDING,        /* 1 from the exit of initialization mode to the first doStep, which takes the start
                               again from its inputs (they may have changed since) and logs the start's events */
    D_HEADER
};
/* an ego state's fields (also the layout of D_EGO) */
enum { EGO_X, EGO_Y, EGO_PSI, EGO_S, EGO_V, EGO_VX, EGO_VY, EGO_YAW_RATE, EGO_AX, EGO_AY, EGO_STOPPED, EGO_FIELDS };
/* the memory: time, v, psi, s, yaw rate */
enum { MEM_TIME, MEM_V, MEM_PSI, MEM_S, MEM_YAW_RATE };
/* per traffic vehicle, after the slots */
enum { V_T0, V_STATION0, V_LATERAL0, V_SPEED0, V_LATERAL1, V_SPEED1, V_DURATION, V_NEXT_ACTION, V_IN_CONTACT,
       V_PRESENT, V_SLOT, V_SIZE };

typedef struct {
    double time, x, y, psi, s, v, vx, vy, ax, ay, yaw_rate;
    int stopped;
} Ego;

/* A view of the data block (pointers into the hidden parameters): built in O(1) from p. */
typedef struct {
    const double *p;      /* all parameters */
    const double *data;   /* the data block */
    int n_events, n_vehicles, n_slots, lanes_right, lanes_left, n_surface_lanes;
    double lane_width, es_distance, last_distance, start_lateral;
    int has_es;
    const double *event_offsets, *vehicle_events, *lane_index, *surfaces;
} View;

/* where the scenario's log lines go (instance NULL: nowhere, for the pure functions) */
typedef struct {
    Instance *instance;
    const char *const *model_names; /* per vehicle (A event order), or NULL */
} Logger;

/* scenario_data.c: the resources file -> the data block (allocated with `allocate`); returns NULL and writes a
 * one-line reason ("<file>:<line>: ...") on any malformed input. The vehicle models' names come back per vehicle,
 * the parameters' start values (N_PARAMETERS) in `parameters`. */
double *scenario_parse(const char *text, size_t length, const char *file, void *(*allocate)(size_t, size_t),
                       void (*release)(void *), size_t *size, char **guid, char ***names, double *parameters,
                       char *reason, size_t reason_size);
void scenario_free_names(char **names, int count, void (*release)(void *));

/* scenario.c: the rules */
void view_make(View *view, const double *p);
size_t state_size(const View *view);
/* Checks a state vector before it may reach an instance (indices, flags, counts in range): 0 if valid, else
 * writes why. */
int state_check(const View *view, const double *d, char *reason, size_t reason_size);
/* The state after the first communication point (t = start time), the ego at its inputs there; the first doStep
 * takes it again from its own inputs (D_START_PENDING). */
void scenario_begin(const View *view, const double *u, double *d, const Logger *log);
/* Advances d from its time to t + h. Returns 0 on success, 1 when it returned early at an event (early_return
 * allowed), -1 on a budget error (logged). */
int scenario_step(const View *view, const double *u, double *d, double t, double h, int early_return,
                  const Logger *log, double *reached);
void scenario_outputs(const View *view, const double *u, const double *d, double *y);
/* A doStep's argument rules beyond the generic ones: 0 if the step may run, else writes why. */
int scenario_check_step(const View *view, double h, char *reason, size_t reason_size);

/* scenario_model.c: the scenario as a model of the generic runtime (model_info, its hooks) */

#endif
