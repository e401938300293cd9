"""`braking`: UN Regulation No. 13-H, Annex 3, Type-0 test with the engine disconnected.

From 100 km/h (the prescribed test speed for M1 vehicles) the brake pedal is applied fully and held until the
vehicle stops, throttle released, steering straight. Criteria (R13-H Annex 3, the Type-0 table for M1 vehicles):
stopping distance s <= 0.1 V + 0.0060 V^2 (V in km/h, s in m) and mean fully developed deceleration
MFDD >= 6.43 m/s^2, with (R13-H Annex 3, the definition of MFDD) MFDD = (v_b^2 - v_e^2) / (25.92 (s_e - s_b)), v_b = 0.8 v_0,
v_e = 0.1 v_0 (km/h), s_b, s_e the distances (m) travelled from the brake application to v_b and v_e.
"""

from __future__ import annotations

import numpy as np

from ..units import KILOMETRE_PER_HOUR
from .drive import ManoeuvreFailed, drive
from .outcome import Outcome

STANDARD = "UN R13-H Annex 3, Type-0 test (engine disconnected)"
TEST_SPEED_KMH = 100.0  # R13-H Annex 3, Type-0 table: M1 test speed
DISTANCE_LINEAR, DISTANCE_SQUARE = 0.1, 0.0060  # R13-H Annex 3, Type-0 table: s <= 0.1 V + 0.0060 V^2
MFDD_MIN = 6.43  # m/s^2, R13-H Annex 3, Type-0 table (M1)
MFDD_FACTOR = 25.92  # R13-H Annex 3 (MFDD definition): 2 x 3.6^2, (km/h)^2 / m -> m/s^2
V_B, V_E = 0.8, 0.1  # R13-H Annex 3 (MFDD definition): between 0.8 v0 and 0.1 v0
LANE_WIDTH = 3.5  # m: a braking vehicle that leaves a 3.5 m lane is not driven through the test (our rule)
STOP_SPEED = 0.01  # m/s: below it the vehicle counts as stopped
TIME_LIMIT = 30.0  # s


def stopping_distance_limit(speed_kmh: float) -> float:
    return DISTANCE_LINEAR * speed_kmh + DISTANCE_SQUARE * speed_kmh**2


def mfdd(speed: np.ndarray, distance: np.ndarray, v0: float) -> float:
    """R13-H Annex 4's MFDD (m/s^2) from a stop's speed (m/s, falling) and distance (m) samples."""
    vb, ve = V_B * v0, V_E * v0
    falling_speed, rising_distance = speed[::-1], distance[::-1]  # np.interp needs increasing x
    sb = float(np.interp(vb, falling_speed, rising_distance))
    se = float(np.interp(ve, falling_speed, rising_distance))
    kmh = 1 / KILOMETRE_PER_HOUR
    return ((vb * kmh) ** 2 - (ve * kmh) ** 2) / (MFDD_FACTOR * (se - sb))


def run(model) -> Outcome:
    outcome = Outcome("braking", STANDARD)
    v0 = TEST_SPEED_KMH * KILOMETRE_PER_HOUR
    half_lane = (LANE_WIDTH - model.width) / 2
    trace = drive(model, v0, lambda t, state: (0.0, 1.0, 0.0), TIME_LIMIT,
                  stop=lambda t, state: t > 0 and (state.stopped or state.v < STOP_SPEED))
    outcome.runs.append(("stop", trace))
    after = trace["time_s"] >= 0
    time, speed, y = trace["time_s"][after], trace["speed_mps"][after], trace["y_m"][after]
    distance = trace["distance_m"][after] - trace["distance_m"][after][0]
    if speed[-1] >= STOP_SPEED:
        raise ManoeuvreFailed(f"the vehicle does not stop within {TIME_LIMIT:.0f} s of full braking "
                              f"({speed[-1] / KILOMETRE_PER_HOUR:.1f} km/h left)")
    if np.max(np.abs(y)) > half_lane:
        raise ManoeuvreFailed(f"the vehicle leaves its {LANE_WIDTH} m lane while braking "
                              f"(lateral deviation {np.max(np.abs(y)):.2f} m)")
    entry = speed[0]
    stop = float(distance[-1])
    deceleration = mfdd(speed, distance, entry)
    limit = stopping_distance_limit(TEST_SPEED_KMH)
    outcome.metrics = {"entry_speed_kmh": round(entry / KILOMETRE_PER_HOUR, 3), "stopping_distance_m": stop,
                       "stopping_time_s": float(time[-1]), "mfdd_mps2": deceleration,
                       "stopping_distance_limit_m": limit, "mfdd_limit_mps2": MFDD_MIN}
    distance_ok, mfdd_ok = stop <= limit, deceleration >= MFDD_MIN
    outcome.criteria = [f"stopping distance {stop:.2f} m <= {limit:.1f} m: {'pass' if distance_ok else 'FAIL'}",
                        f"MFDD {deceleration:.2f} m/s2 >= {MFDD_MIN} m/s2: {'pass' if mfdd_ok else 'FAIL'}"]
    outcome.passed = distance_ok and mfdd_ok
    outcome.plot = {"limit_m": limit, "v0": entry}
    return outcome
