"""SDL parser: the STISIM text's examples parse to the right typed events in SI, and every bad input is reported."""

import pytest

from sdl_fmu.sdl import (
    DEFAULT_ROAD,
    Action,
    ApproachingVehicle,
    Brake,
    ClosureTrigger,
    EndOfScenario,
    ModelChoice,
    Relative,
    Road,
    ScenarioError,
    SdlError,
    SurfaceAttribute,
    VehicleModel,
    check_models,
    default_vehicle_table_path,
    describe,
    load_scenario,
    load_vehicle_table,
    parse_text,
)
from sdl_fmu.units import ENGLISH, FOOT, METRIC

WIDE_ROAD = "0,ROAD,12,10,5\n"  # 5 lanes each way, so the RSA example's lane -5 exists


def only_event(text):
    (event,) = parse_text(text).events
    return event


def errors_of(text, path="s.sdl"):
    with pytest.raises(ScenarioError) as caught:
        parse_text(text, path)
    return caught.value.errors


# --- the STISIM text's examples ------------------------------------------------------------------


def test_seed_approaching_vehicle_example_in_si():
    event = only_event("100,A,20,1000,-6,*1~8,10,*0,20,2,5,-6,20,2")
    assert event == ApproachingVehicle(
        line=1,
        distance=100 * FOOT,
        speed=Relative(20 * FOOT, False),
        gap=1000 * FOOT,
        lateral=Relative(-6 * FOOT, False),
        model=ModelChoice(1, 8),
        actions=(
            Action(ClosureTrigger(10.0, None), Relative(0.0, True), Relative(20 * FOOT, False), 2.0),
            Action(ClosureTrigger(5.0, None), Relative(-6 * FOOT, False), Relative(20 * FOOT, False), 2.0),
        ),
    )
    assert event.speed.value == pytest.approx(6.096)
    assert event.gap == pytest.approx(304.8)
    assert event.model.is_random
    assert event.code == "A"


@pytest.mark.parametrize(
    "line, pedal, threshold, magnitude",
    [
        ("1000,BRK,100,0,3", 1.0, "time", 3.0),
        ("2000,BRK,25,1,200", 0.25, "distance", 200 * FOOT),
        ("3000,BRK,50,2,30", 0.5, "velocity", 30 * FOOT),
        ("4000,BRK,100,3,30", 1.0, "relative_velocity", 30 * FOOT),
    ],
)
def test_seed_brake_examples(line, pedal, threshold, magnitude):
    event = only_event(line)
    distance = float(line.split(",")[0]) * FOOT
    assert event == Brake(line=1, distance=distance, pedal=pedal, threshold=threshold, magnitude=magnitude)


def test_seed_simple_dynamics_rsa_examples():
    scenario = parse_text(WIDE_ROAD + "1000,RSA,1,10,-5,2\n1100,RSA,1,8,-5,8\n")
    assert scenario.events == (
        SurfaceAttribute(line=2, distance=1000 * FOOT, settings=((1, 10.0), (-5, 2.0))),
        SurfaceAttribute(line=3, distance=1100 * FOOT, settings=((1, 8.0), (-5, 8.0))),
    )


def test_seed_advanced_dynamics_rsa_examples_with_shoulder():
    scenario = parse_text(WIDE_ROAD + "1000,RSA,1,1,-5,2,101,3\n1100,RSA,1,0,-5,1\n")
    assert scenario.events == (
        SurfaceAttribute(line=2, distance=1000 * FOOT, settings=((1, 1.0), (-5, 2.0), (101, 3.0))),
        SurfaceAttribute(line=3, distance=1100 * FOOT, settings=((1, 0.0), (-5, 1.0))),
    )


def test_rsa_left_shoulder_exists_on_the_default_road():
    event = only_event("10,RSA,-101,2,-1,3")
    assert event.settings == ((-101, 2.0), (-1, 3.0))


# --- units, layout and file format ---------------------------------------------------------------


def test_english_is_the_default_and_metric_keeps_metres():
    text = "100,A,*-5,50,*0,2\n200,BRK,40,1,30\n"
    english = parse_text(text)
    metric = parse_text("Metric\n" + text)
    assert english.units == ENGLISH and metric.units == METRIC
    assert english.events[0].distance == pytest.approx(30.48)
    assert english.events[0].speed == Relative(-5 * FOOT, True)
    assert metric.events[0].distance == 100.0
    assert metric.events[0].gap == 50.0
    assert metric.events[0].speed == Relative(-5.0, True)
    assert metric.events[1].line == 3
    assert metric.events[1].magnitude == 30.0
    assert english.events[1].magnitude == pytest.approx(9.144)


@pytest.mark.parametrize("header", ["english", "ENGLISH", "  English  // units", "metric", "Metric"])
def test_units_header_is_case_insensitive(header):
    expected = METRIC if "metric" in header.lower() else ENGLISH
    assert parse_text(header + "\n10,ES").units == expected


def test_comments_blank_lines_crlf_whitespace_and_bom():
    text = ("\ufeff// header comment\r\n\r\n  Metric // units\r\n\r\n 10 , brk , 50 , 0 , 2  // brake\r\n"
            "// end\r\n20,es\r\n")
    scenario = parse_text(text)
    assert scenario.units == METRIC
    assert scenario.events == (
        Brake(line=5, distance=10.0, pedal=0.5, threshold="time", magnitude=2.0),
        EndOfScenario(line=7, distance=20.0),
    )
    assert scenario.end_distance == 20.0


def test_numbers_with_exponent_sign_and_fraction():
    event = only_event("1e2,BRK,+5e1,0,.5")
    assert (event.distance, event.pedal, event.magnitude) == (100 * FOOT, 0.5, 0.5)


def test_default_road_and_end():
    scenario = parse_text("10,BRK,50,0,1")
    assert scenario.road == DEFAULT_ROAD
    assert DEFAULT_ROAD.lane_width == pytest.approx(3.6576)
    assert (DEFAULT_ROAD.lanes, DEFAULT_ROAD.lanes_right, DEFAULT_ROAD.lanes_left) == (2, 1, 1)
    assert DEFAULT_ROAD.lane_center(1) == pytest.approx(6 * FOOT)
    assert scenario.end_distance is None


def test_road_event_sets_the_layout_and_is_not_an_event():
    scenario = parse_text("Metric\n0,ROAD,3.5,3,2\n10,ES")
    assert scenario.road == Road(line=2, distance=0.0, lane_width=3.5, lanes=3, lanes_right=2)
    assert scenario.events == (EndOfScenario(line=3, distance=10.0),)


def test_road_lane_geometry():
    road = Road(line=1, distance=0.0, lane_width=4.0, lanes=3, lanes_right=2)
    assert road.lanes_left == 1
    assert road.valid_lanes == (1, 2, -1, 101, -101)
    assert [road.lane_center(lane) for lane in (1, 2, -1, 101, -101)] == [2.0, 6.0, -2.0, 10.0, -6.0]
    assert [road.lane_at(y) for y in (0.0, 3.9, 4.0, 7.9, 8.0, 50.0)] == [1, 1, 2, 2, 101, 101]
    assert [road.lane_at(y) for y in (-0.1, -3.9, -4.0, -50.0)] == [-1, -1, -101, -101]
    with pytest.raises(ValueError):
        road.lane_center(-2)


def test_closure_suffixes_and_negative_times():
    event = only_event("0,A,30,500,6,2,10F,6,30,1,-4B,*0,*0,0,3f,-6,0,1,-2.5b,6,30,0.5,8,6,30,1")
    assert [action.trigger for action in event.actions] == [
        ClosureTrigger(10.0, "F"),
        ClosureTrigger(-4.0, "B"),
        ClosureTrigger(3.0, "F"),
        ClosureTrigger(-2.5, "B"),
        ClosureTrigger(8.0, None),
    ]
    assert len(event.actions) == 5
    assert event.actions[1].duration == 0.0
    assert event.actions[1].speed == Relative(0.0, True)


def test_a_without_actions_and_with_one_action():
    bare = only_event("0,A,-20,-300,*12,5")
    assert bare.actions == ()
    assert bare.speed == Relative(-20 * FOOT, False) and bare.gap == -300 * FOOT
    assert bare.lateral == Relative(12 * FOOT, True)
    assert bare.model == ModelChoice(5, 5) and not bare.model.is_random
    one = only_event("0,A,20,300,6,*3~3,10,*0,20,2")
    assert len(one.actions) == 1 and one.model == ModelChoice(3, 3) and not one.model.is_random


def test_equal_distances_are_allowed_and_file_order_kept():
    scenario = parse_text("10,BRK,50,0,1\n10,RSA,1,4\n10,A,20,100,-6,1\n10,ES")
    assert [event.code for event in scenario.events] == ["BRK", "RSA", "A", "ES"]


def test_describe_reports_in_the_file_units():
    text = describe(parse_text(WIDE_ROAD + "100,A,20,1000,-6,*1~8,10,*0,20,2\n1000,BRK,100,0,3\n1000,RSA,1,10\n5000,ES",
                               "demo.sdl"))
    assert "demo.sdl" in text
    assert "English" in text
    assert "10 lanes of 12 ft, 5 right and 5 left" in text
    assert "line 3  1000 ft  BRK 100 % until time 3 s" in text
    assert "A model 1~8 (random), 1000 ft ahead, lateral -6 ft, speed 20 ft/s" in text
    assert "closing within 10 s -> lateral ego+0 ft, speed 20 ft/s over 2 s" in text
    assert "RSA lane 1 = 10" in text
    assert "end: 5000 ft" in text
    metric = describe(parse_text("Metric\n10,BRK,50,2,5"))
    assert "BRK 50 % until speed below 5 m/s" in metric and "default layout" in metric
    assert "lanes of 3.6576 m" in metric


def test_load_scenario_reads_bom_and_crlf(tmp_path):
    path = tmp_path / "s.sdl"
    path.write_bytes("\ufeffMetric\r\n10,BRK,50,0,1\r\n".encode("utf-8"))
    scenario = load_scenario(path)
    assert scenario.path == str(path) and scenario.units == METRIC
    assert scenario.events[0].line == 2


# --- every error path ------------------------------------------------------------------------------

ERRORS = [
    # units header, event code, distance
    ("Imperial\n10,ES", 1, "units header", "'Imperial' is not a units header"),
    ("10,ES\nMetric", 2, "units header", "must be the first line"),
    ("10,BRK,50,0,1\n20", 2, "event code", "has no event code"),
    ("10,,1", 1, "event code", "unsupported event code empty"),
    ("10,V,1,2", 1, "event code", "unsupported event code 'V' (supported: A, BRK, RSA, ROAD, ES)"),
    ("ten,ES", 1, "distance", "'ten' is not a number"),
    (",ES", 1, "distance", "empty; expected a number"),
    ("*10,ES", 1, "distance", "'*' (relative to the ego) is not allowed here"),
    ("-5,ES", 1, "distance", "'-5' must be >= 0"),
    ("1e999,ES", 1, "distance", "too large"),
    ("nan,ES", 1, "distance", "'nan' is not a number"),
    # ROAD
    ("10,ROAD,12,2,1", 1, "distance", "ROAD must be at distance 0"),
    ("0,ROAD,12,2,1\n0,ROAD,12,4,2", 2, "event code", "a second ROAD (the first is on line 1)"),
    ("0,ROAD,12,2", 1, "ROAD parameters", "ROAD takes 3 parameters"),
    ("0,ROAD,0,2,1", 1, "ROAD parameter 1 (lane width)", "must be > 0"),
    ("0,ROAD,12,0,0", 1, "ROAD parameter 2 (lanes)", "must be >= 1"),
    ("0,ROAD,12,2.5,1", 1, "ROAD parameter 2 (lanes)", "'2.5' is not a whole number"),
    ("0,ROAD,12,2,3", 1, "ROAD parameter 3 (lanes right of the dividing line)", "from 1 to the number of lanes (2)"),
    ("0,ROAD,12,2,0", 1, "ROAD parameter 3 (lanes right of the dividing line)", "the ego starts in lane 1"),
    # ES
    ("10,ES\n20,ES", 2, "event code", "a second ES (the first is on line 1)"),
    ("10,ES\n20,BRK,50,0,1", 2, "distance", "BRK at 20 is at or beyond the ES on line 1: it would never fire"),
    ("10,BRK,50,0,1\n10,ES\n10,RSA,1,4", 3, "distance", "RSA at 10 is at or beyond the ES on line 2"),
    ("10,ES,5", 1, "ES parameters", "ES takes no parameters; got 1"),
    # BRK
    ("10,BRK,50,0", 1, "BRK parameters", "BRK takes 3 parameters"),
    ("10,BRK,101,0,1", 1, "BRK parameter 1 (pedal %)", "percentage from 0 to 100"),
    ("10,BRK,-1,0,1", 1, "BRK parameter 1 (pedal %)", "percentage from 0 to 100"),
    ("10,BRK,*50,0,1", 1, "BRK parameter 1 (pedal %)", "'*' (relative to the ego) is not allowed"),
    ("10,BRK,50,4,1", 1, "BRK parameter 2 (threshold type)", "0 (time), 1 (distance), 2 (velocity) or 3"),
    ("10,BRK,50,1.5,1", 1, "BRK parameter 2 (threshold type)", "not a whole number"),
    ("10,BRK,50,0,0", 1, "BRK parameter 3 (magnitude)", "'0' must be > 0"),
    ("10,BRK,50,0,x", 1, "BRK parameter 3 (magnitude)", "'x' is not a number"),
    # RSA
    ("10,RSA", 1, "RSA parameters", "at least one pair; got 0"),
    ("10,RSA,1,8,2", 1, "RSA parameters", "got 3 parameters"),
    ("10,RSA,1.5,8", 1, "RSA parameter 1 (lane)", "'1.5' is not a whole number"),
    ("10,RSA,1,8,1,2", 1, "RSA parameter 3 (lane)", "lane 1 is set twice"),
    ("10,RSA,1,-2", 1, "RSA parameter 2 (value)", "'-2' must be >= 0"),
    # A
    ("0,A,20,100,-6", 1, "A parameters", "got 3"),
    ("0,A,20,100,-6,1,10", 1, "A parameters", "got 5"),
    ("0,A," + ",".join(["1"] * 28), 1, "A parameters", "got 28"),
    ("0,A,fast,100,-6,1", 1, "A parameter 1 (speed)", "'fast' is not a number or '*number'"),
    ("0,A,*,100,-6,1", 1, "A parameter 1 (speed)", "'*' is not a number or '*number'"),
    ("0,A,20,0,-6,1", 1, "A parameter 2 (gap)", "cannot appear at gap 0"),
    ("0,A,20,*100,-6,1", 1, "A parameter 2 (gap)", "'*' (relative to the ego) is not allowed"),
    ("0,A,20,100,,1", 1, "A parameter 3 (lateral position)", "empty"),
    ("0,A,20,100,-6,0", 1, "A parameter 4 (model)", "model numbers start at 1"),
    ("0,A,20,100,-6,*0~8", 1, "A parameter 4 (model)", "model numbers start at 1, low end is 0"),
    ("0,A,20,100,-6,*8~1", 1, "A parameter 4 (model)", "'*8~1': low end 8 is above high end 1"),
    ("0,A,20,100,-6,*1-8", 1, "A parameter 4 (model)", "random range '*low~high'"),
    ("0,A,20,100,-6,1~8", 1, "A parameter 4 (model)", "'1~8' is not a number"),
    ("0,A,20,100,-6,2.5", 1, "A parameter 4 (model)", "'2.5' is not a whole number"),
    ("0,A,20,100,-6,1,0,*0,20,2", 1, "A parameter 5 (action 1 closure time)", "closure time 0 can never fire"),
    ("0,A,20,100,-6,1,10X,*0,20,2", 1, "A parameter 5 (action 1 closure time)", "optional F or B suffix"),
    ("0,A,20,100,-6,1,*10,*0,20,2", 1, "A parameter 5 (action 1 closure time)", "'*' (relative to the ego)"),
    ("0,A,20,100,-6,1,10,left,20,2", 1, "A parameter 6 (action 1 lateral position)", "'left' is not a number"),
    ("0,A,20,100,-6,1,10,*0,20,2,5,-6,*x,2", 1, "A parameter 11 (action 2 speed)", "'*x' is not a number"),
    ("0,A,20,100,-6,1,10,*0,20,-1", 1, "A parameter 8 (action 1 transition time)", "'-1' must be >= 0"),
]


@pytest.mark.parametrize("text, line, field, reason", ERRORS, ids=[f"{e[2]}: {e[3]}" for e in ERRORS])
def test_error_is_reported_with_line_and_field(text, line, field, reason):
    errors = errors_of(text)
    assert any(e.line == line and e.field == field and reason in e.reason for e in errors), errors
    with pytest.raises(ScenarioError, match=f"s.sdl:{line}: {field.replace('(', r'.').replace(')', r'.')}: "):
        parse_text(text, "s.sdl")


def test_every_bad_line_is_reported_not_only_the_first():
    text = "English\n100,BRK,50,9,1\n200,A,20,100,-6,*8~1\n// ok\n300,RSA,1,-8\n400,ES\n"
    errors = errors_of(text, "three.sdl")
    assert [(e.line, e.field) for e in errors] == [
        (2, "BRK parameter 2 (threshold type)"),
        (3, "A parameter 4 (model)"),
        (5, "RSA parameter 2 (value)"),
    ]
    message = str(ScenarioError(errors))
    assert message.splitlines() == [str(e) for e in errors]
    assert message.splitlines()[0].startswith("three.sdl:2: BRK parameter 2 (threshold type): ")


def test_one_line_can_have_several_errors():
    errors = errors_of("-1,A,x,0,-6,0")
    assert {e.field for e in errors} == {"distance", "A parameter 1 (speed)", "A parameter 2 (gap)",
                                         "A parameter 4 (model)"}


def test_rsa_lanes_are_not_checked_against_a_broken_road():
    errors = errors_of("0,ROAD,12,x,1\n10,RSA,-3,8")
    assert [e.field for e in errors] == ["ROAD parameter 2 (lanes)"]


def test_sdl_error_format():
    assert str(SdlError("a.sdl", 4, "distance", "bad")) == "a.sdl:4: distance: bad"


def test_load_scenario_missing_file(tmp_path):
    with pytest.raises(ScenarioError) as caught:
        load_scenario(tmp_path / "missing.sdl")
    (error,) = caught.value.errors
    assert error.field == "file" and "cannot be read" in error.reason and "missing.sdl" in str(error)


def test_load_scenario_not_utf8_is_read_as_windows_1252_with_a_warning(tmp_path):
    path = tmp_path / "latin1.sdl"
    path.write_bytes(b"10,ES\n// caf\xe9\n")
    assert load_scenario(path).warnings == (
        "line 2: file: is not UTF-8 (first such line); the file was read as Windows-1252",)


def test_load_scenario_reports_the_file_path(tmp_path):
    path = tmp_path / "bad.sdl"
    path.write_text("10,XYZ\n")
    with pytest.raises(ScenarioError, match=r"bad.sdl:1: event code: unsupported event code 'XYZ'"):
        load_scenario(path)


# --- vehicle table ---------------------------------------------------------------------------------


def test_shipped_vehicle_table():
    table = load_vehicle_table(default_vehicle_table_path())
    assert len(table) >= 8 and sorted(table) == list(range(1, len(table) + 1))
    assert table[1] == VehicleModel(1, "compact car", 4.2, 1.75)
    assert all(model.length > 0 and model.width > 0 for model in table.values())
    assert any(model.name == "city bus" and model.length == 12.0 for model in table.values())


@pytest.mark.parametrize(
    "rows, expected",
    [
        ("model,name,length\n1,car,4,2\n", ":1: header: expected 'model,name,length_m,width_m'"),
        ("model,name,length_m,width_m\n0,car,4,2\n", ":2: model: '0' must be a whole number >= 1"),
        ("model,name,length_m,width_m\n1,car,4,2\n1,van,5,2\n", ":3: model: 1 is listed twice"),
        ("model,name,length_m,width_m\n1,,4,2\n", ":2: name: empty"),
        ("model,name,length_m,width_m\n1,car,-4,2\n", ":2: length_m: '-4' must be a number of metres > 0"),
        ("model,name,length_m,width_m\n1,car,4,wide\n", ":2: width_m: 'wide' must be a number"),
        ("model,name,length_m,width_m\n1,car,4\n", ":2: row: expected 4 fields"),
        ("model,name,length_m,width_m\n", ":1: table: no vehicles listed"),
    ],
)
def test_bad_vehicle_table(tmp_path, rows, expected):
    path = tmp_path / "vehicles.csv"
    path.write_text(rows)
    with pytest.raises(ValueError, match="vehicles.csv" + expected.replace("(", r"\(").replace(")", r"\)")):
        load_vehicle_table(path)


def test_missing_vehicle_table(tmp_path):
    with pytest.raises(ValueError, match=r"nope.csv:0: file: cannot be read"):
        load_vehicle_table(tmp_path / "nope.csv")


def test_check_models_against_the_table():
    table = {n: VehicleModel(n, f"car {n}", 4.0, 1.8) for n in (1, 2, 3, 5)}
    scenario = parse_text("0,A,20,100,-6,2\n10,A,20,100,-6,*1~3\n20,A,20,100,-6,4\n30,A,20,100,-6,*2~7", "m.sdl")
    errors = check_models(scenario, table)
    assert [(e.line, e.field) for e in errors] == [(3, "A parameter 4 (model)"), (4, "A parameter 4 (model)")]
    assert "model 4 is not in the table; the vehicle table has models 1-3, 5" in errors[0].reason
    assert "'*2~7': models 4, 6-7 are not in the table" in errors[1].reason
    assert str(errors[0]).startswith("m.sdl:3: A parameter 4 (model): ")


def test_seed_example_models_are_all_in_the_shipped_table():
    scenario = parse_text("100,A,20,1000,-6,*1~8,10,*0,20,2,5,-6,20,2")
    assert check_models(scenario, load_vehicle_table(default_vehicle_table_path())) == []
