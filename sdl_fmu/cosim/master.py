"""The co-simulation master: steps the ego FMU through fmpy together with the road, the BRK
controller, the driver model and the traffic model, and fires every trigger at its true instant,
whatever the communication step.

The run is a loop (`Cosimulation.run`) over four helpers, each in its own module:
- `TriggerSchedule` (schedule.py): before each step, lower bounds from the ego's kinematics and its
  acceleration and yaw-rate limits (triggers.py) on the earliest instant at which any trigger (an event
  distance, a BRK threshold, a closure time, a contact starting or ending, a departure, a wheel crossing onto
  another surface) could become true, and whether one is true at a state;
- `Inputs` (inputs.py): the driver's (or BRK's) pedals, the steer and the surfaces under the wheels;
- `Recorder` (recorder.py): the samples;
- the criticality record (criticality.py), fed by the hooks `look`, `criticality_due` and
  `follow_criticality` below.
Where nothing can happen the loop steps long: to the next driver sample, the `step` limit or the earliest
trigger bound, whichever is first. Within MIN_LOOKAHEAD of a possible trigger it steps from a saved FMU state
and, if a trigger became true inside the step, rolls back and bisects (fmi2GetFMUstate / fmi2SetFMUstate)
until the instant is known within TIME_TOLERANCE; then it fires what is due (`fire_due`). Traffic motion is
closed-form in time, so it needs no rollback of its own. The driver model is a sampled controller with its
own period (`driver_period`): its samples are instants the master steps to, independent of `step`.
"""

from __future__ import annotations

import math
import random
import time as wall_clock
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Callable

import numpy as np

from ..results import RunResult
from ..sdl.events import ApproachingVehicle, Brake, EndOfScenario, Scenario, SurfaceAttribute
from ..sdl.vehicles import VehicleModel
from ..units import FOOT, from_si
from ..vehicle import EgoModel, EgoState, shipped_map_path
from .brake import BrakeHold
from .criticality import Extremes, band_times
from .driver import MAX_STEER, make_driver
from .ego import step_until_time
from .inputs import Inputs
from .recorder import Recorder, ttc_series
from .road import surface_map, surface_sections, wheel_geometry
from .schedule import TriggerSchedule
from ..storage import EventLog
from .traffic import Traffic, choose_model
from .triggers import EgoKinematics, ego_bounds, reach_time_scalar

DEFAULT_SPEED = 88 * FOOT  # m/s: 60 mph, the driver's start speed unless --speed says otherwise
RUNOUT = 1000 * FOOT  # m driven past the last event when neither ES nor --until ends the run
MAX_TIME = 3600.0  # s, a run never goes beyond
TIME_TOLERANCE = 1e-6  # s, how exactly a trigger's instant is located
# s: closer than this to a possible trigger the master steps this far from a saved state and bisects;
# a trigger cannot become true and false again within it (contacts last > 0.1 s, margins move smoothly).
# An FMU that cannot roll back is stepped this far and checked: its triggers are located within it.
MIN_LOOKAHEAD = 1e-3
# s, how exactly a criticality extreme's instant is located (a bracket this wide holds the root, so that two
# runs at different steps agree within TIME_TOLERANCE)
CRITICALITY_TOLERANCE = TIME_TOLERANCE / 4
# the fraction of the way to a flat extreme's extended root a probe goes (root_instant): short of it, so that
# the probes approach it from below, where the rate is known
FLAT_STEP = 0.98
NO_LOOK = -math.inf  # a vehicle's next-look instant when it must be looked at now
DEFAULT_DRIVER_PERIOD = 0.05  # s, the driver model's sampling period (20 Hz)
DEFAULT_STEP = 1.0  # s, longest communication step (the driver's samples and the triggers cut it shorter)


@dataclass
class RunOptions:
    dynamics: str = "simple"  # the shipped map run_scenario drives an FMU given as a path with
    speed: float | None = None  # m/s
    seed: int = 1
    step: float = DEFAULT_STEP  # s, longest communication step; results do not depend on it
    driver_period: float = DEFAULT_DRIVER_PERIOD  # s, the driver model's sampling period
    until_distance: float | None = None  # m
    until_time: float | None = None  # s
    parameters: dict[str, float] = field(default_factory=dict)  # FMU start values, SI
    tire_parameters: dict[str, float] = field(default_factory=dict)  # tire slot start values (advanced)
    known_attributes: set[int] | None = None  # attribute numbers with a tire file (advanced)
    progress: Callable[[Cosimulation, EgoState], None] | None = None  # called after every recorded sample


class Cosimulation:
    """One run of a scenario against one ego vehicle (an EgoModel, or an FMU driven through the shipped map
    of options.dynamics)."""

    def __init__(self, scenario: Scenario, model: EgoModel | Path, options: RunOptions,
                 vehicle_table: dict[int, VehicleModel]):
        if not options.step > 0 or not options.driver_period > 0:
            raise ValueError("the communication step and the driver period must be > 0")
        self.scenario = scenario
        self.options = options
        self.road = scenario.road
        self.vehicle_table = vehicle_table
        self.rng = random.Random(options.seed)
        if not isinstance(model, EgoModel):
            model = EgoModel.open(model, shipped_map_path(options.dynamics))
        self.model = model = model.with_parameters({**options.tire_parameters, **options.parameters})
        self.exact = model.can_roll_back  # triggers bisected to TIME_TOLERANCE, else located within MIN_LOOKAHEAD
        self.time_uncertainty = 0.0  # s, how exactly the instant of what fires now is known
        self.surfaces = surface_map(scenario, model.default_surface)
        speed = DEFAULT_SPEED if options.speed is None else options.speed
        start_lateral = self.road.lane_center(1)
        self.ego = model.instantiate(start={"speed": speed, "x": 0.0, "y": -start_lateral, "yaw": 0.0})
        geometry = wheel_geometry(model)
        mu_max = model.peak_friction([v for values in self.surfaces.values.values() for v in values])
        wheel_arm = max(math.hypot(x, y) for x, y in model.wheels)
        self.bounds = ego_bounds(model, mu_max, speed, wheel_arm, MAX_STEER)
        self.traffic = Traffic()
        self.inputs = Inputs(self.ego, model, make_driver(speed, start_lateral, model), self.road, self.surfaces,
                             geometry)
        self.end_distance, self.end_reason = self._end_distance()
        self.schedule = TriggerSchedule(scenario.events, self.end_distance, self.road, self.surfaces, geometry,
                                        self.bounds, self.traffic, self.inputs)
        self.recorder = Recorder(model.wheel_columns)
        self.events = EventLog()  # summary.json's events, streamed to a file: memory stays bounded
        self.warnings: list[str] = list(self.ego.warnings)
        if not self.exact:
            self.warnings.append(f"the FMU {model.fmu_path.name} cannot get and set its state: each trigger is located "
                                 f"within a communication step of at most {MIN_LOOKAHEAD:g} s, not bisected to "
                                 f"{TIME_TOLERANCE:g} s (time_uncertainty_s on each event)")
        if model.friction is None:
            self.warnings += [f"line {event.line}: RSA has no effect: the vehicle map of {model.name} has no friction "
                              "input, so the road surface cannot act on the vehicle"
                              for event in scenario.events if isinstance(event, SurfaceAttribute)]
        self.collisions = 0
        self.collision_points: list[tuple[float, float]] = []
        self.steps = 0
        self.finished = False
        # criticality (criticality.py): the record, per vehicle the instant it next needs a look and its rates
        # at its last look, the instant its footprint will leave the ego's lane (PET), and how exactly the
        # extremes' instants are known (0: bisected to CRITICALITY_TOLERANCE)
        self.extremes = Extremes(self.bounds.length, self.bounds.width)
        self.next_look = np.full(16, NO_LOOK)
        self.earliest_look = NO_LOOK
        # per vehicle, the instant before which its located instants cannot be (Extremes.quiet), and the
        # earliest step end at which one can be found (at its next look and not before that instant): a step
        # ending before that needs no FMU snapshot to locate it from
        self.quiet_until = np.full(16, NO_LOOK)
        self.look_time = np.full(16, NO_LOOK)  # per vehicle, its last look at a communication point
        self.earliest_quiet = NO_LOOK
        self.look_rates: dict[int, tuple] = {}
        self.leaves_lane: dict[int, float] = {}
        self.pet_pending = False  # whether a PET waits for the ego's front to reach its conflict area
        self.pet_station = math.inf  # the nearest such area's station
        self.pet_due = NO_LOOK  # a lower bound on when the ego's front can reach it (NO_LOOK: to be computed)
        self.evaluated: dict[int, tuple] = {}  # per vehicle, its evaluation at the step's end (rates read)
        self.criticality_uncertainty = 0.0
        self.located = 0  # instants located inside steps (probed from a saved FMU state)

    def _scenario_units(self, value: float) -> float:
        return from_si(value, self.scenario.units)

    def _end_distance(self) -> tuple[float, str]:
        """Where the run ends by distance, and why: ES, --until-distance, or a runout past the last event."""
        candidates = [(d, reason) for d, reason in ((self.scenario.end_distance, "scenario"),
                                                    (self.options.until_distance, "until_distance"))
                      if d is not None]
        if candidates:
            return min(candidates)
        if self.options.until_time is not None:
            return math.inf, "until_time"
        last = max((e.distance for e in self.scenario.events), default=0.0)
        return last + RUNOUT, "runout"

    # ---- the loop -------------------------------------------------------------------------------

    def run(self) -> RunResult:
        started = wall_clock.perf_counter()
        try:
            ego, inputs, schedule = self.ego, self.inputs, self.schedule
            state = ego.read()
            self.fire_due(state)
            self.look(state, everyone=True)
            inputs.sample_driver(state, None)
            inputs.apply(state, True)
            self.record(state)
            step, progress = self.options.step, self.options.progress
            period = self.options.driver_period
            sample = 1  # index of the next driver sample, at next_sample = sample * period
            next_sample = sample * period
            until_time = self.options.until_time
            stop_time = min(MAX_TIME, math.inf if until_time is None else until_time)
            # the kept bounds and their minimum: while none of them is below the limit and nothing has fired,
            # horizons() would return them unchanged, so it is called only when one could bind (or after a fire)
            horizons, earliest = {}, -math.inf
            while not self.finished:
                t = state.time
                if t >= MAX_TIME:
                    self.warnings.append(f"the run was stopped at the time limit of {MAX_TIME:g} s")
                    self.finish(state, "time_limit")
                    break
                limit = min(t + step, next_sample, stop_time)
                if earliest < limit:
                    horizons = schedule.horizons(state, limit)
                    earliest = min(horizons.values()) if horizons else math.inf
                if self.pet_pending and self.pet_due <= limit:
                    self.pet_due = self.pet_horizon(state)
                if self.exact and self.earliest_quiet <= limit:
                    self.look(state, ahead=limit)  # a vehicle's bound from an earlier look ends in this step
                # a snapshot at the step's start, from which extremes inside the step are located
                base = ego.save() if self.exact and (self.earliest_quiet <= limit or self.pet_pending
                                                     or self.leaves_lane) and self.criticality_due(t, limit) else None
                if earliest - t >= MIN_LOOKAHEAD or earliest >= limit:
                    # nothing can become true before `end`; something may be true exactly at it (then at no
                    # other instant: its instant is known exactly)
                    end = min(limit, earliest)
                    ego.step_to(end)
                    state = ego.read()
                    fired = earliest <= end and schedule.triggered(
                        state, [kind for kind, instant in horizons.items() if instant <= end])
                    self.time_uncertainty = 0.0
                else:
                    end = min(t + MIN_LOOKAHEAD, limit)
                    kinds = [kind for kind, instant in horizons.items() if instant <= end]
                    if self.exact:
                        fired = step_until_time(ego, end, lambda probe: schedule.triggered(probe, kinds),
                                                TIME_TOLERANCE)
                    else:  # what became true did so somewhere in (t, end]
                        ego.step_to(end)
                        fired = schedule.triggered(ego.read(), kinds)
                        self.time_uncertainty = end - t
                    state = ego.read()
                self.steps += 1
                driver_sample = state.time >= next_sample
                if base is not None or fired or state.time >= self.earliest_look or not self.exact:
                    self.follow_criticality(base, t, state, everyone=fired)
                if fired:
                    self.fire_due(state)
                    schedule.forget()  # spawns, actions, contacts, departures, the next event, BRK: bounds changed
                    earliest = -math.inf  # the kinds of trigger and their bounds are recomputed next step
                    self.look(state, everyone=True)  # the motions from this instant on
                if until_time is not None and state.time >= until_time:
                    self.finish(state, "until_time")
                if driver_sample:
                    inputs.sample_driver(state, period)
                    while next_sample <= state.time:
                        sample += 1
                        next_sample = sample * period
                inputs.apply(state, fired)  # the inputs from this instant on, as recorded with it
                self.record(state)
                if progress is not None:
                    progress(self, state)
            self.look(state, everyone=True)  # an extreme at the end of the run
            wall = wall_clock.perf_counter() - started
            return self.result(state, wall)
        finally:
            self.ego.close()

    def record(self, state: EgoState) -> None:
        warning = self.schedule.exceeded(state)
        if warning is not None:
            self.warnings.append(warning)
        inputs = self.inputs
        self.recorder.record(state, inputs.controls, inputs.brake_hold is not None, inputs.wheel_values)

    # ---- what happens at an instant -------------------------------------------------------------

    def log(self, code: str, action: str, state: EgoState, **extra) -> None:
        entry = {"code": code, "action": action, "time_s": state.time, "distance": self._scenario_units(state.s),
                 "speed": self._scenario_units(state.v), "lateral": self._scenario_units(-state.y), **extra}
        if not self.exact:
            entry["time_uncertainty_s"] = self.time_uncertainty
        self.events.append(entry)

    def fire_due(self, state: EgoState) -> None:
        """Fires everything due at this state, in file order, until nothing more is due."""
        schedule = self.schedule
        while not self.finished and (event := schedule.pop_due_event(state)) is not None:
            self.fire_event(event, state)
        brake_hold = self.inputs.brake_hold
        if brake_hold is not None:
            reason = brake_hold.release_reason(state)
            if reason:
                self.release_brakes(state, reason)
        if len(self.traffic.active):
            self.fire_traffic(state)
        if state.s >= self.end_distance:
            self.finish(state, self.end_reason)

    def fire_traffic(self, state: EgoState) -> None:
        traffic, schedule, recorder = self.traffic, self.schedule, self.recorder
        kinematics = EgoKinematics.of(state)
        active = traffic.active
        action, overlap, away = schedule.vehicle_conditions(active, kinematics)
        if action.any():
            for i in active[action]:
                while True:  # each action once, the next armed as the previous fires; several may be due at once
                    index = int(traffic.next_action[i]) + 1
                    traffic.start_action(i, state.time, -state.y, state.v)
                    self.log("A", "maneuver", state, vehicle=recorder.vehicle_ids[i], index=index)
                    self.lane_leave_instant(int(i), state)
                    if not schedule.action_due(int(i), kinematics):
                        break
            _, overlap, away = schedule.vehicle_conditions(active, kinematics)
        for i in active[overlap & ~traffic.in_contact[active]]:
            self.collisions += 1
            station, lateral, _ = traffic.at(i, state.time)
            self.collision_points.append(((state.x + station) / 2, (-state.y + lateral) / 2))
            self.log("A", "collision", state, vehicle=recorder.vehicle_ids[i])
        changed = active[overlap != traffic.in_contact[active]]
        traffic.in_contact[active] = overlap
        traffic.next_check[changed] = state.time
        for i in active[away & ~overlap]:
            traffic.remove(i)
            recorder.left(i)
            self.log("A", "despawn", state, vehicle=recorder.vehicle_ids[i])

    def fire_event(self, event, state: EgoState) -> None:
        if isinstance(event, ApproachingVehicle):
            model_number = choose_model(event, self.rng)
            model = self.vehicle_table[model_number]
            index = self.traffic.add(event, model, state.time, state.x, -state.y, state.v)
            self.recorder.spawned(index + 1)
            self.log("A", "spawn", state, vehicle=index + 1, model=model_number, name=model.name, line=event.line)
        elif isinstance(event, Brake):
            brake_hold = self.inputs.brake_hold
            if not self.model.brk_acts:
                self.warnings.append(f"line {event.line}: BRK ignored: brake events act only with simple dynamics "
                                     "(seed text)")
            elif brake_hold is not None:
                self.warnings.append(f"line {event.line}: BRK ignored: the brake event of line "
                                     f"{brake_hold.event.line} is still on")
            else:
                self.inputs.brake_hold = BrakeHold(event, state.time, state.s, state.v)
                magnitude = event.magnitude if event.threshold == "time" else self._scenario_units(event.magnitude)
                self.log("BRK", "on", state, pedal=event.pedal * 100, threshold=event.threshold,
                         magnitude=magnitude, line=event.line)
        elif isinstance(event, SurfaceAttribute):
            for lane, value in event.settings:
                self.log("RSA", "set", state, lane=lane, value=value, line=event.line)
                if self.options.known_attributes is not None and int(value) not in self.options.known_attributes:
                    self.warnings.append(f"line {event.line}: RSA attribute {int(value)} (lane {lane}) has no entry "
                                         "in the Tire Attribute File: attribute 0 (standard tires) is used")
        elif isinstance(event, EndOfScenario):
            self.finish(state, "scenario")

    def release_brakes(self, state: EgoState, reason: str) -> None:
        """Control returns to the driver model at this instant, its speed integral reset."""
        self.log("BRK", "off", state, reason=reason, line=self.inputs.brake_hold.event.line)
        self.inputs.release_brakes(state)

    def finish(self, state: EgoState, reason: str) -> None:
        """Ends the run; reason: scenario (ES), until_distance, until_time, runout or time_limit."""
        if self.finished:
            return
        if self.inputs.brake_hold is not None:
            self.release_brakes(state, "end")
        self.log("ES", "end", state, reason=reason)
        self.finished = True

    # ---- criticality ------------------------------------------------------------------------------

    def criticality_due(self, t: float, limit: float) -> bool:
        """Whether an extreme could lie in a step from t to at most `limit` (then the step starts from an FMU
        snapshot): a vehicle's look comes due after the instant before which none of its located instants can
        be (Extremes.quiet), a vehicle's footprint leaves the ego's lane, or the ego's front can reach a
        pending PET's conflict area (`pet_horizon`)."""
        return (self.earliest_quiet <= limit and bool(len(self.traffic.active))) \
            or (self.pet_pending and self.pet_due <= limit) \
            or bool(self.leaves_lane) and any(t < leave <= limit for leave in self.leaves_lane.values())

    def look(self, state: EgoState, everyone: bool = False, ahead: float | None = None) -> None:
        """Offers the vehicles whose look has come (all of them: `everyone`) to the record at this
        communication point, keeps their rates (the next step's start) and their next-look instants. With
        `ahead` (a step's end), also the vehicles last looked at before now whose located instants could
        come by then: a look now moves that bound on, and the step may then need no FMU snapshot."""
        t = state.time
        if not everyone and t < self.earliest_look and ahead is None:
            return
        traffic, bounds = self.traffic, self.bounds
        if len(self.next_look) < traffic.size:
            self.next_look = np.concatenate([self.next_look, np.full(traffic.size, NO_LOOK)])
            self.quiet_until = np.concatenate([self.quiet_until, np.full(traffic.size, NO_LOOK)])
            self.look_time = np.concatenate([self.look_time, np.full(traffic.size, NO_LOOK)])
        earliest = earliest_quiet = math.inf
        evaluated, self.evaluated = self.evaluated, {}
        extremes = self.extremes
        for i in traffic.active.tolist():
            instant = float(self.next_look[i])
            if everyone or instant <= t or (ahead is not None and self.quiet_until[i] <= ahead
                                            and self.look_time[i] < t):
                rates, horizon = extremes.look(traffic, i, state, bounds.acceleration, bounds.yaw_rate,
                                               bounds.radius, evaluated.get(i))
                self.look_rates[i] = rates
                instant = self.next_look[i] = t + horizon
                self.quiet_until[i] = t + extremes.quiet
                self.look_time[i] = t
            earliest = min(earliest, instant)
            earliest_quiet = min(earliest_quiet, max(instant, float(self.quiet_until[i])))
        self.earliest_look = earliest
        self.earliest_quiet = earliest_quiet

    def follow_criticality(self, base, t0: float, state: EgoState, everyone: bool) -> None:
        """After a step from t0 to state.time: locates the extremes inside it (from the snapshot `base` at t0;
        without one, an FMU that cannot roll back, they are taken at this communication point, known within
        the step), then looks at the vehicles due (all of them: `everyone`, before something fires)."""
        t1 = state.time
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
        if base is not None:
            self.ego.discard(base)
        self.look(state, everyone)

    def _changes_in_step(self, t0: float, state: EgoState) -> list:
        """What changed inside the step for the vehicles looked at now: (vehicle, rate index) where that rate
        turned from < 0 to >= 0 (a closest approach, a smallest TTC, a largest DRAC, a smallest headway), and
        (vehicle, None) where a collision course began or ended (TTC's rate turned nan or back)."""
        t1 = state.time
        changes = []
        if t1 < self.earliest_look:
            return changes
        for i in self.traffic.active.tolist():
            previous = self.look_rates.get(i)
            if previous is None or self.next_look[i] > t1:
                continue
            evaluated = self.evaluated[i] = self.extremes.evaluate(self.traffic, i, state)
            now = evaluated[1]
            changes += [(i, k) for k in range(4) if previous[k] < 0 <= now[k]]
            if math.isnan(previous[1]) != math.isnan(now[1]):
                changes.append((i, None))
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

        def bisect_instant(low, high, condition) -> tuple[EgoState, EgoState]:
            """(state before, state at) the instant condition turns true in (low, high], true at high."""
            low_state, high_state = None, state
            while high - low > CRITICALITY_TOLERANCE:
                middle = 0.5 * (low + high)
                probed = probe(middle)
                if condition(probed):
                    high, high_state = middle, probed
                else:
                    low, low_state = middle, probed
            return low_state, high_state

        def root_instant(low, high, value, low_value, high_value) -> tuple[EgoState, EgoState]:
            """bisect_instant for `value(state) >= 0` of a rate turning from < 0 at low to >= 0 at high: the
            same bracket to CRITICALITY_TOLERANCE, with fewer probes where the rate is smooth (regula falsi,
            Illinois variant; each estimate kept tolerance / 2 inside the bracket, so that once near the root
            the next probe closes the bracket from the other side; bisection whenever a probe did not halve
            it). While the rate at high is exactly 0 (a flat extreme: the distance to a car passing in the next
            lane, whose rate rises continuously to 0 at the root and stays 0 after it) the secant to high only
            ever points at high: the estimate is then the secant through the last two probes below the root,
            extended to 0, taken FLAT_STEP of the way (or bisection before there are two, and after a probe
            past the root that did not halve the bracket)."""
            low_state, high_state = None, state
            side, halve = 0, False
            rising, earlier = low_value, None  # the rate at low (unscaled), and (instant, rate) of the low before
            while high - low > CRITICALITY_TOLERANCE:
                width = high - low
                slope = high_value - low_value
                guess = 0.5 * (low + high)
                flat = high_value == 0.0
                if halve:
                    pass
                elif flat:
                    if earlier is not None and rising > earlier[1]:
                        extended = low - rising * (low - earlier[0]) / (rising - earlier[1])
                        if extended < high:
                            # FLAT_STEP of the way, to stay below the root (then the next extension is
                            # nearer), and once it is within tolerance / 2, a probe there to close the bracket
                            guess = low + FLAT_STEP * (extended - low)
                elif slope > 0.0 and math.isfinite(slope):
                    guess = low - low_value * width / slope
                guess = min(max(guess, low + 0.5 * CRITICALITY_TOLERANCE), high - 0.5 * CRITICALITY_TOLERANCE)
                probed = probe(guess)
                rate = value(probed)
                if rate >= 0:
                    high, high_state, high_value = guess, probed, rate
                    if side > 0:
                        low_value *= 0.5
                    side = 1
                else:
                    earlier = (low, rising)
                    low, low_state, low_value, rising = guess, probed, rate, rate
                    if side < 0:
                        high_value *= 0.5
                    side = -1
                halve = high - low > 0.5 * width and not (flat and rate < 0)
            return low_state, high_state

        def look_at(i: int, *states) -> None:
            for probed in states:
                if probed is not None:
                    extremes.look(traffic, i, probed, bounds.acceleration, bounds.yaw_rate, bounds.radius)
            self.located += 1

        for i, k in changes:
            if k is None:
                off_course = math.isnan(self.look_rates[i][1])
                before, at = bisect_instant(t0, t1, lambda p, i=i, was=off_course:
                                            math.isnan(extremes.rates(traffic, i, p)[1]) != was)
            else:
                rate_of = (lambda p, i=i: extremes.distance_rate(traffic, i, p)) if k == 0 else \
                    (lambda p, i=i, k=k: extremes.rates(traffic, i, p)[k])
                before, at = root_instant(t0, t1, rate_of,
                                          self.look_rates[i][k], self.evaluated[i][1][k])
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
        front = self._front(state)
        for i in np.flatnonzero(extremes.conflict[:extremes.size] <= front).tolist():
            station = float(extremes.conflict[i])
            start = max(t0, float(extremes.left_path[i]))
            _, reached = bisect_instant(start, t1, lambda p: self._front(p) >= station)
            self._reach(reached)
            self.located += 1
        ego.restore(end)
        ego.discard(end)

    def _transitions_ending(self, t0: float, t1: float) -> list[tuple[int, float]]:
        """(vehicle, instant) of the lateral or speed transitions ending inside (t0, t1], for the vehicles
        followed at every communication point (within criticality.RANGE)."""
        traffic = self.traffic
        ending = []
        for i in self.traffic.active.tolist():
            if self.next_look[i] <= t1 and traffic.duration[i] > 0.0:
                end_time = float(traffic.t0[i] + traffic.duration[i])
                if t0 < end_time <= t1:
                    ending.append((i, end_time))
        return ending

    def _front(self, state: EgoState) -> float:
        """Station of the front of the ego's footprint (criticality.Extremes.reach's)."""
        return state.x + self.bounds.length / 2 * abs(math.cos(state.psi)) \
            + self.bounds.width / 2 * abs(math.sin(state.psi))

    def lane_leave_instant(self, i: int, state: EgoState) -> None:
        """When an action starts vehicle i's lateral move: the instant its footprint leaves the ego's lane
        (criticality.band_times, closed form), where the PET's conflict area is set."""
        traffic, road = self.traffic, self.road
        self.leaves_lane.pop(i, None)
        lane = road.lane_at(-state.y)
        centre = road.lane_center(lane)
        _, leave = band_times(float(traffic.t0[i]), float(traffic.lateral0[i]), float(traffic.lateral1[i]),
                              float(traffic.duration[i]), float(traffic.width[i]), centre - road.lane_width / 2,
                              centre + road.lane_width / 2)
        if state.time < leave < math.inf:
            self.leaves_lane[i] = leave

    def _lane_left(self, i: int, state: EgoState) -> None:
        del self.leaves_lane[i]
        station, _, _ = self.traffic.at(i, state.time)
        self.extremes.path_left(i, state.time, station, float(self.traffic.length[i]), self._front(state))
        self._pending()

    def _reach(self, state: EgoState) -> None:
        self.extremes.reach(state)
        self._pending()

    def _pending(self) -> None:
        stations = self.extremes.pending_stations()
        self.pet_pending = bool(len(stations))
        self.pet_station = float(stations.min()) if len(stations) else math.inf
        self.pet_due = NO_LOOK

    def pet_horizon(self, state: EgoState) -> float:
        """When the ego's front can first reach the pending conflict station: the front's station rate is at
        most the reference point's (which grows at most at the acceleration bound A) plus R r_max (the
        footprint turning), so reach_time(station - front, station rate + R r_max, A) as for event distances."""
        bounds = self.bounds
        station_rate = state.vx * math.cos(state.psi) - state.vy * math.sin(state.psi)
        return state.time + reach_time_scalar(self.pet_station - self._front(state),
                                              station_rate + bounds.radius * bounds.yaw_rate, bounds.acceleration)

    # ---- the result -----------------------------------------------------------------------------

    def result(self, state: EgoState, wall: float) -> RunResult:
        recorder = self.recorder
        columns = recorder.columns()
        final = {"time_s": state.time, "distance": self._scenario_units(state.s),
                 "speed": self._scenario_units(state.v), "lateral": self._scenario_units(-state.y)}
        timing = {"wall_s": wall, "real_time_factor": state.time / wall if wall > 0 else None,
                  "steps": self.steps, "samples": recorder.sample_count}
        model, bounds = self.model, self.bounds
        vehicle = {**model.summary(), "bounds": {
            "acceleration_m/s2": bounds.acceleration, "yaw_rate_rad/s": bounds.yaw_rate,
            "source": model.bounds["source"], "defaults": model.defaulted if model.bounds["acceleration"] is None else []}}
        return RunResult(
            scenario_path=self.scenario.path, units=self.scenario.units, dynamics=model.name, vehicle=vehicle,
            friction_meaning=model.surface_meaning,
            seed=self.options.seed, road=self.road, columns=columns,
            vehicles=recorder.vehicle_tracks(self.traffic, columns["time"]),
            events=self.events, collisions=self.collisions, collision_points=self.collision_points,
            surfaces=surface_sections(self.surfaces), warnings=self.warnings, final=final, timing=timing,
            criticality=self.criticality_summary(),
            ttc_series=partial(ttc_series, self.traffic, *recorder.spans(), self.bounds, columns),
        )

    def criticality_summary(self) -> dict:
        """summary.json's `criticality` (SPEC §5), lengths in the scenario's units; with an FMU that cannot roll
        back, how exactly its instants are known (`time_uncertainty_s`, as on the events)."""
        summary = self.extremes.summary(self.recorder.vehicle_ids, self._scenario_units)
        if not self.exact:
            summary["time_uncertainty_s"] = self.criticality_uncertainty
        return summary


def run_scenario(scenario: Scenario, model: EgoModel | Path, options: RunOptions,
                 vehicle_table: dict[int, VehicleModel]) -> RunResult:
    """Co-simulates a parsed scenario against an ego vehicle and returns what happened (SI inside)."""
    return Cosimulation(scenario, model, options, vehicle_table).run()
