/* A small generic FMI 2.0 co-simulation host: loads an FMU's shared library (dlopen on Linux, LoadLibrary
 * on Windows), instantiates it, sets start values, runs a fixed-step doStep loop and prints results.
 * Built by the tests with gcc (Linux) and with mingw-w64 (run under wine); the same file is the valgrind
 * driver (--repeat: instantiate/step/get-set-serialize-deserialize state/free loops).
 *
 *   fmi2_host LIBRARY GUID STEP STOP_TIME [--every N] [--repeat N] [r:VR=VALUE | i:VR=VALUE]... [o:VR | b:VR]...
 *
 * r:/i: set a Real/Integer start value before initialization; o:/b: a Real/Boolean output to print.
 * Output lines start with the marker "RESULT", then time and the outputs, each as the 16 hex digits of the
 * IEEE 754 bits (exact, independent of the C library's printf). Exit status 0 only if every call was OK. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

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

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup_experiment;
    fmi2EnterInitializationModeTYPE *enter_initialization;
    fmi2ExitInitializationModeTYPE *exit_initialization;
    fmi2TerminateTYPE *terminate;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2GetRealTYPE *get_real;
    fmi2GetBooleanTYPE *get_boolean;
    fmi2DoStepTYPE *do_step;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *serialized_size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
} Api;

static void logger(fmi2ComponentEnvironment environment, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    va_list args;
    (void)environment;
    fprintf(stderr, "[%s] %d %s: ", name ? name : "?", (int)status, category ? category : "");
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fputc('\n', stderr);
}

static void print_bits(double value) {
    unsigned int halves[2];
    unsigned long long bits;
    memcpy(&bits, &value, sizeof(bits));
    halves[0] = (unsigned int)(bits >> 32);
    halves[1] = (unsigned int)(bits & 0xffffffffu);
    printf(" %08x%08x", halves[0], halves[1]);
}

static int failed(const char *what, fmi2Status status) {
    if (status == fmi2OK) return 0;
    fprintf(stderr, "fmi2_host: %s returned status %d\n", what, (int)status);
    return 1;
}

#define CALL(what, expression)                                                                                 \
    do {                                                                                                       \
        if (failed(what, (expression))) goto fail;                                                            \
    } while (0)

/* One simulation; with roundtrip, the state is saved, serialized, deserialized and restored half-way. */
static int simulate(const Api *api, const char *guid, double step, double stop_time, int every, int roundtrip,
                    int print, const fmi2ValueReference *real_vr, const fmi2Real *real_values, int n_real,
                    const fmi2ValueReference *integer_vr, const fmi2Integer *integer_values, int n_integer,
                    const fmi2ValueReference *output_vr, int n_output, const fmi2ValueReference *boolean_vr,
                    int n_boolean) {
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component component = api->instantiate("host", fmi2CoSimulation, guid, "", &callbacks, fmi2False, fmi2False);
    fmi2Real outputs[MAX_VALUES];
    fmi2Boolean booleans[MAX_VALUES];
    long steps = (long)(stop_time / step + 0.5), k;
    int i, ok = 0;
    if (!component) {
        fprintf(stderr, "fmi2_host: fmi2Instantiate failed\n");
        return 1;
    }
    CALL("fmi2SetupExperiment", api->setup_experiment(component, fmi2False, 0.0, 0.0, fmi2True, stop_time));
    CALL("fmi2SetReal", api->set_real(component, real_vr, (size_t)n_real, real_values));
    CALL("fmi2SetInteger", api->set_integer(component, integer_vr, (size_t)n_integer, integer_values));
    CALL("fmi2EnterInitializationMode", api->enter_initialization(component));
    CALL("fmi2ExitInitializationMode", api->exit_initialization(component));
    for (k = 0; k <= steps; k++) {
        double time = (double)k * step; /* communication points k h, not a running sum */
        if (print && (k % every == 0 || k == steps)) {
            CALL("fmi2GetReal", api->get_real(component, output_vr, (size_t)n_output, outputs));
            CALL("fmi2GetBoolean", api->get_boolean(component, boolean_vr, (size_t)n_boolean, booleans));
            printf("RESULT");
            print_bits(time);
            for (i = 0; i < n_output; i++) print_bits(outputs[i]);
            for (i = 0; i < n_boolean; i++) print_bits(booleans[i] ? 1.0 : 0.0);
            printf("\n");
        }
        if (roundtrip && k == steps / 2) {
            fmi2FMUstate state = NULL, copy = NULL;
            size_t size = 0;
            fmi2Byte *bytes;
            CALL("fmi2GetFMUstate", api->get_state(component, &state));
            CALL("fmi2SerializedFMUstateSize", api->serialized_size(component, state, &size));
            bytes = (fmi2Byte *)malloc(size);
            if (!bytes) goto fail;
            if (failed("fmi2SerializeFMUstate", api->serialize(component, state, bytes, size)) ||
                failed("fmi2DeSerializeFMUstate", api->deserialize(component, bytes, size, &copy)) ||
                failed("fmi2SetFMUstate", api->set_state(component, copy))) {
                free(bytes);
                goto fail;
            }
            free(bytes);
            CALL("fmi2FreeFMUstate", api->free_state(component, &copy));
            CALL("fmi2FreeFMUstate", api->free_state(component, &state));
        }
        if (k < steps) CALL("fmi2DoStep", api->do_step(component, time, (double)(k + 1) * step - time, fmi2True));
    }
    CALL("fmi2Terminate", api->terminate(component));
    ok = 1;
fail:
    api->free_instance(component);
    return ok ? 0 : 1;
}

int main(int argc, char **argv) {
    fmi2ValueReference real_vr[MAX_VALUES], integer_vr[MAX_VALUES], output_vr[MAX_VALUES], boolean_vr[MAX_VALUES];
    fmi2Real real_values[MAX_VALUES];
    fmi2Integer integer_values[MAX_VALUES];
    int n_real = 0, n_integer = 0, n_output = 0, n_boolean = 0, every = 1, repeat = 0, i, status = 0;
    double step, stop_time;
    Library library;
    Api api;

    if (argc < 5) {
        fprintf(stderr, "usage: fmi2_host LIBRARY GUID STEP STOP_TIME [--every N] [--repeat N] "
                        "[r:VR=VALUE | i:VR=VALUE | o:VR | b:VR]...\n");
        return 2;
    }
    step = atof(argv[3]);
    stop_time = atof(argv[4]);
    for (i = 5; i < argc; i++) {
        const char *a = argv[i];
        unsigned int vr;
        if (!strcmp(a, "--every") && i + 1 < argc) {
            every = atoi(argv[++i]);
        } else if (!strcmp(a, "--repeat") && i + 1 < argc) {
            repeat = atoi(argv[++i]);
        } else if (a[0] == 'r' && a[1] == ':' && n_real < MAX_VALUES && sscanf(a + 2, "%u=", &vr) == 1) {
            real_vr[n_real] = vr;
            real_values[n_real++] = atof(strchr(a, '=') + 1);
        } else if (a[0] == 'i' && a[1] == ':' && n_integer < MAX_VALUES && sscanf(a + 2, "%u=", &vr) == 1) {
            integer_vr[n_integer] = vr;
            integer_values[n_integer++] = atoi(strchr(a, '=') + 1);
        } else if (a[0] == 'o' && a[1] == ':' && n_output < MAX_VALUES && sscanf(a + 2, "%u", &vr) == 1) {
            output_vr[n_output++] = vr;
        } else if (a[0] == 'b' && a[1] == ':' && n_boolean < MAX_VALUES && sscanf(a + 2, "%u", &vr) == 1) {
            boolean_vr[n_boolean++] = vr;
        } else {
            fprintf(stderr, "fmi2_host: bad argument %s\n", a);
            return 2;
        }
    }
    if (!(step > 0.0) || every < 1) {
        fprintf(stderr, "fmi2_host: STEP must be > 0 and --every >= 1\n");
        return 2;
    }
    library = open_library(argv[1]);
    if (!library) {
        fprintf(stderr, "fmi2_host: cannot load %s\n", argv[1]);
        return 1;
    }
#define LOAD(field, name)                                                                                      \
    if (!(*(void **)&api.field = symbol(library, name))) {                                                     \
        fprintf(stderr, "fmi2_host: %s not exported\n", name);                                                \
        return 1;                                                                                              \
    }
    LOAD(instantiate, "fmi2Instantiate")
    LOAD(free_instance, "fmi2FreeInstance")
    LOAD(setup_experiment, "fmi2SetupExperiment")
    LOAD(enter_initialization, "fmi2EnterInitializationMode")
    LOAD(exit_initialization, "fmi2ExitInitializationMode")
    LOAD(terminate, "fmi2Terminate")
    LOAD(set_real, "fmi2SetReal")
    LOAD(set_integer, "fmi2SetInteger")
    LOAD(get_real, "fmi2GetReal")
    LOAD(get_boolean, "fmi2GetBoolean")
    LOAD(do_step, "fmi2DoStep")
    LOAD(get_state, "fmi2GetFMUstate")
    LOAD(set_state, "fmi2SetFMUstate")
    LOAD(free_state, "fmi2FreeFMUstate")
    LOAD(serialized_size, "fmi2SerializedFMUstateSize")
    LOAD(serialize, "fmi2SerializeFMUstate")
    LOAD(deserialize, "fmi2DeSerializeFMUstate")

    status = simulate(&api, argv[2], step, stop_time, every, 0, 1, real_vr, real_values, n_real, integer_vr,
                      integer_values, n_integer, output_vr, n_output, boolean_vr, n_boolean);
    for (i = 0; i < repeat && status == 0; i++)
        status = simulate(&api, argv[2], step, stop_time, every, 1, 0, real_vr, real_values, n_real, integer_vr,
                          integer_values, n_integer, output_vr, n_output, boolean_vr, n_boolean);
    fflush(stdout);
    close_library(library);
    return status;
}
