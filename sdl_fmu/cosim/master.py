"""The co-simulation master: steps the ego FMU through fmpy together with the road, the BRK
controller, the driver model and the traffic model, and fires every trigger at its true instant,
whatever the communication step.

Before each step the master bounds, from the ego's kinematics and its acceleration and yaw-rate limits
(triggers.py), the earliest instant at which any trigger (an event distance, a BRK threshold, a closure
time, a contact starting or ending, a departure, a wheel crossing onto another surface) could become
true. Where nothing can happen it steps long: to the next driver sample, the `step` limit or that
instant, whichever is first. Within MIN_LOOKAHEAD of a possible trigger it steps from a saved FMU state
and, if a trigger became true inside the step, rolls back and bisects (fmi2GetFMUstate /
fmi2SetFMUstate) until the instant is known within TIME_TOLERANCE. Traffic motion is closed-form in
time, so it needs no rollback of its own. The driver model is a sampled controller with its own period
(`driver_period`): its samples are instants the master steps to, independent of `step`.
"""

from __future__ import annotations

import bisect
import math
import random
import time as wall_clock
from array import array
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Callable

import numpy as np

from ..run_result import RunResult, VehicleTracks
from ..sdl.events import ApproachingVehicle, Brake, EndOfScenario, Scenario, SurfaceAttribute
from ..sdl.vehicles import VehicleModel
from ..units import FOOT, from_si
from .brake import BrakeHold
from .criticality import RANGE, Extremes, Footprint, band_times, conflict_far_end, distances, passage_known, ttcs
from .driver import MAX_STEER, make_driver
from ..vehicle import EgoModel, EgoState, shipped_map_path
from .ego import step_until_time
from ..storage import release_pages
from .recorder import ChunkedTable, EventLog
from .road import surface_map, surface_sections, wheel_geometry, wheel_surfaces
from .traffic import Traffic, choose_model
from .triggers import (EgoKinematics, ego_bounds, reach_time_scalar, vehicle_condition,
                       vehicle_conditions, vehicle_horizon, vehicle_horizons, vehicle_triggered)

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
SURFACE_WINDOW = 1.0  # s, how far ahead lane edges between differing surfaces are looked for
# up to this many vehicles are checked one by one in plain floats, more at once in NumPy arrays: on a few
# vehicles NumPy's per-operation overhead (about 1 µs on small arrays) costs more than the arithmetic
SCALAR_VEHICLES = 4
DEFAULT_DRIVER_PERIOD = 0.05  # s, the driver model's sampling period (20 Hz)
DEFAULT_STEP = 1.0  # s, longest communication step (the driver's samples and the triggers cut it shorter)
RELEASE_ROWS = 20_000  # sample rows read from a disk-backed table between releases of its pages (~3.5 MB)

# record() copies the state's fields in their order, then these, then the model's wheel columns
EGO_COLUMNS = (*EgoState._fields, "station", "lateral", "throttle", "brake", "steer", "brk")
STOPPED = EgoState._fields.index("stopped")


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
        self.surface_changes = _surface_changes(self.surfaces)
        self.surface_next = -math.inf  # cached lower bound on the next surface change under a wheel
        self.traffic_earliest = -math.inf  # cached min of the vehicles' bounds (valid until something fires)
        self.cached_bounds: dict[str, float] = {}  # event, end, brake: bounds kept until something fires
        self._differing: dict[tuple[int, int], tuple[list[float], list[float]]] = {}
        self._edges: dict[tuple[int, int], list] = {}  # see _lane_edges
        self.speed = DEFAULT_SPEED if options.speed is None else options.speed
        start_lateral = self.road.lane_center(1)
        self.ego = model.instantiate(start={"speed": self.speed, "x": 0.0, "y": -start_lateral, "yaw": 0.0})
        self.geometry = wheel_geometry(model)
        self.driver = make_driver(self.speed, start_lateral, model)
        self.wheel_columns = model.wheel_columns
        mu_max = model.peak_friction([v for values in self.surfaces.values.values() for v in values])
        wheel_arm = max(math.hypot(x, y) for x, y in model.wheels)
        self.bounds = ego_bounds(model, mu_max, self.speed, wheel_arm, MAX_STEER)
        self.events_in_order = scenario.events
        self.next_event = 0  # index of the first event not yet fired
        self.traffic = Traffic()
        self.vehicle_ids = array("q")  # per vehicle (index = id - 1), its id
        self.brake_hold: BrakeHold | None = None
        self.applied_surfaces: tuple[float, ...] | None = None
        self.wheel_values: tuple[float, ...] = ()  # the FMU's wheel inputs for the applied surfaces
        self.controls = (0.0, 0.0, 0.0)
        self.sent_controls: tuple | None = None
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
        self.bounds_exceeded = False  # whether the ego ever left the bounds of the trigger prediction
        self.collisions = 0
        self.collision_points: list[tuple[float, float]] = []
        self.ego_rows = ChunkedTable(len(EGO_COLUMNS) + len(self.wheel_columns))
        # per vehicle, its first sample and the sample it left at (-1 while on the road); compact arrays
        self.spawn_sample = array("q")
        self.leave_sample = array("q")
        self.sample_count = 0
        self.steps = 0
        self.finished = False
        self.end_distance, self.end_reason = self._end_distance()
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
        self.enters_lane: dict[int, float] = {}  # per vehicle, the instant its footprint will enter the ego's lane
        self.pet_pending = False  # whether a PET waits for the ego's front to reach its conflict area
        self.pet_station = math.inf  # the nearest such area's station
        self.pet_due = NO_LOOK  # a lower bound on when the ego's front can reach it (NO_LOOK: to be computed)
        self.evaluated: dict[int, tuple] = {}  # per vehicle, its evaluation at the step's end (rates read)
        self.criticality_uncertainty = 0.0
        self.located = 0  # instants located inside steps (probed from a saved FMU state)
        self.touched: set[int] = set()  # the vehicles something fired for at this instant (looked at after)

    # ---- scenario units at the results boundary -------------------------------------------------

    def _scenario_units(self, value: float) -> float:
        return from_si(value, self.scenario.units)

    def log(self, code: str, action: str, state: EgoState, **extra) -> None:
        entry = {"code": code, "action": action, "time_s": state.time, "distance": self._scenario_units(state.s),
                 "speed": self._scenario_units(state.v), "lateral": self._scenario_units(-state.y), **extra}
        if not self.exact:
            entry["time_uncertainty_s"] = self.time_uncertainty
        self.events.append(entry)

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

    # ---- the ego's surroundings at an instant ---------------------------------------------------

    def surfaces_under_wheels(self, state: EgoState) -> tuple[float, ...]:
        return wheel_surfaces(self.road, self.surfaces, self.geometry.contact_points(state.x, state.y, state.psi))

    def pending_distance(self) -> float:
        if self.next_event < len(self.events_in_order):
            return self.events_in_order[self.next_event].distance
        return math.inf

    # ---- when the next trigger could be ---------------------------------------------------------

    def horizons(self, state: EgoState, limit: float) -> dict[str, float]:
        """Per kind of trigger, a lower bound on the instant it could become true (absolute time). A bound
        holds until it is reached or something fires (the bounds on the ego hold at all times), so each is
        kept and recomputed only when it could bind before `limit`."""
        a = self.bounds.acceleration
        t = state.time
        cached = self.cached_bounds
        near = {}
        if self.next_event < len(self.events_in_order):
            bound = cached.get("event", -math.inf)
            if bound < limit:
                distance = self.events_in_order[self.next_event].distance
                bound = cached["event"] = t + reach_time_scalar(distance - state.s, state.v, a)
            near["event"] = bound
        if self.end_distance < math.inf:
            bound = cached.get("end", -math.inf)
            if bound < limit:
                bound = cached["end"] = t + reach_time_scalar(self.end_distance - state.s, state.v, a)
            near["end"] = bound
        if self.brake_hold is not None:
            bound = cached.get("brake", -math.inf)
            if bound < limit:
                bound = cached["brake"] = self.brake_hold.earliest_release(state, a)
            near["brake"] = bound
        if self.surface_changes:
            if self.surface_next < limit:
                self.surface_next = t + self.surface_horizon(state)
            near["surface"] = self.surface_next
        if len(self.traffic.active):
            near["traffic"] = self.traffic_horizon(state, limit)
        return near

    def surface_horizon(self, state: EgoState) -> float:
        """How long every wheel surely stays on its surface: the nearest station in its lane where the value
        changes, and its lane's edges where the lane beyond differs within the reach of SURFACE_WINDOW (a
        bound then valid for that window only), each reached at the ego's bounded rates."""
        kin = EgoKinematics.of(state)
        station_rate, lateral_rate = kin.station_rate, kin.lateral_rate
        bounds, road = self.bounds, self.road
        a = bounds.acceleration
        turn = bounds.wheel_arm * bounds.yaw_rate
        width = road.lane_width
        reach = (abs(station_rate) + turn) * SURFACE_WINDOW + a * SURFACE_WINDOW**2 / 2
        horizon = SURFACE_WINDOW
        for station, lateral in self.geometry.contact_points(state.x, state.y, state.psi):
            lane = road.lane_at(lateral)
            changes = self.surface_changes.get(lane)
            if changes:
                k = bisect.bisect_right(changes, station)
                if k < len(changes):
                    horizon = min(horizon, reach_time_scalar(changes[k] - station, station_rate + turn, a))
                if k > 0:
                    horizon = min(horizon, reach_time_scalar(station - changes[k - 1], -station_rate + turn, a))
            for edge, side, (starts, ends) in self._lane_edges(math.floor(lateral / width), lane):
                # the lanes differ somewhere between station -+ reach: a stretch starts at or before the
                # upper end and ends after the lower
                k = bisect.bisect_right(starts, station + reach)
                if k > 0 and ends[k - 1] > station - reach:
                    horizon = min(horizon, reach_time_scalar(abs(edge - lateral), side * lateral_rate + turn, a))
        return horizon

    def _lane_edges(self, k: int, lane: int) -> list:
        """For a wheel in `lane` between the lines k w and (k + 1) w: those of the two lines whose lane beyond
        differs from `lane` somewhere, as (line, side toward it, (starts, ends) of the stretches where the
        two lanes differ). Worked out once per (k, lane) and per pair of lanes."""
        edges = self._edges.get((k, lane))
        if edges is None:
            road, width = self.road, self.road.lane_width
            edges = []
            for edge, side in ((k * width, -1.0), ((k + 1) * width, 1.0)):
                if not road.left_edge <= edge <= road.right_edge:
                    continue  # beyond the shoulders' outer edges nothing changes
                beyond = road.lane_at(edge + side * width / 2)
                if beyond != lane:
                    key = (min(lane, beyond), max(lane, beyond))
                    if key not in self._differing:
                        self._differing[key] = _differing_stretches(self.surfaces, *key)
                    if self._differing[key][0]:
                        edges.append((edge, side, self._differing[key]))
            self._edges[(k, lane)] = edges
        return edges

    def traffic_horizon(self, state: EgoState, limit: float) -> float:
        """The earliest instant any vehicle on the road could trigger something. Each vehicle's bound is
        kept until it could bind (it holds while the vehicle's own motion is unchanged); only those are
        recomputed, vectorised (a few vehicles in plain floats, see SCALAR_VEHICLES)."""
        if self.traffic_earliest >= limit:  # no vehicle's bound can bind before the limit: nothing to redo
            return self.traffic_earliest
        traffic = self.traffic
        active = traffic.active
        if len(active) <= SCALAR_VEHICLES:
            checks = traffic.next_check[active].tolist()
            kinematics = None
            for k, i in enumerate(active.tolist()):
                if checks[k] < limit:
                    if kinematics is None:
                        kinematics = EgoKinematics.of(state)
                    checks[k] = state.time + vehicle_horizon(traffic, i, kinematics, self.bounds)
                    traffic.next_check[i] = checks[k]
            self.traffic_earliest = min(checks)
            return self.traffic_earliest
        stale = active[traffic.next_check[active] < limit]
        if 0 < len(stale) <= SCALAR_VEHICLES:
            kinematics = EgoKinematics.of(state)
            for i in stale.tolist():
                traffic.next_check[i] = state.time + vehicle_horizon(traffic, i, kinematics, self.bounds)
        elif len(stale):
            traffic.next_check[stale] = state.time + vehicle_horizons(traffic, stale, EgoKinematics.of(state),
                                                                      self.bounds)
        self.traffic_earliest = float(traffic.next_check[active].min())
        return self.traffic_earliest

    def triggered(self, state: EgoState, kinds) -> bool:
        """Whether a trigger of the given kinds is true at this state (all are false at a step's start)."""
        if "event" in kinds and self.pending_distance() <= state.s:
            return True
        if "end" in kinds and state.s >= self.end_distance:
            return True
        if "brake" in kinds and self.brake_hold.release_reason(state):
            return True
        if "surface" in kinds and self.surfaces_under_wheels(state) != self.applied_surfaces:
            return True
        if "traffic" in kinds:
            traffic = self.traffic
            active = traffic.active
            if len(active) <= SCALAR_VEHICLES:  # (the bisection's probes: a NumPy selection costs more here)
                due = [i for i, check in zip(active.tolist(), traffic.next_check[active].tolist()) if check <= state.time]
            else:
                due = active[traffic.next_check[active] <= state.time]
            if 0 < len(due) <= SCALAR_VEHICLES:
                kinematics = EgoKinematics.of(state)
                return any(vehicle_triggered(traffic, int(i), kinematics, self.bounds) for i in due)
            if len(due):
                action, overlap, away = vehicle_conditions(traffic, due, EgoKinematics.of(state), self.bounds)
                in_contact = traffic.in_contact[due]
                return bool((action | (overlap != in_contact) | (away & ~in_contact)).any())
        return False

    # ---- what happens at an instant -------------------------------------------------------------

    def fire_due(self, state: EgoState) -> None:
        """Fires everything due at this state, in file order, until nothing more is due."""
        while self.next_event < len(self.events_in_order) and self.pending_distance() <= state.s \
                and not self.finished:
            self.next_event += 1
            self.fire_event(self.events_in_order[self.next_event - 1], state)
        if self.brake_hold is not None:
            reason = self.brake_hold.release_reason(state)
            if reason:
                self.release_brakes(state, reason)
        if len(self.traffic.active):
            self.fire_traffic(state)
        if state.s >= self.end_distance:
            self.finish(state, self.end_reason)

    def vehicle_conditions(self, idx: np.ndarray, kinematics: EgoKinematics):
        """(action due, overlap, may leave) of vehicles idx as boolean arrays; a few in plain floats."""
        if len(idx) > SCALAR_VEHICLES:
            return vehicle_conditions(self.traffic, idx, kinematics, self.bounds)
        rows = [vehicle_condition(self.traffic, i, kinematics, self.bounds) for i in idx.tolist()]
        return tuple(np.array([row[k] for row in rows], dtype=bool) for k in range(3))

    def fire_traffic(self, state: EgoState) -> None:
        traffic = self.traffic
        kinematics = EgoKinematics.of(state)
        active = traffic.active
        action, overlap, away = self.vehicle_conditions(active, kinematics)
        if action.any():
            for i in active[action]:
                self.look_before_change(int(i), state)
                while True:  # each action once, the next armed as the previous fires; several may be due at once
                    index = int(traffic.next_action[i]) + 1
                    traffic.start_action(i, state.time, -state.y, state.v)
                    self.log("A", "maneuver", state, vehicle=self.vehicle_ids[i], index=index)
                    self.lane_leave_instant(int(i), state)
                    if not vehicle_condition(traffic, int(i), kinematics, self.bounds)[0]:
                        break
            _, overlap, away = self.vehicle_conditions(active, kinematics)
        for i in active[overlap & ~traffic.in_contact[active]]:
            self.collisions += 1
            station, lateral, _ = traffic.at(i, state.time)
            self.collision_points.append(((state.x + station) / 2, (-state.y + lateral) / 2))
            self.log("A", "collision", state, vehicle=self.vehicle_ids[i])
        changed = active[overlap != traffic.in_contact[active]]
        traffic.in_contact[active] = overlap
        traffic.next_check[changed] = state.time
        self.touched.update(changed.tolist())
        for i in active[away & ~overlap]:
            self.look_before_change(int(i), state)
            traffic.remove(i)
            self.leave_sample[i] = self.sample_count
            self.log("A", "despawn", state, vehicle=self.vehicle_ids[i])

    def fire_event(self, event, state: EgoState) -> None:
        if isinstance(event, ApproachingVehicle):
            model_number = choose_model(event, self.rng)
            model = self.vehicle_table[model_number]
            index = self.traffic.add(event, model, state.time, state.x, -state.y, state.v)
            self.touched.add(index)
            self.vehicle_ids.append(index + 1)
            self.spawn_sample.append(self.sample_count)
            self.leave_sample.append(-1)
            self.log("A", "spawn", state, vehicle=index + 1, model=model_number, name=model.name, line=event.line)
        elif isinstance(event, Brake):
            if not self.model.brk_acts:
                self.warnings.append(f"line {event.line}: BRK ignored: brake events act only with simple dynamics "
                                     "(seed text)")
            elif self.brake_hold is not None:
                self.warnings.append(f"line {event.line}: BRK ignored: the brake event of line "
                                     f"{self.brake_hold.event.line} is still on")
            else:
                self.brake_hold = BrakeHold(event, state.time, state.s, state.v)
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
        self.log("BRK", "off", state, reason=reason, line=self.brake_hold.event.line)
        self.brake_hold = None
        self.driver.reset_integral()
        throttle, brake = self.driver.pedals(state)
        self.controls = (throttle, brake, self.controls[2])

    def finish(self, state: EgoState, reason: str) -> None:
        """Ends the run; reason: scenario (ES), until_distance, until_time, runout or time_limit."""
        if self.finished:
            return
        if self.brake_hold is not None:
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
            self.next_look = np.concatenate([self.next_look, np.full(traffic.size, NO_LOOK)])
            self.quiet_until = np.concatenate([self.quiet_until, np.full(traffic.size, NO_LOOK)])
            self.look_time = np.concatenate([self.look_time, np.full(traffic.size, NO_LOOK)])
        earliest = earliest_quiet = math.inf
        evaluated, self.evaluated = self.evaluated, {}
        extremes = self.extremes
        if only is not None:
            # the others' instants are kept: the earliest so far stays a bound (at worst early: then a look
            # finds nothing due and recomputes it over every vehicle)
            earliest, earliest_quiet = self.earliest_look, self.earliest_quiet
            everyone = True
        for i in (traffic.active.tolist() if only is None else sorted(i for i in only if traffic.present[i])):
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

        def bisect_instant(low, high, condition, known=None) -> tuple[EgoState, EgoState]:
            """(state before, state at) the instant condition turns true in (low, high], true at high. With
            `known(middle, (instant, state) probed last below, (instant, state) probed last above)`, a test that
            is True or False where it can tell the condition without a probe (None: a probe): the same
            midpoints and outcomes, fewer probes, and the state at the final high probed once if it was not
            (the state before is then that of the last probe below)."""
            low_state, high_state = None, state
            below, above = (low, None), (high, state)
            while high - low > CRITICALITY_TOLERANCE:
                middle = 0.5 * (low + high)
                outcome = None if known is None else known(middle, below, above)
                probed = None
                if outcome is None:
                    probed = probe(middle)
                    outcome = condition(probed)
                if outcome:
                    high, high_state = middle, probed
                    if probed is not None:
                        above = (middle, probed)
                else:
                    low, low_state = middle, probed
                    if probed is not None:
                        below = (middle, probed)
            if high_state is None:
                high_state = probe(high)
            return below[1] if known is not None else low_state, high_state

        turn, acceleration = bounds.radius * bounds.yaw_rate, bounds.acceleration

        def passage(position, station: float):
            """`known` for `position(p) >= station`, position the station of the ego's front or rear."""
            def known(middle, below, above):
                (low, low_state), (high, high_state) = below, above
                return passage_known(middle, low, None if low_state is None else position(low_state),
                                     0.0 if low_state is None else _station_rate(low_state), high,
                                     position(high_state), _station_rate(high_state), station, turn, acceleration)
            return known

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

    def _rear(self, state: EgoState) -> float:
        """Station of the rear of the ego's footprint."""
        return state.x - self.bounds.length / 2 * abs(math.cos(state.psi)) \
            - self.bounds.width / 2 * abs(math.sin(state.psi))

    def lane_leave_instant(self, i: int, state: EgoState) -> None:
        """When an action starts vehicle i's lateral move: the instants its footprint leaves and enters the ego's
        lane (criticality.band_times, closed form), where the PET's conflict areas are set (the vehicle
        leaving first; the ego leaving first: the far end of the area the vehicle will enter)."""
        traffic, road = self.traffic, self.road
        self.leaves_lane.pop(i, None)
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
        ego's rear had left the area first (criticality.Extremes.path_entered); none for a vehicle that left the
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

    def pet_horizon(self, state: EgoState) -> float:
        """When the ego's front can first reach the pending conflict station: the front's station rate is at
        most the reference point's (which grows at most at the acceleration bound A) plus R r_max (the
        footprint turning), so reach_time(station - front, station rate + R r_max, A) as for event distances."""
        bounds = self.bounds
        station_rate = state.vx * math.cos(state.psi) - state.vy * math.sin(state.psi)
        return state.time + reach_time_scalar(self.pet_station - self._front(state),
                                              station_rate + bounds.radius * bounds.yaw_rate, bounds.acceleration)

    # ---- inputs and records ---------------------------------------------------------------------

    def sample_driver(self, state: EgoState, period: float | None) -> None:
        """A driver sample: integrate the speed error over the period (not while BRK holds the pedals),
        then new steer and, unless BRK holds them, new pedals."""
        driver, controls = self.driver, self.controls
        if self.brake_hold is None:
            if period is not None:
                driver.update(state, period, controls[0])
            throttle, brake = driver.pedals(state)
        else:
            throttle, brake = controls[0], controls[1]
        self.controls = (throttle, brake, driver.steer(state))

    def apply_inputs(self, state: EgoState, surfaces_may_change: bool) -> None:
        """Pedals (BRK's while it holds them), steer and the surfaces under the wheels, sent if changed."""
        if self.brake_hold is not None:
            self.controls = (0.0, self.brake_hold.event.pedal, self.controls[2])
        if surfaces_may_change or self.applied_surfaces is None:
            surfaces = self.surfaces_under_wheels(state)
            if surfaces != self.applied_surfaces:
                self.applied_surfaces = surfaces
                values = self.model.wheel_values(surfaces)
                if values != self.wheel_values:
                    self.ego.set_friction(values)
                    self.wheel_values = values
        controls = self.controls
        if controls != self.sent_controls:
            self.ego.set_controls(*controls)
            self.sent_controls = controls

    def record(self, state: EgoState) -> None:
        bounds = self.bounds
        if not self.bounds_exceeded and (abs(state.yaw_rate) > bounds.yaw_rate
                                         or math.hypot(state.ax, state.ay) > bounds.acceleration):
            # the trigger predictions rest on these bounds: say so rather than silently risk a late trigger
            self.bounds_exceeded = True
            self.warnings.append(
                f"at t = {state.time:.3f} s the ego's yaw rate ({state.yaw_rate:.3g} rad/s) or acceleration "
                f"({math.hypot(state.ax, state.ay):.3g} m/s2) exceeded the bounds the trigger prediction assumes "
                f"({self.bounds.yaw_rate:.3g} rad/s, {self.bounds.acceleration:.3g} m/s2): later triggers may be "
                "located late; rerun with a shorter --step")
        # EGO_COLUMNS: the state's fields in their order (time ... yaw_rate, stopped), station, lateral, the
        # controls, brk, then the wheel inputs
        self.ego_rows.append((*state[:STOPPED], float(state.stopped), state.x, -state.y, *self.controls,
                              float(self.brake_hold is not None), *self.wheel_values))
        self.sample_count += 1  # traffic is closed-form in time: its samples are computed at the end

    # ---- the loop -------------------------------------------------------------------------------

    def run(self) -> RunResult:
        started = wall_clock.perf_counter()
        try:
            state = self.ego.read()
            self.fire_due(state)
            self.look(state, everyone=True)
            self.touched.clear()
            self.sample_driver(state, None)
            self.apply_inputs(state, True)
            self.record(state)
            ego, step, progress = self.ego, self.options.step, self.options.progress
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
                    horizons = self.horizons(state, limit)
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
                    fired = earliest <= end and self.triggered(
                        state, [kind for kind, instant in horizons.items() if instant <= end])
                    self.time_uncertainty = 0.0
                else:
                    end = min(t + MIN_LOOKAHEAD, limit)
                    kinds = [kind for kind, instant in horizons.items() if instant <= end]
                    if self.exact:
                        fired = step_until_time(ego, end, lambda probe: self.triggered(probe, kinds), TIME_TOLERANCE)
                    else:  # what became true did so somewhere in (t, end]
                        ego.step_to(end)
                        fired = self.triggered(ego.read(), kinds)
                        self.time_uncertainty = end - t
                    state = ego.read()
                self.steps += 1
                driver_sample = state.time >= next_sample
                if base is not None or fired or state.time >= self.earliest_look or not self.exact:
                    self.follow_criticality(base, t, state, everyone=False)
                if fired:
                    self.fire_due(state)
                    self.traffic_earliest = -math.inf  # spawns, actions, contacts, departures: bounds changed
                    self.cached_bounds.clear()  # the next event, a BRK on or off
                    earliest = -math.inf  # the kinds of trigger and their bounds are recomputed next step
                    self.look(state, only=self.touched)  # the changed motions from this instant on
                    self.touched.clear()
                if until_time is not None and state.time >= until_time:
                    self.finish(state, "until_time")
                if driver_sample:
                    self.sample_driver(state, period)
                    while next_sample <= state.time:
                        sample += 1
                        next_sample = sample * period
                self.apply_inputs(state, fired)  # the inputs from this instant on, as recorded with it
                self.record(state)
                if progress is not None:
                    progress(self, state)
            self.look(state, everyone=True)  # an extreme at the end of the run
            wall = wall_clock.perf_counter() - started
            return self.result(state, wall)
        finally:
            self.ego.close()

    def result(self, state: EgoState, wall: float) -> RunResult:
        names = [*EGO_COLUMNS, *self.wheel_columns]
        table = self.ego_rows.finish()
        columns = {name: table[:, i] for i, name in enumerate(names)}
        final = {"time_s": state.time, "distance": self._scenario_units(state.s),
                 "speed": self._scenario_units(state.v), "lateral": self._scenario_units(-state.y)}
        timing = {"wall_s": wall, "real_time_factor": state.time / wall if wall > 0 else None,
                  "steps": self.steps, "samples": self.sample_count}
        model, bounds = self.model, self.bounds
        vehicle = {**model.summary(), "bounds": {
            "acceleration_m/s2": bounds.acceleration, "yaw_rate_rad/s": bounds.yaw_rate,
            "source": model.bounds["source"], "defaults": model.defaulted if model.bounds["acceleration"] is None else []}}
        return RunResult(
            scenario_path=self.scenario.path, units=self.scenario.units, dynamics=model.name, vehicle=vehicle,
            friction_meaning=model.surface_meaning,
            seed=self.options.seed, road=self.road, columns=columns, vehicles=self.vehicle_tracks(columns["time"]),
            events=self.events, collisions=self.collisions, collision_points=self.collision_points,
            surfaces=surface_sections(self.surfaces), warnings=self.warnings, final=final, timing=timing,
            criticality=self.criticality_summary(),
            ttc_series=partial(ttc_series, self.traffic, np.array(self.spawn_sample, dtype=np.int64),
                               np.array(self.leave_sample, dtype=np.int64), self.bounds, columns),
        )

    def criticality_summary(self) -> dict:
        """summary.json's `criticality` (SPEC §5), lengths in the scenario's units; with an FMU that cannot roll
        back, how exactly its instants are known (`time_uncertainty_s`, as on the events)."""
        summary = self.extremes.summary(self.vehicle_ids, self._scenario_units)
        if not self.exact:
            summary["time_uncertainty_s"] = self.criticality_uncertainty
        return summary

    def vehicle_tracks(self, times: np.ndarray) -> VehicleTracks:
        """Each vehicle's samples from its closed-form motion, from its spawn to the sample it left at, into
        one disk-backed table; the sample times are read in order and their pages released as it goes
        (memory stays bounded)."""
        first = np.array(self.spawn_sample, dtype=np.int64)
        last = np.array(self.leave_sample, dtype=np.int64)
        last[last < 0] = self.sample_count  # still on the road at the end
        track_rows = ChunkedTable(3)
        unreleased = 0
        for i in range(len(first)):
            track_rows.extend(np.column_stack(self.traffic.track(i, np.asarray(times[first[i]:last[i]]))))
            unreleased += last[i] - first[i]
            if unreleased > RELEASE_ROWS:
                release_pages(times)
                unreleased = 0
        release_pages(times)
        offsets = np.concatenate([[0], np.cumsum(last - first)])
        return VehicleTracks(track_rows.finish(), np.array(self.vehicle_ids, dtype=np.int64), self.traffic.models,
                             first, offsets)


def _station_rate(state: EgoState) -> float:
    """The ego's reference point's station rate (m/s): its body-frame velocity turned by psi."""
    return state.vx * math.cos(state.psi) - state.vy * math.sin(state.psi)


def ttc_series(traffic: Traffic, first: np.ndarray, last: np.ndarray, bounds, columns: dict) -> np.ndarray:
    """Per sample, the smallest time to collision over the vehicles within RANGE (s; nan where no vehicle is on
    a collision course): the plot's TTC curve, from the samples and the vehicles' closed-form motions (each
    vehicle from its first sample to the one it left at, -1: still on the road), computed when asked for
    (RunResult.ttc_series), not during the run; not part of timeseries.csv."""
    times = np.asarray(columns["time"])
    series = np.full(len(times), np.inf)
    last = np.where(last < 0, len(times), last)
    for i in range(len(first)):
        rows = slice(first[i], last[i])
        t = times[rows]
        motions = traffic.history(i)
        k = np.maximum(np.searchsorted(motions[:, 0], t, side="right") - 1, 0)
        t0, _, lateral0, _, lateral1, _, duration = motions[k].T
        moving = t - t0 < duration
        lateral_rate = np.where(moving, (lateral1 - lateral0) / np.where(moving, duration, 1.0), 0.0)
        station, lateral, speed = traffic.track(i, t)
        dx, dy = station - np.asarray(columns["x"][rows]), -lateral - np.asarray(columns["y"][rows])
        length, width = float(traffic.length[i]), float(traffic.width[i])
        # only where the centres are within RANGE plus both footprints' radii can the footprints be
        near = np.flatnonzero(np.sqrt(dx * dx + dy * dy) <= RANGE + bounds.radius
                              + 0.5 * math.sqrt(length * length + width * width))
        if not len(near):
            continue
        dx, dy = dx[near], dy[near]
        psi = np.asarray(columns["psi"][rows])[near]
        c, s = np.cos(psi), np.sin(psi)
        vx, vy = np.asarray(columns["vx"][rows])[near], np.asarray(columns["vy"][rows])[near]
        ego = Footprint(bounds.length / 2, bounds.width / 2, c, s)
        value = ttcs(ego, dx, dy, -speed[near] - (vx * c - vy * s), -lateral_rate[near] - (vx * s + vy * c),
                     length, width)
        value = np.where(distances(ego, dx, dy, length, width) <= RANGE, value, np.inf)
        index = near + first[i]
        series[index] = np.minimum(series[index], value)
    series[~np.isfinite(series)] = np.nan
    return series


def _differing_stretches(surfaces, lane: int, other: int) -> tuple[list[float], list[float]]:
    """(starts, ends) of the stretches of road where two lanes' surface values differ, in station order,
    disjoint (adjacent ones merged); an end may be inf."""
    stations = sorted({*surfaces.starts.get(lane, []), *surfaces.starts.get(other, [])})
    starts, ends = [], []
    for k, station in enumerate(stations):
        end = stations[k + 1] if k + 1 < len(stations) else math.inf
        if surfaces.value(lane, station) != surfaces.value(other, station):
            if ends and ends[-1] == station:
                ends[-1] = end
            else:
                starts.append(station)
                ends.append(end)
    return starts, ends


def _surface_changes(surfaces) -> dict[int, list[float]]:
    """Per lane, the stations where its surface value actually changes (a value set again is no change)."""
    changes = {}
    for lane, starts in surfaces.starts.items():
        previous, stations = surfaces.default, []
        for start, value in zip(starts, surfaces.values[lane]):
            if value != previous:
                stations.append(start)
            previous = value
        if stations:
            changes[lane] = stations
    return changes


def run_scenario(scenario: Scenario, model: EgoModel | Path, options: RunOptions,
                 vehicle_table: dict[int, VehicleModel]) -> RunResult:
    """Co-simulates a parsed scenario against an ego vehicle and returns what happened (SI inside)."""
    return Cosimulation(scenario, model, options, vehicle_table).run()
