"""Writing what a run produced (record.RunRecord, SI): timeseries.csv and summary.json in the scenario's units
(summary.json's final state, events and criticality through scenario_units.py, the CSV's columns here), and
plot.png, atomically."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..names import WHEELS
from ..units import Units, from_si, length_label, speed_label
from . import scenario_units
from .folder import write_results_folder
from .record import RunRecord, VehicleTrack
from .storage import release_pages


TIME_FORMAT = "%.6f"
LENGTH_FORMAT = "%.4f"  # distances, positions and speeds in ft, ft/s or m, m/s
GENERAL_FORMAT = "%.6g"  # accelerations, angles, rates, pedals, mu


def _ego_column(result: RunRecord, name: str) -> np.ndarray:
    """One ego time series as a float array; a missing column is a bug in whoever built the RunRecord."""
    try:
        return np.asarray(result.columns[name], dtype=float)
    except KeyError:
        raise KeyError(f"RunRecord.columns has no {name!r} (has {sorted(result.columns)})") from None


WIDE_VEHICLE_LIMIT = 100  # more traffic vehicles than this: their columns go to traffic.csv, one row per sample
CSV_CHUNK_ROWS = 5000  # rows formatted at a time (~6 MB of cells): memory stays bounded however long the run


def _vehicle_slice(track: VehicleTrack, name: str, first: int, stop: int) -> np.ndarray:
    """Samples first..stop-1 of a vehicle's station / lateral / speed / bumper_gap, NaN where it is not on the
    road (or the gap is not known)."""
    values = getattr(track, name)
    out = np.full(stop - first, np.nan)
    if values is None:
        return out
    low, high = max(track.first, first), min(track.first + len(values), stop)
    if high > low:
        out[low - first:high - first] = values[low - track.first:high - track.first]
    return out


def _timeseries_columns(result: RunRecord) -> list[tuple[str, object, str]]:
    """The timeseries.csv columns as (header with unit, values of samples [first, stop) in scenario units,
    printf format)."""
    units = result.units
    length, speed = length_label(units), speed_label(units)
    accel = f"{length}/s2"

    def ego(name: str, convert: bool = False, transform=None):
        column = _ego_column(result, name)

        def values(first: int, stop: int) -> np.ndarray:
            part = np.asarray(column[first:stop], dtype=float)
            part = from_si(part, units) if convert else part
            return transform(part) if transform else part
        return values

    table = [
        ("time_s", ego("time"), TIME_FORMAT),
        (f"distance_{length}", ego("s", True), LENGTH_FORMAT),
        (f"station_{length}", ego("station", True), LENGTH_FORMAT),
        (f"lateral_{length}", ego("lateral", True), LENGTH_FORMAT),
        (f"speed_{speed}", ego("v", True), LENGTH_FORMAT),
        (f"vx_{speed}", ego("vx", True), LENGTH_FORMAT),
        (f"vy_{speed}", ego("vy", True), LENGTH_FORMAT),
        (f"ax_{accel}", ego("ax", True), GENERAL_FORMAT),
        (f"ay_{accel}", ego("ay", True), GENERAL_FORMAT),
        ("yaw_rate_rad/s", ego("yaw_rate"), GENERAL_FORMAT),
        ("psi_rad", ego("psi"), GENERAL_FORMAT),
        ("throttle_1", ego("throttle"), GENERAL_FORMAT),
        ("brake_1", ego("brake"), GENERAL_FORMAT),
        ("steer_rad", ego("steer"), GENERAL_FORMAT),
        ("brk_active", ego("brk", transform=lambda v: (v > 0.5).astype(float)), "%d"),
        ("stopped", ego("stopped", transform=lambda v: (v > 0.5).astype(float)), "%d"),
    ]
    for wheel in WHEELS:
        if f"mu_{wheel}" in result.columns:
            table.append((f"mu_{wheel}_1", ego(f"mu_{wheel}"), GENERAL_FORMAT))
    for wheel in WHEELS:
        if f"surface_{wheel}" in result.columns:
            table.append((f"surface_{wheel}", ego(f"surface_{wheel}", transform=np.round), "%d"))
    if result.controller is not None:  # the driver's commands before arbitration, the requests (docs/controllers.md)
        requested = result.controller.get("outputs", [])
        table += [("driver_throttle_1", ego("driver_throttle"), GENERAL_FORMAT),
                  ("driver_brake_1", ego("driver_brake"), GENERAL_FORMAT),
                  ("driver_steer_rad", ego("driver_steer"), GENERAL_FORMAT),
                  ("request_active", ego("request_active", transform=lambda v: (v > 0.5).astype(float)), "%d")]
        headers = {"throttle": "request_throttle_1", "brake": "request_brake_1", "steer": "request_steer_rad",
                   "deceleration": f"request_deceleration_{accel}"}
        table += [(header, ego(f"request_{name}", convert=name == "deceleration"), GENERAL_FORMAT)
                  for name, header in headers.items() if name in requested]
    if len(result.vehicles) > WIDE_VEHICLE_LIMIT:
        return table
    ego_station = _ego_column(result, "station")
    for track in result.vehicles:
        prefix = f"A{track.vehicle}"

        def vehicle(name: str, track=track, gap: bool = False, sign: float = 1.0):
            def values(first: int, stop: int) -> np.ndarray:
                part = _vehicle_slice(track, name, first, stop)
                if gap:
                    part = part - np.asarray(ego_station[first:stop], dtype=float)
                return from_si(0.0 - part if sign < 0.0 else part, units)  # 0.0 - x: no -0.0 for a stopped one
            return values
        # the speed along the road, + the ego's way (the record's track speed is + toward the ego, as SDL's A
        # event gives it); the gap from centre to centre (station - the ego's) and from bumper to bumper
        table += [
            (f"{prefix}_station_{length}", vehicle("station"), LENGTH_FORMAT),
            (f"{prefix}_lateral_{length}", vehicle("lateral"), LENGTH_FORMAT),
            (f"{prefix}_speed_{speed}", vehicle("speed", sign=-1.0), LENGTH_FORMAT),
            (f"{prefix}_gap_{length}", vehicle("station", gap=True), LENGTH_FORMAT),
            (f"{prefix}_bumper_gap_{length}", vehicle("bumper_gap"), LENGTH_FORMAT),
        ]
    return table


def timeseries_table(result: RunRecord) -> list[tuple[str, np.ndarray, str]]:
    """The timeseries.csv columns as (header with unit, values in scenario units, printf format)."""
    samples = len(_ego_column(result, "time"))
    table = [(header, values(0, samples), fmt) for header, values, fmt in _timeseries_columns(result)]
    for header, values, _ in table:
        if len(values) != samples:
            raise ValueError(f"column {header} has {len(values)} samples, time has {samples}")
    return table


def _format_column(values: np.ndarray, fmt: str) -> list[str]:
    """Printf-format every value; NaN (vehicle absent, value unknown) becomes an empty cell."""
    return [fmt % value if math.isfinite(value) else "" for value in values.tolist()]


def write_timeseries_csv(result: RunRecord, path: Path) -> None:
    """timeseries.csv: one row per sample, units in the headers, scenario units for lengths and speeds;
    written CSV_CHUNK_ROWS rows at a time. With more than WIDE_VEHICLE_LIMIT traffic vehicles their
    columns would make the table unusably wide: they go to traffic.csv instead (`write_traffic_csv`)."""
    columns = _timeseries_columns(result)
    time = _ego_column(result, "time")
    samples = len(time)
    for name, column in result.columns.items():
        if len(column) != samples:
            raise ValueError(f"column {name} has {len(column)} samples, time has {samples}")
    with open(path, "w", encoding="utf-8", newline="") as file:
        file.write(",".join(header for header, _, _ in columns) + "\n")
        for first in range(0, samples, CSV_CHUNK_ROWS):
            stop = min(first + CSV_CHUNK_ROWS, samples)
            cells = [_format_column(values(first, stop), fmt) for _, values, fmt in columns]
            file.write("\n".join(",".join(row) for row in zip(*cells)) + "\n")
            del cells  # before the next chunk's are made: one chunk's cells at a time
            _release_samples(result)
    if len(result.vehicles) > WIDE_VEHICLE_LIMIT:
        write_traffic_csv(result, Path(path).with_name("traffic.csv"))


def write_traffic_csv(result: RunRecord, path: Path) -> None:
    """traffic.csv (runs with many vehicles): one row per vehicle per sample while it is on the road."""
    units = result.units
    length, speed = length_label(units), speed_label(units)
    time = _ego_column(result, "time")
    ego_station = _ego_column(result, "station")
    with open(path, "w", encoding="utf-8", newline="") as file:
        file.write(f"time_s,vehicle,model,station_{length},lateral_{length},speed_{speed},gap_{length},"
                   f"bumper_gap_{length}\n")
        unreleased = 0
        for track in result.vehicles:
            rows = slice(track.first, track.first + len(track.station))
            station = np.asarray(track.station, dtype=float)
            cells = [_format_column(np.asarray(time[rows], dtype=float), TIME_FORMAT),
                     [str(track.vehicle)] * len(station), [str(track.model)] * len(station),
                     _format_column(from_si(station, units), LENGTH_FORMAT),
                     _format_column(from_si(np.asarray(track.lateral, dtype=float), units), LENGTH_FORMAT),
                     _format_column(from_si(0.0 - np.asarray(track.speed, dtype=float), units), LENGTH_FORMAT),
                     _format_column(from_si(station - np.asarray(ego_station[rows], dtype=float), units),
                                    LENGTH_FORMAT),
                     _format_column(from_si(np.full(len(station), np.nan) if track.bumper_gap is None else
                                            np.asarray(track.bumper_gap, dtype=float), units), LENGTH_FORMAT)]
            if len(station):
                file.write("\n".join(",".join(row) for row in zip(*cells)) + "\n")
            unreleased += len(station)
            if unreleased > CSV_CHUNK_ROWS:
                _release_samples(result)
                unreleased = 0
    _release_samples(result)


def _release_samples(result: RunRecord) -> None:
    """Drops the disk-backed sample pages read so far from resident memory (`storage.release_pages`), so
    that writing a long run's files does not hold them all."""
    release_pages(_ego_column(result, "time"))
    table = getattr(result.vehicles, "table", None)
    if table is not None:
        release_pages(table)


def _json_ready(value):
    """Plain JSON types: numpy scalars unwrapped, floats rounded to 6 decimals, NaN/inf as null."""
    if isinstance(value, dict):
        return {str(key): _json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(item) for item in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return round(value, 6) if math.isfinite(value) else None
    if isinstance(value, np.ndarray):
        return _json_ready(value.tolist())
    if isinstance(value, Path):
        return str(value)
    return value


LATERAL_SIGN = ("positive to the driver's right of the dividing line (roadway frame; ISO 8855's y points left: "
                "lateral = -y)")


def key_units(units: Units) -> dict[str, str]:
    """summary.json's "key_units": the unit of each key of "final" and the events that carries one (the keys
    themselves keep their first names: docs/results.md), and the sign of lateral."""
    length, speed = length_label(units), speed_label(units)
    return {"time_s": "s", "distance": length, "speed": speed, "lateral": f"{length}, {LATERAL_SIGN}",
            "relative_speed": speed, "timing.wall_s": "s", "timing.real_time_factor": "simulated s per wall-clock s"}


def _summary_fields(result: RunRecord, events) -> dict:
    return {
        "scenario": Path(str(result.scenario_path)).name,  # its name: no machine's path in results
        "units": result.units,
        "key_units": key_units(result.units),
        "dynamics": result.dynamics,
        "seed": result.seed,
        "collisions": int(result.collisions),
        "final": scenario_units.final(result.final, result.units),
        "events": events,
        "warnings": list(result.warnings),
        "timing": result.timing,
        **({"vehicle": result.vehicle} if result.vehicle else {}),
        **({"criticality": scenario_units.criticality(result.criticality, result.units)}
           if result.criticality is not None else {}),
        **({"driver": result.driver} if result.driver is not None else {}),
        **({"controller": result.controller} if result.controller is not None else {}),
    }


def summary(result: RunRecord) -> dict:
    """summary.json content (docs/results.md, The files): final state, events and warnings in scenario units."""
    return _json_ready(_summary_fields(result, list(scenario_units.Events(result.events, result.units))))


_EVENTS_KEY = '\n  "events": []'  # where the events go in summary.json (no JSON string holds a raw newline)


def write_summary_json(result: RunRecord, path: Path) -> None:
    """summary.json, indented 2, strict JSON (no NaN): the same text as json.dumps(summary(result), indent=2),
    with the events streamed from the run's log one at a time instead of built as one list in memory."""
    text = json.dumps(_json_ready(_summary_fields(result, [])), indent=2, allow_nan=False)
    head, tail = text.split(_EVENTS_KEY, 1)
    with open(path, "w", encoding="utf-8") as file:
        file.write(head + _EVENTS_KEY[:-1])
        written = 0
        for event in scenario_units.Events(result.events, result.units):
            # an element of the events list sits two levels deep: every line of its own dump 4 spaces in
            item = json.dumps(_json_ready(event), indent=2, allow_nan=False).replace("\n", "\n    ")
            file.write(("," if written else "") + "\n    " + item)
            written += 1
        file.write(("\n  ]" if written else "]") + tail + "\n")


def write_results(result: RunRecord, out_dir: Path, plot: bool | Path = True) -> Path:
    """Write timeseries.csv, summary.json and plot.png into out_dir atomically: all of them or nothing, and
    nothing sdl-fmu did not write is touched (folder.py). `plot`: False for no plot; a Path: that PNG, already drawn
    of this record (plots.plot_run), copied in instead of drawing it again."""
    def write(folder: Path) -> None:
        write_timeseries_csv(result, folder / "timeseries.csv")
        write_summary_json(result, folder / "summary.json")
        if isinstance(plot, Path):
            import shutil

            shutil.copyfile(plot, folder / "plot.png")
        elif plot:
            from . import plots

            plots.plot_run(result, folder / "plot.png")

    return write_results_folder(out_dir, write, "run")
