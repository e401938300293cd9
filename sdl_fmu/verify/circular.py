"""`steady_state_circular`: ISO 4138 steady-state circular driving, constant-radius method, left and right turns.

The driver holds the vehicle on a circle of 100 m radius (ISO 4138's recommended radius), turning left and then
right (ISO 4138 asks for both directions). On each circle the speed is held at a series of steady points, the
lateral acceleration v^2 / R = POINTS; at each the car settles for SETTLE_POINT seconds and its steady state is the
mean over the next AVERAGE_POINT seconds (ISO 4138's steady state: speed, steer and yaw rate constant; the test
checks that they changed by less than STEADY_TOLERANCE over the averaging). After the points the speed is raised
slowly (v^2 / R grows by RAMP_RATE per second) until the car can no longer be held on the circle or stops gaining
lateral acceleration. Metrics (ISO 4138 / ISO 8855 terms):
  understeer gradient = d(delta - delta_Ackermann) / d a_y fitted by least squares through the steady points of
  each direction, delta_Ackermann = L r / v (the steer a vehicle without slip needs for the path's actual curvature
  r / v), in degrees of road-wheel angle per g; the top-level value is the mean of the two directions;
  maximum lateral acceleration: the largest a_y held (1 s moving average) on the ramp, the smaller of the two
  directions at the top level. The ramp's own effect on it (its a_x asks for up to 0.4 m/s2 of the tires at 8 m/s2
  of a_y) is below 0.1 % of the friction circle.
ISO 4138 sets no pass/fail limit: `passed` is null.
"""

from __future__ import annotations

import math

import numpy as np

from ..units import STANDARD_GRAVITY
from .drive import SAMPLE_PERIOD, ManoeuvreFailed, SpeedHold, drive
from .driver import PathFollower
from .outcome import Outcome

STANDARD = "ISO 4138 steady-state circular driving (constant radius)"
RADIUS = 100.0  # m, ISO 4138 constant-radius method: 100 m recommended
POINTS = (0.5, 1.0, 1.5, 2.0)  # m/s^2: steady points in the linear range of a car (sdl-fmu's choice)
SETTLE_POINT = 6.0  # s at each point before it is averaged (driver, yaw and speed transients die out)
AVERAGE_POINT = 1.0  # s averaged per point
STEADY_TOLERANCE = 0.01  # relative change of speed, steer and yaw rate over the averaging: the point is steady
RAMP_RATE = 0.2  # m/s^2 of v^2 / R per second above the points, to the limit (sdl-fmu's choice)
MAX_LATERAL = 12.0  # m/s^2: the ramp ends here at the latest (beyond any road tire)
OFF_PATH = 2.0  # m: a vehicle this far off the circle is no longer held on it (the limit is reached)
SETTLE = 5.0  # s on the circle at the first point's speed before time 0 (the driver's transient dies out)
AVERAGE = 1.0  # s: moving average of a_y for its maximum
DIRECTIONS = (("left", 1.0), ("right", -1.0))  # ISO 4138: left and right turns


def circle(radius: float, direction: float = 1.0, laps: float = 8.0, spacing: float = 0.05):
    """The path: a circle to the left (direction +1, centre (0, R)) or right (-1, centre (0, -R)), from the origin
    heading +x, enough laps for the points and the ramp."""
    angle = np.linspace(0, 2 * math.pi * laps, int(2 * math.pi * radius * laps / spacing))
    return radius * np.sin(angle), direction * radius * (1 - np.cos(angle))


def schedule():
    """(v^2 / R target against time from 0, the points' averaging windows, the ramp's start, the run's duration)."""
    windows, time = [], 0.0
    for _ in POINTS:
        windows.append((time + SETTLE_POINT, time + SETTLE_POINT + AVERAGE_POINT))
        time += SETTLE_POINT + AVERAGE_POINT
    ramp_start = time

    def target(t: float) -> float:
        if t < ramp_start:
            return POINTS[min(int(t // (SETTLE_POINT + AVERAGE_POINT)), len(POINTS) - 1)]
        return POINTS[-1] + RAMP_RATE * (t - ramp_start)

    return target, windows, ramp_start, ramp_start + (MAX_LATERAL - POINTS[-1]) / RAMP_RATE


def circle_run(model, direction: float):
    target, windows, ramp_start, duration = schedule()
    follower = PathFollower(*circle(RADIUS, direction), model.wheelbase)
    hold = SpeedHold(math.sqrt(POINTS[0] * RADIUS))

    def law(time, state):
        hold.target = math.sqrt(target(time) * RADIUS)
        throttle, brake = hold(state.v)
        return throttle, brake, follower.steer(state)

    def lost(time, state):
        return abs(math.hypot(state.x, state.y - direction * RADIUS) - RADIUS) > OFF_PATH

    trace = drive(model, math.sqrt(POINTS[0] * RADIUS), law, duration, stop=lost, settle=SETTLE,
                  settle_steer=follower.steer)
    return trace, windows, ramp_start


def steady_points(trace, windows, direction: float, wheelbase: float):
    """Per averaging window (a_y, delta - L r / v) in the turn's sense, and the largest relative change of speed,
    steer and yaw rate across it (its steadiness)."""
    time = trace["time_s"]
    points, drift = [], 0.0
    for start, end in windows:
        inside = (time >= start) & (time <= end)
        if np.count_nonzero(inside) < 10:
            raise ManoeuvreFailed(f"the vehicle cannot be held on the {RADIUS:.0f} m circle through the linear range "
                                  f"(a_y {POINTS[0]}..{POINTS[-1]} m/s2)")
        v, steer, r = (direction * trace[c][inside] if c != "speed_mps" else trace[c][inside]
                       for c in ("speed_mps", "steer_rad", "yaw_rate_radps"))
        ay = direction * trace["ay_mps2"][inside]
        for values in (v, steer, r):
            drift = max(drift, float(np.ptp(values) / max(abs(np.mean(values)), 1e-9)))
        points.append((float(np.mean(ay)), float(np.mean(steer - wheelbase * r / v))))
    return points, drift


def run(model) -> Outcome:
    outcome = Outcome("steady_state_circular", STANDARD)
    g = STANDARD_GRAVITY
    per_direction, fits = {}, {}
    for label, direction in DIRECTIONS:
        trace, windows, ramp_start = circle_run(model, direction)
        outcome.runs.append((label, trace))
        points, drift = steady_points(trace, windows, direction, model.wheelbase)
        if drift > STEADY_TOLERANCE:
            raise ManoeuvreFailed(f"the vehicle does not settle on the {RADIUS:.0f} m circle ({label}): speed, steer "
                                  f"or yaw rate change by {drift:.1%} over a steady point")
        ay, excess = (np.array(column) for column in zip(*points))
        gradient, offset = np.polyfit(ay, excess, 1)  # rad per m/s^2
        fits[label] = (float(gradient), float(offset))
        ramp = trace["time_s"] >= ramp_start
        window = max(1, int(round(AVERAGE / SAMPLE_PERIOD)))
        smooth = np.convolve(direction * trace["ay_mps2"][ramp], np.ones(window) / window, mode="valid")
        per_direction[label] = {"understeer_gradient_deg_per_g": math.degrees(gradient) * g,
                                "max_lateral_acceleration_mps2": float(np.max(smooth)) if smooth.size else math.nan,
                                "steady_points": [{"lateral_acceleration_mps2": a, "steer_excess_rad": e}
                                                  for a, e in points],
                                "steadiness": drift}
    gradient = float(np.mean([entry["understeer_gradient_deg_per_g"] for entry in per_direction.values()]))
    outcome.metrics = {"radius_m": RADIUS, "understeer_gradient_deg_per_g": gradient,
                       "max_lateral_acceleration_mps2": min(e["max_lateral_acceleration_mps2"]
                                                            for e in per_direction.values()),
                       "linear_range_mps2": [POINTS[0], POINTS[-1]], "directions": per_direction}
    outcome.criteria = ["ISO 4138 sets no limit: reported (left and right turns; understeer gradient: their mean, "
                        "maximum lateral acceleration: the smaller)"]
    outcome.plot = {"fits": fits, "wheelbase": model.wheelbase}
    return outcome
