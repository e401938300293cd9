"""The footprints' overlap and how soon a margin can close: the arithmetic that the trigger bounds (triggers.py)
and the criticality measures (measures.py) share, written once.

Frames: ISO 8855 inertial, x = station, y = -lateral (road.py). The ego's footprint is its length x width
rectangle about its reference point, turned by its yaw psi; a traffic vehicle's is aligned with the road. An
offset (dx, dy) is the vehicle's centre minus the ego's.

Forms: each function on plain floats and on NumPy arrays over vehicles doing the same operations in the same
order, so that the two give the same bits (the master picks one or the other by the number of vehicles,
SCALAR_VEHICLES, and what it locates must not depend on that).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

# up to this many vehicles are handled one by one in plain floats, more at once in NumPy arrays: on a few
# vehicles NumPy's per-operation overhead (about 1 µs on small arrays) costs more than the arithmetic (the trigger
# schedule and the criticality record use the same bound)
SCALAR_VEHICLES = 4


class Footprint(NamedTuple):
    """The ego's footprint at one instant: half length and width, cos and sin of its yaw (made once per
    instant and shared by every vehicle; cos and sin may be arrays, one per instant)."""

    half_length: float
    half_width: float
    cos: float
    sin: float

    @staticmethod
    def of(length: float, width: float, psi: float) -> Footprint:
        return Footprint(length / 2, width / 2, math.cos(psi), math.sin(psi))


def axis_reaches(ego: Footprint, length, width):
    """(hx, hy, hu, hv): along each of the four separating axes of the two footprints (the road's x and y, the
    ego's body axes u and v) the sum of their half extents, i.e. how far apart their centres may be along it
    with their projections still overlapping. Floats or arrays."""
    a, b, c, s = ego
    ac, as_ = abs(c), abs(s)
    hl, hw = length / 2, width / 2
    return a * ac + b * as_ + hl, a * as_ + b * ac + hw, a + hl * ac + hw * as_, b + hl * as_ + hw * ac


def overlaps(ego: Footprint, dx, dy, length, width):
    """How far the two footprints' projections overlap on each of the four separating axes (x, y, u, v; > 0:
    they overlap along it). The footprints overlap when all four do (the separating-axis theorem), and the
    smallest is then the penetration depth. Floats or arrays."""
    a, b, c, s = ego
    ac, as_ = abs(c), abs(s)
    hl, hw = length / 2, width / 2
    return (a * ac + b * as_ + hl - abs(dx),
            a * as_ + b * ac + hw - abs(dy),
            a + hl * ac + hw * as_ - abs(dx * c + dy * s),
            b + hl * as_ + hw * ac - abs(-dx * s + dy * c))


def penetration(ego: Footprint, dx: float, dy: float, length: float, width: float) -> float:
    """The overlap depth of the two footprints (> 0: they overlap; >= 0: they touch): the smallest overlap of
    their projections on the four separating axes, which for convex polygons is the penetration depth (the
    shortest translation that separates them). `overlaps`' operations written out for plain floats (the per-probe
    path: no calls), in the same order: the same bits."""
    a, b, c, s = ego
    ac = c if c >= 0.0 else -c
    as_ = s if s >= 0.0 else -s
    hl, hw = length / 2, width / 2
    along_x = a * ac + b * as_ + hl - (dx if dx >= 0.0 else -dx)
    along_y = a * as_ + b * ac + hw - (dy if dy >= 0.0 else -dy)
    du, dv = dx * c + dy * s, -dx * s + dy * c
    along_u = a + hl * ac + hw * as_ - (du if du >= 0.0 else -du)
    along_v = b + hl * as_ + hw * ac - (dv if dv >= 0.0 else -dv)
    least = along_y if along_y < along_x else along_x  # min(min(x, y), min(u, v)) without the calls
    other = along_v if along_v < along_u else along_u
    return other if other < least else least


def penetrations(ego: Footprint, dx, dy, length, width):
    """`penetration` over arrays of vehicles."""
    along_x, along_y, along_u, along_v = overlaps(ego, dx, dy, length, width)
    return np.minimum(np.minimum(along_x, along_y), np.minimum(along_u, along_v))


def reach_time(distance, rate, acceleration):
    """Smallest tau >= 0 with rate tau + acceleration tau^2 / 2 >= distance: the earliest instant a margin
    `distance` can be used up when it shrinks now at `rate` (signed, + shrinking) and that rate grows at
    most by `acceleration`. Zero for a margin already used up. Arrays (or scalars, at an array's cost)."""
    used_up = distance <= 0.0
    distance = np.maximum(distance, 0.0)
    root = np.sqrt(rate * rate + 2 * acceleration * distance)
    # two forms of the same root, each free of cancellation on its side of rate = 0; a margin already used up
    # is 0 whatever the rate (the root form alone would give the later root -2 rate / acceleration)
    return np.where(used_up, 0.0,
                    np.where(rate > 0, 2 * distance / np.maximum(rate + root, 1e-300), (root - rate) / acceleration))


def reach_time_scalar(distance: float, rate: float, acceleration: float) -> float:
    """`reach_time` for plain floats (the per-step path: no array overhead), operation for operation, so that
    the two give the same bits (step ends, and so the samples, depend on it)."""
    if distance <= 0.0:
        return 0.0
    root = math.sqrt(rate * rate + 2 * acceleration * distance)
    if rate > 0:
        closing = rate + root  # max(rate + root, 1e-300) without the call (the same value)
        return 2 * distance / (1e-300 if 1e-300 > closing else closing)
    return (root - rate) / acceleration
