/* Co-simulation stepping: the in-step solver and event location.
 *
 * Solver: RODAS4 (Hairer & Wanner, Solving ODEs II, sec. IV.7), a linearly implicit, L-stable,
 * stiffly accurate Rosenbrock method of order 4 that uses the model's exact Jacobian from CasADi.
 * Inputs are held over a communication step, so the system is autonomous inside it.
 *
 * Internal step: with solver_tolerance > 0 it is error-controlled. RODAS4's embedded third-order solution
 * differs from the fourth-order one by the last stage k6 (x1 = x + sum a6j kj + k6), so k6 is the local
 * error estimate; a step is accepted when its weighted RMS norm (weights tolerance * (nominal + |x|)) is
 * <= 1, and the next step is h * clamp(0.9 err^(-1/4), 1/5, 6), as in Hairer's RODAS code, never longer than
 * solver_step and never growing right after a rejection. The proposal carries over from one doStep to the
 * next and is part of the FMU state, so a restored state steps exactly as it did the first time. With
 * solver_tolerance = 0 the steps are equal and no longer than solver_step (a fixed-step method).
 * A step in which an event indicator changes sign is repeated with shorter lengths (Illinois method)
 * until the crossing is bracketed within EVENT_TIME_TOLERANCE, then the discrete update is applied at that
 * instant.
 */
#include "instance.h"

#include <float.h>
#include <math.h>
#include <string.h>

#define EVENT_TIME_TOLERANCE 1e-12 /* s */
#define MAX_ROOT_ITERATIONS 200

/* RODAS4 coefficients in the form
 *   (I/(h gamma) - J) k_i = f(x + sum_j a_ij k_j) + sum_j (c_ij / h) k_j,   x1 = x + sum_i b_i k_i */
static const double GAMMA = 0.25;
static const double A[6][5] = {
    {0, 0, 0, 0, 0},
    {1.544, 0, 0, 0, 0},
    {0.9466785280815826, 0.2557011698983284, 0, 0, 0},
    {3.314825187068521, 2.896124015972201, 0.9986419139977817, 0, 0},
    {1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 0},
    {1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 1.0}};
static const double C[6][5] = {
    {0, 0, 0, 0, 0},
    {-5.6688, 0, 0, 0, 0},
    {-2.430093356833875, -0.2063599157091915, 0, 0, 0},
    {-0.1073529058151375, -9.594562251023355, -20.47028614809616, 0, 0},
    {7.496443313967647, -10.24680431464352, -33.99990352819905, 11.70890893206160, 0},
    {8.083246795921522, -7.981132988064893, -31.52159432874371, 16.31930543123136, -6.058818238834054}};
static const double B[6] = {1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 1.0,
                            1.0};

/* In-place LU factorisation with partial pivoting of a row-major n x n matrix. */
static int lu_factor(double *a, int n, int *pivots) {
    int i, j, k;
    for (k = 0; k < n; k++) {
        int p = k;
        double largest = fabs(a[k * n + k]);
        for (i = k + 1; i < n; i++)
            if (fabs(a[i * n + k]) > largest) {
                largest = fabs(a[i * n + k]);
                p = i;
            }
        pivots[k] = p;
        if (largest == 0.0 || !isfinite(largest)) return -1;
        if (p != k)
            for (j = 0; j < n; j++) {
                double t = a[k * n + j];
                a[k * n + j] = a[p * n + j];
                a[p * n + j] = t;
            }
        for (i = k + 1; i < n; i++) {
            double factor = a[i * n + k] /= a[k * n + k];
            for (j = k + 1; j < n; j++) a[i * n + j] -= factor * a[k * n + j];
        }
    }
    return 0;
}

static void lu_solve(const double *a, int n, const int *pivots, double *b) {
    int i, j;
    for (i = 0; i < n; i++) {
        double t = b[pivots[i]];
        b[pivots[i]] = b[i];
        b[i] = t;
        for (j = 0; j < i; j++) b[i] -= a[i * n + j] * b[j];
    }
    for (i = n - 1; i >= 0; i--) {
        for (j = i + 1; j < n; j++) b[i] -= a[i * n + j] * b[j];
        b[i] /= a[i * n + i];
    }
}

/* One RODAS4 step of length h from x0 (discrete states d held) into x1; x1 may not alias x0. The local error
 * estimate is left in instance->stage[5]. With `quiet`, a singular matrix or a non-finite result returns
 * STATUS_DISCARD without a log message (the adaptive solver then tries a shorter step). */
static Status rodas_step_checked(Instance *instance, const double *x0, const double *d, double h, double *x1,
                                 int quiet) {
    const ModelInfo *info = instance->info;
    int n = info->nx, i, j, s;
    Status status;
    if (n == 0) return STATUS_OK;
    instance->steps++; /* every attempt counts against the doStep's evaluation budget */
    status = instance->info->jacobian.eval ? STATUS_OK : STATUS_ERROR;
    instance->arg[0] = x0;
    instance->arg[1] = d;
    instance->arg[2] = instance->now.u;
    instance->arg[3] = instance->now.p;
    instance->res[0] = instance->jac;
    instance->res[1] = NULL;
    if (status != STATUS_OK || info->jacobian.eval(instance->arg, instance->res, instance->iw, instance->w, 0)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "evaluation of the Jacobian failed");
        return STATUS_ERROR;
    }
    /* M = I / (h gamma) - J; CasADi's dense Jacobian is column-major */
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++)
            instance->matrix[i * n + j] = (i == j ? 1.0 / (h * GAMMA) : 0.0) - instance->jac[j * n + i];
    if (lu_factor(instance->matrix, n, instance->pivots) != 0) {
        if (quiet) return STATUS_DISCARD;
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "singular iteration matrix at t = %.17g (step %g s)", instance->now.time, h);
        return STATUS_ERROR;
    }
    for (s = 0; s < 6; s++) {
        for (i = 0; i < n; i++) {
            double xi = x0[i];
            for (j = 0; j < s; j++) xi += A[s][j] * instance->stage[j][i];
            instance->x_stage[i] = xi;
        }
        status = instance_derivatives(instance, instance->x_stage, d, instance->rhs);
        if (status != STATUS_OK) return status;
        for (i = 0; i < n; i++) {
            double correction = 0.0;
            for (j = 0; j < s; j++) correction += C[s][j] * instance->stage[j][i];
            instance->stage[s][i] = instance->rhs[i] + correction / h;
        }
        lu_solve(instance->matrix, n, instance->pivots, instance->stage[s]);
    }
    for (i = 0; i < n; i++) {
        double xi = x0[i];
        for (s = 0; s < 6; s++) xi += B[s] * instance->stage[s][i];
        if (!isfinite(xi)) {
            if (quiet) return STATUS_DISCARD;
            instance_log(instance, STATUS_ERROR, "logStatusError",
                         "the solution is no longer finite at t = %.17g; try a smaller solver_step",
                         instance->now.time);
            return STATUS_ERROR;
        }
        x1[i] = xi;
    }
    return STATUS_OK;
}

static Status rodas_step(Instance *instance, const double *x0, const double *d, double h, double *x1) {
    return rodas_step_checked(instance, x0, d, h, x1, 0);
}

static int crossed(double before, double after) {
    return (before > 0.0 && after <= 0.0) || (before < 0.0 && after >= 0.0);
}

/* Locates the first sign change of indicator `k` in (0, h] by the Illinois method; returns the
 * fraction theta of h just past the crossing, with x_trial holding the state there. */
static Status locate_crossing(Instance *instance, int k, double h, double *theta_out) {
    double lo = 0.0, hi = 1.0, g_lo = instance->z_start[k], g_hi = instance->z_trial[k];
    int side = 0, iteration;
    Status status;
    for (iteration = 0; iteration < MAX_ROOT_ITERATIONS && (hi - lo) * h > EVENT_TIME_TOLERANCE; iteration++) {
        double theta = (lo * g_hi - hi * g_lo) / (g_hi - g_lo), g;
        if (!(theta > lo && theta < hi)) theta = 0.5 * (lo + hi);
        status = rodas_step(instance, instance->x_start, instance->now.d, theta * h, instance->x_trial);
        if (status != STATUS_OK) return status;
        status = instance_event_indicators(instance, instance->x_trial, instance->now.d, instance->z_trial);
        if (status != STATUS_OK) return status;
        g = instance->z_trial[k];
        if (crossed(instance->z_start[k], g)) {
            hi = theta;
            g_hi = g;
            if (side == -1) g_lo *= 0.5;
            side = -1;
            if (g == 0.0) break;
        } else {
            lo = theta;
            g_lo = g;
            if (side == 1) g_hi *= 0.5;
            side = 1;
        }
    }
    *theta_out = hi;
    return STATUS_OK;
}

/* Internal steps that one doStep may take. With fixed steps a longer step is refused up front (split it or
 * raise solver_step), so no call runs without bound; at the default 1 ms that is 50 s of simulated time
 * (about 2 s of computing for the Advanced model). With error control the count is only known as the step
 * goes: reaching it ends the step with an error. */
#define MAX_INTERNAL_STEPS 50000.0
/* All RODAS4 evaluations of one doStep, event location included: the hard stop for pathological cases
 * (an event at every internal step); reaching it puts the instance in the error state. */
#define MAX_EVALUATIONS_PER_STEP 120000LL
/* Step-size controller of Hairer's RODAS: h_new = h * clamp(SAFETY * err^(-1/4), MIN_FACTOR, MAX_FACTOR). */
#define SAFETY 0.9
#define MIN_FACTOR 0.2
#define MAX_FACTOR 6.0

static double solver_step_of(const Instance *instance) {
    const ModelInfo *info = instance->info;
    return info->solver_step_parameter >= 0 ? instance->now.p[info->solver_step_parameter] : 1e-3;
}

static double solver_tolerance_of(const Instance *instance) {
    const ModelInfo *info = instance->info;
    return info->solver_tolerance_parameter >= 0 ? instance->now.p[info->solver_tolerance_parameter] : 0.0;
}

/* The length of the equal internal steps that split a step h: no longer than solver_step, at least one. */
static double first_internal_step(double h, double solver_step) {
    return h / fmax(1.0, ceil(h / solver_step - 1e-9));
}

/* Weighted RMS norm of the local error estimate k6 (instance->stage[5]) of a step from x0 to x1. */
static double error_norm(const Instance *instance, const double *x0, const double *x1, double tolerance) {
    const ModelInfo *info = instance->info;
    double sum = 0.0;
    int i;
    if (info->nx == 0) return 0.0;
    for (i = 0; i < info->nx; i++) {
        double scale = tolerance * (info->state_nominal[i] + fmax(fabs(x0[i]), fabs(x1[i])));
        double ratio = instance->stage[5][i] / scale;
        sum += ratio * ratio;
    }
    return sqrt(sum / info->nx);
}

Status instance_check_step(Instance *instance, double current_time, double h) {
    double solver_step = solver_step_of(instance), tolerance = solver_tolerance_of(instance);
    if (!isfinite(current_time)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "communication point %g is not finite", current_time);
        return STATUS_ERROR;
    }
    if (!(h > 0.0) || !isfinite(h)) { /* FMI 2.0.4 and 3.0: communicationStepSize > 0 */
        instance_log(instance, STATUS_ERROR, "logStatusError", "communication step size %g must be finite and > 0",
                     h);
        return STATUS_ERROR;
    }
    if (fabs(current_time - instance->now.time) > 1e-9 * fmax(1.0, fabs(current_time))) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "doStep at t = %.17g but the FMU is at t = %.17g", current_time, instance->now.time);
        return STATUS_ERROR;
    }
    if (!(solver_step > 0.0) || !isfinite(solver_step)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "solver_step %g must be > 0", solver_step);
        return STATUS_ERROR;
    }
    if (!(tolerance >= 0.0) || !isfinite(tolerance)) {
        instance_log(instance, STATUS_ERROR, "logStatusError", "solver_tolerance %g must be >= 0", tolerance);
        return STATUS_ERROR;
    }
    /* the internal steps must advance the time in double precision (not so at t = 1e16 with 1 ms steps) */
    if (h > 0.0 && !(current_time + first_internal_step(h, solver_step) > current_time)) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "time cannot advance: at t = %.17g an internal step of %g s is lost to rounding", current_time,
                     first_internal_step(h, solver_step));
        return STATUS_ERROR;
    }
    /* solver_step is the longest internal step: the step needs at least h / solver_step of them */
    if (h / solver_step > MAX_INTERNAL_STEPS) {
        instance_log(instance, STATUS_ERROR, "logStatusError",
                     "a step of %g s needs %.3g internal steps of solver_step = %g s, more than the budget of %.0f "
                     "per doStep: split the step or raise solver_step",
                     h, ceil(h / solver_step), solver_step, MAX_INTERNAL_STEPS);
        return STATUS_ERROR;
    }
    return STATUS_OK;
}

/* The next internal step with error control: the proposal (solver_step before the first step), cut to
 * end exactly at the communication point; a remainder shorter than the proposal is split in two equal
 * steps rather than leaving a sliver. */
static double adaptive_internal_step(const Instance *instance, double remaining, double solver_step,
                                     double *proposal) {
    *proposal = instance->now.solver_step_next > 0.0 ? fmin(instance->now.solver_step_next, solver_step)
                                                     : solver_step;
    if (remaining <= *proposal) return remaining;
    if (remaining < 2.0 * *proposal) return 0.5 * remaining;
    return *proposal;
}

Status instance_do_step(Instance *instance, double current_time, double h) {
    const ModelInfo *info = instance->info;
    double end_time = current_time + h, solver_step = solver_step_of(instance);
    double tolerance = solver_tolerance_of(instance);
    size_t x_bytes = sizeof(double) * (size_t)info->nx;
    long long first_step = instance->steps, attempts = 0;
    int states_changed, discrete_changed, rejected = 0;
    Status status;

    /* inputs may have changed since the last step: settle the discrete states first */
    status = instance_event_iteration(instance, &states_changed, &discrete_changed);
    if (status != STATUS_OK) return status;

    while (end_time - instance->now.time > EVENT_TIME_TOLERANCE) {
        double remaining = end_time - instance->now.time, proposal = 0.0, dt;
        int k, first = -1, stuck;
        double first_theta = 2.0;

        /* fixed: equal internal steps no longer than solver_step; at least one (remaining may be far below
         * solver_step, e.g. just after an event located near the end) */
        dt = tolerance > 0.0 ? adaptive_internal_step(instance, remaining, solver_step, &proposal)
                             : first_internal_step(remaining, solver_step);
        /* the step must advance the time in double precision; with error control, a proposal shorter than
         * 16 eps max(|t|, solver_step) (after rejections) cannot be taken meaningfully either */
        stuck = !(instance->now.time + dt > instance->now.time) ||
                (tolerance > 0.0 && proposal < 16 * DBL_EPSILON * fmax(fabs(instance->now.time), solver_step));
        if (stuck || instance->steps - first_step > MAX_EVALUATIONS_PER_STEP ||
            attempts++ >= (long long)MAX_INTERNAL_STEPS) {
            if (!stuck)
                instance_log(instance, STATUS_ERROR, "logStatusError",
                             "doStep exceeded its budget of %.0f internal steps at t = %.17g", MAX_INTERNAL_STEPS,
                             instance->now.time);
            else if (tolerance > 0.0)
                instance_log(instance, STATUS_ERROR, "logStatusError",
                             "time cannot advance at t = %.17g: the error-controlled internal step fell to %g s "
                             "(solver_tolerance %g)", instance->now.time, proposal, tolerance);
            else
                instance_log(instance, STATUS_ERROR, "logStatusError", "time cannot advance at t = %.17g",
                             instance->now.time);
            return STATUS_ERROR;
        }
        memcpy(instance->x_start, instance->now.x, x_bytes);
        status = instance_event_indicators(instance, instance->x_start, instance->now.d, instance->z_start);
        if (status != STATUS_OK) return status;
        status = rodas_step_checked(instance, instance->x_start, instance->now.d, dt, instance->x_trial,
                                    tolerance > 0.0);
        if (tolerance > 0.0) {
            double error, factor, next;
            if (status == STATUS_DISCARD)
                error = INFINITY; /* singular or not finite: the step was far too long */
            else if (status != STATUS_OK)
                return status;
            else
                error = error_norm(instance, instance->x_start, instance->x_trial, tolerance);
            factor = error > 0.0 ? fmin(MAX_FACTOR, fmax(MIN_FACTOR, SAFETY * pow(error, -0.25))) : MAX_FACTOR;
            if (!(error <= 1.0)) {
                instance->now.solver_step_next = dt * fmin(factor, 1.0);
                rejected = 1;
                continue;
            }
            if (rejected) factor = fmin(factor, 1.0);
            next = dt * factor;
            if (dt < proposal) next = fmax(next, proposal); /* cut to the end: says nothing against the proposal */
            instance->now.solver_step_next = fmin(next, solver_step);
            rejected = 0;
        } else if (status != STATUS_OK) {
            return status;
        }
        status = instance_event_indicators(instance, instance->x_trial, instance->now.d, instance->z_trial);
        if (status != STATUS_OK) return status;
        for (k = 0; k < info->nz; k++) {
            if (crossed(instance->z_start[k], instance->z_trial[k])) {
                double theta;
                status = locate_crossing(instance, k, dt, &theta);
                if (status != STATUS_OK) return status;
                if (theta < first_theta) {
                    first_theta = theta;
                    first = k;
                }
                /* locate_crossing overwrote the trial state: redo the full step for the next indicator */
                status = rodas_step(instance, instance->x_start, instance->now.d, dt, instance->x_trial);
                if (status != STATUS_OK) return status;
                status = instance_event_indicators(instance, instance->x_trial, instance->now.d, instance->z_trial);
                if (status != STATUS_OK) return status;
            }
        }
        if (first >= 0) {
            status = rodas_step(instance, instance->x_start, instance->now.d, first_theta * dt, instance->now.x);
            if (status != STATUS_OK) return status;
            instance->now.time += first_theta * dt;
            instance_invalidate(instance);
            instance_log(instance, STATUS_OK, "logEvents", "indicator %d crossed zero at t = %.17g", first,
                         instance->now.time);
            status = instance_event_iteration(instance, &states_changed, &discrete_changed);
            if (status != STATUS_OK) return status;
        } else {
            memcpy(instance->now.x, instance->x_trial, x_bytes);
            instance->now.time += dt;
        }
        instance_invalidate(instance);
    }
    instance->now.time = end_time;
    instance_invalidate(instance);
    return STATUS_OK;
}
