"""`sine_with_dwell`: FMVSS No. 126 (49 CFR 571.126) sine with dwell, with its slowly increasing steer tests.

sdl-fmu drives road-wheel angles: the rule's steering-wheel angles (SWA) are turned into road-wheel angles at an
assumed STEERING_RATIO (16:1, recorded in verify.json). Every number below cites its clause.
Slowly increasing steer (S7.6.1): at 80 km/h held constant, the SWA grows at 13.5 deg/s until about 0.5 g; two series,
one counterclockwise (left) and one clockwise (right), three runs each. S7.6.2: A is the SWA that produces 0.3 g,
calculated by linear regression from each of the six runs to the nearest 0.1 deg; the absolute values of the six are
averaged and rounded to the nearest 0.1 deg. The regression range is not in the rule: sdl-fmu fits SWA against a_y
between 0.2 g and 0.4 g, centred on 0.3 g (a curved characteristic biases a straight line's value at the centre of
its range by half its curvature times the range's variance, the least there; a wider 0.1-0.5 g fit gave +0.9 % A on
the Advanced car). The runs of a series repeat one simulation, identical to the last bit; they are run all the same.
Sine with dwell (S7.9): two series of runs, a 0.7 Hz sine whose second peak is held for 500 ms (S7.9.1), one starting
counterclockwise (left), one clockwise (right), from 80 km/h coasting (S7.9.2: throttle released). The first run's
amplitude is 1.5 A (S7.9.3); each next run 0.5 A more, up to the final run's: the greater of 6.5 A and 270 deg, or
300 deg if any 0.5 A increment up to 6.5 A is beyond 300 deg (S7.9.4). Times (S7.11): the beginning of steer (BOS) is
the instant the SWA reaches 5 deg (S7.11.6); the completion of steer (COS) the instant it returns to zero after the
dwell (S7.11.7); the second peak yaw rate the first local peak produced by the reversal of the steering wheel
(S7.11.8). The steer is applied continuously (drive.drive's steer_function: midpoint values), so BOS and COS are
interpolated on the exact input. Per run (S5.2):
  yaw_rate_ratio_1_00s = yaw rate 1.00 s after COS / the second peak yaw rate; must be <= 0.35 (S5.2.1);
  yaw_rate_ratio_1_75s: the same 1.75 s after COS; must be <= 0.20 (S5.2.2);
  lateral_displacement_1_07s_m: lateral displacement of the centre of gravity from its initial straight path (its
    position and heading at BOS) 1.07 s after BOS, toward the first steer; must be >= 1.83 m (S5.2.3, vehicles up
    to 3,500 kg GVWR) in runs of 5 A and more. The rule obtains it by integrating the measured lateral acceleration
    twice (S7.11.9); a simulation has the position itself.
The rule's filtering and zeroing of measured channels (S7.11.1-S7.11.5) have nothing to remove from simulated data.
"""

from __future__ import annotations

import math

import numpy as np

from ..units import KILOMETRE_PER_HOUR, STANDARD_GRAVITY
from .drive import ManoeuvreFailed, SpeedHold, drive
from .outcome import Outcome

STANDARD = "FMVSS 126 (49 CFR 571.126) sine with dwell"
SPEED_KMH = 80.0  # S7.6.1, S7.9.2: 80 +/- 2 km/h
STEERING_RATIO = 16.0  # steering-wheel to road-wheel angle (a typical passenger car; sdl-fmu's assumption)
SIS_RATE_SWA = 13.5  # deg/s of steering-wheel angle, S7.6.1
SIS_END_G = 0.5  # S7.6.1: until approximately 0.5 g
SIS_REPETITIONS = 3  # S7.6.1: three runs per series
SIS_MAX_SWA = 360.0  # deg: the ramp gives up here (a car that never reaches 0.5 g; sdl-fmu's choice)
SIS_FIT_G = (0.2, 0.4)  # g: the regression range, centred on A_LEVEL_G (sdl-fmu's choice; see the docstring)
A_LEVEL_G = 0.3  # S7.6.2: A is the SWA that produces 0.3 g
A_ROUNDING = 0.1  # deg, S7.6.2
FREQUENCY = 0.7  # Hz, S7.9.1
DWELL = 0.5  # s, S7.9.1: 500 ms at the second peak
FIRST_MULTIPLE, INCREMENT = 1.5, 0.5  # x A, S7.9.3 and S7.9.4
LAST_MULTIPLE = 6.5  # x A, S7.9.4
LAST_MINIMUM_SWA, LAST_CAP_SWA = 270.0, 300.0  # deg, S7.9.4
BOS_SWA = 5.0  # deg, S7.11.6: the beginning of steer
RATIO_1_00_MAX = 0.35  # S5.2.1
RATIO_1_75_MAX = 0.20  # S5.2.2
DISPLACEMENT_MIN = 1.83  # m, S5.2.3 (GVWR <= 3,500 kg)
DISPLACEMENT_FROM = 5.0  # x A: S5.2.3 applies to runs of 5 A and more
DISPLACEMENT_TIME = 1.07  # s after BOS, S5.2.3
COS = 1 / FREQUENCY + DWELL  # s after the steer starts: the completion of steer (S7.11.7)
AFTER_COS = (1.00, 1.75)  # s, S5.2.1 and S5.2.2
DIRECTIONS = (("left", 1.0), ("right", -1.0))  # S7.6.1, S7.9.1: counterclockwise and clockwise


def amplitudes(a_swa: float) -> list[float]:
    """The SWA amplitudes (deg) of one series of runs (S7.9.3, S7.9.4): 1.5 A, 2 A, ... in steps of 0.5 A, the final
    run the greater of 6.5 A and 270 deg, or 300 deg if any 0.5 A increment up to 6.5 A is beyond 300 deg."""
    steps = [a_swa * (FIRST_MULTIPLE + INCREMENT * k)
             for k in range(int(round((LAST_MULTIPLE - FIRST_MULTIPLE) / INCREMENT)) + 1)]
    if any(step > LAST_CAP_SWA for step in steps):
        final = LAST_CAP_SWA
    else:
        final = max(LAST_MULTIPLE * a_swa, LAST_MINIMUM_SWA)
    runs, k = [], 0
    while a_swa * (FIRST_MULTIPLE + INCREMENT * k) < final - 1e-9:
        runs.append(a_swa * (FIRST_MULTIPLE + INCREMENT * k))
        k += 1
    return runs + [final]


def sine_with_dwell(amplitude: float, direction: float):
    """The steer (rad) against time from the start of the steer: a 0.7 Hz sine, its second peak held for DWELL."""
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


def beginning_of_steer(amplitude_swa: float) -> float:
    """BOS (S7.11.6): the time after the start of the sine at which the SWA reaches 5 deg."""
    return math.asin(BOS_SWA / amplitude_swa) / (2 * math.pi * FREQUENCY)


def slowly_increasing_steer(model, speed: float, direction: float):
    """One slowly increasing steer run (S7.6.1): (A in deg of SWA from its regression, S7.6.2; the run's trace)."""
    hold = SpeedHold(speed)
    rate = direction * math.radians(SIS_RATE_SWA) / STEERING_RATIO  # rad/s of road-wheel angle

    def law(time, state):
        throttle, brake = hold(state.v)
        return throttle, brake, 0.0

    g = STANDARD_GRAVITY
    trace = drive(model, speed, law, SIS_MAX_SWA / SIS_RATE_SWA, steer_function=lambda time: rate * max(time, 0.0),
                  stop=lambda time, state: direction * state.ay >= SIS_END_G * g)
    after = trace["time_s"] >= 0
    ay = direction * trace["ay_mps2"][after]
    swa = np.degrees(direction * trace["steer_rad"][after]) * STEERING_RATIO
    fit = (ay >= SIS_FIT_G[0] * g) & (ay <= SIS_FIT_G[1] * g)
    if ay.max() < SIS_FIT_G[1] * g or np.count_nonzero(fit) < 20:
        raise ManoeuvreFailed(f"the slowly increasing steer test does not reach {SIS_FIT_G[1]} g "
                              f"(at most {ay.max() / g:.2f} g)")
    slope, offset = np.polyfit(ay[fit], swa[fit], 1)
    return round((slope * A_LEVEL_G * g + offset) / A_ROUNDING) * A_ROUNDING, trace


def run_metrics(trace, direction: float, amplitude_swa: float) -> dict:
    time, r = trace["time_s"], trace["yaw_rate_radps"]
    toward = -direction  # the yaw during and after the dwell turns against the first steer
    reversal = time >= 0.5 / FREQUENCY  # the steer changes sign here
    window = reversal & (time <= COS + AFTER_COS[1])
    values = toward * r[window]
    # the first local peak after the reversal (the largest value if the yaw rate never turns back)
    peaks = np.nonzero((values[1:-1] >= values[:-2]) & (values[1:-1] > values[2:]) & (values[1:-1] > 0))[0]
    peak = float(values[peaks[0] + 1]) if peaks.size else float(values.max())
    if peak <= 0:
        raise ManoeuvreFailed("the vehicle does not yaw against the first steer after it reverses")
    ratios = [toward * trace.at("yaw_rate_radps", COS + delay) / peak for delay in AFTER_COS]
    # lateral displacement from the initial straight path (heading and position at BOS), toward the first steer
    bos = beginning_of_steer(amplitude_swa)
    x0, y0, psi0 = trace.at("x_m", bos), trace.at("y_m", bos), trace.at("yaw_rad", bos)
    x, y = trace.at("x_m", bos + DISPLACEMENT_TIME), trace.at("y_m", bos + DISPLACEMENT_TIME)
    lateral = -(x - x0) * math.sin(psi0) + (y - y0) * math.cos(psi0)
    return {"beginning_of_steer_s": bos, "peak_yaw_rate_radps": peak, "yaw_rate_ratio_1_00s": ratios[0],
            "yaw_rate_ratio_1_75s": ratios[1], "lateral_displacement_1_07s_m": direction * lateral}


def run(model) -> Outcome:
    outcome = Outcome("sine_with_dwell", STANDARD)
    speed = SPEED_KMH * KILOMETRE_PER_HOUR
    each_a = []
    for label, direction in DIRECTIONS:
        for repetition in range(1, SIS_REPETITIONS + 1):
            a_run, sis = slowly_increasing_steer(model, speed, direction)
            each_a.append(a_run)
            outcome.runs.append((f"slowly increasing steer {label} {repetition}", sis))
    a_swa = round(float(np.mean(np.abs(each_a))) / A_ROUNDING) * A_ROUNDING
    if FIRST_MULTIPLE * a_swa <= BOS_SWA:
        raise ManoeuvreFailed(f"A = {a_swa:.1f} deg: the first run's 1.5 A does not reach the {BOS_SWA} deg that marks "
                              "the beginning of steer")
    runs = []
    for label, direction in DIRECTIONS:
        for amplitude_swa in amplitudes(a_swa):
            amplitude = math.radians(amplitude_swa) / STEERING_RATIO
            trace = drive(model, speed, lambda time, state: (0.0, 0.0, 0.0), COS + AFTER_COS[1] + 0.25,
                          steer_function=sine_with_dwell(amplitude, direction))
            metrics = run_metrics(trace, direction, amplitude_swa)
            multiple = amplitude_swa / a_swa
            checks = [metrics["yaw_rate_ratio_1_00s"] <= RATIO_1_00_MAX,
                      metrics["yaw_rate_ratio_1_75s"] <= RATIO_1_75_MAX]
            if multiple >= DISPLACEMENT_FROM - 1e-9:
                checks.append(metrics["lateral_displacement_1_07s_m"] >= DISPLACEMENT_MIN)
            runs.append({"direction": label, "amplitude_A": multiple, "amplitude_swa_deg": amplitude_swa,
                         "steer_rad": amplitude, **metrics, "passed": all(checks)})
            outcome.runs.append((f"{label} {amplitude_swa:.1f} deg ({multiple:.2f} A)", trace))
    worst_1 = max(r["yaw_rate_ratio_1_00s"] for r in runs)
    worst_175 = max(r["yaw_rate_ratio_1_75s"] for r in runs)
    least = min(r["lateral_displacement_1_07s_m"] for r in runs if r["amplitude_A"] >= DISPLACEMENT_FROM - 1e-9)
    a = math.radians(a_swa) / STEERING_RATIO
    outcome.metrics = {"speed_kmh": SPEED_KMH, "steer_A_rad": a, "steer_A_swa_deg": a_swa,
                       "slowly_increasing_steer_A_swa_deg": each_a, "steering_ratio_assumed": STEERING_RATIO,
                       "runs_per_series": len(runs) // len(DIRECTIONS), "yaw_rate_ratio_1_00s": worst_1,
                       "yaw_rate_ratio_1_75s": worst_175, "lateral_displacement_1_07s_m": least, "runs": runs}
    ok = [worst_1 <= RATIO_1_00_MAX, worst_175 <= RATIO_1_75_MAX, least >= DISPLACEMENT_MIN]
    outcome.criteria = [
        f"largest yaw-rate ratio 1.00 s after COS {worst_1:.3f} <= {RATIO_1_00_MAX}: {'pass' if ok[0] else 'FAIL'}",
        f"largest yaw-rate ratio 1.75 s after COS {worst_175:.3f} <= {RATIO_1_75_MAX}: {'pass' if ok[1] else 'FAIL'}",
        f"least lateral displacement 1.07 s after BOS (runs >= {DISPLACEMENT_FROM:g} A) {least:.2f} m >= "
        f"{DISPLACEMENT_MIN} m: {'pass' if ok[2] else 'FAIL'}"]
    outcome.passed = all(ok)
    outcome.plot = {"cosi": COS, "after_cosi": AFTER_COS, "limits": (RATIO_1_00_MAX, RATIO_1_75_MAX)}
    return outcome
