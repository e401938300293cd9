"""Real-world SDL text: encodings, Ctrl-Z, line numbers, the STISIM text's examples verbatim, lanes the road lacks,
fractional attributes with advanced dynamics, codes sdl-fmu does not simulate."""

import pytest

from sdl_fmu import api
from sdl_fmu.cli import main
from sdl_fmu.sdl import ScenarioError, load_scenario

TEXT = "English\r\n// the driver’s lane, café\r\n100,BRK,50,0,1\r\n200,RSA,1,4\r\n300,ES\r\n"
EVENTS = [(3, "BRK"), (4, "RSA"), (5, "ES")]


def events_of(scenario):
    return [(event.line, event.code) for event in scenario.events]


def load_bytes(tmp_path, data, name="s.sdl", **options):
    path = tmp_path / name
    path.write_bytes(data)
    return load_scenario(path, **options)


@pytest.mark.parametrize("encoded", [
    TEXT.encode("utf-8"),
    TEXT.encode("utf-8-sig"),
    TEXT.encode("utf-16"),  # BOM + native order
    b"\xfe\xff" + TEXT.encode("utf-16-be"),
    b"\xff\xfe" + TEXT.encode("utf-16-le"),
    TEXT.replace("\r\n", "\n").encode("utf-8"),
    TEXT.encode("utf-8") + b"\x1a",  # DOS end-of-file marker
    TEXT.encode("utf-16") [:2] + (TEXT + "\x1a\r\n").encode("utf-16-le"),
], ids=["utf8", "utf8-bom", "utf16", "utf16-be-bom", "utf16-le-bom", "lf", "utf8-ctrl-z", "utf16-ctrl-z"])
def test_encodings_read_the_same_events_without_warnings(tmp_path, encoded):
    scenario = load_bytes(tmp_path, encoded)
    assert events_of(scenario) == EVENTS and scenario.warnings == ()


def test_windows_1252_is_read_with_one_warning_naming_the_first_line_that_is_not_utf8(tmp_path):
    data = ("English\r\n// plain\r\n100,BRK,50,0,1 // driver’s brake\r\n200,RSA,1,4 // “ice”\r\n300,ES\r\n"
            ).encode("cp1252")
    scenario = load_bytes(tmp_path, data)
    assert events_of(scenario) == EVENTS
    assert scenario.warnings == ("line 3: file: is not UTF-8 (first such line); the file was read as Windows-1252",)


@pytest.mark.parametrize("data, line, reason", [
    (b"10,ES\n// \x81\n", 2, "neither UTF-8 nor Windows-1252"),  # 0x81 is undefined in cp1252
    (b"English\n10,ES\n\x00\x01binary", 3, "NUL byte"),
    ("English\n10,BRK,50,0,1\x1a\n20,ES\n".encode(), 2, "Ctrl-Z (end-of-file marker) before the end"),
    (b"\xff\xfe" + "English\n10,ES\n".encode("utf-16-le") + b"\x00\xd8" + "\n".encode("utf-16-le"), 3,
     "not valid UTF-16"),  # a lone surrogate on line 3
    (TEXT.encode("utf-16-le"), 1, "NUL byte"),  # UTF-16 without a BOM cannot be told from binary
])
def test_undecodable_text_is_one_error_on_its_line(tmp_path, data, line, reason):
    with pytest.raises(ScenarioError) as caught:
        load_bytes(tmp_path, data)
    (error,) = caught.value.errors
    assert (error.line, error.field) == (line, "file") and reason in error.reason
    assert str(error).startswith(f"{tmp_path / 's.sdl'}:{line}: file: ")


def test_every_error_position_is_a_line_number(tmp_path):
    lines = ["Metric", "// comment", "10,BRK,50,9,1", "", "20,XYZ", "30,RSA,1", "5,ES,1"]
    for encoding in ("utf-8", "utf-16", "cp1252"):
        text = "\r\n".join(lines) + "\r\n// caf\u00e9\r\n"
        with pytest.raises(ScenarioError) as caught:
            load_bytes(tmp_path, text.encode(encoding))
        assert [e.line for e in caught.value.errors] == [3, 5, 6, 7]


# The STISIM text's own RSA and BRK examples, verbatim (scenarios/road_surface_simple.sdl, brake_examples.sdl).
SEED_RSA_SIMPLE = "1000,RSA,1,10,-5,2\n1100,RSA,1,8,-5,8\n"
SEED_RSA_ADVANCED = "1000,RSA,1,1,-5,2,101,3\n1100,RSA,1,0,-5,1\n"
SEED_BRK = "1000,BRK,100,0,3\n2000,BRK,25,1,200\n3000,BRK,50,2,30\n4000,BRK,100,3,30\n"


def test_seed_rsa_example_runs_and_a_lane_the_road_lacks_is_a_warning(tmp_path, simple_fmu):
    path = tmp_path / "rsa.sdl"
    path.write_text(SEED_RSA_SIMPLE)
    result = api.run(path, fmu=simple_fmu, until_distance=1200)
    lane_warnings = [w for w in result.warnings if "lane -5 is not on the road" in w]
    assert [w.split(":")[0] for w in lane_warnings] == ["line 1", "line 2"]
    assert all("never applies" in w for w in lane_warnings)
    # lane 1 is applied (mu 1.0 under every wheel after 1000 ft), lane -5 is logged and never applies
    sets = [(e["lane"], e["value"]) for e in result.events if e["code"] == "RSA"]
    assert sets == [(1, 10), (-5, 2), (1, 8), (-5, 8)]
    mu = result.arrays["mu_fl_1"]
    assert set(mu.tolist()) == {0.8, 1.0}


def test_seed_advanced_rsa_and_brk_examples_are_accepted(tmp_path):
    for text, warned in ((SEED_RSA_ADVANCED, 2), (SEED_BRK, 0)):
        path = tmp_path / "seed.sdl"
        path.write_text(text)
        assert len(api.load(path).warnings) == warned


def test_fractional_attribute_with_advanced_dynamics_is_an_error_naming_the_line(tmp_path, capsys):
    path = tmp_path / "frac.sdl"
    path.write_text("// surfaces\n1000,RSA,1,1\n1100,RSA,1,2.7,-1,3.0\n")
    assert main(["run", str(path), "--dynamics", "advanced", "--out", str(tmp_path / "out")]) == 1
    assert capsys.readouterr().err.splitlines() == [
        f"{path}:3: RSA parameter 2 (value): 2.7: for this vehicle the value is a surface attribute number "
        "and must be whole"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frac.sdl"]


REAL_WORLD = "English\n100,SIGN,3,1\n150,BRK,50,0,1\n200,SOUND,2\n300,SIGN,4\n400,BUILDING,7,2\n500,ES\n"


def test_unsupported_codes_are_errors_each_with_its_line(tmp_path, capsys):
    path = tmp_path / "world.sdl"
    path.write_text(REAL_WORLD)
    assert main(["check", str(path)]) == 1
    lines = capsys.readouterr().err.splitlines()
    assert [(line.split(":")[1], line.split("'")[1]) for line in lines] == [
        ("2", "SIGN"), ("4", "SOUND"), ("5", "SIGN"), ("6", "BUILDING")]
    assert all("--skip-unsupported" in line for line in lines)


def test_skip_unsupported_runs_with_one_warning_per_code(tmp_path, simple_fmu, capsys):
    path = tmp_path / "world.sdl"
    path.write_text(REAL_WORLD)
    expected = ["line 2: event code 'SIGN' is not simulated: skipped (lines 2, 5)",
                "line 4: event code 'SOUND' is not simulated: skipped (line 4)",
                "line 6: event code 'BUILDING' is not simulated: skipped (line 6)"]
    assert main(["check", str(path), "--skip-unsupported"]) == 0
    assert capsys.readouterr().err.splitlines() == [f"warning: {w}" for w in expected]
    result = api.run(path, skip_unsupported=True, fmu=simple_fmu, out=tmp_path / "out", plot=False)
    assert [e["code"] for e in result.events] == ["BRK", "BRK", "ES"] and result.warnings == expected
    assert result.summary["warnings"] == expected
