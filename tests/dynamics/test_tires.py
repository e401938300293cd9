"""Tire property files (.tir), Tire Attribute Files and the FMU's tire slots: parsing, errors, fallbacks."""

import json
import re

import pytest

from sdl_fmu.dynamics.tires import SLOT_COUNT, slot_of, slot_parameters
from sdl_fmu.tire_files import (DEFAULT_ATTRIBUTE_FILE, SLOT_KEYS, TireFileError, mf_coefficients, parse_attribute_file,
                                parse_tir, read_tir)
from sdl_fmu.paths import MODEL_DESCRIPTION_DIRECTORY

DRY = DEFAULT_ATTRIBUTE_FILE.parent / "dry_asphalt.tir"


def write_tire(folder, name="t.tir", lmux=1.0):
    text = re.sub(r"^LMUX +=.*$", f"LMUX = {lmux}", DRY.read_text(), flags=re.M)
    (folder / name).write_text(text)
    return folder / name


def test_shipped_tires_fill_the_slots_by_attribute():
    starts, slots, warnings = slot_parameters()
    assert warnings == []
    assert slots == {0: 0, 1: 1, 2: 2, 3: 3, 4: 4}
    assert len(starts) == SLOT_COUNT * len(SLOT_KEYS)
    assert starts["tire0_PDX1"] == 1.21 and starts["tire0_LMUX"] == 0.7025
    assert starts["tire3_LMUX"] == 0.0826  # ice
    assert all(starts[f"tire7_{key}"] == starts[f"tire0_{key}"] for key in SLOT_KEYS)  # no attribute 7: standard
    assert [slot_of(a) for a in (0, 5, 7, 8, 99, -1)] == [0, 5, 7, 0, 0, 0]


def test_interface_data_lists_the_slot_coefficients():
    data = json.loads((MODEL_DESCRIPTION_DIRECTORY / "EgoVehicleAdvanced.json").read_text())
    (group,) = [entry for entry in data["variables"] if "repeat" in entry]
    assert group["repeat"]["count"] == SLOT_COUNT
    assert tuple(v["name"].split("_", 1)[1] for v in group["variables"]) == SLOT_KEYS


def test_tir_subset_syntax():
    tire = parse_tir("""$ header comment
[UNITS]
LENGTH = 'meter'   ! trailing comment
[SHAPE]
{radial width}
 1.0 0.0
[VERTICAL]
FNOMIN = 4.0D+03 $ Fortran exponent
[MODEL]
TYRESIDE = LEFT
""", "x.tir")
    assert tire.number("VERTICAL", "FNOMIN") == 4000.0
    assert tire.sections["MODEL"]["TYRESIDE"].value == "LEFT"
    assert tire.number("VERTICAL", "MISSING", 2.5) == 2.5


@pytest.mark.parametrize("text, line, key, reason", [
    ("[VERTICAL]\nFNOMIN 4000\n", 2, "FNOMIN 4000", "expected KEY = value"),
    ("FNOMIN = 1\n", 1, "FNOMIN", "before the first [SECTION]"),
    ("[VERTICAL]\nFNOMIN = 1\nFNOMIN = 2\n", 3, "FNOMIN", "given twice"),
    ("[VERTICAL]\nFNOMIN = 'abc\n", 2, "FNOMIN", "unterminated"),
    ("[VERTICAL]\nFNOMIN = 4 000\n", 2, "FNOMIN", "neither a number"),
    ("[UNITS]\nLENGTH = 'mm'\n", 2, "LENGTH", "not supported"),
])
def test_tir_syntax_errors_name_file_line_and_key(text, line, key, reason):
    with pytest.raises(TireFileError) as caught:
        parse_tir(text, "bad.tir")
    assert (caught.value.path, caught.value.line, caught.value.key) == ("bad.tir", line, key)
    assert reason in caught.value.reason and str(caught.value).startswith(f"bad.tir:{line}: {key}: ")


def test_tir_coefficient_errors(tmp_path):
    text = DRY.read_text()
    with pytest.raises(TireFileError, match=r"t\.tir: PKY1: missing; the tire model needs it in \[LATERAL"):
        mf_coefficients(parse_tir(text.replace("PKY1 ", "XKY1 "), tmp_path / "t.tir"))
    with pytest.raises(TireFileError, match=r"PDX1: found in \[LATERAL_COEFFICIENTS\], expected in \[LONG"):
        mf_coefficients(parse_tir(text.replace("PDX1 ", "XDX1 ").replace("PCY1 ", "PDX1 "), "t.tir"))
    with pytest.raises(TireFileError, match=r"t\.tir:\d+: FNOMIN: -1.0 must be > 0"):
        mf_coefficients(parse_tir(text.replace("4000.0", "-1.0"), "t.tir"))
    with pytest.raises(TireFileError, match=r"t\.tir:\d+: PDX1: 'x' is not a number"):
        mf_coefficients(parse_tir(text.replace("1.210 ", "'x' "), "t.tir"))
    with pytest.raises(TireFileError, match="nope.tir: file: cannot be read"):
        read_tir(tmp_path / "nope.tir")


def test_attribute_file_syntax_and_errors(tmp_path):
    entries = parse_attribute_file("// comment\n# comment\n\n0 = a.tir // standard\n 12 = 'sub dir/b.tir'\n",
                                   tmp_path / "attr.txt")
    assert [(e.attribute, e.tire_file, e.line) for e in entries] == [
        (0, tmp_path / "a.tir", 4), (12, tmp_path / "sub dir" / "b.tir", 5)]
    for text, line, field in (("0 a.tir", 1, "line"), ("x = a.tir", 1, "attribute number"),
                              ("-1 = a.tir", 1, "attribute number"), ("1 = a\n1 = b", 2, "attribute number"),
                              ("1 = ", 1, "tire file")):
        with pytest.raises(TireFileError) as caught:
            parse_attribute_file(text, "attr.txt")
        assert (caught.value.line, caught.value.key) == (line, field), text


def test_slot_parameters_fallbacks_and_warnings(tmp_path):
    write_tire(tmp_path, "slick.tir", lmux=0.5)
    (tmp_path / "attr.txt").write_text("2 = slick.tir\n9 = slick.tir\n")
    starts, slots, warnings = slot_parameters(tmp_path / "attr.txt")
    assert slots == {0: 0, 2: 2}
    assert starts["tire2_LMUX"] == 0.5 and starts["tire0_LMUX"] == 0.7025 and starts["tire5_LMUX"] == 0.7025
    assert len(warnings) == 2
    assert "attr.txt:2: attribute 9 is beyond the FMU's 8 tire slots" in warnings[0]
    assert "no attribute 0" in warnings[1]


def test_slot_parameters_errors_name_the_tire_file_and_the_attribute_line(tmp_path):
    (tmp_path / "bad.tir").write_text(re.sub(r"^PCX1 +=.*$", "PCX1 = 0", DRY.read_text(), flags=re.M))  # PCX1 must be > 0
    (tmp_path / "attr.txt").write_text("0 = bad.tir\n")
    with pytest.raises(TireFileError) as caught:
        slot_parameters(tmp_path / "attr.txt")
    assert caught.value.path == str(tmp_path / "bad.tir") and caught.value.key == "PCX1"
    assert f"(tire of attribute 0, {tmp_path / 'attr.txt'}:1)" in caught.value.reason
    (tmp_path / "attr.txt").write_text("0 = missing.tir\n")
    with pytest.raises(TireFileError, match=r"attr\.txt:1: tire file: .*missing\.tir does not exist"):
        slot_parameters(tmp_path / "attr.txt")
