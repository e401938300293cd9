"""The importer matrix: independent FMI importers load the real FMUs, reproduce the Simple FMU's analytic
braking stop and the Advanced FMU's trajectory (fmpy's co-simulation run of the FMI 2.0 FMU is the reference).
FMI 3.0 FMUs run wherever the importer supports them (fmpy, ecospy, the container, the C host); libcosim loads
FMI 2.0 only.

fmpy (co-simulation and model exchange), libcosimpy (FMI 2.0 co-simulation only, in a subprocess: libcosim
aborts the process on FMUs it cannot load and prints FMI Library lines on stdout), ecospy (Vico's ecos; in a
subprocess for the same reason), the FMU container of fmu-manipulation-toolbox (a container FMU holding the ego
FMU, run by fmpy), a plain C host on Linux and the same C host cross-compiled with mingw-w64 loading the
Windows DLL under wine."""

import json
import shutil
import struct
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from sdl_fmu.fmu.package import fmi_headers, mingw_compiler

from helpers import (HOST_SOURCE, HOST_STEP, MU, SIMPLE_START, V0, G, extract_binary, host_arguments,
                     windows_tools_required)

# Simple FMU: SIMPLE_START brakes straight on mu 0.6 without drag and rolling resistance: a = min(b a_max, mu g)
# = mu g (a_max = 9.81 > 0.6 g), stopping distance v0^2 / (2 a).
SIMPLE_STOP = V0**2 / (2 * MU * G)
# Every co-simulation importer drives the same binary: RODAS4 integrates the constant deceleration exactly
# and locates the stop to 1e-12 s, so only round-off remains (tests/dynamics/test_simple_fmu.py: 1e-9 relative).
SIMPLE_TOLERANCE = 1e-9
# fmpy's CVode at rtol 1e-10 (tests/dynamics/test_simple_fmu.py: 1e-7 relative)
SIMPLE_ME_TOLERANCE = 1e-7

# Advanced FMU: braking in a curve (20 m/s, steer 0.03 rad, 30 % pedal), sampled at 1, 2, 3, 4 s.
ADVANCED_START = {"v0": 20.0, "steer": 0.03, "brake": 0.3}
ADVANCED_OUTPUTS = ("x", "y", "psi", "s", "vx", "yaw_rate")
SAMPLE_TIMES = (1.0, 2.0, 3.0, 4.0)
STEP = HOST_STEP  # s, the communication step of every importer here


# ---- tolerances of the Advanced trajectory -------------------------------------------------------------------
# Same binary, other importer: the importers pass communication points k h or sums of h, which differ by a few
# ulps (1e-15 s); the FMU steps from the point it is given, so each step changes by ~|dx/dt| 1e-15 and the
# 400 steps add up to well under 1e-11 in x, y, s (|dx/dt| <= 20 m/s) and in psi and the rates. Measured: 2e-14.
SAME_BINARY_TOLERANCE = 1e-10
# The Windows DLL: mingw-w64 compiles the same C, but exp/sin/cos/atan/sqrt come from msvcrt, whose results may
# differ from glibc's by an ulp (2.2e-16 relative). Each internal step (at most 4000: the step is
# error-controlled, at least 1 ms here) evaluates each equation ~10 times (RODAS4 stages + Jacobian); a relative
# perturbation of 1e-15 per step, accumulated over 4000 steps with no growth (the braking car is dissipative:
# every wheel-speed mode decays), gives 4e-12 relative, i.e. 4e-10 m on 100 m. The step sizes follow the error
# estimate smoothly (h err^(-1/4)), so they move by ~1e-15 relative too; only an estimate within 1e-15 of the
# acceptance limit could flip a decision. 1e-8 leaves a factor 25 for the event times (located to 1e-12 s;
# 20 m/s x 1e-12 s = 2e-11 m). Measured under wine: 2e-15.
WINDOWS_TOLERANCE = 1e-8
# Model exchange: CVode (rtol 1e-10, atol default) instead of RODAS4 error-controlled to solver_tolerance 1e-8.
# RODAS4's global error is ~1e-8 (its fixed 1 ms steps are ~1e-8 m off: README, halving the step changes the
# stop distance by 1.4e-7 m at 2 ms, order 4 -> 1e-8 at 1 ms; the error-controlled run is within 8.4e-9 of
# those); CVode's global error is ~10..100 rtol |x| = 1e-8 x 50 m = 5e-7 m. Allowed: 1e-6 (relative above 1,
# absolute below). Measured: 7.9e-9.
ME_TOLERANCE = 1e-6


def assert_same_trajectory(samples, reference, tolerance):
    for name in ADVANCED_OUTPUTS:
        got, expected = np.asarray(samples[name], float), np.asarray(reference[name], float)
        scale = np.maximum(1.0, np.abs(expected))  # relative for large values, absolute below 1
        assert np.all(np.abs(got - expected) <= tolerance * scale), (name, got - expected)


def fmpy_samples(fmu, fmi_type, start, stop_time, outputs, **options):
    result = simulate_fmu(str(fmu), fmi_type=fmi_type, start_values=start, output=list(outputs),
                          stop_time=stop_time, output_interval=STEP, **options)
    times = result["time"]
    indices = [int(np.argmin(np.abs(times - t))) for t in SAMPLE_TIMES if t <= stop_time]
    return {name: result[name][indices] for name in outputs}, result


VERSIONS = pytest.mark.parametrize("version", [2, 3], ids=["fmi2", "fmi3"])


@pytest.fixture(scope="module")
def reference(advanced_fmu):
    """The Advanced FMU's trajectory in fmpy's co-simulation: the reference of every other importer."""
    samples, _ = fmpy_samples(advanced_fmu, "CoSimulation", ADVANCED_START, SAMPLE_TIMES[-1], ADVANCED_OUTPUTS)
    assert samples["s"][-1] > 50.0 and abs(samples["psi"][-1]) > 0.1  # it drove a curve and slowed down
    return samples


# ---- fmpy -----------------------------------------------------------------------------------------------------


@VERSIONS
def test_fmpy_cosimulation_simple(simple_fmus, version):
    _, result = fmpy_samples(simple_fmus[version], "CoSimulation", SIMPLE_START, 10.0, ("s", "stopped"))
    assert result["stopped"][-1]
    assert abs(result["s"][-1] - SIMPLE_STOP) / SIMPLE_STOP < SIMPLE_TOLERANCE


def test_fmpy_cosimulation_advanced_fmi3(advanced_fmus, reference):
    samples, _ = fmpy_samples(advanced_fmus[3], "CoSimulation", ADVANCED_START, SAMPLE_TIMES[-1], ADVANCED_OUTPUTS)
    assert_same_trajectory(samples, reference, SAME_BINARY_TOLERANCE)  # the same model code and solver


@VERSIONS
def test_fmpy_model_exchange_simple(simple_fmus, version):
    _, result = fmpy_samples(simple_fmus[version], "ModelExchange", SIMPLE_START, 10.0, ("s", "stopped"),
                             solver="CVode", relative_tolerance=1e-10)
    assert result["stopped"][-1]
    assert abs(result["s"][-1] - SIMPLE_STOP) / SIMPLE_STOP < SIMPLE_ME_TOLERANCE


@VERSIONS
def test_fmpy_model_exchange_advanced(advanced_fmus, reference, version):
    # the dynamic wheels, co-simulation's model (model exchange's automatic choice is quasi-static:
    # tests/fmu/test_model_exchange_advanced.py)
    samples, _ = fmpy_samples(advanced_fmus[version], "ModelExchange", {**ADVANCED_START, "wheel_spin": 1},
                              SAMPLE_TIMES[-1], ADVANCED_OUTPUTS, solver="CVode", relative_tolerance=1e-10)
    assert_same_trajectory(samples, reference, ME_TOLERANCE)


# ---- libcosimpy and ecospy (subprocesses) ---------------------------------------------------------------------

LIBCOSIM_SCRIPT = textwrap.dedent("""
    import json, sys
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    fmu, start, outputs, times, step = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3].split(","), \\
        json.loads(sys.argv[4]), float(sys.argv[5])
    execution = CosimExecution.from_step_size(step_size=int(round(step * 1e9)))
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=fmu, instance_name="ego"))
    references = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    for name, value in start.items():
        execution.real_initial_value(index, references[name], value)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    samples = {name: [] for name in outputs}
    for t in times:
        execution.simulate_until(target_time=int(round(t * 1e9)))
        for name, value in zip(outputs, observer.last_real_values(index, [references[n] for n in outputs])):
            samples[name].append(value)
    print("RESULT " + json.dumps(samples))
""")

ECOS_SCRIPT = textwrap.dedent("""
    import json, sys
    from ecospy import EcosSimulation, EcosSimulationStructure

    fmu, start, outputs, times, step = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3].split(","), \\
        json.loads(sys.argv[4]), float(sys.argv[5])
    samples = {name: [] for name in outputs}
    with EcosSimulationStructure() as structure:
        structure.add_model("ego", fmu)
        structure.add_parameter_set("start", {f"ego::{name}": value for name, value in start.items()})
        with EcosSimulation(structure=structure, step_size=step) as simulation:
            simulation.init(parameter_set="start")
            done = 0
            for t in times:  # whole steps: step_until compares a running sum of steps with t
                simulation.step(int(round(t / step)) - done)
                done = int(round(t / step))
                for name in outputs:
                    samples[name].append(simulation.get_real(f"ego::{name}"))
            simulation.terminate()
    print("RESULT " + json.dumps(samples))
""")


def run_script(script, fmu, start, outputs, times, step=STEP):
    completed = subprocess.run([sys.executable, "-c", script, str(fmu), json.dumps(start), ",".join(outputs),
                                json.dumps(list(times)), str(step)], capture_output=True, text=True, timeout=300)
    assert completed.returncode == 0, completed.stderr[-3000:]
    line = next(line for line in completed.stdout.splitlines() if line.startswith("RESULT "))
    return json.loads(line[len("RESULT "):])


# libcosim loads FMI 2.0 co-simulation FMUs only; ecospy (ecos, through fmi4c) loads FMI 2.0 and 3.0
SUBPROCESS_IMPORTERS = pytest.mark.parametrize("script, version", [(LIBCOSIM_SCRIPT, 2), (ECOS_SCRIPT, 2),
                                                                   (ECOS_SCRIPT, 3)],
                                               ids=["libcosimpy-fmi2", "ecospy-fmi2", "ecospy-fmi3"])


@pytest.mark.slow
@SUBPROCESS_IMPORTERS
def test_subprocess_importer_simple(simple_fmus, script, version):
    samples = run_script(script, simple_fmus[version], SIMPLE_START, ("s", "v"), (10.0,))
    assert samples["v"][-1] == 0.0
    assert abs(samples["s"][-1] - SIMPLE_STOP) / SIMPLE_STOP < SIMPLE_TOLERANCE


@pytest.mark.slow
@SUBPROCESS_IMPORTERS
def test_subprocess_importer_advanced(advanced_fmus, reference, script, version):
    samples = run_script(script, advanced_fmus[version], ADVANCED_START, ADVANCED_OUTPUTS, SAMPLE_TIMES)
    assert_same_trajectory(samples, reference, SAME_BINARY_TOLERANCE)


# ---- the FMU container of fmu-manipulation-toolbox ------------------------------------------------------------


def make_container(fmu, directory, version=2):
    """A container FMU (of the ego FMU's FMI version) holding the ego FMU; its inputs and outputs are exposed
    under their own names, its parameters as <fmu>.<name>."""
    from fmu_manipulation_toolbox.assembly import AssemblyNode

    directory.mkdir()
    shutil.copy(fmu, directory / fmu.name)
    node = AssemblyNode("container.fmu", step_size=STEP, auto_parameter=True)
    node.add_fmu(fmu.name)
    node.make_fmu(directory, fmi_version=version)
    prefix = Path(fmu).stem.lower() + "."
    names = {v.name for v in read_model_description(str(directory / "container.fmu")).modelVariables}
    return directory / "container.fmu", lambda start: {(n if n in names else prefix + n): v for n, v in start.items()}


@pytest.mark.slow
@VERSIONS
def test_fmu_container_simple(simple_fmus, tmp_path, version):
    container, names = make_container(simple_fmus[version], tmp_path / "container", version)
    _, result = fmpy_samples(container, "CoSimulation", names(SIMPLE_START), 10.0, ("s", "v"))
    assert result["v"][-1] == 0.0
    assert abs(result["s"][-1] - SIMPLE_STOP) / SIMPLE_STOP < SIMPLE_TOLERANCE


@pytest.mark.slow
@VERSIONS
def test_fmu_container_advanced(advanced_fmus, reference, tmp_path, version):
    container, names = make_container(advanced_fmus[version], tmp_path / "container", version)
    samples, _ = fmpy_samples(container, "CoSimulation", names(ADVANCED_START), SAMPLE_TIMES[-1], ADVANCED_OUTPUTS)
    assert_same_trajectory(samples, reference, SAME_BINARY_TOLERANCE)


# ---- the C host, on Linux and (mingw-w64) under wine ------------------------------------------------------------


@pytest.fixture(scope="session")
def windows_host(tmp_path_factory):
    compiler = mingw_compiler()
    if compiler is None:
        message = "x86_64-w64-mingw32-gcc is not installed (Debian: apt-get install gcc-mingw-w64-x86-64)"
        if windows_tools_required():
            pytest.fail(message)
        pytest.skip(message)
    host = tmp_path_factory.mktemp("host") / "fmi_host.exe"
    subprocess.run([compiler, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-static-libgcc",
                    f"-I{fmi_headers()}", str(HOST_SOURCE), "-o", str(host)], check=True)
    return host


def parse_host_output(stdout, outputs, booleans=()):
    """RESULT lines: time and values as the hex digits of their IEEE 754 bits."""
    rows = [[struct.unpack(">d", bytes.fromhex(word))[0] for word in line.split()[1:]]
            for line in stdout.splitlines() if line.startswith("RESULT")]
    table = np.array(rows)
    columns = {"time": table[:, 0]}
    for i, name in enumerate((*outputs, *booleans)):
        columns[name] = table[:, i + 1]
    return columns


def run_host(runner, host, fmu, library, start, outputs, stop_time, booleans=()):
    completed = runner([host, *host_arguments(fmu, library, start, outputs, stop_time, booleans)])
    assert completed.returncode == 0, completed.stderr[-3000:]
    return parse_host_output(completed.stdout, outputs, booleans)


def linux_runner(arguments):
    return subprocess.run(list(map(str, arguments)), capture_output=True, text=True, timeout=300)


def windows_path(path):
    return "Z:" + str(path).replace("/", "\\")


def sampled(columns):
    indices = [int(np.argmin(np.abs(columns["time"] - t))) for t in SAMPLE_TIMES]
    assert np.allclose(columns["time"][indices], SAMPLE_TIMES, atol=1e-12)
    return {name: columns[name][indices] for name in ADVANCED_OUTPUTS}


@VERSIONS
def test_linux_c_host_simple(simple_fmus, c_host, tmp_path, version):
    fmu = simple_fmus[version]
    library = extract_binary(fmu, tmp_path, version, "so")
    columns = run_host(linux_runner, c_host, fmu, library, SIMPLE_START, ("s", "v"), 10.0, ("stopped",))
    assert columns["stopped"][-1] == 1.0 and columns["v"][-1] == 0.0
    assert abs(columns["s"][-1] - SIMPLE_STOP) / SIMPLE_STOP < SIMPLE_TOLERANCE


@VERSIONS
def test_linux_c_host_advanced(advanced_fmus, reference, c_host, tmp_path, version):
    fmu = advanced_fmus[version]
    library = extract_binary(fmu, tmp_path, version, "so")
    columns = run_host(linux_runner, c_host, fmu, library, ADVANCED_START, ADVANCED_OUTPUTS, SAMPLE_TIMES[-1])
    assert_same_trajectory(sampled(columns), reference, SAME_BINARY_TOLERANCE)


@pytest.mark.slow
@VERSIONS
def test_windows_dll_under_wine_simple(simple_fmus, windows_host, wine, tmp_path, version):
    fmu = simple_fmus[version]
    library = extract_binary(fmu, tmp_path, version, "dll")
    columns = run_host(wine, windows_host, fmu, windows_path(library), SIMPLE_START, ("s", "v"), 10.0, ("stopped",))
    assert columns["stopped"][-1] == 1.0 and columns["v"][-1] == 0.0
    assert abs(columns["s"][-1] - SIMPLE_STOP) / SIMPLE_STOP < SIMPLE_TOLERANCE


@pytest.mark.slow
@VERSIONS
def test_windows_dll_under_wine_advanced(advanced_fmus, reference, windows_host, wine, tmp_path, version):
    fmu = advanced_fmus[version]
    library = extract_binary(fmu, tmp_path, version, "dll")
    columns = run_host(wine, windows_host, fmu, windows_path(library), ADVANCED_START, ADVANCED_OUTPUTS,
                       SAMPLE_TIMES[-1])
    assert_same_trajectory(sampled(columns), reference, WINDOWS_TOLERANCE)
