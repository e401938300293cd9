"""Sweeps on Dask: every combination a row, a failing and a timed-out run as rows with their error,
resume from the journal, value grammar. An in-process LocalCluster runs the real Simple FMU."""

import json

import pytest

from sdl_fmu import sweep as sweeping

distributed = pytest.importorskip("distributed")

# One oncoming vehicle passing 12 ft to the ego's left, no collision; the run ends at --until-distance.
SCENARIO = "English\n100,A,50,600,-6,1\n"


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                       dashboard_address=None)
    with distributed.Client(cluster) as client:
        yield client
    cluster.close()


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


def test_failed_and_timed_out_runs_are_rows(client, scenario, tmp_path):
    # 2 x 2 runs: brake_decel_max -1 is below the FMU's declared minimum (refused before the run: failed).
    # until_distance 300000 ft is about 3400 s simulated: beyond the 1 s wall-clock timeout at any speed
    # this orchestrator reaches: the master takes 20 communication steps per simulated second (the driver's
    # samples), 68 000 in all, each at least one doStep and a few more calls through fmpy (~15 us at the very
    # least; BENCHMARKS.md measures 50-100 us), so 3400 s take several seconds. 200 ft (2.3 s simulated)
    # ends within it even at 10x real time.
    out = tmp_path / "sweep"
    rows = sweeping.sweep(scenario, {"until_distance": [200.0, 300000.0], "brake_decel_max": [9.81, -1.0]}, out,
                          client=client, timeout=1.0, progress=False)
    status = {(r["until_distance"], r["brake_decel_max"]): r["status"] for r in rows}
    assert status == {(200.0, 9.81): "ok", (200.0, -1.0): "failed", (300000.0, 9.81): "timeout",
                      (300000.0, -1.0): "failed"}
    failed = [r for r in rows if r["status"] == "failed"]
    assert all("brake_decel_max" in r["error"] for r in failed)
    timed_out, = [r for r in rows if r["status"] == "timeout"]
    assert "time limit" in timed_out["error"]
    ok, = [r for r in rows if r["status"] == "ok"]
    assert ok["collisions"] == 0 and ok["final_distance"] == pytest.approx(200.0, abs=1e-3)

    import pyarrow.parquet as pq

    table = pq.read_table(out / sweeping.TABLE_NAME)
    assert table.num_rows == 4
    assert table.column_names[:5] == ["run", "until_distance", "brake_decel_max", "status", "error"]
    assert (out / sweeping.CSV_NAME).read_text().count("\n") == 5
    assert (out / sweeping.PLOT_NAME).read_bytes()[:4] == b"\x89PNG"


def test_interrupted_sweep_resumes_from_its_journal(client, scenario, tmp_path):
    out = tmp_path / "sweep"
    varied = {"speed": [60.0, 80.0, 100.0]}
    first = sweeping.sweep(scenario, varied, out, client=client, timeout=120, until_distance=600.0, progress=False)
    assert [r["status"] for r in first] == ["ok"] * 3
    # the vehicle (spawned 600 ft ahead at 100 ft, closing at the ego's speed + 50 ft/s) passes 12 ft to the
    # side before 600 ft: its smallest footprint distance is the lateral clearance between the footprints,
    # the same whatever the speed (located, not sampled: within 1e-6 ft), and below the 12 ft offset
    clearances = [row["A1_min_distance_ft"] for row in first]
    assert 0 < clearances[0] < 12 and clearances == pytest.approx([clearances[0]] * 3, abs=1e-6)
    assert all(row["min_distance_ft"] == row["A1_min_distance_ft"] for row in first)
    # interrupt: the last run's row never reached the journal, and the table was never written
    journal = out / sweeping.JOURNAL_NAME
    lines = journal.read_text().splitlines()
    dropped = json.loads(lines[-1])
    journal.write_text("\n".join(lines[:-1]) + "\n" + lines[-1][:20])  # a line cut short, too
    (out / sweeping.TABLE_NAME).unlink()
    again = sweeping.sweep(scenario, varied, out, client=client, timeout=120, until_distance=600.0, progress=False)
    assert [r["speed"] for r in again] == [60.0, 80.0, 100.0]
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
