"""The FMI call-sequence fuzzer (tools/fmi_fuzz.py) in CI: a fixed seed, 1000 random FMI 2.0 and FMI 3.0 call sequences
per FMU; no crash, no hang, no OK where the standard (or the modelDescription) requires an error.

A hang is a call that does not return within HANG_GUARD: far beyond any call whose work is bounded (the
runtime's step budget, tests/test_fmu_misuse.py), so a busy or slow machine is never taken for a hang."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fmi_fuzz import fuzz

HANG_GUARD = 120.0  # s
TOOL = Path(__file__).resolve().parents[1] / "tools" / "fmi_fuzz.py"


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


# The oracle's findings, shown on mutants of the runtime: the FMU's own sources with one rule broken, compiled
# and packed as an FMU, so that the fuzzer meets a real binary that breaks exactly that rule.
STEP_OF_ZERO_ACCEPTED = ("cosimulation.c", "    if (!(h > 0.0) || !isfinite(h)) {",
                         "    if (!(h >= 0.0) || !isfinite(h)) {")
SILENT_DISCARD = ("fmi2Functions.c", '    instance_log(instance, STATUS_DISCARD, "logStatusWarning",',
                  '    if (0) instance_log(instance, STATUS_DISCARD, "logStatusWarning",')


def mutant_fmu(fmu, work, mutations):
    """A copy of the FMI 2.0 FMU whose Linux binary is built from its sources with each (file, text, replacement)
    applied; each text must occur exactly once, so a changed runtime fails here instead of testing nothing."""
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
    binary, = (unzipped / "binaries" / "linux64").glob("*.so")
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
