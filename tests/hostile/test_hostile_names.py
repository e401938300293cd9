"""Names from files made safe where `sdl-fmu export` turns them into file names, shell words and URIs
(sdl_fmu/text.py, safe_identifier; docs/export.md, Names): the scenario's file name names the SSP and the scenario
FMU, the ego's and the controller's FMU file names their files in the SSP, each as a safe identifier; the original
stays the scenario FMU's model name and is in the documentation.

The findings of round 3 reproduced: ecos passes an FMU's file name to `sh` unquoted (`chmod +x /tmp/ecos_<name>_...`),
so a scenario named `x;touch PWNED_BY_ECOS;y.sdl` ran `touch` there; an SSD `source` is a URI that libcosim decodes
and ecos reads as it is, so `a%20b.sdl` was refused by libcosim and ran with a dead scenario FMU in ecos (its
resource location decoded to a folder that does not exist); a legal 251-character file name ended in a traceback.
The masters are the real ones, run through the recipes of docs/export.md (tests/ssp_masters.py)."""

import re
import shlex
import shutil
import zipfile
from pathlib import Path
from urllib.parse import quote

import numpy as np
import pytest
from fmpy import read_model_description
from lxml import etree

from sdl_fmu import api
from sdl_fmu.cli import main
from sdl_fmu.names import shipped_controller_map_path, shipped_map_path
from sdl_fmu.ssp.document import SSD
from sdl_fmu.text import SAFE_LENGTH, UnsafeName, printable, safe_identifier

from ssp_masters import MASTERS, run_master

SCENARIO = "English\n100,ES\n"  # 100 ft at the default 88 ft/s: the run ends at 1.14 s
NO_LEAD_GAP = 1000.0  # m: lead_gap's sentinel without a lead vehicle (docs/scenario-fmu.md, Variables)
SIGNALS = {"scenario.events": "Integer", "scenario.ended": "Boolean", "scenario.lead_gap": "Real",
           "scenario.throttle": "Real", "ego.v": "Real"}


# ---- the mapping -----------------------------------------------------------------------------------------------------

MAPPED = {  # name -> its safe identifier, by the rules of docs/export.md (Names)
    "demo": "demo", "road_surface_simple": "road_surface_simple", "my-scenario.v2": "my-scenario.v2",  # as they are
    "x;touch PWNED_BY_ECOS;y": "x_touch_PWNED_BY_ECOS_y",  # each run of other characters: one _
    "a%20b": "a_20b", "a#b?c": "a_b_c", "a b  c": "a_b_c", "$(rm -rf ~)`id`'\"": "_rm_-rf_id_",
    "überholen": "uberholen", "Ａ１ ﬁle": "A1_file",  # accents dropped, compatibility forms decomposed
    "测试1": "_1", "esc\x1b[2Jx": "esc_2Jx", "bad\udcff": "bad_",  # not ASCII, controls, bytes that are not UTF-8
    "-rf": "_rf", ".hidden": "_hidden", "..a": "_a",  # no leading - (an option) or . (hidden, ..)
    "con": "con_", "NUL.v2": "NUL_.v2", "com1": "com1_", "Console": "Console",  # Windows' device names
    "n" * SAFE_LENGTH: "n" * SAFE_LENGTH,
}


@pytest.mark.parametrize("name", MAPPED)
def test_a_name_becomes_a_safe_identifier_by_the_documented_rules(name):
    identifier = safe_identifier(name)
    assert identifier == MAPPED[name]
    assert safe_identifier(identifier) == identifier  # a safe name is its own identifier
    assert re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9._-]*", identifier) and len(identifier) <= SAFE_LENGTH
    assert quote(identifier) == identifier and shlex.quote(identifier) == identifier  # a URI and a shell take it as is


@pytest.mark.parametrize("name, reason", [("测试", "no letter or digit"), ("...", "no letter or digit"),
                                          ("_", "no letter or digit"), ("n" * (SAFE_LENGTH + 1), "129 characters")])
def test_a_name_that_cannot_be_made_safe_says_why(name, reason):
    with pytest.raises(UnsafeName, match=reason):
        safe_identifier(name)


# ---- names an export cannot take: one line, nothing written ----------------------------------------------------------

@pytest.mark.parametrize("file_name, needle", [
    ("n" * 247 + ".sdl", "247 characters long made safe, more than 128"),  # legal: 251 characters (the finding)
    ("测试.sdl", "no letter or digit"),
])
def test_a_scenario_name_that_cannot_name_a_file_is_one_line_and_writes_nothing(tmp_path, file_name, needle, capsys,
                                                                                monkeypatch):
    (tmp_path / file_name).write_text(SCENARIO, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    before = sorted(tmp_path.iterdir())
    assert main(["export", str(tmp_path / file_name), "--out", str(tmp_path / "out")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.splitlines()) == 1 and needle in err and file_name in err, err
    assert "rename the file" in err and "Traceback" not in err
    assert sorted(tmp_path.iterdir()) == before


def test_an_ego_or_controller_fmu_name_that_cannot_name_a_file_is_one_line(tmp_path, simple_fmu, example_aeb_fmus,
                                                                           capsys):
    (tmp_path / "s.sdl").write_text(SCENARIO)
    shutil.copyfile(simple_fmu, tmp_path / "测试.fmu")
    shutil.copyfile(example_aeb_fmus[2], tmp_path / "…….fmu")
    vehicle = str(shipped_map_path("simple"))
    for extra, flag in ((["--fmu", str(tmp_path / "测试.fmu"), "--vehicle", vehicle], "--fmu"),
                        (["--controller", str(tmp_path / "…….fmu"), "--controller-map",
                          str(shipped_controller_map_path("example-aeb"))], "--controller")):
        assert main(["export", str(tmp_path / "s.sdl"), "--out", str(tmp_path / "out"), *extra]) == 2
        out, err = capsys.readouterr()
        assert out == "" and len(err.splitlines()) == 1 and err.startswith(f"sdl-fmu: {flag} "), err
        assert "no letter or digit" in err and "Traceback" not in err
        assert not (tmp_path / "out").exists()


# ---- names an export takes: made safe, the original kept ---------------------------------------------------------

def test_controls_and_bytes_that_are_not_utf8_in_a_name_are_kept_escaped_as_the_model_name(tmp_path, simple_fmu):
    """A terminal escape and a byte that is not UTF-8 in the scenario's file name (an XML document can hold neither:
    the export used to end in a traceback): the files are named by the safe identifier, the model name, the SSD's
    description and the documentation keep the name with its escapes written out."""
    name = "scene\x1b[2J" + b"\xff".decode("utf-8", "surrogateescape")  # the byte 0xff, as Python names it
    (tmp_path / f"{name}.sdl").write_text(SCENARIO)
    export = api.export(tmp_path / f"{name}.sdl", out=tmp_path / "out")
    assert export.ssp.name == "scene_2J_.ssp" and export.fmus["scenario"].name == "scene_2J_.fmu"
    shown = printable(name, keep_lines=False)
    assert shown == "scene\\x1b[2J\\udcff"
    assert read_model_description(str(export.fmus["scenario"])).modelName == shown
    with zipfile.ZipFile(export.fmus["scenario"]) as fmu:
        assert f"the SDL scenario {shown}.sdl" in fmu.read("documentation/index.html").decode()
    with zipfile.ZipFile(export.ssp) as ssp:
        root = etree.fromstring(ssp.read("SystemStructure.ssd"))
    assert root.get("name") == "scene_2J_" and f"the SDL scenario {shown}.sdl" in root.get("description")


def sources(ssp: Path) -> dict[str, str]:
    with zipfile.ZipFile(ssp) as archive:
        root = etree.fromstring(archive.read("SystemStructure.ssd"))
    return {c.get("name"): c.get("source") for c in root.iter(f"{{{SSD}}}Component")}


def test_shell_syntax_in_the_scenario_ego_and_controller_names_reaches_no_shell_in_ecos(tmp_path, simple_fmu,
                                                                                      example_aeb_fmus):
    """The finding's scenario name, and the ego's and the controller's FMUs under names of the same kind (a command
    substitution too, for a shell that quotes with double quotes): ecos runs the export and nothing is touched."""
    scenario = tmp_path / "x;touch PWNED_BY_ECOS;y.sdl"
    scenario.write_text(SCENARIO)
    ego, aeb = tmp_path / "car;touch PWNED_EGO.fmu", tmp_path / "aeb$(touch PWNED_AEB).fmu"
    shutil.copyfile(simple_fmu, ego)
    shutil.copyfile(example_aeb_fmus[2], aeb)
    export = api.export(scenario, fmu=ego, vehicle=shipped_map_path("simple"), controller=aeb,
                        controller_map=shipped_controller_map_path("example-aeb"), out=tmp_path / "out")
    work = tmp_path / "work"
    work.mkdir()
    result = run_master("ecos", export.ssp, export.stop_time, export.step, SIGNALS, cwd=work)
    assert list(work.iterdir()) == [] and not list(tmp_path.rglob("PWNED*"))
    assert result["scenario.events"][-1] == len(export.reference.events) and result["scenario.ended"][-1]
    names = {"scenario": "x_touch_PWNED_BY_ECOS_y.fmu", "ego": "car_touch_PWNED_EGO.fmu",
             "controller": "aeb_touch_PWNED_AEB_.fmu"}
    assert export.ssp.name == "x_touch_PWNED_BY_ECOS_y.ssp"
    assert {component: path.name for component, path in export.fmus.items()} == names
    assert sorted(p.name for p in export.folder.iterdir() if p.suffix == ".fmu") == sorted(names.values())
    assert sources(export.ssp) == {component: f"resources/{name}" for component, name in names.items()}


@pytest.fixture(scope="module")
def escaped(tmp_path_factory):
    """The export of a scenario whose name a URI must escape (%, #, ?)."""
    folder = tmp_path_factory.mktemp("uri")
    (folder / "a%20b#c?d.sdl").write_text(SCENARIO)
    return api.export(folder / "a%20b#c?d.sdl", out=folder / "out")


@pytest.mark.parametrize("master", MASTERS)
def test_a_name_a_uri_must_escape_runs_with_a_live_scenario_fmu_in_each_master(escaped, master):
    """libcosim refused the SSP (it decodes `%20` to a space and found no such file), ecos ran it with a dead scenario
    FMU (all its outputs 0): now the scenario FMU fires the run's events, ends and reports no lead vehicle in each."""
    result = run_master(master, escaped.ssp, escaped.stop_time, escaped.step, SIGNALS)
    assert len(escaped.reference.events) == 1  # the ES
    assert result["scenario.events"][-1] == 1 and result["scenario.ended"][-1]
    assert np.all(result["scenario.lead_gap"] == NO_LEAD_GAP)
    assert np.any(result["scenario.throttle"] > 0)  # the driver holds the speed against the drag
    assert escaped.ssp.name == "a_20b_c_d.ssp"
    assert sources(escaped.ssp)["scenario"] == "resources/a_20b_c_d.fmu"
