"""`sine_with_dwell`: FMVSS No. 126 (49 CFR 571.126) sine with dwell, with its slowly increasing steer test.

Slowly increasing steer (S7.6): at 80 km/h the steer grows at 13.5 deg/s of steering-wheel angle, here
13.5 / STEERING_RATIO deg/s of road-wheel angle (sdl-fmu drives road-wheel angles), until 0.5 g; A is the
steer that gives 0.3 g, from a least-squares line of steer against a_y between 0.1 g and 0.5 g.
Sine with dwell (S7.7): from 80 km/h, throttle released, a 0.7 Hz sine whose second peak is held for 500 ms;
amplitudes 1.5 A, 2 A, ... 6.5 A, each to the left first and to the right first. Per run (S5.2):
  yaw_rate_ratio_1_00s = yaw rate 1.00 s after the completion of steer (COSI) / first peak yaw rate after the
    steer reverses; must be <= 0.35 (S5.2.1);
  yaw_rate_ratio_1_75s: the same 1.75 s after COSI; must be <= 0.20 (S5.2.2);
  lateral_displacement_1_07s_m: lateral displacement of the centre of gravity from its initial straight path
    1.07 s after the beginning of steer (BOS), toward the first steer; must be >= 1.83 m (S5.2.3, vehicles up
    to 3,500 kg GVWR) in runs of 5 A and more.
"""

from __future__ import annotations

import math

import numpy as np

from ..units import KILOMETRE_PER_HOUR, STANDARD_GRAVITY
from .drive import ManoeuvreFailed, SpeedHold, drive
from .outcome import Outcome

STANDARD = "FMVSS 126 (49 CFR 571.126) sine with dwell"
SPEED_KMH = 80.0  # S7.6, S7.7: 80 +/- 2 km/h
STEERING_RATIO = 16.0  # steering-wheel to road-wheel angle (a typical passenger car; sdl-fmu's assumption)
SIS_RATE = math.radians(13.5) / STEERING_RATIO  # rad/s road wheel: S7.6, 13.5 deg/s of steering-wheel angle
SIS_END_G = 0.5  # S7.6: until about 0.5 g
SIS_MAX_STEER = math.radians(20.0)  # road wheel: the ramp gives up here (a car that never reaches 0.5 g)
SIS_FIT_G = (0.1, 0.5)  # g: the range of the steer / a_y line (sdl-fmu's choice)
A_LEVEL_G = 0.3  # S7.6: A is the steer giving 0.3 g
FREQUENCY = 0.7  # Hz, S7.7
DWELL = 0.5  # s, S7.7: 500 ms at the second peak
AMPLITUDES = tuple(1.5 + 0.5 * k for k in range(11))  # x A, S7.7: from 1.5 A in steps of 0.5 A to 6.5 A
RATIO_1_00_MAX = 0.35  # S5.2.1
RATIO_1_75_MAX = 0.20  # S5.2.2
DISPLACEMENT_MIN = 1.83  # m, S5.2.3 (GVWR <= 3,500 kg)
DISPLACEMENT_FROM = 5.0  # x A: S5.2.3 applies to runs of 5 A and more
DISPLACEMENT_TIME = 1.07  # s after BOS, S5.2.3
COSI = 1 / FREQUENCY + DWELL  # s after BOS: the completion of steer
AFTER_COSI = (1.00, 1.75)  # s, S5.2.1 and S5.2.2


def sine_with_dwell(amplitude: float, direction: float):
    """The steer (rad) against time from BOS: a 0.7 Hz sine, its second peak held for DWELL."""
    period = 1 / FREQUENCY
    sign = direction * amplitude

    def steer(time: float) -> float:
        if time <= 0:
            return 0.0
        if time < 0.75 * period:
            return sign * math.sin(2 * math.pi * FREQUENCY * time)
        if time < 0.75 * period + DWELL:
            return -sign
        if time < period + DWELL:
            return sign * math.sin(2 * math.pi * FREQUENCY * (time - DWELL))
        return 0.0

    return steer


def slowly_increasing_steer(model, speed: float):
    """A (rad of road-wheel angle at 0.3 g) and the run's trace."""
    hold = SpeedHold(speed)

    def law(time, state):
        throttle, brake = hold(state.v)
        return throttle, brake, SIS_RATE * time

    g = STANDARD_GRAVITY
    trace = drive(model, speed, law, SIS_MAX_STEER / SIS_RATE, stop=lambda time, state: state.ay >= SIS_END_G * g)
    after = trace["time_s"] >= 0
    ay, steer = trace["ay_mps2"][after], trace["steer_rad"][after]
    fit = (ay >= SIS_FIT_G[0] * g) & (ay <= SIS_FIT_G[1] * g)
    if ay.max() < A_LEVEL_G * g or np.count_nonzero(fit) < 20:
        raise ManoeuvreFailed(f"the slowly increasing steer test does not reach {A_LEVEL_G} g "
                              f"(at most {ay.max() / g:.2f} g)")
    slope, offset = np.polyfit(ay[fit], steer[fit], 1)
    return float(slope * A_LEVEL_G * g + offset), trace


def run_metrics(trace, direction: float) -> dict:
    time, r = trace["time_s"], trace["yaw_rate_radps"]
    toward = -direction  # the yaw during and after the dwell turns against the first steer
    reversal = time >= 0.5 / FREQUENCY  # the steer changes sign here
    window = reversal & (time <= COSI + AFTER_COSI[1])
    values = toward * r[window]
    # the first local peak after the reversal (the largest value if the yaw rate never turns back)
    peaks = np.nonzero((values[1:-1] >= values[:-2]) & (values[1:-1] > values[2:]) & (values[1:-1] > 0))[0]
    peak = float(values[peaks[0] + 1]) if peaks.size else float(values.max())
    if peak <= 0:
        raise ManoeuvreFailed("the vehicle does not yaw against the first steer after it reverses")
    ratios = [toward * trace.at("yaw_rate_radps", COSI + delay) / peak for delay in AFTER_COSI]
    # lateral displacement from the initial straight path (heading and position at BOS), toward the first steer
    x0, y0, psi0 = trace.at("x_m", 0.0), trace.at("y_m", 0.0), trace.at("yaw_rad", 0.0)
    x, y = trace.at("x_m", DISPLACEMENT_TIME), trace.at("y_m", DISPLACEMENT_TIME)
    lateral = -(x - x0) * math.sin(psi0) + (y - y0) * math.cos(psi0)
    return {"peak_yaw_rate_radps": peak, "yaw_rate_ratio_1_00s": ratios[0], "yaw_rate_ratio_1_75s": ratios[1],
            "lateral_displacement_1_07s_m": direction * lateral}


def run(model) -> Outcome:
    outcome = Outcome("sine_with_dwell", STANDARD)
    speed = SPEED_KMH * KILOMETRE_PER_HOUR
    a, sis = slowly_increasing_steer(model, speed)
    outcome.runs.append(("slowly increasing steer", sis))
    runs = []
    for direction, label in ((1.0, "left"), (-1.0, "right")):
        for multiple in AMPLITUDES:
            steer = sine_with_dwell(multiple * a, direction)
            trace = drive(model, speed, lambda time, state, steer=steer: (0.0, 0.0, steer(time)),
                          COSI + AFTER_COSI[1] + 0.25)
            metrics = run_metrics(trace, direction)
            checks = [metrics["yaw_rate_ratio_1_00s"] <= RATIO_1_00_MAX,
                      metrics["yaw_rate_ratio_1_75s"] <= RATIO_1_75_MAX]
            if multiple >= DISPLACEMENT_FROM:
                checks.append(metrics["lateral_displacement_1_07s_m"] >= DISPLACEMENT_MIN)
            runs.append({"direction": label, "amplitude_A": multiple, "steer_rad": multiple * a, **metrics,
                         "passed": all(checks)})
            outcome.runs.append((f"{label} {multiple:g}A", trace))
    worst_1 = max(r["yaw_rate_ratio_1_00s"] for r in runs)
    worst_175 = max(r["yaw_rate_ratio_1_75s"] for r in runs)
    least = min(r["lateral_displacement_1_07s_m"] for r in runs if r["amplitude_A"] >= DISPLACEMENT_FROM)
    outcome.metrics = {"speed_kmh": SPEED_KMH, "steer_A_rad": a, "steering_ratio_assumed": STEERING_RATIO,
                       "yaw_rate_ratio_1_00s": worst_1, "yaw_rate_ratio_1_75s": worst_175,
                       "lateral_displacement_1_07s_m": least, "runs": runs}
    ok = [worst_1 <= RATIO_1_00_MAX, worst_175 <= RATIO_1_75_MAX, least >= DISPLACEMENT_MIN]
    outcome.criteria = [
        f"largest yaw-rate ratio 1.00 s after COSI {worst_1:.3f} <= {RATIO_1_00_MAX}: {'pass' if ok[0] else 'FAIL'}",
        f"largest yaw-rate ratio 1.75 s after COSI {worst_175:.3f} <= {RATIO_1_75_MAX}: {'pass' if ok[1] else 'FAIL'}",
        f"least lateral displacement 1.07 s after BOS (runs >= {DISPLACEMENT_FROM:g} A) {least:.2f} m >= "
        f"{DISPLACEMENT_MIN} m: {'pass' if ok[2] else 'FAIL'}"]
    outcome.passed = all(ok)
    outcome.plot = {"cosi": COSI, "after_cosi": AFTER_COSI, "limits": (RATIO_1_00_MAX, RATIO_1_75_MAX)}
    return outcome
