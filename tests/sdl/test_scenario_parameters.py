"""Scenario parameters (sdl_fmu/sdl/parameters.py, docs/scenarios.md#parameters): declared by name (`// @param`,
`$NAME` in a field) or given by address (`LINE.N`, `rsa.LINE[.LANE]`), substituted into the text before each field is
read, so each value is held to its field's own limits; a set value changes a run exactly as a hand-edited file does,
and `resolve` writes that file."""

import json

import pytest

from sdl_fmu import api
from sdl_fmu.sdl import ScenarioError, parse_text
from sdl_fmu.sdl.parser import resolve_text, with_values

from helpers import sdl_fmu

# An oncoming car that swerves into our lane (its gap, lateral and action speed parameters), a brake (its pedal and
# threshold by name, its distance by address), a surface (by rsa address).
TEXT = """English
// @param gap = 1500 ft in 500..3000
// @param lateral = -6 ft
// @param pedal = 80 in 0..100
// @param until = 20 ft/s
100,A,50,$gap,$lateral,1,10,*0,20,2,5,-6,20,2
300,BRK,$pedal,2,$until
400,RSA,1,8,-1,8
1500,ES
"""


def hand_edited(**fields: str) -> str:
    """TEXT with these `$NAME` references replaced by hand, and their declarations made plain comments (each line
    stays a line: events keep their line numbers)."""
    text = TEXT
    for name, value in fields.items():
        text = text.replace(f"${name},", f"{value},").replace(f"${name}\n", f"{value}\n")
        text = text.replace(f"// @param {name} ", f"// {name} ")
    return text


def test_declarations_are_listed_with_their_values_ranges_units_and_uses():
    scenario = parse_text(TEXT, "p.sdl")
    by_name = {p.name: p for p in scenario.parameters}
    assert list(by_name) == ["gap", "lateral", "pedal", "until"]
    gap = by_name["gap"]
    assert (gap.value, gap.unit, gap.low, gap.high, gap.line) == (1500.0, "ft", 500.0, 3000.0, 2)
    assert gap.uses == ((6, "A parameter 2 (gap)"),) and not gap.whole
    assert by_name["pedal"].unit is None and by_name["pedal"].uses == ((7, "BRK parameter 1 (pedal %)"),)
    # the parsed event is the hand-edited file's, field for field
    assert scenario.events == parse_text(hand_edited(gap="1500", lateral="-6", pedal="80", until="20"), "p.sdl").events
    report = api.check(parse_text(TEXT, "p.sdl")).scenario
    from sdl_fmu.sdl import describe

    assert "$gap = 1500 ft in 500..3000 (line 2); used on line 6 (A parameter 2 (gap))" in describe(report)


def test_set_values_and_addresses_parse_as_the_hand_edited_file():
    scenario = parse_text(TEXT, "p.sdl")
    # by name, $name or bare; by address: 7.0 the BRK's distance, 6.5 the A's first action's closure time (10 -> 7),
    # 6.6 its lateral `*0` -> `*2` (the `*` kept), rsa.8.-1 one lane's value
    values = {"gap": 900, "$pedal": 60, "7.0": 350, "6.5": 7, "6.6": 2, "rsa.8.-1": 2}
    edited = ("English\n// @param gap = 1500 ft in 500..3000\n// @param lateral = -6 ft\n"
              "// @param pedal = 80 in 0..100\n// @param until = 20 ft/s\n100,A,50,900,-6,1,7,*2,20,2,5,-6,20,2\n"
              "350,BRK,60,2,20\n400,RSA,1,8,-1,2\n1500,ES\n")
    assert with_values(scenario, values).events == parse_text(edited, "p.sdl").events
    # values set on a Scenario stay when more are set; a later value for the same parameter wins
    twice = with_values(with_values(scenario, {"gap": 700}), {"pedal": 60, "gap": 900})
    assert twice.events == with_values(scenario, {"gap": 900, "pedal": 60}).events
    # a model range given a value by address becomes that model
    ranged = parse_text("100,A,50,1000,-6,*1~8\n", "m.sdl")
    model = with_values(ranged, {"1.4": 3}).events[0].model
    assert (model.low, model.high) == (3, 3)


@pytest.mark.parametrize("values, needle", [
    ({"gap": 0}, "p.sdl:2: @param gap: 0 (set) is outside its range 500..3000"),
    ({"pedal": 120}, "p.sdl:7: BRK parameter 1 (pedal %), from $pedal = 120: '120' must be a percentage from 0 to 100"),
    ({"until": -1}, "p.sdl:7: BRK parameter 3 (magnitude), from $until = -1: '-1' must be > 0"),
    ({"6.2": 0}, "p.sdl:6: A parameter 2 (gap), from address 6.2 = 0: '0': the vehicle cannot appear at gap 0"),
    ({"7.2": 1.5}, "p.sdl:7: BRK parameter 2 (threshold type), from address 7.2 = 1.5: '1.5' is not a whole number"),
    ({"6.4": 0}, "p.sdl:6: A parameter 4 (model), from address 6.4 = 0: model 0: model numbers start at 1"),
    ({"7.4": 1}, "p.sdl:7: address 7.4: the BRK event on line 7 has 3 parameters (7.0 is its distance)"),
    ({"3.1": 1}, "p.sdl:3: address 3.1: line 3 holds no event sdl-fmu reads"),
    ({"99.1": 1}, "p.sdl:99: address 99.1: line 99 holds no event sdl-fmu reads"),
    ({"rsa.7": 1}, "p.sdl:7: address rsa.7: line 7 is not an RSA event (it is BRK)"),
    ({"rsa.8.2": 1}, "p.sdl:8: address rsa.8.2: the RSA event on line 8 does not set lane 2"),
    ({"rsa.8": 2000}, "p.sdl:8: RSA parameter 2 (value), from address rsa.8 = 2000: '2000' is beyond the format's"),
    ({"9.0": 50}, "p.sdl:6: distance: A at 100 is at or beyond the ES on line 9"),
])
def test_every_value_is_checked_by_its_field_naming_file_line_and_parameter(values, needle):
    with pytest.raises(ScenarioError) as caught:
        with_values(parse_text(TEXT, "p.sdl"), values)
    assert any(line.startswith(needle) for line in str(caught.value).splitlines()), str(caught.value)


@pytest.mark.parametrize("text, needle", [
    ("// @param x = 3 m\n100,A,$x,1000,-6,1\n",
     "t.sdl:2: A parameter 1 (speed): $x is declared in m (line 1), but this field is in ft/s"),
    ("Metric\n// @param x = 3 ft\n100,A,20,$x,-6,1\n", "t.sdl:3: A parameter 2 (gap): $x is declared in ft (line 2), "
                                                    "but this field is in m"),
    ("// @param x = 3 s\n100,A,20,1000,-6,1\n100,BRK,100,1,$x\n",
     "t.sdl:3: BRK parameter 3 (magnitude): $x is declared in s (line 1), but this field is in ft"),
    ("// @param n = 3 ft\n100,A,20,1000,-6,$n\n", "t.sdl:2: A parameter 4 (model): $n is declared in ft (line 1), but "
                                                 "this field has no unit"),
    ("// @param x = 3 kg\n", "t.sdl:1: @param x: unit 'kg' is not a unit of this format's fields"),
    ("// @param x 3\n", "t.sdl:1: @param: 'x 3': expected '// @param NAME = VALUE [UNIT] [in LOW..HIGH]'"),
    ("// @param x = 5 in 6..9\n100,BRK,$x,0,1\n", "t.sdl:1: @param x: 5 is outside its range 6..9"),
    ("// @param x = 5 in 9..6\n", "t.sdl:1: @param x: range 9..6: low end above high end"),
    ("// @param x = 5\n// @param x = 6\n100,BRK,$x,0,1\n", "t.sdl:2: @param x: declared twice (first on line 1)"),
    ("100,BRK,$y,0,1\n", "t.sdl:1: BRK parameter 1 (pedal %): $y is not declared (declare it on a comment line"),
])
def test_declaration_and_unit_mistakes_are_one_line_each(text, needle):
    with pytest.raises(ScenarioError) as caught:
        parse_text(text, "t.sdl")
    assert len(str(caught.value).splitlines()) == 1 and str(caught.value).startswith(needle), str(caught.value)


def test_a_declared_unit_that_is_the_fields_own_passes_and_an_unused_declaration_warns():
    scenario = parse_text("Metric\n// @param v = 20 m/s\n// @param t = 2 s\n// @param idle = 1\n"
                          "100,A,$v,300,-3,1,${t}F,*0,$v,$t\n", "u.sdl")
    assert scenario.events[0].actions[0].trigger.where == "F"  # ${t}F: the name ends at the brace
    assert scenario.warnings == ("line 4: @param idle is declared but no field uses $idle",)


def test_names_that_are_no_parameter_are_input_errors_of_set():
    scenario = parse_text(TEXT, "p.sdl")
    for values, needle in (({"lead_speed": 1}, "set lead_speed: p.sdl declares no parameter 'lead_speed' (declared: "
                                                "gap, lateral, pedal, until)"),
                           ({"gap": float("nan")}, "set gap=nan: the value must be a finite number")):
        with pytest.raises(api.InputError) as caught:
            api.set_parameters(scenario, values)
        assert str(caught.value).startswith(needle) and caught.value.option == "set"


def test_resolve_writes_plain_sdl_line_for_line():
    text = resolve_text(parse_text(TEXT, "p.sdl"), {"gap": 900, "7.0": 350})
    lines = text.split("\n")
    assert len(lines) == len(TEXT.split("\n"))  # lines keep their numbers
    assert lines[5] == "100,A,50,900,-6,1,10,*0,20,2,5,-6,20,2" and lines[6] == "350,BRK,80,2,20"
    assert lines[1] == "// resolved parameter gap = 900 ft (was: @param gap = 1500 ft in 500..3000)"
    plain = parse_text(text, "r.sdl")
    assert plain.parameters == () and "$" not in text.replace("// resolved", "").split("(was")[0]
    assert plain.events == with_values(parse_text(TEXT, "p.sdl"), {"gap": 900, "7.0": 350}).events


def _comparable(summary: dict) -> dict:
    """summary.json without what names the file or measures the machine (the path, the wall time)."""
    return {key: value for key, value in summary.items() if key not in ("scenario", "timing")}


def test_set_and_address_change_the_run_as_the_hand_edited_file_and_resolve_runs_the_same(tmp_path, simple_fmu):
    (tmp_path / "p.sdl").write_text(TEXT)
    (tmp_path / "edited.sdl").write_text(hand_edited(gap="900", pedal="60").replace("100,A,50,", "150,A,50,"))
    options = {"fmu": simple_fmu, "plot": False}
    by_parameters = api.run(tmp_path / "p.sdl", set={"gap": 900, "pedal": 60, "6.0": 150}, **options)
    by_hand = api.run(tmp_path / "edited.sdl", **options)
    # the spawn is located within the master's time tolerance (1e-6 s, cosim/locate.py) at 88 ft/s: 8.8e-5 ft
    spawn = by_parameters.summary["events"][0]
    assert (spawn["line"], spawn["action"]) == (6, "spawn") and spawn["distance"] == pytest.approx(150, abs=8.8e-5)
    assert _comparable(by_parameters.summary) == _comparable(by_hand.summary)
    assert by_parameters.summary["collisions"] >= 0 and len(by_parameters.summary["events"]) > 3
    # the command line's resolve writes that file: it runs to the same summary.json
    completed = sdl_fmu("resolve", tmp_path / "p.sdl", "--set", "gap=900", "--set", "pedal=60", "--set", "6.0=150",
                        "--out", tmp_path / "resolved.sdl", cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    resolved = api.run(tmp_path / "resolved.sdl", **options)
    assert _comparable(resolved.summary) == _comparable(by_hand.summary)
    # and `run --set` of the command line, into a results folder
    completed = sdl_fmu("run", tmp_path / "p.sdl", "--fmu", simple_fmu, "--set", "gap=900", "--set", "pedal=60",
                        "--set", "6.0=150", "--out", tmp_path / "run", cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    written = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert _comparable(written) == _comparable(json.loads(json.dumps(by_hand.summary)))


def test_the_command_line_refuses_bad_settings_in_one_line_and_writes_nothing(tmp_path):
    (tmp_path / "p.sdl").write_text(TEXT)
    for arguments, code, needle in (
            (["--set", "lead_speed=1"], 2, "sdl-fmu: --set lead_speed: p.sdl declares no parameter 'lead_speed'"),
            (["--set", "gap=abc"], 2, "sdl-fmu: --set gap=abc: expected NAME=VALUE with a number"),
            (["--set", "gap=10"], 1, "p.sdl:2: @param gap: 10 (set) is outside its range 500..3000")):
        completed = sdl_fmu("resolve", "p.sdl", *arguments, "--out", "r.sdl", cwd=tmp_path)
        assert completed.returncode == code and completed.stderr.splitlines() == [completed.stderr.strip()]
        assert completed.stderr.startswith(needle), completed.stderr
    (tmp_path / "mine.sdl").write_text("my own file")
    completed = sdl_fmu("resolve", "p.sdl", "--out", "mine.sdl", cwd=tmp_path)
    assert completed.returncode == 2 and "exists; resolve writes a new file and never replaces one" in completed.stderr
    assert (tmp_path / "mine.sdl").read_text() == "my own file"
    assert sorted(path.name for path in tmp_path.iterdir()) == ["mine.sdl", "p.sdl"]
