"""Real STISIM files load: events in any order take effect in order of distance (file order breaking ties,
reproducible from the seed), and with --skip-unsupported every line sdl-fmu does not simulate (long-form names,
labels, '@' triggers, {n} values, Config_ settings) is skipped with one warning per code, while the supported events
keep their strict checks and fire at their distances."""

import pytest

from sdl_fmu import api
from sdl_fmu.cli import main
from sdl_fmu.cosim.master import TIME_TOLERANCE
from sdl_fmu.sdl import ScenarioError, parse_text

STISIM3 = api.shipped_scenarios()["stisim3_intersection"]

# (line, code, distance in ft) of every event sdl-fmu simulates in the STISIM 3 file, in the file's order
SUPPORTED = [(37, "ES", 4000.0), (67, "A", 300.0), (68, "A", 900.0), (76, "RSA", 2600.0), (77, "RSA", 1600.0),
             (83, "BRK", 2200.0)]
ROAD_LINE = 43
# every other line with content that is not a comment: what --skip-unsupported must skip, and nothing else
SKIPPED = {15: "settings line 'Config_LoadingMessage = ...'", 16: "settings line 'Config_Start_Y = ...'",
           17: "settings line 'Config_Speed_Units = ...'", 23: "event code 'Begin Block Save'",
           24: "event code 'End Block Save'", 30: "event code 'Crash Settings'", 31: "event code 'Crash Settings'",
           44: "event code 'ROADWAY'", 45: "event code 'ROADWAY'", 51: "event code 'INTERSECTION'",
           52: "event code 'Signal Light'", 53: "event code 'Previously Defined Events'",
           59: "event code 'PEDESTRIAN'", 69: "event 'Vehicles' triggered by '@'",
           70: "event 'Vehicles' triggered by '@'", 89: "event code 'Play Recording'"}


def content_lines(path):
    lines = path.read_text().splitlines()
    return {n for n, line in enumerate(lines, start=1) if line.split("//")[0].strip()}


def test_the_stisim3_file_is_fully_accounted_for():
    # the test's tables cover every line of the file: supported, the ROAD, or skipped
    assert content_lines(STISIM3) == {line for line, _, _ in SUPPORTED} | {ROAD_LINE} | set(SKIPPED)


def test_stisim3_file_without_skip_names_every_unsimulated_line_and_nothing_else(capsys):
    assert main(["check", str(STISIM3)]) == 1
    lines = capsys.readouterr().err.splitlines()
    assert [int(line.split(":")[1]) for line in lines] == sorted(SKIPPED)
    assert all(line.startswith(f"{STISIM3}:") and "--skip-unsupported" in line for line in lines)


def test_stisim3_file_with_skip_warns_once_per_code():
    scenario = api.load(STISIM3, skip_unsupported=True)
    expected = {}
    for line, what in SKIPPED.items():
        expected.setdefault(what, []).append(line)
    assert list(scenario.warnings) == [
        f"line {lines[0]}: {what} is not simulated: skipped (line{'s' * (len(lines) > 1)} {', '.join(map(str, lines))})"
        for what, lines in expected.items()]
    # the events in the order they take effect: by distance
    assert [(e.line, e.code) for e in scenario.events] == [
        (line, code) for line, code, _ in sorted(SUPPORTED, key=lambda item: item[2])]
    assert (scenario.road.lanes, scenario.road.lanes_right, scenario.end_distance) == (4, 2, 4000 * 0.3048)


def test_stisim3_file_runs_and_its_events_fire_at_their_distances(simple_fmu):
    result = api.run(STISIM3, skip_unsupported=True, fmu=simple_fmu, seed=7, plot=False)
    fired = [e for e in result.events if e["action"] in ("spawn", "set", "on") or e["code"] == "ES"]
    by_line = {}
    for event in fired:
        by_line.setdefault(event.get("line", 37), event)  # ES is logged without its line
    assert sorted(by_line) == sorted(line for line, _, _ in SUPPORTED)
    # each fires where the file says: a distance trigger is located within TIME_TOLERANCE, at most 88 ft/s here
    for line, code, distance in SUPPORTED:
        event = by_line[line]
        assert event["code"] == code
        assert 0 <= event["distance"] - distance <= 88.0 * TIME_TOLERANCE, (line, event)
    times = [event["time_s"] for event in fired]
    assert times == sorted(times)  # in order of distance, whatever the file's order
    assert result.events[-1]["reason"] == "scenario"
    # reproducible from the seed: the same events again, the random model included
    again = api.run(STISIM3, skip_unsupported=True, fmu=simple_fmu, seed=7, plot=False)
    assert list(again.events) == list(result.events)


def test_events_take_effect_by_distance_with_file_order_breaking_ties():
    scenario = parse_text("500,BRK,50,0,1\n100,RSA,1,4\n500,A,20,100,-6,*1~8\n100,A,20,100,-6,2\n0,RSA,1,8\n600,ES")
    assert [e.line for e in scenario.events] == [5, 2, 4, 1, 3, 6]


def test_seeded_models_follow_the_order_of_effect(simple_fmu, tmp_path):
    # two random vehicles listed in reverse: the first to spawn (the nearer) draws first, whatever the file's order
    path = tmp_path / "reverse.sdl"
    path.write_text("English\n600,ES\n400,A,20,300,-6,*1~10\n200,A,20,300,-6,*1~10\n")
    forward = tmp_path / "forward.sdl"
    forward.write_text("English\n200,A,20,300,-6,*1~10\n400,A,20,300,-6,*1~10\n600,ES\n")
    models = []
    for scenario in (path, forward):
        result = api.run(scenario, fmu=simple_fmu, seed=11, plot=False, until_distance=450)
        models.append([(e["distance"] // 1, e["model"]) for e in result.events if e["action"] == "spawn"])
    assert models[0] == models[1]
    assert models[0][0][1] != models[0][1][1]  # the two draws differ, so a draw in file order would show


@pytest.mark.parametrize("text, field", [
    ("0,A#3,20,100,-6,1", "event code"),  # a label on a supported code is not silently ignored
    ("10,BRK,100{1},0,3", "BRK parameter 1 (pedal %)"),  # {n} values are strict errors in supported events
    ("10,RSA,1,5{2}", "RSA parameter 2 (value)"),
    ("10{1},ES", "distance"),
])
def test_supported_events_keep_their_strict_checks_with_skip(text, field):
    with pytest.raises(ScenarioError) as caught:
        parse_text(text, "s.sdl", skip_unsupported=True)
    assert [e.field for e in caught.value.errors] == [field]


def test_settings_lines_are_skipped_whatever_their_value_holds():
    text = "Config_Colors = 255, 255, 255\nConfig_Start_Y = 0{0}\nConfig_Colors = 0, 0, 0\n10,BRK,50,0,1\n"
    scenario = parse_text(text, skip_unsupported=True)
    assert [e.code for e in scenario.events] == ["BRK"]
    assert scenario.warnings == ("line 1: settings line 'Config_Colors = ...' is not simulated: skipped (lines 1, 3)",
                                 "line 2: settings line 'Config_Start_Y = ...' is not simulated: skipped (line 2)")
    with pytest.raises(ScenarioError) as caught:
        parse_text(text, "s.sdl")
    assert [(e.line, e.field) for e in caught.value.errors] == [(1, "settings line"), (2, "settings line"),
                                                                (3, "settings line")]
