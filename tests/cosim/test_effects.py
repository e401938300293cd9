"""The warnings for what never took effect in a run (sdl_fmu/cosim/effects.py, docs/results.md#warnings): an A
action whose closure time was never reached (a lead vehicle's braking behind which the follow driver keeps its
distance), an action the next one cut off before its transition ended, a BRK a controller's `override` swallowed or
that was released at the instant it came on, and the events a run that ended at the first contact never reached;
each in summary.json's warnings and on stderr, and none where everything took effect."""

import json
import re

import numpy as np
import pytest

from sdl_fmu import api
from sdl_fmu.cli import main
from sdl_fmu.cosim.master import TIME_TOLERANCE

SPEED = 88.0  # ft/s, the driver's default start speed, held by the lane driver (to 1e-11 ft/s on this straight road)
# The master reports a trigger at the first bisection probe where it holds: t_true <= t <= t_true + TIME_TOLERANCE
LATE = TIME_TOLERANCE + 1e-9

# A compact car (model 1) 300 ft ahead in our lane going our way at 60 ft/s; action 1 (closure time 2 s): it brakes
# to 20 ft/s over 3 s. The lane driver closes at 88 - 60 = 28 ft/s and fires it at a gap of 2 x 28 = 56 ft; the follow
# driver keeps its distance, so the closure time is never reached
LEAD_BRAKING = "English\n100,A,-60,300,*0,1,2,*0,-20,3\n2500,ES\n"


def write(tmp_path, name: str, text: str):
    path = tmp_path / name
    path.write_text(text)
    return path


def a_events(result) -> list[tuple[str, float]]:
    return [(event["action"], event["time_s"]) for event in result.events if event["code"] == "A"]


def test_a_braking_lead_whose_closure_time_the_follow_driver_never_reaches_is_one_warning(tmp_path, simple_fmu):
    path = write(tmp_path, "lead.sdl", LEAD_BRAKING)
    # the lane driver: the action fires when the gap (300 ft at the spawn) has closed to 56 ft at 28 ft/s
    lane = api.run(path, fmu=simple_fmu, plot=False)
    (_, spawn), (_, fired) = a_events(lane)[:2]
    assert a_events(lane)[1][0] == "maneuver" and 0 <= fired - (spawn + (300 - 56) / 28) <= LATE
    assert lane.warnings == []

    follow = api.run(path, fmu=simple_fmu, driver="follow", plot=False)
    assert [action for action, _ in a_events(follow)] == ["spawn"]  # the action never fired
    (warning,) = follow.warnings
    match = re.fullmatch(r"line 2: A action 1 \(parameters 5-8, closure time 2 s\) of vehicle 1 never fired: its "
                         r"closure time was never reached \(closest (\S+) s, at t = (\S+) s\); the run ended at "
                         rf"t = {follow.final['time_s']:.3f} s", warning)
    assert match, warning
    # the closest closure time, from timeseries.csv's columns: |gap| / closing speed where closing, the ego's speed
    # along the road vx cos(psi) - vy sin(psi), the car's A1_speed positive our way
    arrays = follow.arrays
    on_road = ~np.isnan(arrays["A1_gap_ft"])
    gap = arrays["A1_gap_ft"][on_road]
    psi = arrays["psi_rad"][on_road]
    ego = arrays["vx_ft/s"][on_road] * np.cos(psi) - arrays["vy_ft/s"][on_road] * np.sin(psi)
    closing = np.sign(gap) * (ego - arrays["A1_speed_ft/s"][on_road])
    ratio = np.where(closing > 0, np.abs(gap) / np.where(closing > 0, closing, 1.0), np.inf)
    k = int(np.argmin(ratio))
    assert float(match.group(1)) == pytest.approx(ratio[k], rel=5e-3)  # printed to 3 digits
    assert float(match.group(2)) == pytest.approx(arrays["time_s"][on_road][k], abs=5e-4)
    assert ratio[k] > 2.0  # why it never fired: the follow driver never came within 2 s of it


def test_the_actions_after_one_that_never_fired_are_a_warning_each(tmp_path, simple_fmu):
    # a second action (parameters 9-12) is armed only once the first has fired
    path = write(tmp_path, "lead2.sdl", LEAD_BRAKING.replace("-20,3\n", "-20,3,1,*0,0,2\n"))
    follow = api.run(path, fmu=simple_fmu, driver="follow", plot=False)
    assert len(follow.warnings) == 2 and "A action 1 (parameters 5-8" in follow.warnings[0]
    assert follow.warnings[1] == ("line 2: A action 2 (parameters 9-12, closure time 1 s) of vehicle 1 never fired: "
                                  "action 1 before it never did")


def test_an_action_cut_off_by_the_next_is_a_warning_with_the_time_it_ran(tmp_path, simple_fmu):
    # An oncoming car 2000 ft ahead at 20 ft/s: closing at 88 + 20 = 108 ft/s whatever its lateral moves (no action
    # changes its speed). Action 1 (closure time 10 s) fires at a gap of 1080 ft, (2000 - 1080) / 108 s after the
    # spawn, and starts a 2 s move toward our lane; action 2 (closure time 9.16 s) fires at a gap of 989.28 ft,
    # (1080 - 989.28) / 108 = 0.84 s later, and moves it back: action 1 ran 0.84 s of its 2 s
    path = write(tmp_path, "cut.sdl", "English\n100,A,20,2000,-6,1,10,*0,20,2,9.16,-6,20,2\n")
    result = api.run(path, fmu=simple_fmu, until_time=20.0, plot=False)
    (_, spawn), (_, first), (_, second) = a_events(result)[:3]
    assert 0 <= spawn - 100 / SPEED <= LATE
    assert 0 <= first - (spawn + 920 / 108) <= LATE and 0 <= second - (spawn + (2000 - 989.28) / 108) <= LATE
    assert second - first == pytest.approx(0.84, abs=LATE)
    hand = 100 / SPEED + (2000 - 989.28) / 108  # 10.49488 s, far from a rounding edge of the 3 decimals printed
    assert result.warnings == [
        "line 2: A action 1 (parameters 5-8, closure time 10 s) of vehicle 1 was cut off after 0.84 s of its 2 s "
        f"transition by A action 2 (parameters 9-12, closure time 9.16 s) at t = {hand:.3f} s"]
    # with action 2 at closure time 7 s it fires (10 - 7) s after action 1, once the 2 s move has ended: no warning
    later = api.run(write(tmp_path, "later.sdl", path.read_text().replace("9.16", "7")), fmu=simple_fmu,
                    until_time=20.0, plot=False)
    assert [action for action, _ in a_events(later)][:3] == ["spawn", "maneuver", "maneuver"] and later.warnings == []


OVERRIDE_MAP = """period = 0.01
[inputs]
lead_ttc = { variable = "ttc" }
lead_relative_speed = { variable = "relative_speed" }
[outputs]
deceleration = { variable = "deceleration_request" }
[arbitration]
brake = "override"
throttle = "driver"
steer = "driver"
"""


def test_a_brk_a_controller_overrides_is_a_warning_in_summary_json_and_on_stderr(tmp_path, simple_fmu,
                                                                               example_aeb_fmus, capsys):
    # The example AEB with its brake channel on `override` and no `active` output (always active): with no vehicle
    # ahead it requests a deceleration of 0, which replaces BRK's full brake from its onset at 1000 ft
    # (1000 / 88 s) for its 3 s (threshold type 0)
    path = write(tmp_path, "brk.sdl", "English\n1000,BRK,100,0,3\n2000,ES\n")
    cmap = write(tmp_path, "override.toml", OVERRIDE_MAP)
    out = tmp_path / "run"
    assert main(["run", str(path), "--fmu", str(simple_fmu), "--controller", str(example_aeb_fmus[2]),
                 "--controller-map", str(cmap), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    on, off = (event["time_s"] for event in summary["events"] if event["code"] == "BRK")
    assert 0 <= on - 1000 / SPEED <= LATE and off - on == pytest.approx(3.0, abs=1e-9)
    warning = (f"line 2: BRK (brake 100 %) was overridden for all of its 3 s hold (t = {on:.3f} to {off:.3f} s): the "
               "controller ExampleAeb sent less brake than BRK's (arbitration brake = override)")
    assert summary["warnings"] == [warning]
    assert f"warning: {warning}" in capsys.readouterr().err.splitlines()
    # swallowed: no brake at any sample (BRK's throttle cut held: the car coasts)
    assert max(row for row in np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1,
                                         usecols=_column(out, "brake_1"))) == 0.0
    # the shipped map's `max` keeps at least BRK's brake: it acts, no warning
    shipped = api.run(path, fmu=simple_fmu, controller="example-aeb", plot=False)
    assert shipped.warnings == [] and shipped.arrays["brake_1"].max() == 1.0


def _column(out, name: str) -> int:
    return (out / "timeseries.csv").read_text().splitlines()[0].split(",").index(name)


def test_a_brk_released_at_the_instant_it_comes_on_is_a_warning(tmp_path, simple_fmu):
    # threshold type 2: until the speed is below 100 ft/s, which 88 ft/s already is
    result = api.run(write(tmp_path, "brk.sdl", "English\n1000,BRK,50,2,100\n2000,ES\n"), fmu=simple_fmu, plot=False)
    on, off = (event["time_s"] for event in result.events if event["code"] == "BRK")
    assert on == off
    assert result.warnings == [f"line 2: BRK (brake 50 %) never took effect: it was released at the instant it came "
                               f"on (t = {on:.3f} s): the speed was already below its threshold"]


def test_the_events_a_run_stopped_at_the_first_contact_never_reached_are_one_warning(tmp_path, simple_fmu):
    # head_on's car in our lane, then a BRK and an RSA beyond the contact (about 740 ft): --on-collision stop ends
    # the run first
    path = write(tmp_path, "stop.sdl", "English\n200,A,40,800,*0,2\n1400,BRK,100,0,1\n1500,RSA,1,5\n1600,ES\n")
    stopped = api.run(path, fmu=simple_fmu, on_collision="stop", plot=False)
    end = stopped.events[-1]
    assert end["reason"] == "collision" and end["distance"] < 1400
    assert stopped.warnings == [f"line 3: BRK/RSA never reached: the run ended at the first contact (--on-collision "
                                f"stop) at t = {end['time_s']:.3f} s, before the distance of lines 3, 4"]
    # the user's own --until-distance is not warned of
    assert api.run(path, fmu=simple_fmu, until_distance=1000.0, plot=False).warnings == []


def test_the_overridden_part_of_a_hold_is_the_samples_whose_commands_have_less_brake_or_throttle():
    # brake_warnings on a hold's samples written out: each sample's commands hold until the next sample. BRK on at
    # 1.0 s, off at 3.5 s (2.5 s); the brake sent is below BRK's (driver_brake) from 2.0 to 2.5 s, and some throttle
    # is sent from 3.0 s to the release: 0.5 + 0.5 = 1 s of the 2.5 s hold
    from types import SimpleNamespace

    from sdl_fmu.cosim.effects import brake_warnings

    columns = {"time": np.array([0.0, 1.0, 2.0, 2.5, 3.0, 3.5, 4.0]),
               "brake": np.array([0.0, 1.0, 0.3, 1.0, 1.0, 0.0, 0.0]),
               "driver_brake": np.array([0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0]),
               "throttle": np.array([0.5, 0.0, 0.0, 0.0, 0.2, 0.5, 0.5])}
    events = [{"code": "BRK", "action": "on", "time_s": 1.0, "pedal": 100.0, "line": 7},
              {"code": "A", "action": "spawn", "time_s": 1.5, "line": 3},
              {"code": "BRK", "action": "off", "time_s": 3.5, "reason": "time", "line": 7}]
    controller = SimpleNamespace(name="C", rules={"brake": "override", "throttle": "max", "steer": "driver"})
    assert brake_warnings(events, columns, controller) == [(7, (
        "line 7: BRK (brake 100 %) was overridden for 1 s of its 2.5 s hold (t = 1.000 to 3.500 s): the controller C "
        "sent less brake than BRK's (arbitration brake = override) and throttle (arbitration throttle = max)"))]
    # without a controller only a hold of no length is a warning
    assert brake_warnings(events, columns, None) == []
