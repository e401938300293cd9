"""`split_mu_braking`: ISO 14512 straight-ahead braking on a split-friction surface (open loop).

From 100 km/h straight ahead, throttle released, the steering held straight, on MU_LEFT under the left wheels and
MU_RIGHT under the right ones (ISO 14512's high / low pair). ISO 14512 applies to a vehicle without ABS only up to
the locking limit of the wheels on the high-friction side: the brake effort is the highest at which they do not lock.
The pack finds that effort from the car's deceleration (effort.locking_limit): it
grows with the pedal while the high-friction wheels roll, by at least EFFORT_GROWTH per unit pedal, and the stop is
braked at the highest pedal found to still grow so (full pedal for a vehicle whose deceleration grows all the way:
ABS, or brakes weaker than the tires). The low-friction wheels lock first, at a far lower pedal; the high-friction side's brake force keeps the deceleration
growing past it. Metrics: the brake pedal of the stop; the largest yaw angle during the stop (ISO 14512 reports the
largest yaw) and the yaw angle at the stop and 2 s after the brake application, lateral deviation of the centre of
gravity at the stop, stopping distance. ISO 14512 sets no pass/fail limit: `passed` is null. A vehicle without a
friction input cannot run it, nor can one whose friction input is not per wheel (not applicable, `passed` null).
"""

from __future__ import annotations

import math

import numpy as np

from ..units import KILOMETRE_PER_HOUR, STANDARD_GRAVITY
from .drive import ManoeuvreFailed, drive
from .effort import Probes, locking_limit
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
# the brake effort at the high-friction wheels' locking limit (effort.locking_limit): the deceleration must grow by
# at least a quarter of the high-friction side's share of a 1 g pedal, 0.5 g per unit pedal (the low-friction
# wheels, locked long before, add nothing; the high-friction ones, rolling, all their share)
EFFORT_GROWTH = 0.25 * 0.5 * STANDARD_GRAVITY  # m/s^2 per unit pedal


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
    probes = Probes(model, speed, values)
    pedal = locking_limit(probes, EFFORT_GROWTH)
    if pedal <= 0:
        raise ManoeuvreFailed("no brake pedal decelerates the vehicle on the split-friction surface")
    trace = drive(model, speed, lambda t, state: (0.0, pedal, 0.0), TIME_LIMIT, friction=values,
                  stop=lambda t, state: t > 0 and (state.stopped or state.v < STOP_SPEED))
    outcome.runs.append((f"stop, brake {pedal:.3f}", trace))
    after = trace["time_s"] >= 0
    time, speed_after = trace["time_s"][after], trace["speed_mps"][after]
    if speed_after[-1] >= STOP_SPEED:
        raise ManoeuvreFailed(f"the vehicle does not stop within {TIME_LIMIT:.0f} s of braking at pedal {pedal:.3f}")
    yaw0 = trace.at("yaw_rad", 0.0)
    yaw = trace["yaw_rad"][after] - yaw0
    largest = int(np.argmax(np.abs(yaw)))
    distance = trace["distance_m"][after]
    outcome.metrics = {
        "friction": {"meaning": model.friction.meaning, "left": values[0], "right": values[1]},
        "brake_pedal": pedal,
        "max_yaw_angle_deg": math.degrees(yaw[largest]),
        "yaw_angle_deg": math.degrees(yaw[-1]),
        "yaw_angle_2s_deg": math.degrees(trace.at("yaw_rad", min(YAW_TIME, time[-1])) - yaw0),
        "lateral_deviation_m": float(trace["y_m"][-1] - trace.at("y_m", 0.0)),
        "stopping_distance_m": float(distance[-1] - distance[0]),
        "stopping_time_s": float(time[-1]),
        "max_yaw_rate_degps": float(np.degrees(np.max(np.abs(trace["yaw_rate_radps"][after])))),
        "effort_probes": probes.runs,
    }
    outcome.criteria = [f"ISO 14512 sets no limit: reported, at brake {pedal:.3f} (the high-friction wheels' "
                        "locking limit)"]
    return outcome
