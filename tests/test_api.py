"""The Python API: the README's example runs as written; results as NumPy arrays and a pandas DataFrame; events,
warnings; the progress bar; user mistakes as InputError / ScenarioError."""

import csv
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from sdl_fmu import api

README = Path(__file__).resolve().parents[1] / "README.md"


def readme_example() -> str:
    section = README.read_text().split("## Python API", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S)[1]


def test_the_readme_example_runs_as_written(tmp_path, monkeypatch, capsys, simple_fmu):
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(readme_example(), "README.md", "exec"), namespace)
    result = namespace["result"]
    frame = result.dataframe()  # pandas: in the test extra
    printed = capsys.readouterr().out
    assert re.match(r"\d+ samples, top speed [\d.]+ ft/s, 0 collision\(s\)", printed)
    assert result.final["time_s"] == pytest.approx(20.0)
    # the written files and the arrays are the same run
    with open(tmp_path / "runs" / "demo-heavy" / "timeseries.csv") as file:
        rows = list(csv.reader(file))
    assert rows[0] == list(result.arrays) == list(frame.columns)
    assert len(rows) - 1 == len(result.time) == len(frame)
    column = rows[0].index("speed_ft/s")
    # 4 decimals in the file (LENGTH_FORMAT %.4f): half a unit of the last digit
    assert np.allclose([float(row[column]) for row in rows[1:]], result.arrays["speed_ft/s"], rtol=0, atol=5e-5)
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == [
        ".sdl-fmu-results.json", "plot.png", "summary.json", "timeseries.csv"]


@pytest.mark.slow
def test_the_readme_example_runs_after_quick_start_1(tmp_path, simple_fmu):
    # Quick start 1, exactly: a fresh venv in a checkout (a copy: `pip install .` writes build files beside the
    # sources) and `pip install .` with the package's own dependencies from the index; then the example, from an
    # empty folder, with that venv's Python. The FMU comes from the tests' cache (the same sources, the same key).
    checkout = tmp_path / "checkout"
    shutil.copytree(README.parent, checkout, ignore=shutil.ignore_patterns(
        ".venv", ".git", "build", "dist", "runs", "sweeps", "*.egg-info", "__pycache__", ".pytest_cache"))
    env = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH", "VIRTUAL_ENV")}
    installed = subprocess.run(["bash", "-c", "python3 -m venv .venv && . .venv/bin/activate && pip install ."],
                               cwd=checkout, env=env, capture_output=True, text=True)
    assert installed.returncode == 0, installed.stdout[-2000:] + installed.stderr[-2000:]
    python = checkout / ".venv" / "bin" / "python"
    # the example must not need pandas, which Quick start 1 does not install
    assert subprocess.run([python, "-c", "import pandas"], env=env, capture_output=True).returncode != 0
    work = tmp_path / "work"
    work.mkdir()
    (tmp_path / "example.py").write_text(readme_example())
    completed = subprocess.run([python, tmp_path / "example.py"], cwd=work, env=env, capture_output=True, text=True)
    assert completed.returncode == 0, completed.stderr
    assert re.match(r"\d+ samples, top speed [\d.]+ ft/s, 0 collision\(s\)", completed.stdout)
    assert sorted(p.name for p in (work / "runs" / "demo-heavy").iterdir()) == [
        ".sdl-fmu-results.json", "plot.png", "summary.json", "timeseries.csv"]


def test_result_holds_events_warnings_and_the_summary(simple_fmu):
    scenario = api.load("brake_examples")
    result = api.run(scenario, fmu=simple_fmu, until_distance=1500, params={"drag_area": 0.0})
    assert isinstance(result.arrays["time_s"], np.ndarray) and result.arrays["time_s"].dtype == float
    assert [(e["code"], e["action"]) for e in result.events][:2] == [("BRK", "on"), ("BRK", "off")]
    assert result.summary["events"][0]["code"] == "BRK" and result.summary["units"] == scenario.units
    assert result.final["distance"] == pytest.approx(1500, abs=1e-3)
    assert result.warnings == []


def test_progress_bar_on_stderr_only_when_asked_or_a_terminal(capsys, simple_fmu):
    api.run("head_on", fmu=simple_fmu, until_time=1.0, progress=True)
    assert "%|" in capsys.readouterr().err  # tqdm's bar
    api.run("head_on", fmu=simple_fmu, until_time=1.0, progress=None)  # stderr is not a terminal here
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("options, option, message", [
    ({"until_time": float("nan")}, "until_time", "until_time nan: must be a finite number"),
    ({"speed": -1.0}, "speed", "speed -1: must be >= 0"),
    ({"step": 0}, "step", "step 0: must be >= 1e-05"),
    ({"seed": -1}, "seed", "seed -1: must be from 0"),
    ({"dynamics": "turbo"}, "dynamics", "dynamics turbo: must be one of simple, advanced"),
    ({"params": {"mass": 0.0}}, "params", "params mass=0.0: below the declared minimum 1 kg of mass"),
    ({"params": {"wheelbase": 0.0}}, "params", "params wheelbase=0.0: below the declared minimum 0.1 m"),
    ({"params": {"brake_decel_max": -9.81}}, "params", "below the declared minimum 0 m/s2 of brake_decel_max"),
    ({"tires": "attributes.txt"}, "tires", "tires attributes.txt: applies to the advanced dynamics only"),
    ({"fmu": "nowhere.fmu"}, "fmu", "fmu nowhere.fmu: no such file"),
])
def test_user_mistakes_raise_input_error_naming_the_keyword(options, option, message, simple_fmu):
    # the API names its keywords (params, until_time), never the command line's flags (--param, --until-time)
    options.setdefault("fmu", simple_fmu)
    with pytest.raises(api.InputError) as caught:
        api.run("head_on", **options)
    assert caught.value.option == option and message in str(caught.value) and "--" not in str(caught.value)


def test_a_target_speed_above_the_vehicles_top_speed_is_one_warning(simple_fmu):
    # the Simple FMU's top speed is 201.389 ft/s (61.3834 m/s: tests/vehicle/test_vehicle_model.py derives it in closed
    # form)
    warning = ("speed 202 ft/s: above the top speed of simple, 201.4 ft/s (where its drive at full throttle, at most "
               "110 kW, meets its rolling resistance and drag): the driver holds full throttle below the target")
    assert api.run("head_on", fmu=simple_fmu, speed=202.0, until_time=0.5).warnings == [warning]
    assert api.run("head_on", fmu=simple_fmu, speed=201.3, until_time=0.5).warnings == []
    # a 5 kW car (the same cubic: 16.8028 m/s = 55.13 ft/s) cannot reach the default 88 ft/s either
    weak = api.run("head_on", fmu=simple_fmu, until_time=0.5, params={"drive_power_max": 5e3}).warnings
    assert weak == [warning.replace("202", "88").replace("201.4", "55.1").replace("110 kW", "5 kW")]


def test_the_fmu_itself_refuses_parameters_outside_their_declared_range(simple_fmu):
    # the same ranges as the command line's, enforced by fmi2SetReal in the FMU's own runtime
    from sdl_fmu.cosim.ego import EgoFMU, FmuError

    for name, value in (("mass", 0.0), ("wheelbase", 0.0), ("brake_decel_max", -9.81)):
        with pytest.raises(FmuError, match="fmi2SetReal failed"):
            EgoFMU(simple_fmu, {name: value})
    EgoFMU(simple_fmu, {"mass": 1.0, "wheelbase": 0.1, "brake_decel_max": 0.0}).close()  # the bounds themselves


def test_scenario_errors_raise_scenario_error(tmp_path):
    path = tmp_path / "bad.sdl"
    path.write_text("10,BRK,50,9,1\n")
    with pytest.raises(api.ScenarioError, match=r"bad.sdl:1: BRK parameter 2"):
        api.run(path)


def test_the_command_line_shows_the_bar_when_stderr_is_a_terminal(tmp_path, simple_fmu):
    import os
    import pty
    import subprocess
    import sys

    controller, terminal = pty.openpty()
    completed = subprocess.run([sys.executable, "-m", "sdl_fmu.cli", "run", "head_on", "--fmu", str(simple_fmu),
                                "--until-time", "2", "--out", str(tmp_path / "out")], cwd=tmp_path,
                               stdout=subprocess.PIPE, stderr=terminal, text=True, timeout=120)
    os.close(terminal)
    shown = b""
    while True:
        try:
            chunk = os.read(controller, 65536)
        except OSError:  # the terminal's other end is closed and drained
            break
        if not chunk:
            break
        shown += chunk
    os.close(controller)
    assert completed.returncode == 0
    assert b"%|" in shown and "%|" not in completed.stdout  # the bar is on the terminal, never in stdout


def test_a_mapping_of_values_goes_where_each_name_says(simple_fmu):
    # api.apply_values, as a sweep's row is run: run options to run's keywords, FMU parameters into params, scenario
    # parameters (a declared name, $name, an address) into the scenario; a bare name the file declares that the FMU
    # also has is ambiguous (api.check_value_names), an unknown one sets nothing
    from sdl_fmu.sdl import parse_text

    scenario = parse_text("English\n// @param mass = 2 in 1..8\n// @param gap = 800 ft\n"
                          "100,A,50,$gap,-6,$mass\n", "m.sdl")
    targets = {name: api.value_target(name, scenario) for name in
               ("speed", "seed", "$mass", "mass", "gap", "4.2", "rsa.4", "param.mass", "drag_area")}
    assert targets == {"speed": "option", "seed": "option", "$mass": "scenario", "mass": "scenario",
                       "gap": "scenario", "4.2": "scenario", "rsa.4": "scenario", "param.mass": "fmu",
                       "drag_area": "fmu"}
    applied, options = api.apply_values(scenario, {"speed": 70.0, "$mass": 3, "4.0": 150, "param.mass": 1600.0},
                                        {"params": {"drag_area": 0.5}, "plot": False})
    assert options == {"speed": 70.0, "params": {"drag_area": 0.5, "mass": 1600.0}, "plot": False}
    assert applied.events[0].model.low == 3 and applied.events[0].distance == pytest.approx(150 * 0.3048)
    model = api.ego_model(fmu=simple_fmu)
    api.check_value_names(scenario, ["speed", "$mass", "param.mass", "gap", "4.2", "drag_area"], model)
    for names, needle in ((["mass"], "vary mass: is both a parameter of m.sdl and an FMU parameter of simple: write "
                                     "$mass or param.mass"),
                          (["gap", "$gap"], "vary $gap: is the parameter gap names too; give it once"),
                          (["lead_speed"], "vary lead_speed: is no run option (speed, seed, until_distance, "
                                           "until_time), no parameter of m.sdl (declared: mass, gap;"),
                          (["$width"], "vary $width: m.sdl declares no parameter 'width' (declared: mass, gap)"),
                          (["param.grip"], "vary param.grip: the FMU simple has no parameter 'grip' (parameters: ")):
        with pytest.raises(api.InputError) as caught:
            api.check_value_names(scenario, names, model)
        assert str(caught.value).startswith(needle), str(caught.value)
