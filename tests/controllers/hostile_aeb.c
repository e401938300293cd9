/* A hostile controller FMU (FMI 2.0 co-simulation) for the tests: an AEB that misbehaves on demand, the controller's
 * counterpart of tests/vehicles/hostile_car.c.
 *
 * Honest, it latches a full brake request (`brake` = 1) at the first step whose input `ttc` (s) is at most the
 * parameter `ttc_trigger`. Its parameter `mode` picks the misbehaviour, which starts at the step from the parameter
 * `trigger_time` (s) on:
 *   0 honest    1 hangs in fmi2DoStep (a busy loop)    2 crashes (SIGSEGV)    3 calls exit(0)
 *   4 requests NaN    5 requests +inf
 *   6 the capability lie: the XML declares canGetAndSetFMUstate, fmi2SetFMUstate returns OK and restores nothing
 *     (otherwise honest)    7 requests 1e308 (finite, beyond any request)
 * For the tests to act when it happens, not after a guessed time: on entering the hang it creates the file named by
 * $HOSTILE_HANG_FILE; and each call of fmi2GetFMUstate, fmi2SetFMUstate or fmi2FreeFMUstate appends a line to the
 * file $HOSTILE_STATE_FILE (the test reads whether sdl-fmu ever saved or restored the controller's state).
 *
 * Built by tests/hostile_fmus.py with gcc at test time; the model description is written there too. */

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define HOSTILE_GUID "{5d1e7f3a-4b2c-4e8d-9a61-0c3f2b7e4a10}"

enum { TTC, BRAKE, MODE, TRIGGER_TIME, TTC_TRIGGER, N_REALS };

typedef struct {
    fmi2Real r[N_REALS];
    fmi2Real time;
    int latched;
} State;

typedef struct {
    State now;
} Aeb;

static void note(const char *call) {
    const char *path = getenv("HOSTILE_STATE_FILE");
    FILE *file;
    if (path && (file = fopen(path, "a")) != NULL) {
        fprintf(file, "%s\n", call);
        fclose(file);
    }
}

static int misbehaving(const Aeb *aeb, int mode) {
    return (int)aeb->now.r[MODE] == mode && aeb->now.time >= aeb->now.r[TRIGGER_TIME];
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *callbacks, fmi2Boolean visible, fmi2Boolean logging) {
    Aeb *aeb;
    (void)name;
    (void)location;
    (void)callbacks;
    (void)visible;
    (void)logging;
    if (type != fmi2CoSimulation || !guid || strcmp(guid, HOSTILE_GUID) != 0) return NULL;
    aeb = (Aeb *)calloc(1, sizeof(Aeb));
    if (!aeb) return NULL;
    aeb->now.r[TRIGGER_TIME] = 1.0;
    aeb->now.r[TTC_TRIGGER] = 1.0;
    aeb->now.r[TTC] = 1000.0;
    return aeb;
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
    ((Aeb *)c)->now.time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    (void)c;
    return fmi2OK;
}
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    (void)c;
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

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Aeb *aeb = (Aeb *)c;
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] >= N_REALS) return fmi2Error;
        value[i] = aeb->now.r[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Aeb *aeb = (Aeb *)c;
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] >= N_REALS || vr[i] == BRAKE) return fmi2Error;
        aeb->now.r[vr[i]] = value[i];
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
    Aeb *aeb = (Aeb *)c;
    fmi2Real *r = aeb->now.r;
    volatile int spin = 1;
    (void)no_set_prior;
    aeb->now.time = t;
    if (misbehaving(aeb, 1)) {
        const char *hang = getenv("HOSTILE_HANG_FILE");
        FILE *file;
        if (hang && (file = fopen(hang, "w")) != NULL) fclose(file);
        while (spin) {
        }
    }
    if (misbehaving(aeb, 2)) raise(SIGSEGV);
    if (misbehaving(aeb, 3)) exit(0);
    if (r[TTC] <= r[TTC_TRIGGER]) aeb->now.latched = 1;
    r[BRAKE] = aeb->now.latched ? 1.0 : 0.0;
    if (misbehaving(aeb, 4)) r[BRAKE] = NAN;
    if (misbehaving(aeb, 5)) r[BRAKE] = INFINITY;
    if (misbehaving(aeb, 7)) r[BRAKE] = 1e308; /* finite, but no request: a double's largest decade */
    aeb->now.time = t + h;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    (void)c;
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Aeb *aeb = (Aeb *)c;
    State *saved = *state ? (State *)*state : (State *)malloc(sizeof(State));
    note("fmi2GetFMUstate");
    if (!saved) return fmi2Error;
    *saved = aeb->now;
    *state = saved;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    Aeb *aeb = (Aeb *)c;
    note("fmi2SetFMUstate");
    if (!state) return fmi2Error;
    if ((int)aeb->now.r[MODE] == 6) return fmi2OK; /* the lie: nothing restored */
    aeb->now = *(State *)state;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)c;
    note("fmi2FreeFMUstate");
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
