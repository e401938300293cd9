/* A small generic FMI 2.0 / 3.0 co-simulation host: loads an FMU's shared library (dlopen on Linux,
 * LoadLibrary on Windows), instantiates it, sets start values, runs a fixed-step doStep loop and prints results.
 * Built by the tests with gcc (Linux) and with mingw-w64 (run under wine); the same file is the valgrind
 * driver (--repeat: instantiate/step/get-serialize-deserialize-set state/free loops).
 * --misuse-states: after initialization, FMU-state handles are misused as importers do (fmusim v0.0.39's state-file
 * options call FreeFMUstate(c, state) where &state is due; freed, double-freed, foreign and wild handles); every
 * misuse must return an error (the FMU logs why) and the instance must go on.
 *
 *   fmi_host [--fmi3] LIBRARY TOKEN STEP STOP_TIME [--every N] [--repeat N] [--misuse-states]
 *            [--resources LOCATION] [r:VR=VALUE | i:VR=VALUE]... [o:VR | b:VR]...
 *
 * TOKEN is the GUID (FMI 2.0) or instantiation token (FMI 3.0). r:/i: set a Real/Integer start value before
 * initialization; o:/b: a Real/Boolean output to print. Output lines start with the marker "RESULT", then time
 * and the outputs, each as the 16 hex digits of its IEEE 754 bits (exact, independent of the C library's
 * printf). --resources: the resource location passed to instantiate (FMI 2.0: a file: URI; FMI 3.0: a path; default
 * none). Exit status 0 only if every call was OK. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmi3Functions.h"

#ifdef _WIN32
#include <windows.h>
typedef HMODULE Library;
static Library open_library(const char *path) { return LoadLibraryA(path); }
static void *symbol(Library library, const char *name) { return (void *)GetProcAddress(library, name); }
static void close_library(Library library) { FreeLibrary(library); }
#else
#include <dlfcn.h>
typedef void *Library;
static Library open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol(Library library, const char *name) { return dlsym(library, name); }
static void close_library(Library library) { dlclose(library); }
#endif

#define MAX_VALUES 64

static Library library;
static int symbols_missing;
static const char *resources = "";

static void *load(const char *name) {
    void *function = symbol(library, name);
    if (!function) {
        fprintf(stderr, "fmi_host: %s not exported\n", name);
        symbols_missing = 1;
    }
    return function;
}

/* ---- FMI 2.0 ------------------------------------------------------------------------------------------------ */

static void logger2(fmi2ComponentEnvironment environment, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    va_list args;
    (void)environment;
    fprintf(stderr, "[%s] %d %s: ", name ? name : "?", (int)status, category ? category : "");
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fputc('\n', stderr);
}

static const fmi2CallbackFunctions callbacks2 = {logger2, calloc, free, NULL, NULL};

/* ---- FMI 3.0 ------------------------------------------------------------------------------------------------ */

static void logger3(fmi3InstanceEnvironment environment, fmi3Status status, fmi3String category,
                    fmi3String message) {
    (void)environment;
    fprintf(stderr, "%d %s: %s\n", (int)status, category ? category : "", message ? message : "");
}

/* ---- one interface over both ----------------------------------------------------------------------------------- */

typedef struct {
    int version;
    /* FMI 2.0 */
    fmi2InstantiateTYPE *instantiate2;
    fmi2FreeInstanceTYPE *free2;
    fmi2SetupExperimentTYPE *setup2;
    fmi2EnterInitializationModeTYPE *enter2;
    fmi2ExitInitializationModeTYPE *exit2;
    fmi2TerminateTYPE *terminate2;
    fmi2SetRealTYPE *set_real2;
    fmi2SetIntegerTYPE *set_integer2;
    fmi2GetRealTYPE *get_real2;
    fmi2GetBooleanTYPE *get_boolean2;
    fmi2DoStepTYPE *do_step2;
    fmi2GetFMUstateTYPE *get_state2;
    fmi2SetFMUstateTYPE *set_state2;
    fmi2FreeFMUstateTYPE *free_state2;
    fmi2SerializedFMUstateSizeTYPE *size2;
    fmi2SerializeFMUstateTYPE *serialize2;
    fmi2DeSerializeFMUstateTYPE *deserialize2;
    /* FMI 3.0 */
    fmi3InstantiateCoSimulationTYPE *instantiate3;
    fmi3FreeInstanceTYPE *free3;
    fmi3EnterInitializationModeTYPE *enter3;
    fmi3ExitInitializationModeTYPE *exit3;
    fmi3TerminateTYPE *terminate3;
    fmi3SetFloat64TYPE *set_real3;
    fmi3SetInt32TYPE *set_integer3;
    fmi3GetFloat64TYPE *get_real3;
    fmi3GetBooleanTYPE *get_boolean3;
    fmi3DoStepTYPE *do_step3;
    fmi3GetFMUStateTYPE *get_state3;
    fmi3SetFMUStateTYPE *set_state3;
    fmi3FreeFMUStateTYPE *free_state3;
    fmi3SerializedFMUStateSizeTYPE *size3;
    fmi3SerializeFMUStateTYPE *serialize3;
    fmi3DeserializeFMUStateTYPE *deserialize3;
} Api;

#define LOAD(field, name) *(void **)&api->field = load(name)

static void load_api(Api *api) {
    if (api->version == 2) {
        LOAD(instantiate2, "fmi2Instantiate");
        LOAD(free2, "fmi2FreeInstance");
        LOAD(setup2, "fmi2SetupExperiment");
        LOAD(enter2, "fmi2EnterInitializationMode");
        LOAD(exit2, "fmi2ExitInitializationMode");
        LOAD(terminate2, "fmi2Terminate");
        LOAD(set_real2, "fmi2SetReal");
        LOAD(set_integer2, "fmi2SetInteger");
        LOAD(get_real2, "fmi2GetReal");
        LOAD(get_boolean2, "fmi2GetBoolean");
        LOAD(do_step2, "fmi2DoStep");
        LOAD(get_state2, "fmi2GetFMUstate");
        LOAD(set_state2, "fmi2SetFMUstate");
        LOAD(free_state2, "fmi2FreeFMUstate");
        LOAD(size2, "fmi2SerializedFMUstateSize");
        LOAD(serialize2, "fmi2SerializeFMUstate");
        LOAD(deserialize2, "fmi2DeSerializeFMUstate");
    } else {
        LOAD(instantiate3, "fmi3InstantiateCoSimulation");
        LOAD(free3, "fmi3FreeInstance");
        LOAD(enter3, "fmi3EnterInitializationMode");
        LOAD(exit3, "fmi3ExitInitializationMode");
        LOAD(terminate3, "fmi3Terminate");
        LOAD(set_real3, "fmi3SetFloat64");
        LOAD(set_integer3, "fmi3SetInt32");
        LOAD(get_real3, "fmi3GetFloat64");
        LOAD(get_boolean3, "fmi3GetBoolean");
        LOAD(do_step3, "fmi3DoStep");
        LOAD(get_state3, "fmi3GetFMUState");
        LOAD(set_state3, "fmi3SetFMUState");
        LOAD(free_state3, "fmi3FreeFMUState");
        LOAD(size3, "fmi3SerializedFMUStateSize");
        LOAD(serialize3, "fmi3SerializeFMUState");
        LOAD(deserialize3, "fmi3DeserializeFMUState");
    }
}

static void print_bits(double value) {
    unsigned int halves[2];
    unsigned long long bits;
    memcpy(&bits, &value, sizeof(bits));
    halves[0] = (unsigned int)(bits >> 32);
    halves[1] = (unsigned int)(bits & 0xffffffffu);
    printf(" %08x%08x", halves[0], halves[1]);
}

static int failed(const char *what, int status) {
    if (status == 0) return 0;
    fprintf(stderr, "fmi_host: %s returned status %d\n", what, status);
    return 1;
}

#define CALL(what, expression)                                                                                 \
    do {                                                                                                       \
        if (failed(what, (int)(expression))) goto fail;                                                       \
    } while (0)

typedef struct {
    unsigned int real_vr[MAX_VALUES], integer_vr[MAX_VALUES], output_vr[MAX_VALUES], boolean_vr[MAX_VALUES];
    double real_values[MAX_VALUES];
    int integer_values[MAX_VALUES];
    int n_real, n_integer, n_output, n_boolean;
} Values;

/* get state, serialize it, deserialize it, set it, free both */
static int state_roundtrip(const Api *api, void *c) {
    void *state = NULL, *copy = NULL;
    size_t size = 0;
    char *bytes;
    int status;
    if (api->version == 2) {
        if (failed("fmi2GetFMUstate", api->get_state2(c, &state)) ||
            failed("fmi2SerializedFMUstateSize", api->size2(c, state, &size)))
            return 1;
    } else if (failed("fmi3GetFMUState", api->get_state3(c, &state)) ||
               failed("fmi3SerializedFMUStateSize", api->size3(c, state, &size))) {
        return 1;
    }
    bytes = (char *)malloc(size);
    if (!bytes) return 1;
    if (api->version == 2)
        status = failed("fmi2SerializeFMUstate", api->serialize2(c, state, bytes, size)) ||
                 failed("fmi2DeSerializeFMUstate", api->deserialize2(c, bytes, size, &copy)) ||
                 failed("fmi2SetFMUstate", api->set_state2(c, copy)) ||
                 failed("fmi2FreeFMUstate", api->free_state2(c, &copy)) ||
                 failed("fmi2FreeFMUstate", api->free_state2(c, &state));
    else
        status = failed("fmi3SerializeFMUState", api->serialize3(c, state, (fmi3Byte *)bytes, size)) ||
                 failed("fmi3DeserializeFMUState", api->deserialize3(c, (fmi3Byte *)bytes, size, &copy)) ||
                 failed("fmi3SetFMUState", api->set_state3(c, copy)) ||
                 failed("fmi3FreeFMUState", api->free_state3(c, &copy)) ||
                 failed("fmi3FreeFMUState", api->free_state3(c, &state));
    free(bytes);
    return status;
}

static int expect_error(const char *what, int status) {
    if (status == (int)fmi2Error) {
        printf("MISUSE %s refused\n", what);
        return 0;
    }
    fprintf(stderr, "fmi_host: misuse %s returned status %d, expected an error\n", what, status);
    return 1;
}

/* the handle misuse of --misuse-states on instance c (other: a second instance of the same FMU) */
static int misuse_states(const Api *api, void *c, void *other) {
    void *state = NULL, *stale, *foreign = NULL;
    double wild[8] = {0};
    int v3 = api->version == 3, status = 0;
#define GET(instance, pointer) (v3 ? (int)api->get_state3(instance, pointer) : (int)api->get_state2(instance, pointer))
#define SET(instance, handle) (v3 ? (int)api->set_state3(instance, handle) : (int)api->set_state2(instance, handle))
#define FREE(instance, pointer)                                                                                   \
    (v3 ? (int)api->free_state3(instance, (fmi3FMUState *)(pointer))                                              \
        : (int)api->free_state2(instance, (fmi2FMUstate *)(pointer)))
    if (failed("GetFMUstate", GET(c, &state)) || failed("GetFMUstate (other instance)", GET(other, &foreign)))
        return 1;
    status |= expect_error("FreeFMUstate(c, state) where &state is due", FREE(c, state));
    status |= failed("SetFMUstate after the refused free", SET(c, state));
    stale = state;
    status |= failed("FreeFMUstate", FREE(c, &state));
    status |= expect_error("SetFMUstate of a freed handle", SET(c, stale));
    status |= expect_error("FreeFMUstate twice (double free)", FREE(c, &stale));
    status |= expect_error("SetFMUstate of another instance's handle", SET(c, foreign));
    status |= expect_error("FreeFMUstate of another instance's handle", FREE(c, &foreign));
    status |= expect_error("SetFMUstate of a wild pointer", SET(c, (void *)wild));
    status |= failed("FreeFMUstate (other instance)", FREE(other, &foreign));
#undef GET
#undef SET
#undef FREE
    return status;
}

/* One simulation; with roundtrip, the state is saved, serialized, deserialized and restored half-way. */
static int simulate(const Api *api, const char *token, double step, double stop_time, int every, int roundtrip,
                    int print, int misuse, const Values *v) {
    void *c, *other = NULL;
    double outputs[MAX_VALUES];
    fmi2Boolean booleans2[MAX_VALUES];
    fmi3Boolean booleans3[MAX_VALUES];
    fmi3Boolean flag;
    fmi3Float64 last_time;
    int integers3[MAX_VALUES];
    long steps = (long)(stop_time / step + 0.5), k;
    int i, ok = 0, v3 = api->version == 3;
    for (i = 0; i < v->n_integer; i++) integers3[i] = v->integer_values[i];
    c = v3 ? api->instantiate3("host", token, resources, fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0, NULL,
                               logger3, NULL)
           : api->instantiate2("host", fmi2CoSimulation, token, resources, &callbacks2, fmi2False, fmi2False);
    if (!c) {
        fprintf(stderr, "fmi_host: instantiation failed\n");
        return 1;
    }
    if (v3) {
        CALL("fmi3SetFloat64", api->set_real3(c, v->real_vr, v->n_real, v->real_values, v->n_real));
        CALL("fmi3SetInt32", api->set_integer3(c, v->integer_vr, v->n_integer, integers3, v->n_integer));
        CALL("fmi3EnterInitializationMode", api->enter3(c, fmi3False, 0.0, 0.0, fmi3True, stop_time));
        CALL("fmi3ExitInitializationMode", api->exit3(c));
    } else {
        CALL("fmi2SetupExperiment", api->setup2(c, fmi2False, 0.0, 0.0, fmi2True, stop_time));
        CALL("fmi2SetReal", api->set_real2(c, v->real_vr, v->n_real, v->real_values));
        CALL("fmi2SetInteger", api->set_integer2(c, v->integer_vr, v->n_integer, v->integer_values));
        CALL("fmi2EnterInitializationMode", api->enter2(c));
        CALL("fmi2ExitInitializationMode", api->exit2(c));
    }
    if (misuse) {
        other = v3 ? api->instantiate3("other", token, resources, fmi3False, fmi3False, fmi3False, fmi3False, NULL,
                                       0, NULL, logger3, NULL)
                   : api->instantiate2("other", fmi2CoSimulation, token, resources, &callbacks2, fmi2False,
                                       fmi2False);
        if (!other || misuse_states(api, c, other)) goto fail;
    }
    for (k = 0; k <= steps; k++) {
        double time = (double)k * step; /* communication points k h, not a running sum */
        if (print && (k % every == 0 || k == steps)) {
            if (v3) {
                CALL("fmi3GetFloat64", api->get_real3(c, v->output_vr, v->n_output, outputs, v->n_output));
                CALL("fmi3GetBoolean", api->get_boolean3(c, v->boolean_vr, v->n_boolean, booleans3, v->n_boolean));
            } else {
                CALL("fmi2GetReal", api->get_real2(c, v->output_vr, v->n_output, outputs));
                CALL("fmi2GetBoolean", api->get_boolean2(c, v->boolean_vr, v->n_boolean, booleans2));
            }
            printf("RESULT");
            print_bits(time);
            for (i = 0; i < v->n_output; i++) print_bits(outputs[i]);
            for (i = 0; i < v->n_boolean; i++) print_bits((v3 ? booleans3[i] : booleans2[i]) ? 1.0 : 0.0);
            printf("\n");
        }
        if (roundtrip && k == steps / 2 && state_roundtrip(api, c)) goto fail;
        if (k < steps) {
            double h = (double)(k + 1) * step - time;
            if (v3)
                CALL("fmi3DoStep", api->do_step3(c, time, h, fmi3True, &flag, &flag, &flag, &last_time));
            else
                CALL("fmi2DoStep", api->do_step2(c, time, h, fmi2True));
        }
    }
    CALL("Terminate", v3 ? api->terminate3(c) : api->terminate2(c));
    ok = 1;
fail:
    if (v3)
        api->free3(c);
    else
        api->free2(c);
    if (other) {
        if (v3)
            api->free3(other);
        else
            api->free2(other);
    }
    return ok ? 0 : 1;
}

int main(int argc, char **argv) {
    Values values;
    Api api;
    int every = 1, repeat = 0, misuse = 0, i, status, first = 1;
    double step, stop_time;

    memset(&values, 0, sizeof(values));
    memset(&api, 0, sizeof(api));
    api.version = 2;
    if (argc > 1 && !strcmp(argv[1], "--fmi3")) {
        api.version = 3;
        first = 2;
    }
    if (argc < first + 4) {
        fprintf(stderr, "usage: fmi_host [--fmi3] LIBRARY TOKEN STEP STOP_TIME [--every N] [--repeat N] "
                        "[r:VR=VALUE | i:VR=VALUE | o:VR | b:VR]...\n");
        return 2;
    }
    step = atof(argv[first + 2]);
    stop_time = atof(argv[first + 3]);
    for (i = first + 4; i < argc; i++) {
        const char *a = argv[i];
        unsigned int vr;
        if (!strcmp(a, "--every") && i + 1 < argc) {
            every = atoi(argv[++i]);
        } else if (!strcmp(a, "--misuse-states")) {
            misuse = 1;
        } else if (!strcmp(a, "--resources") && i + 1 < argc) {
            resources = argv[++i];
        } else if (!strcmp(a, "--repeat") && i + 1 < argc) {
            repeat = atoi(argv[++i]);
        } else if (a[0] == 'r' && a[1] == ':' && values.n_real < MAX_VALUES && sscanf(a + 2, "%u=", &vr) == 1) {
            values.real_vr[values.n_real] = vr;
            values.real_values[values.n_real++] = atof(strchr(a, '=') + 1);
        } else if (a[0] == 'i' && a[1] == ':' && values.n_integer < MAX_VALUES && sscanf(a + 2, "%u=", &vr) == 1) {
            values.integer_vr[values.n_integer] = vr;
            values.integer_values[values.n_integer++] = atoi(strchr(a, '=') + 1);
        } else if (a[0] == 'o' && a[1] == ':' && values.n_output < MAX_VALUES && sscanf(a + 2, "%u", &vr) == 1) {
            values.output_vr[values.n_output++] = vr;
        } else if (a[0] == 'b' && a[1] == ':' && values.n_boolean < MAX_VALUES && sscanf(a + 2, "%u", &vr) == 1) {
            values.boolean_vr[values.n_boolean++] = vr;
        } else {
            fprintf(stderr, "fmi_host: bad argument %s\n", a);
            return 2;
        }
    }
    if (!(step > 0.0) || every < 1) {
        fprintf(stderr, "fmi_host: STEP must be > 0 and --every >= 1\n");
        return 2;
    }
    library = open_library(argv[first]);
    if (!library) {
        fprintf(stderr, "fmi_host: cannot load %s\n", argv[first]);
        return 1;
    }
    load_api(&api);
    if (symbols_missing) return 1;
    status = simulate(&api, argv[first + 1], step, stop_time, every, 0, 1, misuse, &values);
    for (i = 0; i < repeat && status == 0; i++)
        status = simulate(&api, argv[first + 1], step, stop_time, every, 1, 0, misuse, &values);
    fflush(stdout);
    close_library(library);
    return status;
}
