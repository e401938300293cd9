"""The run's record: the ego's samples at every communication point and the traffic vehicles' spans, kept in
disk-backed tables (storage.py), and the traffic's samples and TTC curve made from them at the end."""

from __future__ import annotations

import math
from array import array

import numpy as np

from ..results import VehicleTracks
from ..results.storage import ChunkedTable, release_pages
from ..vehicle import EgoState
from .extremes import RANGE
from .geometry import Footprint
from .measures import distances, ttcs
from .signals import bumper_gaps, extents, lead_track
from .traffic import Traffic
from .triggers import EgoBounds

RELEASE_ROWS = 20_000  # sample rows read from a disk-backed table between releases of its pages (~3.5 MB)

# Recorder.record copies the state's fields in their order, then these, then the model's wheel columns
EGO_COLUMNS = (*EgoState._fields, "station", "lateral", "throttle", "brake", "steer", "brk")
STOPPED = EgoState._fields.index("stopped")


class Recorder:
    """The ego's samples (one row per communication point, EGO_COLUMNS then the wheel inputs) and, per traffic
    vehicle, its id and the samples it spawned and left at; the vehicles' own samples come from their
    closed-form motions at the end (`vehicle_tracks`)."""

    def __init__(self, wheel_columns: list[str], extra_columns: tuple[str, ...] = ()):
        self.wheel_columns = wheel_columns
        self.extra_columns = extra_columns  # after the wheel columns (a controller's: inputs.CONTROLLER_COLUMNS)
        self.ego_rows = ChunkedTable(len(EGO_COLUMNS) + len(wheel_columns) + len(extra_columns))
        self.sample_count = 0
        self.vehicle_ids = array("q")  # per vehicle (index = id - 1), its id
        # per vehicle, its first sample and the sample it left at (-1 while on the road); compact arrays
        self.spawn_sample = array("q")
        self.leave_sample = array("q")

    def record(self, state: EgoState, controls: tuple, braking: bool, wheel_values: tuple, extra: tuple = ()) -> None:
        # EGO_COLUMNS: the state's fields in their order (time ... yaw_rate, stopped), station, lateral, the
        # controls, brk, then the wheel inputs and the extra columns
        self.ego_rows.append((*state[:STOPPED], float(state.stopped), state.x, -state.y, *controls,
                              float(braking), *wheel_values, *extra))
        self.sample_count += 1

    def spawned(self, vehicle_id: int) -> None:
        self.vehicle_ids.append(vehicle_id)
        self.spawn_sample.append(self.sample_count)
        self.leave_sample.append(-1)

    def left(self, i: int) -> None:
        self.leave_sample[i] = self.sample_count

    def columns(self) -> dict[str, np.ndarray]:
        """The ego's samples by column name (ends the recording)."""
        table = self.ego_rows.finish()
        return {name: table[:, i] for i, name in enumerate((*EGO_COLUMNS, *self.wheel_columns, *self.extra_columns))}

    def vehicle_tracks(self, traffic: Traffic, columns: dict, ego_length: float, ego_width: float) -> VehicleTracks:
        """Each vehicle's samples from its closed-form motion, from its spawn to the sample it left at, and the
        bumper gap to it (signals.bumper_gaps, the ego's extent along the road at each sample), into one
        disk-backed table; the samples are read in order and their pages released as it goes (memory stays
        bounded)."""
        times, ego_x, psi = columns["time"], columns["x"], columns["psi"]
        first = np.array(self.spawn_sample, dtype=np.int64)
        last = np.array(self.leave_sample, dtype=np.int64)
        last[last < 0] = self.sample_count  # still on the road at the end
        track_rows = ChunkedTable(4)
        # the ego's extent ahead of its centre along the road at each sample (signals.extents, with math per sample)
        along = np.array([extents(ego_length, ego_width, angle)[0] for angle in np.asarray(psi).tolist()]) \
            if len(first) else np.zeros(0)
        release_pages(psi)
        unreleased = 0
        for i in range(len(first)):
            rows = slice(first[i], last[i])
            station, lateral, speed = traffic.track(i, np.asarray(times[rows]))
            gap = bumper_gaps(station - np.asarray(ego_x[rows]), along[rows], float(traffic.length[i]))
            track_rows.extend(np.column_stack((station, lateral, speed, gap)))
            unreleased += last[i] - first[i]
            if unreleased > RELEASE_ROWS:
                for column in (times, ego_x):
                    release_pages(column)
                unreleased = 0
        for column in (times, ego_x):
            release_pages(column)
        offsets = np.concatenate([[0], np.cumsum(last - first)])
        return VehicleTracks(track_rows.finish(), np.array(self.vehicle_ids, dtype=np.int64), traffic.models,
                             first, offsets)

    def spans(self) -> tuple[np.ndarray, np.ndarray]:
        """Per vehicle, its first sample and the sample it left at (-1: still on the road)."""
        return np.array(self.spawn_sample, dtype=np.int64), np.array(self.leave_sample, dtype=np.int64)


def ttc_series(traffic: Traffic, first: np.ndarray, last: np.ndarray, bounds: EgoBounds, columns: dict) -> np.ndarray:
    """Per sample, the smallest time to collision over the vehicles within RANGE (s; nan where no vehicle is on
    a collision course): the plot's TTC curve, from the samples and the vehicles' closed-form motions (each
    vehicle from its first sample to the one it left at, -1: still on the road), computed when asked for
    (RunRecord.ttc_series), not during the run; not part of timeseries.csv."""
    times = np.asarray(columns["time"])
    series = np.full(len(times), np.inf)
    last = np.where(last < 0, len(times), last)
    for i in range(len(first)):
        rows = slice(first[i], last[i])
        t = times[rows]
        motions = traffic.history(i)
        k = np.maximum(np.searchsorted(motions[:, 0], t, side="right") - 1, 0)
        t0, _, lateral0, _, lateral1, _, duration = motions[k].T
        moving = t - t0 < duration
        lateral_rate = np.where(moving, (lateral1 - lateral0) / np.where(moving, duration, 1.0), 0.0)
        station, lateral, speed = traffic.track(i, t)
        dx, dy = station - np.asarray(columns["x"][rows]), -lateral - np.asarray(columns["y"][rows])
        length, width = float(traffic.length[i]), float(traffic.width[i])
        # only where the centres are within RANGE plus both footprints' radii can the footprints be
        near = np.flatnonzero(np.sqrt(dx * dx + dy * dy) <= RANGE + bounds.radius
                              + 0.5 * math.sqrt(length * length + width * width))
        if not len(near):
            continue
        dx, dy = dx[near], dy[near]
        psi = np.asarray(columns["psi"][rows])[near]
        c, s = np.cos(psi), np.sin(psi)
        vx, vy = np.asarray(columns["vx"][rows])[near], np.asarray(columns["vy"][rows])[near]
        ego = Footprint(bounds.length / 2, bounds.width / 2, c, s)
        value = ttcs(ego, dx, dy, -speed[near] - (vx * c - vy * s), -lateral_rate[near] - (vx * s + vy * c),
                     length, width)
        value = np.where(distances(ego, dx, dy, length, width) <= RANGE, value, np.inf)
        index = near + first[i]
        series[index] = np.minimum(series[index], value)
    series[~np.isfinite(series)] = np.nan
    return series


def lead_series(traffic: Traffic, first: np.ndarray, last: np.ndarray, bounds: EgoBounds, columns: dict) -> dict:
    """Per sample, the lead-vehicle signals (signals.lead_track: whether there is a vehicle ahead in the ego's
    path, its index, the bumper gap to it, its speed along the road, ...) from the samples and the vehicles'
    closed-form motions, computed when asked for (RunRecord.lead_series: the plot), not during the run."""
    last = np.where(last < 0, len(columns["time"]), last)
    times = np.asarray(columns["time"])
    vehicles = ((i, int(first[i]), *traffic.track(i, times[first[i]:last[i]]), float(traffic.length[i]),
                 float(traffic.width[i])) for i in range(len(first)))
    return lead_track(columns["x"], columns["y"], columns["psi"], columns["vx"], columns["vy"], bounds.length,
                      bounds.width, vehicles)
