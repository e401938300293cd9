"""The lead-vehicle signals of docs/export.md's variable table (lead_present, lead_id, lead_gap, lead_speed,
lead_relative_speed, lead_ttc, lead_lateral_offset): what a controller in the loop, the `follow` driver, the
criticality headway, the results' gap columns and the scenario FMU's outputs all read. One definition, computed
here; the scenario FMU's C runtime computes the same operations in the same order (its conformance test holds the
two equal bit for bit).

Frames and sign conventions (SI, ISO 8855 inertial frame of the road: x = station along the road, y = -lateral,
left positive; a traffic vehicle moving at `speed` toward decreasing station has the velocity -speed along x):
- the ego's footprint is its length x width rectangle about its reference point, turned by its yaw psi; along the
  road it reaches `a |cos psi| + b |sin psi|` ahead of its centre and across it `a |sin psi| + b |cos psi|`
  either side (a, b: half length and half width), the extents criticality's headway uses;
- a vehicle is *in the ego's path* when the footprints overlap laterally: |dy| < ego's lateral extent + the
  vehicle's half width (dy = its centre's y - the ego's), and *ahead* when its centre is ahead of the ego's
  (dx > 0);
- the *lead vehicle* is the vehicle in the path and ahead with the smallest bumper gap (ties: the lower index,
  i.e. the earlier spawn); whichever way it moves (an oncoming car in the ego's lane is a lead vehicle too);
- `lead_gap` = dx - the ego's extent ahead - the vehicle's half length, the bumper-to-bumper gap along the road,
  0 when the footprints' road extents overlap (in contact or about to be);
- `lead_speed` = the vehicle's velocity along the road (negative: it comes toward the ego);
- `lead_relative_speed` = lead_speed - the ego's velocity along the road (vx cos psi - vy sin psi); negative
  while the gap closes;
- `lead_ttc` = lead_gap / -lead_relative_speed while the gap closes (0 in contact), else NO_TTC;
- `lead_lateral_offset` = dy.
Without a lead vehicle: present false, id 0, gap NO_GAP, speed 0, relative speed 0, TTC NO_TTC, offset 0.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

NO_TTC = 1000.0  # s: lead_ttc while the gap does not close or there is no lead vehicle (a finite sentinel)
NO_GAP = 1000.0  # m: lead_gap without a lead vehicle (a finite sentinel)


class Lead(NamedTuple):
    """The lead-vehicle signals at one instant (SI); `index` is the traffic index (vehicle id - 1), -1 for none."""

    present: bool
    index: int
    gap: float
    speed: float
    relative_speed: float
    ttc: float
    lateral_offset: float

    @property
    def vehicle_id(self) -> int:
        """lead_id: the vehicle's id as summary.json gives it (1-based spawn order), 0 without a lead vehicle."""
        return self.index + 1


NO_LEAD = Lead(False, -1, NO_GAP, 0.0, 0.0, NO_TTC, 0.0)


def extents(length: float, width: float, psi: float) -> tuple[float, float]:
    """How far the ego's footprint reaches from its centre along the road and across it (m)."""
    a, b = length / 2, width / 2
    c, s = abs(math.cos(psi)), abs(math.sin(psi))
    return a * c + b * s, a * s + b * c


def lead_vehicle(ego_x: float, ego_y: float, ego_psi: float, ego_vx: float, ego_vy: float, ego_length: float,
                 ego_width: float, stations, laterals, speeds, lengths, widths, indices) -> Lead:
    """The lead-vehicle signals from the ego's state and the traffic vehicles on the road (sequences of station,
    lateral (+ right), speed (toward decreasing station), length and width, and their traffic indices, in
    ascending index order); plain floats, one pass (the C runtime's loop is the same)."""
    along, across = extents(ego_length, ego_width, ego_psi)
    best = -1
    best_gap = math.inf
    for k in range(len(indices)):
        dx = float(stations[k]) - ego_x
        if not dx > 0.0:
            continue
        dy = -float(laterals[k]) - ego_y
        if not abs(dy) < across + float(widths[k]) / 2:
            continue
        gap = dx - along - float(lengths[k]) / 2
        if gap < best_gap:
            best, best_gap = k, gap
    if best < 0:
        return NO_LEAD
    gap = best_gap if best_gap > 0.0 else 0.0
    speed = -float(speeds[best])
    ego_along = ego_vx * math.cos(ego_psi) - ego_vy * math.sin(ego_psi)
    relative = speed - ego_along
    if relative < 0.0:
        ttc = gap / -relative
    else:
        ttc = NO_TTC
    return Lead(True, int(indices[best]), gap, speed, relative, ttc, -float(laterals[best]) - ego_y)


def lead_of(state, ego_length: float, ego_width: float, traffic, t: float | None = None) -> Lead:
    """`lead_vehicle` for an EgoState and the master's Traffic (its active vehicles at the state's time)."""
    active = traffic.active
    if not len(active):
        return NO_LEAD
    t = state.time if t is None else t
    station, lateral, speed, _, _ = traffic.motion(active, t)
    return lead_vehicle(state.x, state.y, state.psi, state.vx, state.vy, ego_length, ego_width, station, lateral,
                        speed, traffic.length[active], traffic.width[active], active)


def bumper_gaps(dx, along: np.ndarray | float, lengths):
    """The bumper-to-bumper gap along the road to each vehicle (m; NumPy arrays or floats): for one ahead (dx, its
    centre's station minus the ego's, > 0) `lead_gap`'s dx - the ego's extent ahead - its half length, 0 when the
    footprints' road extents overlap; for one behind the same distance from its front to the ego's rear, negative
    (dx + the ego's extent + its half length, 0 when they overlap). `along`: `extents`' first value."""
    reach = along + lengths / 2
    return np.where(dx > 0.0, np.maximum(dx - along - lengths / 2, 0.0), np.minimum(dx + reach, 0.0))


def lead_track(ego_x, ego_y, ego_psi, ego_vx, ego_vy, ego_length: float, ego_width: float, vehicles) -> dict:
    """`lead_vehicle` at every sample of a run, vectorised over the samples (the same operations in the same order:
    the same bits, tested): the ego's sampled x, y, psi, vx, vy as arrays, and per traffic vehicle in ascending
    index order (index, first sample, station, lateral, speed arrays from that sample on, length, width). The
    ego's extents and cos / sin are taken with `math` per sample, as `lead_vehicle` takes them. Returns arrays
    `present`, `index` (-1: none), `gap`, `speed`, `relative_speed`, `ttc` and `lateral_offset`, with
    `lead_vehicle`'s values where there is no lead vehicle."""
    ego_x, ego_y = np.asarray(ego_x, dtype=float), np.asarray(ego_y, dtype=float)
    psi = np.asarray(ego_psi, dtype=float)
    samples = len(psi)
    a, b = ego_length / 2, ego_width / 2
    cos = np.array([math.cos(p) for p in psi.tolist()])
    sin = np.array([math.sin(p) for p in psi.tolist()])
    c, s = np.abs(cos), np.abs(sin)
    along, across = a * c + b * s, a * s + b * c
    best = np.full(samples, -1, dtype=np.int64)
    best_gap = np.full(samples, math.inf)
    best_speed = np.zeros(samples)
    best_lateral = np.zeros(samples)
    for index, first, station, lateral, speed, length, width in vehicles:
        rows = slice(first, first + len(station))
        station, lateral = np.asarray(station, dtype=float), np.asarray(lateral, dtype=float)
        with np.errstate(invalid="ignore"):
            dx = station - ego_x[rows]
            dy = -lateral - ego_y[rows]
            gap = dx - along[rows] - length / 2
            chosen = (dx > 0.0) & (np.abs(dy) < across[rows] + width / 2) & (gap < best_gap[rows])
        where = np.flatnonzero(chosen) + first
        best[where], best_gap[where] = index, gap[chosen]
        best_speed[where], best_lateral[where] = np.asarray(speed, dtype=float)[chosen], lateral[chosen]
    present = best >= 0
    gap = np.where(present, np.where(best_gap > 0.0, best_gap, 0.0), NO_GAP)
    speed = np.where(present, -best_speed, 0.0)
    ego_along = np.asarray(ego_vx, dtype=float) * cos - np.asarray(ego_vy, dtype=float) * sin
    relative = np.where(present, speed - ego_along, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ttc = np.where(present & (relative < 0.0), gap / -relative, NO_TTC)
    offset = np.where(present, -best_lateral - ego_y, 0.0)
    return {"present": present, "index": best, "gap": gap, "speed": speed, "relative_speed": relative, "ttc": ttc,
            "lateral_offset": offset}
