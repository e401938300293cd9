"""The command line as a user meets it: real subprocesses, exit codes, messages, files written."""

import json
import os
import subprocess
import sys

import pytest

from helpers import sdl_fmu

BAD_SCENARIO = """English
100,A,20,1000,-6,*8~1
200,BRK,150,0,3
300,XYZ,1
"""


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


# ---- conventions of the ecosystem ----------------------------------------------------------------------------


def test_version_and_python_dash_m(tmp_path):
    from sdl_fmu import __version__

    for command in ([sys.executable, "-m", "sdl_fmu", "--version"], [sys.executable, "-m", "sdl_fmu.cli", "--version"]):
        completed = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, timeout=120)
        assert completed.returncode == 0 and completed.stdout.strip() == f"sdl-fmu {__version__}"


def test_top_level_help_lists_every_command_with_one_line(tmp_path):
    from sdl_fmu.cli import parser

    completed = subprocess.run([sys.executable, "-m", "sdl_fmu", "--help"], capture_output=True, text=True,
                               cwd=tmp_path, timeout=120)
    assert completed.returncode == 0
    commands = parser()._subparsers._group_actions[0]
    for choice in commands._choices_actions:
        line = next(line for line in completed.stdout.splitlines() if line.split()[:1] == [choice.dest])
        assert choice.help and choice.help in line
    assert set(commands.choices) == {choice.dest for choice in commands._choices_actions}


def test_every_option_of_every_command_has_help_text():
    import argparse

    from sdl_fmu.cli import parser

    main = parser()
    commands = next(a for a in main._actions if isinstance(a, argparse._SubParsersAction))
    for name, command in {"sdl-fmu": main, **commands.choices}.items():
        for action in command._actions:
            if action is commands or isinstance(action, argparse._HelpAction):
                continue
            assert action.help and action.help != argparse.SUPPRESS, f"{name} {action.option_strings or action.dest}"


def test_a_closed_pipe_ends_quietly_with_141(tmp_path):
    # sdl-fmu's stdout is a pipe whose only reading end is closed before sdl-fmu starts, so its first write meets
    # EPIPE whatever the timing: what `| head -1` does to a writer that is still writing
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        process = subprocess.Popen([sys.executable, "-m", "sdl_fmu", "check", "demo"], stdout=write_end,
                                   stderr=subprocess.PIPE, cwd=tmp_path)
    finally:
        os.close(write_end)
    error = process.stderr.read().decode()
    assert process.wait(timeout=120) == 141
    assert "Traceback" not in error and "BrokenPipe" not in error and "Exception ignored" not in error


def test_command_line_errors_name_the_flags_the_api_the_keywords(tmp_path, simple_fmu):
    from sdl_fmu import api

    completed = sdl_fmu("run", "head_on", "--fmu", simple_fmu, "--param", "mass=0", "--until-time", "1",
                        cwd=tmp_path)
    assert completed.returncode == 2
    assert completed.stderr.startswith("sdl-fmu: --param mass=0.0: below the declared minimum 1 kg of mass")
    with pytest.raises(api.InputError) as caught:
        api.run("head_on", fmu=simple_fmu, params={"mass": 0}, until_time=1)
    assert str(caught.value).startswith("params mass=0: below the declared minimum 1 kg of mass")


def test_result_repr_is_one_short_line(simple_fmu):
    from sdl_fmu import api

    result = api.run("head_on", fmu=simple_fmu, until_time=30.0)
    text = repr(result)
    samples = len(result.time)
    assert samples > 100  # a long run: its arrays must not be in the repr
    assert text == (f"<Result head_on: simple dynamics, {samples} samples to {result.final['time_s']:.2f} s, "
                    f"{result.collisions} collision(s), {len(result.warnings)} warning(s)>")
    assert len(text) < 120 and "\n" not in text


NO_MATPLOTLIB = """
import sys
from sdl_fmu.cli import main
code = main(sys.argv[1:])
print("matplotlib imported" if "matplotlib" in sys.modules else "matplotlib not imported")
sys.exit(code)
"""


def test_run_no_plot_writes_the_files_but_the_plot_and_never_imports_matplotlib(tmp_path, simple_fmu):
    out = tmp_path / "results"
    completed = subprocess.run([sys.executable, "-c", NO_MATPLOTLIB, "run", "head_on", "--fmu", str(simple_fmu),
                                "--until-time", "1", "--no-plot", "--out", str(out)], capture_output=True, text=True,
                               cwd=tmp_path, timeout=300)
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.splitlines()[-1] == "matplotlib not imported"
    assert "plot:" not in completed.stdout
    assert {path.name for path in out.iterdir()} == {"timeseries.csv", "summary.json", ".sdl-fmu-results.json"}
    # the same folder run again with the plot: plot.png is added, and a --no-plot run after it removes it again
    # (the folder is replaced as a whole: no stale plot of another run is left beside the new files)
    assert sdl_fmu("run", "head_on", "--fmu", simple_fmu, "--until-time", "1", "--out", out,
                   cwd=tmp_path).returncode == 0
    assert (out / "plot.png").is_file()
    assert sdl_fmu("run", "head_on", "--fmu", simple_fmu, "--until-time", "1", "--no-plot", "--out", out,
                   cwd=tmp_path).returncode == 0
    assert not (out / "plot.png").exists()
