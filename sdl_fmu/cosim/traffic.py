"""The traffic model: approaching vehicles (A events) moving along the road by their actions.

A vehicle moves toward decreasing station at its speed (an approaching vehicle; a negative speed
moves it the ego's way). Between actions its motion is closed-form: a transition runs lateral
position and speed linearly over its duration, so the station is quadratic in time. That makes
its state a pure function of time, so the master can roll back and bisect a step freely.
"""

from __future__ import annotations

import math
import random
from array import array
from dataclasses import dataclass

import numpy as np

from ..sdl.events import Action, ApproachingVehicle, ClosureTrigger
from ..sdl.vehicles import VehicleModel


@dataclass(frozen=True)
class Motion:
    """Motion from t0: lateral and speed move linearly from (lateral0, speed0) to (lateral1, speed1)
    over `duration`, then hold."""

    t0: float
    station0: float
    lateral0: float
    speed0: float
    lateral1: float
    speed1: float
    duration: float

    def at(self, t: float) -> tuple[float, float, float]:
        """(station, lateral, speed) at time t >= t0."""
        return motion_at(self.t0, self.station0, self.lateral0, self.speed0, self.lateral1, self.speed1,
                         self.duration, t)


def motion_at(t0: float, station0: float, lateral0: float, speed0: float, lateral1: float, speed1: float,
              duration: float, t: float) -> tuple[float, float, float]:
    """`Motion.at` on plain floats (the bisection's probes call it without making a Motion)."""
    elapsed = t - t0
    if elapsed < duration:
        fraction = elapsed / duration
        speed = speed0 + (speed1 - speed0) * fraction
        travelled = speed0 * elapsed + (speed1 - speed0) * elapsed**2 / (2 * duration)
        return station0 - travelled, lateral0 + (lateral1 - lateral0) * fraction, speed
    travelled = (speed0 + speed1) / 2 * duration + speed1 * (elapsed - duration)
    return station0 - travelled, lateral1, speed1


def closure_reached(trigger: ClosureTrigger, gap: float, gap_rate: float) -> bool:
    """Whether an action's closure-time condition holds.

    gap = vehicle station - ego station (> 0: the vehicle is in front), gap_rate = d(gap)/dt.
    Closing (|gap| shrinking) at speed c: fires when |gap| / c <= T. Separating at speed c: a negative T
    fires when |gap| / c >= |T|. F / B: only with the vehicle in front of / behind the ego.
    """
    if gap == 0.0 or (trigger.where == "F" and gap < 0) or (trigger.where == "B" and gap > 0):
        return False
    closing_speed = -gap_rate * math.copysign(1.0, gap)
    if trigger.seconds > 0:
        return closing_speed > 0 and abs(gap) <= trigger.seconds * closing_speed
    return closing_speed < 0 and abs(gap) >= -trigger.seconds * -closing_speed


def choose_model(event: ApproachingVehicle, rng: random.Random) -> int:
    """The model number: fixed, or uniform over the inclusive range (reproducible from the seed)."""
    return rng.randint(event.model.low, event.model.high) if event.model.is_random else event.model.low


@dataclass
class TrafficVehicle:
    vehicle: int  # id, 1-based in spawn order
    event: ApproachingVehicle
    model: VehicleModel
    motion: Motion
    next_action: int = 0  # index into event.actions of the armed action
    in_contact: bool = False
    present: bool = True

    def at(self, t: float) -> tuple[float, float, float]:
        return self.motion.at(t)

    def armed(self) -> Action | None:
        actions = self.event.actions
        return actions[self.next_action] if self.next_action < len(actions) else None

    def action_due(self, t: float, ego_station: float, ego_station_rate: float) -> bool:
        action = self.armed()
        if action is None:
            return False
        station, _, speed = self.at(t)
        return closure_reached(action.trigger, station - ego_station, -speed - ego_station_rate)

    def start_action(self, t: float, ego_lateral: float, ego_speed: float) -> Action:
        """Fires the armed action: a new transition from where the vehicle is now (interrupting any)."""
        action = self.armed()
        station, lateral, speed = self.at(t)
        self.motion = Motion(t, station, lateral, speed, action.lateral.resolve(ego_lateral),
                             action.speed.resolve(ego_speed), action.duration)
        self.next_action += 1
        return action

    def may_leave(self, t: float, ego_station: float, ego_station_rate: float, ego_length: float) -> bool:
        """Wholly behind the ego (its front behind the ego's rear), moving away, and no action left that
        could still fire (docs/decisions.md, A vehicles)."""
        station, _, speed = self.at(t)
        gap, gap_rate = station - ego_station, -speed - ego_station_rate
        if not (gap < -(ego_length + self.model.length) / 2 and gap_rate < 0):
            return False
        action = self.armed()
        # while behind and separating only a negative closure time without 'F' can still fire
        return action is None or action.trigger.seconds > 0 or action.trigger.where == "F"


def spawn(vehicle_id: int, event: ApproachingVehicle, model: VehicleModel, t: float, ego_station: float,
          ego_lateral: float, ego_speed: float) -> TrafficVehicle:
    speed = event.speed.resolve(ego_speed)
    lateral = event.lateral.resolve(ego_lateral)
    motion = Motion(t, ego_station + event.gap, lateral, speed, *_initial_transition(event, lateral, speed, ego_lateral,
                                                                                    ego_speed))
    return TrafficVehicle(vehicle_id, event, model, motion)


def _initial_transition(event: ApproachingVehicle, lateral: float, speed: float, ego_lateral: float,
                        ego_speed: float) -> tuple[float, float, float]:
    """(lateral1, speed1, duration) of a vehicle's motion from its spawn: its `initial` transition, else holding."""
    if event.initial is None:
        return lateral, speed, 0.0
    return (event.initial.lateral.resolve(ego_lateral), event.initial.speed.resolve(ego_speed),
            event.initial.duration)


def footprints_overlap(a_center, a_heading, a_size, b_center, b_heading, b_size) -> bool:
    """Separating-axis test of two rectangles (centre (x, y), heading rad, (length, width)) in one plane."""
    corners = []
    axes = []
    for (cx, cy), heading, (length, width) in ((a_center, a_heading, a_size), (b_center, b_heading, b_size)):
        c, s = math.cos(heading), math.sin(heading)
        axes += [(c, s), (-s, c)]
        corners.append([(cx + dx * c - dy * s, cy + dx * s + dy * c)
                        for dx, dy in ((length / 2, width / 2), (length / 2, -width / 2),
                                       (-length / 2, -width / 2), (-length / 2, width / 2))])
    for ax, ay in axes:
        a = [x * ax + y * ay for x, y in corners[0]]
        b = [x * ax + y * ay for x, y in corners[1]]
        if max(a) <= min(b) or max(b) <= min(a):
            return False
    return True


# ---- all vehicles at once ---------------------------------------------------------------------------

WHERE_CODES = {None: 0, "F": 1, "B": 2}


class Traffic:
    """Every traffic vehicle of a run in NumPy arrays (index = vehicle id - 1), so that the master checks
    only the vehicles on the road (`active`), and those vectorised. Same motion law as `Motion`."""

    _FLOATS = ("t0", "station0", "lateral0", "speed0", "lateral1", "speed1", "duration", "length", "width",
               "trigger_seconds", "next_check")

    def __init__(self, capacity: int = 16):
        self.size = 0
        for name in self._FLOATS:
            setattr(self, name, np.zeros(capacity))
        self.where = np.zeros(capacity, dtype=np.int8)
        self.next_action = np.zeros(capacity, dtype=np.int64)
        self.in_contact = np.zeros(capacity, dtype=bool)
        self.present = np.zeros(capacity, dtype=bool)
        self.events: list[ApproachingVehicle] = []
        self.models: list[VehicleModel] = []
        # every motion of every vehicle in the order they began (for the results), 7 floats each
        # (`history`), and the vehicle each belongs to: compact however many vehicles pass
        self.motion_rows = array("d")
        self.motion_owner = array("q")
        self._grouped = None  # the motions grouped by vehicle, built when the tracks are computed
        self.active = np.zeros(0, dtype=np.int64)  # indices of the vehicles on the road, ascending

    def _grow(self) -> None:
        for name in (*self._FLOATS, "where", "next_action", "in_contact", "present"):
            values = getattr(self, name)
            setattr(self, name, np.concatenate([values, np.zeros_like(values)]))

    def add(self, event: ApproachingVehicle, model: VehicleModel, t: float, ego_station: float, ego_lateral: float,
            ego_speed: float) -> int:
        """Spawns a vehicle (docs/scenarios.md: gap and lateral from the event, starred values from the ego; a
        generated event's `initial` transition starts at once); its index."""
        if self.size == len(self.t0):
            self._grow()
        i = self.size
        self.size += 1
        speed = event.speed.resolve(ego_speed)
        lateral = event.lateral.resolve(ego_lateral)
        self.t0[i], self.station0[i] = t, ego_station + event.gap
        self.lateral0[i], self.speed0[i] = lateral, speed
        self.lateral1[i], self.speed1[i], self.duration[i] = _initial_transition(event, lateral, speed, ego_lateral,
                                                                                  ego_speed)
        self.length[i], self.width[i] = model.length, model.width
        self.next_action[i], self.in_contact[i], self.present[i] = 0, False, True
        self.next_check[i] = t
        self.events.append(event)
        self.models.append(model)
        self._record_motion(i)
        self._arm(i)
        self.active = np.append(self.active, i)
        return i

    def _arm(self, i: int) -> None:
        action = self.armed(i)
        self.trigger_seconds[i] = np.nan if action is None else action.trigger.seconds
        self.where[i] = 0 if action is None else WHERE_CODES[action.trigger.where]

    def armed(self, i: int) -> Action | None:
        actions = self.events[i].actions
        return actions[self.next_action[i]] if self.next_action[i] < len(actions) else None

    def remove(self, i: int) -> None:
        self.present[i] = False
        self.active = self.active[self.active != i]

    def motion(self, idx: np.ndarray, t: float):
        """(station, lateral, speed, lateral rate, |speed rate|) of vehicles idx at time t (`Motion.at`)."""
        elapsed = t - self.t0[idx]
        duration = self.duration[idx]
        speed0, speed1 = self.speed0[idx], self.speed1[idx]
        lateral0, lateral1 = self.lateral0[idx], self.lateral1[idx]
        moving = elapsed < duration
        span = np.where(moving, duration, 1.0)
        fraction = np.where(moving, elapsed / span, 1.0)
        speed = speed0 + (speed1 - speed0) * fraction
        travelled = np.where(moving, speed0 * elapsed + (speed1 - speed0) * elapsed**2 / (2 * span),
                             (speed0 + speed1) / 2 * duration + speed1 * (elapsed - duration))
        lateral = lateral0 + (lateral1 - lateral0) * fraction
        lateral_rate = np.where(moving, (lateral1 - lateral0) / span, 0.0)
        speed_rate = np.where(moving, np.abs(speed1 - speed0) / span, 0.0)
        return self.station0[idx] - travelled, lateral, speed, lateral_rate, speed_rate

    def motion_of(self, i: int, t: float) -> tuple[float, float, float, float, float]:
        """`motion` of vehicle i in plain floats, operation for operation (both forms give the same bits)."""
        t0, station0, lateral0, speed0, lateral1, speed1, duration = (
            float(self.t0[i]), float(self.station0[i]), float(self.lateral0[i]), float(self.speed0[i]),
            float(self.lateral1[i]), float(self.speed1[i]), float(self.duration[i]))
        elapsed = t - t0
        if elapsed < duration:
            fraction = elapsed / duration
            travelled = speed0 * elapsed + (speed1 - speed0) * (elapsed * elapsed) / (2 * duration)
            lateral_rate = (lateral1 - lateral0) / duration
            speed_rate = abs(speed1 - speed0) / duration
        else:
            fraction = 1.0
            travelled = (speed0 + speed1) / 2 * duration + speed1 * (elapsed - duration)
            lateral_rate = speed_rate = 0.0
        return (station0 - travelled, lateral0 + (lateral1 - lateral0) * fraction,
                speed0 + (speed1 - speed0) * fraction, lateral_rate, speed_rate)

    def at(self, i: int, t: float) -> tuple[float, float, float]:
        """(station, lateral, speed) of vehicle i at time t, in plain floats (`Motion.at`)."""
        return motion_at(float(self.t0[i]), float(self.station0[i]), float(self.lateral0[i]), float(self.speed0[i]),
                         float(self.lateral1[i]), float(self.speed1[i]), float(self.duration[i]), t)

    def start_action(self, i: int, t: float, ego_lateral: float, ego_speed: float) -> Action:
        """Fires the armed action: a new transition from where the vehicle is now (interrupting any)."""
        action = self.armed(i)
        station, lateral, speed = self.at(i, t)
        self.t0[i], self.station0[i], self.lateral0[i], self.speed0[i] = t, station, lateral, speed
        self.lateral1[i] = action.lateral.resolve(ego_lateral)
        self.speed1[i] = action.speed.resolve(ego_speed)
        self.duration[i] = action.duration
        self.next_action[i] += 1
        self._arm(i)
        self.next_check[i] = t
        self._record_motion(i)
        return action

    def _record_motion(self, i: int) -> None:
        self.motion_rows.extend((self.t0[i], self.station0[i], self.lateral0[i], self.speed0[i], self.lateral1[i],
                                 self.speed1[i], self.duration[i]))
        self.motion_owner.append(i)

    def history(self, i: int) -> np.ndarray:
        """Vehicle i's motions in time order, one row (t0, station0, lateral0, speed0, lateral1, speed1,
        duration) each."""
        if self._grouped is None or self._grouped[0] != len(self.motion_owner):
            owner = np.array(self.motion_owner, dtype=np.int64)
            order = np.argsort(owner, kind="stable")
            rows = np.array(self.motion_rows, dtype=float).reshape(-1, 7)[order]
            self._grouped = (len(owner), rows, np.searchsorted(owner[order], np.arange(self.size + 1)))
        _, rows, bounds = self._grouped
        return rows[bounds[i]:bounds[i + 1]]

    def track(self, i: int, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(station, lateral, speed) of vehicle i at the given times, from its motion history."""
        motions = self.history(i)
        k = np.maximum(np.searchsorted(motions[:, 0], times, side="right") - 1, 0)
        t0, station0, lateral0, speed0, lateral1, speed1, duration = motions[k].T
        elapsed = times - t0
        moving = elapsed < duration
        span = np.where(moving, duration, 1.0)
        fraction = np.where(moving, elapsed / span, 1.0)
        travelled = np.where(moving, speed0 * elapsed + (speed1 - speed0) * elapsed**2 / (2 * span),
                             (speed0 + speed1) / 2 * duration + speed1 * (elapsed - duration))
        return (station0 - travelled, lateral0 + (lateral1 - lateral0) * fraction,
                speed0 + (speed1 - speed0) * fraction)
