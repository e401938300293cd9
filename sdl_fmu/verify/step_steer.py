"""`step_steer`: ISO 7401 lateral transient response, step steer input (time domain).

At 80 km/h straight ahead (ISO 7401's standard test speed) the road-wheel angle is ramped in RAMP_TIME (ISO 7401:
the steering input is to be as fast as possible, its rise time not above 0.15 s) to the steer that gives
4 m/s^2 of steady-state lateral acceleration (ISO 7401's standard level), then held; the speed is held by the
driver's pedal. The steer is found by repeating the step (secant on the steady-state a_y, to TARGET_TOLERANCE).
Metrics (ISO 7401 definitions, time 0 at 50 % of the steering input):
  yaw_rate_response_time_s: until the yaw rate first reaches 90 % of its steady-state value;
  yaw_rate_peak_response_time_s: until the yaw rate's peak (null without overshoot);
  yaw_rate_overshoot_pct: (peak - steady state) / steady state x 100;
  lateral_acceleration_response_time_s: until a_y first reaches 90 % of its steady-state value.
ISO 7401 sets no pass/fail limit: `passed` is null.
"""

from __future__ import annotations

import math

import numpy as np

from ..units import KILOMETRE_PER_HOUR
from .drive import ManoeuvreFailed, SpeedHold, drive
from .outcome import Outcome

STANDARD = "ISO 7401 step steer input"
SPEED_KMH = 80.0  # ISO 7401: test speed 80 km/h
TARGET_LATERAL = 4.0  # m/s^2, ISO 7401: steady-state lateral acceleration 4 m/s^2
TARGET_TOLERANCE = 0.1  # m/s^2 (sdl-fmu's choice)
RAMP_TIME = 0.1  # s: within ISO 7401's 0.15 s
DURATION = 4.0  # s after the step: the steady state is the mean of the last STEADY seconds
STEADY = 1.0  # s
ATTEMPTS = 5
RESPONSE_LEVEL = 0.9  # ISO 7401: response time to 90 % of the steady-state value


def step(amplitude: float):
    return lambda time: amplitude * min(max(time / RAMP_TIME, 0.0), 1.0)


def step_run(model, amplitude: float, speed: float, parameters: dict | None = None):
    steer = step(amplitude)
    hold = SpeedHold(speed)

    def law(time, state):
        throttle, brake = hold(state.v)
        return throttle, brake, steer(time)

    return drive(model, speed, law, DURATION, parameters=parameters)


def steady(trace, column: str) -> float:
    late = trace["time_s"] >= trace["time_s"][-1] - STEADY
    return float(np.mean(trace[column][late]))


def crossing(time: np.ndarray, values: np.ndarray, level: float) -> float | None:
    """The first time `values` reaches `level` (rising), linearly interpolated; None if never."""
    above = np.nonzero(values >= level)[0]
    if above.size == 0:
        return None
    i = above[0]
    if i == 0:
        return float(time[0])
    return float(time[i - 1] + (level - values[i - 1]) / (values[i] - values[i - 1]) * (time[i] - time[i - 1]))


def response_metrics(trace) -> dict:
    """ISO 7401's time-domain metrics of one step run (time 0 at 50 % of the steering input)."""
    after = trace["time_s"] >= 0
    time = trace["time_s"][after] - RAMP_TIME / 2
    r, ay = trace["yaw_rate_radps"][after], trace["ay_mps2"][after]
    r_ss, ay_ss = steady(trace, "yaw_rate_radps"), steady(trace, "ay_mps2")
    sign = 1.0 if r_ss >= 0 else -1.0
    peak_index = int(np.argmax(sign * r))
    peak = sign * r[peak_index]
    overshoot = (peak - abs(r_ss)) / abs(r_ss) * 100
    has_peak = overshoot > 0.1 and peak_index < len(r) - 1  # a peak inside the run, above the steady state
    return {
        "yaw_rate_response_time_s": crossing(time, sign * r, RESPONSE_LEVEL * abs(r_ss)),
        "yaw_rate_peak_response_time_s": float(time[peak_index]) if has_peak else None,
        "yaw_rate_overshoot_pct": float(max(overshoot, 0.0)) if has_peak else 0.0,
        "lateral_acceleration_response_time_s": crossing(time, sign * ay, RESPONSE_LEVEL * abs(ay_ss)),
        "steady_state_yaw_rate_radps": r_ss, "steady_state_lateral_acceleration_mps2": ay_ss,
    }


def run(model) -> Outcome:
    outcome = Outcome("step_steer", STANDARD)
    speed = SPEED_KMH * KILOMETRE_PER_HOUR
    amplitude = model.wheelbase * TARGET_LATERAL / speed**2  # Ackermann steer: a first guess
    previous = None
    for attempt in range(ATTEMPTS):
        trace = step_run(model, amplitude, speed)
        outcome.runs.append((f"steer {amplitude:.5f} rad", trace))
        ay = steady(trace, "ay_mps2")
        if abs(ay - TARGET_LATERAL) <= TARGET_TOLERANCE:
            break
        if not math.isfinite(ay) or ay <= 0:
            raise ManoeuvreFailed(f"the vehicle gives no steady lateral acceleration to the left for a steer of "
                                  f"{amplitude:.4f} rad")
        if previous is not None and abs(ay - previous[1]) > 1e-6:  # secant
            slope = (ay - previous[1]) / (amplitude - previous[0])
            previous, amplitude = (amplitude, ay), amplitude + (TARGET_LATERAL - ay) / slope
        else:
            previous, amplitude = (amplitude, ay), amplitude * TARGET_LATERAL / ay
    else:
        raise ManoeuvreFailed(f"no steer found that gives {TARGET_LATERAL} m/s2 of steady-state lateral "
                              f"acceleration in {ATTEMPTS} steps (last {ay:.2f} m/s2)")
    outcome.runs = outcome.runs[-1:]
    outcome.metrics = {"speed_kmh": SPEED_KMH, "steer_rad": amplitude, **response_metrics(trace)}
    outcome.criteria = ["ISO 7401 sets no limit: reported"]
    outcome.plot = {"ramp_time": RAMP_TIME}
    return outcome
