/* The criticality record's per-vehicle arithmetic (looks.py, with what it calls in measures.py, geometry.py and
 * traffic.py), compiled: the same operations in the same order as the Python, so the same bits.
 *
 * Why: with dense traffic the record evaluates a passing car about 60 times (looks, course checks, the rates at a
 * located instant's probes), each a few hundred floating-point operations that cost about 50 000 machine
 * instructions in the interpreter (BENCHMARKS.md section 5). Here they cost about a thousand.
 *
 * How it stays the Python's twin:
 * - every expression is the Python's, term for term and in its order (C's + - * / are left-associative as
 *   Python's; no operation is fused: built with -ffp-contract=off, no -ffast-math), `x if x >= 0.0 else -x` is
 *   `x >= 0.0 ? x : -x`, abs() is fabs(), min(x, y) is `y < x ? y : x` and max(x, 0.0) is `0.0 > x ? 0.0 : x`
 *   (what the builtins return, nan and -0.0 included); sqrt is correctly rounded in both, acos and asin are the
 *   C library's in both (Python's math module calls them);
 * - tests/cosim/test_kernel.py holds each function equal to its Python twin bit for bit on generated and edge
 *   inputs, and whole runs' records equal with and without the kernel;
 * - where the Python raises (a division by zero, the square root of a negative number: states no run reaches),
 *   this returns inf or nan instead.
 * The record (extremes.py) uses it when the package was installed with it (setup.py builds it where a C compiler
 * is found) and looks.py otherwise: the results are the same either way, only the time differs. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

/* looks.py's RANGE and FLAT, measures.py's COURSE_* and HEADING_* (the module exposes them; a test holds them
 * equal to the Python's) */
#define RANGE 50.0
#define FLAT 1e-9
#define COURSE_WINDOW 1.0
#define COURSE_TRIES 8
#define COURSE_MARGIN 1e-6
#define HEADING_STRETCHES 3
#define HEADING_STRETCH 1.5

#define INF_ HUGE_VAL

/* ---- geometry.py ---- */

static double reach_time_scalar(double distance, double rate, double acceleration)
{
    if (distance <= 0.0)
        return 0.0;
    double root = sqrt(rate * rate + 2 * acceleration * distance);
    if (rate > 0) {
        double closing = rate + root;
        return 2 * distance / (1e-300 > closing ? 1e-300 : closing);
    }
    return (root - rate) / acceleration;
}

typedef struct { double a, b, c, s; } Footprint;

static double penetration(Footprint e, double dx, double dy, double length, double width)
{
    double a = e.a, b = e.b, c = e.c, s = e.s;
    double ac = c >= 0.0 ? c : -c;
    double as_ = s >= 0.0 ? s : -s;
    double hl = length / 2, hw = width / 2;
    double along_x = a * ac + b * as_ + hl - (dx >= 0.0 ? dx : -dx);
    double along_y = a * as_ + b * ac + hw - (dy >= 0.0 ? dy : -dy);
    double du = dx * c + dy * s, dv = -dx * s + dy * c;
    double along_u = a + hl * ac + hw * as_ - (du >= 0.0 ? du : -du);
    double along_v = b + hl * as_ + hw * ac - (dv >= 0.0 ? dv : -dv);
    double least = along_y < along_x ? along_y : along_x;
    double other = along_v < along_u ? along_v : along_u;
    return other < least ? other : least;
}

/* ---- measures.py ---- */

static void distance_and_rates(Footprint e, double dx, double dy, double vx, double vy, double yaw_rate,
                               double length, double width, double out[3])
{
    double a = e.a, b = e.b, c = e.c, s = e.s;
    double hl = length / 2, hw = width / 2;
    double ac = c >= 0.0 ? c : -c;
    double as_ = s >= 0.0 ? s : -s;
    if (!(a * as_ + b * ac + hw - (dy >= 0.0 ? dy : -dy) < 0.0
          || a * ac + b * as_ + hl - (dx >= 0.0 ? dx : -dx) < 0.0)
        && penetration(e, dx, dy, length, width) >= 0.0) {
        out[0] = out[1] = out[2] = 0.0;
        return;
    }
    double du = dx * c + dy * s;
    double dv = -dx * s + dy * c;
    double acs = a * c, as_s = a * s, bc = b * c, bs = b * s;
    double lc = hl * c, ls = hl * s, wc = hw * c, ws = hw * s;
    double x[8], y[8], q[8];
    x[0] = acs - bs - dx;   y[0] = as_s + bc - dy;
    x[1] = acs + bs - dx;   y[1] = as_s - bc - dy;
    x[2] = -acs - bs - dx;  y[2] = -as_s + bc - dy;
    x[3] = -acs + bs - dx;  y[3] = -as_s - bc - dy;
    x[4] = du + lc + ws;    y[4] = dv - ls + wc;
    x[5] = du + lc - ws;    y[5] = dv - ls - wc;
    x[6] = du - lc + ws;    y[6] = dv + ls + wc;
    x[7] = du - lc - ws;    y[7] = dv + ls - wc;
    for (int k = 0; k < 8; k++) {
        double half_x = k < 4 ? hl : a, half_y = k < 4 ? hw : b;
        double ex = (x[k] >= 0.0 ? x[k] : -x[k]) - half_x;
        double ey = (y[k] >= 0.0 ? y[k] : -y[k]) - half_y;
        q[k] = (ex > 0.0 ? ex * ex : 0.0) + (ey > 0.0 ? ey * ey : 0.0);
    }
    double least = q[0]; /* min(q0, ..., q7): a later one replaces it only when smaller */
    for (int k = 1; k < 8; k++)
        if (q[k] < least)
            least = q[k];
    double best = sqrt(least);
    double near = least * (1.0 + 1e-15);
    double vu = vx * c + vy * s, vv = -vx * s + vy * c;
    double rate = INF_, frozen = INF_;
    int first = 1;
    for (int k = 0; k < 8; k++) {
        if (q[k] > near || (q[k] != least && sqrt(q[k]) != best))
            continue;
        double xk = x[k], yk = y[k];
        double half_x = k < 4 ? hl : a, half_y = k < 4 ? hw : b;
        double ex = (xk >= 0.0 ? xk : -xk) - half_x;
        if (ex < 0.0)
            ex = 0.0;
        double ey = (yk >= 0.0 ? yk : -yk) - half_y;
        if (ey < 0.0)
            ey = 0.0;
        double gx = xk >= 0.0 ? ex : -ex;
        double gy = yk >= 0.0 ? ey : -ey;
        double px_rate, py_rate, r_frozen;
        if (k < 4) {
            px_rate = -yaw_rate * (yk + dy) - vx;
            py_rate = yaw_rate * (xk + dx) - vy;
            r_frozen = (gx * -vx + gy * -vy) / best;
        } else {
            px_rate = vu + yaw_rate * yk;
            py_rate = vv - yaw_rate * xk;
            r_frozen = (gx * vu + gy * vv) / best;
        }
        double r = (gx * px_rate + gy * py_rate) / best;
        if (first) {
            rate = r;
            frozen = r_frozen;
            first = 0;
        } else {
            if (r < rate)
                rate = r;
            if (r_frozen < frozen)
                frozen = r_frozen;
        }
    }
    out[0] = best;
    out[1] = rate;
    out[2] = frozen;
}

/* geometry.axis_reaches */
static void axis_reaches(Footprint e, double length, double width, double h[4])
{
    double ac = fabs(e.c), as_ = fabs(e.s);
    double hl = length / 2, hw = width / 2;
    h[0] = e.a * ac + e.b * as_ + hl;
    h[1] = e.a * as_ + e.b * ac + hw;
    h[2] = e.a + hl * ac + hw * as_;
    h[3] = e.b + hl * as_ + hw * ac;
}

/* measures.overlap_window: (entry, leave) narrowed by n axes' intervals |p + q t| < h; 0 if one never overlaps */
static int overlap_window(const double *p, const double *q, const double *h, int n, double *entry, double *leave)
{
    for (int k = 0; k < n; k++) {
        if (q[k] == 0.0) {
            if (fabs(p[k]) >= h[k])
                return 0;
            continue;
        }
        double t1 = (-h[k] - p[k]) / q[k], t2 = (h[k] - p[k]) / q[k];
        if (t2 < t1) {
            double t = t1;
            t1 = t2;
            t2 = t;
        }
        if (t1 > *entry)
            *entry = t1;
        if (t2 < *leave)
            *leave = t2;
    }
    return 1;
}

/* measures.window_closed */
static int window_closed(int open, double entry, double leave)
{
    return !open || entry >= leave || leave <= 0.0;
}

static double ttc(Footprint e, double dx, double dy, double vx, double vy, double length, double width)
{
    double c = e.c, s = e.s, h[4];
    axis_reaches(e, length, width, h);
    double p[4] = {dx, dy, dx * c + dy * s, -dx * s + dy * c};
    double q[4] = {vx, vy, vx * c + vy * s, -vx * s + vy * c};
    double entry = -INF_, leave = INF_;
    /* the road's axes, then the ego's (each window read after it is narrowed: a call's arguments have no order) */
    int open = overlap_window(p, q, h, 2, &entry, &leave);
    if (window_closed(open, entry, leave))
        return INF_;
    open = overlap_window(p + 2, q + 2, h + 2, 2, &entry, &leave);
    if (window_closed(open, entry, leave))
        return INF_;
    return entry > 0.0 ? entry : 0.0;
}

static double drac(double ttc_s, double vx, double vy)
{
    if (!(0.0 < ttc_s && ttc_s < INF_))
        return NAN;
    return sqrt(vx * vx + vy * vy) / (2 * ttc_s);
}

static double ttc_rate_known(Footprint e, double dx, double dy, double vx, double vy, double ax, double ay,
                             double yaw_rate, double length, double width)
{
    double a = e.a, b = e.b, c = e.c, s = e.s;
    double hl = length / 2, hw = width / 2;
    double sc = copysign(1.0, c), ss = copysign(1.0, s);
    double cos_rate = -sc * s * yaw_rate, sin_rate = ss * c * yaw_rate;
    double h[4];
    axis_reaches(e, length, width, h);
    double pu = dx * c + dy * s, qu = vx * c + vy * s, pv = -dx * s + dy * c, qv = -vx * s + vy * c;
    double au = ax * c + ay * s, av = -ax * s + ay * c;
    double p[4] = {dx, dy, pu, pv}, q[4] = {vx, vy, qu, qv};
    double p_rate[4] = {vx, vy, qu + yaw_rate * pv, qv - yaw_rate * pu};
    double q_rate[4] = {ax, ay, au + yaw_rate * qv, av - yaw_rate * qu};
    double h_rate[4] = {a * cos_rate + b * sin_rate, a * sin_rate + b * cos_rate, hl * cos_rate + hw * sin_rate,
                        hl * sin_rate + hw * cos_rate};
    double last = -INF_, rate = NAN;
    for (int k = 0; k < 4; k++) {
        if (q[k] == 0.0)
            continue;
        double sigma = q[k] > 0.0 ? 1.0 : -1.0;
        double entry = -(p[k] + sigma * h[k]) / q[k];
        if (entry > last) {
            last = entry;
            rate = -(p_rate[k] + sigma * h_rate[k] + entry * q_rate[k]) / q[k];
        }
    }
    return rate;
}

static double drac_rate_known(double t, double t_rate, double vx, double vy, double ax, double ay)
{
    double speed = sqrt(vx * vx + vy * vy);
    double speed_rate = (vx * ax + vy * ay) / speed;
    return (speed_rate * t - speed * t_rate) / (2 * t * t);
}

static double headway(Footprint e, double dx, double dy, double station_rate, double vehicle_station_rate,
                      double length, double width)
{
    double a = e.a, b = e.b, ac = fabs(e.c), as_ = fabs(e.s);
    double gap = dx - (a * ac + b * as_) - length / 2;
    if (!(dx > 0.0) || fabs(dy) >= a * as_ + b * ac + width / 2 || station_rate <= 0.0
        || vehicle_station_rate < 0.0)
        return INF_;
    return gap > 0.0 ? gap / station_rate : 0.0;
}

static double headway_rate_known(Footprint e, double value, double station_rate, double vehicle_station_rate,
                                 double station_acceleration, double yaw_rate)
{
    if (value == 0.0)
        return 0.0;
    double cos_rate = -copysign(1.0, e.c) * e.s * yaw_rate;
    double sin_rate = copysign(1.0, e.s) * e.c * yaw_rate;
    double gap_rate = vehicle_station_rate - station_rate - (e.a * cos_rate + e.b * sin_rate);
    return (gap_rate - value * station_acceleration) / station_rate;
}

static double approach_horizon(double distance, double frozen_rate, double relative_speed, double turn,
                               double acceleration, double yaw_rate_bound)
{
    double closing = -frozen_rate - turn;
    if (closing <= 0.0 || distance <= 0.0)
        return 0.0;
    double half = reach_time_scalar(distance / 2, relative_speed + turn, acceleration);
    double speed = relative_speed + acceleration * half;
    double growth = acceleration + speed * (4 * (speed + turn) / distance + yaw_rate_bound);
    double bound = closing / growth;
    return bound < half ? bound : half;
}

static double heading_horizon(double dx, double dy, double vx, double vy, double radius_sum, double turn,
                              double acceleration)
{
    double rho = sqrt(dx * dx + dy * dy);
    double speed = sqrt(vx * vx + vy * vy);
    if (speed <= 2 * turn || rho <= 2 * radius_sum)
        return 0.0;
    double cos_alpha = -(dx * vx + dy * vy) / (rho * speed);
    cos_alpha = cos_alpha > -1.0 ? cos_alpha : -1.0;
    double alpha = acos(cos_alpha < 1.0 ? cos_alpha : 1.0);
    double margin = acos(2 * turn / speed) - asin(2 * radius_sum / rho) - alpha;
    if (margin <= 0.0)
        return 0.0;
    double within = reach_time_scalar(rho / 2, speed, acceleration);
    double slowing = speed / (2 * acceleration);
    if (slowing < within)
        within = slowing;
    double fastest = speed + acceleration * within;
    double bound = margin / (2 * fastest / rho + 2 * acceleration / speed);
    bound = bound < within ? bound : within;
    for (int k = 0; k < HEADING_STRETCHES; k++) {
        double longer = HEADING_STRETCH * bound;
        double turned = acceleration * longer;
        double moved = speed * longer + 0.5 * turned * longer;
        double slowest = speed - turned, nearest = rho - moved;
        if (!(turn < slowest && radius_sum < nearest && turned < speed && moved < rho))
            break;
        if (acos(turn / slowest) - asin(radius_sum / nearest) - asin(moved / rho) - asin(turned / speed) - alpha
            <= 0.0)
            break;
        bound = longer;
    }
    return bound;
}

static double course_horizon(double dx, double dy, double vx, double vy, double half_x, double half_y,
                             double until, double turn, double acceleration)
{
    if (dy == 0.0)
        return 0.0;
    double side = dy > 0.0 ? 1.0 : -1.0;
    double lateral = side * vy, ahead = (dx >= 0.0 ? dx : -dx) + half_x, speed = vx >= 0.0 ? vx : -vx;
    double gap = side * dy - half_y;
    if (speed <= 0.0)
        return 0.0;
    double reach0 = ahead / speed;
    double room = gap + (lateral < 0.0 ? lateral : 0.0) * reach0;
    if (room <= 0.0)
        return 0.0;
    double window = COURSE_WINDOW < until ? COURSE_WINDOW : until;
    double away = -lateral;
    double guess = 0.9 * room / (acceleration * reach0 + turn + (away > 0.0 ? away : 0.0));
    double horizon = guess < window ? guess : window;
    for (int k = 0; k < COURSE_TRIES; k++) {
        double drift = acceleration * horizon;
        if (!(speed <= drift)) {
            double slip = 0.5 * drift * horizon;
            double grow = turn * horizon;
            double reach = (ahead + speed * horizon + slip + grow) / (speed - drift);
            double swing = lateral * horizon;
            double late = (lateral - drift) * reach;
            if (gap - slip + (swing < 0.0 ? swing : 0.0) + (late < 0.0 ? late : 0.0) - grow > COURSE_MARGIN)
                return horizon;
        }
        horizon *= 0.75;
    }
    return 0.0;
}

/* ---- looks.py ---- */

/* looks.off_course */
static int off_course(double dx, double dy, double vx, double vy, double reach_x, double reach_y)
{
    double entry = -INF_, leave = INF_;
    double p[2] = {dx, dy}, q[2] = {vx, vy}, h[2] = {reach_x, reach_y};
    int open = overlap_window(p, q, h, 2, &entry, &leave);
    return window_closed(open, entry, leave);
}

/* The ego at a state (looks.ego's tuple) and the vehicle relative to it (traffic.Traffic.motion_of and
 * the lines of looks.evaluate, course_check and distance_rate that read it: traffic.motion_law and after). */
typedef struct {
    Footprint ego;
    double c, s, ego_vx, ego_vy, ego_x, ego_y;
} Ego;

typedef struct {
    double dx, dy, vx, vy, speed, speed_rate, transition_left, length, width;
} Relative;

static void relative(const Ego *at, const double row[7], double length, double width, double t, double x,
                     double y, Relative *r)
{
    double t0 = row[0], station0 = row[1], lateral0 = row[2], speed0 = row[3], lateral1 = row[4],
           speed1 = row[5], duration = row[6];
    /* traffic.motion_of */
    double elapsed = t - t0, fraction, travelled, lateral_rate;
    if (elapsed < duration) {
        fraction = elapsed / duration;
        travelled = speed0 * elapsed + (speed1 - speed0) * (elapsed * elapsed) / (2 * duration);
        lateral_rate = (lateral1 - lateral0) / duration;
    } else {
        fraction = 1.0;
        travelled = (speed0 + speed1) / 2 * duration + speed1 * (elapsed - duration);
        lateral_rate = 0.0;
    }
    double station = station0 - travelled, lateral = lateral0 + (lateral1 - lateral0) * fraction;
    double speed = speed0 + (speed1 - speed0) * fraction;
    /* the callers' lines */
    int moving = elapsed < duration;
    r->speed_rate = moving ? (speed1 - speed0) / duration : 0.0;
    r->transition_left = moving ? duration - elapsed : INF_;
    r->dx = station - x;
    r->dy = -lateral - y;
    r->vx = -speed - at->ego_vx;
    r->vy = -lateral_rate - at->ego_vy;
    r->speed = speed;
    r->length = length;
    r->width = width;
}

/* ---- argument parsing: plain floats and tuples of them ---- */

static int number(PyObject *o, double *out)
{
    *out = PyFloat_AsDouble(o);
    return (*out == -1.0 && PyErr_Occurred()) ? -1 : 0;
}

static int numbers(PyObject *tuple, Py_ssize_t first, Py_ssize_t n, double *out)
{
    if (!PyTuple_Check(tuple) || PyTuple_GET_SIZE(tuple) < first + n) {
        PyErr_Format(PyExc_TypeError, "expected a tuple of at least %zd numbers", first + n);
        return -1;
    }
    for (Py_ssize_t k = 0; k < n; k++)
        if (number(PyTuple_GET_ITEM(tuple, first + k), &out[k]) < 0)
            return -1;
    return 0;
}

static int footprint(PyObject *o, Footprint *e)
{
    double v[4];
    if (numbers(o, 0, 4, v) < 0)
        return -1;
    e->a = v[0];
    e->b = v[1];
    e->c = v[2];
    e->s = v[3];
    return 0;
}

/* cos and sin called through pointers: each the C library's own function, as Python's math.cos and math.sin call
 * them (the compiler may not fuse the two into one sincos call, nor expand either inline) */
static double (*volatile cos_)(double) = cos;
static double (*volatile sin_)(double) = sin;

/* The ego at a state from its half length a and half width b, yaw psi and body-frame velocity (vx, vy): looks.ego's
 * operations */
static void ego_of(double a, double b, double psi, double vx, double vy, Ego *at)
{
    double c = cos_(psi), s = sin_(psi);
    double ac = c >= 0.0 ? c : -c;
    double as_ = s >= 0.0 ? s : -s;
    at->ego.a = a;
    at->ego.b = b;
    at->ego.c = at->c = c;
    at->ego.s = at->s = s;
    at->ego_vx = vx * c - vy * s;
    at->ego_vy = vx * s + vy * c;
    at->ego_x = a * ac + b * as_;
    at->ego_y = a * as_ + b * ac;
}

static int arity(Py_ssize_t nargs, Py_ssize_t n, const char *name)
{
    if (nargs != n) {
        PyErr_Format(PyExc_TypeError, "%s takes %zd arguments (%zd given)", name, n, nargs);
        return -1;
    }
    return 0;
}

static int doubles(PyObject *const *args, Py_ssize_t first, Py_ssize_t n, double *out)
{
    for (Py_ssize_t k = 0; k < n; k++)
        if (number(args[first + k], &out[k]) < 0)
            return -1;
    return 0;
}

static PyObject *floats(Py_ssize_t n, const double *v)
{
    PyObject *t = PyTuple_New(n);
    if (t == NULL)
        return NULL;
    for (Py_ssize_t k = 0; k < n; k++) {
        PyObject *f = PyFloat_FromDouble(v[k]);
        if (f == NULL) {
            Py_DECREF(t);
            return NULL;
        }
        PyTuple_SET_ITEM(t, k, f);
    }
    return t;
}

/* (a, b, row, size, t, x, y, psi, vx, vy): the arguments the vehicle functions share (the ego's half sizes, the
 * vehicle's motion and size, the ego's state) */
#define VEHICLE_ARGS 10
static int vehicle_args(PyObject *const *args, Ego *at, double row[7], double size[2], double txy[3])
{
    double half[2], motion[3];
    if (doubles(args, 0, 2, half) < 0 || numbers(args[2], 0, 7, row) < 0 || numbers(args[3], 0, 2, size) < 0
        || doubles(args, 4, 3, txy) < 0 || doubles(args, 7, 3, motion) < 0)
        return -1;
    ego_of(half[0], half[1], motion[0], motion[1], motion[2], at);
    return 0;
}

/* looks.evaluate's arithmetic: the values to offer (distance, TTC, DRAC, headway), their rates, the first ten of what
 * the horizon needs (distance, frozen rate, dx, dy, vx, vy, length, width, speed rate, transition left) and the
 * road axes' reaches (within RANGE only: returns whether they were computed) */
static int evaluated(const Ego *at, const double row[7], const double size[2], const double txy[3], double state_ax,
                     double state_ay, double yaw_rate, double values[4], double rates[4], double motion[10],
                     double reach[2])
{
    Relative r;
    relative(at, row, size[0], size[1], txy[0], txy[1], txy[2], &r);
    Footprint ego = at->ego;
    double dar[3];
    distance_and_rates(ego, r.dx, r.dy, r.vx, r.vy, yaw_rate, r.length, r.width, dar);
    double d = dar[0], rate = dar[1], frozen = dar[2];
    double m[10] = {d, frozen, r.dx, r.dy, r.vx, r.vy, r.length, r.width, r.speed_rate, r.transition_left};
    memcpy(motion, m, sizeof m);
    if (d > RANGE) {
        values[0] = d; values[1] = INF_; values[2] = NAN; values[3] = INF_;
        rates[0] = rate; rates[1] = rates[2] = rates[3] = NAN;
        return 0;
    }
    double rx = at->ego_x + r.length / 2, ry = at->ego_y + r.width / 2;
    double value = off_course(r.dx, r.dy, r.vx, r.vy, rx, ry) ? INF_
                                                              : ttc(ego, r.dx, r.dy, r.vx, r.vy, r.length, r.width);
    double ego_ax = state_ax * at->c - state_ay * at->s;
    double gap_time = (!(r.dx > 0.0) || (r.dy >= 0.0 ? r.dy : -r.dy) >= ry || at->ego_vx <= 0.0 || -r.speed < 0.0)
                          ? INF_ : headway(ego, r.dx, r.dy, at->ego_vx, -r.speed, r.length, r.width);
    double headway_change = gap_time == INF_
                                ? NAN : headway_rate_known(ego, gap_time, at->ego_vx, -r.speed, ego_ax, yaw_rate);
    values[0] = d; values[1] = value; values[3] = gap_time;
    rates[0] = rate; rates[3] = headway_change;
    if (!(0.0 < value && value < INF_)) {
        values[2] = NAN;
        rates[1] = rates[2] = NAN;
    } else {
        double ax = -r.speed_rate - ego_ax, ay = -(state_ax * at->s + state_ay * at->c);
        double value_rate = ttc_rate_known(ego, r.dx, r.dy, r.vx, r.vy, ax, ay, yaw_rate, r.length, r.width);
        values[2] = drac(value, r.vx, r.vy);
        rates[1] = value_rate;
        rates[2] = -drac_rate_known(value, value_rate, r.vx, r.vy, ax, ay);
    }
    reach[0] = rx;
    reach[1] = ry;
    return 1;
}

/* looks.evaluate's value: ((4 values), (4 rates), (10 numbers, the ego's footprint object, reach_x, reach_y: None
 * beyond RANGE)) */
static PyObject *evaluated_tuple(Footprint e, const double values[4], const double rates[4],
                                 const double motion[10], const double reach[2], int near)
{
    double sides[4] = {e.a, e.b, e.c, e.s};
    PyObject *out = NULL, *v = floats(4, values), *rt = floats(4, rates), *m = PyTuple_New(13);
    PyObject *footprint_object = floats(4, sides);
    if (v == NULL || rt == NULL || m == NULL || footprint_object == NULL) {
        Py_XDECREF(footprint_object);
        goto done;
    }
    for (int k = 0; k < 10; k++) {
        PyObject *f = PyFloat_FromDouble(motion[k]);
        if (f == NULL)
            goto done;
        PyTuple_SET_ITEM(m, k, f);
    }
    PyTuple_SET_ITEM(m, 10, footprint_object);
    for (int k = 0; k < 2; k++) {
        PyObject *f = near ? PyFloat_FromDouble(reach[k]) : Py_NewRef(Py_None);
        if (f == NULL)
            goto done;
        PyTuple_SET_ITEM(m, 11 + k, f);
    }
    out = PyTuple_Pack(3, v, rt, m);
done:
    Py_XDECREF(v);
    Py_XDECREF(rt);
    Py_XDECREF(m);
    return out;
}

/* evaluate(a, b, row, size, t, x, y, psi, vx, vy, ax, ay, yaw_rate) -> looks.evaluate */
static PyObject *k_evaluate(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Ego at;
    double row[7], size[2], txy[3], more[3], values[4], rates[4], motion[10], reach[2];
    if (arity(nargs, VEHICLE_ARGS + 3, "evaluate") < 0 || vehicle_args(args, &at, row, size, txy) < 0
        || doubles(args, VEHICLE_ARGS, 3, more) < 0)
        return NULL;
    int near = evaluated(&at, row, size, txy, more[0], more[1], more[2], values, rates, motion, reach);
    return evaluated_tuple(at.ego, values, rates, motion, reach, near);
}

/* looks.horizon's arithmetic: (horizon, quiet, course) from the ten numbers and the reaches */
static void horizon_of(const double m[10], const double reach[2], double rate0, double recorded, double acceleration,
                       double yaw_rate_bound, double radius, double out[3])
{
    double d = m[0], frozen = m[1], dx = m[2], dy = m[3], vx = m[4], vy = m[5], length = m[6], width = m[7],
           speed_rate = m[8], transition_left = m[9];
    int near = d <= RANGE;
    double turn = radius * yaw_rate_bound;
    double relative_ = acceleration + (speed_rate >= 0.0 ? speed_rate : -speed_rate);
    double new_minimum = reach_time_scalar(d - (recorded - FLAT), turn - frozen, relative_);
    double approach_end = rate0 >= 0.0 ? INF_ : 0.0;
    if (frozen < -turn) {
        double vehicle_radius = 0.5 * sqrt(length * length + width * width);
        approach_end = approach_horizon(d, frozen, sqrt(vx * vx + vy * vy), turn, relative_, yaw_rate_bound);
        double heading = heading_horizon(dx, dy, vx, vy, radius + vehicle_radius, turn, relative_);
        if (heading > approach_end)
            approach_end = heading;
        if (approach_end > new_minimum)
            new_minimum = approach_end;
    }
    if (!near) {
        double entering = reach_time_scalar(d - RANGE, turn - frozen, relative_);
        out[0] = transition_left < new_minimum ? transition_left : new_minimum;
        out[1] = transition_left < approach_end ? transition_left : approach_end;
        out[2] = transition_left < entering ? transition_left : entering;
        return;
    }
    double longest = approach_end > new_minimum ? approach_end : new_minimum;
    if (transition_left < longest)
        longest = transition_left;
    if (!(longest > 0.0)) {
        out[0] = out[1] = 0.0;
        out[2] = INF_;
        return;
    }
    out[0] = transition_left < new_minimum ? transition_left : new_minimum;
    out[1] = transition_left < approach_end ? transition_left : approach_end;
    out[2] = course_horizon(dx, dy, vx, vy, reach[0], reach[1], longest, turn, relative_);
}

/* the ten numbers and the reaches of an evaluation's third value; returns whether the reaches are there */
static int motion_of_tuple(PyObject *motion, double m[10], double reach[2])
{
    if (numbers(motion, 0, 10, m) < 0)
        return -1;
    if (PyTuple_GET_SIZE(motion) < 13 || PyTuple_GET_ITEM(motion, 11) == Py_None)
        return 0;
    return numbers(motion, 11, 2, reach) < 0 ? -1 : 1;
}

/* horizon(motion, rate, recorded_min_distance, acceleration, yaw_rate_bound, radius) -> (horizon, quiet, course):
 * looks.horizon */
static PyObject *k_horizon(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double m[10], reach[2] = {NAN, NAN}, v[5], out[3];
    if (arity(nargs, 6, "horizon") < 0 || motion_of_tuple(args[0], m, reach) < 0 || doubles(args, 1, 5, v) < 0)
        return NULL;
    horizon_of(m, reach, v[0], v[1], v[2], v[3], v[4], out);
    return floats(3, out);
}

/* looks.offer: one value offered to one measure's per-vehicle lists (values, times) */
static int offer(PyObject *values, PyObject *times, Py_ssize_t i, double t, double value, int largest)
{
    if (!isfinite(value))
        return 0;
    if (!PyList_Check(values) || !PyList_Check(times) || i >= PyList_GET_SIZE(values)
        || i >= PyList_GET_SIZE(times)) {
        PyErr_SetString(PyExc_IndexError, "offer: the vehicle is beyond the record's lists");
        return -1;
    }
    double recorded;
    if (number(PyList_GET_ITEM(values, i), &recorded) < 0)
        return -1;
    int better = largest ? (recorded != recorded || value > recorded + FLAT)
                         : (recorded != recorded || value < recorded - FLAT);
    if (better) {
        PyObject *v = PyFloat_FromDouble(value), *w = PyFloat_FromDouble(t);
        if (v == NULL || w == NULL) {
            Py_XDECREF(v);
            Py_XDECREF(w);
            return -1;
        }
        PyList_SetItem(values, i, v);
        PyList_SetItem(times, i, w);
    } else if (largest ? value > recorded : value < recorded) {
        PyObject *v = PyFloat_FromDouble(value);
        if (v == NULL)
            return -1;
        PyList_SetItem(values, i, v);
    }
    return 0;
}

/* offer(values, times, i, t, value, largest) -> None: looks.offer */
static PyObject *k_offer(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double t, value;
    if (arity(nargs, 6, "offer") < 0 || number(args[3], &t) < 0 || number(args[4], &value) < 0)
        return NULL;
    Py_ssize_t i = PyLong_AsSsize_t(args[2]);
    int largest = PyObject_IsTrue(args[5]);
    if ((i == -1 && PyErr_Occurred()) || largest < 0 || offer(args[0], args[1], i, t, value, largest) < 0)
        return NULL;
    Py_RETURN_NONE;
}

/* look(a, b, row, size, t, x, y, psi, vx, vy, ax, ay, yaw_rate, evaluated, i, tables, acceleration, yaw_rate_bound,
 * radius)
 * -> (rates, horizon, quiet, course): looks.look */
static PyObject *k_look(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Ego at;
    double row[7], size[2], txy[3], more[3], values[4], rates[4], motion[10], reach[2] = {NAN, NAN}, bounds[3];
    if (arity(nargs, VEHICLE_ARGS + 9, "look") < 0 || vehicle_args(args, &at, row, size, txy) < 0
        || doubles(args, VEHICLE_ARGS, 3, more) < 0 || doubles(args, VEHICLE_ARGS + 6, 3, bounds) < 0)
        return NULL;
    PyObject *given = args[VEHICLE_ARGS + 3], *tables = args[VEHICLE_ARGS + 5], *rates_object;
    Py_ssize_t i = PyLong_AsSsize_t(args[VEHICLE_ARGS + 4]);
    if (i == -1 && PyErr_Occurred())
        return NULL;
    if (!PyTuple_Check(tables) || PyTuple_GET_SIZE(tables) != 8) {
        PyErr_SetString(PyExc_TypeError, "look: tables is the 8 lists (value, time) of distance, TTC, DRAC, headway");
        return NULL;
    }
    if (given == Py_None) {
        evaluated(&at, row, size, txy, more[0], more[1], more[2], values, rates, motion, reach);
        rates_object = floats(4, rates);
        if (rates_object == NULL)
            return NULL;
    } else {
        if (!PyTuple_Check(given) || PyTuple_GET_SIZE(given) != 3) {
            PyErr_SetString(PyExc_TypeError, "look: evaluated is evaluate's value or None");
            return NULL;
        }
        if (numbers(PyTuple_GET_ITEM(given, 0), 0, 4, values) < 0
            || numbers(PyTuple_GET_ITEM(given, 1), 0, 4, rates) < 0
            || motion_of_tuple(PyTuple_GET_ITEM(given, 2), motion, reach) < 0)
            return NULL;
        rates_object = Py_NewRef(PyTuple_GET_ITEM(given, 1));
    }
    double t = txy[0], out[3];
    PyObject *const *table = &PyTuple_GET_ITEM(tables, 0);
    /* the offers: distance, TTC, headway, DRAC (each list its own: the order does not matter) */
    if (offer(table[0], table[1], i, t, values[0], 0) < 0 || offer(table[2], table[3], i, t, values[1], 0) < 0
        || offer(table[6], table[7], i, t, values[3], 0) < 0 || offer(table[4], table[5], i, t, values[2], 1) < 0)
        goto fail;
    if (values[0] <= RANGE && (rates[1] == rates[1] || rates[3] == rates[3])) {
        out[0] = out[1] = 0.0;
        out[2] = INF_;
    } else {
        double recorded;
        if (number(PyList_GET_ITEM(table[0], i), &recorded) < 0)
            goto fail;
        horizon_of(motion, reach, rates[0], recorded, bounds[0], bounds[1], bounds[2], out);
    }
    PyObject *result = Py_BuildValue("(Nddd)", rates_object, out[0], out[1], out[2]);
    return result;
fail:
    Py_DECREF(rates_object);
    return NULL;
}

/* course_check(a, b, row, size, t, x, y, psi, vx, vy, yaw_rate, acceleration, yaw_rate_bound, radius) -> float:
 * looks.course_check */
static PyObject *k_course_check(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Ego at;
    double row[7], size[2], txy[3], more[4];
    if (arity(nargs, VEHICLE_ARGS + 4, "course_check") < 0 || vehicle_args(args, &at, row, size, txy) < 0
        || doubles(args, VEHICLE_ARGS, 4, more) < 0)
        return NULL;
    double yaw_rate = more[0], acceleration = more[1], yaw_rate_bound = more[2], radius = more[3];
    Relative r;
    relative(&at, row, size[0], size[1], txy[0], txy[1], txy[2], &r);
    Footprint ego = at.ego;
    double relative_ = acceleration + (r.speed_rate >= 0.0 ? r.speed_rate : -r.speed_rate);
    double turn = radius * yaw_rate_bound;
    double reach_x = at.ego_x + r.length / 2, reach_y = at.ego_y + r.width / 2;
    if (off_course(r.dx, r.dy, r.vx, r.vy, reach_x, reach_y)
        && (!(r.dx > 0.0) || (r.dy >= 0.0 ? r.dy : -r.dy) >= reach_y || at.ego_vx <= 0.0 || -r.speed < 0.0))
        return PyFloat_FromDouble(course_horizon(r.dx, r.dy, r.vx, r.vy, reach_x, reach_y, r.transition_left, turn,
                                                 relative_));
    double value = ttc(ego, r.dx, r.dy, r.vx, r.vy, r.length, r.width);
    if ((0.0 < value && value < INF_) || headway(ego, r.dx, r.dy, at.ego_vx, -r.speed, r.length, r.width) != INF_) {
        double dar[3];
        distance_and_rates(ego, r.dx, r.dy, r.vx, r.vy, yaw_rate, r.length, r.width, dar);
        if (dar[0] <= RANGE)
            return PyFloat_FromDouble(NAN);
        double entering = reach_time_scalar(dar[0] - RANGE, turn - dar[2], relative_);
        return PyFloat_FromDouble(r.transition_left < entering ? r.transition_left : entering);
    }
    return PyFloat_FromDouble(course_horizon(r.dx, r.dy, r.vx, r.vy, reach_x, reach_y, r.transition_left, turn,
                                             relative_));
}

/* distance_rate(a, b, row, size, t, x, y, psi, vx, vy, yaw_rate) -> float: looks.distance_rate */
static PyObject *k_distance_rate(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Ego at;
    double row[7], size[2], txy[3], yaw_rate;
    if (arity(nargs, VEHICLE_ARGS + 1, "distance_rate") < 0 || vehicle_args(args, &at, row, size, txy) < 0
        || number(args[VEHICLE_ARGS], &yaw_rate) < 0)
        return NULL;
    Relative r;
    relative(&at, row, size[0], size[1], txy[0], txy[1], txy[2], &r);
    double dar[3];
    distance_and_rates(at.ego, r.dx, r.dy, r.vx, r.vy, yaw_rate, r.length, r.width, dar);
    return PyFloat_FromDouble(dar[1]);
}

/* ---- the measures alone, with the Python's signatures (for the tests that hold each to its twin) ---- */

#define EGO_THEN(name, n)                                                                                      \
    Footprint e;                                                                                               \
    double v[n];                                                                                               \
    if (arity(nargs, (n) + 1, name) < 0 || footprint(args[0], &e) < 0 || doubles(args, 1, n, v) < 0)           \
        return NULL;

static PyObject *k_distance_and_rates(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    EGO_THEN("distance_and_rates", 7)
    double out[3];
    distance_and_rates(e, v[0], v[1], v[2], v[3], v[4], v[5], v[6], out);
    return floats(3, out);
}

static PyObject *k_penetration(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    EGO_THEN("penetration", 4)
    return PyFloat_FromDouble(penetration(e, v[0], v[1], v[2], v[3]));
}

static PyObject *k_ttc(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    EGO_THEN("ttc", 6)
    return PyFloat_FromDouble(ttc(e, v[0], v[1], v[2], v[3], v[4], v[5]));
}

static PyObject *k_ttc_rate_known(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    EGO_THEN("ttc_rate_known", 9)
    return PyFloat_FromDouble(ttc_rate_known(e, v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]));
}

static PyObject *k_headway(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    EGO_THEN("headway", 6)
    return PyFloat_FromDouble(headway(e, v[0], v[1], v[2], v[3], v[4], v[5]));
}

static PyObject *k_headway_rate_known(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    EGO_THEN("headway_rate_known", 5)
    return PyFloat_FromDouble(headway_rate_known(e, v[0], v[1], v[2], v[3], v[4]));
}

#define PLAIN(name, n, call)                                                                                   \
    static PyObject *k_##name(PyObject *self, PyObject *const *args, Py_ssize_t nargs)                         \
    {                                                                                                          \
        double v[n];                                                                                           \
        if (arity(nargs, n, #name) < 0 || doubles(args, 0, n, v) < 0)                                          \
            return NULL;                                                                                       \
        return call;                                                                                           \
    }

PLAIN(reach_time_scalar, 3, PyFloat_FromDouble(reach_time_scalar(v[0], v[1], v[2])))
PLAIN(drac, 3, PyFloat_FromDouble(drac(v[0], v[1], v[2])))
PLAIN(drac_rate_known, 6, PyFloat_FromDouble(drac_rate_known(v[0], v[1], v[2], v[3], v[4], v[5])))
PLAIN(approach_horizon, 6, PyFloat_FromDouble(approach_horizon(v[0], v[1], v[2], v[3], v[4], v[5])))
PLAIN(heading_horizon, 7, PyFloat_FromDouble(heading_horizon(v[0], v[1], v[2], v[3], v[4], v[5], v[6])))
PLAIN(course_horizon, 9,
      PyFloat_FromDouble(course_horizon(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8])))
PLAIN(off_course, 6, PyBool_FromLong(off_course(v[0], v[1], v[2], v[3], v[4], v[5])))

/* ---- the follower's scans over the vehicles on the road (follower.py; looks.py's due_looks, due_checks and
 * earliest): a selection and minima of per-vehicle floats, list by list as the Python's comprehensions and
 * min(map(...)) take them ---- */

static int per_vehicle(PyObject *values, PyObject *index, double *out)
{
    Py_ssize_t i = PyLong_AsSsize_t(index);
    if (i == -1 && PyErr_Occurred())
        return -1;
    if (i < 0 || i >= PyList_GET_SIZE(values)) {
        PyErr_SetString(PyExc_IndexError, "list index out of range");
        return -1;
    }
    return number(PyList_GET_ITEM(values, i), out);
}

static int lists(PyObject *const *args, Py_ssize_t n)
{
    for (Py_ssize_t k = 0; k < n; k++)
        if (!PyList_Check(args[k])) {
            PyErr_SetString(PyExc_TypeError, "expected lists (the vehicles, then their values)");
            return -1;
        }
    return 0;
}

/* due_looks(vehicles, next_look, quiet_until, look_time, t, ahead, now) -> [i for i in vehicles if (now and
 * next_look[i] <= t) or (quiet_until[i] <= ahead and look_time[i] < t)]; ahead None: the first test alone */
static PyObject *k_due_looks(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double t, ahead = 0.0;
    if (arity(nargs, 7, "due_looks") < 0 || lists(args, 4) < 0 || number(args[4], &t) < 0
        || (args[5] != Py_None && number(args[5], &ahead) < 0))
        return NULL;
    int with_ahead = args[5] != Py_None, now = PyObject_IsTrue(args[6]);
    if (now < 0)
        return NULL;
    PyObject *vehicles = args[0], *due = PyList_New(0);
    if (due == NULL)
        return NULL;
    for (Py_ssize_t k = 0; k < PyList_GET_SIZE(vehicles); k++) {
        PyObject *i = PyList_GET_ITEM(vehicles, k);
        double next, quiet, looked;
        int take = 0;
        if (now) {
            if (per_vehicle(args[1], i, &next) < 0)
                goto fail;
            take = next <= t;
        }
        if (!take && with_ahead) {
            if (per_vehicle(args[2], i, &quiet) < 0)
                goto fail;
            if (quiet <= ahead) {
                if (per_vehicle(args[3], i, &looked) < 0)
                    goto fail;
                take = looked < t;
            }
        }
        if (take && PyList_Append(due, i) < 0)
            goto fail;
    }
    return due;
fail:
    Py_DECREF(due);
    return NULL;
}

/* due_checks(vehicles, course_until, check_time, next_look, until, t) -> [i for i in vehicles if course_until[i] <=
 * until and check_time[i] < t and next_look[i] > t] */
static PyObject *k_due_checks(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double until, t;
    if (arity(nargs, 6, "due_checks") < 0 || lists(args, 4) < 0 || number(args[4], &until) < 0
        || number(args[5], &t) < 0)
        return NULL;
    PyObject *vehicles = args[0], *due = PyList_New(0);
    if (due == NULL)
        return NULL;
    for (Py_ssize_t k = 0; k < PyList_GET_SIZE(vehicles); k++) {
        PyObject *i = PyList_GET_ITEM(vehicles, k);
        double course, checked, next;
        if (per_vehicle(args[1], i, &course) < 0)
            goto fail;
        if (!(course <= until))
            continue;
        if (per_vehicle(args[2], i, &checked) < 0)
            goto fail;
        if (!(checked < t))
            continue;
        if (per_vehicle(args[3], i, &next) < 0)
            goto fail;
        if (next > t && PyList_Append(due, i) < 0)
            goto fail;
    }
    return due;
fail:
    Py_DECREF(due);
    return NULL;
}

/* earliest(vehicles, values...) -> per list of values min(map(values.__getitem__, vehicles), default=inf): the
 * first, replaced by a later one only when smaller (nan included); one float, or a tuple for several lists */
static PyObject *k_earliest(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double least[8];
    if (nargs < 2 || nargs > 9) {
        PyErr_SetString(PyExc_TypeError, "earliest takes the vehicles and 1 to 8 lists of values");
        return NULL;
    }
    if (lists(args, nargs) < 0)
        return NULL;
    PyObject *vehicles = args[0];
    Py_ssize_t n = PyList_GET_SIZE(vehicles);
    for (Py_ssize_t m = 1; m < nargs; m++) {
        least[m - 1] = INF_;
        for (Py_ssize_t k = 0; k < n; k++) {
            double value;
            if (per_vehicle(args[m], PyList_GET_ITEM(vehicles, k), &value) < 0)
                return NULL;
            if (k == 0 || value < least[m - 1])
                least[m - 1] = value;
        }
    }
    return nargs == 2 ? PyFloat_FromDouble(least[0]) : floats(nargs - 1, least);
}

#define METHOD(name) {#name, (PyCFunction)(void (*)(void))k_##name, METH_FASTCALL, NULL}

static PyMethodDef methods[] = {
    METHOD(evaluate), METHOD(horizon), METHOD(look), METHOD(offer), METHOD(course_check), METHOD(distance_rate),
    METHOD(distance_and_rates), METHOD(penetration), METHOD(ttc), METHOD(ttc_rate_known), METHOD(headway),
    METHOD(headway_rate_known), METHOD(reach_time_scalar), METHOD(drac), METHOD(drac_rate_known),
    METHOD(approach_horizon), METHOD(heading_horizon), METHOD(course_horizon), METHOD(off_course),
    METHOD(due_looks), METHOD(due_checks), METHOD(earliest),
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_kernel",
    "The criticality record's per-vehicle arithmetic, compiled (the same operations as the Python: _kernel.c).",
    -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__kernel(void)
{
    PyObject *m = PyModule_Create(&module);
    if (m == NULL)
        return NULL;
    if (PyModule_AddObject(m, "RANGE", PyFloat_FromDouble(RANGE)) < 0
        || PyModule_AddObject(m, "FLAT", PyFloat_FromDouble(FLAT)) < 0
        || PyModule_AddObject(m, "COURSE_WINDOW", PyFloat_FromDouble(COURSE_WINDOW)) < 0
        || PyModule_AddIntConstant(m, "COURSE_TRIES", COURSE_TRIES) < 0
        || PyModule_AddObject(m, "COURSE_MARGIN", PyFloat_FromDouble(COURSE_MARGIN)) < 0
        || PyModule_AddIntConstant(m, "HEADING_STRETCHES", HEADING_STRETCHES) < 0
        || PyModule_AddObject(m, "HEADING_STRETCH", PyFloat_FromDouble(HEADING_STRETCH)) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
