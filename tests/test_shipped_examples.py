"""Every shipped example runs without a warning under the dynamics its header says it is written for, and
the Advanced demo's wheels roll over every surface it sets in the driver's lane."""

import re

import numpy as np
import pytest

from sdl_fmu import api

WRITTEN_FOR = re.compile(r"^// Written for: (.+?) dynamics", re.M)
SKIPPING = re.compile(r"^// Written for: .+ dynamics, with --skip-unsupported", re.M)


def written_for() -> list[tuple[str, str]]:
    cases = []
    for name, path in api.shipped_scenarios().items():
        match = WRITTEN_FOR.search(path.read_text(encoding="utf-8"))
        assert match, f"{path.name}: its header does not say which dynamics it is written for"
        cases += [(name, dynamics) for dynamics in match.group(1).split(" and ")]
    return cases


CASES = written_for()


def test_every_dynamics_has_examples_and_the_advanced_demo_is_shipped():
    assert {dynamics for _, dynamics in CASES} == {"simple", "advanced"}
    assert ("demo", "simple") in CASES and ("demo_advanced", "advanced") in CASES


@pytest.mark.parametrize("name, dynamics", CASES, ids=[f"{n}-{d}" for n, d in CASES])
def test_shipped_example_runs_without_a_warning(name, dynamics, simple_fmu, advanced_fmu):
    fmu = simple_fmu if dynamics == "simple" else advanced_fmu
    # an example of a real STISIM file says it needs --skip-unsupported: its only warnings are its skipped lines
    skip = SKIPPING.search(api.shipped_scenarios()[name].read_text(encoding="utf-8")) is not None
    result = api.run(name, dynamics=dynamics, fmu=fmu, skip_unsupported=skip)
    assert [w for w in result.warnings if not (skip and "is not simulated: skipped" in w)] == []
    assert not skip or result.warnings
    assert any(event["code"] == "ES" or event["action"] == "end" for event in result.events) or result.final


def test_the_advanced_demo_rolls_over_each_surface_of_its_lane(advanced_fmu):
    result = api.run("demo_advanced", dynamics="advanced", fmu=advanced_fmu)
    # the attribute numbers RSA sets in lane 1 (the driver's), each under all four wheels at some sample
    lane_one = {int(event["value"]) for event in result.events if event["code"] == "RSA" and event["lane"] == 1}
    assert lane_one == {0, 1, 2, 3}
    for wheel in ("fl", "fr", "rl", "rr"):
        assert set(np.unique(result.raw.columns[f"surface_{wheel}"]).astype(int)) == lane_one
    assert result.final["distance"] == pytest.approx(5280.0, abs=1.0)  # the ES line, the whole mile
