"""Criticality measures between the ego and one traffic vehicle: footprint distance, time to collision (TTC),
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
  way, divided by the ego's speed along the road.

Frames: ISO 8855 inertial, x = station, y = -lateral (road.py). Relative quantities are vehicle - ego: centre
(dx, dy), velocity (vx, vy), acceleration. A vehicle moving at `speed` toward decreasing station with a
lateral rate has the velocity (-speed, -lateral_rate).

Forms: each function on plain floats (the master's path for up to SCALAR_VEHICLES vehicles), and its
vectorised twin (suffix `s`, NumPy arrays over vehicles) doing the same operations in the same order, so
the two give the same bits (tested), as in triggers.py. Square roots as sqrt(x*x + y*y) (math.sqrt and
np.sqrt are both correctly rounded; math.hypot and np.hypot are not the same algorithm).

Design: how the master uses these (one record for the run, `Extremes`, one row per traffic vehicle).
1. Looks. At a look (`Extremes.look`, one pass) a vehicle's values at the ego's state are offered to the
   record (a value replaces the recorded extreme only when better by more than FLAT, so the first instant
   an extreme is reached stays), and the look returns the vehicle's rates and its horizon. The master
   keeps a next-look instant per vehicle and their minimum, as it keeps its traffic bounds: at a
   communication point it looks at the vehicles whose instant has come, and drops every next-look instant
   when something fires (an action changes a vehicle's motion). A look also leaves `Extremes.quiet`, a
   bound before which none of the vehicle's located instants (2) can be: the master starts a step from an FMU
   snapshot only when such a bound ends within it. It also looks at every vehicle at its
   spawn, its departure and the run's end (an extreme at the end of an interval), and at every located
   instant below.
2. Located instants. Inside a step an extreme is the root of its rate (`Extremes.rates`: distance, TTC,
   minus DRAC, headway; from < 0 to >= 0), or a contact's start or end (the master's contact triggers
   already locate them; TTC is 0 and the distance 0 there), or a collision course's start or end (TTC
   turns finite / infinite). The master adds a trigger kind "criticality" whose condition at a probe is: a
   looked-at vehicle's rate turned from < 0 at the step's start to >= 0, or its collision course began or
   ended. It bisects it like any trigger (rollback, TIME_TOLERANCE) and looks at the vehicle at the
   located instant.
3. Horizons (`Extremes.look`'s second value): 0 within RANGE (50 m, SUMO's device.ssm.range) while a
   vehicle is on a collision course or has a headway: TTC, DRAC and headway are followed at every
   communication point there (the driver's 20 Hz samples at least), their roots and courses found by the
   sign checks of 2, which assume at most one change of sign between two communication points (no horizon
   bounds TTC's or headway's rate yet). Within RANGE with neither (a car beside the ego's path), the
   distance's horizon below, cut to `course_horizon`'s proven bound on when a course or a headway can
   begin. Beyond RANGE only the
   distance applies, and the horizon is a proven lower bound, from the ego's bounds as in triggers.py (the
   acceleration A of its CG, its yaw rate r_max, the radius R of its footprint): the earliest of coming
   within RANGE (`distance_horizon`) and of a new minimum distance, which needs both the distance below the
   recorded minimum (`distance_horizon`) and an approach ending (`approach_horizon` near,
   `heading_horizon` far), and never past the end of a lateral transition.
4. PET: when an action starts a lateral move, `band_times` gives the instant the vehicle's footprint
   leaves the ego's lane (closed form); the master steps to it like a driver sample and calls
   `Extremes.path_left`; the conflict stations then pending (`Extremes.pending_stations`) are distance
   triggers for the ego's front, horizon reach_time(station - front, station_rate + R r_max, A) as for the
   master's event distances, and at the located instant `Extremes.reach` records the PET.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

INF = math.inf


class Footprint(NamedTuple):
    """The ego's footprint at one instant: half length and width, cos and sin of its yaw (made once per
    instant and shared by every vehicle)."""

    half_length: float
    half_width: float
    cos: float
    sin: float

    @staticmethod
    def of(length: float, width: float, psi: float) -> Footprint:
        return Footprint(length / 2, width / 2, math.cos(psi), math.sin(psi))


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


def penetration(ego: Footprint, dx: float, dy: float, length: float, width: float) -> float:
    """The overlap depth of the two footprints (> 0: they overlap): the smallest overlap of their
    projections on the four separating axes (x, y, the ego's u and v), which for convex polygons is the
    penetration depth (the shortest translation that separates them)."""
    a, b, c, s = ego
    ac, as_ = abs(c), abs(s)
    hl, hw = length / 2, width / 2
    along_x = a * ac + b * as_ + hl - abs(dx)
    along_y = a * as_ + b * ac + hw - abs(dy)
    along_u = a + hl * ac + hw * as_ - abs(dx * c + dy * s)
    along_v = b + hl * as_ + hw * ac - abs(-dx * s + dy * c)
    return min(min(along_x, along_y), min(along_u, along_v))


def penetrations(ego: Footprint, dx, dy, length, width):
    """`penetration` over arrays of vehicles."""
    a, b, c, s = ego
    ac, as_ = abs(c), abs(s)
    hl, hw = length / 2, width / 2
    along_x = a * ac + b * as_ + hl - np.abs(dx)
    along_y = a * as_ + b * ac + hw - np.abs(dy)
    along_u = a + hl * ac + hw * as_ - np.abs(dx * c + dy * s)
    along_v = b + hl * as_ + hw * ac - np.abs(-dx * s + dy * c)
    return np.minimum(np.minimum(along_x, along_y), np.minimum(along_u, along_v))


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
    return _distance_and_rates(ego, dx, dy, vx, vy, yaw_rate, length, width)[1]


def _distance_and_rates(ego: Footprint, dx: float, dy: float, vx: float, vy: float, yaw_rate: float, length: float,
                        width: float) -> tuple[float, float, float]:
    """(distance, its rate, its rate with the ego's yaw frozen) in one pass over the corners (the master's
    look at one vehicle): `distance`, `distance_rate` and `distance_rate` with yaw_rate 0.

    The per-look path, so written out: `penetration` and `_corners` inline (the same operations in the same
    order, so the same bits); the eight corners unrolled, their squared gaps first and one square root, the
    least's (sqrt is correctly rounded, so monotonic: sqrt(min) = min(sqrt)), then the rates of the closest
    corners only: those whose gap's square root equals it (in corner order: the first sets them, later
    equally close ones can only lower them)."""
    a, b, c, s = ego
    ac = c if c >= 0.0 else -c
    as_ = s if s >= 0.0 else -s
    hl, hw = length / 2, width / 2
    du = dx * c + dy * s  # the vehicle's centre in the ego's body frame
    dv = -dx * s + dy * c
    if (a * ac + b * as_ + hl - abs(dx) >= 0.0 and a * as_ + b * ac + hw - abs(dy) >= 0.0
            and a + hl * ac + hw * as_ - abs(du) >= 0.0 and b + hl * as_ + hw * ac - abs(dv) >= 0.0):
        return 0.0, 0.0, 0.0  # penetration >= 0: in contact or touching
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
    footprints' half extents along it (`penetration`'s terms)."""
    a, b, c, s = ego
    ac, as_ = abs(c), abs(s)
    hl, hw = length / 2, width / 2
    return ((dx, vx, a * ac + b * as_ + hl),
            (dy, vy, a * as_ + b * ac + hw),
            (dx * c + dy * s, vx * c + vy * s, a + hl * ac + hw * as_),
            (-dx * s + dy * c, -vx * s + vy * c, b + hl * as_ + hw * ac))


def ttc(ego: Footprint, dx: float, dy: float, vx: float, vy: float, length: float, width: float) -> float:
    """Constant-velocity time to collision (s): the projections on an axis overlap while |p + q t| < h, an
    interval (entry, exit) of t; the footprints overlap on the intersection of the four intervals. 0 when
    they overlap now, inf when not on a collision course (the intersection is empty, or past)."""
    entry, leave = -INF, INF
    for p, q, h in _axes(ego, dx, dy, vx, vy, length, width):
        if q == 0.0:
            if abs(p) >= h:
                return INF  # never overlapping along this axis
            continue
        t1, t2 = (-h - p) / q, (h - p) / q
        if t2 < t1:
            t1, t2 = t2, t1
        if t1 > entry:
            entry = t1
        if t2 < leave:
            leave = t2
    if entry >= leave or leave <= 0.0:
        return INF
    return entry if entry > 0.0 else 0.0


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
    return _ttc_rate(ego, dx, dy, vx, vy, ax, ay, yaw_rate, length, width)


def _ttc_rate(ego: Footprint, dx: float, dy: float, vx: float, vy: float, ax: float, ay: float, yaw_rate: float,
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
    return _drac_rate(t, _ttc_rate(ego, dx, dy, vx, vy, ax, ay, yaw_rate, length, width), vx, vy, ax, ay)


def _drac_rate(t: float, t_rate: float, vx: float, vy: float, ax: float, ay: float) -> float:
    speed = math.sqrt(vx * vx + vy * vy)
    speed_rate = (vx * ax + vy * ay) / speed
    return (speed_rate * t - speed * t_rate) / (2 * t * t)


# ---- time headway -----------------------------------------------------------------------------------------

def headway(ego: Footprint, dx: float, dy: float, station_rate: float, vehicle_station_rate: float,
            length: float, width: float) -> float:
    """Time headway (s) to a vehicle ahead in the ego's path moving the same way: the bumper-to-bumper gap
    along the road (the vehicle's rear to the front of the ego's footprint) over the ego's speed along the
    road (SUMO's TGAP). inf when the vehicle is not ahead in the ego's path (the footprints do not overlap
    laterally, or it is not wholly ahead), not moving the ego's way, or the ego does not move forward."""
    a, b, c, s = ego
    ac, as_ = abs(c), abs(s)
    gap = dx - (a * ac + b * as_) - length / 2
    if (gap <= 0.0 or abs(dy) >= a * as_ + b * ac + width / 2 or station_rate <= 0.0
            or vehicle_station_rate <= 0.0):
        return INF
    return gap / station_rate


def headway_rate(ego: Footprint, dx: float, dy: float, station_rate: float, vehicle_station_rate: float,
                 station_acceleration: float, yaw_rate: float, length: float, width: float) -> float:
    """d/dt of `headway` along the present motion (nan where it is not defined): headway = g / v with the
    gap g = dx - (a |cos psi| + b |sin psi|) - l / 2, so headway' = (g' v - g v') / v^2 with
    g' = vehicle_station_rate - station_rate - (a d|cos psi|/dt + b d|sin psi|/dt), v' = station_acceleration."""
    value = headway(ego, dx, dy, station_rate, vehicle_station_rate, length, width)
    if value == INF:
        return math.nan
    return _headway_rate(ego, value, station_rate, vehicle_station_rate, station_acceleration, yaw_rate)


def _headway_rate(ego: Footprint, value: float, station_rate: float, vehicle_station_rate: float,
                  station_acceleration: float, yaw_rate: float) -> float:
    """`headway_rate` where the headway `value` is known to be defined."""
    a, b, c, s = ego
    cos_rate = -math.copysign(1.0, c) * s * yaw_rate
    sin_rate = math.copysign(1.0, s) * c * yaw_rate
    gap_rate = vehicle_station_rate - station_rate - (a * cos_rate + b * sin_rate)
    return (gap_rate - value * station_acceleration) / station_rate


def headways(ego: Footprint, dx, dy, station_rate: float, vehicle_station_rate, length, width):
    a, b, c, s = ego
    ac, as_ = abs(c), abs(s)
    gap = dx - (a * ac + b * as_) - length / 2
    ahead = (gap > 0.0) & (np.abs(dy) < a * as_ + b * ac + width / 2) & (vehicle_station_rate > 0.0)
    if station_rate <= 0.0:
        return np.full(np.shape(gap), INF)
    return np.where(ahead, gap / station_rate, INF)


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

def _reach_time(distance: float, rate: float, acceleration: float) -> float:
    """triggers.reach_time_scalar (repeated to keep imports flowing one way: triggers imports traffic only)."""
    if distance <= 0.0:
        return 0.0
    root = math.sqrt(rate * rate + 2 * acceleration * distance)
    if rate > 0:
        closing = rate + root  # max(rate + root, 1e-300) without the call (the same value)
        return 2 * distance / (1e-300 if 1e-300 > closing else closing)
    return (root - rate) / acceleration


def distance_horizon(distance: float, frozen_rate: float, floor: float, turn: float, acceleration: float) -> float:
    """A lower bound (s) on when the footprint distance can fall to `floor` (the vehicle's recorded minimum):
    no new minimum distance can occur before it.

    With the ego's yaw frozen the distance is that of the relative position to the Minkowski difference of
    the footprints, a convex set, so it is a convex function of the relative position: after a relative
    displacement v tau + delta (|delta| <= A tau^2 / 2, A the relative acceleration bound) it is at least
    d + frozen_rate tau - A tau^2 / 2. The ego turning about its reference point moves each of its points by
    at most R |dpsi| <= R r_max tau = turn tau, which changes the distance by at most as much. So the
    distance stays above d - (turn - frozen_rate) tau - A tau^2 / 2."""
    return _reach_time(distance - floor, turn - frozen_rate, acceleration)


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
    half = _reach_time(distance / 2, relative_speed + turn, acceleration)
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
    within = _reach_time(rho / 2, speed, acceleration)
    slowing = speed / (2 * acceleration)
    if slowing < within:
        within = slowing
    fastest = speed + acceleration * within
    bound = margin / (2 * fastest / rho + 2 * acceleration / speed)
    return bound if bound < within else within


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
    lateral, ahead, speed, gap = side * vy, abs(dx) + half_x, abs(vx), side * dy - half_y

    def proven(horizon: float) -> bool:
        drift = acceleration * horizon  # F
        if speed <= drift:
            return False
        slip = 0.5 * drift * horizon  # E
        grow = turn * horizon
        reach = (ahead + speed * horizon + slip + grow) / (speed - drift)  # S
        return (gap - slip + min(0.0, lateral * horizon) + min(0.0, (lateral - drift) * reach) - grow
                > COURSE_MARGIN)

    # the test only gets harder as T grows (every term worsens). A first T from its leading terms (S ~ S0 =
    # (|dx| + half_x) / |vx|: gap + min(0, sigma vy) S0 - (A S0 + turn + max(0, -sigma vy)) T > 0), shortened
    # until the test passes
    if speed <= 0.0:
        return 0.0
    reach0 = ahead / speed
    room = gap + min(0.0, lateral) * reach0
    if room <= 0.0:
        return 0.0
    horizon = min(min(until, COURSE_WINDOW), 0.9 * room / (acceleration * reach0 + turn + max(0.0, -lateral)))
    for _ in range(COURSE_TRIES):
        if proven(horizon):
            return horizon
        horizon *= 0.75
    return 0.0


def _reach_times(distance, rate, acceleration):
    """`_reach_time` over arrays (triggers.reach_time)."""
    used_up = distance <= 0.0
    distance = np.maximum(distance, 0.0)
    root = np.sqrt(rate * rate + 2 * acceleration * distance)
    return np.where(used_up, 0.0,
                    np.where(rate > 0, 2 * distance / np.maximum(rate + root, 1e-300), (root - rate) / acceleration))


def distance_horizons(distance, frozen_rate, floor, turn: float, acceleration):
    """`distance_horizon` over arrays of vehicles."""
    return _reach_times(distance - floor, turn - frozen_rate, acceleration)


def approach_horizons(distance, frozen_rate, relative_speed, turn: float, acceleration, yaw_rate_bound: float):
    """`approach_horizon` over arrays of vehicles."""
    closing = -frozen_rate - turn
    with np.errstate(divide="ignore", invalid="ignore"):
        half = _reach_times(distance / 2, relative_speed + turn, acceleration)
        speed = relative_speed + acceleration * half
        growth = acceleration + speed * (4 * (speed + turn) / distance + yaw_rate_bound)
        bound = np.minimum(half, closing / growth)
    return np.where((closing <= 0.0) | (distance <= 0.0), 0.0, bound)


# ---- the run's record: per vehicle, its extremes ---------------------------------------------------------------

FLAT = 1e-9  # m or s: a later instant replaces a recorded extreme only if it is better by more than this
# m: TTC, DRAC and headway are followed while the footprints are within this distance, as SUMO's SSM device
# follows encounters within device.ssm.range (default 50 m); the distance everywhere
RANGE = 50.0
# course_horizon: s, the longest horizon tried; how many times it shortens its first guess (by a quarter) before
# giving up; m, the least lateral margin it accepts (far above the rounding of ttc's and headway's few operations
# on metres)
COURSE_WINDOW = 1.0
COURSE_TRIES = 8
COURSE_MARGIN = 1e-6
# up to this many vehicles are handled one by one in plain floats, more at once in NumPy arrays: on a few
# vehicles NumPy's per-operation overhead (about 1 µs on small arrays) costs more than the arithmetic (the trigger
# schedule uses the same bound)
SCALAR_VEHICLES = 4

MEASURES = ("min_distance", "min_ttc", "max_drac", "min_pet", "min_headway")


class Extremes:
    """Per traffic vehicle (index as in traffic.Traffic), the extreme of each measure and the instant it was
    first reached, offered values at every communication point and at every instant the master locates (a
    root of a rate, a contact's or a collision course's start or end, a PET instant).

    A later value replaces the recorded one only when better by more than FLAT, so that a flat extreme (the
    distance to a car passing in the next lane, constant over the whole overlap) keeps the first instant it
    was reached, whatever the samples after it: with the start located, the instant does not depend on the
    step. Values are SI (m, s, m/s2); `summary` converts lengths at the results boundary."""

    def __init__(self, ego_length: float, ego_width: float, capacity: int = 16):
        self.ego_length, self.ego_width = ego_length, ego_width
        self.size = 0
        self.value = {name: np.full(capacity, np.nan) for name in MEASURES}
        self.time = {name: np.full(capacity, np.nan) for name in MEASURES}
        self.left_path = np.full(capacity, np.nan)  # s, when the vehicle's footprint last left the ego's path
        self.conflict = np.full(capacity, np.nan)  # m, the station the ego's front must reach then (PET)
        # the ego passing first (PET): the far end of the area where the vehicle's footprint will enter the ego's
        # path, while the ego's rear has yet to pass it (m), and the instant it did (s)
        self.far_end = np.full(capacity, np.nan)
        self.rear_left = np.full(capacity, np.nan)
        # s from the last look: a lower bound on when that vehicle's next located instant (a closest
        # approach, a collision course's start or end, a transition's end) can be (0: any time)
        self.quiet = 0.0
        # the last ego state evaluated at and (footprint, cos, sin, inertial velocity) there; per vehicle its
        # (length, width) in floats (fixed from its spawn, a vehicle's index is never reused)
        self._at = (None, None)
        self._sizes: dict[int, tuple[float, float]] = {}

    def _grow(self, size: int) -> None:
        while size > len(self.left_path):
            for table in (self.value, self.time):
                for name, values in table.items():
                    table[name] = np.concatenate([values, np.full(len(values), np.nan)])
            self.left_path = np.concatenate([self.left_path, np.full(len(self.left_path), np.nan)])
            self.conflict = np.concatenate([self.conflict, np.full(len(self.conflict), np.nan)])
            self.far_end = np.concatenate([self.far_end, np.full(len(self.far_end), np.nan)])
            self.rear_left = np.concatenate([self.rear_left, np.full(len(self.rear_left), np.nan)])
        self.size = max(self.size, size)

    # -- offering values

    def offer(self, name: str, i: int, t: float, value: float) -> None:
        """One vehicle's value of one measure at instant t (nan or inf: not applicable now)."""
        if not math.isfinite(value):
            return
        if i >= self.size:
            self._grow(i + 1)
        values = self.value[name]
        recorded = float(values[i])
        if name == "max_drac":
            better = recorded != recorded or value > recorded + FLAT
        else:
            better = recorded != recorded or value < recorded - FLAT
        if better:
            values[i] = value
            self.time[name][i] = t
        elif (value > recorded) if name == "max_drac" else (value < recorded):
            values[i] = value  # within FLAT: the value improves, the first instant stays

    def offers(self, name: str, idx: np.ndarray, t: float, values: np.ndarray) -> None:
        """`offer` for vehicles idx at once."""
        if len(idx) and int(idx.max()) >= self.size:
            self._grow(int(idx.max()) + 1)
        recorded = self.value[name][idx]
        finite = np.isfinite(values)
        empty = np.isnan(recorded)
        if name == "max_drac":
            better = finite & (empty | (values > recorded + FLAT))
            improves = finite & ~empty & (values > recorded)
        else:
            better = finite & (empty | (values < recorded - FLAT))
            improves = finite & ~empty & (values < recorded)
        self.value[name][idx] = np.where(better | improves, values, recorded)
        self.time[name][idx[better]] = t

    def observe(self, traffic, idx: np.ndarray, state) -> None:
        """Offers the distance (and within RANGE, TTC, DRAC and headway) of vehicles idx (traffic.Traffic
        indices) at the ego's state (EgoState: ISO 8855 position x, y, yaw psi, body-frame velocity vx, vy),
        and completes any PET whose conflict station the ego's front has reached. A few vehicles in plain
        floats, more in arrays (the same bits)."""
        t = state.time
        c, s = math.cos(state.psi), math.sin(state.psi)
        ego = Footprint(self.ego_length / 2, self.ego_width / 2, c, s)
        ego_vx, ego_vy = state.vx * c - state.vy * s, state.vx * s + state.vy * c  # inertial
        if len(idx) <= SCALAR_VEHICLES:
            for i in idx.tolist():
                station, lateral, speed, lateral_rate, _ = traffic.motion_of(i, t)
                length, width = float(traffic.length[i]), float(traffic.width[i])
                dx, dy = station - state.x, -lateral - state.y
                vx, vy = -speed - ego_vx, -lateral_rate - ego_vy
                d = distance(ego, dx, dy, length, width)
                self.offer("min_distance", i, t, d)
                if d <= RANGE:
                    value = ttc(ego, dx, dy, vx, vy, length, width)
                    self.offer("min_ttc", i, t, value)
                    self.offer("max_drac", i, t, drac(value, vx, vy))
                    self.offer("min_headway", i, t, headway(ego, dx, dy, ego_vx, -speed, length, width))
        else:
            station, lateral, speed, lateral_rate, _ = traffic.motion(idx, t)
            length, width = traffic.length[idx], traffic.width[idx]
            dx, dy = station - state.x, -lateral - state.y
            vx, vy = -speed - ego_vx, -lateral_rate - ego_vy
            d = distances(ego, dx, dy, length, width)
            self.offers("min_distance", idx, t, d)
            near = d <= RANGE  # beyond: inf, not applicable
            values = np.where(near, ttcs(ego, dx, dy, vx, vy, length, width), INF)
            self.offers("min_ttc", idx, t, values)
            self.offers("max_drac", idx, t, dracs(values, vx, vy))
            self.offers("min_headway", idx, t, np.where(near, headways(ego, dx, dy, ego_vx, -speed, length, width),
                                                        INF))
        self.reach(state)

    def _evaluate(self, traffic, i: int, state):
        """Vehicle i at the ego's state, in one pass: (values to offer {measure: value}, rates, what the horizon
        needs). Beyond RANGE only the distance and its rates."""
        t = state.time
        at = self._at
        if at[0] is state:  # another vehicle at the same ego state: its footprint and velocity as computed
            ego, c, s, ego_vx, ego_vy = at[1]
        else:
            c, s = math.cos(state.psi), math.sin(state.psi)
            ego = Footprint(self.ego_length / 2, self.ego_width / 2, c, s)
            ego_vx, ego_vy = state.vx * c - state.vy * s, state.vx * s + state.vy * c
            self._at = (state, (ego, c, s, ego_vx, ego_vy))
        station, lateral, speed, lateral_rate, _ = traffic.motion_of(i, t)
        elapsed, duration = t - float(traffic.t0[i]), float(traffic.duration[i])
        moving = elapsed < duration
        speed_rate = (float(traffic.speed1[i]) - float(traffic.speed0[i])) / duration if moving else 0.0
        size = self._sizes.get(i)
        if size is None:
            size = self._sizes[i] = (float(traffic.length[i]), float(traffic.width[i]))
        length, width = size
        dx, dy = station - state.x, -lateral - state.y
        vx, vy = -speed - ego_vx, -lateral_rate - ego_vy
        d, rate, frozen = _distance_and_rates(ego, dx, dy, vx, vy, state.yaw_rate, length, width)
        motion = (d, frozen, dx, dy, vx, vy, length, width, speed_rate, duration - elapsed if moving else INF, ego)
        if d > RANGE:
            return {"min_distance": d}, (rate, math.nan, math.nan, math.nan), motion
        value = ttc(ego, dx, dy, vx, vy, length, width)
        ego_ax = state.ax * c - state.ay * s
        gap_time = headway(ego, dx, dy, ego_vx, -speed, length, width)
        values = {"min_distance": d, "min_ttc": value, "min_headway": gap_time}
        headway_change = math.nan if gap_time == INF else \
            _headway_rate(ego, gap_time, ego_vx, -speed, ego_ax, state.yaw_rate)
        if not 0.0 < value < INF:
            return values, (rate, math.nan, math.nan, headway_change), motion
        ax, ay = -speed_rate - ego_ax, -(state.ax * s + state.ay * c)
        values["max_drac"] = drac(value, vx, vy)
        value_rate = _ttc_rate(ego, dx, dy, vx, vy, ax, ay, state.yaw_rate, length, width)
        return values, (rate, value_rate, -_drac_rate(value, value_rate, vx, vy, ax, ay), headway_change), motion

    def rates(self, traffic, i: int, state) -> tuple[float, float, float, float]:
        """(distance rate, TTC rate, minus the DRAC rate, headway rate) of vehicle i at the ego's state (nan
        where the measure is not defined, and for all but the distance beyond RANGE). The master's
        "criticality" condition at a bisection probe: any of them turned from < 0 at the step's start to >= 0
        (a closest approach, a smallest TTC, a largest DRAC, a smallest headway), or the TTC rate turned
        from nan to a number or back (a collision course began or ended, or the vehicle crossed RANGE: the
        value there bounds the interval over which the extreme is taken)."""
        return self._evaluate(traffic, i, state)[1]

    def distance_rate(self, traffic, i: int, state) -> float:
        """`rates`' first: the distance's rate alone (the master's probe for a closest approach)."""
        t = state.time
        c, s = math.cos(state.psi), math.sin(state.psi)
        station, lateral, speed, lateral_rate, _ = traffic.motion_of(i, t)
        ego_vx, ego_vy = state.vx * c - state.vy * s, state.vx * s + state.vy * c
        return _distance_and_rates(Footprint(self.ego_length / 2, self.ego_width / 2, c, s), station - state.x,
                                   -lateral - state.y, -speed - ego_vx, -lateral_rate - ego_vy, state.yaw_rate,
                                   float(traffic.length[i]), float(traffic.width[i]))[1]

    def evaluate(self, traffic, i: int, state):
        """Vehicle i at the ego's state, nothing offered yet: for `look` (its `evaluated`), so that the master
        reads the rates at a step's end (`rates`) and looks there with one evaluation."""
        return self._evaluate(traffic, i, state)

    def look(self, traffic, i: int, state, acceleration: float, yaw_rate_bound: float,
             radius: float, evaluated=None) -> tuple[tuple[float, float, float, float], float]:
        """The master's look at vehicle i at a communication point or a located instant: offers its values
        and returns its rates (`rates`) and a horizon: a lower bound (s from now) on when it next needs a
        look. 0 within RANGE on a collision course or with a headway (TTC, DRAC and headway are followed at
        every communication point there, their roots and collision courses located by the master); beyond
        it, the earliest of the vehicle coming within RANGE and of a new minimum distance (which needs both
        the distance below the recorded minimum and an approach ending: the latest of `distance_horizon`,
        `approach_horizon` and `heading_horizon`), and never past the end of a lateral transition (the
        vehicle's velocity changes at once there). Within RANGE with neither, the new minimum's and the
        transition's bound, no later than `course_horizon` proves no collision course or headway can
        begin. The ego's bounds as in
        triggers.py: |acceleration| of its CG, yaw rate, radius = its reference point to a footprint corner.
        Valid while the vehicle's motion is unchanged (until an action fires), like the master's other
        vehicle bounds."""
        values, rates, (d, frozen, dx, dy, vx, vy, length, width, speed_rate, transition_left, ego) = \
            self._evaluate(traffic, i, state) if evaluated is None else evaluated
        t = state.time
        for name, value in values.items():
            self.offer(name, i, t, value)
        near = d <= RANGE
        if near and (rates[1] == rates[1] or rates[3] == rates[3]):
            self.quiet = 0.0
            return rates, 0.0  # on a collision course or behind a vehicle ahead: TTC, DRAC, headway followed
        # the per-look path: min(x, y) written as `y if y < x else x` and max(x, y) as `y if y > x else x`
        # (what the builtins return, nan included), without their calls
        turn = radius * yaw_rate_bound
        relative = acceleration + (speed_rate if speed_rate >= 0.0 else -speed_rate)
        new_minimum = _reach_time(d - (float(self.value["min_distance"][i]) - FLAT), turn - frozen, relative)
        # a closest approach (the distance's rate turning from < 0 to >= 0) needs the rate < 0 now
        approach_end = INF if rates[0] >= 0.0 else 0.0
        if frozen < -turn:
            vehicle_radius = 0.5 * math.sqrt(length * length + width * width)
            approach_end = approach_horizon(d, frozen, math.sqrt(vx * vx + vy * vy), turn, relative, yaw_rate_bound)
            heading = heading_horizon(dx, dy, vx, vy, radius + vehicle_radius, turn, relative)
            if heading > approach_end:
                approach_end = heading
            if approach_end > new_minimum:
                new_minimum = approach_end
        if not near:
            # a collision course can be seen only within RANGE
            entering = _reach_time(d - RANGE, turn - frozen, relative)
            quiet = approach_end if approach_end < entering else entering
            self.quiet = transition_left if transition_left < quiet else quiet
            horizon = new_minimum if new_minimum < entering else entering
            return rates, transition_left if transition_left < horizon else horizon
        # new_minimum >= approach_end unless the rate is >= 0 (then approach_end is inf): one proof for both
        longest = approach_end if approach_end > new_minimum else new_minimum
        if transition_left < longest:
            longest = transition_left
        if not longest > 0.0:
            self.quiet = 0.0
            return rates, 0.0
        a, b, c, s = ego
        ac = c if c >= 0.0 else -c
        as_ = s if s >= 0.0 else -s
        course = course_horizon(dx, dy, vx, vy, a * ac + b * as_ + length / 2, a * as_ + b * ac + width / 2,
                                longest, turn, relative)
        quiet = transition_left if transition_left < approach_end else approach_end
        self.quiet = course if course < quiet else quiet
        horizon = transition_left if transition_left < new_minimum else new_minimum
        return rates, course if course < horizon else horizon

    # -- post-encroachment time

    def path_left(self, i: int, t: float, station: float, length: float, ego_front: float) -> None:
        """Vehicle i's footprint left the ego's path at t (`band_times`' leave instant, which the master steps
        to), standing at `station`. If the ego's front has not yet reached the area it stood on, a PET is
        pending until it does (`pending_stations`, `reach`); if it has, the two were there together (a
        contact or a near miss: distance and TTC tell) and there is none."""
        if i >= self.size:
            self._grow(i + 1)
        near_end = conflict_station(station, length)
        if ego_front < near_end:
            self.left_path[i], self.conflict[i] = t, near_end
        else:
            self.left_path[i] = self.conflict[i] = np.nan

    def path_entering(self, i: int, far_end: float, ego_rear: float) -> None:
        """Vehicle i's footprint will enter the ego's path (`band_times`' enter instant, closed form as its move
        starts), reaching then up to `far_end` (`conflict_far_end`). If the ego's rear has yet to pass that
        station, the ego may leave the area first: its rear's passage (`rear_stations`, `rear_reached`) and the
        entry (`path_entered`) give the PET. If the rear has passed it already (the ego left the area before
        the move began), no PET is measured for this entry (README)."""
        if i >= self.size:
            self._grow(i + 1)
        self.rear_left[i] = np.nan
        self.far_end[i] = far_end if ego_rear < far_end else np.nan

    def cancel_entry(self, i: int) -> None:
        """Vehicle i's motion changed before it entered the ego's path: its pending entry is void."""
        if i < self.size:
            self.far_end[i] = self.rear_left[i] = np.nan

    def rear_stations(self) -> np.ndarray:
        """(vehicle indices, far ends) whose passage by the ego's rear is pending."""
        far = self.far_end[:self.size]
        pending = np.flatnonzero((far == far) & (self.rear_left[:self.size] != self.rear_left[:self.size]))
        return pending, far[pending]

    def rear_reached(self, i: int, t: float) -> None:
        """The ego's rear passed vehicle i's entry area's far end at t."""
        self.rear_left[i] = t

    def path_entered(self, i: int, t: float) -> None:
        """Vehicle i's footprint entered the ego's path at t: if the ego's rear had left the area by then, the
        PET (ego first) = t - that instant; either way the entry is done."""
        if i >= self.size:
            return
        left = float(self.rear_left[i])
        if left == left and self.far_end[i] == self.far_end[i]:
            self.offer("min_pet", i, t, post_encroachment_time(left, t))
        self.far_end[i] = self.rear_left[i] = np.nan

    def pending_stations(self) -> np.ndarray:
        """The conflict stations the ego's front has yet to reach (the master's PET trigger: a station, like
        an event distance; horizon reach_time(station - front, station_rate + R r_max, A))."""
        conflict = self.conflict[:self.size]
        return conflict[~np.isnan(conflict)]

    def reach(self, state) -> None:
        """Completes the PETs whose conflict station the ego's front has reached by this state."""
        conflict = self.conflict[:self.size]
        if not (conflict == conflict).any():
            return
        c, s = math.cos(state.psi), math.sin(state.psi)
        front = state.x + self.ego_length / 2 * abs(c) + self.ego_width / 2 * abs(s)
        for i in np.flatnonzero(conflict <= front).tolist():
            self.offer("min_pet", i, state.time, post_encroachment_time(float(self.left_path[i]), state.time))
            self.left_path[i] = self.conflict[i] = np.nan

    # -- the results

    def summary(self, vehicle_ids, to_scenario_units) -> dict:
        """summary.json's `criticality` object (docs/results.md): run-wide extremes and one entry per vehicle,
        lengths (and DRAC, a length per s^2) through `to_scenario_units` (units.from_si), null where a measure
        never applied.
        Keys added to the first six: max_drac_time_s, min_headway_s, min_headway_time_s."""
        def number(x):
            return None if x != x else float(x)

        def entry(values: dict, times: dict) -> dict:
            length = {"min_distance", "max_drac"}
            out = {}
            for name, key, time_key in (("min_distance", "min_distance", "min_distance_time_s"),
                                        ("min_ttc", "min_ttc_s", "min_ttc_time_s"),
                                        ("max_drac", "max_drac", "max_drac_time_s"),
                                        ("min_pet", "min_pet_s", None),
                                        ("min_headway", "min_headway_s", "min_headway_time_s")):
                value = number(values[name])
                out[key] = None if value is None else (to_scenario_units(value) if name in length else value)
                if time_key:
                    out[time_key] = number(times[name])
            return out

        n = len(vehicle_ids)
        self._grow(n)  # a vehicle never looked at has all its measures null
        vehicles = [{"vehicle": int(vehicle_ids[i]),
                     **entry({k: self.value[k][i] for k in MEASURES}, {k: self.time[k][i] for k in MEASURES})}
                    for i in range(n)]
        overall_values, overall_times = {}, {}
        for name in MEASURES:
            values, times = self.value[name][:n], self.time[name][:n]
            if n == 0 or np.isnan(values).all():
                overall_values[name] = overall_times[name] = math.nan
                continue
            # the best value; among vehicles within FLAT of it, the earliest instant
            best = np.nanmax(values) if name == "max_drac" else np.nanmin(values)
            near = np.abs(values - best) <= FLAT
            overall_values[name] = best
            overall_times[name] = float(np.nanmin(np.where(near, times, np.nan)))
        return {**entry(overall_values, overall_times), "vehicles": vehicles}


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
