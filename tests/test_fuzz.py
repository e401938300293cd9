"""The in-tree fuzzer (sdl_fmu/fmu/fuzz.py) in CI: a fixed seed, 1000 random FMI 2.0 call sequences per FMU;
no crash, no call over 5 s, no OK where the standard (or the modelDescription) requires an error."""

import pytest

from sdl_fmu.fmu.fuzz import fuzz


@pytest.mark.parametrize("fixture", ["simple_fmu", "advanced_fmu"])
def test_random_call_sequences(request, fixture):
    report = fuzz(request.getfixturevalue(fixture), sequences=1000, seed=20261122)
    print(report.summary())
    assert report.sequences == 1000 and report.calls > 10000
    assert report.crashes == [] and report.hangs == [] and report.violations == []
    # the sequences reach deep: steps were taken and refused, states saved and restored
    assert report.statuses["fmi2DoStep OK"] > 1000 and report.statuses["fmi2DoStep Error"] > 100
    assert report.statuses["fmi2SetFMUstate OK"] > 10 and report.statuses["fmi2DeSerializeFMUstate Error"] > 0
