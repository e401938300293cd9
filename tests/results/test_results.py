"""Writing a run's results: timeseries.csv units and cells, summary.json keys, atomic directory, plot.png."""

import csv
import dataclasses
import json

import numpy as np
import pytest

from sdl_fmu.results import RunRecord, SurfaceSection, VehicleTrack, plots, summary, write_results
from sdl_fmu.results.folder import ResultsFolderError
from sdl_fmu.sdl.events import Road
from sdl_fmu.units import from_si

ROAD = Road(line=0, distance=0.0, lane_width=3.6576, lanes=2, lanes_right=1)
NAN = float("nan")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

EGO_HEADER = ["time_s", "distance_{L}", "station_{L}", "lateral_{L}", "speed_{V}", "vx_{V}", "vy_{V}", "ax_{L}/s2",
              "ay_{L}/s2", "yaw_rate_rad/s", "psi_rad", "throttle_1", "brake_1", "steer_rad", "brk_active", "stopped"]


def make_result(units="English", dynamics="simple", collision=False) -> RunRecord:
    """Five samples 0.1 s apart at 15.24 m/s (50 ft/s); A1 appears at the third sample."""
    time = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    s = 15.24 * time  # 0, 1.524 m (5 ft), 3.048 m (10 ft), ...
    n = len(time)
    columns = {
        "time": time, "x": s.copy(), "y": np.full(n, -1.8288), "psi": np.zeros(n), "s": s, "v": np.full(n, 15.24),
        "vx": np.full(n, 15.24), "vy": np.zeros(n), "ax": np.array([0.0, 0.0, -3.048, -3.048, 0.0]),
        "ay": np.zeros(n), "yaw_rate": np.zeros(n), "stopped": np.zeros(n), "station": s.copy(),
        "lateral": np.full(n, 1.8288), "throttle": np.array([0.2, 0.2, 0.0, 0.0, 0.2]),
        "brake": np.array([0.0, 0.0, 1.0, 1.0, 0.0]), "steer": np.zeros(n), "brk": np.array([0, 0, 1, 1, 0.0]),
    }
    if dynamics == "simple":
        columns.update({f"mu_{w}": np.array([0.8, 0.8, 0.3, 0.3, 0.8]) for w in ("fl", "fr", "rl", "rr")})
    else:
        columns.update({f"surface_{w}": np.array([0.0, 0.0, 2.0, 2.0, 0.0]) for w in ("fl", "fr", "rl", "rr")})
    vehicle = VehicleTrack(
        vehicle=1, model=3, name="Pickup", length=5.3, width=2.0,
        station=np.array([NAN, NAN, 33.528, 31.0, 28.472]),  # 110 ft at the third sample
        lateral=np.array([NAN, NAN, -1.8288, -1.8288, -1.8288]),
        speed=np.array([NAN, NAN, 6.096, 6.096, 6.096]),  # approaching (SDL's sign): 20 ft/s toward the ego
        # the bumper gap as the run stage gives it (an ego 4.6 m long, yaw 0): 30.48 - 2.3 - 2.65 = 25.53 m at the
        # third sample (100 ft between the centres), then 2.528 m and 2.528 + 3.048 m less
        bumper_gap=np.array([NAN, NAN, 25.53, 20.454, 15.378]),
    )
    # the record is SI: 3.048 m (10 ft) at 15.24 m/s (50 ft/s), 1.8288 m (6 ft) right of the dividing line
    events = [
        {"code": "A", "action": "spawn", "vehicle": 1, "model": 3, "time_s": 0.2, "distance": 3.048, "speed": 15.24,
         "lateral": 1.8288},
        {"code": "BRK", "action": "on", "time_s": 0.2, "distance": 3.048, "speed": 15.24, "lateral": 1.8288,
         "threshold": "distance", "magnitude": 30.48},
    ]
    if collision:
        events.append({"code": "A", "action": "collision", "vehicle": 1, "time_s": 0.3, "distance": 4.572,
                       "speed": 15.24, "lateral": 1.8288})
    return RunRecord(
        scenario_path="scenarios/example.sdl", units=units, dynamics=dynamics, seed=42, road=ROAD, columns=columns,
        vehicles=[vehicle], events=events, collisions=int(collision),
        collision_points=[(4.6, 0.0)] if collision else [],
        surfaces=[SurfaceSection(lane=1, start=1.0, end=None, value=3 if dynamics == "simple" else 2)],
        warnings=["a warning"], final={"time_s": 0.4, "distance": 6.096, "speed": 15.24, "lateral": 1.8288000000003},
    )


def read_csv(path):
    with open(path, newline="") as file:
        rows = list(csv.reader(file))
    return rows[0], rows[1:]


def expected_header(length, speed, wheels):
    ego = [name.format(L=length, V=speed) for name in EGO_HEADER]
    vehicle = [f"A1_station_{length}", f"A1_lateral_{length}", f"A1_speed_{speed}", f"A1_gap_{length}",
               f"A1_bumper_gap_{length}"]
    return ego + wheels + vehicle


def test_csv_english_header_and_feet(tmp_path):
    out = write_results(make_result("English"), tmp_path / "run", plot=False)
    header, rows = read_csv(out / "timeseries.csv")
    assert header == expected_header("ft", "ft/s", ["mu_fl_1", "mu_fr_1", "mu_rl_1", "mu_rr_1"])
    assert len(rows) == 5 and all(len(row) == len(header) for row in rows)
    row = dict(zip(header, rows[2]))
    assert row["time_s"] == "0.200000"
    assert float(row["distance_ft"]) == pytest.approx(10.0)  # 3.048 m / 0.3048 m/ft, by hand
    assert float(row["speed_ft/s"]) == pytest.approx(50.0)
    assert float(row["lateral_ft"]) == pytest.approx(6.0)
    assert float(row["ax_ft/s2"]) == pytest.approx(-10.0)
    assert float(row["distance_ft"]) == pytest.approx(from_si(3.048, "English"))
    assert row["brk_active"] == "1" and row["stopped"] == "0"
    assert float(row["mu_fl_1"]) == pytest.approx(0.3)
    assert float(row["A1_station_ft"]) == pytest.approx(110.0)
    assert float(row["A1_speed_ft/s"]) == pytest.approx(-20.0)  # along the road, + the ego's way: it comes toward us
    assert float(row["A1_gap_ft"]) == pytest.approx(100.0)  # vehicle station - ego station
    assert float(row["A1_bumper_gap_ft"]) == pytest.approx(25.53 / 0.3048)  # 83.7598 ft


def test_csv_metric_header_and_metres(tmp_path):
    out = write_results(make_result("Metric"), tmp_path / "run", plot=False)
    header, rows = read_csv(out / "timeseries.csv")
    assert header == expected_header("m", "m/s", ["mu_fl_1", "mu_fr_1", "mu_rl_1", "mu_rr_1"])
    row = dict(zip(header, rows[2]))
    assert float(row["distance_m"]) == pytest.approx(3.048)
    assert float(row["speed_m/s"]) == pytest.approx(15.24)
    assert float(row["A1_gap_m"]) == pytest.approx(33.528 - 3.048)


def test_csv_advanced_surface_columns_are_integers(tmp_path):
    out = write_results(make_result(dynamics="advanced"), tmp_path / "run", plot=False)
    header, rows = read_csv(out / "timeseries.csv")
    assert header == expected_header("ft", "ft/s", ["surface_fl", "surface_fr", "surface_rl", "surface_rr"])
    assert [dict(zip(header, row))["surface_rr"] for row in rows] == ["0", "0", "2", "2", "0"]


def test_csv_cells_empty_while_vehicle_absent(tmp_path):
    out = write_results(make_result(), tmp_path / "run", plot=False)
    header, rows = read_csv(out / "timeseries.csv")
    vehicle_columns = [k for k, name in enumerate(header) if name.startswith("A1_")]
    for row in rows[:2]:
        assert [row[k] for k in vehicle_columns] == ["", "", "", "", ""]
    for row in rows[2:]:
        assert all(row[k] != "" for k in vehicle_columns)
    assert all(cell != "" for row in rows for k, cell in enumerate(row) if k not in vehicle_columns)


def test_summary_json_keys_per_spec(tmp_path):
    result = make_result()
    out = write_results(result, tmp_path / "run", plot=False)
    data = json.loads((out / "summary.json").read_text())
    assert set(data) == {"scenario", "seed", "units", "key_units", "dynamics", "collisions", "final", "events",
                         "warnings", "timing"}
    # every unit-carrying key of "final" has its unit stated, and lateral its sign
    assert {"time_s": "s", "distance": "ft", "speed": "ft/s"}.items() <= data["key_units"].items()
    assert data["key_units"]["lateral"].startswith("ft, positive to the driver's right")
    assert set(data["final"]) <= set(data["key_units"])
    assert data["units"] == "English" and data["dynamics"] == "simple" and data["seed"] == 42
    assert data["collisions"] == 0 and data["scenario"] == "example.sdl"  # its name: no machine path in results
    assert set(data["final"]) == {"time_s", "distance", "speed", "lateral"}
    # the record's SI values in feet (by hand: m / 0.3048), rounded to 6 decimals
    assert data["final"] == {"time_s": 0.4, "distance": 20.0, "speed": 50.0, "lateral": 6.0}
    assert data["events"] == [
        {"code": "A", "action": "spawn", "vehicle": 1, "model": 3, "time_s": 0.2, "distance": 10.0, "speed": 50.0,
         "lateral": 6.0},
        {"code": "BRK", "action": "on", "time_s": 0.2, "distance": 10.0, "speed": 50.0, "lateral": 6.0,
         "threshold": "distance", "magnitude": 100.0}]
    assert data["warnings"] == ["a warning"]
    assert (out / "summary.json").read_text().startswith('{\n  "')  # indent 2


def test_summary_is_strict_json():
    result = make_result()
    result.final = {"time_s": np.float64(0.4), "distance": NAN, "speed": np.float32(50.0), "lateral": 6.0}
    data = summary(result)
    json.dumps(data, allow_nan=False)
    assert data["final"]["distance"] is None and type(data["final"]["time_s"]) is float


def test_failure_leaves_no_directory(tmp_path, monkeypatch):
    def broken_plot(result, path):
        path.write_bytes(b"half a png")
        raise RuntimeError("plot failed")

    monkeypatch.setattr(plots, "plot_run", broken_plot)
    with pytest.raises(RuntimeError, match="plot failed"):
        write_results(make_result(), tmp_path / "run")
    assert list(tmp_path.iterdir()) == []


def test_failure_keeps_old_results_untouched(tmp_path, monkeypatch):
    old = write_results(make_result(), tmp_path / "run", plot=False)
    before = {p.name: p.read_bytes() for p in old.iterdir()}
    monkeypatch.setattr(plots, "plot_run", lambda result, path: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        write_results(make_result(), old)
    assert [p.name for p in tmp_path.iterdir()] == ["run"]
    assert {p.name: p.read_bytes() for p in old.iterdir()} == before


def test_success_replaces_old_results(tmp_path):
    old = write_results(make_result(), tmp_path / "run")
    out = write_results(make_result(), old, plot=False)
    assert out == old.absolute()
    assert sorted(p.name for p in out.iterdir()) == [".sdl-fmu-results.json", "summary.json", "timeseries.csv"]
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


def test_missing_parents_are_created(tmp_path):
    out = write_results(make_result(), tmp_path / "a" / "b" / "run", plot=False)
    assert (out / "timeseries.csv").is_file()


def test_out_dir_that_is_a_file_is_refused(tmp_path):
    (tmp_path / "run").write_text("not a directory")
    with pytest.raises(ResultsFolderError, match="exists and is not a folder"):
        write_results(make_result(), tmp_path / "run", plot=False)
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


@pytest.mark.parametrize("dynamics, collision", [("simple", True), ("advanced", False)])
def test_plot_png_is_written(tmp_path, dynamics, collision):
    out = write_results(make_result(dynamics=dynamics, collision=collision), tmp_path / "run")
    assert sorted(p.name for p in out.iterdir()) == [".sdl-fmu-results.json", "plot.png", "summary.json",
                                                     "timeseries.csv"]
    assert (out / "plot.png").read_bytes()[:8] == PNG_SIGNATURE


def test_label_rows_stack_crowded_labels_and_reuse_a_free_row():
    # spans (x, width) in pixels on a 700 px axes: three labels 5 px apart stack, one far right of them goes back to
    # the first row, one at the right edge is drawn leftward of its line; with more crowded labels than rows the
    # last ones get no row (left out rather than drawn over another)
    placed = plots._label_rows([(0.0, 60.0), (5.0, 60.0), (10.0, 60.0), (300.0, 60.0), (695.0, 60.0)], 700.0)
    assert [row for row, _ in placed] == [0, 1, 2, 0, 0] and placed[-1][1] == "right"
    crowded = plots._label_rows([(float(k), 60.0) for k in range(plots.MAX_LABEL_ROWS + 2)], 700.0)
    assert [row for row, _ in crowded] == [*range(plots.MAX_LABEL_ROWS), None, None]


def drawn_figure(result, monkeypatch, tmp_path):
    """The figure plot_run draws for `result` (captured at savefig)."""
    from matplotlib.figure import Figure

    figures = []
    original = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: (figures.append(self), original(self, *a, **k)))
    plots.plot_run(result, tmp_path / "plot.png")
    return figures[0]


def test_event_labels_do_not_overlap_as_drawn(tmp_path, monkeypatch):
    # 40 events in bursts 0.1 s apart over 30 s, labels of every length: the labels drawn in the speed panel,
    # measured by the renderer, overlap none of the others (each left out where no row has room)
    result = make_result()
    n = 601
    t = np.arange(n) * 0.05
    for name, values in list(result.columns.items()):
        result.columns[name] = np.resize(values, n)
    result.columns.update(time=t, s=15.24 * t, station=15.24 * t, x=15.24 * t)
    kinds = [{"code": "A", "action": "spawn", "vehicle": 12}, {"code": "BRK", "action": "off", "reason": "velocity"},
             {"code": "RSA", "action": "set", "lane": -1, "value": 7.5}, {"code": "A", "action": "maneuver",
                                                                          "vehicle": 3, "index": 2}]
    result.events = [{**kinds[k % 4], "time_s": 0.1 * (k % 8) + 3.0 * (k // 8), "distance": 0.0, "speed": 15.24,
                      "lateral": 1.8288} for k in range(40)]
    figure = drawn_figure(result, monkeypatch, tmp_path)
    speed_ax = figure.axes[0]
    renderer = figure.canvas.get_renderer()
    boxes = [text.get_window_extent(renderer) for text in speed_ax.texts if text.get_visible()]
    assert len(boxes) >= 20
    for k, box in enumerate(boxes):
        for other in boxes[k + 1:]:
            assert not box.overlaps(other), (box, other)


def test_the_zoom_follows_the_runs_criticality_minimum():
    # two vehicles: A1's closest approach (centre to centre) comes first, but the run's minimum footprint distance
    # (the criticality record) is A2's at 0.3 s: the zoom shows that instant and names A2
    result = make_result()
    result.vehicles.append(VehicleTrack(vehicle=2, model=1, name="Sedan", length=4.5, width=1.8,
                                        station=np.array([NAN, 20.0, 19.0, 18.0, 17.0]),
                                        lateral=np.array([NAN, -1.8288, -1.8288, -1.8288, -1.8288]),
                                        speed=np.array([NAN, 10.0, 10.0, 10.0, 10.0])))
    entry = {"min_ttc_s": None, "min_ttc_time_s": None, "max_drac": None, "max_drac_time_s": None, "min_pet_s": None,
             "min_headway_s": None, "min_headway_time_s": None}
    result.criticality = {"min_distance": 1.2, "min_distance_time_s": 0.3, **entry,
                          "vehicles": [{"vehicle": 1, "min_distance": 9.0, "min_distance_time_s": 0.2, **entry},
                                       {"vehicle": 2, "min_distance": 1.2, "min_distance_time_s": 0.3, **entry}]}
    index, what = plots._focus(result, result.columns["time"])
    # 1.2 m / 0.3048 = 3.937 ft, by hand
    assert index == 3 and what == "minimum distance 3.937 ft to A2 Sedan, t = 0.30 s (the run's criticality minimum)"


def test_a_lead_vehicle_and_the_gap_to_it_are_drawn(tmp_path, monkeypatch):
    # the record's lead series (the run stage computes it from signals.py's definition): the speed panel draws the
    # lead vehicle's speed, and a panel of its own the bumper gap (in ft: 30.48 m / 0.3048) and the relative speed
    result = make_result()
    present = np.array([False, True, True, True, False])
    result.lead_series = lambda: {"present": present, "index": np.where(present, 0, -1),
                                  "gap": np.array([1000.0, 30.48, 27.432, 24.384, 1000.0]),
                                  "speed": np.array([0.0, 6.096, 6.096, 6.096, 0.0]),
                                  "relative_speed": np.array([0.0, -9.144, -9.144, -9.144, 0.0]),
                                  "ttc": np.array([1000.0, 3.333, 3.0, 2.667, 1000.0]),
                                  "lateral_offset": np.zeros(5)}
    figure = drawn_figure(result, monkeypatch, tmp_path)
    speed_ax = figure.axes[0]
    lead_line = next(line for line in speed_ax.lines if line.get_label() == "lead vehicle speed")
    assert np.allclose(lead_line.get_ydata(), [NAN, 20.0, 20.0, 20.0, NAN], equal_nan=True)
    lead_ax = next(ax for ax in figure.axes if ax.get_title(loc="left").startswith("lead vehicle"))
    gap = next(line for line in lead_ax.lines if line.get_label() == "bumper gap")
    assert np.allclose(gap.get_ydata(), [NAN, 100.0, 90.0, 80.0, NAN], equal_nan=True)
    assert [text.get_text() for text in lead_ax.texts] == ["A1"]


def test_without_a_lead_vehicle_no_lead_panel_is_drawn(tmp_path, monkeypatch):
    result = make_result()
    result.lead_series = lambda: {"present": np.zeros(5, dtype=bool)}
    figure = drawn_figure(result, monkeypatch, tmp_path)
    assert not [ax for ax in figure.axes if ax.get_title(loc="left").startswith("lead vehicle")]


def test_plot_handles_long_runs(tmp_path):
    # speed targets live in benchmarks, not in tests: this only checks that a 20 000-sample run plots
    result = make_result(collision=True)
    n = 20000
    t = np.arange(n) * 0.01
    for name, values in list(result.columns.items()):
        result.columns[name] = np.resize(values, n)
    result.columns.update(time=t, s=15.24 * t, station=15.24 * t, x=15.24 * t)
    for track in result.vehicles:
        track.station = np.where(t < 10, NAN, 3000 - 6 * t)
        track.lateral = np.where(t < 10, NAN, -1.8288)
        track.speed = np.where(t < 10, NAN, 6.0)
    plots.plot_run(result, tmp_path / "plot.png")
    assert (tmp_path / "plot.png").read_bytes().startswith(b"\x89PNG")


def test_plot_of_many_vehicles_sections_and_events_uses_few_artists(tmp_path, monkeypatch):
    # 300 vehicles (each on the road for 50 samples, arrays offset by `first`), 1000 RSA sections and 900
    # events: drawn as a handful of collections, not one artist each (what keeps such plots fast; the
    # speed itself is a benchmark, not a test)
    from matplotlib.figure import Figure

    result = make_result()
    n = 3000
    t = np.arange(n) * 0.05
    for name, values in list(result.columns.items()):
        result.columns[name] = np.resize(values, n)
    result.columns.update(time=t, s=15.24 * t, station=15.24 * t, x=15.24 * t)
    result.vehicles = [VehicleTrack(k + 1, 1, "car", 4.5, 1.8, station=600.0 + 9 * k - 10 * np.arange(50) * 0.05,
                                    lateral=np.full(50, -1.8288), speed=np.full(50, 10.0), first=9 * k)
                       for k in range(300)]
    result.surfaces = [SurfaceSection(lane=1, start=2.0 * k, end=2.0 * k + 1, value=3 + k % 5) for k in range(1000)]
    result.events = [{"code": "A", "action": "spawn" if k % 2 else "despawn", "vehicle": k // 2 + 1,
                      "time_s": 0.15 * k, "distance": 2.286 * k, "speed": 50.0, "lateral": 6.0} for k in range(900)]
    figures = []
    original = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: (figures.append(self), original(self, *a, **k)))
    plots.plot_run(result, tmp_path / "plot.png")
    assert (tmp_path / "plot.png").read_bytes().startswith(b"\x89PNG")
    artists = sum(len(ax.lines) + len(ax.collections) + len(ax.patches) + len(ax.texts)
                  for ax in figures[0].axes)
    assert artists < 200


def test_traffic_csv_has_the_signed_speed_and_both_gaps(tmp_path):
    # more than WIDE_VEHICLE_LIMIT vehicles: their columns go to traffic.csv, one row per vehicle per sample, with
    # the same signs and gaps as timeseries.csv's per-vehicle columns (hand values of make_result's A1)
    from sdl_fmu.results import files

    result = make_result()
    result.vehicles = [dataclasses.replace(result.vehicles[0], vehicle=k + 1)
                       for k in range(files.WIDE_VEHICLE_LIMIT + 1)]
    out = write_results(result, tmp_path / "run", plot=False)
    header, rows = read_csv(out / "traffic.csv")
    assert header == ["time_s", "vehicle", "model", "station_ft", "lateral_ft", "speed_ft/s", "gap_ft", "bumper_gap_ft"]
    first = dict(zip(header, rows[2]))  # A1 at its first sample on the road (its track's third)
    assert (first["time_s"], first["vehicle"]) == ("0.200000", "1")
    assert float(first["speed_ft/s"]) == pytest.approx(-20.0) and float(first["gap_ft"]) == pytest.approx(100.0)
    assert float(first["bumper_gap_ft"]) == pytest.approx(25.53 / 0.3048)
