"""What a run produced, in SI: the ego's time series, the traffic's tracks, events, surfaces. Made by the run
stage (cosim/), written by files.py and drawn by plots.py; it imports neither stage."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..lazy_sequence import LazySequence
from ..sdl.events import Road
from ..units import Units


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
    speed: np.ndarray  # m/s, + toward the ego's start (approaching: the SDL A event's sign)
    first: int = 0  # sample index of the arrays' first entry: they cover samples first .. first + len - 1
    # m, the bumper-to-bumper gap along the road (signals.bumper_gaps: + ahead of the ego, - behind, 0 while the
    # footprints overlap along the road); None: not known (a track made without the ego's footprint)
    bumper_gap: np.ndarray | None = None

    def dense(self, name: str, samples: int) -> np.ndarray:
        """One of station / lateral / speed / bumper_gap over all `samples` samples, NaN where the vehicle is absent
        (or the gap not known)."""
        if getattr(self, name) is None:
            return np.full(samples, np.nan)
        values = np.asarray(getattr(self, name), dtype=float)
        if self.first == 0 and len(values) == samples:
            return values
        out = np.full(samples, np.nan)
        out[self.first:self.first + len(values)] = values[:max(samples - self.first, 0)]
        return out


class VehicleTracks(LazySequence):
    """A run's traffic vehicles in spawn order, held as a few numbers per vehicle over one (rows, 4) table of
    station, lateral, speed, bumper gap (disk-backed for a long run); each VehicleTrack is made when it is asked for,
    so that thousands of vehicles cost no Python objects until used."""

    def __init__(self, table: np.ndarray, vehicles: np.ndarray, models: list, first: np.ndarray,
                 offsets: np.ndarray):
        self.table = table  # rows offsets[k]:offsets[k + 1] are vehicle k's samples
        self.vehicles = vehicles  # ids
        self.models = models  # VehicleModel of each vehicle
        self.first = first  # sample index of each vehicle's first row
        self.offsets = offsets

    def __len__(self) -> int:
        return len(self.vehicles)

    def _item(self, index: int) -> VehicleTrack:
        model = self.models[index]
        block = self.table[self.offsets[index]:self.offsets[index + 1]]
        return VehicleTrack(int(self.vehicles[index]), model.number, model.name, model.length, model.width,
                            block[:, 0], block[:, 1], block[:, 2], first=int(self.first[index]),
                            bumper_gap=block[:, 3])

    def __repr__(self) -> str:
        return f"VehicleTracks({len(self)} vehicles)"


@dataclass(frozen=True)
class SurfaceSection:
    """A stretch of one lane with a surface value set by RSA (SI stations; end None = to the road's end)."""

    lane: int
    start: float
    end: float | None
    value: float


@dataclass
class RunRecord:
    """Everything a run produced, all in SI (m, m/s, m/s2, s, rad): the time series, the traffic's tracks, the
    events, the final state and the criticality measures. `units` is the scenario's: the results are converted to
    it only where they are given out (scenario_units.py: summary.json, api.Result, the plot; files.py: the CSV)."""

    scenario_path: str
    units: Units
    dynamics: str  # the vehicle's name: "simple" or "advanced" for the shipped maps, else its map's or FMU's
    seed: int
    road: Road
    # ego time series, SI, one entry per sample: time, x, y, psi, s, v, vx, vy, ax, ay, yaw_rate, stopped,
    # station, lateral, throttle, brake, steer, brk (1 while a BRK event holds the pedals), and per wheel
    # mu_fl.. (friction meaning "mu") or surface_fl.. ("attribute"), none for a vehicle without friction input
    columns: dict[str, np.ndarray]
    vehicles: Sequence[VehicleTrack]  # a list, or VehicleTracks (made on demand) from the master
    # summary.json's events with the ego's distance, speed, lateral (and a BRK threshold's magnitude) in SI (a
    # list, or the master's EventLog: read back from its file on demand)
    events: Sequence[dict]
    collisions: int
    collision_points: list[tuple[float, float]]  # (station, lateral) in m, for the plot
    surfaces: Sequence[SurfaceSection]  # a list, or the road's SurfaceSections (made on demand)
    warnings: list[str] = field(default_factory=list)
    final: dict = field(default_factory=dict)  # summary "final": time_s, distance (m), speed (m/s), lateral (m)
    timing: dict = field(default_factory=dict)  # summary "timing": wall_s, real_time_factor, steps, samples
    friction_meaning: str | None = "mu"  # what an RSA value means for the vehicle: "mu", "attribute" or None
    vehicle: dict = field(default_factory=dict)  # summary "vehicle": the EgoModel's summary and the bounds used
    # summary "criticality" (docs/results.md): run-wide and per-vehicle extremes, SI (min_distance m, max_drac
    # m/s2, times s); None: not measured
    criticality: dict | None = None
    # s per sample, the smallest time to collision (nan: none defined), computed when called (the plot)
    ttc_series: Callable[[], np.ndarray] | None = None
    # per sample, the lead vehicle (docs/results.md: a vehicle ahead in the ego's path) as arrays `present`, `index`
    # (traffic index, -1: none), `gap` (bumper to bumper, m), `speed` (m/s along the road, + the ego's way),
    # `relative_speed`, `ttc` (s), `lateral_offset` (m), computed when called (the plot)
    lead_series: Callable[[], dict] | None = None
    controller: dict | None = None  # summary "controller" (docs/controllers.md): a controller in the loop, or None
    driver: dict | None = None  # summary "driver": the follow driver's law and parameters; None for the lane driver
