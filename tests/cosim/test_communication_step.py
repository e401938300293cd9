"""Triggers are located at their true instants whatever the communication step: the same events at the same times
and the same collisions at --step 0.001 ... 10 s. Runs the real Simple FMU."""

import pytest

from sdl_fmu.cosim.master import RunOptions, run_scenario
from sdl_fmu.paths import SCENARIO_DIRECTORY
from sdl_fmu.sdl import load_scenario, parse_text
from sdl_fmu.units import FOOT

from helpers import TABLE

STEPS = (0.001, 0.01, 0.1, 1.0, 10.0)
# Every trigger is bisected to within TIME_TOLERANCE = 1e-6 s of its instant, from whichever side the
# step happens to bracket it: two runs place one instant at most 1e-6 s apart. Later instants inherit the
# earlier ones' offsets through the ego's state (a 1e-6 s shift at 27 m/s moves the ego 2.7e-5 m, which at
# 27 m/s is 1e-6 s again), and the FMU's fixed-step RODAS4 solver, whose steps end at every communication
# point, differs between the runs only by round-off. A few located instants in a chain: 1e-5 s.
TIME_TOLERANCE = 1e-5  # s
# a 2 ft ice patch: full brake from 88 ft/s at 100 ft, released below 10 ft/s; the wheels
# cross the patch (200..202 ft) while braking, each crossing changes the deceleration
SHORT_PATCH = "English\n100,BRK,100,2,10\n200,RSA,1,2\n202,RSA,1,8\n500,ES"

SCENARIOS = {
    # the demo up to 4700 ft (54 s): three vehicles spawned, the swerving one's manoeuvres, passes and
    # despawns, the ice stretch entered and left under a 2 s full brake
    "demo": (lambda: load_scenario(SCENARIO_DIRECTORY / "demo.sdl"), 4700 * FOOT),
    "head_on": (lambda: load_scenario(SCENARIO_DIRECTORY / "head_on.sdl"), None),
    "seed_a": (lambda: load_scenario(SCENARIO_DIRECTORY / "approaching_vehicle.sdl"), None),
    "short_patch": (lambda: parse_text(SHORT_PATCH, "short_patch.sdl"), None),
    # BRK on split friction: the car yaws, the driver counter-steers and the wheels cross 5 ft lane edges
    # onto other surfaces sideways (the surface triggers' lateral bounds under yaw)
    "spin": (lambda: load_scenario(SCENARIO_DIRECTORY / "spin.sdl"), None),
}


def identity(event):
    return (event["code"], event["action"], event.get("vehicle"), event.get("index"), event.get("reason"),
            event.get("lane"))


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_same_events_and_collisions_at_any_step(simple_fmu, name):
    load, until = SCENARIOS[name]
    scenario = load()
    runs = {step: run_scenario(scenario, simple_fmu, RunOptions(step=step, until_distance=until), TABLE)
            for step in STEPS}
    reference = runs[0.01]
    assert len(reference.events) >= 3
    for step, result in runs.items():
        assert [identity(e) for e in result.events] == [identity(e) for e in reference.events], step
        for event, expected in zip(result.events, reference.events):
            assert event["time_s"] == pytest.approx(expected["time_s"], abs=TIME_TOLERANCE), (step, event)
        assert result.collisions == reference.collisions, step
    if name == "head_on":
        assert reference.collisions == 1
    if name == "short_patch":
        rsa_crossings = {e["time_s"] for e in reference.events if e["code"] == "RSA"}
        assert len(rsa_crossings) == 2
    # long steps are long: at --step 10 the run takes about one step per driver sample, not more
    assert runs[10.0].timing["steps"] < 1.2 * reference.final["time_s"] / 0.05 + 200


def test_a_run_that_leaves_the_prediction_bounds_says_so(simple_fmu, monkeypatch):
    """The trigger prediction assumes bounds on the ego's yaw rate and acceleration; a run whose ego exceeds
    them (here: bounds shrunk below the spin scenario's 0.77 rad/s) carries one warning instead of silently
    risking a late trigger."""
    import dataclasses

    from sdl_fmu.cosim import master

    normal = run_scenario(load_scenario(SCENARIO_DIRECTORY / "spin.sdl"), simple_fmu, RunOptions(), TABLE)
    assert normal.warnings == []
    original = master.ego_bounds
    monkeypatch.setattr(master, "ego_bounds", lambda *args: dataclasses.replace(original(*args), yaw_rate=0.1))
    result = run_scenario(load_scenario(SCENARIO_DIRECTORY / "spin.sdl"), simple_fmu, RunOptions(), TABLE)
    assert sum("exceeded the bounds the trigger prediction assumes" in w for w in result.warnings) == 1
