"""The run's criticality record: per traffic vehicle, the extreme of each measure (measures.py) and the instant
it was first reached, and what the run needs to locate those instants instead of taking the best sample.

How the run uses it (one record, `Extremes`, one row per traffic vehicle; the follower, follower.py, keeps the
per-vehicle instants and asks the FMU for snapshots and probes):
1. Looks. At a look (`Extremes.look`, one pass) a vehicle's values at the ego's state are offered to the
   record (a value replaces the recorded extreme only when better by more than FLAT, so the first instant
   an extreme is reached stays), and the look returns the vehicle's rates and its horizon, a lower bound on
   when it next needs a look. The follower keeps a next-look instant per vehicle and their minimum, as the
   trigger schedule keeps its traffic bounds, and looks at a communication point at the vehicles whose instant
   has come. A look also leaves `Extremes.quiet`, a bound before which none of the vehicle's located instants
   (2) can be, and `Extremes.course`, a bound before which no collision course or headway can begin (4): a step
   starts from an FMU snapshot only when such a bound ends within it. Every vehicle is also looked at at its
   spawn, before and after its own actions, at its contacts' starts and ends, before it leaves the road, at the
   run's end (an extreme at the end of an interval), and at every located instant below.
2. Located instants. Inside a step an extreme is the root of its rate (`Extremes.rates`: distance, TTC,
   minus DRAC, headway; from < 0 to >= 0), or a contact's start or end (the master's contact triggers
   already locate them; TTC is 0 and the distance 0 there), or a collision course's start or end (TTC's rate
   turns defined / undefined; also where a vehicle on a course crosses RANGE). The follower finds a change of
   sign between the rates at the step's start and at its end and bisects it from the snapshot (locate.py), then
   looks at the vehicle on both sides of the located instant.
3. Horizons (`Extremes.look`'s second value): 0 within RANGE (50 m, SUMO's device.ssm.range) while a
   vehicle is on a collision course or has a headway: TTC, DRAC and headway are followed at every
   communication point there (the driver's 20 Hz samples at least), their roots and courses found by the
   sign checks of 2, which assume at most one change of sign between two communication points (no horizon
   bounds TTC's or headway's rate yet). Otherwise only the distance is followed by looks, and the horizon is a
   proven lower bound, from the ego's bounds as in triggers.py (the acceleration A of its CG, its yaw rate
   r_max, the radius R of its footprint), on a new minimum distance, which needs both the distance below the
   recorded minimum (`distance_horizon`) and an approach ending (`approach_horizon` near, `heading_horizon`
   far), and never past the end of a lateral transition.
4. Courses. Between its looks a vehicle off any course and headway is checked (`course_check`: TTC and the
   headway alone, a third of a look's cost) at every communication point from `course` on, which is
   `course_horizon`'s proven bound within RANGE and the instant it can come within RANGE beyond it: a check that
   finds a course or a headway within RANGE makes the vehicle due a look at once (a course's start is then
   located as in 2). A car passing in the next lane within RANGE is checked at nearly every communication point
   (the ego could steer toward it within about 0.05 s) but looked at only as its distance's bounds require.
5. PET: when an action starts a lateral move, `band_times` gives the instant the vehicle's footprint
   leaves the ego's lane (closed form); the master steps to it like a driver sample and calls
   `Extremes.path_left`; the conflict stations then pending (`Extremes.pending_stations`) are distance
   triggers for the ego's front, horizon reach_time(station - front, station_rate + R r_max, A) as for the
   master's event distances, and at the located instant `Extremes.reach` records the PET.
"""

from __future__ import annotations

import math

import numpy as np

from . import looks
from .geometry import SCALAR_VEHICLES, Footprint
from .looks import FLAT, RANGE
from .measures import (INF, conflict_station, distance, distances, drac, dracs, headway, headways,
                       post_encroachment_time, ttc, ttcs)

MEASURES = ("min_distance", "min_ttc", "max_drac", "min_pet", "min_headway")


class Extremes:
    """Per traffic vehicle (index as in traffic.Traffic), the extreme of each measure and the instant it was
    first reached, offered values at every communication point and at every instant the master locates (a
    root of a rate, a contact's or a collision course's start or end, a PET instant).

    A later value replaces the recorded one only when better by more than FLAT, so that a flat extreme (the
    distance to a car passing in the next lane, constant over the whole overlap) keeps the first instant it
    was reached, whatever the samples after it: with the start located, the instant does not depend on the
    step. Values are SI (m, s, m/s2), in `summary` too (the results convert them)."""

    def __init__(self, ego_length: float, ego_width: float, capacity: int = 16):
        self.ego_length, self.ego_width = ego_length, ego_width
        # the per-vehicle arithmetic: the compiled kernel where it was built, else its Python twin (looks.py); the
        # follower's scans take the same
        self.arithmetic = looks.arithmetic()
        self.size = 0
        # per measure, per vehicle: the extreme and its instant (nan: none yet); plain lists, read and written per
        # look
        self.value = {name: [math.nan] * capacity for name in MEASURES}
        self.time = {name: [math.nan] * capacity for name in MEASURES}
        # the lists a look offers to (looks.look; _grow extends them in place)
        self._tables = tuple(table[name] for name in ("min_distance", "min_ttc", "max_drac", "min_headway")
                             for table in (self.value, self.time))
        self.left_path = np.full(capacity, np.nan)  # s, when the vehicle's footprint last left the ego's path
        self.conflict = np.full(capacity, np.nan)  # m, the station the ego's front must reach then (PET)
        # the ego passing first (PET): the far end of the area where the vehicle's footprint will enter the ego's
        # path, while the ego's rear has yet to pass it (m), and the instant it did (s)
        self.far_end = np.full(capacity, np.nan)
        self.rear_left = np.full(capacity, np.nan)
        # s from the last look: a lower bound on when that vehicle's next located instant (a closest
        # approach, a collision course's end, a transition's end) can be (0: any time), and on when a collision
        # course or a headway can begin (inf: not to be checked before the vehicle's next look)
        self.quiet = 0.0
        self.course = INF
        # the ego's half length and width (looks.ego); per vehicle its (length, width) in floats (fixed from its
        # spawn, a vehicle's index is never reused)
        self._a, self._b = ego_length / 2, ego_width / 2
        self._sizes: dict[int, tuple[float, float]] = {}

    def _grow(self, size: int) -> None:
        while size > len(self.left_path):
            for table in (self.value, self.time):
                for values in table.values():
                    values.extend([math.nan] * len(values))
            self.left_path = np.concatenate([self.left_path, np.full(len(self.left_path), np.nan)])
            self.conflict = np.concatenate([self.conflict, np.full(len(self.conflict), np.nan)])
            self.far_end = np.concatenate([self.far_end, np.full(len(self.far_end), np.nan)])
            self.rear_left = np.concatenate([self.rear_left, np.full(len(self.rear_left), np.nan)])
        self.size = max(self.size, size)

    # -- offering values

    def offer(self, name: str, i: int, t: float, value: float) -> None:
        """One vehicle's value of one measure at instant t (nan or inf: not applicable now): looks.offer."""
        if not math.isfinite(value):
            return
        if i >= self.size:
            self._grow(i + 1)
        self.arithmetic.offer(self.value[name], self.time[name], i, t, value, name == "max_drac")

    def offers(self, name: str, idx: np.ndarray, t: float, values: np.ndarray) -> None:
        """`offer` for vehicles idx at once."""
        if len(idx) and int(idx.max()) >= self.size:
            self._grow(int(idx.max()) + 1)
        recorded = np.array(self.value[name])[idx]
        finite = np.isfinite(values)
        empty = np.isnan(recorded)
        if name == "max_drac":
            better = finite & (empty | (values > recorded + FLAT))
            improves = finite & ~empty & (values > recorded)
        else:
            better = finite & (empty | (values < recorded - FLAT))
            improves = finite & ~empty & (values < recorded)
        for i, value in zip(idx.tolist(), np.where(better | improves, values, recorded).tolist()):
            self.value[name][i] = value
        for i in idx[better].tolist():
            self.time[name][i] = t

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

    def _size(self, traffic, i: int) -> tuple[float, float]:
        """Vehicle i's (length, width), kept from its first evaluation (`self._sizes.get(i) or self._size(...)` on
        the per-look path: a hit costs no call)."""
        size = self._sizes[i] = (float(traffic.length[i]), float(traffic.width[i]))
        return size

    def evaluate(self, traffic, i: int, state):
        """Vehicle i at the ego's state in one pass, nothing offered yet (looks.evaluate: the values to offer, their
        rates, what the horizon needs), for `look` (its `evaluated`), so that the master reads the rates at a
        step's end (`rates`) and looks there with one evaluation."""
        return self.arithmetic.evaluate(self._a, self._b, traffic.row(i),
                                        self._sizes.get(i) or self._size(traffic, i), state.time, state.x, state.y,
                                        state.psi, state.vx, state.vy, state.ax, state.ay, state.yaw_rate)

    def rates(self, traffic, i: int, state) -> tuple[float, float, float, float]:
        """(distance rate, TTC rate, minus the DRAC rate, headway rate) of vehicle i at the ego's state (nan
        where the measure is not defined, and for all but the distance beyond RANGE). The master's
        "criticality" condition at a bisection probe: any of them turned from < 0 at the step's start to >= 0
        (a closest approach, a smallest TTC, a largest DRAC, a smallest headway), or the TTC rate turned
        from nan to a number or back (a collision course began or ended, or the vehicle crossed RANGE: the
        value there bounds the interval over which the extreme is taken)."""
        return self.evaluate(traffic, i, state)[1]

    def distance_rate(self, traffic, i: int, state) -> float:
        """`rates`' first: the distance's rate alone (the master's probe for a closest approach)."""
        return self.arithmetic.distance_rate(self._a, self._b, traffic.row(i),
                                             self._sizes.get(i) or self._size(traffic, i), state.time, state.x,
                                             state.y, state.psi, state.vx, state.vy, state.yaw_rate)

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
        begin (looks.horizon). The ego's bounds as in
        triggers.py: |acceleration| of its CG, yaw rate, radius = its reference point to a footprint corner.
        Valid while the vehicle's motion is unchanged (until an action fires), like the master's other
        vehicle bounds."""
        if i >= self.size:
            self._grow(i + 1)
        rates, horizon, self.quiet, self.course = self.arithmetic.look(
            self._a, self._b, traffic.row(i), self._sizes.get(i) or self._size(traffic, i), state.time, state.x,
            state.y, state.psi, state.vx, state.vy, state.ax, state.ay, state.yaw_rate, evaluated, i, self._tables,
            acceleration, yaw_rate_bound, radius)
        return rates, horizon

    def course_check(self, traffic, i: int, state, acceleration: float, yaw_rate_bound: float,
                     radius: float) -> float:
        """Between two looks at vehicle i off any collision course and headway within RANGE, whether one has begun
        (the follower checks at every communication point once the bound `course` of its last look or check has
        ended): nan if the vehicle is now within RANGE on a collision course or with a headway (it then needs a
        look, and a course's start, or its coming within RANGE on one, is located); else a new bound (s from now)
        on when that can be: `course_horizon`, or beyond RANGE on a course or behind a vehicle ahead, when it can
        come within RANGE (looks.course_check)."""
        return self.arithmetic.course_check(self._a, self._b, traffic.row(i), self._sizes[i], state.time, state.x,
                                             state.y, state.psi, state.vx, state.vy, state.yaw_rate, acceleration,
                                             yaw_rate_bound, radius)

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

    def summary(self, vehicle_ids) -> dict:
        """summary.json's `criticality` object (docs/results.md) in SI (the results give the lengths, and DRAC, a
        length per s^2, in the scenario's units: results/scenario_units.py): run-wide extremes and one entry per
        vehicle, None (null) where a measure never applied.
        Keys added to the first six: max_drac_time_s, min_headway_s, min_headway_time_s, contact.
        A vehicle the ego touched (its minimum distance 0: `contact` true) has no DRAC: DRAC grows without bound
        toward a contact (closing speed / 2 TTC, TTC -> 0), so any finite value would only say how close to the
        contact it was last evaluated; its max_drac and max_drac_time_s are null, and the run-wide max_drac is
        that of the vehicles the ego did not touch."""
        def number(x):
            return None if x != x else float(x)

        def entry(values: dict, times: dict, contact: bool) -> dict:
            out = {}
            for name, key, time_key in (("min_distance", "min_distance", "min_distance_time_s"),
                                        ("min_ttc", "min_ttc_s", "min_ttc_time_s"),
                                        ("max_drac", "max_drac", "max_drac_time_s"),
                                        ("min_pet", "min_pet_s", None),
                                        ("min_headway", "min_headway_s", "min_headway_time_s")):
                out[key] = number(values[name])
                if time_key:
                    out[time_key] = number(times[name])
            out["contact"] = contact
            return out

        n = len(vehicle_ids)
        self._grow(n)  # a vehicle never looked at has all its measures null
        touched = [self.value["min_distance"][i] == 0.0 for i in range(n)]
        value = {name: [math.nan if name == "max_drac" and touched[i] else self.value[name][i] for i in range(n)]
                 for name in MEASURES}
        time = {name: [math.nan if name == "max_drac" and touched[i] else self.time[name][i] for i in range(n)]
                for name in MEASURES}
        vehicles = [{"vehicle": int(vehicle_ids[i]), **entry({k: value[k][i] for k in MEASURES},
                                                            {k: time[k][i] for k in MEASURES}, touched[i])}
                    for i in range(n)]
        overall_values, overall_times = {}, {}
        for name in MEASURES:
            values, times = np.array(value[name], dtype=float), np.array(time[name], dtype=float)
            if n == 0 or np.isnan(values).all():
                overall_values[name] = overall_times[name] = math.nan
                continue
            # the best value; among vehicles within FLAT of it, the earliest instant
            best = np.nanmax(values) if name == "max_drac" else np.nanmin(values)
            near = np.abs(values - best) <= FLAT
            overall_values[name] = best
            overall_times[name] = float(np.nanmin(np.where(near, times, np.nan)))
        return {**entry(overall_values, overall_times, any(touched)), "vehicles": vehicles}

