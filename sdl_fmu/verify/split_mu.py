"""`split_mu_braking`: ISO 14512 straight-ahead braking on a split-friction surface (open loop).

From 100 km/h straight ahead, full brake, throttle released, the steering held straight, on MU_LEFT under the
left wheels and MU_RIGHT under the right ones (ISO 14512's high / low pair). Metrics: yaw angle at the stop
and 2 s after the brake application, lateral deviation of the centre of gravity at the stop, stopping
distance. ISO 14512 sets no pass/fail limit: `passed` is null. A vehicle without a friction input cannot
run it, nor can one whose friction input is not per wheel (not applicable, `passed` null).
"""

from __future__ import annotations

import math

import numpy as np

from ..units import KILOMETRE_PER_HOUR
from .drive import ManoeuvreFailed, drive
from .outcome import Outcome

STANDARD = "ISO 14512 straight-ahead braking on split friction"
SPEED_KMH = 100.0
MU_LEFT, MU_RIGHT = 0.8, 0.2  # ISO 14512: high-mu (dry) left, low-mu right
# Friction given as surface attribute numbers: the default Tire Attribute File's dry asphalt (0, peak 0.85)
# and packed snow (2, peak 0.2) (scenarios/tires/attributes.txt)
ATTRIBUTE_LEFT, ATTRIBUTE_RIGHT = 0, 2
YAW_TIME = 2.0  # s after the brake application
STOP_SPEED = 0.01  # m/s
TIME_LIMIT = 30.0  # s


def friction_values(meaning: str) -> tuple[float, float, float, float]:
    left, right = (MU_LEFT, MU_RIGHT) if meaning == "mu" else (ATTRIBUTE_LEFT, ATTRIBUTE_RIGHT)
    return left, right, left, right  # fl fr rl rr


def run(model) -> Outcome:
    outcome = Outcome("split_mu_braking", STANDARD)
    if model.friction is None:
        outcome.reason = "not applicable: the vehicle has no friction input"
        outcome.criteria = ["not applicable"]
        return outcome
    if len(model.friction.variables) != 4:
        outcome.reason = ("not applicable: the vehicle's friction input is not per wheel "
                          f"({', '.join(model.friction.variables)}), so left and right cannot differ")
        outcome.criteria = ["not applicable"]
        return outcome
    speed = SPEED_KMH * KILOMETRE_PER_HOUR
    values = friction_values(model.friction.meaning)
    trace = drive(model, speed, lambda t, state: (0.0, 1.0, 0.0), TIME_LIMIT, friction=values,
                  stop=lambda t, state: t > 0 and (state.stopped or state.v < STOP_SPEED))
    outcome.runs.append(("stop", trace))
    after = trace["time_s"] >= 0
    time, speed_after = trace["time_s"][after], trace["speed_mps"][after]
    if speed_after[-1] >= STOP_SPEED:
        raise ManoeuvreFailed(f"the vehicle does not stop within {TIME_LIMIT:.0f} s of full braking")
    yaw0 = trace.at("yaw_rad", 0.0)
    distance = trace["distance_m"][after]
    outcome.metrics = {
        "friction": {"meaning": model.friction.meaning, "left": values[0], "right": values[1]},
        "yaw_angle_deg": math.degrees(trace["yaw_rad"][-1] - yaw0),
        "yaw_angle_2s_deg": math.degrees(trace.at("yaw_rad", min(YAW_TIME, time[-1])) - yaw0),
        "lateral_deviation_m": float(trace["y_m"][-1] - trace.at("y_m", 0.0)),
        "stopping_distance_m": float(distance[-1] - distance[0]),
        "stopping_time_s": float(time[-1]),
        "max_yaw_rate_degps": float(np.degrees(np.max(np.abs(trace["yaw_rate_radps"][after])))),
    }
    outcome.criteria = ["ISO 14512 sets no limit: reported"]
    return outcome
