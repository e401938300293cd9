"""The co-simulation master: steps the ego FMU through fmpy together with the road, the BRK
controller, the driver model and the traffic model, and fires every trigger at its true instant,
whatever the communication step.

The run is a loop (`Cosimulation.run`, in the shape of FMPy's simulateCS) over four helpers, each in its
own module:
- `TriggerSchedule` (schedule.py): before each step, lower bounds from the ego's kinematics and its
  acceleration and yaw-rate limits (triggers.py) on the earliest instant at which any trigger (an event
  distance, a BRK threshold, a closure time, a contact starting or ending, a departure, a wheel crossing onto
  another surface) could become true, and whether one is true at a state;
- `Inputs` (inputs.py): the driver's (or BRK's) pedals, the steer and the surfaces under the wheels;
- `Recorder` (recorder.py): the samples;
- `CriticalityFollower` (follower.py): the criticality record (extremes.py) and the extremes located inside
  steps; the loop asks it whether a step needs an FMU snapshot (`wants_snapshot`) and tells it the step's end
  (`stepped`).
Where nothing can happen the loop steps long (`advance`): to the next driver sample, the `step` limit or the
earliest trigger bound, whichever is first. Within MIN_LOOKAHEAD of a possible trigger it steps from a saved FMU
state and, if a trigger became true inside the step, rolls back and bisects (fmi2GetFMUstate / fmi2SetFMUstate)
until the instant is known within TIME_TOLERANCE (locate.py); then it fires what is due (`fire`, and the
handlers beside it). Traffic motion is closed-form in time, so it needs no rollback of its own. The driver model is
a sampled controller with its own period (`driver_period`), and so are the follow driver's decisions and a controller
FMU in the loop (clocks.py): their samples are instants the master steps to, independent of `step`, so none of them
is stepped or read inside a located step.
"""

from __future__ import annotations

import math
import random
import time as wall_clock
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Callable, Literal

from ..options import DEFAULT_DRIVER_PERIOD, DEFAULT_SPEED, DEFAULT_STEP, MAX_TIME
from ..results import RunRecord
from ..results.storage import EventLog
from ..sdl.checks import attribute_without_tire, brk_ignored, rsa_without_effect
from ..sdl.events import ApproachingVehicle, Brake, EndOfScenario, Scenario, SurfaceAttribute
from ..sdl.vehicles import VehicleModel
from ..units import FOOT
from ..vehicle import Dynamics, EgoModel, EgoState, shipped_map_path
from ..vehicle.controller import ControllerModel
from .brake import BrakeHold
from .closing import ClosingEnd
from .clocks import SampleClocks
from .driver import MAX_STEER, make_driver
from .effects import action_warnings, brake_warnings, ineffective, unreached_warnings
from .ego import step_until_time
from .follow import REACTION_TIME, FollowDriver
from .follower import CriticalityFollower
from .inputs import CONTROLLER_COLUMNS, Inputs
from .locate import CRITICALITY_TOLERANCE, TIME_TOLERANCE  # noqa: F401 (CRITICALITY_TOLERANCE: the master's API)
from .recorder import Recorder, lead_series, ttc_series
from .road import surface_map, surface_sections, wheel_geometry
from .schedule import TriggerSchedule
from .signals import lead_of
from .traffic import Traffic, choose_model
from .triggers import EgoKinematics, ego_bounds

RUNOUT = 1000 * FOOT  # m driven past the last event when neither ES nor --until ends the run
# s: closer than this to a possible trigger the master steps this far from a saved state and bisects;
# a trigger cannot become true and false again within it (contacts last > 0.1 s, margins move smoothly).
# An FMU that cannot roll back is stepped this far and checked: its triggers are located within it.
MIN_LOOKAHEAD = 1e-3
# summary.json's ES reason
EndReason = Literal["scenario", "until_distance", "until_time", "runout", "time_limit", "collision", "not_closing"]
DriverName = Literal["lane", "follow"]  # the built-in driver (docs/controllers.md)
OnCollision = Literal["continue", "stop"]  # what the first contact does


def impact_speed(state: EgoState, speed: float, lateral_rate: float) -> float:
    """The relative impact speed of a contact (summary.json's `relative_speed`, SI): the magnitude of the traffic
    vehicle's velocity minus the ego's, on the road's axes. The vehicle moves along the road at -speed (its speed
    counts toward the driver) and across it at -lateral_rate (lateral is positive right, the road's y left); the
    ego's body-frame velocity (vx, vy) turned by its yaw (looks.ego)."""
    c, s = math.cos(state.psi), math.sin(state.psi)
    return math.hypot(-speed - (state.vx * c - state.vy * s), -lateral_rate - (state.vx * s + state.vy * c))


@dataclass
class RunOptions:
    dynamics: Dynamics = "simple"  # the shipped map run_scenario drives an FMU given as a path with
    speed: float | None = None  # m/s
    seed: int = 1
    step: float = DEFAULT_STEP  # s, longest communication step; results do not depend on it
    driver_period: float = DEFAULT_DRIVER_PERIOD  # s, the driver model's sampling period
    until_distance: float | None = None  # m
    until_time: float | None = None  # s
    until_not_closing: int | None = None  # end once the ego, having closed on this vehicle (id), no longer does
    progress: Callable[[Cosimulation, EgoState], None] | None = None  # called after every recorded sample
    driver: DriverName = "lane"  # lane: holds its lane and speed; follow: also follows the vehicle ahead
    controller: ControllerModel | None = None  # a controller in the loop (docs/controllers.md)
    on_collision: OnCollision = "continue"  # stop: the run ends at the first contact (ES reason "collision")


class Cosimulation:
    """One run of a scenario against one ego vehicle: an EgoModel with the run's FMU start values and tires
    (EgoModel.with_parameters, with_tires), or an FMU driven through the shipped map of options.dynamics."""

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
        self.model = model
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
        self.controller = None
        self.clocks, self.inputs = self._sampled(options, make_driver(speed, start_lateral, model), geometry)
        self.end_distance, self.end_reason = self._end_distance()
        closing = None if options.until_not_closing is None else ClosingEnd(options.until_not_closing, self.traffic,
                                                                             self.bounds)
        self.schedule = TriggerSchedule(scenario.events, self.end_distance, self.road, self.surfaces, geometry,
                                        self.bounds, self.traffic, self.inputs, closing)
        self.recorder = Recorder(model.wheel_columns, () if self.controller is None else CONTROLLER_COLUMNS)
        self.events = EventLog()  # summary.json's events, streamed to a file: memory stays bounded
        self.warnings: list[str] = list(self.ego.warnings)
        if not self.exact:
            self.warnings.append(f"the FMU {model.fmu_path.name} cannot get and set its state: each trigger is located "
                                 f"within a communication step of at most {MIN_LOOKAHEAD:g} s, not bisected to "
                                 f"{TIME_TOLERANCE:g} s (time_uncertainty_s on each event)")
        if model.friction is None:
            self.warnings += [rsa_without_effect(event.line, model.name)
                              for event in scenario.events if isinstance(event, SurfaceAttribute)]
        self.ended_by: EndReason | None = None  # why the run ended (finish)
        self.collisions = 0
        self.collision_points: list[tuple[float, float]] = []
        self.steps = 0
        self.finished = False
        self.follower = CriticalityFollower(self.ego, self.traffic, self.bounds, self.road, self.exact)

    def _sampled(self, options: RunOptions, driver, geometry) -> tuple[SampleClocks, Inputs]:
        """The sampled parts and their clocks (clocks.py): the driver (lane, or follow with its decisions every
        reaction time) and a controller in the loop, instantiated here (the ego is closed if it cannot be)."""
        model = self.model
        periods = {"driver": options.driver_period}
        if options.driver == "follow":
            driver = FollowDriver(driver)
            periods["follow"] = REACTION_TIME
        if options.controller is not None:
            periods["controller"] = options.controller.period
            try:
                self.controller = options.controller.instantiate()
            except Exception:
                self.ego.close()
                raise
        inputs = Inputs(self.ego, model, driver, self.road, self.surfaces, geometry, options.driver_period,
                        self.controller, lambda state: lead_of(state, model.length, model.width, self.traffic))
        inputs.counts = lambda: (self.collisions, len(self.events))
        return SampleClocks(periods), inputs

    def _end_distance(self) -> tuple[float, EndReason]:
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

    def run(self) -> RunRecord:
        """The loop (FMPy's simulateCS over its helpers): each pass steps the FMU to the next communication point
        (a sample of the driver or a controller, the `step` limit or the earliest trigger bound), fires what became
        true there, and records a sample with the inputs from that instant on."""
        started = wall_clock.perf_counter()
        try:
            ego, inputs, schedule, follower, clocks = self.ego, self.inputs, self.schedule, self.follower, self.clocks
            state = ego.read()
            self.fire_due(state)
            follower.start(state)
            inputs.sample(state, {name: 0 for name in clocks.periods})
            inputs.apply(state, True)
            self.record(state)
            step, progress = self.options.step, self.options.progress
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
                limit = min(t + step, clocks.earliest, stop_time)
                if earliest < limit:
                    horizons = schedule.horizons(state, limit)
                    earliest = min(horizons.values()) if horizons else math.inf
                # a snapshot at the step's start, from which the extremes inside the step are located
                base = ego.save() if follower.wants_snapshot(state, limit) else None
                state, fired = self.advance(t, limit, horizons, earliest)
                follower.stepped(base, t, state, fired)
                if fired:
                    self.fire(state)
                    earliest = -math.inf  # the kinds of trigger and their bounds are recomputed next step
                if until_time is not None and state.time >= until_time:
                    self.finish(state, "until_time")
                due = clocks.due(state.time)  # the samples of the driver, its decisions, a controller
                if due:
                    inputs.sample(state, due)
                inputs.apply(state, fired)  # the inputs from this instant on, as recorded with it
                self.record(state)
                if progress is not None:
                    progress(self, state)
            follower.finish(state)  # an extreme at the end of the run
            return self.result(state, wall_clock.perf_counter() - started)
        finally:
            self.ego.close()
            if self.controller is not None:
                self.controller.close()

    def advance(self, t: float, limit: float, horizons: dict, earliest: float) -> tuple[EgoState, bool]:
        """One communication step from t toward `limit`: (the state at its end, whether a trigger fired there).
        Where nothing can become true before `limit` (no trigger bound within MIN_LOOKAHEAD of t) one step to
        the earliest bound or the limit; else a step of at most MIN_LOOKAHEAD, bisected to the instant a trigger
        turned true (the FMU rolled back), or located within it (time_uncertainty) without rollback."""
        ego, schedule = self.ego, self.schedule
        self.steps += 1
        if earliest - t >= MIN_LOOKAHEAD or earliest >= limit:
            # nothing can become true before `end`; something may be true exactly at it (then at no other instant:
            # its instant is known exactly)
            end = min(limit, earliest)
            ego.step_to(end)
            state = ego.read()
            self.time_uncertainty = 0.0
            return state, earliest <= end and schedule.triggered(
                state, [kind for kind, instant in horizons.items() if instant <= end])
        end = min(t + MIN_LOOKAHEAD, limit)
        kinds = [kind for kind, instant in horizons.items() if instant <= end]
        if self.exact:
            fired = step_until_time(ego, end, lambda probe: schedule.triggered(probe, kinds), TIME_TOLERANCE)
        else:  # what became true did so somewhere in (t, end]
            ego.step_to(end)
            fired = schedule.triggered(ego.read(), kinds)
            self.time_uncertainty = end - t
        return ego.read(), fired

    def record(self, state: EgoState) -> None:
        """A sample of the ego and its inputs; the first time the ego leaves the bounds the trigger prediction
        rests on, a warning (the check written out: this runs every step)."""
        bounds, inputs = self.bounds, self.inputs
        if not self.schedule.bounds_exceeded and (abs(state.yaw_rate) > bounds.yaw_rate
                                                  or math.hypot(state.ax, state.ay) > bounds.acceleration):
            self.warnings.append(self.schedule.exceeded_warning(state))
        self.recorder.record(state, inputs.controls, inputs.brake_hold is not None, inputs.wheel_values,
                             () if self.controller is None else inputs.controller_columns())

    # ---- what happens at an instant -------------------------------------------------------------

    def log(self, code: str, action: str, state: EgoState, **extra) -> None:
        entry = {"code": code, "action": action, "time_s": state.time, "distance": state.s, "speed": state.v,
                 "lateral": -state.y, **extra}  # SI: the results give them in the scenario's units
        if not self.exact:
            entry["time_uncertainty_s"] = self.time_uncertainty
        self.events.append(entry)

    def fire(self, state: EgoState) -> None:
        """What became true at this instant fires; the trigger bounds and the fired vehicles' criticality looks are
        redone from it (spawns, actions, contacts, departures, the next event, BRK change what they rest on)."""
        self.fire_due(state)
        self.schedule.forget()
        self.follower.fired(state)

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
        if schedule.closing is not None and not self.finished and schedule.closing.fire(state):
            self.finish(state, "not_closing")
        if state.s >= self.end_distance:
            self.finish(state, self.end_reason)

    def fire_traffic(self, state: EgoState) -> None:
        traffic, schedule, recorder = self.traffic, self.schedule, self.recorder
        kinematics = EgoKinematics.of(state)
        active = traffic.active
        action, overlap, away = schedule.vehicle_conditions(active, kinematics)
        if action.any():
            for i in active[action]:
                self.follower.changing(int(i), state)
                while True:  # each action once, the next armed as the previous fires; several may be due at once
                    index = int(traffic.next_action[i]) + 1
                    traffic.start_action(i, state.time, -state.y, state.v)
                    self.log("A", "maneuver", state, vehicle=recorder.vehicle_ids[i], index=index)
                    self.follower.lane_leave_instant(int(i), state)
                    if not schedule.action_due(int(i), kinematics):
                        break
            _, overlap, away = schedule.vehicle_conditions(active, kinematics)
        contacts = active[overlap & ~traffic.in_contact[active]]
        for i in contacts:
            self.collisions += 1
            station, lateral, speed, lateral_rate, _ = traffic.motion_of(int(i), state.time)
            self.collision_points.append(((state.x + station) / 2, (-state.y + lateral) / 2))
            self.log("A", "collision", state, vehicle=recorder.vehicle_ids[i],
                     relative_speed=impact_speed(state, speed, lateral_rate))
        if len(contacts) and self.options.on_collision == "stop":
            self.finish(state, "collision")
        changed = active[overlap != traffic.in_contact[active]]
        traffic.in_contact[active] = overlap
        traffic.next_check[changed] = state.time
        self.follower.touch(changed.tolist())
        for i in active[away & ~overlap]:
            self.follower.changing(int(i), state)
            traffic.remove(i)
            recorder.left(i)
            self.log("A", "despawn", state, vehicle=recorder.vehicle_ids[i])

    def fire_event(self, event, state: EgoState) -> None:
        if isinstance(event, ApproachingVehicle):
            model_number = choose_model(event, self.rng)
            model = self.vehicle_table[model_number]
            index = self.traffic.add(event, model, state.time, state.x, -state.y, state.v)
            self.follower.touch([index])
            self.recorder.spawned(index + 1)
            self.log("A", "spawn", state, vehicle=index + 1, model=model_number, name=model.name, line=event.line)
        elif isinstance(event, Brake):
            brake_hold = self.inputs.brake_hold
            if not self.model.brk_acts:
                self.warnings.append(brk_ignored(event.line))
            elif brake_hold is not None:
                self.warnings.append(f"line {event.line}: BRK ignored: the brake event of line "
                                     f"{brake_hold.event.line} is still on")
            else:
                self.inputs.brake_hold = BrakeHold(event, state.time, state.s, state.v)
                self.log("BRK", "on", state, pedal=event.pedal * 100, threshold=event.threshold,
                         magnitude=event.magnitude, line=event.line)
        elif isinstance(event, SurfaceAttribute):
            for lane, value in event.settings:
                self.log("RSA", "set", state, lane=lane, value=value, line=event.line)
                known = self.model.known_attributes
                if known is not None and int(value) not in known:
                    self.warnings.append(attribute_without_tire(event.line, int(value), lane))
        elif isinstance(event, EndOfScenario):
            self.finish(state, "scenario")

    def release_brakes(self, state: EgoState, reason: str) -> None:
        """Control returns to the driver model at this instant, its speed integral reset."""
        self.log("BRK", "off", state, reason=reason, line=self.inputs.brake_hold.event.line)
        self.inputs.release_brakes(state)

    def finish(self, state: EgoState, reason: EndReason) -> None:
        """Ends the run; reason: scenario (ES), until_distance, until_time, runout, time_limit, collision
        (--on-collision stop) or not_closing."""
        if self.finished:
            return
        if self.inputs.brake_hold is not None:
            self.release_brakes(state, "end")
        self.log("ES", "end", state, reason=reason)
        self.finished = True
        self.ended_by = reason

    # ---- the result -----------------------------------------------------------------------------

    def result(self, state: EgoState, wall: float) -> RunRecord:
        recorder = self.recorder
        columns = recorder.columns()
        self.warnings += self.never_took_effect(columns, state)
        final = {"time_s": state.time, "distance": state.s, "speed": state.v, "lateral": -state.y}
        timing = {"wall_s": wall, "real_time_factor": state.time / wall if wall > 0 else None,
                  "steps": self.steps, "samples": recorder.sample_count}
        model, bounds = self.model, self.bounds
        vehicle = {**model.summary(), "bounds": {
            "acceleration_m/s2": bounds.acceleration, "yaw_rate_rad/s": bounds.yaw_rate,
            "source": model.bounds["source"],
            "defaults": model.defaulted if model.bounds["acceleration"] is None else []}}
        return RunRecord(
            scenario_path=self.scenario.path, units=self.scenario.units, dynamics=model.name, vehicle=vehicle,
            friction_meaning=model.surface_meaning,
            seed=self.options.seed, road=self.road, columns=columns,
            vehicles=recorder.vehicle_tracks(self.traffic, columns, self.bounds.length, self.bounds.width),
            events=self.events, collisions=self.collisions, collision_points=self.collision_points,
            surfaces=surface_sections(self.surfaces), warnings=self.warnings, final=final, timing=timing,
            criticality=self.follower.summary(self.recorder.vehicle_ids),
            controller=None if self.options.controller is None else self.options.controller.summary(),
            driver=self.driver_summary(),
            ttc_series=partial(ttc_series, self.traffic, *recorder.spans(), self.bounds, columns),
            lead_series=partial(lead_series, self.traffic, *recorder.spans(), self.bounds, columns),
        )

    def never_took_effect(self, columns: dict, state: EgoState) -> list[str]:
        """The warnings, in line order, for what never took effect in the run (effects.py): actions never fired or cut
        off by the next, BRK events released at once or overridden by the controller, events an early end never
        reached; from the traffic's motions, the samples and the event log, once."""
        first, last = self.recorder.spans()
        tolerance = TIME_TOLERANCE if self.exact else MIN_LOOKAHEAD  # how exactly two fired instants' gap is known
        found = action_warnings(self.traffic, self.recorder.vehicle_ids, first, last, columns, state.time, tolerance)
        if any(isinstance(event, Brake) for event in self.scenario.events):
            found += brake_warnings(self.events, columns, self.options.controller)
        schedule = self.schedule
        found += unreached_warnings(schedule.events[schedule.next_event:], self.ended_by, state.time)
        return ineffective(found)

    def driver_summary(self) -> dict | None:
        """summary.json's `driver` for the follow driver (docs/controllers.md); None (no key) for the lane driver."""
        if self.options.driver != "follow":
            return None
        from . import follow

        return {"name": "follow", "law": "Gipps (1981)", "reaction_time_s": follow.REACTION_TIME,
                "braking_m/s2": follow.BRAKING, "leader_braking_m/s2": follow.LEADER_BRAKING,
                "standstill_gap_m": follow.STANDSTILL_GAP, "period_s": self.options.driver_period}


def run_scenario(scenario: Scenario, model: EgoModel | Path, options: RunOptions,
                 vehicle_table: dict[int, VehicleModel]) -> RunRecord:
    """Co-simulates a parsed scenario against an ego vehicle and returns what happened (RunRecord: SI)."""
    return Cosimulation(scenario, model, options, vehicle_table).run()
