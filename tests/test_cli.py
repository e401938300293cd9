"""The command line as a user meets it: real subprocesses, exit codes, messages, files written."""

import json
import subprocess
import sys

import pytest

BAD_SCENARIO = """English
100,A,20,1000,-6,*8~1
200,BRK,150,0,3
300,XYZ,1
"""


def sdl_fmu(*args, cwd):
    return subprocess.run([sys.executable, "-m", "sdl_fmu.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


def test_run_on_malformed_input_names_each_line_and_writes_nothing(tmp_path, simple_fmu):
    scenario = tmp_path / "bad.sdl"
    scenario.write_text(BAD_SCENARIO)
    out = tmp_path / "results"
    completed = sdl_fmu("run", scenario, "--fmu", simple_fmu, "--out", out, cwd=tmp_path)
    assert completed.returncode == 1
    assert "Traceback" not in completed.stderr
    lines = completed.stderr.strip().splitlines()
    assert [line.split(":")[1] for line in lines] == ["2", "3", "4"]
    assert all(line.startswith(str(scenario)) for line in lines)
    assert not out.exists() and list(tmp_path.iterdir()) == [scenario]


def test_check_reports_all_errors(tmp_path):
    scenario = tmp_path / "bad.sdl"
    scenario.write_text(BAD_SCENARIO)
    completed = sdl_fmu("check", scenario, cwd=tmp_path)
    assert completed.returncode == 1 and "Traceback" not in completed.stderr
    assert "model" in completed.stderr and "BRK parameter 1" in completed.stderr and "XYZ" in completed.stderr


def test_check_lists_a_good_scenario(tmp_path):
    scenario = tmp_path / "good.sdl"
    scenario.write_text("Metric\n10,BRK,100,0,2\n")
    completed = sdl_fmu("check", scenario, cwd=tmp_path)
    assert completed.returncode == 0 and "BRK" in completed.stdout and "Metric" in completed.stdout


@pytest.mark.parametrize("arguments, message", [
    (["--param", "no_such_parameter=1"], "no_such_parameter"),
    (["--param", "mass"], "NAME=VALUE"),
    (["--fmu", "missing.fmu"], "missing.fmu"),
    (["--step", "0"], "--step"),
])
def test_user_mistakes_are_one_line_errors(tmp_path, simple_fmu, arguments, message):
    scenario = tmp_path / "good.sdl"
    scenario.write_text("10,BRK,100,0,2\n")
    out = tmp_path / "results"
    fmu = [] if "--fmu" in arguments else ["--fmu", simple_fmu]
    completed = sdl_fmu("run", scenario, *fmu, "--out", out, *arguments, cwd=tmp_path)
    assert completed.returncode == 2
    assert "Traceback" not in completed.stderr and len(completed.stderr.strip().splitlines()) == 1
    assert message in completed.stderr
    assert not out.exists()


def test_run_writes_the_three_results(tmp_path, simple_fmu):
    scenario = tmp_path / "stop.sdl"
    scenario.write_text("100,BRK,100,1,1000\n400,ES\n")
    out = tmp_path / "results"
    completed = sdl_fmu("run", scenario, "--fmu", simple_fmu, "--out", out, "--speed", "60", cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    assert {p.name for p in out.iterdir()} == {"timeseries.csv", "summary.json", "plot.png", ".sdl-fmu-results.json"}
    summary = json.loads((out / "summary.json").read_text())
    assert {"units", "dynamics", "collisions", "final", "events", "warnings"} <= set(summary)
    assert [(e["code"], e["action"]) for e in summary["events"]] == [("BRK", "on"), ("BRK", "off"), ("ES", "end")]
    assert summary["events"][1]["reason"] == "stopped"


def test_verify_prints_the_pass_fail_table(tmp_path, simple_fmu):
    completed = sdl_fmu("verify", "--fmu", simple_fmu, "--only", "braking", "--out", tmp_path / "v", cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    assert any(line.split()[:2] == ["braking", "pass"] for line in completed.stdout.splitlines())
