"""Driving a vehicle through a manoeuvre: a control law sampled at a fixed period, every sample recorded.

A manoeuvre starts the vehicle at its entry speed (the map's start speed; a vehicle whose FMU ignores it
accelerates at full throttle), holds that speed straight ahead for a settling time and checks it is within
ENTRY_SPEED_TOLERANCE; then the manoeuvre's own control law runs from its time 0. Anything that stops the
vehicle from being driven through (entry speed not reached, an FMU error, a state that is not finite) raises
ManoeuvreFailed with one line saying why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..hold import hold_here
from ..units import KILOMETRE_PER_HOUR

SAMPLE_PERIOD = 0.01  # s: the driver's and the recorder's period (100 Hz, as ISO 7401 / FMVSS 126 data rates)
# FMVSS 126 S7.6.1 / S7.9.2 (49 CFR 571.126): manoeuvres begin at 80 +/- 2 km/h; the same band is used for every entry
ENTRY_SPEED_TOLERANCE = 2.0 * KILOMETRE_PER_HOUR
RUN_UP_LIMIT = 60.0  # s of full throttle allowed to reach the entry speed (sdl-fmu's choice)
SETTLE_TIME = 1.0  # s of straight driving at the entry speed before time 0 (sdl-fmu's choice)
# speed controller (throttle / brake pedal per m/s of speed error, and its integral per m); gains chosen for
# the shipped models' pedals (4 m/s2 of drive and 9.81 m/s2 of brake per full pedal): error < 0.05 m/s
SPEED_GAIN, SPEED_INTEGRAL_GAIN = 4.0, 4.0

COLUMNS = ("time_s", "x_m", "y_m", "yaw_rad", "distance_m", "speed_mps", "vx_mps", "vy_mps", "ax_mps2", "ay_mps2",
           "yaw_rate_radps", "throttle", "brake", "steer_rad")

Controls = tuple[float, float, float]  # throttle, brake (pedals 0..1), steer (road-wheel angle, rad, positive left)


class ManoeuvreFailed(Exception):
    """The vehicle could not be driven through the manoeuvre; the message is one line saying why."""


@dataclass
class Trace:
    """One run's time series, SI, time 0 at the manoeuvre's start (the settling phase before it is negative)."""

    columns: dict[str, np.ndarray]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def at(self, name: str, time: float) -> float:
        """The column linearly interpolated at `time`."""
        return float(np.interp(time, self.columns["time_s"], self.columns[name]))


class SpeedHold:
    """PI speed controller: throttle below the target speed, brake above it."""

    def __init__(self, target: float):
        self.target, self.integral = target, 0.0

    def __call__(self, speed: float) -> tuple[float, float]:
        error = self.target - speed
        self.integral = min(max(self.integral + error * SAMPLE_PERIOD, -1.0), 1.0 / SPEED_INTEGRAL_GAIN)
        command = SPEED_GAIN * error + SPEED_INTEGRAL_GAIN * self.integral
        return min(max(command, 0.0), 1.0), min(max(-command, 0.0), 1.0)


def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def drive(model, entry_speed: float, law: Callable, duration: float, *, parameters: dict | None = None,
          friction=None, stop: Callable | None = None, start: dict | None = None,
          settle: float = SETTLE_TIME, settle_steer: Callable | None = None,
          steer_function: Callable[[float], float] | None = None,
          substeps: int | Callable[[float], int] = 1) -> Trace:
    """Drives `model` through one manoeuvre and returns its trace.

    law(time, state) -> (throttle, brake, steer) for time >= 0 (state: the model's EgoState); `stop(time, state)`
    ends the run early when true; `start` the initial position {"x", "y", "yaw"} (default the origin, heading +x);
    `friction` the 4 wheel values set before the start; `settle_steer(state)` the steering while settling
    (default straight ahead). `steer_function(t)`: an open-loop steer given as a function of time, in place of the
    law's (recorded at the sample instants). It is set at the midpoint of each sub-interval (`substeps` per sample
    period, a number or a function of the sample's time): an FMU holds an input over its communication step, and a
    value held from a step's start lags a ramp by half a step (5 ms at 100 Hz); the midpoint value is the function's
    mean over the sub-interval wherever it is linear there (a ramp), so the FMU sees its integral exactly and no lag."""
    try:
        ego = model.instantiate(start={"speed": entry_speed, "x": 0.0, "y": 0.0, "yaw": 0.0, **(start or {})},
                                parameters=parameters or {}, instance_name="verify")
    except Exception as error:  # noqa: BLE001 - any FMU / map failure is this manoeuvre's result
        raise ManoeuvreFailed(f"the vehicle FMU cannot be started: {_first_line(error)}") from None
    rows: list[tuple] = []
    time = 0.0
    try:
        hold_here()  # the test hook (sdl_fmu/hold.py)
        if friction is not None:
            ego.set_friction(friction)
        state = ego.read()
        hold = SpeedHold(entry_speed)
        # run-up: only for a vehicle that does not start at its entry speed
        t = start_time = ego.time
        while state.v < entry_speed - ENTRY_SPEED_TOLERANCE / 2:
            if t - start_time > RUN_UP_LIMIT:
                raise ManoeuvreFailed(f"cannot reach the entry speed {entry_speed / KILOMETRE_PER_HOUR:.0f} km/h "
                                      f"({state.v / KILOMETRE_PER_HOUR:.1f} km/h after {RUN_UP_LIMIT:.0f} s "
                                      "at full throttle)")
            ego.set_controls(1.0, 0.0, 0.0)
            t += SAMPLE_PERIOD
            ego.step_to(t)
            state = _checked(ego.read())
        origin = t + settle
        steps = int(round(settle / SAMPLE_PERIOD))
        for k in range(1, steps + 1):
            throttle, brake = hold(state.v)
            steer = settle_steer(state) if settle_steer is not None else 0.0
            ego.set_controls(throttle, brake, steer)
            rows.append((t - origin, *_values(state), throttle, brake, steer))
            t = origin - settle + k * SAMPLE_PERIOD
            ego.step_to(t)
            state = _checked(ego.read())
        if steps and rows[-1][-3] >= 1.0 and state.v < rows[-1][5]:
            # full throttle and still slowing down: the entry speed is beyond this vehicle's top speed
            raise ManoeuvreFailed(f"cannot reach the entry speed {entry_speed / KILOMETRE_PER_HOUR:.0f} km/h "
                                  f"(at full throttle it slows down at {state.v / KILOMETRE_PER_HOUR:.1f} km/h)")
        if abs(state.v - entry_speed) > ENTRY_SPEED_TOLERANCE:
            raise ManoeuvreFailed(f"cannot hold the entry speed {entry_speed / KILOMETRE_PER_HOUR:.0f} km/h "
                                  f"(at {state.v / KILOMETRE_PER_HOUR:.1f} km/h after {settle:g} s of speed "
                                  "control)")
        for k in range(int(math.ceil(duration / SAMPLE_PERIOD - 1e-9)) + 1):
            time = k * SAMPLE_PERIOD
            if stop is not None and stop(time, state):
                rows.append((time, *_values(state), *rows[-1][-3:]))
                break
            throttle, brake, steer = law(time, state)
            if steer_function is not None:
                steer = steer_function(time)
            ego.set_controls(throttle, brake, steer)
            rows.append((time, *_values(state), throttle, brake, steer))
            if k * SAMPLE_PERIOD >= duration:
                break
            if steer_function is not None:
                parts = substeps(time) if callable(substeps) else substeps
                for j in range(parts):
                    ego.set_controls(throttle, brake, steer_function(time + (j + 0.5) * SAMPLE_PERIOD / parts))
                    if j < parts - 1:
                        ego.step_to(origin + time + (j + 1) * SAMPLE_PERIOD / parts)
            ego.step_to(origin + (k + 1) * SAMPLE_PERIOD)
            state = _checked(ego.read())
    except ManoeuvreFailed:
        raise
    except Exception as error:  # noqa: BLE001 - an FMU error fails this manoeuvre, not the pack
        raise ManoeuvreFailed(f"the vehicle FMU failed at t = {time:.2f} s: {_first_line(error)}") from None
    finally:
        try:
            ego.close()
        except Exception:  # noqa: BLE001 - a failing close must not hide the result
            pass
    table = np.array(rows, dtype=float)
    return Trace({name: table[:, i] for i, name in enumerate(COLUMNS)})


def _values(state) -> tuple:
    return (state.x, state.y, state.psi, state.s, state.v, state.vx, state.vy, state.ax, state.ay, state.yaw_rate)


def _checked(state):
    if not all(map(math.isfinite, _values(state))):
        raise ManoeuvreFailed(f"the vehicle's outputs are not finite at t = {state.time:.2f} s")
    return state
