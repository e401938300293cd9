"""What a run produced, and writing it: timeseries.csv, summary.json, plot.png (atomically)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .results_folder import write_results_folder
from .sdl.events import Road
from .units import from_si, length_label, speed_label


@dataclass
class VehicleTrack:
    """One traffic vehicle, sampled at the run's sample times (NaN while it is not on the road)."""

    vehicle: int  # id, 1-based in spawn order
    model: int
    name: str
    length: float  # m
    width: float  # m
    station: np.ndarray  # m along the road from the ego's start
    lateral: np.ndarray  # m from the dividing line, + right
    speed: np.ndarray  # m/s, + toward the ego's start (approaching)


@dataclass(frozen=True)
class SurfaceSection:
    """A stretch of one lane with a surface value set by RSA (SI stations; end None = to the road's end)."""

    lane: int
    start: float
    end: float | None
    value: float


@dataclass
class RunResult:
    """Everything a run produced, in SI; converted to the scenario's units only when written."""

    scenario_path: str
    units: str  # "English" or "Metric"
    dynamics: str  # "simple" or "advanced"
    seed: int
    road: Road
    # ego time series, SI, one entry per sample: time, x, y, psi, s, v, vx, vy, ax, ay, yaw_rate, stopped,
    # station, lateral, throttle, brake, steer, brk (1 while a BRK event holds the pedals), and per wheel
    # mu_fl.. (simple) or surface_fl.. (advanced)
    columns: dict[str, np.ndarray]
    vehicles: list[VehicleTrack]
    events: list[dict]  # summary.json entries, already in the scenario's units
    collisions: int
    collision_points: list[tuple[float, float]]  # (station, lateral) in m, for the plot
    surfaces: list[SurfaceSection]
    warnings: list[str] = field(default_factory=list)
    final: dict = field(default_factory=dict)  # summary "final", scenario units


WHEELS = ("fl", "fr", "rl", "rr")

TIME_FORMAT = "%.6f"
LENGTH_FORMAT = "%.4f"  # distances, positions and speeds in ft, ft/s or m, m/s
GENERAL_FORMAT = "%.6g"  # accelerations, angles, rates, pedals, mu


def _ego_column(result: RunResult, name: str) -> np.ndarray:
    """One ego time series as a float array; a missing column is a bug in whoever built the RunResult."""
    try:
        return np.asarray(result.columns[name], dtype=float)
    except KeyError:
        raise KeyError(f"RunResult.columns has no {name!r} (has {sorted(result.columns)})") from None


def timeseries_table(result: RunResult) -> list[tuple[str, np.ndarray, str]]:
    """The timeseries.csv columns as (header with unit, values in scenario units, printf format)."""
    units = result.units
    length, speed = length_label(units), speed_label(units)
    accel = f"{length}/s2"

    def scenario(name: str) -> np.ndarray:
        return from_si(_ego_column(result, name), units)

    station = _ego_column(result, "station")
    table = [
        ("time_s", _ego_column(result, "time"), TIME_FORMAT),
        (f"distance_{length}", scenario("s"), LENGTH_FORMAT),
        (f"station_{length}", from_si(station, units), LENGTH_FORMAT),
        (f"lateral_{length}", scenario("lateral"), LENGTH_FORMAT),
        (f"speed_{speed}", scenario("v"), LENGTH_FORMAT),
        (f"vx_{speed}", scenario("vx"), LENGTH_FORMAT),
        (f"vy_{speed}", scenario("vy"), LENGTH_FORMAT),
        (f"ax_{accel}", scenario("ax"), GENERAL_FORMAT),
        (f"ay_{accel}", scenario("ay"), GENERAL_FORMAT),
        ("yaw_rate_rad/s", _ego_column(result, "yaw_rate"), GENERAL_FORMAT),
        ("psi_rad", _ego_column(result, "psi"), GENERAL_FORMAT),
        ("throttle_1", _ego_column(result, "throttle"), GENERAL_FORMAT),
        ("brake_1", _ego_column(result, "brake"), GENERAL_FORMAT),
        ("steer_rad", _ego_column(result, "steer"), GENERAL_FORMAT),
        ("brk_active", (_ego_column(result, "brk") > 0.5).astype(float), "%d"),
        ("stopped", (_ego_column(result, "stopped") > 0.5).astype(float), "%d"),
    ]
    for wheel in WHEELS:
        if f"mu_{wheel}" in result.columns:
            table.append((f"mu_{wheel}_1", _ego_column(result, f"mu_{wheel}"), GENERAL_FORMAT))
    for wheel in WHEELS:
        if f"surface_{wheel}" in result.columns:
            table.append((f"surface_{wheel}", np.round(_ego_column(result, f"surface_{wheel}")), "%d"))
    for track in result.vehicles:
        prefix = f"A{track.vehicle}"
        vehicle_station = np.asarray(track.station, dtype=float)
        table += [
            (f"{prefix}_station_{length}", from_si(vehicle_station, units), LENGTH_FORMAT),
            (f"{prefix}_lateral_{length}", from_si(np.asarray(track.lateral, dtype=float), units), LENGTH_FORMAT),
            (f"{prefix}_speed_{speed}", from_si(np.asarray(track.speed, dtype=float), units), LENGTH_FORMAT),
            (f"{prefix}_gap_{length}", from_si(vehicle_station - station, units), LENGTH_FORMAT),
        ]
    samples = len(table[0][1])
    for header, values, _ in table:
        if len(values) != samples:
            raise ValueError(f"column {header} has {len(values)} samples, time has {samples}")
    return table


def _format_column(values: np.ndarray, fmt: str) -> list[str]:
    """Printf-format every value; NaN (vehicle absent, value unknown) becomes an empty cell."""
    return [fmt % value if math.isfinite(value) else "" for value in values.tolist()]


def write_timeseries_csv(result: RunResult, path: Path) -> None:
    """timeseries.csv: one row per sample, units in the headers, scenario units for lengths and speeds."""
    table = timeseries_table(result)
    cells = [_format_column(values, fmt) for _, values, fmt in table]
    lines = [",".join(header for header, _, _ in table)]
    lines += [",".join(row) for row in zip(*cells)]
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


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


def summary(result: RunResult) -> dict:
    """summary.json content (SPEC section 4): final state, events and warnings in scenario units."""
    return _json_ready({
        "scenario": str(result.scenario_path),
        "units": result.units,
        "dynamics": result.dynamics,
        "seed": result.seed,
        "collisions": int(result.collisions),
        "final": result.final,
        "events": result.events,
        "warnings": list(result.warnings),
    })


def write_summary_json(result: RunResult, path: Path) -> None:
    """summary.json, indented 2, strict JSON (no NaN)."""
    text = json.dumps(summary(result), indent=2, allow_nan=False)
    Path(path).write_text(text + "\n", encoding="utf-8")


def write_results(result: RunResult, out_dir: Path, plot: bool = True) -> Path:
    """Write timeseries.csv, summary.json and plot.png into out_dir atomically: all of them or nothing, and
    nothing sdl-fmu did not write is touched (results_folder)."""
    def write(folder: Path) -> None:
        write_timeseries_csv(result, folder / "timeseries.csv")
        write_summary_json(result, folder / "summary.json")
        if plot:
            from . import plots

            plots.plot_run(result, folder / "plot.png")

    return write_results_folder(out_dir, write)
