/* The rules of an SDL scenario (sdl_fmu/cosim/ in C): traffic motion (traffic.py), closure times, contacts and
 * departures (triggers.py), BRK (brake.py), the surfaces under the wheels (road.py), the lane driver (driver.py),
 * the lead-vehicle signals (signals.py), what fires at an instant and the run's end (master.py), and how soon a
 * trigger could become true (triggers.py's bounds). Each function names the Python it follows; the arithmetic is
 * the same, operation for operation.
 *
 * The step. With trigger_prediction (the default), doStep(t, h) knows the ego only at t (its inputs). Over the step
 * the FMU follows a belief of the ego's path: the second-order prediction from the inputs at t (pose, velocity and
 * acceleration, yaw rate held; a predicted stop holds it at rest), plus the belief's offset from the inputs at t
 * fading linearly to zero at t + h, so that the belief is continuous from one step to the next and no condition
 * flips back and forth at a communication point. Triggers are located on it as `sdl-fmu run` locates them on the
 * ego FMU: lower bounds on the next trigger's instant, probes at most MIN_LOOKAHEAD apart within reach of one,
 * bisection to TRIGGER_TOLERANCE; what is due fires there, and the driver samples at k * driver_period. Without
 * prediction, everything is evaluated at the communication points with the ego's inputs there, as `sdl-fmu run`
 * evaluates it at its samples. */
#if defined(__MINGW32__) && !defined(__USE_MINGW_ANSI_STDIO)
#define __USE_MINGW_ANSI_STDIO 1
#endif
#include "scenario.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* Python's x**2: pow(x, 2.0) of the C library, which is not always x * x (glibc's pow is not correctly rounded);
 * the exponent is volatile so that the compiler does not fold the call into a multiplication. */
static double python_square(double x) {
    volatile double two = 2.0;
    return pow(x, two);
}

/* ---- the data --------------------------------------------------------------------------------------------------- */

void view_make(View *view, const double *p) {
    const double *data = p + DATA_START;
    view->p = p;
    view->data = data;
    view->n_events = (int)data[H_N_EVENTS];
    view->n_vehicles = (int)data[H_N_VEHICLES];
    view->n_slots = (int)data[H_N_SLOTS];
    view->lane_width = data[H_LANE_WIDTH];
    view->lanes_right = (int)data[H_LANES_RIGHT];
    view->lanes_left = (int)data[H_LANES_LEFT];
    view->has_es = data[H_HAS_ES] != 0.0;
    view->es_distance = data[H_ES_DISTANCE];
    view->last_distance = data[H_LAST_DISTANCE];
    view->start_lateral = data[H_START_LATERAL];
    view->event_offsets = data + (size_t)data[H_EVENT_OFFSETS];
    view->vehicle_events = data + (size_t)data[H_VEHICLE_EVENTS];
    view->lane_index = data + (size_t)data[H_LANE_INDEX];
    view->n_surface_lanes = (int)data[H_N_SURFACE_LANES];
    view->surfaces = data + (size_t)data[H_SURFACES];
}

size_t state_size(const View *view) {
    return (size_t)D_HEADER + (size_t)view->n_slots + (size_t)view->n_vehicles * V_SIZE;
}

static const double *event_at(const View *view, int k) { return view->data + (size_t)view->event_offsets[k]; }

static const double *vehicle_event(const View *view, int i) {
    return event_at(view, (int)view->vehicle_events[i]);
}

static double *vehicle(const View *view, double *d, int i) {
    return d + D_HEADER + view->n_slots + (size_t)i * V_SIZE;
}

static const double *vehicle_const(const View *view, const double *d, int i) {
    return d + D_HEADER + view->n_slots + (size_t)i * V_SIZE;
}

#define PARAMETER(view, name) ((view)->p[P_##name])

/* The armed action of vehicle i (NULL: none left). */
static const double *armed(const View *view, const double *d, int i) {
    const double *event = vehicle_event(view, i);
    int next = (int)vehicle_const(view, d, i)[V_NEXT_ACTION];
    if (next >= (int)event[A_N_ACTIONS]) return NULL;
    return event + A_ACTIONS + (size_t)next * ACT_SIZE;
}

/* Relative.resolve: the ego's value plus the value when written with '*'. */
static double resolve(double value, double relative, double ego_value) {
    return relative != 0.0 ? ego_value + value : value;
}

/* Cosimulation._end_distance: where the run ends by distance, and why. */
static double end_distance(const View *view, int *reason) {
    double until = PARAMETER(view, UNTIL_DISTANCE), best = INFINITY;
    *reason = END_NONE;
    if (view->has_es) {
        best = view->es_distance;
        *reason = END_SCENARIO;
    }
    if (until > 0.0 && (*reason == END_NONE || until < best)) { /* a tie goes to ES ("scenario" < "until_...") */
        best = until;
        *reason = END_UNTIL_DISTANCE;
    }
    if (*reason != END_NONE) return best;
    if (PARAMETER(view, UNTIL_TIME) > 0.0) {
        *reason = END_UNTIL_TIME;
        return INFINITY;
    }
    *reason = END_RUNOUT;
    return view->last_distance + RUNOUT;
}

/* ---- the ego ---------------------------------------------------------------------------------------------------- */

static void ego_store(double *to, const Ego *e) {
    to[EGO_X] = e->x;
    to[EGO_Y] = e->y;
    to[EGO_PSI] = e->psi;
    to[EGO_S] = e->s;
    to[EGO_V] = e->v;
    to[EGO_VX] = e->vx;
    to[EGO_VY] = e->vy;
    to[EGO_YAW_RATE] = e->yaw_rate;
    to[EGO_AX] = e->ax;
    to[EGO_AY] = e->ay;
    to[EGO_STOPPED] = e->stopped ? 1.0 : 0.0;
}

static void ego_load(Ego *e, const double *from, double time) {
    e->time = time;
    e->x = from[EGO_X];
    e->y = from[EGO_Y];
    e->psi = from[EGO_PSI];
    e->s = from[EGO_S];
    e->v = from[EGO_V];
    e->vx = from[EGO_VX];
    e->vy = from[EGO_VY];
    e->yaw_rate = from[EGO_YAW_RATE];
    e->ax = from[EGO_AX];
    e->ay = from[EGO_AY];
    e->stopped = from[EGO_STOPPED] != 0.0;
}

/* The ego at a communication point from the inputs; what is not connected is derived from the previous
 * communication point as EgoInstance._derive does for a vehicle map without that output (the memory is updated). */
static void ego_from_inputs(const View *view, const double *u, double *memory, double time, Ego *e) {
    double h = time - memory[MEM_TIME], v = u[U_EGO_V], psi = u[U_EGO_PSI];
    e->time = time;
    e->x = u[U_EGO_X];
    e->y = u[U_EGO_Y];
    e->psi = psi;
    e->v = v;
    e->s = PARAMETER(view, EGO_S_CONNECTED) != 0.0 ? u[U_EGO_S] : memory[MEM_S] + 0.5 * (memory[MEM_V] + v) * h;
    if (PARAMETER(view, EGO_YAW_RATE_CONNECTED) != 0.0)
        e->yaw_rate = u[U_EGO_YAW_RATE];
    else
        e->yaw_rate = h > 0 ? (psi - memory[MEM_PSI]) / h : memory[MEM_YAW_RATE];
    e->vy = PARAMETER(view, EGO_VY_CONNECTED) != 0.0 ? u[U_EGO_VY] : 0.0;
    if (PARAMETER(view, EGO_VX_CONNECTED) != 0.0)
        e->vx = u[U_EGO_VX];
    else {
        double square = v * v - e->vy * e->vy;
        e->vx = sqrt(square > 0.0 ? square : 0.0);
    }
    e->ax = PARAMETER(view, EGO_AX_CONNECTED) != 0.0 ? u[U_EGO_AX] : (h > 0 ? (v - memory[MEM_V]) / h : 0.0);
    e->ay = PARAMETER(view, EGO_AY_CONNECTED) != 0.0 ? u[U_EGO_AY] : v * e->yaw_rate;
    e->stopped = PARAMETER(view, EGO_STOPPED_CONNECTED) != 0.0 ? u[U_EGO_STOPPED] > 0.5 : fabs(v) < STOPPED_SPEED;
    memory[MEM_TIME] = time;
    memory[MEM_V] = v;
    memory[MEM_PSI] = psi;
    memory[MEM_S] = e->s;
    memory[MEM_YAW_RATE] = e->yaw_rate;
}

/* The ego as the observation outputs see it without prediction: the inputs as they are (no memory). */
static void ego_of_inputs(const View *view, const double *u, const double *d, Ego *e) {
    ego_load(e, d + D_EGO, d[D_TIME]);
    e->x = u[U_EGO_X];
    e->y = u[U_EGO_Y];
    e->psi = u[U_EGO_PSI];
    e->v = u[U_EGO_V];
    e->vy = PARAMETER(view, EGO_VY_CONNECTED) != 0.0 ? u[U_EGO_VY] : 0.0;
    if (PARAMETER(view, EGO_VX_CONNECTED) != 0.0)
        e->vx = u[U_EGO_VX];
    else {
        double square = e->v * e->v - e->vy * e->vy;
        e->vx = sqrt(square > 0.0 ? square : 0.0);
    }
}

/* EgoKinematics.of: the ego in the road frame (station, lateral + right) and their rates. */
typedef struct {
    double time, station, lateral, station_rate, lateral_rate, psi;
} Kinematics;

static Kinematics kinematics_of(const Ego *e) {
    Kinematics k;
    double c = cos(e->psi), s = sin(e->psi);
    k.time = e->time;
    k.station = e->x;
    k.lateral = -e->y;
    k.station_rate = e->vx * c - e->vy * s;
    k.lateral_rate = -(e->vx * s + e->vy * c);
    k.psi = e->psi;
    return k;
}

/* ---- traffic motion (traffic.py) -------------------------------------------------------------------------------- */

/* motion_at (Traffic.at): (station, lateral, speed) at time t; the transition's end values themselves once done. */
static void motion_at(const double *vh, double t, double *station, double *lateral, double *speed) {
    double t0 = vh[V_T0], station0 = vh[V_STATION0], lateral0 = vh[V_LATERAL0], speed0 = vh[V_SPEED0];
    double lateral1 = vh[V_LATERAL1], speed1 = vh[V_SPEED1], duration = vh[V_DURATION];
    double elapsed = t - t0, travelled;
    if (duration > 0.0 && elapsed < duration) { /* (a zero duration never divides, before its start neither) */
        double fraction = elapsed / duration;
        *speed = speed0 + (speed1 - speed0) * fraction;
        travelled = speed0 * elapsed + (speed1 - speed0) * python_square(elapsed) / (2 * duration);
        *station = station0 - travelled;
        *lateral = lateral0 + (lateral1 - lateral0) * fraction;
        return;
    }
    travelled = (speed0 + speed1) / 2 * duration + speed1 * (elapsed - duration);
    *station = station0 - travelled;
    *lateral = lateral1;
    *speed = speed1;
}

/* Traffic.motion_of (and Traffic.motion, the arrays' form): with the rates of the transition. */
typedef struct {
    double station, lateral, speed, lateral_rate, speed_rate;
} Motion;

static Motion motion_of(const double *vh, double t) {
    Motion m;
    double t0 = vh[V_T0], station0 = vh[V_STATION0], lateral0 = vh[V_LATERAL0], speed0 = vh[V_SPEED0];
    double lateral1 = vh[V_LATERAL1], speed1 = vh[V_SPEED1], duration = vh[V_DURATION];
    double elapsed = t - t0, fraction, travelled;
    if (duration > 0.0 && elapsed < duration) { /* (a zero duration never divides, before its start neither) */
        fraction = elapsed / duration;
        travelled = speed0 * elapsed + (speed1 - speed0) * (elapsed * elapsed) / (2 * duration);
        m.lateral_rate = (lateral1 - lateral0) / duration;
        m.speed_rate = fabs(speed1 - speed0) / duration;
    } else {
        fraction = 1.0;
        travelled = (speed0 + speed1) / 2 * duration + speed1 * (elapsed - duration);
        m.lateral_rate = m.speed_rate = 0.0;
    }
    m.station = station0 - travelled;
    m.lateral = lateral0 + (lateral1 - lateral0) * fraction;
    m.speed = speed0 + (speed1 - speed0) * fraction;
    return m;
}

/* ---- triggers (triggers.py) ------------------------------------------------------------------------------------- */

/* reach_time_scalar: smallest tau >= 0 with rate tau + acceleration tau^2 / 2 >= distance. */
static double reach_time(double distance, double rate, double acceleration) {
    double root, denominator;
    if (distance <= 0.0) return 0.0;
    root = sqrt(rate * rate + 2 * acceleration * distance);
    denominator = rate + root;
    if (!(denominator >= 1e-300)) denominator = 1e-300; /* max(rate + root, 1e-300) */
    return rate > 0 ? 2 * distance / denominator : (root - rate) / acceleration;
}

/* _penetration: the overlap depth of the ego's footprint (turned by psi) and a vehicle's (aligned with the road);
 * > 0: they overlap. */
static double penetration(const Kinematics *ego, double ego_length, double ego_width, double d_station,
                          double d_lateral, double length, double width) {
    double cos_psi = cos(ego->psi), sin_psi = sin(ego->psi);
    double c = fabs(cos_psi), s = fabs(sin_psi);
    double half_l = ego_length / 2, half_w = ego_width / 2;
    double dx = d_station, dy = -d_lateral;
    double along_x = half_l * c + half_w * s + length / 2 - fabs(dx);
    double along_y = half_l * s + half_w * c + width / 2 - fabs(dy);
    double along_u = half_l + length / 2 * c + width / 2 * s - fabs(dx * cos_psi + dy * sin_psi);
    double along_v = half_w + length / 2 * s + width / 2 * c - fabs(-dx * sin_psi + dy * cos_psi);
    double a = along_x < along_y ? along_x : along_y, b = along_u < along_v ? along_u : along_v;
    return a < b ? a : b;
}

typedef struct {
    int due, overlap, away;
} Conditions;

/* vehicle_condition: (action due, footprints overlap, may leave) of vehicle i at the ego's instant. */
static Conditions vehicle_condition(const View *view, const double *d, int i, const Kinematics *ego) {
    Conditions result;
    const double *vh = vehicle_const(view, d, i), *event = vehicle_event(view, i), *action = armed(view, d, i);
    Motion m = motion_of(vh, ego->time);
    double gap = m.station - ego->station, gap_rate = -m.speed - ego->station_rate;
    double closing = -gap_rate * (gap > 0 ? 1.0 : gap < 0 ? -1.0 : 0.0);
    double ego_length = PARAMETER(view, EGO_LENGTH), length = event[A_LENGTH], width = event[A_WIDTH];
    result.due = 0;
    if (action != NULL) {
        double seconds = action[ACT_SECONDS];
        int where = (int)action[ACT_WHERE];
        int allowed = gap != 0 && !(where == WHERE_FRONT && gap < 0) && !(where == WHERE_BEHIND && gap > 0);
        result.due = allowed && ((seconds > 0 && closing > 0 && fabs(gap) <= seconds * closing) ||
                                 (seconds < 0 && closing < 0 && fabs(gap) >= seconds * closing));
    }
    result.overlap = penetration(ego, ego_length, PARAMETER(view, EGO_WIDTH), gap, m.lateral - ego->lateral, length,
                                 width) > 0;
    {
        int leave_allowed = action == NULL || action[ACT_SECONDS] > 0 || (int)action[ACT_WHERE] == WHERE_FRONT;
        result.away = leave_allowed && gap < -(ego_length + length) / 2 && gap_rate < 0;
    }
    return result;
}

/* vehicle_horizon: a lower bound (s from the ego's instant) on when vehicle i's action, contact change or
 * departure could first become true, with |ego acceleration| <= a and |yaw rate| <= yaw_rate (the ego's station and
 * lateral rates being its position's derivatives). */
static double vehicle_horizon(const View *view, const double *d, int i, const Kinematics *ego, double yaw_rate) {
    const double *vh = vehicle_const(view, d, i), *event = vehicle_event(view, i), *action = armed(view, d, i);
    Motion m = motion_of(vh, ego->time);
    double length = event[A_LENGTH], width = event[A_WIDTH];
    double ego_length = PARAMETER(view, EGO_LENGTH), ego_width = PARAMETER(view, EGO_WIDTH);
    double radius = hypot(ego_length / 2, ego_width / 2);
    double a = PARAMETER(view, EGO_MAX_ACCELERATION), relative_acceleration = a + m.speed_rate;
    double gap = m.station - ego->station, gap_rate = -m.speed - ego->station_rate;
    double closing = -gap_rate * (gap >= 0 ? 1.0 : -1.0);
    int in_contact = vh[V_IN_CONTACT] != 0.0;
    double action_bound, contact, leave, d_lateral, turn;

    if (action == NULL) {
        action_bound = INFINITY;
    } else {
        double seconds = action[ACT_SECONDS];
        int where = (int)action[ACT_WHERE];
        if ((where == WHERE_FRONT && gap <= 0) || (where == WHERE_BEHIND && gap >= 0)) {
            action_bound = reach_time(fabs(gap), closing, relative_acceleration);
        } else if (seconds > 0) {
            action_bound = reach_time(fabs(gap) - seconds * closing, closing + seconds * relative_acceleration,
                                      relative_acceleration);
        } else {
            double separating = -closing;
            if (separating <= 0) {
                double a1 = -separating / relative_acceleration, a2 = reach_time(fabs(gap), closing,
                                                                                  relative_acceleration);
                action_bound = a1 < a2 ? a1 : a2;
            } else {
                action_bound = reach_time(-seconds * separating - fabs(gap), separating - seconds *
                                          relative_acceleration, relative_acceleration);
            }
        }
    }

    d_lateral = m.lateral - ego->lateral;
    turn = radius * yaw_rate;
    if (in_contact) {
        double depth = penetration(ego, ego_length, ego_width, gap, d_lateral, length, width);
        double vehicle_radius = hypot(length / 2, width / 2);
        double relative_speed = fabs(gap_rate) + fabs(ego->lateral_rate) + fabs(m.lateral_rate);
        contact = reach_time(depth, relative_speed + 2 * (radius + vehicle_radius) * yaw_rate,
                             relative_acceleration);
    } else {
        double c = fabs(cos(ego->psi)), s = fabs(sin(ego->psi));
        double half_l = ego_length / 2, half_w = ego_width / 2;
        double along_x = half_l * c + half_w * s + length / 2 - fabs(gap);
        double along_y = half_l * s + half_w * c + width / 2 - fabs(-d_lateral);
        double lateral_closing = (d_lateral > 0 ? 1.0 : d_lateral < 0 ? -1.0 : 0.0) * ego->lateral_rate;
        double c1 = reach_time(-along_x, closing + turn, relative_acceleration);
        double c2 = reach_time(-along_y, lateral_closing + fabs(m.lateral_rate) + turn, a);
        contact = c1 > c2 ? c1 : c2;
    }

    if ((action == NULL || action[ACT_SECONDS] > 0 || (int)action[ACT_WHERE] == WHERE_FRONT) && !in_contact) {
        double behind = reach_time(gap + (ego_length + length) / 2, -gap_rate, relative_acceleration);
        double away = gap_rate >= 0 ? gap_rate / relative_acceleration : 0.0;
        leave = behind > away ? behind : away;
    } else {
        leave = INFINITY;
    }
    {
        double first = action_bound < contact ? action_bound : contact;
        return first < leave ? first : leave;
    }
}

/* ---- BRK (brake.py) --------------------------------------------------------------------------------------------- */

static int release_reason(const View *view, const double *d, const Ego *e) {
    const double *event = event_at(view, (int)d[D_BRK_EVENT]);
    int threshold = (int)event[BRK_THRESHOLD];
    double magnitude = event[BRK_MAGNITUDE];
    if (threshold == THRESHOLD_TIME && e->time >= d[D_BRK_TIME_ON] + magnitude) return REASON_TIME;
    if (threshold == THRESHOLD_DISTANCE && e->s - d[D_BRK_DISTANCE_ON] >= magnitude) return REASON_DISTANCE;
    if (threshold == THRESHOLD_VELOCITY && e->v < magnitude) return REASON_VELOCITY;
    if (threshold == THRESHOLD_RELATIVE_VELOCITY && d[D_BRK_SPEED_ON] - e->v >= magnitude)
        return REASON_RELATIVE_VELOCITY;
    if (e->stopped) return REASON_STOPPED;
    return REASON_NONE;
}

/* BrakeHold.earliest_release: a lower bound on the instant the brakes could come off (s_rate: the rate of the
 * distance travelled, the speed for an ego whose distance is its speed's integral). */
static double earliest_release(const View *view, const double *d, const Ego *e, double s_rate, double acceleration) {
    const double *event = event_at(view, (int)d[D_BRK_EVENT]);
    int threshold = (int)event[BRK_THRESHOLD];
    double magnitude = event[BRK_MAGNITUDE], stop = e->time + e->v / acceleration, reach, margin;
    if (threshold == THRESHOLD_TIME) {
        reach = d[D_BRK_TIME_ON] + magnitude;
    } else if (threshold == THRESHOLD_DISTANCE) {
        reach = e->time + reach_time(d[D_BRK_DISTANCE_ON] + magnitude - e->s, s_rate, acceleration);
    } else if (threshold == THRESHOLD_VELOCITY) {
        margin = e->v - magnitude;
        reach = e->time + (margin > 0.0 ? margin : 0.0) / acceleration;
    } else {
        margin = e->v - (d[D_BRK_SPEED_ON] - magnitude);
        reach = e->time + (margin > 0.0 ? margin : 0.0) / acceleration;
    }
    return reach < stop ? reach : stop;
}

/* ---- the driver (driver.py) ------------------------------------------------------------------------------------- */

static double wheelbase_of(const View *view) {
    return PARAMETER(view, EGO_CG_TO_FRONT_AXLE) + PARAMETER(view, EGO_CG_TO_REAR_AXLE);
}

static double driver_steer(const View *view, const Ego *e) {
    double v = e->v, preview = PREVIEW_TIME * v, wheelbase = wheelbase_of(view), alpha, steer, path_yaw_rate;
    if (preview < MIN_PREVIEW) preview = MIN_PREVIEW;
    alpha = atan2(-view->start_lateral - e->y, preview) - e->psi;
    steer = atan(2 * wheelbase * sin(alpha) / preview);
    path_yaw_rate = e->vx * tan(steer) / wheelbase;
    steer += YAW_RATE_GAIN * (path_yaw_rate - e->yaw_rate);
    return steer < -MAX_STEER ? -MAX_STEER : steer > MAX_STEER ? MAX_STEER : steer;
}

/* Driver.resistance: the rolling and air resistance's deceleration at speed v, the feed-forward. */
static double resistance(const View *view, double v) {
    double mass = PARAMETER(view, EGO_MASS);
    double drag_factor = PARAMETER(view, EGO_AIR_DENSITY) * PARAMETER(view, EGO_DRAG_AREA) / (2 * mass);
    return PARAMETER(view, EGO_ROLLING_RESISTANCE) * STANDARD_GRAVITY * (v > 0 ? 1.0 : 0.0) +
           drag_factor * python_square(v);
}

/* Driver.demand: PI on the speed error plus the resistance's feed-forward. */
static double driver_demand(const View *view, const double *d, const Ego *e) {
    double error = PARAMETER(view, SPEED) - e->v;
    return SPEED_GAIN * error + SPEED_INTEGRAL_GAIN * d[D_INTEGRAL] + resistance(view, e->v);
}

/* Driver.pedals_for: (throttle, brake) that give the acceleration `demand` at speed v. */
static void pedals_for(const View *view, double demand, double v, int deadband, double *throttle, double *brake) {
    *throttle = *brake = 0.0;
    if (demand >= 0) {
        double mass = PARAMETER(view, EGO_MASS);
        double power_limited = PARAMETER(view, EGO_DRIVE_POWER_MAX) / (mass * (v < 1e-3 ? 1e-3 : v));
        double drive_accel_max = PARAMETER(view, EGO_DRIVE_ACCEL_MAX);
        double available = power_limited < drive_accel_max ? power_limited : drive_accel_max, value;
        if (!(available > 0)) return;
        value = demand / available;
        *throttle = value > 1.0 ? 1.0 : value;
        return;
    }
    if (deadband && demand > -BRAKE_DEADBAND) return;
    {
        double value = -demand / PARAMETER(view, EGO_BRAKE_DECEL_MAX);
        *brake = value > 1.0 ? 1.0 : value;
    }
}

static int following(const View *view) { return (int)PARAMETER(view, DRIVER) == DRIVER_FOLLOW; }

/* The driver's pedals: the lane driver's (Driver.pedals), or the follow driver's (FollowDriver.pedals: the lane
 * driver's unless Gipps' law asks for less acceleration; then pedals for the law's, or the hold brake at rest). */
static void driver_pedals(const View *view, double *d, const Ego *e, double *throttle, double *brake) {
    double v = e->v, demand = driver_demand(view, d, e), acceleration = d[D_FOLLOW_ACCELERATION];
    if (!following(view)) {
        pedals_for(view, demand, v, 1, throttle, brake);
        return;
    }
    if (d[D_FOLLOW_LIMITED] == 0.0 || demand <= acceleration + resistance(view, v)) {
        d[D_FOLLOW_LIMITING] = 0.0;
        pedals_for(view, demand, v, 1, throttle, brake);
        return;
    }
    d[D_FOLLOW_LIMITING] = 1.0;
    if ((e->stopped || v < STOPPED_SPEED) && d[D_FOLLOW_ALLOWED] < HOLD_SPEED) {
        *throttle = 0.0;
        *brake = HOLD_BRAKE;
        return;
    }
    pedals_for(view, acceleration + resistance(view, v), v, 0, throttle, brake);
}

static void driver_update(const View *view, double *d, const Ego *e, double h, double throttle) {
    double error = PARAMETER(view, SPEED) - e->v;
    if (following(view) && d[D_FOLLOW_LIMITING] != 0.0) return; /* FollowDriver.update: no wind-up */
    if (!(throttle >= 1.0 && error > 0)) {
        double integral = d[D_INTEGRAL] + error * h;
        d[D_INTEGRAL] = integral < -5.0 ? -5.0 : integral > 5.0 ? 5.0 : integral;
    }
}

/* follow.safe_speed: Gipps' braking term, the speed the driver may have REACTION_TIME from now. */
static double safe_speed(double v, double gap, double lead_speed) {
    double tau = REACTION_TIME, b = BRAKING, leader = LEADER_BRAKING, lead = lead_speed > 0.0 ? lead_speed : 0.0;
    double argument = b * b * tau * tau + b * (2.0 * (gap - STANDSTILL_GAP) - v * tau + lead * lead / leader);
    double speed;
    if (!(argument > 0.0)) return 0.0;
    speed = -b * tau + sqrt(argument);
    return speed > 0.0 ? speed : 0.0;
}

/* signals.lead_vehicle: the lead-vehicle signals from the ego and the vehicles on the road at `time`. */
typedef struct {
    int present, id;
    double gap, speed, relative_speed, ttc, lateral_offset;
} Lead;

static Lead lead_of(const View *view, const double *d, const Ego *e, double time) {
    Lead lead = {0, 0, NO_GAP, 0.0, 0.0, NO_TTC, 0.0};
    double a = PARAMETER(view, EGO_LENGTH) / 2, b = PARAMETER(view, EGO_WIDTH) / 2;
    double c = fabs(cos(e->psi)), s = fabs(sin(e->psi));
    double along = a * c + b * s, across = a * s + b * c, best_gap = INFINITY;
    Motion best_motion = {0, 0, 0, 0, 0};
    int i, n = (int)d[D_SPAWNED], best = -1;
    for (i = 0; i < n; i++) {
        const double *vh = vehicle_const(view, d, i), *event = vehicle_event(view, i);
        Motion m;
        double dx, dy, gap;
        if (vh[V_PRESENT] == 0.0) continue;
        m = motion_of(vh, time);
        dx = m.station - e->x;
        if (!(dx > 0.0)) continue;
        dy = -m.lateral - e->y;
        if (!(fabs(dy) < across + event[A_WIDTH] / 2)) continue;
        gap = dx - along - event[A_LENGTH] / 2;
        if (gap < best_gap) {
            best = i;
            best_gap = gap;
            best_motion = m;
        }
    }
    if (best >= 0) {
        double ego_along = e->vx * cos(e->psi) - e->vy * sin(e->psi);
        lead.present = 1;
        lead.id = best + 1;
        lead.gap = best_gap > 0.0 ? best_gap : 0.0;
        lead.speed = -best_motion.speed;
        lead.relative_speed = lead.speed - ego_along;
        lead.ttc = lead.relative_speed < 0.0 ? lead.gap / -lead.relative_speed : NO_TTC;
        lead.lateral_offset = -best_motion.lateral - e->y;
    }
    return lead;
}

/* FollowDriver.decide: a decision of Gipps' law from the lead-vehicle signals; whether it changes the pedals now. */
static int follow_decide(const View *view, double *d, const Ego *e) {
    Lead lead = lead_of(view, d, e, e->time);
    int changed;
    if (lead.present) {
        d[D_FOLLOW_LIMITED] = 1.0;
        d[D_FOLLOW_ALLOWED] = safe_speed(e->v, lead.gap, lead.speed);
        d[D_FOLLOW_ACCELERATION] = (safe_speed(e->v, lead.gap, lead.speed) - e->v) / REACTION_TIME;
    } else {
        d[D_FOLLOW_LIMITED] = 0.0;
        d[D_FOLLOW_ALLOWED] = 0.0;
        d[D_FOLLOW_ACCELERATION] = 0.0;
    }
    changed = d[D_FOLLOW_LIMITING] != 0.0 ||
              (lead.present && driver_demand(view, d, e) > d[D_FOLLOW_ACCELERATION] + resistance(view, e->v));
    return changed;
}

/* Inputs.sample_driver: integrate over the period (none at the start), new steer and, unless BRK holds them, new
 * pedals. */
static void sample_driver(const View *view, double *d, const Ego *e, int integrate) {
    double throttle, brake;
    if (d[D_BRK_ACTIVE] == 0.0) {
        if (integrate) driver_update(view, d, e, PARAMETER(view, DRIVER_PERIOD), d[D_THROTTLE]);
        driver_pedals(view, d, e, &throttle, &brake);
    } else {
        throttle = d[D_THROTTLE];
        brake = d[D_BRAKE];
    }
    d[D_THROTTLE] = throttle;
    d[D_BRAKE] = brake;
    d[D_STEER] = driver_steer(view, e);
}

/* Inputs.apply: BRK's pedals while it holds them. */
static void apply_brake_hold(const View *view, double *d) {
    if (d[D_BRK_ACTIVE] != 0.0) {
        d[D_THROTTLE] = 0.0;
        d[D_BRAKE] = event_at(view, (int)d[D_BRK_EVENT])[BRK_PEDAL];
    }
}

/* ---- the log ---------------------------------------------------------------------------------------------------- */

static const char *const CODE_NAMES[] = {"", "A", "BRK", "RSA", "ES"};
static const char *const ACTION_NAMES[] = {"", "spawn", "maneuver", "collision", "despawn", "on", "off", "set", "end"};
static const char *const REASON_NAMES[] = {"", "time", "distance", "velocity", "relative_velocity", "stopped", "end"};
static const char *const END_NAMES[] = {"", "scenario", "until_distance", "until_time", "runout", "time_limit",
                                        "collision"};
static const char *const THRESHOLD_NAMES[] = {"time", "distance", "velocity", "relative_velocity"};

/* One entry of summary.json's events: counted, shown in the last_event_* outputs, logged (category logEvents). */
static void log_event(double *d, const Logger *log, const Ego *e, int code, int action, int vehicle_id, int line,
                      const char *detail) {
    d[D_EVENTS] += 1.0;
    d[D_LAST_CODE] = code;
    d[D_LAST_ACTION] = action;
    d[D_LAST_VEHICLE] = vehicle_id;
    d[D_LAST_LINE] = line;
    d[D_LAST_TIME] = e->time;
    if (log == NULL || log->instance == NULL) return;
    instance_log(log->instance, STATUS_OK, "logEvents",
                 "t = %.17g s, s = %.17g m, v = %.17g m/s: %s %s%s%s (line %d); events %.0f, collisions %.0f", e->time,
                 e->s, e->v, CODE_NAMES[code], ACTION_NAMES[action], detail[0] ? " " : "", detail, line,
                 d[D_EVENTS], d[D_COLLISIONS]);
}

static void log_warning(const Logger *log, const char *message, int line) {
    if (log == NULL || log->instance == NULL) return;
    instance_log(log->instance, STATUS_WARNING, "logStatusWarning", "line %d: %s", line, message);
}

/* ---- what happens at an instant (master.py) --------------------------------------------------------------------- */

static void release_brakes(const View *view, double *d, const Ego *e, int reason, const Logger *log) {
    char detail[64];
    double throttle, brake;
    snprintf(detail, sizeof(detail), "reason %s", REASON_NAMES[reason]);
    log_event(d, log, e, CODE_BRK, ACTION_OFF, 0, (int)event_at(view, (int)d[D_BRK_EVENT])[E_LINE], detail);
    d[D_BRK_ACTIVE] = 0.0;
    d[D_INTEGRAL] = 0.0; /* driver.reset_integral */
    driver_pedals(view, d, e, &throttle, &brake);
    d[D_THROTTLE] = throttle;
    d[D_BRAKE] = brake;
}

static void finish(const View *view, double *d, const Ego *e, int reason, const Logger *log) {
    char detail[64];
    if (d[D_FINISHED] != 0.0) return;
    if (d[D_BRK_ACTIVE] != 0.0) release_brakes(view, d, e, REASON_END, log);
    snprintf(detail, sizeof(detail), "reason %s", END_NAMES[reason]);
    log_event(d, log, e, CODE_ES, ACTION_END, 0, 0, detail);
    d[D_FINISHED] = 1.0;
    d[D_END_REASON] = reason;
}

static void spawn(const View *view, double *d, const Ego *e, const double *event, const Logger *log) {
    int i = (int)d[D_SPAWNED], k;
    double *vh = vehicle(view, d, i), speed, lateral;
    char detail[160];
    speed = resolve(event[A_SPEED], event[A_SPEED_RELATIVE], e->v);
    lateral = resolve(event[A_LATERAL], event[A_LATERAL_RELATIVE], -e->y);
    vh[V_T0] = e->time;
    vh[V_STATION0] = e->x + event[A_GAP];
    vh[V_LATERAL0] = lateral;
    vh[V_SPEED0] = speed;
    if (event[A_INITIAL] != 0.0) { /* _initial_transition: a transition from the spawn */
        vh[V_LATERAL1] = resolve(event[A_INITIAL_LATERAL], event[A_INITIAL_LATERAL_RELATIVE], -e->y);
        vh[V_SPEED1] = resolve(event[A_INITIAL_SPEED], event[A_INITIAL_SPEED_RELATIVE], e->v);
        vh[V_DURATION] = event[A_INITIAL_DURATION];
    } else {
        vh[V_LATERAL1] = lateral;
        vh[V_SPEED1] = speed;
        vh[V_DURATION] = 0.0;
    }
    vh[V_NEXT_ACTION] = 0.0;
    vh[V_IN_CONTACT] = 0.0;
    vh[V_PRESENT] = 1.0;
    vh[V_SLOT] = -1.0;
    for (k = 0; k < view->n_slots; k++) /* the lowest free traffic slot */
        if (d[D_HEADER + k] == 0.0) {
            d[D_HEADER + k] = i + 1;
            vh[V_SLOT] = k;
            break;
        }
    d[D_SPAWNED] = i + 1;
    d[D_ACTIVE] += 1.0;
    snprintf(detail, sizeof(detail), "vehicle %d (model %d%s%s)", i + 1, (int)event[A_MODEL],
             log && log->model_names && log->model_names[i] ? " " : "",
             log && log->model_names && log->model_names[i] ? log->model_names[i] : "");
    log_event(d, log, e, CODE_A, ACTION_SPAWN, i + 1, (int)event[E_LINE], detail);
}

static void fire_event(const View *view, double *d, const Ego *e, int k, int *end, const Logger *log) {
    const double *event = event_at(view, k);
    int code = (int)event[E_CODE], line = (int)event[E_LINE];
    char detail[96];
    if (code == CODE_A) {
        spawn(view, d, e, event, log);
    } else if (code == CODE_BRK) {
        if (PARAMETER(view, BRK_ACTS) == 0.0) {
            log_warning(log, "BRK ignored: brake events act only with simple dynamics", line);
        } else if (d[D_BRK_ACTIVE] != 0.0) {
            char message[96];
            snprintf(message, sizeof(message), "BRK ignored: the brake event of line %d is still on",
                     (int)event_at(view, (int)d[D_BRK_EVENT])[E_LINE]);
            log_warning(log, message, line);
        } else {
            d[D_BRK_ACTIVE] = 1.0;
            d[D_BRK_EVENT] = k;
            d[D_BRK_TIME_ON] = e->time;
            d[D_BRK_DISTANCE_ON] = e->s;
            d[D_BRK_SPEED_ON] = e->v;
            snprintf(detail, sizeof(detail), "pedal %g %%, threshold %s %g", event[BRK_PEDAL] * 100,
                     THRESHOLD_NAMES[(int)event[BRK_THRESHOLD]], event[BRK_MAGNITUDE]);
            log_event(d, log, e, CODE_BRK, ACTION_ON, 0, line, detail);
        }
    } else if (code == CODE_RSA) {
        int n = (int)event[RSA_COUNT], j;
        for (j = 0; j < n; j++) {
            snprintf(detail, sizeof(detail), "lane %d value %g", (int)event[RSA_SETTINGS + 2 * j],
                     event[RSA_SETTINGS + 2 * j + 1]);
            log_event(d, log, e, CODE_RSA, ACTION_SET, 0, line, detail);
        }
    } else if (code == CODE_ES) {
        *end = END_SCENARIO;
    }
}

/* Traffic.start_action: the armed action fires, a new transition from where the vehicle is now. */
static void start_action(const View *view, double *d, int i, const Ego *e) {
    double *vh = vehicle(view, d, i), station, lateral, speed;
    const double *action = armed(view, d, i);
    motion_at(vh, e->time, &station, &lateral, &speed);
    vh[V_T0] = e->time;
    vh[V_STATION0] = station;
    vh[V_LATERAL0] = lateral;
    vh[V_SPEED0] = speed;
    vh[V_LATERAL1] = resolve(action[ACT_LATERAL], action[ACT_LATERAL_RELATIVE], -e->y);
    vh[V_SPEED1] = resolve(action[ACT_SPEED], action[ACT_SPEED_RELATIVE], e->v);
    vh[V_DURATION] = action[ACT_DURATION];
    vh[V_NEXT_ACTION] += 1.0;
}

/* Cosimulation.fire_traffic: actions (each once, the next armed as one fires), then the contacts, then the
 * departures, each in the order of the vehicles' ids. */
static void fire_traffic(const View *view, double *d, const Ego *e, const Logger *log) {
    Kinematics kin = kinematics_of(e);
    int n = (int)d[D_SPAWNED], i, contacts = 0;
    char detail[64];
    for (i = 0; i < n; i++) {
        double *vh = vehicle(view, d, i);
        if (vh[V_PRESENT] == 0.0 || !vehicle_condition(view, d, i, &kin).due) continue;
        for (;;) {
            int index = (int)vh[V_NEXT_ACTION] + 1;
            start_action(view, d, i, e);
            snprintf(detail, sizeof(detail), "vehicle %d, action %d", i + 1, index);
            log_event(d, log, e, CODE_A, ACTION_MANEUVER, i + 1, (int)vehicle_event(view, i)[E_LINE], detail);
            if (!vehicle_condition(view, d, i, &kin).due) break;
        }
    }
    for (i = 0; i < n; i++) { /* contacts, with the motions after the actions; departures marked (present 2) */
        double *vh = vehicle(view, d, i);
        Conditions c;
        if (vh[V_PRESENT] == 0.0) continue;
        c = vehicle_condition(view, d, i, &kin);
        if (c.overlap && vh[V_IN_CONTACT] == 0.0) {
            d[D_COLLISIONS] += 1.0;
            contacts++;
            snprintf(detail, sizeof(detail), "vehicle %d", i + 1);
            log_event(d, log, e, CODE_A, ACTION_COLLISION, i + 1, (int)vehicle_event(view, i)[E_LINE], detail);
        }
        vh[V_IN_CONTACT] = c.overlap ? 1.0 : 0.0;
        if (c.away && !c.overlap) vh[V_PRESENT] = 2.0;
    }
    if (contacts > 0 && PARAMETER(view, ON_COLLISION_STOP) != 0.0) finish(view, d, e, END_COLLISION, log);
    for (i = 0; i < n; i++) { /* Traffic.remove: off the road, its slot freed */
        double *vh = vehicle(view, d, i);
        if (vh[V_PRESENT] != 2.0) continue;
        vh[V_PRESENT] = 0.0;
        d[D_ACTIVE] -= 1.0;
        if (vh[V_SLOT] >= 0.0) d[D_HEADER + (int)vh[V_SLOT]] = 0.0;
        vh[V_SLOT] = -1.0;
        snprintf(detail, sizeof(detail), "vehicle %d", i + 1);
        log_event(d, log, e, CODE_A, ACTION_DESPAWN, i + 1, (int)vehicle_event(view, i)[E_LINE], detail);
    }
}

/* Cosimulation.fire_due: everything due at this state, in file order, until nothing more is due. */
static void fire_due(const View *view, double *d, const Ego *e, const Logger *log) {
    int end = END_NONE, reason;
    while (d[D_FINISHED] == 0.0 && (int)d[D_NEXT_EVENT] < view->n_events &&
           event_at(view, (int)d[D_NEXT_EVENT])[E_DISTANCE] <= e->s) {
        int k = (int)d[D_NEXT_EVENT];
        d[D_NEXT_EVENT] = k + 1;
        fire_event(view, d, e, k, &end, log);
        if (end != END_NONE) finish(view, d, e, end, log);
    }
    if (d[D_BRK_ACTIVE] != 0.0 && (reason = release_reason(view, d, e)) != REASON_NONE)
        release_brakes(view, d, e, reason, log);
    if (d[D_ACTIVE] > 0.0) fire_traffic(view, d, e, log);
    if (e->s >= end_distance(view, &reason)) finish(view, d, e, reason, log);
}

/* ---- triggers on a state (the prediction's probes) -------------------------------------------------------------- */

/* TriggerSchedule.triggered over every kind: whether something is due at this state (all are false after fire_due). */
static int triggered(const View *view, const double *d, const Ego *e) {
    int reason, i, n = (int)d[D_SPAWNED];
    Kinematics kin;
    if (d[D_FINISHED] != 0.0) return 0;
    if ((int)d[D_NEXT_EVENT] < view->n_events && event_at(view, (int)d[D_NEXT_EVENT])[E_DISTANCE] <= e->s) return 1;
    if (e->s >= end_distance(view, &reason)) return 1;
    if (d[D_BRK_ACTIVE] != 0.0 && release_reason(view, d, e) != REASON_NONE) return 1;
    if (d[D_ACTIVE] == 0.0) return 0;
    kin = kinematics_of(e);
    for (i = 0; i < n; i++) {
        const double *vh = vehicle_const(view, d, i);
        Conditions c;
        int in_contact;
        if (vh[V_PRESENT] == 0.0) continue;
        c = vehicle_condition(view, d, i, &kin);
        in_contact = vh[V_IN_CONTACT] != 0.0;
        if (c.due || c.overlap != in_contact || (c.away && !in_contact)) return 1;
    }
    return 0;
}

/* TriggerSchedule.horizons: a lower bound on the instant any trigger could become true (absolute time), for an
 * ego whose distance travelled grows at s_rate (its speed, for the belief plus its fading offset's rate) and whose
 * heading turns at most at yaw_rate. */
static double horizon(const View *view, const double *d, const Ego *e, double s_rate, double yaw_rate) {
    double a = PARAMETER(view, EGO_MAX_ACCELERATION), bound = INFINITY, candidate, distance;
    int reason, i, n = (int)d[D_SPAWNED];
    if ((int)d[D_NEXT_EVENT] < view->n_events) {
        candidate = e->time + reach_time(event_at(view, (int)d[D_NEXT_EVENT])[E_DISTANCE] - e->s, s_rate, a);
        if (candidate < bound) bound = candidate;
    }
    distance = end_distance(view, &reason);
    if (distance < INFINITY) {
        candidate = e->time + reach_time(distance - e->s, s_rate, a);
        if (candidate < bound) bound = candidate;
    }
    if (d[D_BRK_ACTIVE] != 0.0) {
        candidate = earliest_release(view, d, e, s_rate, a);
        if (candidate < bound) bound = candidate;
    }
    if (d[D_ACTIVE] > 0.0) {
        Kinematics kin = kinematics_of(e);
        for (i = 0; i < n; i++) {
            if (vehicle_const(view, d, i)[V_PRESENT] == 0.0) continue;
            candidate = e->time + vehicle_horizon(view, d, i, &kin, yaw_rate);
            if (candidate < bound) bound = candidate;
        }
    }
    return bound;
}

/* ---- the belief of the ego's path over a step ------------------------------------------------------------------- */

typedef struct {
    double t, h, end;          /* the step: from t, h long, to end = t + h */
    Ego e;                     /* the ego's inputs at t */
    double xd, yd, xdd, ydd;   /* world-frame velocity and acceleration at t */
    double vdot, tau_stop;     /* rate of the speed; when the prediction comes to rest (inf: not in reach) */
    double offset[4];          /* the belief's offset from the inputs at t (x, y, psi, s), fading to 0 at t + h */
    double drift[4];           /* the fading offset's rate over the step: -offset / h (m/s, m/s, rad/s, m/s) */
    int stopped_connected;
} Prediction;

static void prediction_make(Prediction *pr, const View *view, const Ego *e, const double *belief, double t, double h) {
    double c = cos(e->psi), s = sin(e->psi);
    int k;
    pr->t = t;
    pr->h = h;
    pr->end = t + h;
    pr->e = *e;
    pr->xd = e->vx * c - e->vy * s;
    pr->yd = e->vx * s + e->vy * c;
    pr->xdd = e->ax * c - e->ay * s;
    pr->ydd = e->ax * s + e->ay * c;
    pr->vdot = e->v > 0 ? (e->vx * e->ax + e->vy * e->ay) / e->v : e->ax;
    pr->tau_stop = pr->vdot < 0 ? (e->v > 0 ? e->v / -pr->vdot : 0.0) : INFINITY;
    pr->offset[0] = belief[EGO_X] - e->x;
    pr->offset[1] = belief[EGO_Y] - e->y;
    pr->offset[2] = belief[EGO_PSI] - e->psi;
    pr->offset[3] = belief[EGO_S] - e->s;
    for (k = 0; k < 4; k++) pr->drift[k] = -pr->offset[k] / h;
    pr->stopped_connected = PARAMETER(view, EGO_STOPPED_CONNECTED) != 0.0;
}

/* The belief at the absolute time `time` in [t, t + h] (up to a tie's tolerance after it). Its body-frame velocity
 * is its path's derivative over the step (the fading offset's rate included; at t + h and after it the derivative
 * from the left, so that no rounding of `time` decides whether the offset's rate counts) turned into its heading:
 * the station and lateral rates the trigger bounds start from are then the rates of the position they bound
 * (docs/scenario-fmu.md, Stepping, the bound's proof). */
static void predict(const Prediction *pr, double time, Ego *b) {
    const Ego *e = &pr->e;
    /* at the step's end exactly h and a faded offset, whatever the rounding of (t + h) - t: the state a step hands
     * on does not depend on where the master's clock puts t */
    double tau = time == pr->end ? pr->h : time - pr->t, moving = tau < pr->tau_stop ? tau : pr->tau_stop;
    double fade = pr->h > 0 ? (pr->end - time) / pr->h : 0.0, x_rate, y_rate, c, s;
    int at_rest = tau >= pr->tau_stop;
    if (fade < 0.0) fade = 0.0;
    b->time = time;
    b->x = e->x + pr->xd * moving + pr->xdd * moving * moving / 2 + pr->offset[0] * fade;
    b->y = e->y + pr->yd * moving + pr->ydd * moving * moving / 2 + pr->offset[1] * fade;
    b->psi = e->psi + e->yaw_rate * moving + pr->offset[2] * fade;
    b->s = e->s + e->v * moving + pr->vdot * moving * moving / 2 + pr->offset[3] * fade;
    x_rate = (at_rest ? 0.0 : pr->xd + pr->xdd * tau) + pr->drift[0];
    y_rate = (at_rest ? 0.0 : pr->yd + pr->ydd * tau) + pr->drift[1];
    c = cos(b->psi);
    s = sin(b->psi);
    b->vx = x_rate * c + y_rate * s;
    b->vy = y_rate * c - x_rate * s;
    if (at_rest) { /* come to rest: held there (but for the fading offset) */
        b->v = b->yaw_rate = b->ax = b->ay = 0.0;
        b->stopped = 1;
        return;
    }
    b->v = e->v + pr->vdot * tau;
    b->yaw_rate = e->yaw_rate;
    b->ax = e->ax;
    b->ay = e->ay;
    b->stopped = pr->stopped_connected ? e->stopped : fabs(b->v) < STOPPED_SPEED;
}

/* ---- the steps -------------------------------------------------------------------------------------------------- */

/* How close after a communication point t an instant still belongs to the step that ends at t: a driver sample, a
 * trigger's located instant, an end by time (docs/scenario-fmu.md, Stepping, ties). */
static double time_tolerance(double t) { return TIE_TOLERANCE * (fabs(t) > 1.0 ? fabs(t) : 1.0); }

/* ---- the sample clocks (clocks.py): the driver every driver_period, the follow driver's decisions every
 * REACTION_TIME, each at k x its period from the start  */

static double clock_instant(const View *view, double k, double period) {
    return view->p[HIDDEN_START_TIME] + k * period;
}

/* SampleClocks.earliest: the next instant any clock samples at. */
static double sample_time(const View *view, const double *d) {
    double driver = clock_instant(view, d[D_SAMPLE], PARAMETER(view, DRIVER_PERIOD)), follow;
    if (!following(view)) return driver;
    follow = clock_instant(view, d[D_FOLLOW_K], REACTION_TIME);
    return follow < driver ? follow : driver;
}

/* SampleClocks.due at the clocks' instant `nominal` (>= the earliest) and Inputs.sample, with the ego at it: every
 * clock due within MERGE samples once and moves past it; the follow driver decides first, then the driver samples
 * (a decision that changes the pedals acts at once between driver samples). */
static void sample_clocks(const View *view, double *d, const Ego *e, double nominal) {
    double limit = nominal + MERGE, period = PARAMETER(view, DRIVER_PERIOD), k;
    int changed = 0, driver_due = clock_instant(view, d[D_SAMPLE], period) <= limit;
    if (following(view) && clock_instant(view, d[D_FOLLOW_K], REACTION_TIME) <= limit) {
        for (k = d[D_FOLLOW_K] + 1; clock_instant(view, k, REACTION_TIME) <= limit; k += 1.0) continue;
        d[D_FOLLOW_K] = k;
        changed = follow_decide(view, d, e);
    }
    if (driver_due) {
        for (k = d[D_SAMPLE] + 1; clock_instant(view, k, period) <= limit; k += 1.0) continue;
        d[D_SAMPLE] = k;
        sample_driver(view, d, e, 1);
    } else if (changed && d[D_BRK_ACTIVE] == 0.0) {
        double throttle, brake;
        driver_pedals(view, d, e, &throttle, &brake);
        d[D_THROTTLE] = throttle;
        d[D_BRAKE] = brake;
    }
}

static void warn_bounds(const View *view, double *d, const Ego *e, const Logger *log) {
    double a = PARAMETER(view, EGO_MAX_ACCELERATION), r = PARAMETER(view, EGO_MAX_YAW_RATE);
    if (d[D_BOUNDS_WARNED] != 0.0 || !(fabs(e->yaw_rate) > r || hypot(e->ax, e->ay) > a)) return;
    d[D_BOUNDS_WARNED] = 1.0;
    if (log != NULL && log->instance != NULL)
        instance_log(log->instance, STATUS_WARNING, "logStatusWarning",
                     "at t = %.3f s the ego's yaw rate (%.3g rad/s) or acceleration (%.3g m/s2) exceeded the bounds "
                     "the trigger prediction assumes (ego_max_yaw_rate %.3g rad/s, ego_max_acceleration %.3g m/s2): "
                     "later triggers may be located late; use a shorter communication step",
                     e->time, e->yaw_rate, hypot(e->ax, e->ay), r, a);
}

/* After what fired at an instant: the run's end by time, the samples due (with `sampling`, at the clocks' instant
 * `nominal`), BRK's pedals, the time limit (Cosimulation.run's order). */
static void after_instant(const View *view, double *d, const Ego *e, int sampling, double nominal,
                          const Logger *log) {
    double until = PARAMETER(view, UNTIL_TIME);
    if (d[D_FINISHED] == 0.0 && until > 0.0 && e->time >= until) finish(view, d, e, END_UNTIL_TIME, log);
    if (sampling) sample_clocks(view, d, e, nominal);
    apply_brake_hold(view, d);
    if (d[D_FINISHED] == 0.0 && e->time >= MAX_TIME) finish(view, d, e, END_TIME_LIMIT, log);
}

void scenario_begin(const View *view, const double *u, double *d, const Logger *log) {
    double t0 = view->p[HIDDEN_START_TIME];
    Ego e;
    memset(d, 0, sizeof(double) * state_size(view));
    d[D_TIME] = t0;
    d[D_SAMPLE] = 1.0;
    d[D_MEMORY + MEM_TIME] = t0;
    d[D_MEMORY + MEM_V] = u[U_EGO_V];
    d[D_MEMORY + MEM_PSI] = u[U_EGO_PSI];
    d[D_MEMORY + MEM_S] = PARAMETER(view, EGO_S_CONNECTED) != 0.0 ? u[U_EGO_S] : 0.0;
    d[D_MEMORY + MEM_YAW_RATE] = 0.0;
    d[D_FOLLOW_K] = 1.0;
    ego_from_inputs(view, u, d + D_MEMORY, t0, &e);
    fire_due(view, d, &e, log);
    if (following(view)) follow_decide(view, d, &e); /* the first samples (k = 0): no integration */
    sample_driver(view, d, &e, 0);
    apply_brake_hold(view, d);
    ego_store(d + D_EGO, &e);
    d[D_STARTED] = 1.0;
    d[D_START_PENDING] = 1.0;
}

/* Without prediction: the communication point t is evaluated with the ego's inputs there, as `sdl-fmu run`
 * evaluates its samples; every driver sample due by t (k * driver_period <= t) is taken there. */
static void step_at_points(const View *view, const double *u, double *d, double t, double h, const Logger *log) {
    Ego e;
    ego_from_inputs(view, u, d + D_MEMORY, t, &e);
    if (d[D_FINISHED] == 0.0) fire_due(view, d, &e, log);
    /* the samples due at the first communication point at or after their instant, as the run takes them */
    after_instant(view, d, &e, sample_time(view, d) <= t, t, log);
    ego_store(d + D_EGO, &e);
    d[D_TIME] = t + h;
}

static double bisect(const View *view, const double *d, const Prediction *pr, double low, double high) {
    Ego b;
    while (high - low > TRIGGER_TOLERANCE) {
        double middle = 0.5 * (low + high);
        predict(pr, middle, &b);
        if (triggered(view, d, &b))
            high = middle;
        else
            low = middle;
    }
    return high;
}

static int over_budget(long *probes, double tau, const Logger *log) {
    if (++*probes <= MAX_PROBES_PER_STEP) return 0;
    if (log != NULL && log->instance != NULL)
        instance_log(log->instance, STATUS_ERROR, "logStatusError",
                     "doStep exceeded its budget of %ld looks at the predicted path at t = %.17g",
                     (long)MAX_PROBES_PER_STEP, tau);
    return 1;
}

/* Ties: what becomes true within time_tolerance(end) after the step's end belongs to this step, as a driver sample
 * there does (docs/scenario-fmu.md, Stepping: masters form their communication points with different rounding, so
 * an instant on a communication point would otherwise fall into one step in one master and into the next in
 * another). Fired at its located instant on the belief (triggers bisected, the ends by time at theirs), in time
 * order. Writes the last instant something fired at (end if nothing did) to `last`; returns -1 on the budget, else
 * 0. */
static int step_ties(const View *view, double *d, const Prediction *pr, double end, long *probes, const Logger *log,
                     double *last) {
    double reach = end + time_tolerance(end), until = PARAMETER(view, UNTIL_TIME), tau = end;
    Ego b;
    while (d[D_FINISHED] == 0.0) {
        double at = reach;
        if (until > 0.0 && until > tau && until < at) at = until;
        if (MAX_TIME > tau && MAX_TIME < at) at = MAX_TIME;
        predict(pr, at, &b);
        if (triggered(view, d, &b)) {
            at = bisect(view, d, pr, tau, at);
            predict(pr, at, &b);
            fire_due(view, d, &b, log);
        } else if (!((until > 0.0 && at >= until) || at >= MAX_TIME)) {
            break; /* nothing more in the window */
        }
        after_instant(view, d, &b, 0, 0.0, log); /* the ends by time, BRK's pedals */
        tau = at;
        if (over_budget(probes, tau, log)) return -1;
    }
    *last = tau;
    return 0;
}

/* With prediction: the triggers located on the belief over (t, t + h], fired there; the driver samples there. The
 * search starts at the state's own time when a tie put it a hair past t (the conditions were evaluated there). */
static int step_predicted(const View *view, const double *u, double *d, double t, double h, int early_return,
                          const Logger *log, double *reached) {
    double end = t + h, tau = t, until = PARAMETER(view, UNTIL_TIME), yaw_rate_bound, last;
    long probes = 0;
    Prediction pr;
    Ego actual, b;
    ego_from_inputs(view, u, d + D_MEMORY, t, &actual);
    warn_bounds(view, d, &actual, log);
    prediction_make(&pr, view, &actual, d + D_EGO, t, h);
    if (d[D_TIME] > t && d[D_TIME] - t <= 3 * time_tolerance(t)) tau = d[D_TIME]; /* after a tie */
    /* the belief turns at the ego's yaw rate plus its fading offset's: the bounds take both (its position's rates
     * are its velocity's by construction, its distance's rate is its speed plus the fading offset's, below) */
    yaw_rate_bound = PARAMETER(view, EGO_MAX_YAW_RATE) + fabs(pr.drift[2]);
    while (tau < end) {
        double limit = end, sample_at = INFINITY, next = sample_time(view, d), probe;
        int fired = 0;
        if (next <= end + time_tolerance(end)) sample_at = next < end ? next : end;
        if (sample_at < limit) limit = sample_at;
        if (d[D_FINISHED] == 0.0) { /* the run's ends by time are instants it steps to */
            if (until > 0.0 && until > tau && until < limit) limit = until;
            if (MAX_TIME > tau && MAX_TIME < limit) limit = MAX_TIME;
        }
        if (limit < tau) limit = tau;
        probe = limit;
        if (d[D_FINISHED] == 0.0) {
            double earliest;
            predict(&pr, tau, &b);
            earliest = horizon(view, d, &b, b.v + pr.drift[3], yaw_rate_bound);
            if (earliest - tau >= MIN_LOOKAHEAD || earliest >= limit) {
                /* nothing can become true before `earliest`; something may be true exactly at it */
                probe = earliest < limit ? earliest : limit;
                if (earliest <= probe) {
                    predict(&pr, probe, &b);
                    fired = triggered(view, d, &b);
                }
            } else {
                probe = tau + MIN_LOOKAHEAD < limit ? tau + MIN_LOOKAHEAD : limit;
                predict(&pr, probe, &b);
                fired = triggered(view, d, &b);
                if (fired) probe = bisect(view, d, &pr, tau, probe);
            }
        }
        tau = probe;
        predict(&pr, tau, &b);
        if (fired) fire_due(view, d, &b, log);
        after_instant(view, d, &b, tau >= sample_at, next, log);
        if (over_budget(&probes, tau, log)) return -1;
        if (fired && early_return && tau < end) { /* FMI 3.0 early return at the instant something fired */
            ego_store(d + D_EGO, &b);
            d[D_TIME] = tau;
            *reached = tau;
            return 1;
        }
    }
    if (step_ties(view, d, &pr, end, &probes, log, &last) < 0) return -1;
    /* the state at the last instant it was evaluated at (end, or a tie's instant a hair after it) */
    predict(&pr, last, &b);
    ego_store(d + D_EGO, &b);
    d[D_TIME] = last;
    *reached = end;
    return 0;
}

/* The first doStep takes the start again from its inputs: a master may have passed the ego's outputs on in
 * initialization mode before the ego filled them (docs/scenario-fmu.md, Wiring); the start's events are logged here,
 * once. Unchanged inputs give the same start bit for bit (scenario_begin is a function of the inputs). */
static void take_start(const View *view, const double *u, double *d, const Logger *log) {
    double before[EGO_FIELDS];
    int k, changed = 0;
    memcpy(before, d + D_EGO, sizeof(before));
    scenario_begin(view, u, d, log);
    d[D_START_PENDING] = 0.0;
    for (k = 0; k < EGO_FIELDS; k++) changed |= before[k] != d[D_EGO + k];
    if (changed && log != NULL && log->instance != NULL)
        instance_log(log->instance, STATUS_WARNING, "logStatusWarning",
                     "the ego's inputs changed between initialization and the first step (speed %.6g -> %.6g m/s, "
                     "y %.6g -> %.6g m): the start is taken from those of the first step; the outputs read in "
                     "initialization mode came from the earlier ones", before[EGO_V], d[D_EGO + EGO_V], before[EGO_Y],
                     d[D_EGO + EGO_Y]);
}

int scenario_step(const View *view, const double *u, double *d, double t, double h, int early_return,
                  const Logger *log, double *reached) {
    if (d[D_START_PENDING] != 0.0) take_start(view, u, d, log);
    if (PARAMETER(view, TRIGGER_PREDICTION) != 0.0)
        return step_predicted(view, u, d, t, h, early_return, log, reached);
    step_at_points(view, u, d, t, h, log);
    *reached = t + h;
    return 0;
}

int scenario_check_step(const View *view, double h, char *reason, size_t reason_size) {
    double period = PARAMETER(view, DRIVER_PERIOD);
    if (h / period > MAX_SAMPLES_PER_STEP) {
        snprintf(reason, reason_size,
                 "a step of %g s holds %.3g driver samples of driver_period = %g s, more than the budget of %.0f per "
                 "doStep: split the step", h, h / period, period, MAX_SAMPLES_PER_STEP);
        return 1;
    }
    return 0;
}

/* ---- outputs ---------------------------------------------------------------------------------------------------- */

/* Road.lane_at: the lane under a lateral position (+ right); beyond the outer lanes the shoulder. */
static int lane_at(const View *view, double lateral) {
    double k;
    if (lateral >= 0) {
        k = floor(lateral / view->lane_width) + 1;
        return k <= view->lanes_right ? (int)k : RIGHT_SHOULDER;
    }
    k = floor(-lateral / view->lane_width) + 1;
    return k <= view->lanes_left ? -(int)k : LEFT_SHOULDER;
}

/* SurfaceMap.value: the value set on a lane at the largest start <= station (bisect_right), else the default. */
static double surface_value(const View *view, int lane, double station, double default_value) {
    int index = (int)view->lane_index[lane + RIGHT_SHOULDER], low = 0, high;
    const double *record, *starts;
    if (index < 0) return default_value;
    record = view->surfaces + (size_t)index * SL_SIZE;
    high = (int)record[SL_COUNT];
    starts = view->data + (size_t)record[SL_STARTS];
    while (low < high) { /* the first start > station */
        int middle = (low + high) / 2;
        if (station < starts[middle])
            high = middle;
        else
            low = middle + 1;
    }
    return low > 0 ? view->data[(size_t)record[SL_VALUES] + (size_t)(low - 1)] : default_value;
}

static double pedal(double value) { return value < 0.0 ? 0.0 : value > 1.0 ? 1.0 : value; }

/* arbitration.arbitrate: the commands from the driver's (or BRK's) and the controller's requests, per channel
 * (driver: the request ignored; override: the request; max: the larger, pedals only). The brake request is the larger
 * of the brake pedal and the deceleration / brake_decel_max; while it counts and is above zero the throttle is 0. */
static void arbitrate(const View *view, const double *u, double *throttle, double *brake, double *steer) {
    int rule = (int)PARAMETER(view, ARBITRATION_BRAKE);
    double wanted = 0.0;
    int counted = 0;
    if (!(u[U_REQUEST_ACTIVE] > 0.5)) return;
    if (rule != ARBITRATION_DRIVER) {
        double from_deceleration = u[U_REQUEST_DECELERATION] / PARAMETER(view, EGO_BRAKE_DECEL_MAX), value;
        wanted = from_deceleration > u[U_REQUEST_BRAKE] ? from_deceleration : u[U_REQUEST_BRAKE];
        counted = 1;
        value = pedal(wanted);
        if (rule == ARBITRATION_OVERRIDE || value > *brake) *brake = value;
    }
    rule = (int)PARAMETER(view, ARBITRATION_THROTTLE);
    if (rule != ARBITRATION_DRIVER) {
        double value = pedal(u[U_REQUEST_THROTTLE]);
        if (rule == ARBITRATION_OVERRIDE || value > *throttle) *throttle = value;
    }
    if (counted && wanted > 0.0) *throttle = 0.0;
    if ((int)PARAMETER(view, ARBITRATION_STEER) == ARBITRATION_OVERRIDE) {
        double value = u[U_REQUEST_STEER];
        *steer = value < -MAX_STEER ? -MAX_STEER : value > MAX_STEER ? MAX_STEER : value;
    }
}

#define PI 3.14159265358979323846

void scenario_outputs(const View *view, const double *u, const double *d, double *y) {
    Ego e;
    double time = d[D_TIME], cos_psi, sin_psi, throttle, brake, steer, mu[4];
    double front = PARAMETER(view, EGO_CG_TO_FRONT_AXLE), rear = PARAMETER(view, EGO_CG_TO_REAR_AXLE);
    double half_front = PARAMETER(view, EGO_TRACK_FRONT) / 2, half_rear = PARAMETER(view, EGO_TRACK_REAR) / 2;
    double along_wheel[4], left_wheel[4];
    int i, w;
    if (PARAMETER(view, TRIGGER_PREDICTION) != 0.0)
        ego_load(&e, d + D_EGO, time);
    else
        ego_of_inputs(view, u, d, &e);

    /* the commands: the driver's (BRK's) and after arbitration */
    throttle = d[D_THROTTLE];
    brake = d[D_BRAKE];
    steer = d[D_STEER];
    y[Y_DRIVER_THROTTLE] = throttle;
    y[Y_DRIVER_BRAKE] = brake;
    y[Y_DRIVER_STEER] = steer;
    arbitrate(view, u, &throttle, &brake, &steer);
    y[Y_THROTTLE] = throttle;
    y[Y_BRAKE] = brake;
    y[Y_STEER] = steer;

    /* the surfaces under the wheels (WheelGeometry.contact_points, wheel_surfaces) */
    cos_psi = cos(e.psi);
    sin_psi = sin(e.psi);
    along_wheel[0] = along_wheel[1] = front;
    along_wheel[2] = along_wheel[3] = -rear;
    left_wheel[0] = half_front;
    left_wheel[1] = -half_front;
    left_wheel[2] = half_rear;
    left_wheel[3] = -half_rear;
    for (w = 0; w < 4; w++) {
        double station = e.x + along_wheel[w] * cos_psi - left_wheel[w] * sin_psi;
        double lateral = -(e.y + along_wheel[w] * sin_psi + left_wheel[w] * cos_psi);
        int lane = lane_at(view, lateral);
        mu[w] = surface_value(view, lane, station, DEFAULT_MU_SURFACE) / 10;
        y[Y_MU_FL + w] = mu[w];
        y[Y_SURFACE_FL + w] = trunc(surface_value(view, lane, station, DEFAULT_ATTRIBUTE));
    }
    y[Y_MU_FRONT] = (mu[0] + mu[1]) / 2;
    y[Y_MU_REAR] = (mu[2] + mu[3]) / 2;
    y[Y_MU_MEAN] = (((mu[0] + mu[1]) + mu[2]) + mu[3]) / 4;

    /* the lead vehicle (signals.lead_vehicle) */
    {
        Lead lead = lead_of(view, d, &e, time);
        y[Y_LEAD_PRESENT] = lead.present;
        y[Y_LEAD_ID] = lead.id;
        y[Y_LEAD_GAP] = lead.gap;
        y[Y_LEAD_SPEED] = lead.speed;
        y[Y_LEAD_RELATIVE_SPEED] = lead.relative_speed;
        y[Y_LEAD_TTC] = lead.ttc;
        y[Y_LEAD_LATERAL_OFFSET] = lead.lateral_offset;
    }

    y[Y_COLLISIONS] = d[D_COLLISIONS];
    y[Y_EVENTS] = d[D_EVENTS];
    y[Y_ENDED] = d[D_FINISHED];
    y[Y_END_REASON] = d[D_END_REASON];
    y[Y_BRK_ACTIVE] = d[D_BRK_ACTIVE];
    y[Y_LAST_EVENT_CODE] = d[D_LAST_CODE];
    y[Y_LAST_EVENT_ACTION] = d[D_LAST_ACTION];
    y[Y_LAST_EVENT_VEHICLE] = d[D_LAST_VEHICLE];
    y[Y_LAST_EVENT_LINE] = d[D_LAST_LINE];
    y[Y_LAST_EVENT_TIME] = d[D_LAST_TIME];
    y[Y_TRAFFIC_COUNT] = d[D_ACTIVE];

    /* the traffic slots */
    for (i = 0; i < view->n_slots; i++) {
        double *slot = y + N_OUTPUTS_FIXED + (size_t)i * N_SLOT_OUTPUTS;
        int id = (int)d[D_HEADER + i];
        if (id <= 0) {
            memset(slot, 0, sizeof(double) * N_SLOT_OUTPUTS);
            continue;
        }
        {
            const double *event = vehicle_event(view, id - 1);
            Motion m = motion_of(vehicle_const(view, d, id - 1), time);
            slot[YS_PRESENT] = 1.0;
            slot[YS_ID] = id;
            slot[YS_X] = m.station;
            slot[YS_Y] = -m.lateral;
            slot[YS_PSI] = m.speed >= 0 ? PI : 0.0;
            slot[YS_V] = fabs(m.speed);
            slot[YS_LENGTH] = event[A_LENGTH];
            slot[YS_WIDTH] = event[A_WIDTH];
        }
    }
}

/* ---- checks of a state from the importer (SetFMUstate, DeSerializeFMUstate) ------------------------------------- */

static int whole_in(double value, double low, double high) {
    return value >= low && value <= high && value == floor(value);
}

static int flag(double value) { return value == 0.0 || value == 1.0; }

int state_check(const View *view, const double *d, char *reason, size_t reason_size) {
    int i, spawned, active = 0, n = view->n_vehicles;
    const char *bad = NULL;
    if (!flag(d[D_STARTED]) || !flag(d[D_BRK_ACTIVE]) || !flag(d[D_FINISHED]) || !flag(d[D_BOUNDS_WARNED]) ||
        !flag(d[D_EGO + EGO_STOPPED]) || !flag(d[D_FOLLOW_LIMITED]) || !flag(d[D_FOLLOW_LIMITING]) ||
        !flag(d[D_START_PENDING]))
        bad = "a flag is neither 0 nor 1";
    else if (!whole_in(d[D_NEXT_EVENT], 0, view->n_events))
        bad = "the next event is out of range";
    else if (d[D_BRK_ACTIVE] != 0.0 && (!whole_in(d[D_BRK_EVENT], 0, view->n_events - 1) ||
                                        (int)event_at(view, (int)d[D_BRK_EVENT])[E_CODE] != CODE_BRK))
        bad = "the active BRK is not a BRK event";
    else if (!whole_in(d[D_SAMPLE], 0, 9007199254740992.0) || !whole_in(d[D_FOLLOW_K], 0, 9007199254740992.0))
        bad = "the driver's sample index is out of range";
    else if (!whole_in(d[D_END_REASON], 0, END_COLLISION) || !whole_in(d[D_LAST_CODE], 0, CODE_ES) ||
             !whole_in(d[D_LAST_ACTION], 0, ACTION_END))
        bad = "a code is out of range";
    else if (!whole_in(d[D_COLLISIONS], 0, 2147483647.0) || !whole_in(d[D_EVENTS], 0, 2147483647.0) ||
             !whole_in(d[D_LAST_VEHICLE], 0, n) || !whole_in(d[D_LAST_LINE], 0, 2147483647.0))
        bad = "a counter is out of range";
    else if (!whole_in(d[D_SPAWNED], 0, n))
        bad = "the number of vehicles is out of range";
    else if (!(d[D_THROTTLE] >= 0.0 && d[D_THROTTLE] <= 1.0 && d[D_BRAKE] >= 0.0 && d[D_BRAKE] <= 1.0))
        bad = "a pedal is outside 0..1";
    if (bad == NULL) {
        spawned = (int)d[D_SPAWNED];
        for (i = 0; i < n && bad == NULL; i++) {
            const double *vh = vehicle_const(view, d, i);
            if (i >= spawned) {
                if (vh[V_PRESENT] != 0.0) bad = "a vehicle not spawned is on the road";
                continue;
            }
            if (!flag(vh[V_PRESENT]) || !flag(vh[V_IN_CONTACT]) ||
                !whole_in(vh[V_NEXT_ACTION], 0, vehicle_event(view, i)[A_N_ACTIONS]) || !(vh[V_DURATION] >= 0.0) ||
                !whole_in(vh[V_SLOT], -1, view->n_slots - 1))
                bad = "a vehicle's record is out of range";
            else if (vh[V_PRESENT] != 0.0) {
                active++;
                if (vh[V_SLOT] >= 0 && d[D_HEADER + (int)vh[V_SLOT]] != i + 1) bad = "the traffic slots disagree";
            } else if (vh[V_SLOT] != -1.0) {
                bad = "a vehicle off the road holds a slot";
            }
        }
        for (i = 0; i < view->n_slots && bad == NULL; i++) {
            double id = d[D_HEADER + i];
            if (!whole_in(id, 0, spawned))
                bad = "a traffic slot is out of range";
            else if (id > 0 && (vehicle_const(view, d, (int)id - 1)[V_PRESENT] == 0.0 ||
                                vehicle_const(view, d, (int)id - 1)[V_SLOT] != i))
                bad = "the traffic slots disagree";
        }
        if (bad == NULL && active != (int)d[D_ACTIVE]) bad = "the count of vehicles on the road disagrees";
    }
    if (bad == NULL) return 0;
    snprintf(reason, reason_size, "%s", bad);
    return 1;
}
