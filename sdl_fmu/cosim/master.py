"""The co-simulation master: steps the ego FMU through fmpy together with the road, the BRK
controller, the driver model and the traffic model, and fires every trigger at its true instant.

Each communication step is taken from a saved FMU state; if any trigger (an event distance, a BRK
threshold, a closure time, a contact, a wheel crossing onto another surface) became true inside it,
the step is rolled back and bisected (fmi2GetFMUstate / fmi2SetFMUstate) until the instant is known
within TIME_TOLERANCE. Traffic motion is closed-form in time, so it needs no rollback of its own.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..results import RunResult, VehicleTrack
from ..sdl.events import ApproachingVehicle, Brake, EndOfScenario, Scenario, SurfaceAttribute
from ..sdl.vehicles import VehicleModel
from ..units import FOOT, from_si
from .brake import BrakeHold
from .driver import make_driver
from .ego import EgoFMU, EgoState, parameter_defaults, step_until
from .road import WHEELS, surface_map, surface_sections, wheel_geometry, wheel_surfaces
from .traffic import TrafficVehicle, choose_model, footprints_overlap, spawn

DEFAULT_SPEED = 88 * FOOT  # m/s: 60 mph, the driver's start speed unless --speed says otherwise
RUNOUT = 1000 * FOOT  # m driven past the last event when neither ES nor --until ends the run
MAX_TIME = 3600.0  # s, a run never goes beyond
TIME_TOLERANCE = 1e-6  # s, how exactly a trigger's instant is located


@dataclass
class RunOptions:
    dynamics: str = "simple"
    speed: float | None = None  # m/s
    seed: int = 1
    step: float = 0.01  # s, communication step
    until_distance: float | None = None  # m
    until_time: float | None = None  # s
    parameters: dict[str, float] = field(default_factory=dict)  # FMU start values, SI
    tire_parameters: dict[str, float] = field(default_factory=dict)  # tire slot start values (advanced)
    known_attributes: set[int] | None = None  # attribute numbers with a tire file (advanced)
    progress: Callable[[Cosimulation, EgoState], None] | None = None  # called after every recorded sample


class Cosimulation:
    """One run of a scenario against one ego FMU."""

    def __init__(self, scenario: Scenario, fmu: Path, options: RunOptions, vehicle_table: dict[int, VehicleModel]):
        self.scenario = scenario
        self.options = options
        self.road = scenario.road
        self.vehicle_table = vehicle_table
        self.rng = random.Random(options.seed)
        self.surfaces = surface_map(scenario, options.dynamics)
        self.speed = DEFAULT_SPEED if options.speed is None else options.speed
        start_lateral = self.road.lane_center(1)
        start = {"v0": self.speed, "x0": 0.0, "y0": -start_lateral, "psi0": 0.0,
                 **options.tire_parameters, **options.parameters}
        self.ego = EgoFMU(fmu, start)
        parameters = {**parameter_defaults(self.ego.model_description), **start}
        self.geometry = wheel_geometry(parameters)
        self.ego_size = (parameters["length"], parameters["width"])
        self.driver = make_driver(self.speed, start_lateral, parameters)
        self.wheel_inputs = [f"mu_{w}" if options.dynamics == "simple" else f"surface_{w}" for w in WHEELS]
        self.pending = list(scenario.events)
        self.traffic: list[TrafficVehicle] = []
        self.brake_hold: BrakeHold | None = None
        self.applied_surfaces: tuple[float, ...] | None = None
        self.wheel_values: list[float] = []  # the FMU's wheel inputs for the applied surfaces
        self.controls = (0.0, 0.0, 0.0)
        self.events: list[dict] = []
        self.warnings: list[str] = []
        self.collisions = 0
        self.collision_points: list[tuple[float, float]] = []
        self.samples: list[tuple] = []
        self.traffic_samples: list[dict[int, tuple[float, float, float]]] = []
        self.finished = False
        self.end_distance, self.end_reason = self._end_distance()

    # ---- scenario units at the results boundary -------------------------------------------------

    def _scenario_units(self, value: float) -> float:
        return from_si(value, self.scenario.units)

    def log(self, code: str, action: str, state: EgoState, **extra) -> None:
        self.events.append({"code": code, "action": action, "time_s": state.time,
                            "distance": self._scenario_units(state.s), "speed": self._scenario_units(state.v),
                            "lateral": self._scenario_units(-state.y), **extra})

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

    def station_rate(self, state: EgoState) -> float:
        return state.vx * math.cos(state.psi) - state.vy * math.sin(state.psi)

    def surfaces_under_wheels(self, state: EgoState) -> tuple[float, ...]:
        return wheel_surfaces(self.road, self.surfaces, self.geometry.contact_points(state.x, state.y, state.psi))

    def in_contact(self, vehicle: TrafficVehicle, state: EgoState) -> bool:
        station, lateral, _ = vehicle.at(state.time)
        return footprints_overlap((state.x, state.y), state.psi, self.ego_size, (station, -lateral), 0.0,
                                  (vehicle.model.length, vehicle.model.width))

    def triggered(self, state: EgoState) -> bool:
        """Whether anything must happen at this state (false at the start of every step)."""
        if self.pending and self.pending[0].distance <= state.s:
            return True
        if state.s >= self.end_distance:
            return True
        if self.brake_hold is not None and self.brake_hold.release_reason(state):
            return True
        if self.surfaces_under_wheels(state) != self.applied_surfaces:
            return True
        rate = self.station_rate(state)
        for vehicle in self.traffic:
            if vehicle.present and (vehicle.action_due(state.time, state.x, rate)
                                    or (not vehicle.in_contact and self.in_contact(vehicle, state))):
                return True
        return False

    # ---- what happens at an instant -------------------------------------------------------------

    def fire_due(self, state: EgoState) -> None:
        """Fires everything due at this state, in file order, until nothing more is due."""
        while self.pending and self.pending[0].distance <= state.s and not self.finished:
            self.fire_event(self.pending.pop(0), state)
        if self.brake_hold is not None:
            reason = self.brake_hold.release_reason(state)
            if reason:
                self.release_brakes(state, reason)
        rate = self.station_rate(state)
        for vehicle in self.traffic:
            if not vehicle.present:
                continue
            while vehicle.action_due(state.time, state.x, rate):
                index = vehicle.next_action + 1
                vehicle.start_action(state.time, -state.y, state.v)
                self.log("A", "maneuver", state, vehicle=vehicle.vehicle, index=index)
            contact = self.in_contact(vehicle, state)
            if contact and not vehicle.in_contact:
                self.collisions += 1
                station, lateral, _ = vehicle.at(state.time)
                self.collision_points.append(((state.x + station) / 2, (-state.y + lateral) / 2))
                self.log("A", "collision", state, vehicle=vehicle.vehicle)
            vehicle.in_contact = contact
        if state.s >= self.end_distance:
            self.finish(state, self.end_reason)

    def fire_event(self, event, state: EgoState) -> None:
        if isinstance(event, ApproachingVehicle):
            model_number = choose_model(event, self.rng)
            vehicle = spawn(len(self.traffic) + 1, event, self.vehicle_table[model_number], state.time, state.x,
                            -state.y, state.v)
            self.traffic.append(vehicle)
            self.log("A", "spawn", state, vehicle=vehicle.vehicle, model=model_number, name=vehicle.model.name,
                     line=event.line)
        elif isinstance(event, Brake):
            if self.options.dynamics != "simple":
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
        self.log("BRK", "off", state, reason=reason, line=self.brake_hold.event.line)
        self.brake_hold = None
        self.driver.reset_integral()

    def finish(self, state: EgoState, reason: str) -> None:
        """Ends the run; reason: scenario (ES), until_distance, until_time, runout or time_limit."""
        if self.finished:
            return
        if self.brake_hold is not None:
            self.release_brakes(state, "end")
        self.log("ES", "end", state, reason=reason)
        self.finished = True

    def leave(self, state: EgoState) -> None:
        rate = self.station_rate(state)
        for vehicle in self.traffic:
            if vehicle.present and not vehicle.in_contact and vehicle.may_leave(state.time, state.x, rate, self.ego_size[0]):
                vehicle.present = False
                self.log("A", "despawn", state, vehicle=vehicle.vehicle)

    # ---- inputs and records ---------------------------------------------------------------------

    def apply_controls(self, state: EgoState) -> None:
        steer = self.driver.steer(state)
        if self.brake_hold is not None:
            throttle, brake = 0.0, self.brake_hold.event.pedal
        else:
            throttle, brake = self.driver.pedals(state)
        surfaces = self.surfaces_under_wheels(state)
        self.applied_surfaces = surfaces
        self.controls = (throttle, brake, steer)
        self.wheel_values = [value / 10 if self.options.dynamics == "simple" else int(value) for value in surfaces]
        self.ego.set(throttle=throttle, brake=brake, steer=steer, **dict(zip(self.wheel_inputs, self.wheel_values)))

    def record(self, state: EgoState) -> None:
        throttle, brake, steer = self.controls
        self.samples.append((state.time, state.x, state.y, state.psi, state.s, state.v, state.vx, state.vy,
                             state.ax, state.ay, state.yaw_rate, float(state.stopped), state.x, -state.y,
                             throttle, brake, steer, float(self.brake_hold is not None), *self.wheel_values))
        self.traffic_samples.append({v.vehicle: v.at(state.time) for v in self.traffic if v.present})

    # ---- the loop -------------------------------------------------------------------------------

    def run(self) -> RunResult:
        try:
            state = self.ego.read()
            self.fire_due(state)
            self.apply_controls(state)
            self.record(state)
            while not self.finished:
                if state.time >= MAX_TIME:
                    self.warnings.append(f"the run was stopped at the time limit of {MAX_TIME:g} s")
                    self.finish(state, "time_limit")
                    break
                until_time = self.options.until_time
                h = self.options.step if until_time is None else min(self.options.step, until_time - state.time)
                fired = step_until(self.ego, h, self.triggered, TIME_TOLERANCE)
                previous, state = state, self.ego.read()
                if self.brake_hold is None:
                    self.driver.update(state, state.time - previous.time, self.controls[0])
                if fired:
                    self.fire_due(state)
                self.leave(state)
                if until_time is not None and state.time >= until_time - 1e-12:
                    self.finish(state, "until_time")
                self.apply_controls(state)  # the inputs from this instant on, as recorded with it
                self.record(state)
                if self.options.progress is not None:
                    self.options.progress(self, state)
            return self.result(state)
        finally:
            self.ego.close()

    def result(self, state: EgoState) -> RunResult:
        names = ["time", "x", "y", "psi", "s", "v", "vx", "vy", "ax", "ay", "yaw_rate", "stopped", "station",
                 "lateral", "throttle", "brake", "steer", "brk", *self.wheel_inputs]
        table = np.array(self.samples, dtype=float)
        columns = {name: table[:, i] for i, name in enumerate(names)}
        tracks = []
        for vehicle in self.traffic:
            rows = np.full((len(self.samples), 3), np.nan)
            for i, present in enumerate(self.traffic_samples):
                if vehicle.vehicle in present:
                    rows[i] = present[vehicle.vehicle]
            tracks.append(VehicleTrack(vehicle.vehicle, vehicle.model.number, vehicle.model.name,
                                       vehicle.model.length, vehicle.model.width, rows[:, 0], rows[:, 1],
                                       rows[:, 2]))
        final = {"time_s": state.time, "distance": self._scenario_units(state.s),
                 "speed": self._scenario_units(state.v), "lateral": self._scenario_units(-state.y)}
        return RunResult(
            scenario_path=self.scenario.path, units=self.scenario.units, dynamics=self.options.dynamics,
            seed=self.options.seed, road=self.road, columns=columns, vehicles=tracks, events=self.events,
            collisions=self.collisions, collision_points=self.collision_points,
            surfaces=surface_sections(self.surfaces), warnings=self.warnings, final=final,
        )


def run_scenario(scenario: Scenario, fmu: Path, options: RunOptions,
                 vehicle_table: dict[int, VehicleModel]) -> RunResult:
    """Co-simulates a parsed scenario against an ego FMU and returns what happened (SI inside)."""
    return Cosimulation(scenario, fmu, options, vehicle_table).run()
