"""`braking`: UN Regulation No. 13-H, Annex 3, Type-0 test with the engine disconnected, the directional stability it
asks of the stop, and the wheel-lock sequence of Annex 5.

Type-0 (Annex 3, para. 2.1, M1 vehicles): from 100 km/h the brake pedal is applied fully and held until the vehicle
stops, throttle released, steering straight. Criteria (Annex 3, the Type-0 table for M1): stopping distance
s <= 0.1 V + 0.0060 V^2 (V in km/h, s in m) and mean fully developed deceleration MFDD >= 6.43 m/s^2, with (Annex 3,
para. 1.1.2) MFDD = (v_b^2 - v_e^2) / (25.92 (s_e - s_b)), v_b = 0.8 v_0, v_e = 0.1 v_0 (km/h), s_b, s_e the
distances (m) travelled from v_0 to v_b and v_e. A braking vehicle that leaves a 3.5 m lane is not driven through the
test (our rule: the lane of a test track).
Directional stability: the stop must be achieved without the vehicle deviating from its course. A car whose rear
wheels lock first has no lateral guidance at the rear and spins from the smallest disturbance, which a straight,
symmetric simulation never has. So the Type-0 stop is braked twice more with a steer perturbation of PERTURBATION
(road-wheel angle; 0.08 rad, 4.6 deg at the steering wheel at the pack's 16:1) held for the first PERTURBATION_TIME,
to each side: the vehicle's footprint must stay within the 3.5 m lane.
Lock sequence (Annex 5, para. 3.1, vehicles without ABS): for braking rates between 0.15 and 0.8 the front wheels
must lock before, or together with, the rear wheels. A vehicle FMU shows no wheels; the pack finds, on surfaces whose
friction puts the first lock within those braking rates (LOCK_SURFACES, per friction meaning), the pedal of the first
lock from the car's deceleration (effort.locking_limit: the first pedal at which it stops growing at LOCK_GROWTH of
its rate at a light pedal) and brakes just past it (LOCK_MARGIN), turning steadily with a small steer (PERTURBATION,
from before the application). Then only the axle that locks first is locked, and the car shows which: the front
(or both together), and it loses its turn and runs straight on; the rear, and the still-steered front turns it in,
a spin. The yaw rate must not grow beyond LOCK_YAW_RATE_GROWTH x its value at the application. A vehicle without a
friction input is braked on its own surface only. On a surface where the deceleration grows with the pedal all the
way (no wheel locks: brakes weaker than the tires, ABS, or a model without wheels, as CommonRoad's single-track car)
there is no lock sequence; where no surface locks, the criterion is n/a with that reason, never a FAIL.
"""

from __future__ import annotations

import math

import numpy as np

from ..units import KILOMETRE_PER_HOUR
from .drive import ManoeuvreFailed, drive
from .effort import RESOLUTION, Probes, locking_limit
from .outcome import Outcome

STANDARD = "UN R13-H Annex 3, Type-0 test (engine disconnected); directional stability; Annex 5 lock sequence"
TEST_SPEED_KMH = 100.0  # R13-H Annex 3, para. 2.1, Type-0 table: M1 test speed
DISTANCE_LINEAR, DISTANCE_SQUARE = 0.1, 0.0060  # R13-H Annex 3, Type-0 table: s <= 0.1 V + 0.0060 V^2
MFDD_MIN = 6.43  # m/s^2, R13-H Annex 3, Type-0 table (M1)
MFDD_FACTOR = 25.92  # R13-H Annex 3, para. 1.1.2 (MFDD): 2 x 3.6^2, (km/h)^2 / m -> m/s^2
V_B, V_E = 0.8, 0.1  # R13-H Annex 3, para. 1.1.2 (MFDD): between 0.8 v0 and 0.1 v0
LANE_WIDTH = 3.5  # m: a braking vehicle that leaves a 3.5 m lane is not driven through the test (our rule)
STOP_SPEED = 0.01  # m/s: below it the vehicle counts as stopped
TIME_LIMIT = 30.0  # s
PERTURBATION = 0.005  # rad of road-wheel angle (sdl-fmu's choice: a driver's hands are never exactly still)
PERTURBATION_TIME = 0.2  # s from the brake application (the Type-0 stops; sdl-fmu's choice: a car that steers, as one
# without locked wheels does, turns by v delta T / L, 0.01 rad, and drifts 0.4 m over the stop: inside the lane)
LOCK_BRAKING_RATES = (0.15, 0.8)  # R13-H Annex 5, para. 3.1: the range the lock sequence applies to
# surfaces whose friction puts the first lock within LOCK_BRAKING_RATES: mu, or the default Tire Attribute File's
# attributes 2 (packed snow, peak 0.2) and 1 (wet asphalt, 0.6) (scenarios/tires/attributes.txt)
LOCK_SURFACES = {"mu": (0.2, 0.5, 0.8), "attribute": (2, 1)}
LOCK_GROWTH = 0.8  # a lock: the deceleration grows at less than this share of its rate at a light pedal
LIGHT_PEDAL = 0.1  # the pedal over which the rate with every wheel rolling is measured
LOCK_MARGIN = 2 * RESOLUTION  # pedal past the found limit, which lies within RESOLUTION below the first lock: the other
# axle locks some 0.03 of pedal later in the cars tested (sdl-fmu's choice)
# the yaw rate may grow at most by this factor: turning steadily, a car's yaw rate v delta / (L + K v^2) falls as it
# slows, or rises by at most 3 % toward its characteristic speed; a locked front axle takes the turn away; a locked
# rear axle under a steered front turns it in (3 x in CommonRoad's BMW 320i on wet asphalt; sdl-fmu's choice)
LOCK_YAW_RATE_GROWTH = 1.5


def stopping_distance_limit(speed_kmh: float) -> float:
    return DISTANCE_LINEAR * speed_kmh + DISTANCE_SQUARE * speed_kmh**2


def mfdd(speed: np.ndarray, distance: np.ndarray, v0: float) -> float:
    """R13-H Annex 3's MFDD (para. 1.1.2; m/s^2) from a stop's speed (m/s, falling) and distance (m) samples."""
    vb, ve = V_B * v0, V_E * v0
    falling_speed, rising_distance = speed[::-1], distance[::-1]  # np.interp needs increasing x
    sb = float(np.interp(vb, falling_speed, rising_distance))
    se = float(np.interp(ve, falling_speed, rising_distance))
    kmh = 1 / KILOMETRE_PER_HOUR
    return ((vb * kmh) ** 2 - (ve * kmh) ** 2) / (MFDD_FACTOR * (se - sb))


def footprint_offset(trace, length: float, width: float) -> float:
    """The largest distance of the vehicle's footprint (length x width, turned by its yaw) from the line y = y(0)
    after the brake application (m)."""
    after = trace["time_s"] >= 0
    x, y, psi = trace["x_m"][after], trace["y_m"][after] - trace.at("y_m", 0.0), trace["yaw_rad"][after]
    corners = [y + lx * np.sin(psi) + ly * np.cos(psi) for lx in (-length / 2, length / 2) for ly in (-width / 2, width / 2)]
    return float(np.max(np.abs(corners)))


def stopped(t, state) -> bool:
    return t > 0 and (state.stopped or state.v < STOP_SPEED)


def run(model) -> Outcome:
    outcome = Outcome("braking", STANDARD)
    v0 = TEST_SPEED_KMH * KILOMETRE_PER_HOUR
    half_lane = (LANE_WIDTH - model.width) / 2
    trace = drive(model, v0, lambda t, state: (0.0, 1.0, 0.0), TIME_LIMIT, stop=stopped)
    outcome.runs.append(("Type-0 stop", trace))
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

    # directional stability: the Type-0 stop with a steer perturbation to each side
    offsets = {}
    for label, sign in (("left", 1.0), ("right", -1.0)):
        perturbed = drive(model, v0, lambda t, state: (0.0, 1.0, 0.0), TIME_LIMIT, stop=stopped,
                          steer_function=lambda t, sign=sign: sign * PERTURBATION if 0 <= t < PERTURBATION_TIME else 0)
        outcome.runs.append((f"Type-0 stop, steer perturbation to the {label}", perturbed))
        offsets[label] = footprint_offset(perturbed, model.length, model.width)
    lane_offset = max(offsets.values())

    # lock sequence: just past the first lock on surfaces of lower friction, turning steadily with a small steer
    if model.friction is None:
        surfaces = (None,)
    else:
        surfaces = LOCK_SURFACES["mu" if model.friction.meaning == "mu" else "attribute"]
    growths, lock_pedals, unlocked = {}, {}, []
    for surface in surfaces:
        friction = None if surface is None else (surface,) * 4
        name = "own surface" if surface is None else f"{'mu' if model.friction.meaning == 'mu' else 'attribute'} {surface}"
        probes = Probes(model, v0, friction)
        rate = (probes(LIGHT_PEDAL) - probes(0.0)) / LIGHT_PEDAL
        limit_pedal = locking_limit(probes, LOCK_GROWTH * rate)
        if limit_pedal >= 1.0:  # the deceleration grows all the way: no wheel locks on this surface
            unlocked.append(name)
            growths[name] = lock_pedals[name] = None
            continue
        pedal = min(limit_pedal + LOCK_MARGIN, 1.0)
        turning = drive(model, v0, lambda t, state, pedal=pedal: (0.0, pedal if t >= 0 else 0.0, 0.0), TIME_LIMIT,
                        stop=stopped, friction=friction, steer_function=lambda t: PERTURBATION,
                        settle_steer=lambda state: PERTURBATION)
        outcome.runs.append((f"first lock, brake {pedal:.3f}, steady steer, {name}", turning))
        after = turning["time_s"] >= 0
        r0 = abs(turning.at("yaw_rate_radps", 0.0))
        growths[name] = float(np.max(np.abs(turning["yaw_rate_radps"][after])) / max(r0, 1e-9))
        lock_pedals[name] = pedal
    locked = [g for g in growths.values() if g is not None]
    worst_growth = max(locked) if locked else None

    outcome.metrics = {"entry_speed_kmh": round(entry / KILOMETRE_PER_HOUR, 3), "stopping_distance_m": stop,
                       "stopping_time_s": float(time[-1]), "mfdd_mps2": deceleration,
                       "stopping_distance_limit_m": limit, "mfdd_limit_mps2": MFDD_MIN,
                       "perturbed_lane_offset_m": lane_offset, "perturbed_lane_offsets_m": offsets,
                       "lock_sequence_yaw_rate_growth": worst_growth, "lock_sequence_yaw_rate_growths": growths,
                       "lock_sequence_brake": lock_pedals, "lock_sequence_no_lock": unlocked}
    distance_ok = outcome.judge(f"stopping distance {stop:.2f} m <= {limit:.1f} m", stop <= limit)
    mfdd_ok = outcome.judge(f"MFDD {deceleration:.2f} m/s2 >= {MFDD_MIN} m/s2", deceleration >= MFDD_MIN)
    stable_ok = outcome.judge(f"steer perturbation of {PERTURBATION} rad: footprint within {lane_offset:.2f} m of the "
                              f"lane's centre <= {LANE_WIDTH / 2} m", lane_offset <= LANE_WIDTH / 2)
    no_lock = (f"no wheel locks up to full pedal on {', '.join(unlocked)}: the deceleration grows with the pedal "
               f"all the way (at >= {LOCK_GROWTH:g} x its rate at a light pedal), so there is no lock sequence")
    if worst_growth is None:  # R13-H Annex 5's lock sequence concerns wheels that lock: here none does
        outcome.judge("lock sequence (front before rear)", None, no_lock)
        sequence_ok = True
    else:
        sequence_ok = outcome.judge(
            f"lock sequence (front before rear): yaw rate just past the first lock at most {worst_growth:.2f} x its "
            f"value before <= {LOCK_YAW_RATE_GROWTH:g}"
            + (f" (on the surfaces where a wheel locks; none does on {', '.join(unlocked)})" if unlocked else ""),
            worst_growth <= LOCK_YAW_RATE_GROWTH)
    outcome.passed = distance_ok and mfdd_ok and stable_ok and sequence_ok
    outcome.plot = {"limit_m": limit, "v0": entry}
    return outcome
