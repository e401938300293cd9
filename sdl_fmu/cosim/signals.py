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
