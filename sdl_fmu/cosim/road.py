"""The road: lanes from ROAD, surface sections from RSA, and where each wheel touches them.

Road frame: station = metres along the road from the ego's start, lateral = metres from the dividing
line, positive to the driver's right. The ego's inertial frame (ISO 8855, x forward, y left) has its
origin on the dividing line at station 0, so station = x and lateral = -y.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from itertools import accumulate

from ..lazy_sequence import LazySequence
from ..results import SurfaceSection
from ..sdl.events import Road, Scenario, SurfaceAttribute



@dataclass(frozen=True)
class SurfaceMap:
    """Per-lane RSA values along the road: a value holds from its station until the lane is set again."""

    starts: dict  # lane -> sorted stations (m)
    values: dict  # lane -> values, same order
    default: float

    def value(self, lane: int, station: float) -> float:
        starts = self.starts.get(lane)
        if not starts:
            return self.default
        position = bisect.bisect_right(starts, station) - 1
        return self.values[lane][position] if position >= 0 else self.default


def surface_map(scenario: Scenario, default: float) -> SurfaceMap:
    """default: the value of a lane nobody set (EgoModel.default_surface)."""
    starts: dict[int, list[float]] = {}
    values: dict[int, list[float]] = {}
    for event in scenario.events:
        if isinstance(event, SurfaceAttribute):
            for lane, value in event.settings:
                starts.setdefault(lane, []).append(event.distance)
                values.setdefault(lane, []).append(float(value))
    return SurfaceMap(starts, values, default)


class SurfaceSections(LazySequence):
    """Every RSA-set stretch of the road as SurfaceSection, lane by lane in station order, made when asked
    for from the surface map (no object per section held: a long scenario has tens of thousands)."""

    def __init__(self, surfaces: SurfaceMap):
        self.surfaces = surfaces
        self.lanes = list(surfaces.starts)
        self.ends = list(accumulate(len(surfaces.starts[lane]) for lane in self.lanes))  # running counts

    def __len__(self) -> int:
        return self.ends[-1] if self.ends else 0

    def _item(self, index: int) -> SurfaceSection:
        k = bisect.bisect_right(self.ends, index)
        return self._section(self.lanes[k], index - (self.ends[k - 1] if k else 0))

    def __iter__(self):
        for lane in self.lanes:
            for i in range(len(self.surfaces.starts[lane])):
                yield self._section(lane, i)

    def _section(self, lane: int, i: int) -> SurfaceSection:
        starts = self.surfaces.starts[lane]
        end = starts[i + 1] if i + 1 < len(starts) else None
        return SurfaceSection(lane, starts[i], end, self.surfaces.values[lane][i])

    def __repr__(self) -> str:
        return f"SurfaceSections({len(self)} sections)"


def surface_sections(surfaces: SurfaceMap) -> SurfaceSections:
    return SurfaceSections(surfaces)


@dataclass(frozen=True)
class WheelGeometry:
    """Contact points relative to the centre of gravity (m): axles ahead/behind it, half tracks."""

    front: float
    rear: float
    half_track_front: float
    half_track_rear: float

    def contact_points(self, x: float, y: float, psi: float) -> list[tuple[float, float]]:
        """(station, lateral) of the fl, fr, rl, rr contact points."""
        cos_psi, sin_psi = math.cos(psi), math.sin(psi)
        points = []
        for along, left in ((self.front, self.half_track_front), (self.front, -self.half_track_front),
                            (-self.rear, self.half_track_rear), (-self.rear, -self.half_track_rear)):
            points.append((x + along * cos_psi - left * sin_psi, -(y + along * sin_psi + left * cos_psi)))
        return points


def wheel_geometry(model) -> WheelGeometry:
    """From the EgoModel's contact points (fl, fr, rl, rr; x forward, y left of the CG)."""
    (front, half_track_front), _, (rear, half_track_rear), _ = model.wheels
    return WheelGeometry(front, -rear, half_track_front, half_track_rear)


def wheel_surfaces(road: Road, surfaces: SurfaceMap, points: list[tuple[float, float]]) -> tuple[float, ...]:
    """The surface value under each contact point, from the lane it is in."""
    value, lane_at = surfaces.value, road.lane_at
    return tuple([value(lane_at(lateral), station) for station, lateral in points])
