"""`double_lane_change`: ISO 3888-2 severe lane change, obstacle avoidance track, with a path-following driver.

The track (ISO 3888-2, Table 1; b = the vehicle's width, x from the entry gate, y positive left):
  section 1, entry lane: 12 m long, 1.1 b + 0.25 m wide;
  section 2, lane change: 13.5 m;
  section 3, side lane: 11 m long, b + 1 m wide, offset to the left so that its right limit lies 1 m left of
    the entry lane's left limit;
  section 4, lane change back: 12.5 m;
  section 5, exit lane: 12 m long, 1.3 b + 0.25 m wide (at least 3 m), its right limit in line with the entry
    lane's (61 m in all).
Cones mark the limits of sections 1, 3 and 5 (the lane limits are tangent to the cones' bases); a run touches a
cone when the vehicle's footprint crosses a limit of a marked section. The vehicle enters at the entry speed,
the throttle is released at the entry gate (ISO 3888-2 test method), and the driver (driver.PathFollower)
follows a smooth path through the lane centres. The highest entry speed without touching a cone is found by
bisection. ISO 3888-2 sets no pass/fail limit: `passed` is null; a vehicle that touches a cone even at
LOW_SPEED_KMH cannot be driven through the track and fails.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..units import KILOMETRE_PER_HOUR
from .drive import ManoeuvreFailed, drive
from .driver import PathFollower
from .outcome import Outcome

STANDARD = "ISO 3888-2 severe lane change (obstacle avoidance)"
SECTION_LENGTHS = (12.0, 13.5, 11.0, 12.5, 12.0)  # m, ISO 3888-2 Table 1
OFFSET = 1.0  # m, ISO 3888-2 Table 1: lateral gap between the entry lane's left and the side lane's right limit
LOW_SPEED_KMH, HIGH_SPEED_KMH = 30.0, 150.0  # the bisection's bracket (sdl-fmu's choice)
RESOLUTION_KMH = 0.5
RUN_IN = 30.0  # m of straight driving in the entry lane before the gate
RUN_OUT = 20.0  # m after the exit gate
BIAS = 0.6  # share of a lane's spare width the driver's path uses toward the next lane change
OVERLAP = 0.0  # m: how far the transitions reach into the marked sections (tuned on the shipped models)


@dataclass(frozen=True)
class Lane:
    start: float  # m, x of the section's start
    end: float
    right: float  # m, y of the right limit
    left: float


def track(width: float) -> list[Lane]:
    """The marked sections 1, 3, 5 of ISO 3888-2 for a vehicle `width` wide."""
    x = np.concatenate(([0.0], np.cumsum(SECTION_LENGTHS)))
    entry = 1.1 * width + 0.25
    side = width + 1.0
    exit_width = max(1.3 * width + 0.25, 3.0)
    right1 = -entry / 2
    right3 = right1 + entry + OFFSET
    return [Lane(x[0], x[1], right1, right1 + entry), Lane(x[2], x[3], right3, right3 + side),
            Lane(x[4], x[5], right1, right1 + exit_width)]


def centre_path(lanes: list[Lane], length: float, width: float, spacing: float = 0.05):
    """The driver's path: in each marked lane a line BIAS of the lane's spare width toward the next lane change,
    joined by cosine transitions that start when the body has left a lane and end when it enters the next
    (shifted by OVERLAP, as the driver's look-ahead starts the turn early)."""
    first, side, last = lanes
    targets = []
    for lane, toward in zip(lanes, (1.0, -1.0, 1.0)):
        spare = (lane.left - lane.right - width) / 2
        targets.append((lane.right + lane.left) / 2 + toward * BIAS * spare)
    x = np.arange(-RUN_IN, last.end + RUN_OUT, spacing)
    y = np.full_like(x, targets[0])

    def blend(x0, x1, y0, y1):
        inside = (x >= x0) & (x <= x1)
        y[inside] = y0 + (y1 - y0) * (1 - np.cos(math.pi * (x[inside] - x0) / (x1 - x0))) / 2
        y[x > x1] = y1

    blend(first.end + length / 2 - OVERLAP, side.start - length / 2 + OVERLAP, targets[0], targets[1])
    blend(side.end + length / 2 - OVERLAP, last.start - length / 2 + OVERLAP, targets[1], targets[2])
    return x, y


def footprint_limits(trace, length: float, width: float, lane: Lane):
    """Per sample, the highest and lowest y of the vehicle's footprint within x in [lane.start, lane.end]
    (nan where no part of it is in that range): the corners inside, and where its edges cross the ends."""
    x, y, psi = trace["x_m"], trace["y_m"], trace["yaw_rad"]
    c, s = np.cos(psi), np.sin(psi)
    local = [(length / 2, width / 2), (length / 2, -width / 2), (-length / 2, -width / 2), (-length / 2, width / 2)]
    cx = np.stack([x + lx * c - ly * s for lx, ly in local], axis=1)
    cy = np.stack([y + lx * s + ly * c for lx, ly in local], axis=1)
    candidates_y, valid = [cy], [(cx >= lane.start) & (cx <= lane.end)]
    for k in range(4):
        ax, ay, bx, by = cx[:, k], cy[:, k], cx[:, (k + 1) % 4], cy[:, (k + 1) % 4]
        for gate in (lane.start, lane.end):
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (gate - ax) / (bx - ax)
            crosses = (t >= 0) & (t <= 1) & np.isfinite(t)
            candidates_y.append((ay + t * (by - ay))[:, None])
            valid.append(crosses[:, None])
    ys, ok = np.concatenate(candidates_y, axis=1), np.concatenate(valid, axis=1)
    high = np.where(ok, ys, -np.inf).max(axis=1)
    low = np.where(ok, ys, np.inf).min(axis=1)
    inside = ok.any(axis=1)
    return np.where(inside, high, np.nan), np.where(inside, low, np.nan)


def cone_touch(trace, length: float, width: float, lanes: list[Lane]) -> str | None:
    """Where the footprint first crosses a marked limit ("section 3, left limit at x = 30.2 m"), or None."""
    for number, lane in zip((1, 3, 5), lanes):
        high, low = footprint_limits(trace, length, width, lane)
        for side, beyond in (("left", high > lane.left), ("right", low < lane.right)):
            hits = np.nonzero(np.nan_to_num(beyond, nan=0.0).astype(bool))[0]
            if hits.size:
                return f"section {number}, {side} limit, at x = {trace['x_m'][hits[0]]:.1f} m"
    return None


def lane_change_run(model, speed: float, lanes: list[Lane], width: float):
    path = centre_path(lanes, model.length, width)
    follower = PathFollower(*path, model.wheelbase)
    end = lanes[-1].end + model.length

    def law(time, state):
        return 0.0, 0.0, follower.steer(state)  # throttle released at the entry gate (time 0)

    settle = RUN_IN / speed
    trace = drive(model, speed, law, 30.0, settle=settle, start={"x": -RUN_IN, "y": path[1][0]},
                  settle_steer=follower.steer, stop=lambda time, state: state.x > end or state.v < 1.0)
    if trace["x_m"][-1] <= end:
        raise ManoeuvreFailed(f"the vehicle does not get through the track at {speed / KILOMETRE_PER_HOUR:.1f} km/h "
                              f"(stops at x = {trace['x_m'][-1]:.1f} m)")
    return trace


def run(model) -> Outcome:
    outcome = Outcome("double_lane_change", STANDARD)
    lanes = track(model.width)
    tried = []

    def attempt(kmh: float):
        """(what went wrong or None for a clean run, the trace or None when the run could not be made)"""
        try:
            trace = lane_change_run(model, kmh * KILOMETRE_PER_HOUR, lanes, model.width)
        except ManoeuvreFailed as failure:
            if kmh <= LOW_SPEED_KMH:
                raise
            # above the lowest speed, a run the vehicle cannot make (e.g. beyond its top speed) bounds the search
            tried.append({"entry_speed_kmh": kmh, "touched": None, "failed": str(failure)})
            return str(failure), None
        touch = cone_touch(trace, model.length, model.width, lanes)
        tried.append({"entry_speed_kmh": kmh, "touched": touch})
        return touch, trace

    problem, best = attempt(LOW_SPEED_KMH)
    if problem is not None:
        raise ManoeuvreFailed(f"touches a cone even at {LOW_SPEED_KMH:.0f} km/h ({problem})")
    low, high = LOW_SPEED_KMH, HIGH_SPEED_KMH
    high_problem, high_trace = attempt(high)
    if high_problem is None:
        low, best = high, high_trace
    while high_problem is not None and high - low > RESOLUTION_KMH:
        middle = (low + high) / 2
        problem, trace = attempt(middle)
        if problem is None:
            low, best = middle, trace
        else:
            high, high_problem, high_trace = middle, problem, trace
    outcome.runs = [(f"{low:.2f} km/h (fastest clean run)", best)]
    if high_trace is not None and high_problem is not None:
        outcome.runs.append((f"{high:.2f} km/h (touches: {high_problem})", high_trace))
    outcome.metrics = {"max_entry_speed_kmh": low,
                       "first_touch_kmh": high if high_problem is not None else None,
                       "first_touch": high_problem, "runs": tried}
    outcome.criteria = ["ISO 3888-2 sets no limit: reported"]
    path_x, path_y = centre_path(lanes, model.length, model.width)
    outcome.plot = {"lanes": [lane.__dict__ for lane in lanes], "length": model.length, "width": model.width,
                    "path": [path_x[::20].tolist(), path_y[::20].tolist()]}
    return outcome
