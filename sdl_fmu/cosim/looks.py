"""One traffic vehicle relative to the ego at one state, for the criticality record (extremes.py): the arithmetic
of a look (`evaluate`, then `horizon`), a course check (`course_check`) and a closest approach's probe
(`distance_rate`), on plain floats and tuples, nothing recorded.

Two twins do it. `_kernel.c` (built by setup.py where a C compiler is found, `KERNEL`) is the one runs use; the
functions below are the same operations in the same order in Python, used where the package was installed without
it, and the reference the kernel is held to bit for bit (tests/cosim/test_kernel.py). Their arguments:
- at: the ego at the state (Extremes._ego_at: its footprint, cos and sin of its yaw, its velocity on the road's
  axes, its own parts of the road axes' reaches);
- row: the vehicle's motion (traffic.Traffic.row), size: its (length, width);
- t, x, y, ax, ay, yaw_rate: the ego's state (EgoState's time, position, body-frame acceleration, yaw rate);
- acceleration, yaw_rate_bound, radius: the ego's bounds (EgoBounds), as in triggers.py.
What each value means, and the proofs of the bounds: extremes.py and measures.py."""

from __future__ import annotations

import math
import sys

from .geometry import reach_time_scalar
from .measures import (INF, approach_horizon, course_horizon, distance_and_rates, drac, drac_rate_known, headway,
                       headway_rate_known, heading_horizon, ttc, ttc_rate_known)
from .traffic import motion_law

try:  # the compiled twin (setup.py); None where the package was installed without it
    from . import _kernel as KERNEL
except ImportError:
    KERNEL = None

FLAT = 1e-9  # m or s: a later instant replaces a recorded extreme only if it is better by more than this
# m: TTC, DRAC and headway are followed while the footprints are within this distance, as SUMO's SSM device
# follows encounters within device.ssm.range (default 50 m); the distance everywhere
RANGE = 50.0


def evaluate(at, row, size, t: float, x: float, y: float, ax: float, ay: float, yaw_rate: float):
    """(the values to offer: distance, TTC, DRAC, headway; their rates: the distance's, TTC's, minus DRAC's, the
    headway's; what the horizon needs: distance, its rate with the ego's yaw frozen, dx, dy, vx, vy, length,
    width, the vehicle's speed rate, the time left in its transition, the ego's footprint, the road axes' reaches
    (None beyond RANGE)). Beyond RANGE only the distance and its rates (the others inf or nan: not offered)."""
    ego, c, s, ego_vx, ego_vy, ego_x, ego_y = at
    station, lateral, speed, lateral_rate, _ = motion_law(row, t)
    t0, _, _, speed0, _, speed1, duration = row
    elapsed = t - t0
    moving = elapsed < duration
    speed_rate = (speed1 - speed0) / duration if moving else 0.0
    length, width = size
    dx, dy = station - x, -lateral - y
    vx, vy = -speed - ego_vx, -lateral_rate - ego_vy
    d, rate, frozen = distance_and_rates(ego, dx, dy, vx, vy, yaw_rate, length, width)
    if d > RANGE:
        motion = (d, frozen, dx, dy, vx, vy, length, width, speed_rate, duration - elapsed if moving else INF,
                  ego, None, None)
        return (d, INF, math.nan, INF), (rate, math.nan, math.nan, math.nan), motion
    # the road axes' reaches once, for `ttc`'s and `headway`'s common decision (a car in another lane: off
    # course by the road's axes, not ahead in the ego's path) and for the look's course_horizon
    reach_x, reach_y = ego_x + length / 2, ego_y + width / 2  # axis_reaches' first two
    motion = (d, frozen, dx, dy, vx, vy, length, width, speed_rate, duration - elapsed if moving else INF, ego,
              reach_x, reach_y)
    value = INF if off_course(dx, dy, vx, vy, reach_x, reach_y) else ttc(ego, dx, dy, vx, vy, length, width)
    ego_ax = ax * c - ay * s
    gap_time = INF if (not dx > 0.0 or (dy if dy >= 0.0 else -dy) >= reach_y or ego_vx <= 0.0
                       or -speed < 0.0) else headway(ego, dx, dy, ego_vx, -speed, length, width)
    headway_change = math.nan if gap_time == INF else \
        headway_rate_known(ego, gap_time, ego_vx, -speed, ego_ax, yaw_rate)
    if not 0.0 < value < INF:
        return (d, value, math.nan, gap_time), (rate, math.nan, math.nan, headway_change), motion
    rel_ax, rel_ay = -speed_rate - ego_ax, -(ax * s + ay * c)
    value_rate = ttc_rate_known(ego, dx, dy, vx, vy, rel_ax, rel_ay, yaw_rate, length, width)
    return ((d, value, drac(value, vx, vy), gap_time),
            (rate, value_rate, -drac_rate_known(value, value_rate, vx, vy, rel_ax, rel_ay), headway_change), motion)


def horizon(motion, rate: float, recorded: float, acceleration: float, yaw_rate_bound: float,
            radius: float) -> tuple[float, float, float]:
    """Extremes.look's bounds for a vehicle not within RANGE on a collision course or with a headway, from
    `evaluate`'s third value, its distance rate and the vehicle's recorded minimum distance: (the horizon, quiet,
    course) that Extremes.look returns and leaves."""
    d, frozen, dx, dy, vx, vy, length, width, speed_rate, transition_left, _, reach_x, reach_y = motion
    near = d <= RANGE
    # min(x, y) written as `y if y < x else x` and max(x, y) as `y if y > x else x` (what the builtins return, nan
    # included), without their calls
    turn = radius * yaw_rate_bound
    relative = acceleration + (speed_rate if speed_rate >= 0.0 else -speed_rate)
    new_minimum = reach_time_scalar(d - (recorded - FLAT), turn - frozen, relative)
    # a closest approach (the distance's rate turning from < 0 to >= 0) needs the rate < 0 now
    approach_end = INF if rate >= 0.0 else 0.0
    if frozen < -turn:
        vehicle_radius = 0.5 * math.sqrt(length * length + width * width)
        approach_end = approach_horizon(d, frozen, math.sqrt(vx * vx + vy * vy), turn, relative, yaw_rate_bound)
        heading = heading_horizon(dx, dy, vx, vy, radius + vehicle_radius, turn, relative)
        if heading > approach_end:
            approach_end = heading
        if approach_end > new_minimum:
            new_minimum = approach_end
    if not near:
        # a collision course or a headway counts only within RANGE: checked (course_check) from when the
        # vehicle can come within it
        entering = reach_time_scalar(d - RANGE, turn - frozen, relative)
        return (transition_left if transition_left < new_minimum else new_minimum,
                transition_left if transition_left < approach_end else approach_end,
                transition_left if transition_left < entering else entering)
    # new_minimum >= approach_end unless the rate is >= 0 (then approach_end is inf): one proof for both
    longest = approach_end if approach_end > new_minimum else new_minimum
    if transition_left < longest:
        longest = transition_left
    if not longest > 0.0:
        return 0.0, 0.0, INF
    return (transition_left if transition_left < new_minimum else new_minimum,
            transition_left if transition_left < approach_end else approach_end,
            course_horizon(dx, dy, vx, vy, reach_x, reach_y, longest, turn, relative))


def course_check(at, row, size, t: float, x: float, y: float, yaw_rate: float, acceleration: float,
                 yaw_rate_bound: float, radius: float) -> float:
    """Extremes.course_check's value: nan if the vehicle is within RANGE on a collision course or with a headway,
    else a bound (s from now) on when that can be. The same operations as `evaluate`'s for the quantities it reads
    (the same decisions)."""
    ego, _, _, ego_vx, ego_vy, ego_x, ego_y = at
    station, lateral, speed, lateral_rate, _ = motion_law(row, t)
    t0, _, _, speed0, _, speed1, duration = row
    elapsed = t - t0
    moving = elapsed < duration
    speed_rate = (speed1 - speed0) / duration if moving else 0.0
    length, width = size
    dx, dy = station - x, -lateral - y
    vx, vy = -speed - ego_vx, -lateral_rate - ego_vy
    transition_left = duration - elapsed if moving else INF
    relative = acceleration + (speed_rate if speed_rate >= 0.0 else -speed_rate)
    turn = radius * yaw_rate_bound
    # the common case (a car in another lane), decided as `ttc` and `headway` decide it, with the road axes'
    # reaches computed once for both and for course_horizon: off any collision course by the road's two axes
    # alone, and not ahead in the ego's path
    reach_x, reach_y = ego_x + length / 2, ego_y + width / 2  # axis_reaches' first two
    if off_course(dx, dy, vx, vy, reach_x, reach_y) and (
            not dx > 0.0 or (dy if dy >= 0.0 else -dy) >= reach_y or ego_vx <= 0.0 or -speed < 0.0):
        return course_horizon(dx, dy, vx, vy, reach_x, reach_y, transition_left, turn, relative)
    value = ttc(ego, dx, dy, vx, vy, length, width)
    if 0.0 < value < INF or headway(ego, dx, dy, ego_vx, -speed, length, width) != INF:
        d, _, frozen = distance_and_rates(ego, dx, dy, vx, vy, yaw_rate, length, width)
        if d <= RANGE:
            return math.nan
        # beyond RANGE: checked again from when it can come within it
        entering = reach_time_scalar(d - RANGE, turn - frozen, relative)
        return transition_left if transition_left < entering else entering
    return course_horizon(dx, dy, vx, vy, reach_x, reach_y, transition_left, turn, relative)


def distance_rate(at, row, size, t: float, x: float, y: float, yaw_rate: float) -> float:
    """`evaluate`'s distance rate alone (the master's probe for a closest approach)."""
    ego, _, _, ego_vx, ego_vy, _, _ = at
    station, lateral, speed, lateral_rate, _ = motion_law(row, t)
    return distance_and_rates(ego, station - x, -lateral - y, -speed - ego_vx, -lateral_rate - ego_vy, yaw_rate,
                              *size)[1]


def off_course(dx: float, dy: float, vx: float, vy: float, reach_x: float, reach_y: float) -> bool:
    """Whether `ttc` returns inf after the road's two axes (x, y; reach_x, reach_y their reaches): the same
    operations in the same order (the same decision)."""
    entry, leave = -INF, INF
    for p, q, h in ((dx, vx, reach_x), (dy, vy, reach_y)):
        if q == 0.0:
            if (p if p >= 0.0 else -p) >= h:
                return True
            continue
        t1, t2 = (-h - p) / q, (h - p) / q
        if t2 < t1:
            t1, t2 = t2, t1
        if t1 > entry:
            entry = t1
        if t2 < leave:
            leave = t2
    return entry >= leave or leave <= 0.0


def arithmetic(compiled: bool = True):
    """The twin a record uses: the kernel where it was built (and `compiled`), else this module."""
    return KERNEL if compiled and KERNEL is not None else sys.modules[__name__]
