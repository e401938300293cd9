/* A hostile vehicle FMU (FMI 2.0 co-simulation) for the tests: a plain point-mass car that misbehaves on demand.
 *
 * Its parameter `mode` picks the misbehaviour, which starts at the parameter `trigger_time` (s):
 *   0 honest car            1 hangs in fmi2DoStep (a busy loop)   2 crashes (SIGSEGV)   3 calls exit(0)
 *   4 outputs NaN           5 outputs +inf                         6 outputs 1e308
 *   7 logs a message that is not UTF-8 and holds terminal escapes, on every step (and drives on honestly)
 *   8 fmi2SetFMUstate returns OK but restores nothing (the capability lie; the XML declares the capability)
 *   9 fmi2ExitInitializationMode fails (with a log message)
 * fmi2Instantiate refuses a GUID other than HOSTILE_GUID (a wrong GUID in the modelDescription).
 * For the tests to act when it happens, not after a guessed time: on entering the hang it creates the file named by
 * $HOSTILE_HANG_FILE, and each fmi2Instantiate appends its resource location to the file $HOSTILE_INSTANCES_FILE.
 *
 * Built by tests/hostile_fmus.py with gcc at test time; the model description is written there too. */

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define HOSTILE_GUID "{8c4e810f-3df3-4a00-8276-176fa3c9f000}"

enum { THROTTLE, BRAKE, STEER, X, Y, YAW, SPEED, V_INIT, MODE, TRIGGER_TIME, N_REALS };

typedef struct {
    fmi2Real r[N_REALS];
    fmi2Real time;
} State;

typedef struct {
    State now;
    fmi2CallbackFunctions callbacks;
    char name[64];
    int initialized;
} Car;

static void say(Car *car, fmi2Status status, const char *message) {
    if (car->callbacks.logger)
        car->callbacks.logger(car->callbacks.componentEnvironment, car->name, status, "logAll", "%s", message);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *callbacks, fmi2Boolean visible, fmi2Boolean logging) {
    Car *car;
    const char *instances = getenv("HOSTILE_INSTANCES_FILE");
    FILE *file;
    (void)visible;
    (void)logging;
    if (type != fmi2CoSimulation || !guid || strcmp(guid, HOSTILE_GUID) != 0) return NULL;
    if (instances && (file = fopen(instances, "a")) != NULL) {
        fprintf(file, "%s\n", location ? location : "");
        fclose(file);
    }
    car = (Car *)calloc(1, sizeof(Car));
    if (!car) return NULL;
    if (callbacks) car->callbacks = *callbacks;
    strncpy(car->name, name ? name : "hostile", sizeof(car->name) - 1);
    car->now.r[TRIGGER_TIME] = 1.0;
    return car;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[]) {
    (void)c;
    (void)on;
    (void)n;
    (void)categories;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean a, fmi2Real b, fmi2Real start, fmi2Boolean d,
                               fmi2Real e) {
    (void)a;
    (void)b;
    (void)d;
    (void)e;
    ((Car *)c)->now.time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    (void)c;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Car *car = (Car *)c;
    if ((int)car->now.r[MODE] == 9) {
        say(car, fmi2Error, "cannot initialise: the engine is missing");
        return fmi2Error;
    }
    car->now.r[SPEED] = car->now.r[V_INIT];
    car->initialized = 1;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    (void)c;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    (void)c;
    return fmi2OK;
}

static int misbehaving(const Car *car, int mode) {
    return (int)car->now.r[MODE] == mode && car->now.time >= car->now.r[TRIGGER_TIME];
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Car *car = (Car *)c;
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] >= N_REALS) return fmi2Error;
        value[i] = car->now.r[vr[i]];
        if (vr[i] == SPEED || vr[i] == X) {
            if (misbehaving(car, 4)) value[i] = NAN;
            if (misbehaving(car, 5)) value[i] = INFINITY;
            if (misbehaving(car, 6)) value[i] = 1e308;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Car *car = (Car *)c;
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] >= N_REALS) return fmi2Error;
        car->now.r[vr[i]] = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
    (void)c;
    (void)vr;
    (void)value;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[]) {
    (void)c;
    (void)vr;
    (void)value;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]) {
    (void)c;
    (void)vr;
    (void)value;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[]) {
    (void)c;
    (void)vr;
    (void)value;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    (void)c;
    (void)vr;
    (void)value;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[]) {
    (void)c;
    (void)vr;
    (void)value;
    return n ? fmi2Error : fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_prior) {
    Car *car = (Car *)c;
    fmi2Real *r = car->now.r, a, v;
    volatile int spin = 1;
    (void)no_set_prior;
    (void)t;
    if (misbehaving(car, 1)) {
        const char *hang = getenv("HOSTILE_HANG_FILE");
        FILE *file;
        if (hang && (file = fopen(hang, "w")) != NULL) fclose(file);
        while (spin) {
        }
    }
    if (misbehaving(car, 2)) raise(SIGSEGV);
    if (misbehaving(car, 3)) exit(0);
    if ((int)r[MODE] == 7)
        say(car, fmi2OK, "step \xff\xfe\xc3\x28 not UTF-8 \x1b[2J\x1b[31m red \x07 bell");
    /* a point-mass car: 3 m/s2 of drive, 8 m/s2 of brake, kinematic steering on a 2.7 m wheelbase */
    a = 3.0 * r[THROTTLE] - 8.0 * r[BRAKE];
    v = r[SPEED] + a * h;
    if (v < 0.0) v = 0.0;
    r[YAW] += 0.5 * (r[SPEED] + v) * tan(r[STEER]) / 2.7 * h;
    r[X] += 0.5 * (r[SPEED] + v) * cos(r[YAW]) * h;
    r[Y] += 0.5 * (r[SPEED] + v) * sin(r[YAW]) * h;
    r[SPEED] = v;
    car->now.time += h;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    (void)c;
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Car *car = (Car *)c;
    State *saved = *state ? (State *)*state : (State *)malloc(sizeof(State));
    if (!saved) return fmi2Error;
    *saved = car->now;
    *state = saved;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    Car *car = (Car *)c;
    if (!state) return fmi2Error;
    if ((int)car->now.r[MODE] == 8) return fmi2OK; /* the lie: nothing restored */
    car->now = *(State *)state;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)c;
    if (state && *state) {
        free(*state);
        *state = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    (void)c;
    (void)s;
    (void)n;
    return fmi2Error;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    (void)c;
    (void)s;
    (void)b;
    (void)n;
    return fmi2Error;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) {
    (void)c;
    (void)b;
    (void)n;
    (void)s;
    return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference k[], size_t nk, const fmi2Real dk[],
                                        fmi2Real du[]) {
    (void)c;
    (void)u;
    (void)nu;
    (void)k;
    (void)nk;
    (void)dk;
    (void)du;
    return fmi2Error;
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)c;
    (void)vr;
    (void)n;
    (void)order;
    (void)value;
    return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)c;
    (void)vr;
    (void)n;
    (void)order;
    (void)value;
    return fmi2Error;
}
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) {
    (void)c;
    (void)s;
    (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) {
    (void)c;
    (void)s;
    (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) {
    (void)c;
    (void)s;
    (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) {
    (void)c;
    (void)s;
    (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) {
    (void)c;
    (void)s;
    (void)v;
    return fmi2Discard;
}
