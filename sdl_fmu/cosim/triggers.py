"""When can a trigger first become true? Lower bounds on that instant from the ego's and the traffic's
kinematics, so that the master steps long where nothing can happen and never past a trigger unchecked.

Every bound rests on two constants of the ego, derived once from its FMU parameters (`ego_bounds`):
the magnitude A of its centre of gravity's acceleration (tire forces cannot exceed mu_max g per unit mass,
plus rolling resistance and drag, with a margin) and its yaw rate r_max. Over a time tau from now a point
of the ego at arm l from the CG moves, along any road axis, at most
    |rate now| tau + A tau^2 / 2 + l r_max tau,
and a traffic vehicle moves by its closed-form motion (speed ramps, lateral moves at a constant rate
during a transition). The instant a gap, speed or time margin could close is then the positive root of a
quadratic (geometry.reach_time). The bounds are valid whatever the ego's inputs do, so a per-vehicle bound
stays valid until that vehicle's own motion changes (an action fires), and the master caches it.

The traffic conditions (`vehicle_conditions`, and its plain-float forms `vehicle_condition`, `vehicle_triggered`):
- an action's closure time T (docs/scenarios.md): with gap = vehicle station - ego station and the closing speed
  c at which |gap| shrinks, a positive T fires when c > 0 and |gap| / c <= T, a negative T when the two separate
  (c < 0) and |gap| / -c >= |T|; `F` / `B` only with the vehicle in front of / behind the ego;
- contact: the footprints overlap (geometry.penetration > 0);
- departure: the vehicle is wholly behind the ego (its front behind the ego's rear), moving away, and no action
  is left that could still fire (docs/decisions.md, A vehicles).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..units import STANDARD_GRAVITY
from ..vehicle import EgoState
from .geometry import Footprint, overlaps, penetration, penetrations, reach_time, reach_time_scalar
from .traffic import Traffic

ACCELERATION_MARGIN = 1.25  # x the physical bound, + ACCELERATION_SLACK: model transients, round-off
ACCELERATION_SLACK = 0.5  # m/s2
YAW_RATE_MARGIN = 2.0
REFERENCE_SPEED = 60.0  # m/s, drag is bounded at max(this, 2 x the start speed)


@dataclass(frozen=True)
class EgoBounds:
    acceleration: float  # m/s2, |a| of the CG
    yaw_rate: float  # rad/s
    length: float  # m, footprint
    width: float
    radius: float  # m, CG to a footprint corner
    wheel_arm: float  # m, CG to the farthest contact point


def ego_bounds(model, mu_max: float, start_speed: float, wheel_arm: float, max_steer: float) -> EgoBounds:
    """The vehicle map's bounds where it gives them; else A from the friction limit (the Simple FMU clamps each
    wheel to mu g; the Advanced FMU's tire forces saturate at its peak friction), the drive and brake limits,
    rolling resistance and drag; r_max from the lateral friction limit with the driver's steer limit (steady
    turning: r <= min(v tan(d)/L, mu g / v), whose maximum over v is sqrt(mu g tan(d) / L))."""
    length, width = model.length, model.width
    radius = math.hypot(length / 2, width / 2)
    if model.bounds["acceleration"] is not None:
        return EgoBounds(model.bounds["acceleration"], model.bounds["yaw_rate"], length, width, radius, wheel_arm)
    g = STANDARD_GRAVITY
    speed = max(REFERENCE_SPEED, 2 * start_speed)
    tire = max(mu_max * g, model.brake_decel_max, model.drive_accel_max)
    resist = model.rolling_resistance * g + model.drag_factor * speed**2
    acceleration = ACCELERATION_MARGIN * (math.sqrt(2) * tire + resist) + ACCELERATION_SLACK
    yaw_rate = YAW_RATE_MARGIN * math.sqrt(mu_max * g * math.tan(max_steer) / model.wheelbase)
    return EgoBounds(acceleration, yaw_rate, length, width, radius, wheel_arm)


class EgoKinematics(NamedTuple):
    """The ego in the road frame at one instant: station X, lateral Y (+ right) and their rates (a named
    tuple: made at trigger checks and bisection probes, it must be cheap)."""

    time: float
    station: float
    lateral: float
    station_rate: float
    lateral_rate: float
    psi: float

    @staticmethod
    def of(state: EgoState) -> EgoKinematics:
        c, s = math.cos(state.psi), math.sin(state.psi)
        return EgoKinematics(state.time, state.x, -state.y, state.vx * c - state.vy * s,
                             -(state.vx * s + state.vy * c), state.psi)


def _footprint(ego: EgoKinematics, bounds: EgoBounds) -> Footprint:
    return Footprint.of(bounds.length, bounds.width, ego.psi)


def vehicle_conditions(traffic: Traffic, idx: np.ndarray, ego: EgoKinematics, bounds: EgoBounds):
    """(action due, footprints overlap, wholly behind and moving away with no action that could still fire)
    for vehicles idx at the ego's instant; a vehicle may leave when the last holds and it is not in contact."""
    station, lateral, speed, _, _ = traffic.motion(idx, ego.time)
    gap = station - ego.station
    gap_rate = -speed - ego.station_rate
    seconds, where = traffic.trigger_seconds[idx], traffic.where[idx]
    closing = -gap_rate * np.sign(gap)
    allowed = (gap != 0) & ~((where == 1) & (gap < 0)) & ~((where == 2) & (gap > 0))
    due = allowed & (((seconds > 0) & (closing > 0) & (np.abs(gap) <= seconds * closing))
                     | ((seconds < 0) & (closing < 0) & (np.abs(gap) >= seconds * closing)))
    length, width = traffic.length[idx], traffic.width[idx]
    overlap = penetrations(_footprint(ego, bounds), gap, -(lateral - ego.lateral), length, width) > 0
    leave_allowed = np.isnan(seconds) | (seconds > 0) | (where == 1)
    away = leave_allowed & (gap < -(bounds.length + length) / 2) & (gap_rate < 0)
    return due, overlap, away


def vehicle_triggered(traffic: Traffic, i: int, ego: EgoKinematics, bounds: EgoBounds) -> bool:
    """`vehicle_conditions` for one vehicle in plain floats (the bisection probes' path): whether its
    action is due, its contact state changes or it may leave."""
    station, lateral, speed = traffic.at(i, ego.time)
    gap = station - ego.station
    gap_rate = -speed - ego.station_rate
    seconds, where = traffic.trigger_seconds[i], traffic.where[i]
    if seconds == seconds and gap != 0 and not (where == 1 and gap < 0) and not (where == 2 and gap > 0):
        closing = -gap_rate if gap > 0 else gap_rate
        if seconds > 0 and closing > 0 and abs(gap) <= seconds * closing:
            return True
        if seconds < 0 and closing < 0 and abs(gap) >= seconds * closing:
            return True
    length, width = traffic.length[i], traffic.width[i]
    overlap = penetration(_footprint(ego, bounds), gap, -(lateral - ego.lateral), length, width) > 0
    in_contact = bool(traffic.in_contact[i])
    if overlap != in_contact:
        return True
    leave_allowed = seconds != seconds or seconds > 0 or where == 1
    return leave_allowed and not in_contact and gap < -(bounds.length + length) / 2 and gap_rate < 0


def vehicle_horizons(traffic: Traffic, idx: np.ndarray, ego: EgoKinematics, bounds: EgoBounds) -> np.ndarray:
    """Lower bounds (s from the ego's instant) on when each vehicle's action, contact change or departure
    can first become true."""
    station, lateral, speed, lateral_rate, speed_rate = traffic.motion(idx, ego.time)
    a = bounds.acceleration
    relative_acceleration = a + speed_rate  # bound on |d2 gap / dt2|
    gap = station - ego.station
    gap_rate = -speed - ego.station_rate
    sign = np.where(gap >= 0, 1.0, -1.0)
    closing = -gap_rate * sign  # rate at which |gap| shrinks
    seconds, where = traffic.trigger_seconds[idx], traffic.where[idx]
    inf = np.full(len(idx), np.inf)

    # closure-time actions (the module's docstring)
    pass_time = reach_time(np.abs(gap), closing, relative_acceleration)  # earliest instant gap = 0
    blocked = ((where == 1) & (gap <= 0)) | ((where == 2) & (gap >= 0))
    closing_margin = np.abs(gap) - seconds * closing  # <= 0: a positive T is due
    positive = reach_time(closing_margin, closing + seconds * relative_acceleration, relative_acceleration)
    separating = -closing
    separating_margin = -seconds * separating - np.abs(gap)  # <= 0 with separating > 0: a negative T is due
    negative = np.where(
        separating <= 0,
        np.minimum(-separating / relative_acceleration, pass_time),
        reach_time(separating_margin, separating - seconds * relative_acceleration, relative_acceleration))
    action = np.where(np.isnan(seconds), inf,
                      np.where(blocked, pass_time, np.where(seconds > 0, positive, negative)))

    # footprint contact: starts once both road-axis separations have closed; ends once any penetration has
    length, width = traffic.length[idx], traffic.width[idx]
    d_lateral = lateral - ego.lateral
    along_x, along_y, along_u, along_v = overlaps(_footprint(ego, bounds), gap, -d_lateral, length, width)
    depth = np.minimum(np.minimum(along_x, along_y), np.minimum(along_u, along_v))  # penetrations
    turn = bounds.radius * bounds.yaw_rate
    lateral_closing = np.sign(d_lateral) * ego.lateral_rate
    start = np.maximum(reach_time(-along_x, closing + turn, relative_acceleration),
                       reach_time(-along_y, lateral_closing + np.abs(lateral_rate) + turn, a))
    vehicle_radius = np.hypot(length / 2, width / 2)
    relative_speed = np.abs(gap_rate) + np.abs(ego.lateral_rate) + np.abs(lateral_rate)
    end = reach_time(depth, relative_speed + 2 * (bounds.radius + vehicle_radius) * bounds.yaw_rate,
                     relative_acceleration)
    in_contact = traffic.in_contact[idx]
    contact = np.where(in_contact, end, start)

    # departure: wholly behind the ego and moving away
    leave_allowed = (np.isnan(seconds) | (seconds > 0) | (where == 1)) & ~in_contact
    behind = reach_time(gap + (bounds.length + length) / 2, -gap_rate, relative_acceleration)
    away = np.where(gap_rate >= 0, gap_rate / relative_acceleration, 0.0)
    leave = np.where(leave_allowed, np.maximum(behind, away), inf)
    return np.minimum(np.minimum(action, contact), leave)


def vehicle_condition(traffic: Traffic, i: int, ego: EgoKinematics, bounds: EgoBounds) -> tuple[bool, bool, bool]:
    """`vehicle_conditions` for one vehicle in plain floats, operation for operation (the same decisions,
    tested)."""
    station, lateral, speed, _, _ = traffic.motion_of(i, ego.time)
    gap = station - ego.station
    gap_rate = -speed - ego.station_rate
    seconds, where = float(traffic.trigger_seconds[i]), int(traffic.where[i])
    closing = -gap_rate * (1.0 if gap > 0 else -1.0 if gap < 0 else 0.0)
    allowed = gap != 0 and not (where == 1 and gap < 0) and not (where == 2 and gap > 0)
    due = allowed and ((seconds > 0 and closing > 0 and abs(gap) <= seconds * closing)
                       or (seconds < 0 and closing < 0 and abs(gap) >= seconds * closing))
    length, width = float(traffic.length[i]), float(traffic.width[i])
    overlap = penetration(_footprint(ego, bounds), gap, -(lateral - ego.lateral), length, width) > 0
    leave_allowed = seconds != seconds or seconds > 0 or where == 1
    away = leave_allowed and gap < -(bounds.length + length) / 2 and gap_rate < 0
    return due, overlap, away


def vehicle_horizon(traffic: Traffic, i: int, ego: EgoKinematics, bounds: EgoBounds) -> float:
    """`vehicle_horizons` for one vehicle in plain floats, the same arithmetic operation for operation (equal
    bit for bit, tested). With a few vehicles on the road the array form's cost is NumPy's per-operation
    overhead (about 1 µs for each of some 150 operations on one-element arrays), not the arithmetic."""
    station, lateral, speed, lateral_rate, speed_rate = traffic.motion_of(i, ego.time)
    length, width, seconds = float(traffic.length[i]), float(traffic.width[i]), float(traffic.trigger_seconds[i])
    where, in_contact = int(traffic.where[i]), bool(traffic.in_contact[i])
    a = bounds.acceleration
    relative_acceleration = a + speed_rate
    gap = station - ego.station
    gap_rate = -speed - ego.station_rate
    closing = -gap_rate * (1.0 if gap >= 0 else -1.0)

    # closure-time actions
    if seconds != seconds:
        action = math.inf
    elif (where == 1 and gap <= 0) or (where == 2 and gap >= 0):
        action = reach_time_scalar(abs(gap), closing, relative_acceleration)
    elif seconds > 0:
        action = reach_time_scalar(abs(gap) - seconds * closing, closing + seconds * relative_acceleration,
                                   relative_acceleration)
    else:
        separating = -closing
        if separating <= 0:
            action = min(-separating / relative_acceleration,
                         reach_time_scalar(abs(gap), closing, relative_acceleration))
        else:
            action = reach_time_scalar(-seconds * separating - abs(gap), separating - seconds * relative_acceleration,
                                       relative_acceleration)

    # footprint contact (geometry.overlaps)
    d_lateral = lateral - ego.lateral
    turn = bounds.radius * bounds.yaw_rate
    if in_contact:
        depth = penetration(_footprint(ego, bounds), gap, -d_lateral, length, width)
        vehicle_radius = float(np.hypot(length / 2, width / 2))
        relative_speed = abs(gap_rate) + abs(ego.lateral_rate) + abs(lateral_rate)
        contact = reach_time_scalar(depth, relative_speed + 2 * (bounds.radius + vehicle_radius) * bounds.yaw_rate,
                                    relative_acceleration)
    else:
        along_x, along_y, _, _ = overlaps(_footprint(ego, bounds), gap, -d_lateral, length, width)
        lateral_closing = (1.0 if d_lateral > 0 else -1.0 if d_lateral < 0 else 0.0) * ego.lateral_rate
        contact = max(reach_time_scalar(-along_x, closing + turn, relative_acceleration),
                      reach_time_scalar(-along_y, lateral_closing + abs(lateral_rate) + turn, a))

    # departure
    if (seconds != seconds or seconds > 0 or where == 1) and not in_contact:
        behind = reach_time_scalar(gap + (bounds.length + length) / 2, -gap_rate, relative_acceleration)
        leave = max(behind, gap_rate / relative_acceleration if gap_rate >= 0 else 0.0)
    else:
        leave = math.inf
    return min(min(action, contact), leave)
