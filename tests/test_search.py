"""The worst-case search (sdl_fmu/search.py): its grammar, its objectives against hand computations, real searches on
an in-process Dask cluster (the Simple FMU of the cache), the worst case reproduced from worst.sdl by `sdl-fmu run`,
and resume: no finished trial is ever run again."""

import json

import numpy as np
import pytest

from helpers import local_cluster, sdl_fmu
from sdl_fmu import api
from sdl_fmu import search as searching

distributed = pytest.importorskip("distributed")
pytestmark = pytest.mark.usefixtures("simple_fmus")

# A stopped car (the Euro NCAP target, model 11) 60 m ahead in the ego's lane: the lane driver holds its speed and
# ignores it, so the ego hits it at about its start speed; the run ends at the contact (--on-collision stop).
STOPPED = "Metric\n0,A,0,60,*0,11\n400,ES\n"
# The same target moving the ego's way at 5 m/s (an A speed of -5 m/s).
MOVING = "Metric\n0,A,-5,60,*0,11\n800,ES\n"
FIXED = {"on_collision": "stop", "until_time": 60.0}


@pytest.fixture(scope="module")
def client():
    with local_cluster(2) as cluster, distributed.Client(cluster) as client:
        yield client


@pytest.fixture
def stopped(tmp_path):
    path = tmp_path / "stopped.sdl"
    path.write_text(STOPPED)
    return str(path)


def journal(out):
    return [json.loads(line) for line in (out / searching.JOURNAL_NAME).read_text().splitlines()]


def test_ranges_objectives_and_their_refusals():
    ranges = searching.parse_ranges(["speed=10..20", "seed=1..9", "mass = 1200..1800"])
    assert ranges["speed"] == searching.Range("speed", 10.0, 20.0) and ranges["seed"].integer
    assert ranges["mass"].value(0.5) == 1500.0 and ranges["seed"].value(1.0) == 9
    for bad in ("speed=20..10", "speed=1,2", "speed=..3", "speed=nan..3", "seed=0.5..3", "speed=", "9x"):
        with pytest.raises(searching.SearchError):
            searching.parse_ranges([bad])
    with pytest.raises(searching.SearchError, match="given twice"):
        searching.parse_ranges(["speed=1..2", "speed=3..4"])
    for good in ("min_ttc_s", "min_distance", "min_distance_ft", "A2_min_distance_m", "impact_speed", "collisions",
                 "max_drac", "brk1_stop_distance", "final.speed", "criticality.min_pet_s"):
        assert searching.objective_of(good, None, None).direction == "minimize"
    for bad in ("speed_of_light", "A1_nothing", "final"):
        with pytest.raises(searching.SearchError, match="not a measure"):
            searching.objective_of(None, bad, None)
    with pytest.raises(searching.SearchError, match="one objective"):
        searching.objective_of("min_ttc_s", "collisions", None)
    spec = searching.objective_of(None, None, "always (A1_bumper_gap_m > 2.0)")
    assert (spec.kind, spec.direction) == ("spec", "minimize")
    assert searching.spec_variables("eventually[0:2] (speed_m_s < 3 and not brk_active > 0)") == [
        "brk_active", "speed_m_s"]
    with pytest.raises(searching.SearchError, match="--spec"):
        searching.objective_of(None, None, "always (gap >")
    assert searching.identifier("speed_m/s") == "speed_m_s" and searching.identifier("ax_m/s2") == "ax_m_s2"


def test_robustness_is_the_formulas_margin_by_hand():
    # dense time, the samples joined linearly: `always (g > 2)` at the start is min(g) - 2 and `eventually (g > 2)`
    # max(g) - 2 (a linear piece takes its extremes at its ends); a sample where g is not a number is left out, and
    # of two samples at one instant the last counts
    arrays = {"time_s": np.array([0.0, 1.0, 2.0, 2.0, 3.0, 4.0]),
              "A1_gap_m": np.array([9.0, 4.0, 7.0, 2.5, np.nan, 6.0])}
    assert searching.robustness("always (A1_gap_m > 2)", arrays) == 2.5 - 2
    assert searching.robustness("eventually (A1_gap_m > 2)", arrays) == 9.0 - 2
    # within [0, 1.5]: the samples at 0 and 1 and the linear piece to 2 (7 at t = 2): min 4 at t = 1
    assert searching.robustness("always[0:1.5] (A1_gap_m > 2)", arrays) == pytest.approx(4.0 - 2, abs=1e-12)
    with pytest.raises(searching.ObjectiveError, match="no column speed_m_s"):
        searching.robustness("always (speed_m_s > 1)", arrays)


def test_impact_speeds_are_the_contacts_by_hand(tmp_path, client):
    # the ego at 15 m/s onto a target moving its way at 5 m/s: the relative impact speed is the ego's speed at the
    # contact (the collision event's) minus 5 exactly (the target's speed never changes)
    (tmp_path / "moving.sdl").write_text(MOVING)
    out = tmp_path / "search"
    found = searching.search(str(tmp_path / "moving.sdl"), searching.parse_ranges(["speed=15..15"]), out,
                             objective=searching.objective_of(None, "impact_speed", None), budget=1, client=client,
                             progress=False, **FIXED)
    row = found.rows[0]
    summary = json.loads((out / "worst" / "summary.json").read_text())
    contact = next(e for e in summary["events"] if e["action"] == "collision")
    # summary.json writes 6 decimals, and the objective is the measure as summary.json gives it
    assert round(row["impact_speed_m/s"], 6) == contact["speed"] == row["objective"]
    assert row["relative_impact_speed_m/s"] == pytest.approx(row["impact_speed_m/s"] - 5.0, abs=1e-12)
    assert abs(contact["speed"] - 15.0) < 1e-6  # the lane driver holds 15 m/s against drag


def test_a_search_finds_its_worst_case_and_worst_sdl_reproduces_it(stopped, tmp_path, client):
    out = tmp_path / "search"
    objective = searching.objective_of(None, "impact_speed", None)
    found = searching.search(stopped, searching.parse_ranges(["speed=8..20", "brake_decel_max=6..10"]), out,
                             objective=objective, budget=6, seed=3, client=client, progress=False, **FIXED)
    rows = found.rows
    assert [row["trial"] for row in rows] == list(range(6)) and all(row["status"] == "ok" for row in rows)
    # two worker threads: four trials proposed at once (one running and one queued per thread), then one more as each
    # comes back
    assert [row["round"] for row in rows] == [0, 0, 0, 0, 1, 2]
    for row in rows:
        assert 8.0 <= row["speed_m/s"] <= 20.0 and 6.0 <= row["brake_decel_max_m/s2"] <= 10.0
        assert row["objective"] == round(row["impact_speed_m/s"], 6) and row["collisions"] == 1
    best = max(row["objective"] for row in rows)
    assert found.worst["objective"] == best and rows[-1]["best_so_far"] == best
    assert found.reproduced is True
    for name in ("search.parquet", "search.csv", "search.png", "report.html", "worst.sdl", "search.json"):
        assert (out / name).is_file(), name
    report = (out / "report.html").read_text()
    assert report.count("data:image/png;base64,") == 2 and f"trial {found.worst['trial']}" in report
    # `sdl-fmu run worst.sdl` with the options search.json gives: the same objective, to the bit
    command = json.loads((out / "search.json").read_text())["worst"]["command"]
    assert command[:3] == ["sdl-fmu", "run", str(out / "worst.sdl")] and "--speed" in command
    command[command.index("--out") + 1] = str(tmp_path / "again")
    ran = sdl_fmu(*command[1:], cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    summary = json.loads((tmp_path / "again" / "summary.json").read_text())
    contact = next(e for e in summary["events"] if e["action"] == "collision")
    assert contact["speed"] == found.worst["objective"]
    import pyarrow.parquet as pq

    table = pq.read_table(out / "search.parquet").to_pylist()
    assert [row["objective"] for row in table] == [row["objective"] for row in rows]
    assert list(table[0])[:8] == ["trial", "round", "speed_m/s", "brake_decel_max_m/s2", "status", "error",
                                  "objective", "best_so_far"]


@pytest.mark.parametrize("method", ["tpe", "random", "cmaes"])
def test_a_resumed_search_never_runs_a_finished_trial_again(stopped, tmp_path, client, method):
    """A journal cut as an interruption leaves it (a finished trial's line lost, a line cut short): the resumed search
    runs that trial again with its recorded values and keeps every other finished one as it was (its wall time
    too); a larger budget then continues it, each trial once in the journal."""
    out = tmp_path / "search"
    ranges = searching.parse_ranges(["speed=8..20", "brake_decel_max=6..10"])
    objective = searching.objective_of(None, "impact_speed", None)

    def go(budget):
        return searching.search(stopped, ranges, out, objective=objective, budget=budget, method=method, seed=1,
                                client=client, progress=False, report=False, **FIXED).rows

    first = go(4)
    lines = (out / searching.JOURNAL_NAME).read_text().splitlines()
    lost = next(k for k in range(len(lines) - 1, -1, -1) if json.loads(lines[k])["kind"] == "trial")
    lost_trial = json.loads(lines[lost])["trial"]
    (out / searching.JOURNAL_NAME).write_text("\n".join(lines[:lost] + lines[lost + 1:]) + '\n{"kind": "tri')
    # the journal is appended to after the manifest recorded its start: a cut within it is what an interruption
    # leaves; here the whole file was rewritten, which the manifest would refuse, so its entry is made afresh
    searching._write_manifest(out, {searching.JOURNAL_NAME: out / searching.JOURNAL_NAME})
    again = go(4)
    for before, after in zip(first, again):
        if before["trial"] == lost_trial:
            assert after["speed_m/s"] == before["speed_m/s"] and after["run_wall_s"] != before["run_wall_s"]
        else:
            assert after == before
    more = go(7)
    assert more[:4] == again and [row["trial"] for row in more] == list(range(7))
    trials = [record["trial"] for record in journal(out) if record["kind"] == "trial"]
    assert sorted(trials) == list(range(7))


def test_a_spec_is_minimised_and_its_robustness_is_the_columns_margin(stopped, tmp_path, client):
    # `always (A1_bumper_gap_m > 0.5)`: the ego drives into the target, so the bumper gap falls to 0 at the contact
    # and the robustness is 0 - 0.5 whatever the speed
    out = tmp_path / "search"
    found = searching.search(stopped, searching.parse_ranges(["speed=10..20"]), out,
                             objective=searching.objective_of(None, None, "always (A1_bumper_gap_m > 0.5)"),
                             budget=2, client=client, progress=False, **FIXED)
    timeseries = np.genfromtxt(out / "worst" / "timeseries.csv", delimiter=",", names=True)
    gaps = timeseries["A1_bumper_gap_m"]
    assert found.worst["objective"] == float(np.nanmin(gaps)) - 0.5
    assert all(row["objective"] == pytest.approx(-0.5, abs=1e-9) for row in found.rows)


def test_mistakes_are_one_line_before_anything_runs(stopped, tmp_path):
    for arguments, needle in [
            (["--vary", "speed=20..10", "--maximize", "impact_speed"], "--vary speed=20..10"),
            (["--vary", "speed=10..20", "--maximize", "speed_of_light"], "--maximize speed_of_light: not a measure"),
            (["--vary", "speed=10..20", "--spec", "always (x >"], "--spec"),
            (["--vary", "no_such_parameter=1..2", "--maximize", "impact_speed"], "--vary no_such_parameter"),
            (["--vary", "brake_decel_max=-5..2", "--maximize", "impact_speed"], "--vary brake_decel_max"),
            (["--vary", "speed=10..20", "--maximize", "impact_speed", "--budget", "0"], "--budget 0")]:
        if "--budget" not in arguments:
            arguments = [*arguments, "--budget", "3"]
        ran = sdl_fmu("search", stopped, *arguments, "--workers", "1", "--out", tmp_path / "out", cwd=tmp_path)
        lines = ran.stderr.splitlines()
        assert ran.returncode == 2 and len(lines) == 1 and needle in lines[0], ran.stderr
        assert not (tmp_path / "out").exists()
    # a folder of another command is refused, and a folder holding a different search
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("mine")
    ran = sdl_fmu("search", stopped, "--vary", "speed=10..20", "--maximize", "impact_speed", "--budget", "1",
                  "--workers", "1", "--out", tmp_path / "mine", cwd=tmp_path)
    assert ran.returncode == 2 and "holds files a search did not write" in ran.stderr
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["notes.txt"]


def test_scenario_parameters_vary_by_name_with_their_declared_ranges(tmp_path, client):
    # the stopped target's gap declared with a range and varied alone (`--vary gap`): each trial's gap is in the
    # declared range, and worst.sdl is the plain text with the worst trial's gap written in, which api.run runs to
    # the same objective
    path = tmp_path / "gap.sdl"
    path.write_text("Metric\n// @param gap = 60 m in 30..90\n0,A,0,$gap,*0,11\n400,ES\n")
    out = tmp_path / "search"
    found = searching.search(str(path), searching.parse_ranges(["gap", "speed=12..12"]), out,
                             objective=searching.objective_of("final_time_s", None, None), budget=4, client=client,
                             progress=False, **FIXED)
    assert all(30.0 <= row["gap"] <= 90.0 for row in found.rows)
    gap = found.values["gap"]
    text = (out / "worst.sdl").read_text()
    assert "$gap" not in text and f"0,A,0,{gap!r},*0,11" in text.replace(f"{gap:.17g}", repr(gap))
    result = api.run(str(out / "worst.sdl"), speed=12.0, **FIXED)
    assert round(result.final["time_s"], 6) == found.worst["objective"] == min(r["objective"] for r in found.rows)
    with pytest.raises(searching.SearchError, match="declares no range"):
        path.write_text("Metric\n// @param gap = 60 m\n0,A,0,$gap,*0,11\n400,ES\n")
        searching.search(str(path), searching.parse_ranges(["gap"]), tmp_path / "other",
                         objective=searching.objective_of("final_time_s", None, None), budget=1, client=client,
                         progress=False, **FIXED)
    with pytest.raises(searching.SearchError, match="--vary gap=10..90"):
        path.write_text("Metric\n// @param gap = 60 m in 30..90\n0,A,0,$gap,*0,11\n400,ES\n")
        searching.search(str(path), searching.parse_ranges(["gap=10..90"]), tmp_path / "other",
                         objective=searching.objective_of("final_time_s", None, None), budget=1, client=client,
                         progress=False, **FIXED)
    assert not (tmp_path / "other").exists()


@pytest.mark.slow  # a search started and interrupted, then resumed, as commands (a Dask cluster each)
@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
def test_an_interrupted_search_resumes_without_running_a_finished_trial_again(tmp_path, how):
    """One worker, held at its third run (the hold file's number: sdl_fmu/hold.py) and interrupted there once trials
    0 and 1 are journaled; the same command then resumes, keeps them as they were (their wall times too) and runs
    only trials 2 to 4."""
    from hostile_fmus import assert_clean, capped, environment, held_work, interrupted

    work = held_work(tmp_path)
    (work / "hold").write_text("3")
    (work / "work" / "stopped.sdl").write_text(STOPPED)
    out = work / "work" / "search"
    command = ["search", "stopped.sdl", "--vary", "speed=8..20", "--maximize", "impact_speed", "--budget", "5",
               "--workers", "1", "--on-collision", "stop", "--out", out]
    def two_finished():
        path = out / searching.JOURNAL_NAME
        return path.exists() and path.read_text().count('"kind": "trial"') == 2

    code, stdout, stderr = interrupted(work, command, how, ready=two_finished)
    what = {"ctrl-c": (130, "interrupted (Ctrl-C)"), "sigterm": (143, "terminated (SIGTERM)")}[how]
    assert (code, stderr.splitlines()) == (what[0], [
        f"sdl-fmu: search {what[1]}; the finished trials are in {out / 'search-trials.jsonl'}: the same command "
        "resumes the search"]), stderr
    assert_clean(work)
    before = {r["trial"]: r for r in journal(out) if r["kind"] == "trial"}
    assert sorted(before) == [0, 1]
    resumed = capped(*command, cwd=work / "work", env=environment(work))
    assert resumed.returncode == 0, resumed.stderr
    assert "5 trials (5 ok)" in resumed.stdout
    after = [r for r in journal(out) if r["kind"] == "trial"]
    assert sorted(r["trial"] for r in after) == [0, 1, 2, 3, 4]  # each once: none run again
    for record in after:
        if record["trial"] in before:
            assert record == before[record["trial"]]
    assert_clean(work)


def test_a_spec_naming_no_column_stops_the_search_and_leaves_nothing(stopped, tmp_path, client):
    # the columns are known once a run has them: the first round's runs say so, and the search stops there
    out = tmp_path / "search"
    with pytest.raises(searching.SearchError, match="timeseries.csv has no column A2_gap_m"):
        searching.search(stopped, searching.parse_ranges(["speed=10..20"]), out,
                         objective=searching.objective_of(None, None, "always (A2_gap_m > 1)"), budget=4,
                         client=client, progress=False, **FIXED)
    assert not out.exists()
