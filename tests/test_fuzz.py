"""The FMI call-sequence fuzzer (tools/fmi_fuzz.py) in CI: a fixed seed, 1000 random FMI 2.0 and FMI 3.0 call sequences
per FMU; no crash, no hang, no OK where the standard (or the modelDescription) requires an error.

A hang is a call that does not return within HANG_GUARD: far beyond any call whose work is bounded (the
runtime's step budget, tests/test_runtime_hardening.py), so a busy or slow machine is never taken for a hang."""

import pytest

from fmi_fuzz import fuzz

HANG_GUARD = 120.0  # s


def count(statuses, function, status):
    """Calls of e.g. "DoStep" that returned e.g. "OK", under either version's function name."""
    return sum(n for key, n in statuses.items() if key.lower().endswith(f"{function} {status}".lower()))


@pytest.mark.slow
@pytest.mark.parametrize("version", [2, 3], ids=["fmi2", "fmi3"])
@pytest.mark.parametrize("fixture", ["simple_fmus", "advanced_fmus"], ids=["simple", "advanced"])
def test_random_call_sequences(request, fixture, version):
    report = fuzz(request.getfixturevalue(fixture)[version], sequences=1000, seed=20261122,
                  hang_timeout=HANG_GUARD)
    print(report.summary())
    assert report.sequences == 1000 and report.calls > 10000
    assert report.crashes == [] and report.hangs == [] and report.violations == []
    # the sequences reach deep: steps were taken and refused, states saved and restored, corruptions refused
    assert count(report.statuses, "DoStep", "OK") > 1000 and count(report.statuses, "DoStep", "Error") > 100
    assert count(report.statuses, "SetFMUstate", "OK") > 10
    assert count(report.statuses, "DeSerializeFMUstate", "Error") > 0
    assert count(report.statuses, "SetContinuousStates", "OK") > 10
