"""Rebuild from sources anywhere: the FMU's sources/ (with the FMI headers) and buildDescription.xml give a
binary that links libm itself, so it loads in a plain C host that does not link libm, and reproduces the
analytic stop. Built two ways: the plain compiler line of the README and fmpy's CMake build."""

import shutil
import subprocess
import zipfile
import xml.etree.ElementTree as ET

import pytest
from fmpy import read_model_description

from helpers import COSIM_TOLERANCE, expected_distance

HOST = r"""
/* A plain C host: dlopen()s an FMU binary, brakes from v0 to a stop in co-simulation, prints s.
 * It uses nothing from libm and is linked without it. */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#if FMI_VERSION == 2
#include "fmi2Functions.h"
#else
#include "fmi3Functions.h"
#endif

#define LOAD(name)                                                                                     \
    name##TYPE *name = (name##TYPE *)dlsym(library, #name);                                            \
    if (!name) {                                                                                       \
        fprintf(stderr, "missing %s\n", #name);                                                         \
        return 3;                                                                                      \
    }

#if FMI_VERSION == 2
static void logger(fmi2ComponentEnvironment environment, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    va_list args;
    (void)environment;
    (void)name;
    (void)status;
    va_start(args, message);
    fprintf(stderr, "[%s] ", category);
    vfprintf(stderr, message, args);
    fputc('\n', stderr);
    va_end(args);
}
#else
static void logger(fmi3InstanceEnvironment environment, fmi3Status status, fmi3String category, fmi3String message) {
    (void)environment;
    (void)status;
    fprintf(stderr, "[%s] %s\n", category, message);
}
#endif

int main(int argc, char **argv) {
    /* binary token vr_v0 vr_drag_area vr_rolling_resistance vr_brake vr_s vr_stopped v0 step */
    void *library;
    unsigned int vr_set[4], vr_s, vr_stopped;
    double values[4], step, t = 0.0, s = -1.0;
    int i;
    if (argc != 11) return 1;
    library = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    for (i = 0; i < 4; i++) vr_set[i] = (unsigned int)strtoul(argv[3 + i], NULL, 10);
    vr_s = (unsigned int)strtoul(argv[7], NULL, 10);
    vr_stopped = (unsigned int)strtoul(argv[8], NULL, 10);
    values[0] = strtod(argv[9], NULL); /* v0 */
    values[1] = 0.0;                    /* drag_area */
    values[2] = 0.0;                    /* rolling_resistance */
    values[3] = 1.0;                    /* brake */
    step = strtod(argv[10], NULL);
#if FMI_VERSION == 2
    {
        LOAD(fmi2Instantiate) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode)
        LOAD(fmi2ExitInitializationMode) LOAD(fmi2SetReal) LOAD(fmi2GetReal) LOAD(fmi2GetBoolean) LOAD(fmi2DoStep)
        LOAD(fmi2Terminate) LOAD(fmi2FreeInstance)
        fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
        fmi2Boolean stopped = fmi2False;
        fmi2Component c = fmi2Instantiate("host", fmi2CoSimulation, argv[2], "", &callbacks, fmi2False, fmi2False);
        if (!c || fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK ||
            fmi2EnterInitializationMode(c) != fmi2OK || fmi2SetReal(c, vr_set, 4, values) != fmi2OK ||
            fmi2ExitInitializationMode(c) != fmi2OK)
            return 4;
        while (!stopped && t < 100.0) {
            if (fmi2DoStep(c, t, step, fmi2True) != fmi2OK) return 5;
            t += step;
            if (fmi2GetBoolean(c, &vr_stopped, 1, &stopped) != fmi2OK) return 6;
        }
        if (fmi2GetReal(c, &vr_s, 1, &s) != fmi2OK) return 7;
        fmi2Terminate(c);
        fmi2FreeInstance(c);
    }
#else
    {
        LOAD(fmi3InstantiateCoSimulation) LOAD(fmi3EnterInitializationMode) LOAD(fmi3ExitInitializationMode)
        LOAD(fmi3SetFloat64) LOAD(fmi3GetFloat64) LOAD(fmi3GetBoolean) LOAD(fmi3DoStep) LOAD(fmi3Terminate)
        LOAD(fmi3FreeInstance)
        fmi3Boolean stopped = fmi3False, event, terminate, early;
        fmi3Float64 last;
        fmi3Instance c = fmi3InstantiateCoSimulation("host", argv[2], "", fmi3False, fmi3False, fmi3False, fmi3False,
                                                     NULL, 0, NULL, logger, NULL);
        if (!c || fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0) != fmi3OK ||
            fmi3SetFloat64(c, vr_set, 4, values, 4) != fmi3OK || fmi3ExitInitializationMode(c) != fmi3OK)
            return 4;
        while (!stopped && t < 100.0) {
            if (fmi3DoStep(c, t, step, fmi3True, &event, &terminate, &early, &last) != fmi3OK) return 5;
            t += step;
            if (fmi3GetBoolean(c, &vr_stopped, 1, &stopped, 1) != fmi3OK) return 6;
        }
        if (fmi3GetFloat64(c, &vr_s, 1, &s, 1) != fmi3OK) return 7;
        fmi3Terminate(c);
        fmi3FreeInstance(c);
    }
#endif
    printf("%.17g\n", s);
    dlclose(library);
    return 0;
}
"""

V0 = 30.0


@pytest.fixture(scope="module")
def host(tmp_path_factory, simple_fmus):
    """The host compiled for FMI 2.0 and 3.0 against the headers the FMUs ship in sources/; no -lm."""
    directory = tmp_path_factory.mktemp("host")
    (directory / "host.c").write_text(HOST)
    hosts = {}
    for version in (2, 3):
        headers = directory / f"headers{version}"
        with zipfile.ZipFile(simple_fmus[version]) as archive:
            for name in archive.namelist():
                if name.startswith(f"sources/fmi{version}") and name.endswith(".h"):
                    headers.mkdir(exist_ok=True)
                    (headers / name.split("/")[-1]).write_bytes(archive.read(name))
        executable = directory / f"host{version}"
        subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", f"-DFMI_VERSION={version}",
                        f"-I{headers}", str(directory / "host.c"), "-o", str(executable), "-ldl"],
                       check=True, capture_output=True, text=True)
        linked = subprocess.run(["ldd", str(executable)], capture_output=True, text=True, check=True).stdout
        assert "libm." not in linked  # the host itself brings no libm
        hosts[version] = executable
    return hosts


def run_host(host, binary, fmu, step=0.01):
    md = read_model_description(str(fmu))
    references = {v.name: v.valueReference for v in md.modelVariables}
    arguments = [str(binary), md.guid, *(str(references[n]) for n in
                 ("v0", "drag_area", "rolling_resistance", "brake", "s", "stopped")), repr(V0), repr(step)]
    return subprocess.run([str(host), *arguments], capture_output=True, text=True, timeout=60)


def unzip(fmu, directory):
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(directory)
    shutil.rmtree(directory / "binaries")
    return directory


def build_sources(directory):
    """The SourceFile list of sources/buildDescription.xml, as a tool reads it."""
    root = ET.parse(directory / "sources" / "buildDescription.xml").getroot()
    return [element.get("name") for element in root.iter("SourceFile")]


def plain_compiler_line(directory, output, libm=True, optimization="-O2"):
    """The README's line: cc -std=c99 -O2 -fPIC -shared -Isources <the listed sources> -o <binary> -lm"""
    command = ["gcc", "-std=c99", optimization, "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror", "-Isources",
               *[f"sources/{name}" for name in build_sources(directory)], "-o", str(output)]
    subprocess.run(command + (["-lm"] if libm else []), cwd=directory, check=True, capture_output=True, text=True)
    return output


@pytest.mark.slow
@pytest.mark.parametrize("version", [2, 3])
def test_plain_compiler_line_gives_a_binary_a_plain_host_loads(simple_fmus, defaults_simple, host, tmp_path,
                                                               version):
    directory = unzip(simple_fmus[version], tmp_path / "fmu")
    binary = plain_compiler_line(directory, tmp_path / "rebuilt.so")
    assert "libm." in subprocess.run(["ldd", str(binary)], capture_output=True, text=True).stdout
    completed = run_host(host[version], binary, simple_fmus[version])
    assert completed.returncode == 0, completed.stderr
    expected = expected_distance(defaults_simple, False, mu=0.8, v0=V0)
    assert abs(float(completed.stdout) - expected) / expected < COSIM_TOLERANCE

    if version == 2:  # the control (once): the same line without -lm gives a binary the host cannot load
        unlinked = plain_compiler_line(directory, tmp_path / "unlinked.so", libm=False, optimization="-O0")
        completed = run_host(host[version], unlinked, simple_fmus[version])
        assert completed.returncode == 2 and "undefined symbol" in completed.stderr


@pytest.mark.slow
def test_fmpy_build_gives_a_binary_a_plain_host_loads(simple_fmus, defaults_simple, host, tmp_path):
    """fmpy's CMake template ignores buildDescription.xml's <Library name="m"/>; the README's fmpy call
    passes libm as the standard library of C targets (linked last, so it holds with --as-needed too)."""
    from fmpy.build import build_platform_binary

    if shutil.which("cmake") is None:
        pytest.fail("cmake is needed for fmpy's build (Debian: apt-get install cmake)")
    directory = unzip(simple_fmus[3], tmp_path / "fmu")
    (tmp_path / "build").mkdir()
    build_platform_binary(directory, build_dir=tmp_path / "build",
                          cmake_options={"CMAKE_C_STANDARD_LIBRARIES:STRING": "-lm"})
    binary = directory / "binaries" / "x86_64-linux" / "EgoVehicleSimple.so"
    completed = run_host(host[3], binary, simple_fmus[3], step=0.1)
    assert completed.returncode == 0, completed.stderr
    expected = expected_distance(defaults_simple, False, mu=0.8, v0=V0)
    assert abs(float(completed.stdout) - expected) / expected < COSIM_TOLERANCE
