"""The traffic model: approaching vehicles (A events) moving along the road by their actions.

A vehicle moves toward decreasing station at its speed (an approaching vehicle; a negative speed
moves it the ego's way). Between actions its motion is closed-form: a transition runs lateral
position and speed linearly over its duration, so the station is quadratic in time. That makes
its state a pure function of time, so the master can roll back and bisect a step freely.
"""

from __future__ import annotations

import random
from array import array

import numpy as np

from ..sdl.events import Action, ApproachingVehicle
from ..sdl.vehicles import VehicleModel


def choose_model(event: ApproachingVehicle, rng: random.Random) -> int:
    """The model number: fixed, or uniform over the inclusive range (reproducible from the seed)."""
    return rng.randint(event.model.low, event.model.high) if event.model.is_random else event.model.low


def _initial_transition(event: ApproachingVehicle, lateral: float, speed: float, ego_lateral: float,
                        ego_speed: float) -> tuple[float, float, float]:
    """(lateral1, speed1, duration) of a vehicle's motion from its spawn: its `initial` transition, else holding."""
    if event.initial is None:
        return lateral, speed, 0.0
    return (event.initial.lateral.resolve(ego_lateral), event.initial.speed.resolve(ego_speed),
            event.initial.duration)


WHERE_CODES = {None: 0, "F": 1, "B": 2}


def motion_law(row: tuple[float, ...], t: float) -> tuple[float, float, float, float, float]:
    """(station, lateral, speed, lateral rate, |speed rate|) at time t of a vehicle whose motion is `row`
    (Traffic.row: t0, station0, lateral0, speed0, lateral1, speed1, duration): Traffic.motion's law in plain
    floats, operation for operation (both forms give the same bits; cosim/_kernel.c's `relative` is its compiled
    twin)."""
    t0, station0, lateral0, speed0, lateral1, speed1, duration = row
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


class Traffic:
    """Every traffic vehicle of a run in NumPy arrays (index = vehicle id - 1), so that the master checks
    only the vehicles on the road (`active`), and those vectorised.

    The motion law (`at`, and its forms `motion_of`, `motion`, `track`): from its motion's start t0 a vehicle's
    lateral position and speed move linearly from (lateral0, speed0) to (lateral1, speed1) over `duration`,
    then hold; its station decreases by the distance travelled at that speed."""

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
        # per vehicle, its current motion (`row`) in plain floats, read from the arrays when it begins: the plain-
        # float forms read it instead of seven array elements
        self._rows: dict[int, tuple[float, ...]] = {}
        self._active_list = (None, [])

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

    def row(self, i: int) -> tuple[float, ...]:
        """Vehicle i's current motion in plain floats: (t0, station0, lateral0, speed0, lateral1, speed1,
        duration). Read from the arrays for a vehicle placed there directly (not by `add`)."""
        row = self._rows.get(i)
        if row is None:
            row = (float(self.t0[i]), float(self.station0[i]), float(self.lateral0[i]), float(self.speed0[i]),
                   float(self.lateral1[i]), float(self.speed1[i]), float(self.duration[i]))
        return row

    def _arm(self, i: int) -> None:
        action = self.armed(i)
        self.trigger_seconds[i] = np.nan if action is None else action.trigger.seconds
        self.where[i] = 0 if action is None else WHERE_CODES[action.trigger.where]

    def armed(self, i: int) -> Action | None:
        actions = self.events[i].actions
        return actions[self.next_action[i]] if self.next_action[i] < len(actions) else None

    def active_list(self) -> list[int]:
        """`active` as a list of ints (made once per change of `active`: the per-step loops read it)."""
        cached = self._active_list
        if cached[0] is not self.active:
            cached = self._active_list = (self.active, self.active.tolist())
        return cached[1]

    def remove(self, i: int) -> None:
        self.present[i] = False
        self.active = self.active[self.active != i]

    def motion(self, idx: np.ndarray, t: float):
        """(station, lateral, speed, lateral rate, |speed rate|) of vehicles idx at time t (`at`)."""
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
        return motion_law(self.row(i), t)

    def at(self, i: int, t: float) -> tuple[float, float, float]:
        """(station, lateral, speed) of vehicle i at time t, in plain floats: the motion law."""
        t0, station0, lateral0, speed0, lateral1, speed1, duration = self.row(i)
        elapsed = t - t0
        if elapsed < duration:
            fraction = elapsed / duration
            speed = speed0 + (speed1 - speed0) * fraction
            travelled = speed0 * elapsed + (speed1 - speed0) * elapsed**2 / (2 * duration)
            return station0 - travelled, lateral0 + (lateral1 - lateral0) * fraction, speed
        travelled = (speed0 + speed1) / 2 * duration + speed1 * (elapsed - duration)
        return station0 - travelled, lateral1, speed1

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
        row = self._rows[i] = (float(self.t0[i]), float(self.station0[i]), float(self.lateral0[i]),
                               float(self.speed0[i]), float(self.lateral1[i]), float(self.speed1[i]),
                               float(self.duration[i]))
        self.motion_rows.extend(row)
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
