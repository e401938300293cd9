"""Names from files and FMUs are shown as written and harm nothing (sdl_fmu/text.py): matplotlib never parses them as
mathtext (a `$` in a scenario file name, an FMU's modelName, a map's name, a --vary name used to fail the plot after
the whole simulation), and terminal control characters in them are escaped wherever the command line prints them.

The real command line under a 1.5 GB address-space cap (tests/hostile_fmus.py)."""

import json
import os

import pytest

from hostile_fmus import capped, hostile_fmu, hostile_map, library

pytestmark = pytest.mark.slow  # whole runs, sweeps and verifications of the command line, each capped

MATH = r"$\frac{1}{$ and $x^^$"  # unbalanced and malformed mathtext: matplotlib's parser fails on both
ESCAPES = "\x1b[2J\x1b[31m\x07\u202e"  # clear the screen, red, bell, right-to-left override
ESCAPED = r"\x1b[2J\x1b[31m\x07\u202e"
XML_ESCAPES, XML_ESCAPED = "\x9b2J\x85\u202e", r"\x9b2J\x85\u202e"  # CSI and NEL (C1), right-to-left override


@pytest.fixture(scope="module")
def car(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hostile")
    library(folder)
    return folder


def test_dollars_in_the_scenario_fmu_and_map_names_are_drawn_as_written(car, tmp_path):
    scenario = tmp_path / "budget_$5_vs_$10.sdl"
    scenario.write_text("English\n300,BRK,100,1,50\n600,ES\n")
    fmu = hostile_fmu(tmp_path / "fmu", model_name=f"Car {MATH}")
    for named in (False, True):  # the FMU's modelName, then the map's name
        vehicle = hostile_map(tmp_path, extra=f"name = '{MATH}'" if named else "", name=f"map{named}")
        out = tmp_path / f"out{named}"
        completed = capped("run", scenario, "--fmu", fmu, "--vehicle", vehicle, "--out", out)
        assert completed.returncode == 0, completed.stderr
        assert (out / "plot.png").read_bytes().startswith(b"\x89PNG")
        summary = json.loads((out / "summary.json").read_text())
        assert summary["dynamics"] == (MATH if named else f"Car {MATH}")
    verify = capped("verify", "--fmu", fmu, "--vehicle", vehicle, "--only", "braking,step_steer", "--out",
                    tmp_path / "verify")
    assert verify.returncode == 0, verify.stderr
    assert verify.stdout.startswith(f"{MATH} (HostileCar.fmu, GUID ")
    assert (tmp_path / "verify" / "report.html").stat().st_size > 0


def test_a_dollar_in_a_vary_name_is_drawn_as_written(car, tmp_path):
    """An FMU parameter whose name is malformed mathtext, varied: the sweep's table and plot are written."""
    name = r"gain_$\frac{$"
    fmu = hostile_fmu(tmp_path / "fmu", names={"trigger_time": name})
    vehicle = hostile_map(tmp_path, parameters="mode = 0.0")
    scenario = tmp_path / "s.sdl"
    scenario.write_text("English\n300,ES\n")
    completed = capped("sweep", scenario, "--fmu", fmu, "--vehicle", vehicle, "--vary", f"{name}=1,2", "--workers",
                       "1", "--out", tmp_path / "sweep")
    assert completed.returncode == 0, completed.stderr
    assert (tmp_path / "sweep" / "sweep.png").read_bytes().startswith(b"\x89PNG")
    assert (tmp_path / "sweep" / "sweep.csv").read_text().splitlines()[0].startswith(f"\"run\",\"{name}\"")


def test_terminal_control_characters_in_names_are_escaped_where_they_are_printed(car, tmp_path):
    """A map name (verify prints it), a scenario file name (run prints it), an FMU variable name in an error, and the
    FMU's log lines: each shown with its escapes written out, no raw control character on the terminal."""
    fmu = hostile_fmu(tmp_path / "fmu", model_name=f"evil{XML_ESCAPES}")  # XML allows no C0 control but tab, LF, CR
    vehicle = hostile_map(tmp_path, extra=f'name = "map\\u001b[2J\\u001b[31m\\u0007\\u202e"')
    verify = capped("verify", "--fmu", fmu, "--vehicle", vehicle, "--only", "braking", "--out", tmp_path / "v")
    assert verify.returncode == 0, verify.stderr
    assert verify.stdout.startswith(f"map{ESCAPED} (HostileCar.fmu, GUID ")
    scenario = tmp_path / f"scene{ESCAPES}.sdl"
    scenario.write_text("English\n300,ES\n")
    run = capped("run", scenario, "--fmu", fmu, "--vehicle", hostile_map(tmp_path, name="plain"), "--out",
                 tmp_path / "r")
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith(f"scene{ESCAPED}.sdl: evil{XML_ESCAPED} dynamics")
    broken = hostile_fmu(tmp_path / "broken", names={"speed": f"speed{XML_ESCAPES}"})  # the map's speed: missing
    error = capped("run", scenario, "--fmu", broken, "--vehicle", hostile_map(tmp_path, name="plain"), "--out",
                   tmp_path / "e")
    assert error.returncode == 2 and f"scene{ESCAPED}" not in error.stderr
    garbage = capped("run", scenario, "--fmu", fmu, "--vehicle", hostile_map(tmp_path, "garbage_log", name="g"),
                     "--out", tmp_path / "g")
    assert garbage.returncode == 0, garbage.stderr
    for completed in (verify, run, error, garbage):
        for stream in (completed.stdout, completed.stderr):
            assert not set(stream) & {"\x1b", "\x07", "\u202e", "\x9b", "\x85"}, stream[-2000:]
    assert os.listdir(tmp_path / "r")
