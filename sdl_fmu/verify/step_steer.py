"""`step_steer`: ISO 7401 lateral transient response, step steer input (time domain), to the left and to the right.

At 80 km/h straight ahead (ISO 7401's standard test speed) the road-wheel angle is ramped in RAMP_TIME (ISO 7401:
the steering input is to be as fast as possible, its rise time not above 0.15 s) to the steer that gives
4 m/s^2 of steady-state lateral acceleration (ISO 7401's standard level), then held; the speed is held by the
driver's pedal. ISO 7401 asks for steps to the left and to the right: each direction's steer is found by repeating
the step (secant on the steady-state a_y, to TARGET_TOLERANCE). The ramp is continuous: during it the FMU's steer
input is updated RAMP_SUBSTEPS times per sample, each time to the ramp's value at the middle of the sub-interval
(drive.drive's steer_function), so the car sees the ramp itself, not a staircase of 10 ms steps lagging it by 5 ms.
Metrics (ISO 7401 definitions, time 0 at 50 % of the steering input), per direction and their mean:
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
RAMP_SUBSTEPS = 10  # steer updates per 10 ms sample during the ramp (1 ms; midpoint values: see the docstring)
DURATION = 4.0  # s after the step: the steady state is the mean of the last STEADY seconds
STEADY = 1.0  # s
ATTEMPTS = 5
RESPONSE_LEVEL = 0.9  # ISO 7401: response time to 90 % of the steady-state value
DIRECTIONS = (("left", 1.0), ("right", -1.0))  # ISO 7401: steps to the left and to the right
METRICS = ("yaw_rate_response_time_s", "yaw_rate_peak_response_time_s", "yaw_rate_overshoot_pct",
           "lateral_acceleration_response_time_s")


def step(amplitude: float):
    """The steer (rad) against time: a linear ramp from 0 at t = 0 to `amplitude` at RAMP_TIME, then held."""
    return lambda time: amplitude * min(max(time / RAMP_TIME, 0.0), 1.0)


def step_run(model, amplitude: float, speed: float, parameters: dict | None = None):
    hold = SpeedHold(speed)

    def law(time, state):
        throttle, brake = hold(state.v)
        return throttle, brake, 0.0

    return drive(model, speed, law, DURATION, parameters=parameters, steer_function=step(amplitude),
                 substeps=lambda time: RAMP_SUBSTEPS if time < RAMP_TIME else 1)


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
    """ISO 7401's time-domain metrics of one step run (time 0 at 50 % of the steering input), for either direction
    (the responses are taken in the sense of their steady state)."""
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


def find_step(model, speed: float, direction: float, first_guess: float):
    """(steer, trace) of the step to `direction` (+1 left, -1 right) whose steady-state |a_y| is TARGET_LATERAL, by the
    secant method on the steer's magnitude, from first_guess (rad, > 0); the runs tried are returned too."""
    amplitude, previous, tried = first_guess, None, []
    for _ in range(ATTEMPTS):
        trace = step_run(model, direction * amplitude, speed)
        tried.append(trace)
        ay = direction * steady(trace, "ay_mps2")
        if abs(ay - TARGET_LATERAL) <= TARGET_TOLERANCE:
            return amplitude, trace
        if not math.isfinite(ay) or ay <= 0:
            side = "left" if direction > 0 else "right"
            raise ManoeuvreFailed(f"the vehicle gives no steady lateral acceleration to the {side} for a steer of "
                                  f"{amplitude:.4f} rad")
        if previous is not None and abs(ay - previous[1]) > 1e-6:  # secant
            slope = (ay - previous[1]) / (amplitude - previous[0])
            previous, amplitude = (amplitude, ay), amplitude + (TARGET_LATERAL - ay) / slope
        else:
            previous, amplitude = (amplitude, ay), amplitude * TARGET_LATERAL / ay
    raise ManoeuvreFailed(f"no steer found that gives {TARGET_LATERAL} m/s2 of steady-state lateral "
                          f"acceleration in {ATTEMPTS} steps (last {ay:.2f} m/s2)")


def run(model) -> Outcome:
    outcome = Outcome("step_steer", STANDARD)
    speed = SPEED_KMH * KILOMETRE_PER_HOUR
    guess = model.wheelbase * TARGET_LATERAL / speed**2  # Ackermann steer: a first guess for the left step
    per_direction = {}
    for label, direction in DIRECTIONS:
        amplitude, trace = find_step(model, speed, direction, guess)
        guess = amplitude  # the right step starts from the left one's steer (a symmetric car needs no more)
        per_direction[label] = {"steer_rad": direction * amplitude, **response_metrics(trace)}
        outcome.runs.append((f"{label} {amplitude:.5f} rad", trace))
    means = {}
    for key in METRICS:
        values = [entry[key] for entry in per_direction.values()]
        means[key] = None if any(v is None for v in values) else float(np.mean(values))
    outcome.metrics = {"speed_kmh": SPEED_KMH, "steer_rad": per_direction["left"]["steer_rad"], **means,
                       "directions": per_direction}
    outcome.criteria = ["ISO 7401 sets no limit: reported (left and right; the metrics are their mean)"]
    outcome.plot = {"ramp_time": RAMP_TIME}
    return outcome
