"""The driver model: the ego's controller whenever no event overrides it. Holds the start speed
(PI on speed with a feedforward of the rolling and air resistance) and the centre of its lane
(pure pursuit of a point one preview distance ahead on the lane centre, plus yaw-rate feedback: when the
car yaws faster than the path asks for, as in a skid, the driver counter-steers, within MAX_STEER)."""

from __future__ import annotations

from dataclasses import dataclass
from math import atan, atan2, sin, tan

from ..units import STANDARD_GRAVITY
from ..vehicle import EgoState

SPEED_GAIN = 1.0  # 1/s: speed error to acceleration demand
SPEED_INTEGRAL_GAIN = 0.2  # 1/s2
BRAKE_DEADBAND = 0.5  # m/s2: the driver coasts for smaller decelerations and brakes beyond
PREVIEW_TIME = 1.0  # s
MIN_PREVIEW = 5.0  # m
MAX_STEER = 0.5  # rad
# s: road-wheel angle per rad/s of yaw rate beyond the pure-pursuit path's (v tan(steer) / L). Counter-steer
# of 0.3 rad for a 1 rad/s skid; in steady lane keeping the two yaw rates agree and it adds nothing.
YAW_RATE_GAIN = 0.3


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

    # steer, pedals and update run at every driver sample: plain comparisons instead of min / max calls
    # (the same values, NaN included), math functions imported by name

    def steer(self, state: EgoState) -> float:
        v = state.v
        preview = PREVIEW_TIME * v
        if preview < MIN_PREVIEW:
            preview = MIN_PREVIEW
        wheelbase = self.wheelbase
        alpha = atan2(-self.target_lateral - state.y, preview) - state.psi
        steer = atan(2 * wheelbase * sin(alpha) / preview)
        path_yaw_rate = state.vx * tan(steer) / wheelbase
        steer += YAW_RATE_GAIN * (path_yaw_rate - state.yaw_rate)
        return -MAX_STEER if steer < -MAX_STEER else MAX_STEER if steer > MAX_STEER else steer

    def pedals(self, state: EgoState) -> tuple[float, float]:
        """(throttle, brake) that hold the target speed."""
        return self.pedals_for(self.demand(state), state.v)

    def resistance(self, v: float) -> float:
        """The rolling and air resistance's deceleration at speed v (m/s2), the feed-forward."""
        return self.rolling_resistance * STANDARD_GRAVITY * (v > 0) + self.drag_factor * v**2

    def demand(self, state: EgoState) -> float:
        """The acceleration the drive or the brakes must give (m/s2; resistance included) to hold the target
        speed: PI on the speed error plus the resistance's feed-forward."""
        error = self.target_speed - state.v
        return SPEED_GAIN * error + SPEED_INTEGRAL_GAIN * self.integral + self.resistance(state.v)

    def pedals_for(self, demand: float, v: float, deadband: bool = True) -> tuple[float, float]:
        """(throttle, brake) that give the acceleration `demand` (m/s2, resistance included) at speed v: throttle
        against the drive limit (acceleration or power), brake against brake_decel_max; with `deadband` it
        coasts for decelerations below BRAKE_DEADBAND."""
        if demand >= 0:
            power_limited = self.drive_power_max / (self.mass * (1e-3 if v < 1e-3 else v))
            available = power_limited if power_limited < self.drive_accel_max else self.drive_accel_max
            if not available > 0:
                return 0.0, 0.0
            throttle = demand / available
            return (1.0 if throttle > 1.0 else throttle), 0.0
        if deadband and demand > -BRAKE_DEADBAND:
            return 0.0, 0.0
        brake = -demand / self.brake_decel_max
        return 0.0, (1.0 if brake > 1.0 else brake)

    def update(self, state: EgoState, h: float, throttle: float) -> None:
        """Integrates the speed error over an accepted step (not while the throttle is saturated)."""
        error = self.target_speed - state.v
        if not (throttle >= 1.0 and error > 0):
            integral = self.integral + error * h
            self.integral = -5.0 if integral < -5.0 else 5.0 if integral > 5.0 else integral

    def reset_integral(self) -> None:
        self.integral = 0.0


def make_driver(target_speed: float, target_lateral: float, model) -> Driver:
    """From the EgoModel's properties (SI)."""
    return Driver(
        target_speed=target_speed,
        target_lateral=target_lateral,
        wheelbase=model.wheelbase,
        mass=model.mass,
        drive_accel_max=model.drive_accel_max,
        drive_power_max=model.drive_power_max,
        brake_decel_max=model.brake_decel_max,
        rolling_resistance=model.rolling_resistance,
        drag_factor=model.drag_factor,
    )
