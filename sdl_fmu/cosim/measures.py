"""The criticality measures between the ego and one traffic vehicle: footprint distance, time to collision (TTC),
deceleration rate to avoid a crash (DRAC), post-encroachment time (PET) and time headway, with their time
derivatives and lower bounds on when an extreme can occur, so that the master locates each extreme as an
instant by its event machinery instead of taking the best sample. Numbers only, SI, no I/O.

Definitions (SUMO's SSM device, https://sumo.dlr.de/docs/Simulation/Output/SSM_Device.html and
src/microsim/devices/MSDevice_SSM.cpp; CommonRoad-CriMe, commonroad_crime/measure/time/{ttc,thw,pet}.py and
distance/hw.py; https://criticality-metrics.readthedocs.io):
- distance: the minimum Euclidean distance between the ego's footprint (a length x width rectangle about its
  reference point, turned by its yaw psi) and the vehicle's (aligned with the road, as traffic.py moves it);
  0 in contact. `signed_distance` is minus the penetration depth while they overlap.
- TTC: the earliest time at which the footprints would touch if both kept their current velocities (the ego's
  yaw frozen), "defined only on a collision course" (SUMO; CriMe's TTC is the same quantity along a lanelet,
  gap / closing speed for a constant velocity). Closed form: along each of the four separating axes the
  projections overlap during one interval of time, linear in time; the footprints touch when all four do
  (the separating-axis theorem). Collision course: the intersection of the intervals is not empty and ends in
  the future. Infinite when not on a collision course, 0 in contact.
- DRAC = closing speed^2 / (2 x distance along the collision course) (SUMO: (v_follower - v_leader)^2 / (2 gap)
  for a follower). Under constant velocities the footprints close along the relative velocity v_rel and meet
  after |v_rel| TTC, so DRAC = |v_rel|^2 / (2 |v_rel| TTC) = |v_rel| / (2 TTC), which for a head-on approach
  at closing speed c and gap g is c^2 / (2 g). Defined while on a collision course and not in contact.
- PET: the time between one leaving the area both use and the other reaching it (SUMO: "the time between the
  departure of the first vehicle from the conflict area and the arrival of the second"; CriMe pet.py:
  t_entry(second) - t_exit(first)). Here, for a vehicle crossing the ego's path (a lateral action into the
  ego's lane and back): the conflict area is where the vehicle's footprint stood when it left the ego's path
  band (`band_times`), and the ego reaches it when its front reaches that area's near end
  (`conflict_station`). PET = t_ego_reaches - t_vehicle_left. The ego first (a vehicle moving into the ego's
  lane behind it): the area is where the vehicle's footprint stands when it enters the band, the ego left it
  when its rear passed that area's far end (`conflict_far_end`); PET = t_vehicle_enters - t_ego_left.
- time headway (SUMO's TGAP = space gap / follower speed; CriMe thw.py for a constant ego speed): the
  bumper-to-bumper gap to a vehicle ahead in the ego's path (the footprints overlap laterally) moving the same
  way or stopped, divided by the ego's speed along the road; 0 once the gap has closed (in contact).

Frames: ISO 8855 inertial, x = station, y = -lateral (road.py). Relative quantities are vehicle - ego: centre
(dx, dy), velocity (vx, vy), acceleration. A vehicle moving at `speed` toward decreasing station with a
lateral rate has the velocity (-speed, -lateral_rate).

Forms: each function on plain floats (the master's path for up to SCALAR_VEHICLES vehicles), and its
vectorised twin (suffix `s`, NumPy arrays over vehicles) doing the same operations in the same order, so
the two give the same bits (tested), as in geometry.py and triggers.py. Square roots as sqrt(x*x + y*y)
(math.sqrt and np.sqrt are both correctly rounded; math.hypot and np.hypot are not the same algorithm).

How the run uses them (the extremes record, its looks, located instants and horizons): extremes.py.
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import Footprint, axis_reaches, penetration, penetrations, reach_time, reach_time_scalar

INF = math.inf

# course_horizon: s, the longest horizon tried; how many times it shortens its first guess (by a quarter) before
# giving up; m, the least lateral margin it accepts (far above the rounding of ttc's and headway's few operations
# on metres)
COURSE_WINDOW = 1.0
COURSE_TRIES = 8
COURSE_MARGIN = 1e-6
# heading_horizon: how many times it tries to stretch its first bound, and by what factor
HEADING_STRETCHES = 3
HEADING_STRETCH = 1.5


# ---- footprint distance ---------------------------------------------------------------------------------

def _corners(ego: Footprint, dx, dy, length, width):
    """The eight (x, y, half_x, half_y) corner-to-box problems whose minimum is the distance of two disjoint
    convex polygons (the closest pair always has a vertex of one of them): the ego's four corners relative
    to the vehicle's centre against the vehicle's box, and the vehicle's four corners in the ego's body
    frame against the ego's box. Works on floats and arrays alike."""
    a, b, c, s = ego
    hl, hw = length / 2, width / 2
    ac, as_, bc, bs = a * c, a * s, b * c, b * s
    du = dx * c + dy * s  # the vehicle's centre in the ego's body frame
    dv = -dx * s + dy * c
    lc, ls, wc, ws = hl * c, hl * s, hw * c, hw * s
    return (
        # ego corner (sign_l a, sign_w b) turned by psi, minus the vehicle's centre
        (ac - bs - dx, as_ + bc - dy, hl, hw),
        (ac + bs - dx, as_ - bc - dy, hl, hw),
        (-ac - bs - dx, -as_ + bc - dy, hl, hw),
        (-ac + bs - dx, -as_ - bc - dy, hl, hw),
        # vehicle corner (sign_l hl, sign_w hw) turned by -psi, plus the centre in the body frame
        (du + lc + ws, dv - ls + wc, a, b),
        (du + lc - ws, dv - ls - wc, a, b),
        (du - lc + ws, dv + ls + wc, a, b),
        (du - lc - ws, dv + ls - wc, a, b),
    )


def signed_distance(ego: Footprint, dx: float, dy: float, length: float, width: float) -> float:
    """Minimum distance between the footprints (m), minus the penetration depth while they overlap."""
    depth = penetration(ego, dx, dy, length, width)
    if depth > 0.0:
        return -depth
    best = INF  # the smallest squared corner distance; one square root at the end (sqrt is monotone)
    for x, y, half_x, half_y in _corners(ego, dx, dy, length, width):
        ex = max(abs(x) - half_x, 0.0)
        ey = max(abs(y) - half_y, 0.0)
        best = min(best, ex * ex + ey * ey)
    return math.sqrt(best)


def signed_distances(ego: Footprint, dx, dy, length, width):
    """`signed_distance` over arrays of vehicles."""
    depth = penetrations(ego, dx, dy, length, width)
    best = np.full(np.shape(depth), INF)
    for x, y, half_x, half_y in _corners(ego, dx, dy, length, width):
        ex = np.maximum(np.abs(x) - half_x, 0.0)
        ey = np.maximum(np.abs(y) - half_y, 0.0)
        best = np.minimum(best, ex * ex + ey * ey)
    return np.where(depth > 0.0, -depth, np.sqrt(best))


def distance(ego: Footprint, dx: float, dy: float, length: float, width: float) -> float:
    """Minimum distance between the footprints (m), 0 in contact."""
    return max(signed_distance(ego, dx, dy, length, width), 0.0)


def distances(ego: Footprint, dx, dy, length, width):
    return np.maximum(signed_distances(ego, dx, dy, length, width), 0.0)


# ---- its rate of change -----------------------------------------------------------------------------------

def distance_rate(ego: Footprint, dx: float, dy: float, vx: float, vy: float, yaw_rate: float, length: float,
                  width: float) -> float:
    """d/dt of `distance` along the present motion: relative velocity (vx, vy) = vehicle - ego, the ego
    turning at yaw_rate (yaw_rate 0: the rate with the ego's yaw frozen, used by the horizons). 0 in
    contact or touching (the distance is 0 there). Where several corners are equally close, the smallest of
    their rates: the rate of their minimum from now on.

    Distance from a point p to a box: |g| with g = (sign(px) max(|px| - hx, 0), ...); its rate g.p'/|g|.
    An ego corner e (turned with the ego) relative to the vehicle's centre: p = e - d,
    p' = yaw_rate (-e_y, e_x) - v. A vehicle corner in the ego's body frame: q = R(-psi)(d + f),
    q' = R(-psi) v + yaw_rate (q_v, -q_u)."""
    return distance_and_rates(ego, dx, dy, vx, vy, yaw_rate, length, width)[1]


def distance_and_rates(ego: Footprint, dx: float, dy: float, vx: float, vy: float, yaw_rate: float, length: float,
                        width: float) -> tuple[float, float, float]:
    """(distance, its rate, its rate with the ego's yaw frozen) in one pass over the corners (the master's
    look at one vehicle): `distance`, `distance_rate` and `distance_rate` with yaw_rate 0.

    The per-look path, so written out: `_corners` inline (the same operations in the same order, so the same
    bits); the eight corners unrolled, their squared gaps first and one square root, the least's (sqrt is
    correctly rounded, so monotonic: sqrt(min) = min(sqrt)), then the rates of the closest corners only: those
    whose gap's square root equals it (in corner order: the first sets them, later equally close ones can only
    lower them)."""
    a, b, c, s = ego
    hl, hw = length / 2, width / 2
    # `penetration`'s overlaps along the road's y and x axes, its operations: either < 0 makes it < 0 (or nan), so
    # it is computed only when neither is (a car in the next lane is decided by the first)
    ac = c if c >= 0.0 else -c
    as_ = s if s >= 0.0 else -s
    if not (a * as_ + b * ac + hw - (dy if dy >= 0.0 else -dy) < 0.0
            or a * ac + b * as_ + hl - (dx if dx >= 0.0 else -dx) < 0.0) \
            and penetration(ego, dx, dy, length, width) >= 0.0:
        return 0.0, 0.0, 0.0  # in contact or touching
    du = dx * c + dy * s  # the vehicle's centre in the ego's body frame
    dv = -dx * s + dy * c
    acs, as_s, bc, bs = a * c, a * s, b * c, b * s
    lc, ls, wc, ws = hl * c, hl * s, hw * c, hw * s
    # the corners (x, y): ego corner (sign_l a, sign_w b) turned by psi minus the vehicle's centre, against the
    # vehicle's box (hl, hw); vehicle corner (sign_l hl, sign_w hw) turned by -psi plus the centre in the body
    # frame, against the ego's (a, b); per corner the squared gap max(|x| - half_x, 0)^2 + max(|y| - half_y, 0)^2
    x0, y0 = acs - bs - dx, as_s + bc - dy
    x1, y1 = acs + bs - dx, as_s - bc - dy
    x2, y2 = -acs - bs - dx, -as_s + bc - dy
    x3, y3 = -acs + bs - dx, -as_s - bc - dy
    x4, y4 = du + lc + ws, dv - ls + wc
    x5, y5 = du + lc - ws, dv - ls - wc
    x6, y6 = du - lc + ws, dv + ls + wc
    x7, y7 = du - lc - ws, dv + ls - wc
    ex = (x0 if x0 >= 0.0 else -x0) - hl
    ey = (y0 if y0 >= 0.0 else -y0) - hw
    q0 = (ex * ex if ex > 0.0 else 0.0) + (ey * ey if ey > 0.0 else 0.0)
    ex = (x1 if x1 >= 0.0 else -x1) - hl
    ey = (y1 if y1 >= 0.0 else -y1) - hw
    q1 = (ex * ex if ex > 0.0 else 0.0) + (ey * ey if ey > 0.0 else 0.0)
    ex = (x2 if x2 >= 0.0 else -x2) - hl
    ey = (y2 if y2 >= 0.0 else -y2) - hw
    q2 = (ex * ex if ex > 0.0 else 0.0) + (ey * ey if ey > 0.0 else 0.0)
    ex = (x3 if x3 >= 0.0 else -x3) - hl
    ey = (y3 if y3 >= 0.0 else -y3) - hw
    q3 = (ex * ex if ex > 0.0 else 0.0) + (ey * ey if ey > 0.0 else 0.0)
    ex = (x4 if x4 >= 0.0 else -x4) - a
    ey = (y4 if y4 >= 0.0 else -y4) - b
    q4 = (ex * ex if ex > 0.0 else 0.0) + (ey * ey if ey > 0.0 else 0.0)
    ex = (x5 if x5 >= 0.0 else -x5) - a
    ey = (y5 if y5 >= 0.0 else -y5) - b
    q5 = (ex * ex if ex > 0.0 else 0.0) + (ey * ey if ey > 0.0 else 0.0)
    ex = (x6 if x6 >= 0.0 else -x6) - a
    ey = (y6 if y6 >= 0.0 else -y6) - b
    q6 = (ex * ex if ex > 0.0 else 0.0) + (ey * ey if ey > 0.0 else 0.0)
    ex = (x7 if x7 >= 0.0 else -x7) - a
    ey = (y7 if y7 >= 0.0 else -y7) - b
    q7 = (ex * ex if ex > 0.0 else 0.0) + (ey * ey if ey > 0.0 else 0.0)
    least = min(q0, q1, q2, q3, q4, q5, q6, q7)
    sqrt = math.sqrt
    best = sqrt(least)
    near = least * (1.0 + 1e-15)  # sqrt(q) == best needs q / least < (1 + 2^-52)^2
    vu, vv = vx * c + vy * s, -vx * s + vy * c
    rate = frozen = INF
    first = True
    # the closest corners, in corner order: a corner is skipped where q > near or (q != least and sqrt(q) != best)
    for k, q, x, y in ((0, q0, x0, y0), (1, q1, x1, y1), (2, q2, x2, y2), (3, q3, x3, y3),
                       (4, q4, x4, y4), (5, q5, x5, y5), (6, q6, x6, y6), (7, q7, x7, y7)):
        if q > near or (q != least and sqrt(q) != best):
            continue
        if k < 4:
            half_x, half_y = hl, hw
        else:
            half_x, half_y = a, b
        ex = (x if x >= 0.0 else -x) - half_x
        if ex < 0.0:
            ex = 0.0
        ey = (y if y >= 0.0 else -y) - half_y
        if ey < 0.0:
            ey = 0.0
        gx = ex if x >= 0.0 else -ex
        gy = ey if y >= 0.0 else -ey
        if k < 4:
            px_rate, py_rate = -yaw_rate * (y + dy) - vx, yaw_rate * (x + dx) - vy
            r_frozen = (gx * -vx + gy * -vy) / best
        else:
            px_rate, py_rate = vu + yaw_rate * y, vv - yaw_rate * x
            r_frozen = (gx * vu + gy * vv) / best
        r = (gx * px_rate + gy * py_rate) / best
        if first:
            rate, frozen, first = r, r_frozen, False
        else:
            if r < rate:
                rate = r
            if r_frozen < frozen:
                frozen = r_frozen
    return best, rate, frozen


def distance_rates(ego: Footprint, dx, dy, vx, vy, yaw_rate: float, length, width):
    """`distance_rate` over arrays of vehicles."""
    a, b, c, s = ego
    vu, vv = vx * c + vy * s, -vx * s + vy * c
    best = np.full(np.shape(dx), INF)
    rate = np.full(np.shape(dx), INF)
    with np.errstate(invalid="ignore", divide="ignore"):
        for k, (x, y, half_x, half_y) in enumerate(_corners(ego, dx, dy, length, width)):
            ex = np.maximum(np.abs(x) - half_x, 0.0)
            ey = np.maximum(np.abs(y) - half_y, 0.0)
            d = np.sqrt(ex * ex + ey * ey)
            gx = np.where(x >= 0.0, ex, -ex)
            gy = np.where(y >= 0.0, ey, -ey)
            if k < 4:
                px_rate = -yaw_rate * (y + dy) - vx
                py_rate = yaw_rate * (x + dx) - vy
            else:
                px_rate = vu + yaw_rate * y
                py_rate = vv - yaw_rate * x
            r = (gx * px_rate + gy * py_rate) / d
            rate = np.where(d < best, r, np.where(d == best, np.minimum(rate, r), rate))
            best = np.minimum(best, d)
    return np.where(penetrations(ego, dx, dy, length, width) >= 0.0, 0.0, rate)


# ---- time to collision and DRAC -----------------------------------------------------------------------------

def _axes(ego: Footprint, dx, dy, vx, vy, length, width):
    """Per separating axis (x, y, u, v): centre offset p, relative velocity q and the sum h of the two
    footprints' half extents along it (geometry.axis_reaches)."""
    _, _, c, s = ego
    hx, hy, hu, hv = axis_reaches(ego, length, width)
    return ((dx, vx, hx), (dy, vy, hy), (dx * c + dy * s, vx * c + vy * s, hu),
            (-dx * s + dy * c, -vx * s + vy * c, hv))


def ttc(ego: Footprint, dx: float, dy: float, vx: float, vy: float, length: float, width: float) -> float:
    """Constant-velocity time to collision (s): the projections on an axis overlap while |p + q t| < h, an
    interval (entry, exit) of t; the footprints overlap on the intersection of the four intervals. 0 when
    they overlap now, inf when not on a collision course (the intersection is empty, or past). The road's axes
    first: where their two intervals already leave nothing (the common case, a car in another lane), the ego's
    axes are not needed (more axes can only narrow the intersection)."""
    _, _, c, s = ego
    hx, hy, hu, hv = axis_reaches(ego, length, width)
    window = overlap_window(((dx, vx, hx), (dy, vy, hy)))
    if window_closed(window):
        return INF
    window = overlap_window(((dx * c + dy * s, vx * c + vy * s, hu), (-dx * s + dy * c, -vx * s + vy * c, hv)),
                            *window)
    if window_closed(window):
        return INF
    entry = window[0]
    return entry if entry > 0.0 else 0.0


def overlap_window(axes, entry: float = -INF, leave: float = INF) -> tuple[float, float] | None:
    """`ttc`'s intersection of intervals: (entry, leave) narrowed to the times t at which the projections overlap
    on every axis (p, q, h) of `axes`, |p + q t| < h (an interval of t, linear in t); None if one never overlaps
    (q = 0 and |p| >= h)."""
    for p, q, h in axes:
        if q == 0.0:
            if abs(p) >= h:
                return None  # never overlapping along this axis
            continue
        t1, t2 = (-h - p) / q, (h - p) / q
        if t2 < t1:
            t1, t2 = t2, t1
        if t1 > entry:
            entry = t1
        if t2 < leave:
            leave = t2
    return entry, leave


def window_closed(window: tuple[float, float] | None) -> bool:
    """Whether an `overlap_window` leaves no collision course: none, empty, or past."""
    return window is None or window[0] >= window[1] or window[1] <= 0.0


def ttcs(ego: Footprint, dx, dy, vx, vy, length, width):
    """`ttc` over arrays of vehicles."""
    shape = np.shape(dx)
    entry, leave = np.full(shape, -INF), np.full(shape, INF)
    never = np.zeros(shape, dtype=bool)
    for p, q, h in _axes(ego, dx, dy, vx, vy, length, width):
        still = q == 0.0
        never |= still & (np.abs(p) >= h)
        span = np.where(still, 1.0, q)
        t1, t2 = (-h - p) / span, (h - p) / span
        entry = np.where(still, entry, np.maximum(entry, np.minimum(t1, t2)))
        leave = np.where(still, leave, np.minimum(leave, np.maximum(t1, t2)))
    return np.where(never | (entry >= leave) | (leave <= 0.0), INF, np.maximum(entry, 0.0))


def drac(ttc_s: float, vx: float, vy: float) -> float:
    """Deceleration rate to avoid a crash (m/s2), |v_rel| / (2 TTC) = |v_rel|^2 / (2 |v_rel| TTC); nan when
    TTC is not defined (inf) or the footprints overlap (TTC 0)."""
    if not 0.0 < ttc_s < INF:
        return math.nan
    return math.sqrt(vx * vx + vy * vy) / (2 * ttc_s)


def dracs(ttc_s, vx, vy):
    with np.errstate(divide="ignore", invalid="ignore"):
        value = np.sqrt(vx * vx + vy * vy) / (2 * ttc_s)
    return np.where((ttc_s > 0.0) & (ttc_s < INF), value, np.nan)


def ttc_rate(ego: Footprint, dx: float, dy: float, vx: float, vy: float, ax: float, ay: float, yaw_rate: float,
             length: float, width: float) -> float:
    """d/dt of `ttc` along the present motion (relative acceleration (ax, ay) = vehicle - ego, the ego turning
    at yaw_rate): -1 under constant velocities and yaw. nan where TTC is not defined or 0.

    TTC is the entry time of the axis entered last, t = -(p + sigma h) / q (sigma = sign q), so
    t' = -(p' + sigma h' + t q') / q with p' = q on the road's axes and q + yaw_rate p_v, q - yaw_rate p_u on
    the ego's (u, v) axes; q' the relative acceleration along the axis (plus the turning of u and v); h'
    from the turning of the projected half extents (d|cos psi|/dt = -sign(cos) sin yaw_rate, ...)."""
    t = ttc(ego, dx, dy, vx, vy, length, width)
    if not 0.0 < t < INF:
        return math.nan
    return ttc_rate_known(ego, dx, dy, vx, vy, ax, ay, yaw_rate, length, width)


def ttc_rate_known(ego: Footprint, dx: float, dy: float, vx: float, vy: float, ax: float, ay: float, yaw_rate: float,
              length: float, width: float) -> float:
    """`ttc_rate` where TTC is known to be defined and > 0."""
    a, b, c, s = ego
    hl, hw = length / 2, width / 2
    sc, ss = math.copysign(1.0, c), math.copysign(1.0, s)
    cos_rate, sin_rate = -sc * s * yaw_rate, ss * c * yaw_rate  # of |cos psi|, |sin psi|
    (px, qx, hx), (py, qy, hy), (pu, qu, hu), (pv, qv, hv) = _axes(ego, dx, dy, vx, vy, length, width)
    au, av = ax * c + ay * s, -ax * s + ay * c
    axes = ((px, qx, hx, qx, ax, a * cos_rate + b * sin_rate),
            (py, qy, hy, qy, ay, a * sin_rate + b * cos_rate),
            (pu, qu, hu, qu + yaw_rate * pv, au + yaw_rate * qv, hl * cos_rate + hw * sin_rate),
            (pv, qv, hv, qv - yaw_rate * pu, av - yaw_rate * qu, hl * sin_rate + hw * cos_rate))
    # the axis that sets the entry time: the latest entry among the axes with q != 0
    last, rate = -INF, math.nan
    for p, q, h, p_rate, q_rate, h_rate in axes:
        if q == 0.0:
            continue
        sigma = 1.0 if q > 0.0 else -1.0
        entry = -(p + sigma * h) / q
        if entry > last:
            last = entry
            rate = -(p_rate + sigma * h_rate + entry * q_rate) / q
    return rate


def drac_rate(ego: Footprint, dx: float, dy: float, vx: float, vy: float, ax: float, ay: float, yaw_rate: float,
              length: float, width: float) -> float:
    """d/dt of `drac` along the present motion: DRAC = |v| / (2 TTC), so
    DRAC' = (|v|' TTC - |v| TTC') / (2 TTC^2) with |v|' = v . a / |v|. nan where DRAC is not defined. Its
    maximum is where this turns from > 0 to <= 0 (or at a collision course's start or end)."""
    t = ttc(ego, dx, dy, vx, vy, length, width)
    if not 0.0 < t < INF:
        return math.nan
    return drac_rate_known(t, ttc_rate_known(ego, dx, dy, vx, vy, ax, ay, yaw_rate, length, width), vx, vy, ax, ay)


def drac_rate_known(t: float, t_rate: float, vx: float, vy: float, ax: float, ay: float) -> float:
    speed = math.sqrt(vx * vx + vy * vy)
    speed_rate = (vx * ax + vy * ay) / speed
    return (speed_rate * t - speed * t_rate) / (2 * t * t)


# ---- time headway -----------------------------------------------------------------------------------------

def headway(ego: Footprint, dx: float, dy: float, station_rate: float, vehicle_station_rate: float,
            length: float, width: float) -> float:
    """Time headway (s) to a vehicle ahead in the ego's path moving the same way or stopped: the bumper-to-bumper
    gap along the road (the vehicle's rear to the front of the ego's footprint) over the ego's speed along the
    road (SUMO's TGAP); 0 once the two overlap along the road (in contact: the gap has closed, as TTC is 0 there).
    inf when the vehicle is not ahead in the ego's path (the footprints do not overlap laterally, or its centre
    is not ahead of the ego's), comes toward the ego, or the ego does not move forward."""
    a, b, c, s = ego
    ac, as_ = abs(c), abs(s)
    gap = dx - (a * ac + b * as_) - length / 2
    if (not dx > 0.0 or abs(dy) >= a * as_ + b * ac + width / 2 or station_rate <= 0.0
            or vehicle_station_rate < 0.0):
        return INF
    return gap / station_rate if gap > 0.0 else 0.0


def headway_rate(ego: Footprint, dx: float, dy: float, station_rate: float, vehicle_station_rate: float,
                 station_acceleration: float, yaw_rate: float, length: float, width: float) -> float:
    """d/dt of `headway` along the present motion (nan where it is not defined): headway = g / v with the
    gap g = dx - (a |cos psi| + b |sin psi|) - l / 2, so headway' = (g' v - g v') / v^2 with
    g' = vehicle_station_rate - station_rate - (a d|cos psi|/dt + b d|sin psi|/dt), v' = station_acceleration."""
    value = headway(ego, dx, dy, station_rate, vehicle_station_rate, length, width)
    if value == INF:
        return math.nan
    return headway_rate_known(ego, value, station_rate, vehicle_station_rate, station_acceleration, yaw_rate)


def headway_rate_known(ego: Footprint, value: float, station_rate: float, vehicle_station_rate: float,
                  station_acceleration: float, yaw_rate: float) -> float:
    """`headway_rate` where the headway `value` is known to be defined (0 where it is held at 0: in contact)."""
    if value == 0.0:
        return 0.0
    a, b, c, s = ego
    cos_rate = -math.copysign(1.0, c) * s * yaw_rate
    sin_rate = math.copysign(1.0, s) * c * yaw_rate
    gap_rate = vehicle_station_rate - station_rate - (a * cos_rate + b * sin_rate)
    return (gap_rate - value * station_acceleration) / station_rate


def headways(ego: Footprint, dx, dy, station_rate: float, vehicle_station_rate, length, width):
    a, b, c, s = ego
    ac, as_ = abs(c), abs(s)
    gap = dx - (a * ac + b * as_) - length / 2
    ahead = (dx > 0.0) & (np.abs(dy) < a * as_ + b * ac + width / 2) & (vehicle_station_rate >= 0.0)
    if station_rate <= 0.0:
        return np.full(np.shape(gap), INF)
    return np.where(ahead, np.where(gap > 0.0, gap / station_rate, 0.0), INF)


# ---- post-encroachment time -------------------------------------------------------------------------------

def band_times(t0: float, lateral0: float, lateral1: float, duration: float, width: float, band_low: float,
               band_high: float) -> tuple[float, float]:
    """(enter, leave): the instants the vehicle's footprint (lateral extent lateral -+ width / 2) begins and
    ceases to overlap the band band_low < lateral < band_high (the ego's path), while its lateral position
    moves linearly from lateral0 at t0 to lateral1 at t0 + duration and then holds (traffic.Motion).
    enter = -inf if it overlaps at t0, leave = inf if it still overlaps at the end; (nan, nan) if it never
    overlaps within the motion."""
    low, high = band_low - width / 2, band_high + width / 2  # the centre's lateral range of overlap
    inside0 = low < lateral0 < high
    if duration <= 0.0 or lateral1 == lateral0:
        return (-INF, INF) if inside0 else (math.nan, math.nan)
    rate = (lateral1 - lateral0) / duration
    if rate > 0.0:  # moving toward higher lateral: in across `low`, out across `high`
        if not inside0 and not (lateral0 <= low < lateral1):
            return math.nan, math.nan
        enter = -INF if inside0 else t0 + (low - lateral0) / rate
        leave = t0 + (high - lateral0) / rate if lateral1 >= high else INF
    else:
        if not inside0 and not (lateral0 >= high > lateral1):
            return math.nan, math.nan
        enter = -INF if inside0 else t0 + (high - lateral0) / rate
        leave = t0 + (low - lateral0) / rate if lateral1 <= low else INF
    return enter, leave


def conflict_station(station: float, length: float) -> float:
    """The near (lower-station) end of the conflict area: the vehicle's rear as it leaves the ego's path,
    the station the front of the ego's footprint reaches at the ego's encroachment."""
    return station - length / 2


def conflict_far_end(station: float, length: float) -> float:
    """The far (higher-station) end of the area where a vehicle's footprint enters the ego's path: its front
    in the ego's direction of travel, the station the ego's rear must have passed for the ego to have left
    the area before the vehicle entered it (the ego passing first)."""
    return station + length / 2


def passage_known(middle: float, low: float, low_position: float | None, low_rate: float, high: float,
                  high_position: float, high_rate: float, station: float, turn: float,
                  acceleration: float) -> bool | None:
    """Whether a point of the ego's footprint moving along the road (its front or rear: the reference point's
    station plus an offset turning with the yaw) is at or past `station` at `middle`, where its positions at
    low (None: unknown) and high and the reference point's station rates there say so for certain; None where
    only a probe can tell. The point's station rate is the reference point's (which changes at most at the
    acceleration bound A) plus at most R r_max (`turn`: the offset turning), so over d = middle - low it moves
    at most (rate + turn) d + A d^2 / 2 on from low, and over d = high - middle it moved at most as much to
    high. The master's bisection of a PET passage skips the probes this decides: the same brackets, the
    same instant, fewer FMU probes."""
    if low_position is not None:
        d = middle - low
        if low_position + (low_rate + turn) * d + 0.5 * acceleration * d * d < station:
            return False
    d = high - middle
    if high_position - (high_rate + turn) * d - 0.5 * acceleration * d * d >= station:
        return True
    return None


def post_encroachment_time(first_leaves: float, second_enters: float) -> float:
    """PET (s) = t_second_enters - t_first_leaves (the vehicle first: the ego's front reaching the area it
    left; the ego first: the vehicle entering the area the ego's rear left); nan when the second entered
    before the first left (then the two occupied it together: a contact or a near miss, measured by distance
    and TTC, not PET)."""
    return second_enters - first_leaves if second_enters >= first_leaves else math.nan


# ---- horizons -------------------------------------------------------------------------------------------

def distance_horizon(distance: float, frozen_rate: float, floor: float, turn: float, acceleration: float) -> float:
    """A lower bound (s) on when the footprint distance can fall to `floor` (the vehicle's recorded minimum):
    no new minimum distance can occur before it.

    With the ego's yaw frozen the distance is that of the relative position to the Minkowski difference of
    the footprints, a convex set, so it is a convex function of the relative position: after a relative
    displacement v tau + delta (|delta| <= A tau^2 / 2, A the relative acceleration bound) it is at least
    d + frozen_rate tau - A tau^2 / 2. The ego turning about its reference point moves each of its points by
    at most R |dpsi| <= R r_max tau = turn tau, which changes the distance by at most as much. So the
    distance stays above d - (turn - frozen_rate) tau - A tau^2 / 2."""
    return reach_time_scalar(distance - floor, turn - frozen_rate, acceleration)


def approach_horizon(distance: float, frozen_rate: float, relative_speed: float, turn: float,
                     acceleration: float, yaw_rate_bound: float) -> float:
    """A lower bound (s) on when an approach (frozen_rate < -turn) can end, i.e. the distance's rate reach 0
    (a closest approach, the root `distance_rate` = 0 the master bisects).

    The rate is n . v_rel plus the turning part (at most `turn` = R r_max in size), n the unit normal of the
    Minkowski difference at the relative position. While the distance stays above d / 2 (at least for
    tau_half = reach_time(d / 2, relative_speed + turn, A)), |v_rel| <= S1 = relative_speed + A tau_half and
    the relative position moves at most at S1. n turns: with the translation at most at S1 / (d / 2) (the
    distance to a convex set has a Hessian of norm <= 1 / distance), with the ego's turning at most at r_max
    (an edge's normal turns with the ego) or turn / (d / 2) (a closest vertex moves at most at turn); all
    within 4 P / d + r_max, P = S1 + turn. So n . v_rel grows at most at K = A + S1 (4 P / d + r_max), and
    the approach cannot end before min(tau_half, (-frozen_rate - turn) / K)."""
    closing = -frozen_rate - turn
    if closing <= 0.0 or distance <= 0.0:
        return 0.0
    half = reach_time_scalar(distance / 2, relative_speed + turn, acceleration)
    speed = relative_speed + acceleration * half
    growth = acceleration + speed * (4 * (speed + turn) / distance + yaw_rate_bound)
    bound = closing / growth
    return bound if bound < half else half  # min(half, bound)


def heading_horizon(dx: float, dy: float, vx: float, vy: float, radius_sum: float, turn: float,
                    acceleration: float) -> float:
    """A lower bound (s) on when an approach can end, for a vehicle far compared to the footprints' sizes
    (`approach_horizon` is the tighter near): it needs no bound on the ego's yaw beyond `turn`.

    The closest points p_A, p_B lie within R_A, R_B of the centres (radius_sum = R_A + R_B), so the unit
    normal n = (p_B - p_A) / d is within asin(radius_sum / rho) of the centre offset c = (dx, dy),
    rho = |c|. The distance's rate is n . v_rel plus the turning part (at most `turn`), so it stays < 0 while
    the angle between n and -v_rel stays below acos(turn / |v_rel|). Over tau_1 = min(reach_time(rho / 2,
    |v|, A), |v| / 2A), rho >= rho0 / 2 and |v_rel| >= |v0| / 2; the direction of c turns at most at
    S1 / (rho0 / 2) (S1 = |v0| + A tau_1) and that of v_rel at most at A / (|v0| / 2). So the approach
    cannot end before min(tau_1, (acos(2 turn / |v0|) - asin(2 radius_sum / rho0) - alpha0) / (2 S1 / rho0 +
    2 A / |v0|)), alpha0 the angle between c and -v_rel now; 0 if that is not positive."""
    rho = math.sqrt(dx * dx + dy * dy)
    speed = math.sqrt(vx * vx + vy * vy)
    if speed <= 2 * turn or rho <= 2 * radius_sum:
        return 0.0
    cos_alpha = -(dx * vx + dy * vy) / (rho * speed)
    cos_alpha = cos_alpha if cos_alpha > -1.0 else -1.0  # clipped to [-1, 1] as min(1, max(-1, .)) does
    alpha = math.acos(cos_alpha if cos_alpha < 1.0 else 1.0)
    margin = math.acos(2 * turn / speed) - math.asin(2 * radius_sum / rho) - alpha
    if margin <= 0.0:
        return 0.0
    within = reach_time_scalar(rho / 2, speed, acceleration)
    slowing = speed / (2 * acceleration)
    if slowing < within:
        within = slowing
    fastest = speed + acceleration * within
    bound = margin / (2 * fastest / rho + 2 * acceleration / speed)
    bound = bound if bound < within else within
    # longer, where the angles themselves (not their rates) prove it: over tau the relative velocity moves by at
    # most A tau (its direction by at most asin(A tau / |v0|), its size to at least |v0| - A tau), the centre
    # offset by at most P = |v0| tau + A tau^2 / 2 (its direction by at most asin(P / rho0), its length to at least
    # rho0 - P); the approach goes on while alpha0 + those turns + asin(radius_sum / (rho0 - P)) stays below
    # acos(turn / (|v0| - A tau)). Each stretch of the bound is kept only if that holds at its end (every term
    # worsens as tau grows, so it holds before it).
    for _ in range(HEADING_STRETCHES):
        longer = HEADING_STRETCH * bound
        turned = acceleration * longer
        moved = speed * longer + 0.5 * turned * longer
        slowest, nearest = speed - turned, rho - moved
        if not (turn < slowest and radius_sum < nearest and turned < speed and moved < rho):
            break
        if math.acos(turn / slowest) - math.asin(radius_sum / nearest) - math.asin(moved / rho) \
                - math.asin(turned / speed) - alpha <= 0.0:
            break
        bound = longer
    return bound


def course_horizon(dx: float, dy: float, vx: float, vy: float, half_x: float, half_y: float, until: float,
                   turn: float, acceleration: float) -> float:
    """A lower bound (s) on when a collision course or a time headway can begin for a vehicle beside the ego's
    path (the common case within RANGE: a car passing in the next lane): a T <= `until`, near the longest that the
    test below proves, else 0. half_x, half_y: the sums of the two
    footprints' half extents along the road's axes x, y now (`_axes`' h: a |cos psi| + b |sin psi| + l / 2,
    a |sin psi| + b |cos psi| + w / 2).

    TTC is finite only if some s >= 0 has the projections overlapping on all four axes, so in particular on
    x and y: |dx + vx s| < half_x and |dy + vy s| < half_y at the same s; and a headway needs
    |dy| < half_y (s = 0). Neither can hold while the footprints' y projections stay apart, on the same
    side, for every s in [0, S] with S >= every s at which the x projections overlap. Over tau in [0, T],
    with the relative acceleration bounded by A (`acceleration`) and the ego turning (`turn` = R r_max):
    - each velocity component moves at most F = A T and each position component at most v tau + E,
      E = A T^2 / 2, from now;
    - half_x and half_y grow at most turn T (d/dt (a |cos psi| + b |sin psi|) is at most
      sqrt(a^2 + b^2) r_max <= R r_max, Cauchy-Schwarz);
    - |dx + vx s| < half_x implies |vx| s < |dx| + half_x, so with |vx| > F every such s is below
      S = (|dx| + |vx| T + E + half_x + turn T) / (|vx| - F);
    - with sigma = sign(dy): sigma (dy + vy s) >= sigma dy - E + min(0, sigma vy T) + min(0, (sigma vy - F) S)
      for every s in [0, S] (linear in s and tau, so its least value is at an end).
    So if that lower bound exceeds half_y + turn T (by COURSE_MARGIN, for the rounding of `ttc` and
    `headway`), TTC and the headway stay undefined for the whole of [0, T]."""
    if dy == 0.0:
        return 0.0
    side = 1.0 if dy > 0.0 else -1.0
    lateral, ahead, speed, gap = side * vy, (dx if dx >= 0.0 else -dx) + half_x, vx if vx >= 0.0 else -vx, \
        side * dy - half_y

    # the test only gets harder as T grows (every term worsens). A first T from its leading terms (S ~ S0 =
    # (|dx| + half_x) / |vx|: gap + min(0, sigma vy) S0 - (A S0 + turn + max(0, -sigma vy)) T > 0), shortened
    # until the test passes. The per-check path: min(0, x) written as `x if x < 0.0 else 0.0`, max(0, x) as
    # `x if x > 0.0 else 0.0`, min(x, y) as `y if y < x else x` (what the builtins return, nan included), and
    # the test of one T inline
    if speed <= 0.0:
        return 0.0
    reach0 = ahead / speed
    room = gap + (lateral if lateral < 0.0 else 0.0) * reach0
    if room <= 0.0:
        return 0.0
    window = COURSE_WINDOW if COURSE_WINDOW < until else until
    away = -lateral
    guess = 0.9 * room / (acceleration * reach0 + turn + (away if away > 0.0 else 0.0))
    horizon = guess if guess < window else window
    for _ in range(COURSE_TRIES):
        # the test for one T (`horizon`): F = A T, E = A T^2 / 2, S as above
        drift = acceleration * horizon
        if not speed <= drift:
            slip = 0.5 * drift * horizon
            grow = turn * horizon
            reach = (ahead + speed * horizon + slip + grow) / (speed - drift)
            swing = lateral * horizon
            late = (lateral - drift) * reach
            if (gap - slip + (swing if swing < 0.0 else 0.0) + (late if late < 0.0 else 0.0) - grow
                    > COURSE_MARGIN):
                return horizon
        horizon *= 0.75
    return 0.0


def distance_horizons(distance, frozen_rate, floor, turn: float, acceleration):
    """`distance_horizon` over arrays of vehicles."""
    return reach_time(distance - floor, turn - frozen_rate, acceleration)


def approach_horizons(distance, frozen_rate, relative_speed, turn: float, acceleration, yaw_rate_bound: float):
    """`approach_horizon` over arrays of vehicles."""
    closing = -frozen_rate - turn
    with np.errstate(divide="ignore", invalid="ignore"):
        half = reach_time(distance / 2, relative_speed + turn, acceleration)
        speed = relative_speed + acceleration * half
        growth = acceleration + speed * (4 * (speed + turn) / distance + yaw_rate_bound)
        bound = np.minimum(half, closing / growth)
    return np.where((closing <= 0.0) | (distance <= 0.0), 0.0, bound)


def relative_motion(traffic, i: int, state, ego_length: float, ego_width: float):
    """(ego footprint, dx, dy, vx, vy, ax, ay, length, width): vehicle i relative to the ego at its state, in
    the inertial frame (the ego's body-frame velocity vx, vy and acceleration ax, ay turned by psi; the
    vehicle's station acceleration -(speed1 - speed0) / duration during a transition, its lateral rate
    constant)."""
    c, s = math.cos(state.psi), math.sin(state.psi)
    station, lateral, speed, lateral_rate, _ = traffic.motion_of(i, state.time)
    elapsed, duration = state.time - float(traffic.t0[i]), float(traffic.duration[i])
    station_acceleration = -(float(traffic.speed1[i]) - float(traffic.speed0[i])) / duration \
        if elapsed < duration else 0.0
    return (Footprint(ego_length / 2, ego_width / 2, c, s), station - state.x, -lateral - state.y,
            -speed - (state.vx * c - state.vy * s), -lateral_rate - (state.vx * s + state.vy * c),
            station_acceleration - (state.ax * c - state.ay * s), -(state.ax * s + state.ay * c),
            float(traffic.length[i]), float(traffic.width[i]))
