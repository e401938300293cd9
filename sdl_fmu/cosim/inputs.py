"""What the ego FMU is given at each communication point: the driver model's pedals and steer (BRK's pedal while a
brake event holds them), arbitrated with a controller's requests when one is in the loop (arbitration.py), and the
road surface under each wheel, sent only when they changed. The sampled parts (the driver, the follow driver's
decisions, the controller) are sampled here at the instants clocks.py gives."""

from __future__ import annotations

import math
from typing import Callable

from ..sdl.events import Road
from ..vehicle import EgoInstance, EgoModel, EgoState
from ..vehicle.controller import NO_REQUEST, ControllerInstance
from .arbitration import arbitrate
from .brake import BrakeHold
from .driver import Driver
from .road import SurfaceMap, WheelGeometry, wheel_surfaces
from .signals import Lead

# the time series' columns of a run with a controller (after the wheel columns; docs/controllers.md): the driver's
# commands before arbitration and the controller's requests (NaN where the map does not map that request)
CONTROLLER_COLUMNS = ("driver_throttle", "driver_brake", "driver_steer", "request_active", "request_throttle",
                      "request_brake", "request_steer", "request_deceleration")


class Inputs:
    """The ego's inputs: `controls` (throttle, brake, steer, as sent), `driver_controls` (the driver's or BRK's,
    before arbitration), the controller's `request`, the brake hold, the surfaces under the wheels."""

    def __init__(self, ego: EgoInstance, model: EgoModel, driver: Driver, road: Road, surfaces: SurfaceMap,
                 geometry: WheelGeometry, driver_period: float | None = None,
                 controller: ControllerInstance | None = None, lead: Callable[[EgoState], Lead] | None = None):
        self.ego, self.model, self.driver = ego, model, driver
        self.road, self.surfaces, self.geometry = road, surfaces, geometry
        self.driver_period = driver_period  # s, the speed integral's step at a driver sample
        self.controller = controller
        self.lead = lead  # the lead-vehicle signals at a state (signals.lead_of), for the follow driver and controller
        self.rules = None if controller is None else controller.model.rules
        self.counts: Callable[[], tuple[int, int]] = lambda: (0, 0)  # the run's (collisions, events) so far
        self.brake_hold: BrakeHold | None = None  # BRK holding the pedals
        self.driver_controls = (0.0, 0.0, 0.0)
        self.controls = (0.0, 0.0, 0.0)
        self.request = NO_REQUEST
        self.sent_controls: tuple | None = None
        self.applied_surfaces: tuple[float, ...] | None = None
        self.wheel_values: tuple[float, ...] = ()  # the FMU's wheel inputs for the applied surfaces

    def surfaces_under_wheels(self, state: EgoState) -> tuple[float, ...]:
        return wheel_surfaces(self.road, self.surfaces, self.geometry.contact_points(state.x, state.y, state.psi))

    def sample(self, state: EgoState, due: dict[str, int]) -> None:
        """The samples due at this state (clocks.SampleClocks.due: name -> k), in this order: the follow driver's
        decision, the driver (its speed integral over the period, unless this is its first sample), the controller
        (which reads the driver's fresh commands)."""
        lead, changed = None, False
        if "follow" in due:
            lead = self.lead(state)
            changed = self.driver.decide(state, lead)
        k = due.get("driver")
        if k is not None:
            self.sample_driver(state, self.driver_period if k > 0 else None)
        elif changed and self.brake_hold is None:  # the decision acts at once: new pedals, same steer
            self.driver_controls = (*self.driver.pedals(state), self.driver_controls[2])
        k = due.get("controller")
        if k is not None:
            self.request = self.controller.sample(k, self.signals(state, lead or self.lead(state), *self.counts()))

    def signals(self, state: EgoState, lead: Lead, collisions: int, events: int) -> dict[str, float]:
        """The signals a controller may read, by name (vehicle.controller_map.SIGNALS), SI."""
        throttle, brake, steer = self.driver_controls
        if self.brake_hold is not None:
            throttle, brake = 0.0, self.brake_hold.event.pedal
        return {"ego_x": state.x, "ego_y": state.y, "ego_psi": state.psi, "ego_v": state.v, "ego_s": state.s,
                "ego_yaw_rate": state.yaw_rate, "ego_ax": state.ax,
                "lead_present": lead.present, "lead_id": lead.vehicle_id, "lead_gap": lead.gap,
                "lead_speed": lead.speed, "lead_relative_speed": lead.relative_speed, "lead_ttc": lead.ttc,
                "lead_lateral_offset": lead.lateral_offset,
                "driver_throttle": throttle, "driver_brake": brake, "driver_steer": steer,
                "collisions": collisions, "events": events}

    def sample_driver(self, state: EgoState, period: float | None) -> None:
        """A driver sample: integrate the speed error over the period (not while BRK holds the pedals),
        then new steer and, unless BRK holds them, new pedals."""
        driver, controls = self.driver, self.driver_controls
        if self.brake_hold is None:
            if period is not None:
                driver.update(state, period, controls[0])
            throttle, brake = driver.pedals(state)
        else:
            throttle, brake = controls[0], controls[1]
        self.driver_controls = (throttle, brake, driver.steer(state))

    def release_brakes(self, state: EgoState) -> None:
        """Control returns to the driver model at this instant, its speed integral reset."""
        self.brake_hold = None
        self.driver.reset_integral()
        throttle, brake = self.driver.pedals(state)
        self.driver_controls = (throttle, brake, self.driver_controls[2])

    def apply(self, state: EgoState, surfaces_may_change: bool) -> None:
        """Pedals (BRK's while it holds them) and steer, arbitrated with the controller's requests, and the surfaces
        under the wheels, sent if changed."""
        if self.brake_hold is not None:
            self.driver_controls = (0.0, self.brake_hold.event.pedal, self.driver_controls[2])
        if self.controller is None:
            self.controls = self.driver_controls
        else:
            self.controls = arbitrate(self.driver_controls, self.request, self.rules, self.model.brake_decel_max)
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

    def controller_columns(self) -> tuple[float, ...]:
        """This instant's values of CONTROLLER_COLUMNS (NaN for a request the controller does not make)."""
        request = self.request
        return (*self.driver_controls, float(request.active),
                *(math.nan if value is None else value
                  for value in (request.throttle, request.brake, request.steer, request.deceleration)))
