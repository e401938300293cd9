"""The criticality record kept during a run (extremes.py's Extremes): which traffic vehicles need a look at
a communication point, when a step needs an FMU snapshot to locate an extreme inside it, locating those
extremes (locate.py), and the PET's conflict areas. The master's loop asks it one question before a step
(`wants_snapshot`) and gives it one notice after it (`stepped`); the firing handlers beside the loop tell it what
fires (`touch`, `changing`, `lane_leave_instant`, then `fired`)."""

from __future__ import annotations

import math

import numpy as np

from ..sdl.events import Road
from ..vehicle import EgoInstance, EgoState
from .extremes import Extremes
from .geometry import reach_time_scalar
from .measures import band_times, conflict_far_end, passage_known
from .locate import CRITICALITY_TOLERANCE, first_instant, root_instant
from .traffic import Traffic
from .triggers import EgoBounds

NO_LOOK = -math.inf  # a vehicle's next-look instant when it must be looked at now
HEADWAY_DOMAIN = "headway"  # a change found in a step: the headway began or ceased to apply


class CriticalityFollower:
    """The criticality record, and per vehicle the instant it next needs a look and its rates at its last look,
    the instant its footprint will leave the ego's lane (PET), and how exactly the extremes' instants are known
    (0: bisected to CRITICALITY_TOLERANCE)."""

    def __init__(self, ego: EgoInstance, traffic: Traffic, bounds: EgoBounds, road: Road, exact: bool):
        self.ego, self.traffic, self.bounds, self.road = ego, traffic, bounds, road
        self.exact = exact  # whether the FMU can roll back (else extremes are taken at communication points)
        self.extremes = Extremes(bounds.length, bounds.width)
        # the scans over the vehicles on the road (which are due, the earliest bounds): the record's twin (looks.py)
        self._scans = self.extremes.arithmetic
        self.next_look: list[float] = []  # per vehicle (traffic index), the instant it next needs a look
        self.earliest_look = NO_LOOK
        # per vehicle, the instant before which its located instants cannot be (Extremes.quiet), and the
        # earliest step end at which one can be found (at its next look and not before that instant): a step
        # ending before that needs no FMU snapshot to locate it from
        self.quiet_until: list[float] = []
        self.quiet_look: list[float] = []  # per vehicle, max(next look, quiet_until)
        self.look_time: list[float] = []  # per vehicle, its last look at a communication point
        # per vehicle, the instant before which no collision course or headway can begin (Extremes.course: from
        # then on it is checked at every communication point between its looks, Extremes.course_check), and the
        # instant of its last check or look
        self.course_until: list[float] = []
        self.check_time: list[float] = []
        self.looks_quiet = NO_LOOK  # the earliest over the vehicles of max(next look, quiet_until)
        self.earliest_course = math.inf  # the earliest course_until
        self.earliest_quiet = NO_LOOK  # the earliest of the two: a step ending before needs no snapshot
        self.look_rates: dict[int, tuple] = {}
        self.leaves_lane: dict[int, float] = {}
        self.enters_lane: dict[int, float] = {}  # per vehicle, the instant its footprint will enter the ego's lane
        self.pet_pending = False  # whether a PET waits for the ego's front to reach its conflict area
        self.pet_station = math.inf  # the nearest such area's station
        self.pet_due = NO_LOOK  # a lower bound on when the ego's front can reach it (NO_LOOK: to be computed)
        self.evaluated: dict[int, tuple] = {}  # per vehicle, its evaluation at the step's end (rates read)
        self.criticality_uncertainty = 0.0
        self.located = 0  # instants located inside steps (probed from a saved FMU state)
        self.touched: set[int] = set()  # the vehicles something fired for at this instant (looked at after)
        self._calm: float | None = None  # `_calm_until`, None: to be computed again
        # traffic.active when the looks' minima and the course bounds' minimum were last taken over every vehicle
        self._looks_of = self._courses_of = None

    def summary(self, vehicle_ids) -> dict:
        """summary.json's `criticality` (docs/results.md) in SI; with an FMU that cannot roll back, how exactly its
        instants are known (`time_uncertainty_s`, as on the events)."""
        summary = self.extremes.summary(vehicle_ids)
        if not self.exact:
            summary["time_uncertainty_s"] = self.criticality_uncertainty
        return summary

    # ---- what the master's loop and its firing handlers tell and ask ---------------------------------------

    def start(self, state: EgoState) -> None:
        """The run's first instant (after what fires there): every vehicle looked at."""
        self.look(state, everyone=True)
        self.touched.clear()

    def wants_snapshot(self, state: EgoState, limit: float) -> bool:
        """The loop's question before a step from state.time to at most `limit`: whether to save the FMU's state
        at the step's start, from which an extreme inside the step is located (only for an FMU that can roll
        back). The vehicles whose bound on their next located instant ends inside the step are looked at now
        first (a look moves that bound on: the step may then need no snapshot)."""
        calm = self._calm
        if calm is None:
            calm = self._calm = self._calm_until()
        if limit < calm:
            return False  # none of the bounds below ends by `limit`: no look, no check, no snapshot
        if self.pet_pending and self.pet_due <= limit:
            self.pet_due = self.pet_horizon(state)
            self._calm = None
        if not self.exact:
            return False
        if self.looks_quiet <= limit:
            self.look(state, ahead=limit)
        if self.earliest_course <= limit:
            self._check_courses(state, limit)
            if self.earliest_look == NO_LOOK:  # a check found a course (it cannot begin unseen: only rounding)
                self.look(state)
        return bool(self.earliest_quiet <= limit or self.pet_pending or self.leaves_lane) \
            and self.criticality_due(state.time, limit)

    def stepped(self, base, t0: float, state: EgoState, fired: bool) -> None:
        """The loop's notice after a step from t0 to state.time (`base`: the snapshot at t0, or None; `fired`:
        something fires at its end): the extremes inside the step located, the vehicles due looked at."""
        if base is not None or fired or state.time >= self.earliest_look or not self.exact:
            self.follow_criticality(base, t0, state, everyone=False)

    def touch(self, vehicles) -> None:
        """Something fires for these vehicles at this instant (a spawn, a contact beginning or ending): they are
        looked at after the fire (`fired`)."""
        self.touched.update(vehicles)

    def changing(self, i: int, state: EgoState) -> None:
        """Vehicle i's motion changes at this instant (an action starts) or it leaves the road: looked at with the
        motion it had until now, and again after the fire."""
        self.look_before_change(i, state)

    def fired(self, state: EgoState) -> None:
        """After a fire: the vehicles it touched looked at with their motions from this instant on."""
        self.look(state, only=self.touched)
        self.touched.clear()

    def finish(self, state: EgoState) -> None:
        """The run's end: every vehicle looked at (an extreme at the end of its interval)."""
        self.look(state, everyone=True)

    # ---- inside

    def _calm_until(self) -> float:
        """The earliest step end for which `wants_snapshot` has anything to do: a PET horizon to compute again, and
        with rollback a look's or a check's bound ending, a lane leave (recomputed when any of them changes)."""
        calm = self.pet_due if self.pet_pending else math.inf
        if self.exact:  # min(calm, earliest_quiet, the lane leaves) without the calls (what min returns)
            quiet = self.earliest_quiet
            if quiet < calm:
                calm = quiet
            if self.leaves_lane:
                leave = min(self.leaves_lane.values())
                if leave < calm:
                    calm = leave
        return calm

    def criticality_due(self, t: float, limit: float) -> bool:
        """Whether an extreme could lie in a step from t to at most `limit` (then the step starts from an FMU
        snapshot): a vehicle's look comes due after the instant before which none of its located instants can
        be (Extremes.quiet), a vehicle's footprint leaves the ego's lane, or the ego's front can reach a
        pending PET's conflict area (`pet_horizon`)."""
        return (self.earliest_quiet <= limit and bool(len(self.traffic.active))) \
            or (self.pet_pending and self.pet_due <= limit) \
            or bool(self.leaves_lane) and any(t < leave <= limit for leave in self.leaves_lane.values())

    def look(self, state: EgoState, everyone: bool = False, ahead: float | None = None, only=None) -> None:
        """Offers the vehicles whose look has come (all of them: `everyone`) to the record at this
        communication point, keeps their rates (the next step's start) and their next-look instants. With
        `ahead` (a step's end), also the vehicles last looked at before now whose located instants could
        come by then: a look now moves that bound on, and the step may then need no FMU snapshot. With
        `only` (the vehicles something fired for: spawned, started an action, began or ended a contact), those
        still on the road and no other: the others' bounds still hold (they rest on the ego's bounds, which
        hold whatever its inputs, and on the vehicles' own motions), so the cost of a fire does not grow with
        the number of vehicles."""
        t = state.time
        if not everyone and t < self.earliest_look and ahead is None and only is None:
            return
        traffic, bounds = self.traffic, self.bounds
        if len(self.next_look) < traffic.size:
            self._grow()
        next_look, quiet_until, look_time = self.next_look, self.quiet_until, self.look_time
        course_until, check_time, quiet_look = self.course_until, self.check_time, self.quiet_look
        evaluated, self.evaluated = self.evaluated, {}
        extremes, look_rates = self.extremes, self.look_rates
        if only is None:
            vehicles = traffic.active_list()
            # (earliest_look is a lower bound on every vehicle's next look: none is due before it)
            due = vehicles if everyone else \
                self._scans.due_looks(vehicles, next_look, quiet_until, look_time, t, ahead, t >= self.earliest_look)
        else:
            vehicles = due = sorted(i for i in only if traffic.present[i])
        if not due and traffic.active is self._looks_of:
            return  # no bound moved and no vehicle left: the minima below still hold
        for i in due:
            rates, horizon = extremes.look(traffic, i, state, bounds.acceleration, bounds.yaw_rate, bounds.radius,
                                           evaluated.get(i))
            look_rates[i] = rates
            next_look[i] = t + horizon
            quiet_until[i] = t + extremes.quiet
            course_until[i] = t + extremes.course
            look_time[i] = check_time[i] = t
            quiet_look[i] = quiet_until[i] if quiet_until[i] > next_look[i] else next_look[i]
        # per vehicle its next look, the earliest step end at which a located instant can be found (its next look,
        # not before its quiet bound: max(instant, quiet), kept in quiet_look), its course bound; their minima
        earliest, earliest_quiet, earliest_course = self._scans.earliest(vehicles, next_look, quiet_look, course_until)
        if only is None:
            self._looks_of = self._courses_of = traffic.active  # the minima over every vehicle on the road
        else:
            # the others' instants are kept: the earliest so far stays a bound (at worst early: then a look
            # finds nothing due and recomputes it over every vehicle)
            self._looks_of = self._courses_of = None
            earliest = min(self.earliest_look, earliest)
            earliest_quiet = min(self.looks_quiet, earliest_quiet)
            earliest_course = min(self.earliest_course, earliest_course)
        self.earliest_look = earliest
        self.looks_quiet, self.earliest_course = earliest_quiet, earliest_course
        self.earliest_quiet = earliest_course if earliest_course < earliest_quiet else earliest_quiet
        self._calm = None

    def _grow(self) -> None:
        size = self.traffic.size
        if len(self.next_look) < size:
            for table in (self.next_look, self.quiet_until, self.quiet_look, self.look_time, self.check_time):
                table.extend([NO_LOOK] * (size - len(table)))
            self.course_until.extend([math.inf] * (size - len(self.course_until)))

    def _check_courses(self, state: EgoState, until: float) -> None:
        """The vehicles whose bound on a collision course's or a headway's start (`course_until`) ends by `until`
        (this instant: a step's end; or the coming step's end, checked at its start to move the bound on, so
        that the step may need no snapshot), not due a look and neither looked at nor checked at this instant:
        each checked (Extremes.course_check). One found on a course or with a headway is due a look at once (a
        course that began inside the step is then located like any change: its rates at the last look had none)."""
        if self.earliest_course > until:
            return
        t = state.time
        traffic, bounds, extremes = self.traffic, self.bounds, self.extremes
        next_look, course_until, check_time = self.next_look, self.course_until, self.check_time
        vehicles = traffic.active_list()
        due = self._scans.due_checks(vehicles, course_until, check_time, next_look, until, t)
        if not due and traffic.active is self._courses_of:
            return  # no bound moved and no vehicle left: the minimum still holds
        self._courses_of = traffic.active
        for i in due:
            check_time[i] = t
            bound = extremes.course_check(traffic, i, state, bounds.acceleration, bounds.yaw_rate, bounds.radius)
            if bound == bound:
                course_until[i] = t + bound
            else:  # due a look now (its look sets the bound again)
                next_look[i] = self.earliest_look = self.looks_quiet = NO_LOOK
                quiet = self.quiet_until[i]
                self.quiet_look[i] = quiet if quiet > NO_LOOK else NO_LOOK
                self._looks_of = None
                course_until[i] = math.inf
        earliest_course = self.earliest_course = self._scans.earliest(vehicles, course_until)
        looks_quiet = self.looks_quiet
        self.earliest_quiet = earliest_course if earliest_course < looks_quiet else looks_quiet
        self._calm = None

    def look_before_change(self, i: int, state: EgoState) -> None:
        """Vehicle i at this instant with the motion it had until now, before an action changes it or it leaves
        the road (an extreme at the end of that motion), unless it was looked at here already; it is looked at
        again with its new motion after the fire."""
        if i >= len(self.look_time) or self.look_time[i] != state.time:
            bounds = self.bounds
            self.extremes.look(self.traffic, i, state, bounds.acceleration, bounds.yaw_rate, bounds.radius)
        self.touched.add(i)

    def follow_criticality(self, base, t0: float, state: EgoState, everyone: bool) -> None:
        """After a step from t0 to state.time: locates the extremes inside it (from the snapshot `base` at t0;
        without one, an FMU that cannot roll back, they are taken at this communication point, known within
        the step), then looks at the vehicles due (all of them: `everyone`, before something fires)."""
        t1 = state.time
        self._check_courses(state, t1)
        if base is not None:
            self._locate_in_step(base, t0, state)
        elif not self.exact and (self._changes_in_step(t0, state) or self.pet_pending
                                 or any(leave <= t1 for leave in self.leaves_lane.values())):
            self.criticality_uncertainty = max(self.criticality_uncertainty, t1 - t0)
        if self.leaves_lane:
            for i, leave in list(self.leaves_lane.items()):
                if leave <= t1:  # at this instant, or (no snapshot) within this step
                    self._lane_left(i, state)
        if self.pet_pending and self._front(state) >= self.pet_station:
            self._reach(state)
        if self.enters_lane:
            self._entries(t1)
        if base is not None:
            self.ego.discard(base)
        self.look(state, everyone)

    def _changes_in_step(self, t0: float, state: EgoState) -> list:
        """What changed inside the step for the vehicles looked at now: (vehicle, rate index) where that rate
        turned from < 0 to >= 0 (a closest approach, a smallest TTC, a largest DRAC, a smallest headway), and
        (vehicle, None) where a collision course began or ended (TTC's rate turned nan or back), (vehicle,
        HEADWAY_DOMAIN) where the headway began or ceased to apply (a vehicle ahead moving into or out of the
        ego's path, coming to a stop or turning toward the ego, crossing RANGE)."""
        t1 = state.time
        changes = []
        if t1 < self.earliest_look:
            return changes
        next_look = self.next_look
        for i in [i for i in self.traffic.active_list() if next_look[i] <= t1]:
            previous = self.look_rates.get(i)
            if previous is None:
                continue
            evaluated = self.evaluated[i] = self.extremes.evaluate(self.traffic, i, state)
            now = evaluated[1]
            changes += [(i, k) for k in range(4) if previous[k] < 0 <= now[k]]
            if math.isnan(previous[1]) != math.isnan(now[1]):
                changes.append((i, None))
            if math.isnan(previous[3]) != math.isnan(now[3]):
                changes.append((i, HEADWAY_DOMAIN))
        return changes

    def _locate_in_step(self, base, t0: float, state: EgoState) -> None:
        """Each extreme inside the step bisected from the snapshot at t0 (the FMU's state at t1 saved and
        restored after: the run goes on exactly as without the probes), and the vehicle looked at on both
        sides of the located instant (the first instant an extreme is reached is kept)."""
        t1 = state.time
        changes = self._changes_in_step(t0, state)
        leaving = [(i, leave) for i, leave in self.leaves_lane.items() if t0 < leave < t1]
        extremes = self.extremes
        reaching = self.pet_pending and self._front(state) >= self.pet_station
        ending = self._transitions_ending(t0, t1) if t1 >= self.earliest_look else []
        if not (changes or leaving or reaching or ending):
            return
        ego, traffic, bounds = self.ego, self.traffic, self.bounds
        end = ego.save()

        def probe(t: float) -> EgoState:
            ego.restore(base)
            ego.step_to(t)
            return ego.read()

        def bisect_instant(low, high, condition, known=None) -> tuple[EgoState, EgoState]:
            """(state before, state at) the instant condition turns true in (low, high], true at high; `known`:
            locate.first_instant's."""
            _, before, at = first_instant(probe, low, high, condition, CRITICALITY_TOLERANCE, high_state=state,
                                          known=known)
            return before, at

        turn, acceleration = bounds.radius * bounds.yaw_rate, bounds.acceleration

        def passage(position, station: float):
            """`known` for `position(p) >= station`, position the station of the ego's front or rear."""
            def known(middle, below, above):
                (low, low_state), (high, high_state) = below, above
                return passage_known(middle, low, None if low_state is None else position(low_state),
                                     0.0 if low_state is None else _station_rate(low_state), high,
                                     position(high_state), _station_rate(high_state), station, turn, acceleration)
            return known

        def look_at(i: int, *states) -> None:
            for probed in states:
                if probed is not None:
                    extremes.look(traffic, i, probed, bounds.acceleration, bounds.yaw_rate, bounds.radius)
            self.located += 1

        for i, k in changes:
            if k is None or k == HEADWAY_DOMAIN:
                # the start or end of a measure's domain: the instant its rate turns defined / undefined (nan)
                which = 1 if k is None else 3
                was = math.isnan(self.look_rates[i][which])
                before, at = bisect_instant(t0, t1, lambda p, i=i, was=was, which=which:
                                            math.isnan(extremes.rates(traffic, i, p)[which]) != was)
            else:
                rate_of = (lambda p, i=i: extremes.distance_rate(traffic, i, p)) if k == 0 else \
                    (lambda p, i=i, k=k: extremes.rates(traffic, i, p)[k])
                before, at = root_instant(probe, t0, t1, rate_of, self.look_rates[i][k], self.evaluated[i][1][k],
                                          CRITICALITY_TOLERANCE, state)
            # a contact's start (the master's contact trigger locates it: distance and TTC 0 there): the
            # instant before it is not offered, DRAC growing without bound toward a contact
            evaluated = extremes.evaluate(traffic, i, at)
            rates = evaluated[1]
            contact = rates[0] == 0.0 and math.isnan(rates[1])
            if not contact and before is not None:
                extremes.look(traffic, i, before, bounds.acceleration, bounds.yaw_rate, bounds.radius)
            extremes.look(traffic, i, at, bounds.acceleration, bounds.yaw_rate, bounds.radius, evaluated)
            self.located += 1
        for i, end_time in ending:
            # the vehicle's velocity jumps at its transition's end (TTC, DRAC and headway with it): looked at
            # with the motion just before (1e-9 s earlier for the vehicle: < 1e-7 m) and at the instant
            at = state if end_time == t1 else probe(end_time)
            look_at(i, at._replace(time=end_time - 1e-9), at)
        for i, leave in leaving:
            self._lane_left(i, probe(leave))
        rear = self._rear(state)
        for i, station in zip(*(k.tolist() for k in extremes.rear_stations())):
            if station <= rear:
                _, reached = bisect_instant(t0, t1, lambda p, station=station: self._rear(p) >= station,
                                            passage(self._rear, station))
                extremes.rear_reached(i, reached.time)
                self.located += 1
        front = self._front(state)
        for i in np.flatnonzero(extremes.conflict[:extremes.size] <= front).tolist():
            station = float(extremes.conflict[i])
            start = max(t0, float(extremes.left_path[i]))
            _, reached = bisect_instant(start, t1, lambda p: self._front(p) >= station, passage(self._front, station))
            self._reach(reached)
            self.located += 1
        ego.restore(end)
        ego.discard(end)

    def _transitions_ending(self, t0: float, t1: float) -> list[tuple[int, float]]:
        """(vehicle, instant) of the lateral or speed transitions ending inside (t0, t1], for the vehicles
        followed at every communication point (within extremes.RANGE)."""
        traffic = self.traffic
        ending = []
        next_look = self.next_look
        for i in [i for i in traffic.active_list() if next_look[i] <= t1]:
            start, _, _, _, _, _, duration = traffic.row(i)
            if duration > 0.0:
                end_time = start + duration
                if t0 < end_time <= t1:
                    ending.append((i, end_time))
        return ending

    def _front(self, state: EgoState) -> float:
        """Station of the front of the ego's footprint (extremes.Extremes.reach's)."""
        return state.x + self.bounds.length / 2 * abs(math.cos(state.psi)) \
            + self.bounds.width / 2 * abs(math.sin(state.psi))

    def _rear(self, state: EgoState) -> float:
        """Station of the rear of the ego's footprint."""
        return state.x - self.bounds.length / 2 * abs(math.cos(state.psi)) \
            - self.bounds.width / 2 * abs(math.sin(state.psi))

    def lane_leave_instant(self, i: int, state: EgoState) -> None:
        """When an action starts vehicle i's lateral move: the instants its footprint leaves and enters the ego's
        lane (measures.band_times, closed form), where the PET's conflict areas are set (the vehicle
        leaving first; the ego leaving first: the far end of the area the vehicle will enter)."""
        traffic, road = self.traffic, self.road
        self.leaves_lane.pop(i, None)
        self._calm = None
        lane = road.lane_at(-state.y)
        centre = road.lane_center(lane)
        enter, leave = band_times(float(traffic.t0[i]), float(traffic.lateral0[i]), float(traffic.lateral1[i]),
                                  float(traffic.duration[i]), float(traffic.width[i]), centre - road.lane_width / 2,
                                  centre + road.lane_width / 2)
        if state.time < leave < math.inf:
            self.leaves_lane[i] = leave
        if state.time < enter < math.inf:
            self.enters_lane[i] = enter
            far_end = conflict_far_end(traffic.motion_of(i, enter)[0], float(traffic.length[i]))
            self.extremes.path_entering(i, far_end, self._rear(state))
            self._pending()
        elif self.enters_lane.pop(i, None) is not None:
            self.extremes.cancel_entry(i)
            self._pending()

    def _entries(self, t1: float) -> None:
        """The vehicles whose footprint entered the ego's lane by t1 (closed-form instants): the PET where the
        ego's rear had left the area first (extremes.Extremes.path_entered); none for a vehicle that left the
        road before entering."""
        for i, enter in list(self.enters_lane.items()):
            if enter <= t1:
                del self.enters_lane[i]
                if self.traffic.present[i]:
                    self.extremes.path_entered(i, enter)
                else:
                    self.extremes.cancel_entry(i)
        self._pending()

    def _lane_left(self, i: int, state: EgoState) -> None:
        del self.leaves_lane[i]
        station, _, _ = self.traffic.at(i, state.time)
        self.extremes.path_left(i, state.time, station, float(self.traffic.length[i]), self._front(state))
        self._pending()

    def _reach(self, state: EgoState) -> None:
        extremes = self.extremes
        extremes.reach(state)
        pending, far = extremes.rear_stations()
        for i in pending[far <= self._rear(state)].tolist():
            extremes.rear_reached(i, state.time)
        self._pending()

    def _pending(self) -> None:
        """The nearest station the ego's front must reach for a pending PET: a conflict area's near end, or a
        far end its rear must pass (the front is then at least min(L, W) further on: front - rear =
        L |cos psi| + W |sin psi|)."""
        stations = self.extremes.pending_stations()
        _, far = self.extremes.rear_stations()
        self.pet_pending = bool(len(stations) or len(far))
        self.pet_station = min(float(stations.min()) if len(stations) else math.inf,
                               float(far.min()) + min(self.bounds.length, self.bounds.width) if len(far) else math.inf)
        self.pet_due = NO_LOOK
        self._calm = None

    def pet_horizon(self, state: EgoState) -> float:
        """When the ego's front can first reach the pending conflict station: the front's station rate is at
        most the reference point's (which grows at most at the acceleration bound A) plus R r_max (the
        footprint turning), so reach_time(station - front, station rate + R r_max, A) as for event distances."""
        bounds = self.bounds
        station_rate = state.vx * math.cos(state.psi) - state.vy * math.sin(state.psi)
        return state.time + reach_time_scalar(self.pet_station - self._front(state),
                                              station_rate + bounds.radius * bounds.yaw_rate, bounds.acceleration)


def _station_rate(state: EgoState) -> float:
    """The ego's reference point's station rate (m/s): its body-frame velocity turned by psi."""
    return state.vx * math.cos(state.psi) - state.vy * math.sin(state.psi)
