"""A foreign controller FMU cannot take sdl-fmu down silently either (sdl_fmu/vehicle/controller.py: an
IsolatedController in a host process, vehicle/isolated.py; docs/controllers.md).

The hostile controller (tests/controllers/hostile_aeb.c, compiled here) crashes, exits, hangs, requests NaN, inf or
1e308, or lies about its FMU state on demand, from its sample at t = 1 s. The ego is the shipped Simple FMU (in
sdl-fmu's own process), the scenario brakes with a BRK whose distance threshold the master bisects on saved and
restored ego states. Every case runs the real command line under a 1.5 GB address-space cap (tests/hostile_fmus.py),
with a private $TMPDIR that must be empty afterwards and no host process left; timeouts only catch hangs, and a
signal is sent when the controller says it hangs (it creates a file), never after a guessed time."""

import csv
import json
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from hostile_fmus import (HANG_LIMIT, _capped, assert_clean, capped, capped_command, environment, hostile_controller,
                          hostile_controller_map, one_line, popen_capped, wait_for)

SCENARIO = "English\n300,BRK,100,1,50\n600,ES\n"  # BRK at 300 ft (t = 3.4 s), released 50 ft on: bisected
SLOW = pytest.mark.slow  # the fast loop keeps a crash and a hang under Ctrl-C; the rest runs in CI
FAILED = "sdl-fmu: the controller HostileAeb.fmu failed: "
STEP = "in fmi2DoStep from t = 1.000000 s to 1.010000 s"  # the sample at k = 100 of the 0.01 s period


@pytest.fixture(scope="module")
def aeb(tmp_path_factory):
    """(FMU, scenario): the hostile controller built once."""
    folder = tmp_path_factory.mktemp("hostile-aeb")
    scenario = folder / "brake.sdl"
    scenario.write_text(SCENARIO)
    return hostile_controller(folder), scenario


@pytest.fixture
def work(tmp_path):
    """A working folder and a private, empty $TMPDIR (checked empty at the end)."""
    (tmp_path / "tmp").mkdir()
    (tmp_path / "work").mkdir()
    return tmp_path


def run_command(aeb, work, simple_fmu, mode, *more, out="out"):
    fmu, scenario = aeb
    return ["run", scenario, "--fmu", simple_fmu, "--controller", fmu, "--controller-map",
            hostile_controller_map(work, mode), "--out", work / "work" / out, *more]


@pytest.mark.parametrize("mode, needle", [
    ("crash", f"it crashed (SIGSEGV) {STEP}"),
    pytest.param("exit", f"its process ended (exit status 0) {STEP}; an FMU must not end the process it runs in",
                 marks=SLOW),
    pytest.param("nan", "its output 'brake' (brake) is nan at t = 1.000000 s: not a finite number", marks=SLOW),
    pytest.param("inf", "its output 'brake' (brake) is inf at t = 1.000000 s: not a finite number", marks=SLOW),
    # 1e308 is finite (it once ran to exit 0 with numpy's RuntimeWarning and an empty column): beyond the ego's
    # outputs' bound (1e9 in SI) it is the run's one line too
    ("huge", "its output 'brake' (brake) is 1e+308 at t = 1.000000 s: beyond 1e+09 in SI units"),
])
def test_a_crash_an_exit_or_a_non_finite_request_ends_the_run_in_one_line(aeb, work, simple_fmu, mode, needle):
    completed = capped(*run_command(aeb, work, simple_fmu, mode), cwd=work / "work", env=environment(work))
    line = one_line(completed, 2, FAILED, needle)
    assert line == FAILED + needle
    assert completed.stdout == "" and os.listdir(work / "work") == []  # nothing written
    assert_clean(work)


@pytest.mark.parametrize("how", ["ctrl-c", pytest.param("timeout", marks=SLOW)])
def test_a_hang_in_the_controllers_do_step_is_ended_by_ctrl_c_and_by_timeout(aeb, work, simple_fmu, how):
    """Ctrl-C (exit 130) and coreutils `timeout`, which sends SIGTERM to the command and then its process group
    (exit 143), end a run whose controller loops for ever inside fmi2DoStep."""
    hanging = work / "hanging"
    command = run_command(aeb, work, simple_fmu, "hang")
    env = environment(work, HOSTILE_HANG_FILE=str(hanging))
    if how == "ctrl-c":
        process = popen_capped(*command, cwd=work / "work", env=env)
    else:
        process = subprocess.Popen(["timeout", str(HANG_LIMIT), *map(str, capped_command(*command))],
                                   cwd=work / "work", env={**os.environ, **env}, preexec_fn=_capped,
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for(hanging, process)
        process.send_signal(signal.SIGINT if how == "ctrl-c" else signal.SIGTERM)
        stdout, stderr = process.communicate(timeout=HANG_LIMIT)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    expected = {"ctrl-c": (130, "sdl-fmu: interrupted (Ctrl-C); nothing was written"),
                "timeout": (143, "sdl-fmu: terminated (SIGTERM); nothing was written")}[how]
    assert (process.returncode, stderr.splitlines()) == (expected[0], [expected[1]]), stderr
    assert stdout == "" and os.listdir(work / "work") == []
    assert_clean(work)


@SLOW
def test_the_api_timeout_ends_a_hang_inside_the_controllers_step(aeb, work, simple_fmu):
    """api.run(timeout=) stops waiting for a hung controller mid-step, and says which FMU did not answer."""
    fmu, scenario = aeb
    code = ("from sdl_fmu import api\n"
            "try:\n"
            f"    api.run({str(scenario)!r}, fmu={str(simple_fmu)!r}, controller={str(fmu)!r},\n"
            f"            controller_map={str(hostile_controller_map(work, 'hang'))!r}, timeout=2)\n"
            "except api.RunTimeout as error:\n"
            "    print(error)\n")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_LIMIT,
                               env={**os.environ, **environment(work)}, cwd=work / "work", preexec_fn=_capped)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout == (f"the run exceeded its time limit of 2 s (wall clock): the controller HostileAeb.fmu "
                                f"did not answer {STEP} before the wall-clock limit (its process was ended)\n")
    assert_clean(work)


@SLOW
def test_a_sweeps_timeout_ends_a_hung_controllers_run(aeb, work, simple_fmu):
    """sweep --timeout (each run's api.run timeout, on a Dask worker): the hung run is a `timeout` row naming the
    controller, the sweep ends (exit 3, one line) and leaves neither host nor unpacked FMU behind."""
    fmu, scenario = aeb
    out = work / "work" / "sweep"
    completed = capped("sweep", scenario, "--vary", "speed=80", "--workers", "1", "--timeout", "3", "--fmu",
                       simple_fmu, "--controller", fmu, "--controller-map", hostile_controller_map(work, "hang"),
                       "--out", out, cwd=work / "work", env=environment(work))
    one_line(completed, 3, "sdl-fmu: all 1 runs timed out (", "run 0: the run exceeded its time limit of 3 s (wall clock): "
             "the controller HostileAeb.fmu did not answer in fmi2DoStep from t = 1.000000 s")
    rows = [json.loads(line) for line in (out / "sweep-rows.jsonl").read_text().splitlines()]
    assert [row["status"] for row in rows] == ["timeout"]
    assert "the controller HostileAeb.fmu did not answer in fmi2DoStep from t = 1.000000 s" in rows[0]["error"]
    assert_clean(work)


@SLOW
def test_the_controllers_state_is_never_saved_or_restored_so_a_capability_lie_changes_nothing(aeb, work, simple_fmu):
    """The controller declares canGetAndSetFMUstate and its fmi2SetFMUstate restores nothing. It is stepped only at
    its samples, step ends of the master (docs/controllers.md, Exactness), so sdl-fmu never saves or restores its
    state, even while the ego's is saved and restored to bisect the BRK threshold: the FMU records no state call, and
    the run's results are byte for byte those of the honest controller."""
    outputs = []
    for mode in ("honest", "lie"):
        record = work / f"state-{mode}"
        completed = capped(*run_command(aeb, work, simple_fmu, mode, out=mode), cwd=work / "work",
                           env=environment(work, HOSTILE_STATE_FILE=str(record)))
        assert completed.returncode == 0, completed.stderr
        assert not record.exists(), record.read_text()  # no fmi2GetFMUstate, SetFMUstate or FreeFMUstate
        summary = json.loads((work / "work" / mode / "summary.json").read_text())
        assert summary["controller"]["can_roll_back"] is True
        brk = [event for event in summary["events"] if event["code"] == "BRK"]
        assert brk and "time_uncertainty_s" not in brk[0]  # bisected: the ego's state was saved and restored
        outputs.append((work / "work" / mode / "timeseries.csv").read_bytes())
    assert outputs[0] == outputs[1]
    assert_clean(work)


@SLOW
def test_a_crashing_controller_is_each_aeb_test_s_error_and_export_s_one_line(aeb, work, simple_fmu):
    """verify --pack aeb-ccr: a failure is the test's result (verify.json names the crash in each test); export runs
    the controller in its reference run: one line, nothing written."""
    fmu, scenario = aeb
    crash = hostile_controller_map(work, "crash", trigger_time=0.0)
    out = work / "work" / "verify"
    completed = capped("verify", "--pack", "aeb-ccr", "--only", "CCRs", "--workers", "0", "--fmu", simple_fmu,
                       "--controller", fmu, "--controller-map", crash, "--out", out, cwd=work / "work",
                       env=environment(work))
    assert completed.returncode == 0, completed.stderr
    tests = json.loads((out / "verify.json").read_text())["tests"]
    assert tests and all(test["error"] == "the controller HostileAeb.fmu failed: it crashed (SIGSEGV) in fmi2DoStep "
                         "from t = 0.000000 s to 0.010000 s" for test in tests), tests[0]
    exported = capped("export", scenario, "--fmu", simple_fmu, "--controller", fmu, "--controller-map",
                      hostile_controller_map(work, "crash"), "--out", work / "work" / "export", cwd=work / "work",
                      env=environment(work))
    one_line(exported, 2, f"{FAILED}it crashed (SIGSEGV) {STEP}")
    assert sorted(os.listdir(work / "work")) == ["verify"]
    assert_clean(work)


def test_only_a_controller_sdl_fmu_built_runs_in_its_process(aeb, monkeypatch):
    """The shipped example AEB (its bytes are those of the FMU cache's build) runs in sdl-fmu's process; any other
    controller FMU in a host; SDL_FMU_ISOLATION=always puts the example in a host too."""
    from sdl_fmu import api
    from sdl_fmu.vehicle.controller import ControllerInstance, ControllerModel, IsolatedController
    from sdl_fmu.vehicle.isolated import ISOLATION_VARIABLE

    fmu, scenario = aeb
    example = ControllerModel.open(*api.example_controller())
    foreign = ControllerModel.open(fmu, hostile_controller_map(fmu.parent, "honest"))
    for model, kind in ((example, ControllerInstance), (foreign, IsolatedController)):
        with model.instantiate() as instance:
            assert type(instance) is kind
    monkeypatch.setenv(ISOLATION_VARIABLE, "always")
    with example.instantiate() as instance:
        assert type(instance) is IsolatedController


@SLOW
def test_a_controller_in_a_host_gives_the_same_results(work, simple_fmu):
    """The example AEB through a CCRs-like approach, in sdl-fmu's process and in a host (SDL_FMU_ISOLATION=always):
    byte-identical time series (its samples travel as requests, in the same order, with the same values)."""
    scenario = work / "ccrs.sdl"
    scenario.write_text("Metric\n0, A, 0, 60, *0, 1\n200, ES\n")
    outputs = []
    for isolation in ("auto", "always"):
        out = work / "work" / isolation
        completed = capped("run", scenario, "--fmu", simple_fmu, "--speed", 50 / 3.6, "--controller", "example-aeb",
                           "--until-time", 8, "--out", out, cwd=work / "work",
                           env=environment(work, SDL_FMU_ISOLATION=isolation))
        assert completed.returncode == 0, completed.stderr
        outputs.append((out / "timeseries.csv").read_bytes())
        rows = list(csv.DictReader(outputs[-1].decode().splitlines()))
        assert {row["request_active"] for row in rows} == {"0", "1"}  # the AEB acted
    assert outputs[0] == outputs[1]
    assert_clean(work)


def journal_rows(path) -> list[dict]:
    """The rows of a pack's journal that are whole (an interruption may cut its last line short)."""
    rows = []
    for line in path.read_text().splitlines():
        try:
            rows.append(json.loads(line))
        except ValueError:
            continue
    return rows


@pytest.mark.parametrize("how", ["ctrl-c", pytest.param("sigterm", marks=SLOW)])
def test_a_hung_controller_times_out_each_aeb_test_and_the_interrupted_pack_resumes(aeb, work, simple_fmu, how):
    """verify --pack aeb-ccr --test-timeout with a controller that hangs from its first sample (trigger_time 0): every
    test hangs, so any timeout ends each one, whatever the machine's speed. Each finished test is kept in the
    journal as it ends and said on stderr (tests done, failed, timed out, elapsed); Ctrl-C (or SIGTERM), sent once two
    are kept (read from what the command wrote), keeps them and says so; the same command then runs only the others (one
    progress line each, counting from the kept ones), and every test is reported as timed out: never passed, no
    points, counted in the totals."""
    fmu, _ = aeb
    out = work / "work" / "aeb"
    journal = out / "tests-rows.jsonl"
    hang = hostile_controller_map(work, "hang", trigger_time=0.0)
    command = ["verify", "--pack", "aeb-ccr", "--only", "CCRb", "--workers", "0", "--test-timeout", "0.2", "--fmu",
               simple_fmu, "--controller", fmu, "--controller-map", hang, "--out", out]
    process = popen_capped(*command, cwd=work / "work", env=environment(work))
    try:
        deadline = time.monotonic() + HANG_LIMIT  # only against a hang: the loop ends once two tests are kept
        while not (journal.is_file() and len(journal_rows(journal)) >= 2):
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "no test was kept"
            time.sleep(0.02)
        process.send_signal(signal.SIGINT if how == "ctrl-c" else signal.SIGTERM)
        stdout, stderr = process.communicate(timeout=HANG_LIMIT)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    lines = stderr.splitlines()
    code, what = {"ctrl-c": (130, "interrupted (Ctrl-C)"), "sigterm": (143, "terminated (SIGTERM)")}[how]
    assert process.returncode == code and lines[-1] == (
        f"sdl-fmu: verify {what}; the finished tests are in {journal}: the same command resumes the pack"), stderr
    kept = journal_rows(journal)
    assert len(kept) >= 2 and all(row["outcome"]["end"] == "timeout" for row in kept), kept
    # one progress line per kept test (the last may have been cut short by the signal, after its row was written)
    assert len(kept) - 1 <= len(lines) - 1 <= len(kept), stderr
    for n, line in enumerate(lines[:-1], 1):
        assert re.fullmatch(rf"aeb-ccr: {n}/20 tests done, 0 failed, {n} timed out, \d+ s", line), line
    assert stdout == "" and os.listdir(work / "work") == ["aeb"]
    assert_clean(work)

    resumed = capped(*command, cwd=work / "work", env=environment(work))
    assert resumed.returncode == 0, resumed.stderr
    # the kept tests are not run again: one line per test run, counting on from the kept ones
    lines = resumed.stderr.splitlines()
    assert len(lines) == 20 - len(kept), resumed.stderr
    for n, line in enumerate(lines, len(kept) + 1):
        assert re.fullmatch(rf"aeb-ccr: {n}/20 tests done, 0 failed, {n} timed out, \d+ s", line), line
    document = json.loads((out / "verify.json").read_text())
    tests = document["tests"]
    assert len(tests) == 20
    for test in tests:
        assert (test["end"], test["passed"], test["score"], test["impact"]) == ("timeout", False, None, None), test
        assert test["error"].startswith("the run exceeded its time limit of 0.2 s (wall clock): the controller "
                                        "HostileAeb.fmu did not answer "), test["error"]
    # the kept tests' outcomes are those the interrupted pack wrote, to the microsecond of their wall time
    by_key = {json.dumps({k: t[k] for k in ("group", "ego_speed_kmh", "target_speed_kmh", "overlap_pct",
                                            "target_decel_mps2", "headway_m")}, sort_keys=True): t for t in tests}
    for row in kept:
        assert by_key[row["key"]] == row["outcome"]
    assert document["totals"]["CCRb"] == {"tests": 20, "impacts": 0, "errors": 0, "timeouts": 20, "points": 0.0,
                                          "max_points": 20.0, "score_pct": 0.0, "passed": 0}
    assert document["passed"] is False
    assert "CCRb: 0.00 of 20 points (0.0 %), 0 impact(s) in 20 tests, 20 timed out" in resumed.stdout
    assert sum(line.split().count("t/o") for line in resumed.stdout.splitlines()) == 20  # the grid's cells
    # the results replaced the journal
    assert sorted(os.listdir(out)) == [".sdl-fmu-results.json", "report.html", "tests.csv", "verify.json"]
    assert_clean(work)
