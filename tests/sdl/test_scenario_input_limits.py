"""Scenario inputs at and beyond the format's limits: the inputs that once crashed or exhausted a run, and generated
inputs of the same families (huge model ranges, long digit strings, extreme but legal magnitudes of every numeric
field, many lanes, long lines, non-ASCII digits). The set is meant to grow: add a case to a list below.

Each case runs the real command line in a subprocess under a memory cap (resource.setrlimit on the address space)
and a wall-clock limit that only catches hangs (never a speed assertion), and has one of two outcomes, which
the case states in advance:
- a correct run: exit 0, the three results files written, nothing on stderr but warnings;
- a refusal: exit 1 with one short line on stderr naming the file, the line and the field, nothing on stdout,
  nothing written, no traceback."""

import json
import os
import resource
import subprocess
import sys

import pytest

from sdl_fmu.sdl.parser import MAX_LANES, MAX_NUMBER_CHARS, MAX_PARAMETERS, MAX_SHOWN_CHARS

import helpers

UNKNOWN_MODEL = max(helpers.TABLE) + 1  # the first model number the shipped vehicle table does not list

MEMORY_CAP = 1 << 30  # bytes of address space per sdl-fmu process; a run needs ~0.3 GiB, the old reproducers > 1
HANG_LIMIT = 900  # s: only a hang gets near it (the longest case, a 3600 s run, takes ~10 s alone)
MAX_ERROR_LINE = 300  # characters: "one short line"

L_MAX = "3280839"  # ft: the format's longest length is 1e6 m = 3280839.9 ft
L_OVER = "3280840"
S_MAX = "3280"  # ft/s: the fastest speed is 1000 m/s = 3280.84 ft/s
S_OVER = "3281"
T_MAX = "1000000"  # s
T_OVER = "1000001"


def _capped():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))


# A generated family runs in one capped subprocess: each case through the real command line (cli.main), its
# output captured; an exception escaping main is recorded as the traceback it would have printed.
DRIVER = """
import contextlib, io, json, sys, traceback, warnings
warnings.simplefilter("always")  # a warning repeated from one case to the next is shown in each
from sdl_fmu.cli import main
results = []
for argv in json.load(sys.stdin):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except BaseException:
            traceback.print_exc()
            code = -1
    results.append({"returncode": code, "stdout": out.getvalue(), "stderr": err.getvalue()})
json.dump(results, sys.stdout)
"""


def run_batch(tmp_path, fmu, cases):
    """cases: (name, text, extra arguments); returns per case (result, path, out) as run_case does."""
    argv, where = [], []
    for k, (name, text, extra) in enumerate(cases):
        folder = tmp_path / f"case{k}"
        folder.mkdir()
        path, out = folder / "case.sdl", folder / "out"
        path.write_bytes(text.encode("utf-8"))
        argv.append(["run", str(path), "--out", str(out), "--fmu", str(fmu), *extra])
        where.append((path, out))
    done = subprocess.run([sys.executable, "-c", DRIVER], input=json.dumps(argv), capture_output=True, text=True,
                          timeout=HANG_LIMIT, preexec_fn=_capped)
    assert done.returncode == 0, done.stderr[-3000:]
    results = [subprocess.CompletedProcess(a, r["returncode"], r["stdout"], r["stderr"])
               for a, r in zip(argv, json.loads(done.stdout))]
    return [(result, path, out) for result, (path, out) in zip(results, where)]


def failures(cases, outcomes, check) -> list[str]:
    """Runs check(case, outcome) for every case and collects the failures, naming each case."""
    failed = []
    for (name, _, _), outcome in zip(cases, outcomes):
        try:
            check(name, *outcome)
        except AssertionError as error:
            failed.append(f"{name}: {str(error)[:400]}")
    return failed


def sdl_fmu(arguments, cwd):
    return helpers.sdl_fmu(*arguments, cwd=cwd, timeout=HANG_LIMIT, preexec_fn=_capped,
                           env={**os.environ, "PYTHONWARNINGS": ""})


def run_case(tmp_path, fmu, text, extra=(), name="case.sdl"):
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8") if isinstance(text, str) else text)
    out = tmp_path / "out"
    result = sdl_fmu(["run", path, "--out", out, "--fmu", fmu, *extra], tmp_path)
    return result, path, out


def assert_correct_run(result, out):
    assert "Traceback" not in result.stderr
    assert result.returncode == 0, result.stderr[-2000:]
    assert all(line.startswith("warning: ") for line in result.stderr.splitlines()), result.stderr[-2000:]
    assert {p.name for p in out.iterdir()} >= {"timeseries.csv", "summary.json", "plot.png"}
    return json.loads((out / "summary.json").read_text())


def assert_refused(result, path, out, line, field, code=1):
    assert "Traceback" not in result.stderr
    assert result.returncode == code, (result.returncode, result.stderr[-2000:])
    lines = result.stderr.splitlines()
    assert len(lines) == 1, lines[:5]
    assert len(lines[0]) <= MAX_ERROR_LINE, lines[0][:MAX_ERROR_LINE * 2]
    assert lines[0].startswith(f"{path}:{line}: {field}: "), lines[0]
    assert result.stdout == ""
    assert not out.exists()
    return lines[0]


# --- inputs that once held a run --------------------------------------------------------------------------

def test_brk_relative_velocity_beyond_the_stop_no_longer_holds_the_run(tmp_path, simple_fmu):
    result, _, out = run_case(tmp_path, simple_fmu, "English\n1000,BRK,100,3,200\n2000,A,20,500,-6,1\n3000,ES\n")
    summary = assert_correct_run(result, out)
    actions = [(e["code"], e["action"], e.get("reason")) for e in summary["events"]]
    assert actions[:3] == [("BRK", "on", None), ("BRK", "off", "stopped"), ("A", "spawn", None)]
    assert actions[-1] == ("ES", "end", "scenario") and summary["final"]["time_s"] < 100


# The short refusals below share one capped subprocess (run_batch, once per module): each case is still the real
# command line (cli.main) on its own file and folder; only the interpreter's start-up is shared.
HUGE_MODEL_RANGES = ["*1~30000000", "*1~1000000000", "*1~99999999999999999999", "*1~" + "9" * MAX_NUMBER_CHARS,
                     "*5~" + "1" + "0" * 30]
WHOLE_NUMBER_FIELDS = [
    ("0,ROAD,12,2,{}", "ROAD parameter 3 (lanes right of the dividing line)"),
    ("100,RSA,{},8", "RSA parameter 1 (lane)"),
    ("100,BRK,100,{},3", "BRK parameter 2 (threshold type)"),
    ("100,A,20,1000,-6,{}", "A parameter 4 (model)"),
]
DIGITS = [MAX_NUMBER_CHARS + 1, 4301, 10**6]
UNDRAWABLE = [
    ("100,A,-1e308,1000,-6,1", "A parameter 1 (speed)"),
    ("0,ROAD,1e308,2,1", "ROAD parameter 1 (lane width)"),
    ("0,ROAD,12,100000,1", "ROAD parameter 2 (lanes)"),
    ("0,ROAD,12,1000000,1", "ROAD parameter 2 (lanes)"),
    ("0,ROAD,12,200,99", "ROAD parameter 3 (lanes right of the dividing line)"),  # 101 left: lane -101 = shoulder
]
REFUSALS = {  # case -> scenario text
    **{("models", models): f"English\n100,A,20,1000,-6,{models}\n" for models in HUGE_MODEL_RANGES},
    **{("digits", event, digits): "English\n" + event.format("1" * digits) + "\n"
       for event, _ in WHOLE_NUMBER_FIELDS for digits in DIGITS},
    **{("undrawable", event): f"English\n{event}\n" for event, _ in UNDRAWABLE},
    ("1 MB field",): "English\n100,BRK,100,0," + "x" * 2**20 + "\n",
}


@pytest.fixture(scope="module")
def refused(tmp_path_factory, simple_fmu):
    """case -> (result, path, out) of every case of REFUSALS, run as run_case runs one."""
    cases = [(str(case), text, []) for case, text in REFUSALS.items()]
    return dict(zip(REFUSALS, run_batch(tmp_path_factory.mktemp("refusals"), simple_fmu, cases)))


@pytest.mark.parametrize("models", HUGE_MODEL_RANGES)
def test_a_huge_model_range_is_refused_at_once(refused, models):
    result, path, out = refused["models", models]
    line = assert_refused(result, path, out, 2, "A parameter 4 (model)")
    assert f"{UNKNOWN_MODEL}-" in line and "are not in the table" in line


@pytest.mark.parametrize("event, field", WHOLE_NUMBER_FIELDS)
@pytest.mark.parametrize("digits", DIGITS, ids=["33", "4301", "1M"])
def test_a_whole_number_field_with_too_many_digits_is_one_short_line(refused, event, field, digits):
    result, path, out = refused["digits", event, digits]
    line = assert_refused(result, path, out, 2, field)
    assert f"longer than {MAX_NUMBER_CHARS} characters" in line
    assert (f"({digits} characters)" in line) == (digits > MAX_SHOWN_CHARS)  # shortened when long


@pytest.mark.parametrize("event, field", UNDRAWABLE)
def test_values_the_plot_could_not_draw_are_refused_up_front(refused, event, field):
    result, path, out = refused["undrawable", event]
    line = assert_refused(result, path, out, 2, field)
    assert "beyond the format's limit" in line or "at most 100 (lane numbers 101 and -101 are the shoulders)" in line


def test_a_1mb_bad_field_is_shown_shortened(refused):
    result, path, out = refused["1 MB field",]
    assert "(1048576 characters)" in assert_refused(result, path, out, 2, "BRK parameter 3 (magnitude)")


def test_check_with_advanced_dynamics_applies_the_advanced_rules(tmp_path):
    path = tmp_path / "rsa.sdl"
    path.write_text("English\n100,RSA,1,2.7\n")
    assert sdl_fmu(["check", path], tmp_path).returncode == 0
    result = sdl_fmu(["check", path, "--dynamics", "advanced"], tmp_path)
    assert result.returncode == 1 and result.stderr.splitlines() == [
        f"{path}:2: RSA parameter 2 (value): 2.7: for this vehicle the value is a surface attribute number "
        "and must be whole"]


@pytest.mark.parametrize("shadow", ["folder demo", "folder demo.sdl", "file demo.sdl"])
def test_a_short_name_shadowed_in_the_working_folder_is_one_line(tmp_path, shadow):
    kind, name = shadow.split()
    (tmp_path / name).mkdir() if kind == "folder" else (tmp_path / name).write_text("English\n10,ES\n")
    result = sdl_fmu(["check", "demo"], tmp_path)
    assert result.returncode == 1 and result.stdout == "" and "Traceback" not in result.stderr
    (line,) = result.stderr.splitlines()
    assert line.startswith(f"demo: file: ambiguous: '{name}' is a {kind} in the working folder") and "./" in line
    # an explicit path is never ambiguous, and without the shadow the short name is the shipped example
    if kind == "file":
        assert sdl_fmu(["check", f"./{name}"], tmp_path).returncode == 0
    (tmp_path / "clean").mkdir()
    assert sdl_fmu(["check", "demo"], tmp_path / "clean").returncode == 0


def test_the_scenario_docs_list_every_shipped_scenario():
    from pathlib import Path

    from sdl_fmu import api

    docs = (Path(__file__).parents[2] / "docs" / "scenarios.md").read_text()
    section = docs.split("## The shipped examples")[1].split("\n## ")[0]
    assert all(f"`{name}`" in section for name in api.shipped_scenarios()), sorted(api.shipped_scenarios())


# --- generated: extreme but legal magnitudes of every numeric field run and plot -----------------------------

EXTREMES = {
    "distance": f"{L_MAX},ES",
    "A max": f"100,A,{S_MAX},{L_MAX},{L_MAX},10",
    "A min": f"100,A,-{S_MAX},-{L_MAX},-{L_MAX},1",
    "A relative": f"100,A,*{S_MAX},1000,*-{L_MAX},*1~10",
    "A relative min": f"100,A,*-{S_MAX},-1000,*{L_MAX},*10~10",
    "A tiny gap": "100,A,20,0.000000001,6,1",
    "A action extremes": f"100,A,20,1000,-6,1,{T_MAX},*0,{S_MAX},{T_MAX},-{T_MAX},-{L_MAX},-{S_MAX},0",
    "A action tiny": f"100,A,-80,-500,6,2,0.000001F,*{L_MAX},*-{S_MAX},0.000001,-0.000001B,-6,*{S_MAX},{T_MAX}",
    "A five actions": "100,A,-60,300,18,3" + ",-1,18,-60,1" * 4 + f",-{T_MAX},{L_MAX},{S_MAX},{T_MAX}",
    "BRK time": f"100,BRK,100,0,{T_MAX}\n200,RSA,1,8",
    "BRK distance": f"100,BRK,100,1,{L_MAX}\n200,RSA,1,8",
    "BRK velocity": f"100,BRK,100,2,{S_MAX}\n200,RSA,1,8",
    "BRK relative": f"100,BRK,100,3,{S_MAX}\n200,RSA,1,8",
    "BRK tiny": "100,BRK,0,1,0.000000001\n200,BRK,100,0,0.000001",
    "RSA": "100,RSA,1,1000,-1,0,101,1000,-101,0," + "9" * MAX_NUMBER_CHARS + ",5\n300,RSA,1,0\n500,RSA,1,0.0001",
    "ROAD widest": f"0,ROAD,328,{MAX_LANES},{MAX_LANES // 2}\n100,RSA,1,3,100,1,-100,5",
    "ROAD narrowest": f"0,ROAD,0.000001,{MAX_LANES},{MAX_LANES // 2}\n100,RSA,1,3,-999,1,101,2",
    "ROAD one side": "0,ROAD,12,100,100\n100,RSA,1,3,100,1,-1,5,-101,2",
    "ROAD many lanes": f"0,ROAD,12,{MAX_LANES},{MAX_LANES // 2}\n100,A,20,1000,*0,*1~10,5,*12,20,2",
    "long digit strings": f"{'0' * (MAX_NUMBER_CHARS - 3)}100,BRK,{'0' * (MAX_NUMBER_CHARS - 3)}100,"
                          f"{'0' * (MAX_NUMBER_CHARS - 1)}0,{'3.' + '0' * (MAX_NUMBER_CHARS - 2)}",
    "long RSA line": f"0,ROAD,12,{MAX_LANES},{MAX_LANES // 2}\n100,RSA," + ",".join(  # every lane and shoulder
        f"{lane},{lane % 9}" for lane in [*range(1, 101), *range(-1, -101, -1), 101, -101]),
}


METRIC_EXTREMES = ("distance", "A max", "A action extremes", "BRK distance", "ROAD widest")


def _metric(text: str) -> str:
    # the same cases in m and m/s at the Metric limits (1e6 m, 1000 m/s, 100 m lanes)
    return text.replace(L_MAX, "1000000").replace(S_MAX, "1000").replace("328,", "100,")


@pytest.mark.slow  # 27 whole runs of up to 600 s with their plots
def test_extreme_legal_values_run_and_plot(tmp_path, simple_fmu):
    assert EXTREMES["long RSA line"].split("\n")[1].count(",") - 1 == MAX_PARAMETERS  # the most a line may hold
    cases = [(f"English {name}", f"English\n{text}\n", ["--until-time", "600"]) for name, text in EXTREMES.items()]
    cases += [(f"Metric {name}", f"Metric\n{_metric(EXTREMES[name])}\n", ["--until-time", "600"])
              for name in METRIC_EXTREMES]

    def check(name, result, path, out):
        summary = assert_correct_run(result, out)
        assert summary["units"] == name.split()[0]

    assert failures(cases, run_batch(tmp_path, simple_fmu, cases), check) == []


def test_extreme_rsa_with_advanced_dynamics_runs(tmp_path, advanced_fmu):
    result, _, out = run_case(tmp_path, advanced_fmu, "English\n100,RSA,1,1000,-1,0\n400,ES\n",
                              extra=["--dynamics", "advanced"])
    summary = assert_correct_run(result, out)
    assert any("1000" in warning for warning in summary["warnings"])


# --- generated: just beyond a limit, too many characters, non-ASCII digits: refused, naming the field ----------

FIELDS = {  # field name -> (a good line, the index of the field in it, a value just beyond its limit)
    "distance": ("100,ES", 0, L_OVER),
    "A parameter 1 (speed)": ("100,A,20,1000,-6,1,5,6,20,2", 2, S_OVER),
    "A parameter 2 (gap)": ("100,A,20,1000,-6,1,5,6,20,2", 3, L_OVER),
    "A parameter 3 (lateral position)": ("100,A,20,1000,-6,1,5,6,20,2", 4, "*-" + L_OVER),
    "A parameter 4 (model)": ("100,A,20,1000,-6,1,5,6,20,2", 5, str(UNKNOWN_MODEL)),
    "A parameter 5 (action 1 closure time)": ("100,A,20,1000,-6,1,5,6,20,2", 6, "-" + T_OVER + "F"),
    "A parameter 6 (action 1 lateral position)": ("100,A,20,1000,-6,1,5,6,20,2", 7, L_OVER),
    "A parameter 7 (action 1 speed)": ("100,A,20,1000,-6,1,5,6,20,2", 8, "*" + S_OVER),
    "A parameter 8 (action 1 transition time)": ("100,A,20,1000,-6,1,5,6,20,2", 9, T_OVER),
    "BRK parameter 1 (pedal %)": ("100,BRK,50,0,3", 2, "100.001"),
    "BRK parameter 2 (threshold type)": ("100,BRK,50,0,3", 3, "4"),
    "BRK parameter 3 (magnitude)": ("100,BRK,50,0,3", 4, T_OVER),
    "RSA parameter 1 (lane)": ("100,RSA,1,8", 2, "1.0"),
    "RSA parameter 2 (value)": ("100,RSA,1,8", 3, "1000.001"),
    "ROAD parameter 1 (lane width)": ("0,ROAD,12,2,1", 2, "329"),
    "ROAD parameter 2 (lanes)": ("0,ROAD,12,2,1", 3, str(MAX_LANES + 1)),
    "ROAD parameter 3 (lanes right of the dividing line)": ("0,ROAD,12,2,1", 4, "3"),
}
NON_ASCII_DIGITS = {"fullwidth": "\uff11\uff10", "arabic-indic": "\u0661\u0660", "devanagari": "\u0967\u0966",
                    "superscript": "\u00b9\u2070", "mathematical": "\U0001d7cf\U0001d7ce"}


def _with(line: str, index: int, value: str) -> str:
    fields = line.split(",")
    fields[index] = value
    return ",".join(fields)


BAD = [(field, over) for field, (_, _, over) in FIELDS.items()]
BAD += [(field, "1" * (MAX_NUMBER_CHARS + 1)) for field in FIELDS]
BAD += [(field, NON_ASCII_DIGITS["fullwidth"]) for field in FIELDS]
BAD += [("distance", digits) for digits in NON_ASCII_DIGITS.values()]
BAD += [("BRK parameter 3 (magnitude)", "1" + digits) for digits in NON_ASCII_DIGITS.values()]


def test_a_bad_numeric_field_is_refused_naming_it(tmp_path, simple_fmu):
    cases = [(f"{field} = {value!r}",
              "English\n// generated\n" + _with(FIELDS[field][0], FIELDS[field][1], value) + "\n", [])
             for field, value in BAD]
    assert len(cases) == 3 * len(FIELDS) + 2 * len(NON_ASCII_DIGITS)

    def check(name, result, path, out):
        assert_refused(result, path, out, 3, name.split(" = ")[0])

    assert failures(cases, run_batch(tmp_path, simple_fmu, cases), check) == []


@pytest.mark.parametrize("case", ["too many parameters", "too many lanes", "bad long code"])
def test_long_lines_are_refused_in_one_short_line(tmp_path, simple_fmu, case):
    text, field = {
        "too many parameters": ("100,RSA," + ",".join(["1", "8"] * (MAX_PARAMETERS // 2 + 1)), "RSA parameters"),
        "too many lanes": ("0,ROAD,12," + str(10**30) + ",1", "ROAD parameter 2 (lanes)"),
        "bad long code": ("100," + "Sign" * 250_000 + "!,1,2", "event code"),
    }[case]
    result, path, out = run_case(tmp_path, simple_fmu, f"English\n{text}\n")
    assert_refused(result, path, out, 2, field)


def test_a_5mb_unsupported_line_is_skipped_or_refused(tmp_path, simple_fmu):
    text = "English\n100,Play Recording," + ",".join(["C:\\STISIM3\\Sound\\Long.wav"] * 200_000) + "\n200,ES\n"
    result, path, out = run_case(tmp_path, simple_fmu, text)
    assert "--skip-unsupported" in assert_refused(result, path, out, 2, "event code")
    result, path, out = run_case(tmp_path, simple_fmu, text, extra=["--skip-unsupported"])
    assert_correct_run(result, out)


def test_many_bad_lines_stop_after_a_bounded_report(tmp_path, simple_fmu):
    # 300 000 bad lines: the report stops after MAX_ERRORS problems instead of growing with the file
    from sdl_fmu.sdl.parser import MAX_ERRORS

    result, path, out = run_case(tmp_path, simple_fmu, "English\n" + "10,BRK,x,0,1\n" * 300_000)
    assert result.returncode == 1 and "Traceback" not in result.stderr and not out.exists()
    lines = result.stderr.splitlines()
    assert len(lines) == MAX_ERRORS + 1 and lines[-1].endswith(f"stopped reading after {MAX_ERRORS} problems")


def test_the_plot_draws_the_same_road_however_many_lanes_nothing_uses(simple_fmu):
    # The cost of the road view follows what is drawn: with the ego in lane 1 and no other traffic, a road of
    # 20, 100 or 200 lanes shows the same lanes near the path, so the same artists with the same segments.
    import dataclasses

    from matplotlib.figure import Figure

    from sdl_fmu import api
    from sdl_fmu.results import plots
    from sdl_fmu.sdl import Road

    raw = api.run(api.load("brake_examples"), fmu=simple_fmu, until_time=2.0, plot=False).raw
    drawn = []
    for lanes in (20, 100, MAX_LANES):
        result = dataclasses.replace(raw, road=Road(0, 0.0, raw.road.lane_width, lanes, lanes // 2))
        ax = Figure().add_subplot()
        plots._draw_road(ax, result, 0.0, 200.0, plots._lateral_limits(result))
        segments = sum(len(c.get_segments()) for c in ax.collections if hasattr(c, "get_segments"))
        drawn.append((len(ax.lines), len(ax.patches), len(ax.collections), segments))
    assert drawn[0] == drawn[1] == drawn[2]
    assert drawn[0][3] <= 2 * plots.NEAR_LANES + 2  # the lane lines within NEAR_LANES of the path, no more


# --- the number of traffic vehicles --------------------------------------------------------------------------

REPRODUCER_CAP = 1_500_000_000  # bytes of address space: the reproducer once reached 1.07 GB and failed in the plot


def _vehicle_lines(count: int, distance: str = "{k}") -> str:
    """`count` A lines of 22 bytes or so (oncoming, 2000 ft ahead, the eight vehicle models in turn)."""
    return "English\n" + "".join(f"{distance.format(k=k + 1)},A,50,2000,-6,{1 + k % 8}\n" for k in range(count))


def _reproducer_cap():
    resource.setrlimit(resource.RLIMIT_AS, (REPRODUCER_CAP, REPRODUCER_CAP))


def test_a_10_mib_scenario_of_a_lines_is_refused_up_front_in_one_line(tmp_path, simple_fmu):
    # The reproducer: 459 811 A lines, just under the 10 MiB file limit, passed `check`; `run --until-time 2`
    # took minutes, reached 1.07 GB and ended in a traceback in the plot. Now the A line beyond MAX_VEHICLES is an
    # error naming the file, its line and the limit, before any FMU is loaded: under a 1.5 GB address-space cap the
    # run exits 1 with that one line and writes nothing; `check` gives the same line.
    from sdl_fmu.sdl.parser import MAX_FILE_SIZE, MAX_VEHICLES

    text = _vehicle_lines(459_811)
    assert MAX_FILE_SIZE - 2**20 < len(text.encode()) <= MAX_FILE_SIZE  # within the size limit
    path, out = tmp_path / "vehicles.sdl", tmp_path / "out"
    path.write_text(text)
    limit = f"{path}:{MAX_VEHICLES + 2}: A: more than {MAX_VEHICLES} A events (traffic vehicles) in one scenario"
    for command in (["run", path, "--until-time", "2", "--out", out, "--fmu", simple_fmu], ["check", path]):
        result = helpers.sdl_fmu(*command, cwd=tmp_path, timeout=HANG_LIMIT, preexec_fn=_reproducer_cap)
        assert assert_refused(result, path, out, MAX_VEHICLES + 2, "A").startswith(limit)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["vehicles.sdl"]


def test_the_vehicle_limit_counts_a_lines_only():
    from sdl_fmu.sdl import ScenarioError, parse_text
    from sdl_fmu.sdl.parser import MAX_VEHICLES

    at_limit = _vehicle_lines(MAX_VEHICLES) + "".join(f"{k},BRK,5,0,0.1\n" for k in range(1, 100))
    assert sum(event.code == "A" for event in parse_text(at_limit).events) == MAX_VEHICLES
    with pytest.raises(ScenarioError) as caught:
        parse_text(_vehicle_lines(MAX_VEHICLES + 1), "x.sdl")
    assert [str(error) for error in caught.value.errors] == [
        f"x.sdl:{MAX_VEHICLES + 2}: A: more than {MAX_VEHICLES} A events (traffic vehicles) in one scenario; the "
        f"format allows at most {MAX_VEHICLES}: reading stopped"]


@pytest.mark.slow  # one run of 20 000 vehicles with its plot: about 15 s of CPU time
def test_the_most_vehicles_all_at_once_run_and_plot_within_the_memory_cap(tmp_path, simple_fmu):
    # The worst placement of the most vehicles the format allows: every one spawns at the start, so all are on the
    # road for the whole run (the traffic samples, traffic.csv and the plot's paths all at their largest per
    # second). Under the 1 GiB cap of this file's runs it runs and plots (measured: about 0.15 GB of RSS).
    from sdl_fmu.sdl.parser import MAX_VEHICLES

    result, _, out = run_case(tmp_path, simple_fmu, _vehicle_lines(MAX_VEHICLES, distance="0"),
                              extra=["--until-time", "0.5"])
    summary = assert_correct_run(result, out)
    assert sum(event["action"] == "spawn" for event in summary["events"]) == MAX_VEHICLES
