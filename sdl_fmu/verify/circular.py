"""`steady_state_circular`: ISO 4138 steady-state circular driving, constant-radius method.

The driver holds the vehicle on a circle of 100 m radius (ISO 4138's recommended radius) while the speed is
raised slowly (quasi-steady: the lateral acceleration v^2 / R grows by RAMP_RATE per second, sdl-fmu's
choice) from a low speed until the vehicle can no longer be held on the circle or stops gaining lateral
acceleration. Metrics (ISO 4138 / ISO 8855 terms):
  understeer gradient = d(delta - delta_Ackermann) / d a_y in the linear range, delta_Ackermann = L r / v
  (the steer a vehicle without slip needs for the path's actual curvature r / v), fitted by least squares
  over LINEAR_RANGE, reported in degrees of road-wheel angle per g;
  maximum lateral acceleration: the largest a_y held (1 s moving average).
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
START_LATERAL = 0.5  # m/s^2 at the start speed
RAMP_RATE = 0.1  # m/s^2 of v^2 / R per second: quasi-steady (sdl-fmu's choice)
LINEAR_RANGE = (0.5, 2.0)  # m/s^2: where the understeer gradient is fitted (the linear range of a car)
MAX_LATERAL = 12.0  # m/s^2: the ramp ends here at the latest (beyond any road tire)
OFF_PATH = 2.0  # m: a vehicle this far off the circle is no longer held on it (the limit is reached)
SETTLE = 5.0  # s on the circle at the start speed before the ramp (the driver's transient dies out)
AVERAGE = 1.0  # s: moving average of a_y for its maximum


def circle(radius: float, laps: float = 8.0, spacing: float = 0.05):
    """The path: a circle to the left (centre (0, R)), from the origin heading +x, enough laps for the ramp."""
    angle = np.linspace(0, 2 * math.pi * laps, int(2 * math.pi * radius * laps / spacing))
    return radius * np.sin(angle), radius * (1 - np.cos(angle))


def run(model) -> Outcome:
    outcome = Outcome("steady_state_circular", STANDARD)
    v_start = math.sqrt(START_LATERAL * RADIUS)
    duration = (MAX_LATERAL - START_LATERAL) / RAMP_RATE
    follower = PathFollower(*circle(RADIUS), model.wheelbase)
    hold = SpeedHold(v_start)

    def law(time, state):
        hold.target = math.sqrt((START_LATERAL + RAMP_RATE * time) * RADIUS)
        throttle, brake = hold(state.v)
        return throttle, brake, follower.steer(state)

    def lost(time, state):
        return abs(math.hypot(state.x, state.y - RADIUS) - RADIUS) > OFF_PATH

    trace = drive(model, v_start, law, duration, stop=lost, settle=SETTLE, settle_steer=follower.steer)
    outcome.runs.append(("ramp", trace))
    after = trace["time_s"] >= 0
    ay, r, v, steer = (trace[c][after] for c in ("ay_mps2", "yaw_rate_radps", "speed_mps", "steer_rad"))
    window = max(1, int(round(AVERAGE / SAMPLE_PERIOD)))
    smooth = np.convolve(ay, np.ones(window) / window, mode="valid")
    max_lateral = float(np.max(smooth)) if smooth.size else float("nan")
    linear = (ay >= LINEAR_RANGE[0]) & (ay <= LINEAR_RANGE[1])
    if np.count_nonzero(linear) < 50:
        raise ManoeuvreFailed(f"the vehicle cannot be held on the {RADIUS:.0f} m circle through the linear range "
                              f"(a_y {LINEAR_RANGE[0]}..{LINEAR_RANGE[1]} m/s2)")
    excess = steer - model.wheelbase * r / v  # delta - delta_Ackermann for the actual path curvature
    gradient, offset = np.polyfit(ay[linear], excess[linear], 1)  # rad per m/s^2
    per_g = math.degrees(gradient) * STANDARD_GRAVITY
    outcome.metrics = {"radius_m": RADIUS, "understeer_gradient_deg_per_g": per_g,
                       "max_lateral_acceleration_mps2": max_lateral,
                       "linear_range_mps2": list(LINEAR_RANGE)}
    outcome.criteria = ["ISO 4138 sets no limit: reported"]
    outcome.plot = {"gradient": gradient, "offset": offset, "wheelbase": model.wheelbase}
    return outcome
