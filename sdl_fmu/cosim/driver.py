"""The driver model: the ego's controller whenever no event overrides it. Holds the start speed
(PI on speed with a feedforward of the rolling and air resistance) and the centre of its lane
(pure pursuit of a point one preview distance ahead on the lane centre)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..units import STANDARD_GRAVITY
from .ego import EgoState

SPEED_GAIN = 1.0  # 1/s: speed error to acceleration demand
SPEED_INTEGRAL_GAIN = 0.2  # 1/s2
BRAKE_DEADBAND = 0.5  # m/s2: the driver coasts for smaller decelerations and brakes beyond
PREVIEW_TIME = 1.0  # s
MIN_PREVIEW = 5.0  # m
MAX_STEER = 0.5  # rad


@dataclass
class Driver:
    target_speed: float  # m/s
    target_lateral: float  # m, roadway frame (+ right)
    wheelbase: float
    mass: float
    drive_accel_max: float
    drive_power_max: float
    brake_decel_max: float
    rolling_resistance: float
    drag_factor: float  # rho CdA / (2 m)
    integral: float = 0.0  # m/s, accumulated speed error

    def steer(self, state: EgoState) -> float:
        preview = max(PREVIEW_TIME * state.v, MIN_PREVIEW)
        alpha = math.atan2(-self.target_lateral - state.y, preview) - state.psi
        steer = math.atan(2 * self.wheelbase * math.sin(alpha) / preview)
        return min(max(steer, -MAX_STEER), MAX_STEER)

    def pedals(self, state: EgoState) -> tuple[float, float]:
        """(throttle, brake) that hold the target speed."""
        error = self.target_speed - state.v
        resistance = self.rolling_resistance * STANDARD_GRAVITY * (state.v > 0) + self.drag_factor * state.v**2
        demand = SPEED_GAIN * error + SPEED_INTEGRAL_GAIN * self.integral + resistance
        if demand >= 0:
            available = min(self.drive_accel_max, self.drive_power_max / (self.mass * max(state.v, 1e-3)))
            return (min(demand / available, 1.0) if available > 0 else 0.0), 0.0
        if demand > -BRAKE_DEADBAND:
            return 0.0, 0.0
        return 0.0, min(-demand / self.brake_decel_max, 1.0)

    def update(self, state: EgoState, h: float, throttle: float) -> None:
        """Integrates the speed error over an accepted step (not while the throttle is saturated)."""
        error = self.target_speed - state.v
        if not (throttle >= 1.0 and error > 0):
            self.integral = min(max(self.integral + error * h, -5.0), 5.0)

    def reset_integral(self) -> None:
        self.integral = 0.0


def make_driver(target_speed: float, target_lateral: float, parameters: dict[str, float]) -> Driver:
    mass = parameters["mass"]
    wheelbase = parameters.get("wheelbase") or parameters["cg_to_front_axle"] + parameters["cg_to_rear_axle"]
    return Driver(
        target_speed=target_speed,
        target_lateral=target_lateral,
        wheelbase=wheelbase,
        mass=mass,
        # the Advanced FMU states its drive as a wheel torque: a = T / (m R)
        drive_accel_max=parameters["drive_accel_max"] if "drive_accel_max" in parameters
        else parameters["drive_torque_max"] / (mass * parameters["wheel_radius"]),
        drive_power_max=parameters.get("drive_power_max", 1e5),
        brake_decel_max=parameters["brake_decel_max"],
        rolling_resistance=parameters["rolling_resistance"],
        drag_factor=parameters["air_density"] * parameters["drag_area"] / (2 * mass),
    )
