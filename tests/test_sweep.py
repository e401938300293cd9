"""Sweeps on Dask: every combination a row, a failing and a timed-out run as rows with their error,
resume from the journal, value grammar. An in-process LocalCluster runs the real Simple FMU."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from helpers import local_cluster
from sdl_fmu import api
from sdl_fmu import sweep as sweeping

distributed = pytest.importorskip("distributed")
pytestmark = pytest.mark.usefixtures("simple_fmus")  # the sweeps run the Simple FMU of the cache

# One oncoming vehicle passing 12 ft to the ego's left, no collision; the run ends at --until-distance.
SCENARIO = "English\n100,A,50,600,-6,1\n"


@pytest.fixture(scope="module")
def cluster():
    cluster = local_cluster(2)
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
                "brk1_distance_m", "brk1_stop_distance_m", "impact_speed_m/s", "relative_impact_speed_m/s"}
    # the criticality measures (docs/results.md), run-wide and for vehicle 1, lengths in m, DRAC in m/s2
    measures = {"min_distance_m", "min_distance_time_s", "min_ttc_s", "min_ttc_time_s", "max_drac_m/s2",
                "max_drac_time_s", "min_pet_s", "min_headway_s", "min_headway_time_s"}
    expected |= measures | {f"A1_{name}" for name in measures}
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
                                "run 0: params brake_decel_max=-1.0: below the declared minimum 0 m/s2 of "
                                "brake_decel_max"]
    assert main([*common, "--vary", "speed=60,80", "--out", str(tmp_path / "fine")]) == 0
    assert capsys.readouterr().err == ""


def test_the_command_line_ends_every_run_at_until_time(cluster, scenario, tmp_path, capsys):
    from sdl_fmu.cli import main

    out = tmp_path / "timed"
    assert main(["sweep", scenario, "--scheduler", cluster.scheduler_address, "--vary", "seed=1,2",
                 "--until-time", "1.5", "--out", str(out)]) == 0
    rows = [json.loads(line) for line in (out / sweeping.JOURNAL_NAME).read_text().splitlines()]
    assert [(row["status"], row["final_time_s"]) for row in rows] == [("ok", 1.5), ("ok", 1.5)]
    assert main(["sweep", scenario, "--scheduler", cluster.scheduler_address, "--vary", "seed=1",
                 "--until-time", "-1", "--out", str(tmp_path / "refused")]) == 2
    assert capsys.readouterr().err.splitlines()[-1] == "sdl-fmu: --until-time -1: must be > 0 and <= 3600 s"
    assert not (tmp_path / "refused").exists()


def test_interrupted_sweep_resumes_from_its_journal(client, scenario, tmp_path):
    out = tmp_path / "sweep"
    varied = {"speed": [60.0, 80.0, 100.0], "until_distance": [600.0]}
    first = sweeping.sweep(scenario, varied, out, client=client, timeout=120, progress=False)
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


def test_the_tire_files_travel_with_the_attribute_file(tmp_path, monkeypatch):
    # an attribute file naming one tire by a relative path and one by an absolute path, shipped as a bundle and
    # written elsewhere: the slot start values read from the copy equal those read from the originals
    from sdl_fmu.dynamics.tires import slot_parameters
    from sdl_fmu.tire_files import TIRE_DIRECTORY

    # a cache of its own: in the session's cache (kept between sessions with SDL_FMU_TEST_CACHE) the bundle may
    # already exist from an earlier session, and then nothing is written and nothing cleaned up
    monkeypatch.setenv("SDL_FMU_CACHE", str(tmp_path / "cache"))

    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "wet.tir").write_bytes((TIRE_DIRECTORY / "wet_asphalt.tir").read_bytes())
    attributes = tmp_path / "mine" / "attributes.txt"
    attributes.write_text(f"// mine\n0 = {TIRE_DIRECTORY / 'dry_asphalt.tir'}\n\n3 = 'wet.tir'  # wet\n")
    bundle = sweeping.SHIPPED["tires"](attributes)
    assert [name for name, _ in bundle.files] == ["attributes.txt", "tires/0-dry_asphalt.tir", "tires/1-wet.tir"]
    # the temporary folder of a worker killed while writing (a process id that no longer exists) goes away
    from sdl_fmu.fmu.cache import cache_directory

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    abandoned = cache_directory() / sweeping.SHIPPED_FOLDER / f".building-{dead.stdout.strip()}-x1y2"
    abandoned.mkdir(parents=True)
    local = sweeping.materialize(bundle)
    assert local.parent.name == bundle.digest[:32] and local.parent.parent.name == sweeping.SHIPPED_FOLDER
    assert not abandoned.exists()
    assert slot_parameters(local)[:2] == slot_parameters(attributes)[:2]
    assert sweeping.materialize(bundle) == local  # written once
    assert local.read_text().splitlines()[1] == "0 = tires/0-dry_asphalt.tir"  # on its original line


def test_a_sweep_with_a_tire_attribute_file_runs_as_a_single_run_does(client, scenario, tmp_path,
                                                                     advanced_fmu):
    # The attribute file sits in the user's folder beside its own tire, named by a relative path; the workers
    # read the shipped copies. Its attribute 9 is beyond the FMU's 8 slots: one warning, which only a run that
    # read this file gives. The sweep's row and a direct api.run agree exactly.
    from sdl_fmu.tire_files import TIRE_DIRECTORY

    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "slippery.tir").write_bytes((TIRE_DIRECTORY / "ice.tir").read_bytes())
    attributes = tmp_path / "mine" / "attributes.txt"
    attributes.write_text("0 = slippery.tir\n9 = slippery.tir\n")
    fixed = {"dynamics": "advanced", "fmu": str(advanced_fmu), "tires": str(attributes)}
    rows = sweeping.sweep(scenario, {"until_distance": [300.0]}, tmp_path / "sweep", client=client,
                          progress=False, **fixed)
    assert rows[0]["status"] == "ok", rows[0]["error"]
    direct = api.run(scenario, until_distance=300.0, **fixed)
    assert rows[0]["warnings"] == len(direct.warnings) == 1 and "attribute 9" in direct.warnings[0]
    assert rows[0]["final_time_s"] == direct.final["time_s"]
    assert rows[0]["final_lateral_ft"] == direct.final["lateral"]


def _stop(process: subprocess.Popen) -> None:
    """Stops a process this test started, by its PID: SIGTERM, then SIGKILL if it lingers."""
    if process.poll() is None:
        os.kill(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.kill(process.pid, signal.SIGKILL)
            process.wait()


def _wait_for(condition, processes, what: str, limit: float = 300.0) -> None:
    """Waits until `condition()` holds; fails if one of `processes` ends first (or after `limit` s: a hang)."""
    deadline = time.monotonic() + limit
    while not condition():
        for process in processes:
            assert process.poll() is None, f"{process.args[:4]} ended (code {process.returncode}) before {what}"
        assert time.monotonic() < deadline, f"no {what} within {limit:.0f} s"
        time.sleep(0.05)


@pytest.mark.slow
def test_a_real_cluster_with_workers_elsewhere_runs_every_row_even_when_a_worker_dies(tmp_path, simple_fmu):
    # A `dask scheduler` and two `dask worker` processes (no nanny: the worker is the process, and a killed
    # worker stays dead) started in another folder, each with its own HOME and an empty FMU cache; the sweep
    # names its scenario by a path relative to its own folder, which the workers do not have. Every run is held
    # at its first step (the api's test hook) until the test has killed the worker of the first held run.
    project, elsewhere = tmp_path / "project", tmp_path / "elsewhere"
    (project / "scenarios").mkdir(parents=True)
    (project / "scenarios" / "pass.sdl").write_text(SCENARIO)
    elsewhere.mkdir()
    hold = tmp_path / "hold"
    hold.touch()
    checkout = str(Path(sweeping.__file__).resolve().parents[1])
    base = {key: value for key, value in os.environ.items()
            if key not in ("SDL_FMU_CACHE", "XDG_CACHE_HOME", api.HOLD_VARIABLE, "PYTHONPATH")}
    base["PYTHONPATH"] = checkout  # the code under test, wherever the process starts
    scheduler_file = tmp_path / "scheduler.json"
    processes = []
    try:
        processes.append(subprocess.Popen(
            [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
             "--scheduler-file", str(scheduler_file)], cwd=elsewhere, env={**base, "HOME": str(tmp_path / "h0")},
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        _wait_for(lambda: '"address"' in (scheduler_file.read_text() if scheduler_file.exists() else "")
                  and scheduler_file.read_text().rstrip().endswith("}"), processes, "the scheduler's address")
        address = json.loads(scheduler_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        homes = [tmp_path / "home1", tmp_path / "home2"]
        workers = []
        for home in homes:
            home.mkdir()
            workers.append(subprocess.Popen(
                [sys.executable, "-m", "dask", "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                 "--host", "127.0.0.1"], cwd=elsewhere, env={**base, "HOME": str(home), api.HOLD_VARIABLE: str(hold)},
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        processes += workers
        with distributed.Client(address, timeout=60) as watcher:
            watcher.wait_for_workers(2, timeout=300)

        sweep_command = subprocess.Popen(
            [sys.executable, "-m", "sdl_fmu.cli", "sweep", "scenarios/pass.sdl", "--scheduler", address,
             "--vary", "until_distance=300", "--vary", "speed=60:110:10", "--out", "table"], cwd=project,
            env={**base, "SDL_FMU_CACHE": os.environ["SDL_FMU_CACHE"]}, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True)
        processes.append(sweep_command)
        running = tmp_path / "hold.running"
        _wait_for(lambda: running.exists() and running.read_text().endswith("\n"), processes, "a held run")
        victim_pid = int(running.read_text().split()[0])
        (victim,) = [worker for worker in workers if worker.pid == victim_pid]
        os.kill(victim.pid, signal.SIGKILL)  # mid-run
        victim.wait()
        hold.unlink()  # the other worker's runs go on
        stdout, stderr = sweep_command.communicate(timeout=600)
        assert sweep_command.returncode == 0, stderr
        assert stdout.splitlines()[0] == "pass.sdl: 6 runs: 6 ok, 0 failed, 0 timed out"
    finally:
        for process in reversed(processes):
            _stop(process)

    import pyarrow.parquet as pq

    table = pq.read_table(project / "table" / sweeping.TABLE_NAME).to_pylist()
    assert [(row["run"], row["speed_ft/s"], row["status"]) for row in table] == [
        (k, 60.0 + 10 * k, "ok") for k in range(6)]
    assert all(row["final_distance_ft"] == pytest.approx(300.0, abs=1e-3) for row in table)
    # the survivor got the FMU and the scenario as bytes, into its own cache under its own HOME: it built no FMU
    (survivor,) = [home for home, worker in zip(homes, workers) if worker is not victim]
    cache = survivor / ".cache" / "sdl-fmu"
    assert sorted(path.name for path in cache.iterdir()) == [sweeping.SHIPPED_FOLDER]
    shipped = sorted(path.name for path in (cache / sweeping.SHIPPED_FOLDER).glob("*/*"))
    assert shipped == ["EgoVehicleSimple.fmu", "pass.sdl"]
    assert list(elsewhere.iterdir()) == []
    assert sorted(os.listdir(project)) == ["scenarios", "table"]


def test_the_plot_draws_one_series_per_value_of_the_other_quantity_and_whole_collision_ticks(tmp_path, monkeypatch):
    # speed x seed: against speed, one line per seed (a line varies speed alone: the two quantities are never
    # mixed in one scatter), and against seed one per speed; the collision counts (0, 1, 2) get whole-number ticks
    from matplotlib.figure import Figure

    figures = []
    original = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: (figures.append(self), original(self, *a, **k)))
    rows = [{"run": k, "speed_ft/s": speed, "seed": seed, "status": "ok", "collisions": (speed > 70) + (seed == 2),
             "min_distance_ft": 100.0 - speed + seed} for k, (speed, seed) in enumerate(
                 (s, d) for s in (60.0, 70.0, 80.0) for d in (1, 2))]
    rows.append({"run": 6, "speed_ft/s": 90.0, "seed": 1, "status": "failed", "error": "x"})
    sweeping.plot_sweep(rows, ["speed_ft/s", "seed"], "English", tmp_path / "sweep.png")
    axes = figures[0].axes
    collisions_by_speed, _, distance_by_speed = axes[:3]
    lines = {line.get_label(): line for line in collisions_by_speed.lines}
    assert set(lines) == {"seed=1", "seed=2"}
    assert list(lines["seed=1"].get_xdata()) == [60.0, 70.0, 80.0] and list(lines["seed=1"].get_ydata()) == [0, 0, 1]
    assert list(lines["seed=2"].get_ydata()) == [1, 1, 2]
    assert {line.get_label() for line in axes[3].lines} == {"speed (ft/s)=60", "speed (ft/s)=70", "speed (ft/s)=80"}
    assert [line.get_label() for line in distance_by_speed.lines] == ["seed=1", "seed=2"]
    ticks = [tick for tick in collisions_by_speed.get_yticks() if -0.2 <= tick <= 2.2]
    assert ticks and all(float(tick).is_integer() for tick in ticks)
    # the failed run is marked at the bottom, apart from the series
    assert [list(c.get_offsets()[:, 0]) for c in collisions_by_speed.collections] == [[90.0]]


# Two declared parameters of the oncoming car: its gap and its lateral position (nearer the ego's lane: closer pass).
PARAMETERS = ("English\n// @param gap = 800 ft in 400..1500\n// @param lateral = -6 ft in -9..-3\n"
              "100,A,50,$gap,$lateral,1\n")
TIMING = {"sim_wall_s", "real_time_factor", "run_wall_s"}


def _outcome(row: dict) -> dict:
    """A row's outcome columns (what a run computes; not its place, its status or the machine's timing)."""
    return {key: value for key, value in row.items()
            if key not in TIMING | {"run", "rank", "key", "status", "error", "gap_ft", "lateral_ft"}}


def test_sort_ranks_the_table_and_rerun_reproduces_a_row(client, tmp_path):
    import pyarrow.parquet as pq

    from helpers import sdl_fmu

    path = tmp_path / "p.sdl"
    path.write_text(PARAMETERS)
    assignments = ["gap=lhs(4)", "lateral=lhs(4)"]
    varied = sweeping.parse_vary(assignments, 5, api.load(path))
    joint = sweeping.lhs_names(assignments)
    out = tmp_path / "sweep"
    rows = sweeping.sweep(str(path), varied, out, client=client, progress=False, joint=joint, sort="min_distance",
                          until_distance=900.0)
    assert [r["status"] for r in rows] == ["ok"] * 4 and [r["rank"] for r in rows] == [1, 2, 3, 4]
    distances = [r["min_distance_ft"] for r in rows]
    assert distances == sorted(distances) and len(set(distances)) == 4
    table = pq.read_table(out / sweeping.TABLE_NAME).to_pylist()
    assert list(table[0])[:4] == ["rank", "run", "gap_ft", "lateral_ft"]
    assert [r["run"] for r in table] == [r["run"] for r in rows]
    # the same sweep ranked the other way: every row kept from the journal (nothing runs again), the order reversed
    again = sweeping.sweep(str(path), varied, out, client=client, progress=False, joint=joint,
                           sort="min_distance_ft:desc", until_distance=900.0)
    assert [r["run"] for r in again] == [r["run"] for r in reversed(rows)]
    assert [r["run_wall_s"] for r in again] == [r["run_wall_s"] for r in reversed(rows)]
    with pytest.raises(sweeping.SweepError, match="--sort status: not a numeric column of the table"):
        sweeping.sweep(str(path), varied, tmp_path / "unsorted", client=client, joint=joint, sort="status")
    assert not (tmp_path / "unsorted").exists()

    # the worst row run again, alone: the same values and the same outcome, to the last bit
    worst = rows[0]
    result, values = sweeping.rerun(str(path), varied, worst["run"], tmp_path / "again", joint=joint,
                                    until_distance=900.0)
    assert values == {"gap": worst["gap_ft"], "lateral": worst["lateral_ft"]}
    assert _outcome(sweeping._summarise(result)) == _outcome(worst)
    # from the command line: the sweep's arguments and --rerun K; its summary.json holds the row's values (written
    # to 6 decimals: results/files.py)
    completed = sdl_fmu("sweep", path, *(a for pair in zip(["--vary"] * 2, assignments) for a in pair),
                        "--sample-seed", "5", "--until-distance", "900", "--rerun", worst["run"], "--out",
                        tmp_path / "cli", cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    assert f"--set gap={worst['gap_ft']!r} --set lateral={worst['lateral_ft']!r}" in completed.stdout
    summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert summary["collisions"] == worst["collisions"]
    assert summary["criticality"]["min_distance"] == round(worst["min_distance_ft"], 6)
    assert summary["final"]["distance"] == round(worst["final_distance_ft"], 6)
    with pytest.raises(sweeping.SweepError, match="--rerun 4: the sweep has 4 runs, numbered 0 to 3"):
        sweeping.rerun(str(path), varied, 4, tmp_path / "none", joint=joint)


class _Listener:
    """A TCP listener on a free port of 127.0.0.1 that counts the connections made to it: a --scheduler that
    shows whether a sweep contacted its cluster at all."""

    def __init__(self):
        import socket
        import threading

        self.socket = socket.create_server(("127.0.0.1", 0))
        self.address = f"tcp://127.0.0.1:{self.socket.getsockname()[1]}"
        self.connections = 0
        self.thread = threading.Thread(target=self._count, daemon=True)
        self.thread.start()

    def _count(self):
        while True:
            try:
                connection, _ = self.socket.accept()
            except OSError:
                return
            self.connections += 1
            connection.close()

    def close(self):
        self.socket.close()


@pytest.mark.parametrize("vary, code, needle", [
    (["lead_speed=1,2"], 2, "sdl-fmu: --vary lead_speed: is no run option (speed, seed, until_distance, "
                            "until_time), no parameter of p.sdl (declared: gap, lateral; or an address LINE.N"),
    (["$width=1,2"], 2, "sdl-fmu: --vary $width: p.sdl declares no parameter 'width' (declared: gap, lateral)"),
    (["4.2=800,0"], 1, "/p.sdl:4: A parameter 2 (gap), from address 4.2 = 0: '0': the vehicle cannot appear at gap 0"),
    (["4.9=1"], 1, "/p.sdl:4: address 4.9: the A event on line 4 has 4 parameters"),
    (["gap=100,800"], 2, "sdl-fmu: --vary gap=100,800: 100 is outside the declared range 400..1500 of gap (line 2)"),
    (["gap=lhs(3)", "lateral=lhs(4)"], 2, "sdl-fmu: --vary lateral: the lhs() of one sweep are one Latin hypercube"),
    (["speed=60"], 2, "sdl-fmu: --sort nothing: not a numeric column of the table"),
])
def test_names_and_values_that_set_nothing_are_refused_before_any_cluster_is_contacted(tmp_path, vary, code, needle):
    from helpers import sdl_fmu

    (tmp_path / "p.sdl").write_text(PARAMETERS)
    listener = _Listener()
    try:
        sort = ["--sort", "nothing"] if vary == ["speed=60"] else []
        completed = sdl_fmu("sweep", "p.sdl", *(a for name in vary for a in ("--vary", name)), *sort,
                            "--scheduler", listener.address, "--out", tmp_path / "sweep", cwd=tmp_path)
    finally:
        listener.close()
    assert completed.returncode == code and len(completed.stderr.splitlines()) == 1, completed.stderr
    assert needle in completed.stderr and completed.stdout == ""  # a scenario's error names its absolute path
    assert listener.connections == 0  # the scheduler was never even probed
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.sdl"]

def _figures_saved(monkeypatch) -> list:
    from matplotlib.figure import Figure

    figures = []
    original = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: (figures.append(self), original(self, *a, **k)))
    return figures


def test_a_2d_grid_too_large_for_lines_is_drawn_as_heat_maps(tmp_path, monkeypatch):
    # speed (10 values) x mass (9 values): one line per value of the other would be 9 or 10 lines, beyond
    # MAX_PLOT_SERIES, and once fell back to one series of every run, zig-zagging between the masses. Now one row of
    # heat maps: speed across, mass up, each cell the run's value (read back from the image), the failed run's cell
    # empty and marked with a cross.
    figures = _figures_saved(monkeypatch)
    speeds, masses = [60.0 + 10 * k for k in range(10)], [1000.0 + 200 * k for k in range(9)]
    rows = [{"run": k, "speed_ft/s": speed, "mass_kg": mass, "status": "ok", "collisions": int(speed > 100),
             "min_distance_ft": 200.0 - speed + mass / 100, "brk1_distance_ft": speed * mass / 1000}
            for k, (speed, mass) in enumerate((s, m) for s in speeds for m in masses)]
    rows[-1] = {**rows[-1], "status": "failed", "error": "x", "collisions": None}
    assert sweeping.heat_map_axes(rows, ["speed_ft/s", "mass_kg"]) == ("speed_ft/s", "mass_kg")
    sweeping.plot_sweep(rows, ["speed_ft/s", "mass_kg"], "English", tmp_path / "sweep.png")
    panels = [ax for ax in figures[0].axes if ax.images]
    assert len(panels) == 3 and all(not ax.lines for ax in panels)  # no line through the runs
    cells = np.ma.filled(panels[2].images[0].get_array(), np.nan)
    assert cells.shape == (len(masses), len(speeds))
    expected = np.array([[200.0 - s + m / 100 for s in speeds] for m in masses])
    expected[-1, -1] = np.nan  # the failed run: no value
    np.testing.assert_array_equal(cells, expected)
    collisions = np.ma.filled(panels[0].images[0].get_array(), np.nan)
    assert np.nanmax(collisions[:, :5]) == 0 and np.nanmin(collisions[:-1, 5:]) == 1
    assert [t.get_text() for t in panels[0].get_xticklabels()] == [f"{s:g}" for s in speeds]
    assert panels[0].get_xlabel() == "speed (ft/s)" and panels[0].get_ylabel() == "mass (kg)"
    assert [list(c.get_offsets()[0]) for c in panels[0].collections if len(c.get_offsets())] == [[9.0, 8.0]]


def test_a_small_2d_grid_keeps_one_line_per_value_and_mixed_series_are_not_joined(tmp_path, monkeypatch):
    # 3 x 2 stays lines (test above); with three quantities and more combinations than MAX_PLOT_SERIES, a series
    # holds several runs per x value: drawn as markers alone, never as a line zig-zagging between them
    figures = _figures_saved(monkeypatch)
    rows = [{"run": k, "speed_ft/s": s, "seed": d, "mass_kg": m, "status": "ok", "collisions": (s > 70) + d,
             "min_distance_ft": s + d + m} for k, (s, d, m) in enumerate(
                 (s, d, m) for s in (60.0, 70.0, 80.0) for d in (1, 2, 3) for m in (1000.0, 1100.0, 1200.0, 1300.0))]
    varied = ["speed_ft/s", "seed", "mass_kg"]
    assert sweeping.heat_map_axes(rows, varied) is None
    sweeping.plot_sweep(rows, varied, "English", tmp_path / "sweep.png")
    drawn = [line for ax in figures[0].axes for line in ax.lines]
    assert drawn and not [ax for ax in figures[0].axes if ax.images]
    for line in drawn:
        if line.get_linewidth() > 0:  # a joined line varies its quantity alone: each x once, in order
            assert list(line.get_xdata()) == sorted(set(line.get_xdata()))
    assert any(line.get_linewidth() == 0 for line in drawn)  # the 12 combinations against speed: markers only
