"""Every shipped example runs without a warning under the dynamics its header says it is written for, and
the Advanced demo's wheels roll over every surface it sets in the driver's lane."""

import re

import numpy as np
import pytest

from sdl_fmu import api

WRITTEN_FOR = re.compile(r"^// Written for: (.+?) dynamics", re.M)
SKIPPING = re.compile(r"^// Written for: .+ dynamics, with --skip-unsupported", re.M)
DRIVER = re.compile(r"^// Written for: .+ dynamics, with --driver (\w+)", re.M)


def driver_of(name: str) -> str | None:
    """The built-in driver an example's header asks for (`with --driver follow`), else the default lane driver."""
    match = DRIVER.search(api.shipped_scenarios()[name].read_text(encoding="utf-8"))
    return match.group(1) if match else "lane"


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
    result = api.run(name, dynamics=dynamics, fmu=fmu, skip_unsupported=skip, driver=driver_of(name))
    assert [w for w in result.warnings if not (skip and "is not simulated: skipped" in w)] == []
    assert not skip or result.warnings
    assert any(event["code"] == "ES" or event["action"] == "end" for event in result.events) or result.final


def test_the_advanced_demo_rolls_over_each_surface_of_its_lane(advanced_fmu):
    result = api.run("demo_advanced", dynamics="advanced", fmu=advanced_fmu, driver="follow")
    # the attribute numbers RSA sets in lane 1 (the driver's), each under all four wheels at some sample
    lane_one = {int(event["value"]) for event in result.events if event["code"] == "RSA" and event["lane"] == 1}
    assert lane_one == {0, 1, 2, 3}
    for wheel in ("fl", "fr", "rl", "rr"):
        assert set(np.unique(result.raw.columns[f"surface_{wheel}"]).astype(int)) == lane_one
    assert result.final["distance"] == pytest.approx(5280.0, abs=1.0)  # the ES line, the whole mile


def test_in_the_advanced_demo_the_car_brakes_for_the_suv_ahead_and_follows_it(advanced_fmu):
    # With the follow driver the Advanced car holds 88 ft/s until it catches up with the SUV going our way at
    # 50 ft/s in our lane (A2, spawned at 1200 ft 600 ft ahead), then brakes and follows it: its speed ends at the
    # SUV's (Gipps' law settles on the leader's speed: within 0.1 ft/s), the brake pedal is used, no collision,
    # and the SUV is the lead vehicle from its spawn to the end
    assert driver_of("demo_advanced") == "follow"
    result = api.run("demo_advanced", dynamics="advanced", fmu=advanced_fmu, driver="follow")
    speed = result.arrays["speed_ft/s"]
    assert speed[0] == pytest.approx(88.0, abs=1e-6) and result.final["speed"] == pytest.approx(50.0, abs=0.1)
    assert result.arrays["brake_1"].max() > 0.05 and result.collisions == 0
    spawn = next(e for e in result.events if e["action"] == "spawn" and e.get("line") is not None
                 and e["distance"] == pytest.approx(1200.0, abs=1.0))
    lead = result.raw.lead_series()
    after = result.time >= spawn["time_s"]
    assert (lead["index"][after] == spawn["vehicle"] - 1).all()


def test_the_lead_vehicle_example_follows_the_car_and_passes_it(simple_fmu):
    # The car going our way at 60 ft/s, 500 ft ahead: the ego closes at 28 ft/s, and passes it once it has moved
    # into the opposite lane (closure time 5 s: a gap of 140 ft, 360 ft / 28 ft/s = 12.857 s after its spawn): no
    # collision, and while it is the lead vehicle its speed is +60 ft/s our way (signals.py: along the road)
    result = api.run("lead_vehicle", dynamics="simple", fmu=simple_fmu)
    assert result.collisions == 0 and [e["action"] for e in result.events if e["code"] == "A"] == [
        "spawn", "maneuver", "despawn"]
    spawn, maneuver = (e["time_s"] for e in result.events if e["action"] in ("spawn", "maneuver"))
    assert maneuver - spawn == pytest.approx(360 / 28, abs=1e-5)
    lead = result.raw.lead_series()
    assert lead["present"].any()
    assert np.allclose(lead["speed"][lead["present"] & (result.time <= maneuver)], 60 * 0.3048)
    # timeseries.csv's A1 columns (docs/results.md): its speed +60 ft/s (our way) while it drives straight; at its
    # spawn 500 ft ahead (centres) the bumper gap is 500 ft less the ego's half length and the car's (4.2 m / 2),
    # the ego at yaw 0 (lane keeping on a straight road: |psi| < 1e-9, its extent ahead L/2 to 1e-9 m)
    arrays = result.arrays
    on_road = ~np.isnan(arrays["A1_speed_ft/s"])
    spawn = int(np.flatnonzero(on_road)[0])
    assert np.abs(arrays["psi_rad"]).max() < 1e-9
    assert np.allclose(arrays["A1_speed_ft/s"][on_road & (result.time <= maneuver)], 60.0)
    assert arrays["A1_gap_ft"][spawn] == pytest.approx(500.0, abs=1e-9)
    ego_length = api.ego_model("simple", fmu=simple_fmu).length
    assert arrays["A1_bumper_gap_ft"][spawn] == pytest.approx(500.0 - (ego_length / 2 + 2.1) / 0.3048, abs=1e-6)
