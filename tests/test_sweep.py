"""Sweeps on Dask: every combination a row, a failing and a timed-out run as rows with their error,
resume from the journal, value grammar. An in-process LocalCluster runs the real Simple FMU."""

import json

import pytest

from sdl_fmu import api
from sdl_fmu import sweep as sweeping

distributed = pytest.importorskip("distributed")

# One oncoming vehicle passing 12 ft to the ego's left, no collision; the run ends at --until-distance.
SCENARIO = "English\n100,A,50,600,-6,1\n"


@pytest.fixture(scope="module")
def cluster():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                       dashboard_address=None)
    yield cluster
    cluster.close()


@pytest.fixture(scope="module")
def client(cluster):
    with distributed.Client(cluster) as client:
        yield client


@pytest.fixture
def scenario(tmp_path):
    path = tmp_path / "pass.sdl"
    path.write_text(SCENARIO)
    return str(path)


def test_value_grammar():
    rng = __import__("random").Random(0)
    assert sweeping.parse_values("speed", "60,70.5,80", rng) == [60.0, 70.5, 80.0]
    assert sweeping.parse_values("speed", "40:60:10", rng) == [40.0, 50.0, 60.0]
    assert sweeping.parse_values("seed", "1:3:1", rng) == [1, 2, 3]
    first = sweeping.parse_vary(["mu=uniform(0.2,0.8,4)", "seed=integers(1,9,3)"], sample_seed=5)
    again = sweeping.parse_vary(["mu=uniform(0.2,0.8,4)", "seed=integers(1,9,3)"], sample_seed=5)
    assert first == again and len(first["mu"]) == 4 and all(0.2 <= v <= 0.8 for v in first["mu"])
    assert len(sweeping.combinations(first)) == 12
    for bad in ("speed=", "speed=1:0:1", "speed=a,b", "seed=1.5", "speed=uniform(1,0,3)"):
        with pytest.raises(sweeping.SweepError):
            sweeping.parse_vary([bad])


def journal_rows(out):
    return [json.loads(line) for line in (out / sweeping.JOURNAL_NAME).read_text().splitlines()]


def test_failed_runs_are_rows_and_a_resume_runs_only_them_again(client, scenario, tmp_path):
    # 2 x 2 runs: brake_decel_max -1 is below the FMU's declared minimum (refused before the run: failed)
    out = tmp_path / "sweep"
    varied = {"until_distance": [200.0, 300.0], "brake_decel_max": [9.81, -1.0]}
    rows = sweeping.sweep(scenario, varied, out, client=client, progress=False)
    status = {(r["until_distance_ft"], r["brake_decel_max_m/s2"]): r["status"] for r in rows}
    assert status == {(200.0, 9.81): "ok", (200.0, -1.0): "failed", (300.0, 9.81): "ok", (300.0, -1.0): "failed"}
    failed = [r for r in rows if r["status"] == "failed"]
    assert all("brake_decel_max" in r["error"] for r in failed)
    for row in rows:
        if row["status"] == "ok":
            assert row["collisions"] == 0
            assert row["final_distance_ft"] == pytest.approx(row["until_distance_ft"], abs=1e-3)
    assert sweeping.failure_line(rows, out / "sweep.csv") == f"2 of 4 runs failed ({out / 'sweep.csv'}, column error)"

    # resume: the ok rows are kept as they were, the failed ones are run again (and fail again)
    again = sweeping.sweep(scenario, varied, out, client=client, progress=False)
    assert [r["status"] for r in again] == [r["status"] for r in rows]
    for before, after in zip(rows, again):
        if before["status"] == "ok":
            assert after == before  # not run again: the very same row, wall time included
    journal = journal_rows(out)  # the earlier failed rows were dropped from it, the new ones appended
    assert sorted((r["run"], r["status"]) for r in journal) == [(0, "ok"), (1, "failed"), (2, "ok"), (3, "failed")]
    assert [r["run"] for r in journal[2:]] in ([1, 3], [3, 1])


def test_every_column_with_a_unit_names_it(client, tmp_path):
    # English: lengths in ft, speeds in ft/s; Metric: m, m/s; FMU parameters carry their declared unit; a BRK
    # that stops the car gives its on/off times and distances
    (tmp_path / "metric.sdl").write_text("Metric\n0,A,15,200,-3,1\n10,BRK,100,0,20\n")
    out = tmp_path / "sweep"
    rows = sweeping.sweep(str(tmp_path / "metric.sdl"), {"speed": [20.0], "mass": [1500.0, 1800.0],
                                                         "until_time": [12.0]}, out, client=client, progress=False)
    assert [r["status"] for r in rows] == ["ok", "ok"], rows
    import pyarrow.parquet as pq

    columns = pq.read_table(out / sweeping.TABLE_NAME).column_names
    assert columns[:6] == ["run", "speed_m/s", "mass_kg", "until_time_s", "status", "error"]
    expected = {"collisions", "final_time_s", "final_distance_m", "final_speed_m/s", "final_lateral_m", "sim_wall_s",
                "real_time_factor", "run_wall_s", "warnings", "brk1_on_time_s", "brk1_off_time_s", "brk1_reason",
                "brk1_distance_m", "brk1_stop_distance_m", "A1_min_gap_m"}
    assert set(columns[6:]) == expected
    assert (out / sweeping.CSV_NAME).read_text().splitlines()[0].split(",")[:3] == ['"run"', '"speed_m/s"', '"mass_kg"']
    # only mass takes more than one value: the plot has one row of panels, against mass, in kg
    assert sweeping.plotted_quantities(rows, ["speed_m/s", "mass_kg", "until_time_s"]) == ["mass_kg"]
    assert sweeping._axis_label("mass_kg") == "mass (kg)" and sweeping._axis_label("speed_ft/s") == "speed (ft/s)"
    assert sweeping._axis_label("brake_decel_max_m/s2") == "brake_decel_max (m/s2)"
    assert sweeping._axis_label("seed") == "seed" and sweeping._axis_label("rsa.3") == "rsa.3"


def test_the_plot_has_a_row_of_panels_per_quantity_that_varies(client, scenario, tmp_path):
    from PIL import Image

    out = tmp_path / "sweep"
    varied = {"until_distance": [200.0], "speed": [60.0, 80.0], "seed": [1, 2]}
    rows = sweeping.sweep(scenario, varied, out, client=client, progress=False)
    assert sweeping.plotted_quantities(rows, ["until_distance_ft", "speed_ft/s", "seed"]) == ["speed_ft/s", "seed"]
    # 0.8 in of title and 3 in per row of panels, at 100 dpi
    assert Image.open(out / sweeping.PLOT_NAME).size == (1200, 680)


def test_a_run_held_past_its_timeout_is_a_timeout_row_and_runs_again_on_resume(client, scenario, tmp_path,
                                                                               monkeypatch):
    # Every run is held at its first step (the api's test hook) until the hold file goes: it can only end by
    # its own wall-clock deadline, however fast the machine is.
    hold = tmp_path / "hold"
    hold.touch()
    monkeypatch.setenv(api.HOLD_VARIABLE, str(hold))
    out = tmp_path / "sweep"
    varied = {"until_distance": [200.0], "speed": [60.0, 80.0]}
    rows = sweeping.sweep(scenario, varied, out, client=client, timeout=0.5, progress=False)
    assert [r["status"] for r in rows] == ["timeout", "timeout"]
    assert all("time limit of 0.5 s" in r["error"] and r["run_wall_s"] >= 0.5 for r in rows)
    assert len((tmp_path / "hold.running").read_text().splitlines()) == 2  # both runs were held
    assert sweeping.failure_line(rows, out / "sweep.csv") == (
        f"all 2 runs timed out ({out / 'sweep.csv'}, column error); run 0: {rows[0]['error']}")
    hold.unlink()  # released: the resumed sweep runs the timed-out rows again, and they end
    again = sweeping.sweep(scenario, varied, out, client=client, timeout=0.5 + 600, progress=False)
    assert [r["status"] for r in again] == ["ok", "ok"]
    assert sweeping.failure_line(again, out / "sweep.csv") is None


def test_the_command_line_exits_3_with_one_line_when_runs_failed(cluster, scenario, tmp_path, capsys):
    from sdl_fmu.cli import EXIT_RUNS_FAILED, main

    common = ["sweep", scenario, "--scheduler", cluster.scheduler_address, "--vary", "until_distance=200"]
    code = main([*common, "--vary", "brake_decel_max=9.81,-1", "--out", str(tmp_path / "some")])
    out, err = capsys.readouterr()
    assert code == EXIT_RUNS_FAILED == 3
    assert err.splitlines() == [f"sdl-fmu: 1 of 2 runs failed ({tmp_path / 'some' / 'sweep.csv'}, column error); "
                                "the same command runs them again"]
    assert out.splitlines()[0] == "pass.sdl: 2 runs: 1 ok, 1 failed, 0 timed out"
    code = main([*common, "--vary", "brake_decel_max=-1,-2", "--out", str(tmp_path / "none")])
    out, err = capsys.readouterr()
    assert code == 3 and out == ""
    assert err.splitlines() == [f"sdl-fmu: all 2 runs failed ({tmp_path / 'none' / 'sweep.csv'}, column error); "
                                "run 0: --param brake_decel_max=-1.0: below the declared minimum 0 m/s2 of "
                                "brake_decel_max"]
    assert main([*common, "--vary", "speed=60,80", "--out", str(tmp_path / "fine")]) == 0
    assert capsys.readouterr().err == ""


def test_interrupted_sweep_resumes_from_its_journal(client, scenario, tmp_path):
    out = tmp_path / "sweep"
    varied = {"speed": [60.0, 80.0, 100.0], "until_distance": [600.0]}
    first = sweeping.sweep(scenario, varied, out, client=client, timeout=120, progress=False)
    assert [r["status"] for r in first] == ["ok"] * 3
    # the vehicle (spawned 600 ft ahead at 100 ft, closing at the ego's speed + 50 ft/s) passes 12 ft to the
    # side before 600 ft: the smallest sampled gap is at most half the closing in one 0.05 s driver sample
    for row in first:
        assert row["A1_min_gap_ft"] <= (row["speed_ft/s"] + 50) * 0.05 / 2 + 1e-6
    # interrupt: the last run's row never reached the journal, and the table was never written
    journal = out / sweeping.JOURNAL_NAME
    lines = journal.read_text().splitlines()
    dropped = json.loads(lines[-1])
    journal.write_text("\n".join(lines[:-1]) + "\n" + lines[-1][:20])  # a line cut short, too
    (out / sweeping.TABLE_NAME).unlink()
    again = sweeping.sweep(scenario, varied, out, client=client, timeout=120, progress=False)
    assert [r["speed_ft/s"] for r in again] == [60.0, 80.0, 100.0]
    kept = {r["run"]: r for r in map(json.loads, lines[:-1])}
    for row in again:
        if row["run"] in kept:  # not run again: the very same row, wall time included
            assert row["run_wall_s"] == kept[row["run"]]["run_wall_s"]
        else:
            assert row["run"] == dropped["run"] and row["status"] == "ok"
            assert row["final_time_s"] == pytest.approx(dropped["final_time_s"], abs=1e-9)


def test_a_folder_with_other_files_or_another_sweep_is_refused(client, scenario, tmp_path):
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me")
    with pytest.raises(sweeping.SweepError, match="notes.txt"):
        sweeping.sweep(scenario, {"speed": [60.0]}, foreign, client=client, progress=False)
    assert (foreign / "notes.txt").read_text() == "keep me"
    out = tmp_path / "sweep"
    sweeping.sweep(scenario, {"speed": [60.0]}, out, client=client, until_distance=200.0, progress=False)
    with pytest.raises(sweeping.SweepError, match="different sweep"):
        sweeping.sweep(scenario, {"seed": [1, 2]}, out, client=client, until_distance=200.0, progress=False)
