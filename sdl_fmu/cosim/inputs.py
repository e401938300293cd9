"""What the ego FMU is given at each communication point: the driver model's pedals and steer (BRK's pedal
while a brake event holds them) and the road surface under each wheel, sent only when they changed."""

from __future__ import annotations

from ..sdl.events import Road
from ..vehicle import EgoInstance, EgoModel, EgoState
from .brake import BrakeHold
from .driver import Driver
from .road import SurfaceMap, WheelGeometry, wheel_surfaces


class Inputs:
    """The ego's inputs: `controls` (throttle, brake, steer), the brake hold, the surfaces under the wheels."""

    def __init__(self, ego: EgoInstance, model: EgoModel, driver: Driver, road: Road, surfaces: SurfaceMap,
                 geometry: WheelGeometry):
        self.ego, self.model, self.driver = ego, model, driver
        self.road, self.surfaces, self.geometry = road, surfaces, geometry
        self.brake_hold: BrakeHold | None = None  # BRK holding the pedals
        self.controls = (0.0, 0.0, 0.0)
        self.sent_controls: tuple | None = None
        self.applied_surfaces: tuple[float, ...] | None = None
        self.wheel_values: tuple[float, ...] = ()  # the FMU's wheel inputs for the applied surfaces

    def surfaces_under_wheels(self, state: EgoState) -> tuple[float, ...]:
        return wheel_surfaces(self.road, self.surfaces, self.geometry.contact_points(state.x, state.y, state.psi))

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

    def release_brakes(self, state: EgoState) -> None:
        """Control returns to the driver model at this instant, its speed integral reset."""
        self.brake_hold = None
        self.driver.reset_integral()
        throttle, brake = self.driver.pedals(state)
        self.controls = (throttle, brake, self.controls[2])

    def apply(self, state: EgoState, surfaces_may_change: bool) -> None:
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
