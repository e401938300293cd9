"""One traffic vehicle relative to the ego at one state, for the criticality record (extremes.py): the arithmetic
of a look (`look`: `evaluate`, the values offered to the record's lists by `offer`, then `horizon`), a course check
(`course_check`) and a closest approach's probe (`distance_rate`), on plain floats, tuples and the record's lists;
and the follower's scans over the vehicles on the road (follower.py: `due_looks`, `due_checks`, `earliest`).

Two twins do it. `_kernel.c` (built by setup.py where a C compiler is found, `KERNEL`) is the one runs use; the
functions below are the same operations in the same order in Python, used where the package was installed without
it, and the reference the kernel is held to bit for bit (tests/cosim/test_kernel.py). Their arguments:
- a, b: the ego's half length and half width;
- row: the vehicle's motion (traffic.Traffic.row), size: its (length, width);
- t, x, y, psi, body_vx, body_vy, ax, ay, yaw_rate: the ego's state (EgoState's time, position, yaw, body-frame
  velocity and acceleration, yaw rate), from which `ego` gives what the rest reads;
- acceleration, yaw_rate_bound, radius: the ego's bounds (EgoBounds), as in triggers.py.
What each value means, and the proofs of the bounds: extremes.py and measures.py."""

from __future__ import annotations

import math
import sys

from .geometry import reach_time_scalar
from .measures import (INF, approach_horizon, course_horizon, distance_and_rates, drac, drac_rate_known, headway,
                       headway_rate_known, heading_horizon, overlap_window, ttc, ttc_rate_known, window_closed)
from .traffic import motion_law

try:  # the compiled twin (setup.py); None where the package was installed without it
    from . import _kernel as KERNEL
except ImportError:
    KERNEL = None

FLAT = 1e-9  # m or s: a later instant replaces a recorded extreme only if it is better by more than this
# m: TTC, DRAC and headway are followed while the footprints are within this distance, as SUMO's SSM device
# follows encounters within device.ssm.range (default 50 m); the distance everywhere
RANGE = 50.0


def ego(a: float, b: float, psi: float, vx: float, vy: float):
    """The ego at a state: (its footprint (a, b, cos psi, sin psi), cos psi, sin psi, its velocity on the road's axes,
    its own parts of the road axes' reaches a |cos psi| + b |sin psi| and a |sin psi| + b |cos psi|: a vehicle's half
    length and width added to them give geometry.axis_reaches' first two, the same operations in the same order)."""
    c, s = math.cos(psi), math.sin(psi)
    ac = c if c >= 0.0 else -c
    as_ = s if s >= 0.0 else -s
    return (a, b, c, s), c, s, vx * c - vy * s, vx * s + vy * c, a * ac + b * as_, a * as_ + b * ac


def relative(a: float, b: float, row, t: float, x: float, y: float, psi: float, body_vx: float, body_vy: float):
    """Vehicle `row` relative to the ego at a state: (`ego`'s footprint, cos psi, sin psi, the ego's velocity along
    the road, its parts of the road axes' reaches; the vehicle's centre minus the ego's dx, dy and velocity minus the
    ego's vx, vy on the road's axes, its speed, its speed's rate, the time left in its transition (inf: none)), the
    motion law read once (traffic.motion_law; _kernel.c's `relative`)."""
    footprint, c, s, ego_vx, ego_vy, ego_x, ego_y = ego(a, b, psi, body_vx, body_vy)
    station, lateral, speed, lateral_rate, _ = motion_law(row, t)
    t0, _, _, speed0, _, speed1, duration = row
    elapsed = t - t0
    moving = elapsed < duration
    return (footprint, c, s, ego_vx, ego_x, ego_y, station - x, -lateral - y, -speed - ego_vx, -lateral_rate - ego_vy,
            speed, (speed1 - speed0) / duration if moving else 0.0, duration - elapsed if moving else INF)


def evaluate(a: float, b: float, row, size, t: float, x: float, y: float, psi: float, body_vx: float, body_vy: float,
             ax: float, ay: float, yaw_rate: float):
    """(the values to offer: distance, TTC, DRAC, headway; their rates: the distance's, TTC's, minus DRAC's, the
    headway's; what the horizon needs: distance, its rate with the ego's yaw frozen, dx, dy, vx, vy, length,
    width, the vehicle's speed rate, the time left in its transition, the ego's footprint, the road axes' reaches
    (None beyond RANGE)). Beyond RANGE only the distance and its rates (the others inf or nan: not offered)."""
    footprint, c, s, ego_vx, ego_x, ego_y, dx, dy, vx, vy, speed, speed_rate, transition_left = \
        relative(a, b, row, t, x, y, psi, body_vx, body_vy)
    length, width = size
    d, rate, frozen = distance_and_rates(footprint, dx, dy, vx, vy, yaw_rate, length, width)
    if d > RANGE:
        motion = (d, frozen, dx, dy, vx, vy, length, width, speed_rate, transition_left, footprint, None, None)
        return (d, INF, math.nan, INF), (rate, math.nan, math.nan, math.nan), motion
    # the road axes' reaches once, for `ttc`'s and `headway`'s common decision (a car in another lane: off
    # course by the road's axes, not ahead in the ego's path) and for the look's course_horizon
    reach_x, reach_y = ego_x + length / 2, ego_y + width / 2  # axis_reaches' first two
    motion = (d, frozen, dx, dy, vx, vy, length, width, speed_rate, transition_left, footprint, reach_x, reach_y)
    value = INF if off_course(dx, dy, vx, vy, reach_x, reach_y) else ttc(footprint, dx, dy, vx, vy, length, width)
    ego_ax = ax * c - ay * s
    gap_time = INF if (not dx > 0.0 or (dy if dy >= 0.0 else -dy) >= reach_y or ego_vx <= 0.0
                       or -speed < 0.0) else headway(footprint, dx, dy, ego_vx, -speed, length, width)
    headway_change = math.nan if gap_time == INF else \
        headway_rate_known(footprint, gap_time, ego_vx, -speed, ego_ax, yaw_rate)
    if not 0.0 < value < INF:
        return (d, value, math.nan, gap_time), (rate, math.nan, math.nan, headway_change), motion
    rel_ax, rel_ay = -speed_rate - ego_ax, -(ax * s + ay * c)
    value_rate = ttc_rate_known(footprint, dx, dy, vx, vy, rel_ax, rel_ay, yaw_rate, length, width)
    return ((d, value, drac(value, vx, vy), gap_time),
            (rate, value_rate, -drac_rate_known(value, value_rate, vx, vy, rel_ax, rel_ay), headway_change), motion)


def look(a: float, b: float, row, size, t: float, x: float, y: float, psi: float, body_vx: float,
         body_vy: float, ax: float, ay: float, yaw_rate: float, evaluated, i: int, tables: tuple, acceleration: float,
         yaw_rate_bound: float, radius: float):
    """Extremes.look's work on vehicle i in one call: `evaluate` (unless `evaluated` is its value already), the values
    offered to the record's lists `tables` ((values, times) of the distance, TTC, DRAC and headway, in that order:
    `offer`), then (rates, horizon, quiet, course): within RANGE on a collision course or with a headway (0, 0,
    inf), else `horizon`'s."""
    values, rates, motion = evaluated if evaluated is not None else \
        evaluate(a, b, row, size, t, x, y, psi, body_vx, body_vy, ax, ay, yaw_rate)
    d, value, drac_value, gap_time = values
    distance_values, distance_times, ttc_values, ttc_times, drac_values, drac_times, gap_values, gap_times = tables
    offer(distance_values, distance_times, i, t, d, False)
    offer(ttc_values, ttc_times, i, t, value, False)
    offer(gap_values, gap_times, i, t, gap_time, False)
    offer(drac_values, drac_times, i, t, drac_value, True)
    if d <= RANGE and (rates[1] == rates[1] or rates[3] == rates[3]):
        # on a collision course or behind a vehicle ahead: TTC, DRAC, headway followed at every communication point
        return rates, 0.0, 0.0, INF
    return (rates, *horizon(motion, rates[0], distance_values[i], acceleration, yaw_rate_bound, radius))


def offer(values: list, times: list, i: int, t: float, value: float, largest: bool) -> None:
    """Vehicle i's value of one measure at instant t offered to that measure's per-vehicle extremes `values` and their
    instants `times` (nan: none yet): it replaces the extreme when better by more than FLAT (largest: DRAC's maximum;
    else a minimum), with its instant; within FLAT only the value improves, the first instant stays. A value that is
    not finite (not applicable now) is not offered."""
    if not math.isfinite(value):
        return
    recorded = values[i]
    if largest:
        better = recorded != recorded or value > recorded + FLAT
    else:
        better = recorded != recorded or value < recorded - FLAT
    if better:
        values[i] = value
        times[i] = t
    elif (value > recorded) if largest else (value < recorded):
        values[i] = value


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
    relative_acceleration = acceleration + (speed_rate if speed_rate >= 0.0 else -speed_rate)
    new_minimum = reach_time_scalar(d - (recorded - FLAT), turn - frozen, relative_acceleration)
    # a closest approach (the distance's rate turning from < 0 to >= 0) needs the rate < 0 now
    approach_end = INF if rate >= 0.0 else 0.0
    if frozen < -turn:
        vehicle_radius = 0.5 * math.sqrt(length * length + width * width)
        approach_end = approach_horizon(d, frozen, math.sqrt(vx * vx + vy * vy), turn, relative_acceleration,
                                        yaw_rate_bound)
        heading = heading_horizon(dx, dy, vx, vy, radius + vehicle_radius, turn, relative_acceleration)
        if heading > approach_end:
            approach_end = heading
        if approach_end > new_minimum:
            new_minimum = approach_end
    if not near:
        # a collision course or a headway counts only within RANGE: checked (course_check) from when the
        # vehicle can come within it
        entering = reach_time_scalar(d - RANGE, turn - frozen, relative_acceleration)
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
            course_horizon(dx, dy, vx, vy, reach_x, reach_y, longest, turn, relative_acceleration))


def course_check(a: float, b: float, row, size, t: float, x: float, y: float, psi: float, body_vx: float,
                 body_vy: float, yaw_rate: float, acceleration: float, yaw_rate_bound: float, radius: float) -> float:
    """Extremes.course_check's value: nan if the vehicle is within RANGE on a collision course or with a headway,
    else a bound (s from now) on when that can be. The same operations as `evaluate`'s for the quantities it reads
    (the same decisions)."""
    footprint, _, _, ego_vx, ego_x, ego_y, dx, dy, vx, vy, speed, speed_rate, transition_left = \
        relative(a, b, row, t, x, y, psi, body_vx, body_vy)
    length, width = size
    relative_acceleration = acceleration + (speed_rate if speed_rate >= 0.0 else -speed_rate)
    turn = radius * yaw_rate_bound
    # the common case (a car in another lane), decided as `ttc` and `headway` decide it, with the road axes'
    # reaches computed once for both and for course_horizon: off any collision course by the road's two axes
    # alone, and not ahead in the ego's path
    reach_x, reach_y = ego_x + length / 2, ego_y + width / 2  # axis_reaches' first two
    if off_course(dx, dy, vx, vy, reach_x, reach_y) and (
            not dx > 0.0 or (dy if dy >= 0.0 else -dy) >= reach_y or ego_vx <= 0.0 or -speed < 0.0):
        return course_horizon(dx, dy, vx, vy, reach_x, reach_y, transition_left, turn, relative_acceleration)
    value = ttc(footprint, dx, dy, vx, vy, length, width)
    if 0.0 < value < INF or headway(footprint, dx, dy, ego_vx, -speed, length, width) != INF:
        d, _, frozen = distance_and_rates(footprint, dx, dy, vx, vy, yaw_rate, length, width)
        if d <= RANGE:
            return math.nan
        # beyond RANGE: checked again from when it can come within it
        entering = reach_time_scalar(d - RANGE, turn - frozen, relative_acceleration)
        return transition_left if transition_left < entering else entering
    return course_horizon(dx, dy, vx, vy, reach_x, reach_y, transition_left, turn, relative_acceleration)


def distance_rate(a: float, b: float, row, size, t: float, x: float, y: float, psi: float, body_vx: float,
                  body_vy: float, yaw_rate: float) -> float:
    """`evaluate`'s distance rate alone (the master's probe for a closest approach)."""
    footprint, _, _, _, _, _, dx, dy, vx, vy, _, _, _ = relative(a, b, row, t, x, y, psi, body_vx, body_vy)
    return distance_and_rates(footprint, dx, dy, vx, vy, yaw_rate, *size)[1]


def off_course(dx: float, dy: float, vx: float, vy: float, reach_x: float, reach_y: float) -> bool:
    """Whether `ttc` returns inf after the road's two axes (x, y; reach_x, reach_y their reaches): its first
    window (the same decision)."""
    return window_closed(overlap_window(((dx, vx, reach_x), (dy, vy, reach_y))))


# ---- the follower's scans over the vehicles on the road (follower.py): which are due, the earliest bounds

def due_looks(vehicles: list, next_look: list, quiet_until: list, look_time: list, t: float, ahead: float | None,
              now: bool) -> list:
    """The vehicles whose look has come (`now`: next_look <= t) or, with `ahead` (a step's end), that were last
    looked at before t and whose quiet bound ends by `ahead`."""
    if ahead is None:
        return [i for i in vehicles if next_look[i] <= t] if now else []
    if now:
        return [i for i in vehicles if next_look[i] <= t or (quiet_until[i] <= ahead and look_time[i] < t)]
    return [i for i in vehicles if quiet_until[i] <= ahead and look_time[i] < t]


def due_checks(vehicles: list, course_until: list, check_time: list, next_look: list, until: float,
               t: float) -> list:
    """The vehicles whose course bound ends by `until`, not checked at t yet and not due a look."""
    return [i for i in vehicles if course_until[i] <= until and check_time[i] < t and next_look[i] > t]


def earliest(vehicles: list, *values: list):
    """Per list of per-vehicle values, its least over `vehicles` (inf for none): one float, or a tuple of them."""
    least = tuple(min(map(of.__getitem__, vehicles), default=INF) for of in values)
    return least[0] if len(values) == 1 else least


def arithmetic():
    """The twin a record uses: the kernel where it was built, else this module."""
    return KERNEL if KERNEL is not None else sys.modules[__name__]
