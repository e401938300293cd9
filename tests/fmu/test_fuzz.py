"""The FMI call-sequence fuzzer (tools/fmi_fuzz.py) in CI: a fixed seed, 1000 random FMI 2.0 and FMI 3.0 call sequences
per FMU; no crash, no hang, no OK where the standard (or the modelDescription) requires an error.

A hang is a call that does not return within HANG_GUARD: far beyond any call whose work is bounded (the
runtime's step budget, tests/fmu/test_fmu_misuse.py), so a busy or slow machine is never taken for a hang."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fmi_fuzz import fuzz

HANG_GUARD = 120.0  # s
TOOL = Path(__file__).resolve().parents[2] / "tools" / "fmi_fuzz.py"


def test_the_fuzzer_runs_as_a_script_from_a_checkout(tmp_path):
    """`python tools/fmi_fuzz.py --help` from any folder, with neither the checkout nor tools/ on the path."""
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    completed = subprocess.run([sys.executable, TOOL, "--help"], cwd=tmp_path, env=environment,
                               capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.startswith("usage: python tools/fmi_fuzz.py") and "--sanitize" in completed.stdout


def count(statuses, function, status):
    """Calls of e.g. "DoStep" that returned e.g. "OK", under either version's function name."""
    return sum(n for key, n in statuses.items() if key.lower().endswith(f"{function} {status}".lower()))


@pytest.mark.slow
@pytest.mark.parametrize("version", [2, 3], ids=["fmi2", "fmi3"])
def test_random_call_sequences(ego_fmus, version):
    report = fuzz(ego_fmus[version], sequences=1000, seed=20261122, hang_timeout=HANG_GUARD)
    print(report.summary())
    assert report.sequences == 1000 and report.calls > 10000
    assert report.crashes == [] and report.hangs == [] and report.violations == []
    # the sequences reach deep: steps were taken and refused, states saved and restored, corruptions refused
    assert count(report.statuses, "DoStep", "OK") > 1000 and count(report.statuses, "DoStep", "Error") > 100
    assert count(report.statuses, "SetFMUstate", "OK") > 10
    assert count(report.statuses, "DeSerializeFMUstate", "Error") > 0
    assert count(report.statuses, "SetContinuousStates", "OK") > 10
    # handles never issued, freed or NULL, and null event outputs were offered, and refused (no violation above)
    assert report.statuses["bad handle probes"] > 20 and report.statuses["null output probes"] > 20
    assert count(report.statuses, "SerializedFMUstateSize", "Error") >= report.statuses["bad handle probes"]


# The oracle's findings, shown on mutants of the runtime: the FMU's own sources with one rule broken, compiled
# and packed as an FMU, so that the fuzzer meets a real binary that breaks exactly that rule.
STEP_OF_ZERO_ACCEPTED = ("cosimulation.c", "    if (!(h > 0.0) || !isfinite(h)) {",
                         "    if (!(h >= 0.0) || !isfinite(h)) {")
SILENT_DISCARD = ("fmi2Functions.c", '    instance_log(instance, STATUS_DISCARD, "logStatusWarning",',
                  '    if (0) instance_log(instance, STATUS_DISCARD, "logStatusWarning",')


# The two calls that were lenient, each answering OK without a message for what it does not know: the size of an FMU
# state for any handle (freed, wild, NULL), and fmi3UpdateDiscreteStates with null outputs (it skipped them)
LENIENT_STATE_SIZE = {
    version: (f"fmi{version}Functions.c",
              f'        !snapshot_handle_valid(instance, {state}, "fmi{version}SerializedFMU{s}tateSize"))',
              f"        !((void){state}, 1))")
    for version, state, s in ((2, "FMUstate", "s"), (3, "FMUState", "S"))}
REQUIRED_OUTPUTS = """\
    if (!instance || !present(instance, function, discreteStatesNeedUpdate, "discreteStatesNeedUpdate") ||
        !present(instance, function, terminateSimulation, "terminateSimulation") ||
        !present(instance, function, nominalsOfContinuousStatesChanged, "nominalsOfContinuousStatesChanged") ||
        !present(instance, function, valuesOfContinuousStatesChanged, "valuesOfContinuousStatesChanged") ||
        !present(instance, function, nextEventTimeDefined, "nextEventTimeDefined") ||
        !present(instance, function, nextEventTime, "nextEventTime"))
        return fmi3Error;
    /* the event iteration runs to its fixed point here, so no further update is needed */
    status = instance_event_iteration(instance, &states_changed, &discrete_changed);
    states_changed |= instance_take_input_jump(instance);
    *discreteStatesNeedUpdate = fmi3False;
    *terminateSimulation = fmi3False;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = states_changed ? fmi3True : fmi3False;
    *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0.0;
"""
SKIPPED_OUTPUTS = """\
    (void)function;
    if (!instance) return fmi3Error;
    status = instance_event_iteration(instance, &states_changed, &discrete_changed);
    states_changed |= instance_take_input_jump(instance);
    if (discreteStatesNeedUpdate) *discreteStatesNeedUpdate = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (nominalsOfContinuousStatesChanged) *nominalsOfContinuousStatesChanged = fmi3False;
    if (valuesOfContinuousStatesChanged) *valuesOfContinuousStatesChanged = states_changed ? fmi3True : fmi3False;
    if (nextEventTimeDefined) *nextEventTimeDefined = fmi3False;
    if (nextEventTime) *nextEventTime = 0.0;
"""
LENIENT_NULL_OUTPUTS = ("fmi3Functions.c", REQUIRED_OUTPUTS, SKIPPED_OUTPUTS)


def mutant_fmu(fmu, work, mutations):
    """A copy of the FMU (FMI 2.0 or 3.0) whose Linux binary is built from its sources with each (file, text,
    replacement) applied; each text must occur exactly once, so a changed runtime fails here instead of testing
    nothing."""
    import shutil
    import zipfile

    from fmpy.model_description import read_build_description

    from sdl_fmu.fmu.package import compile_binary

    unzipped = work / "unzipped"
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(unzipped)
    for name, text, replacement in mutations:
        source = unzipped / "sources" / name
        code = source.read_text()
        assert code.count(text) == 1, f"{name} no longer contains {text!r}: update the mutant"
        source.write_text(code.replace(text, replacement))
    configuration, = read_build_description(str(unzipped))
    binary, = [*(unzipped / "binaries").glob("linux64/*.so"), *(unzipped / "binaries").glob("x86_64-linux/*.so")]
    compile_binary(unzipped / "sources", configuration.sourceFileSets[0].sourceFiles, binary)
    mutant = work / fmu.name
    shutil.make_archive(str(mutant.with_suffix("")), "zip", unzipped)
    mutant.with_suffix(".zip").rename(mutant)
    return mutant


@pytest.mark.slow
def test_the_oracle_finds_a_step_of_zero_accepted_and_a_silent_non_ok_return(simple_fmus, tmp_path):
    report = fuzz(mutant_fmu(simple_fmus[2], tmp_path, [STEP_OF_ZERO_ACCEPTED, SILENT_DISCARD]), sequences=300,
                  seed=20261123, hang_timeout=HANG_GUARD)
    print(report.summary())
    assert report.crashes == [] and report.hangs == []
    zero_steps = [v for v in report.violations if "OK where an error is required: doStep(" in v and ", 0.0)" in v]
    silent = [v for v in report.violations if "returned Discard without a log message" in v]
    assert zero_steps and silent
    # nothing else: the two mutations are the only rules broken
    assert len(zero_steps) + len(silent) == len(report.violations)


@pytest.mark.slow
def test_the_unmutated_build_of_the_same_sources_is_clean(simple_fmus, tmp_path):
    """The mutant test's baseline: the same sources rebuilt the same way, same seed, give no finding."""
    report = fuzz(mutant_fmu(simple_fmus[2], tmp_path, []), sequences=300, seed=20261123, hang_timeout=HANG_GUARD)
    assert report.sequences == 300 and report.violations == [] and report.crashes == [] and report.hangs == []


@pytest.mark.slow
@pytest.mark.parametrize("version", [2, 3], ids=["fmi2", "fmi3"])
def test_the_oracle_finds_a_lenient_state_size_and_skipped_null_event_outputs(simple_fmus, tmp_path, version):
    """The runtime as it was: the size of an FMU state answered OK for any handle, and fmi3UpdateDiscreteStates
    skipped null outputs with OK. The oracle reports both (each kind of bad handle), and nothing else."""
    mutations = [LENIENT_STATE_SIZE[version]] + ([LENIENT_NULL_OUTPUTS] if version == 3 else [])
    report = fuzz(mutant_fmu(simple_fmus[version], tmp_path, mutations), sequences=300, seed=20261124,
                  hang_timeout=HANG_GUARD)
    print(report.summary())
    assert report.crashes == [] and report.hangs == []
    sizes = [v for v in report.violations
             if "SerializedFMUStateSize returned OK where an error is required: a " in v.replace("FMUstate", "FMUState")]
    nulls = [v for v in report.violations if "UpdateDiscreteStates returned OK where an error is required: a null" in v]
    assert {kind for kind in ("freed", "wild", "null") if any(f"a {kind} FMU state handle" in v for v in sizes)} \
        == {"freed", "wild", "null"}
    assert bool(nulls) == (version == 3)
    assert len(sizes) + len(nulls) == len(report.violations)
