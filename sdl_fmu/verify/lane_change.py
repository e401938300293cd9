"""`double_lane_change`: ISO 3888-2 severe lane change, obstacle avoidance track, rated by a family of drivers.

The track (ISO 3888-2, Table 1; b = the vehicle's width, x from the entry gate, y positive left):
  section 1, entry lane: 12 m long, 1.1 b + 0.25 m wide;
  section 2, lane change: 13.5 m;
  section 3, side lane: 11 m long, b + 1 m wide, offset to the left so that its right limit lies 1 m left of
    the entry lane's left limit;
  section 4, lane change back: 12.5 m;
  section 5, exit lane: 12 m long, 1.3 b + 0.25 m wide (at least 3 m), its right limit in line with the entry
    lane's (61 m in all).
Cones mark the limits of sections 1, 3 and 5 (the lane limits are tangent to the cones' bases); a run touches a
cone when the vehicle's footprint crosses a limit of a marked section. The vehicle enters at the entry speed and
the throttle is released at the entry gate (ISO 3888-2 test method).
ISO 3888-2 rates the car with a human driver, who drives it again and again to find how fast it can go through. The
pack rates it with a family of drivers instead of one tuned driver: pure pursuit (driver.PathFollower) of the plain
path through the marked lanes' centres (straight lines across sections 2 and 4), with a preview time tau between
TAU_RANGE (look-ahead tau v, at least MIN_LOOKAHEAD). A driver with too long a preview turns in too early and
touches the cones of section 1 (or cuts back early into section 3's right limit); one with too short a preview turns
late and overshoots into section 3 or 5. So at each speed the clean drivers form a band of tau, which narrows as the
speed grows and closes at the car's highest clean speed. The search: at each speed, bisection on tau in its bracket
(TAU_STEPS runs at most, from the last clean driver; a late touch raises the lower end, an early one lowers the upper
end; a driver late at a speed is late above it, one early at a speed early below it); the speed rises by SPEED_STEP_KMH while a clean driver is found,
then bisection on the speed to RESOLUTION_KMH. The result is the highest clean entry speed found and the driver that
achieved it; every run is listed. ISO 3888-2 sets no pass/fail limit: `passed` is null; a vehicle that no driver of
the family takes cleanly through the track at LOW_SPEED_KMH cannot be driven through it and fails.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..units import KILOMETRE_PER_HOUR
from .drive import ManoeuvreFailed, drive
from .driver import PREVIEW_TIME, PathFollower
from .outcome import Outcome

STANDARD = "ISO 3888-2 severe lane change (obstacle avoidance)"
SECTION_LENGTHS = (12.0, 13.5, 11.0, 12.5, 12.0)  # m, ISO 3888-2 Table 1
OFFSET = 1.0  # m, ISO 3888-2 Table 1: lateral gap between the entry lane's left and the side lane's right limit
LOW_SPEED_KMH, HIGH_SPEED_KMH = 30.0, 150.0  # the search's bounds (sdl-fmu's choice)
SPEED_STEP_KMH = 10.0  # the speed rises by this while a clean driver is found
RESOLUTION_KMH = 0.5
TAU_RANGE = (0.1, 0.8)  # s: the family's preview times (sdl-fmu's choice)
TAU_STEPS = 7  # drivers tried per speed at most (bisection on tau)
TAU_RESOLUTION = 0.002  # s: the bisection on tau ends here
MIN_LOOKAHEAD = 1.0  # m
RUN_IN = 15.0  # m of straight driving in the entry lane before the gate
RUN_OUT = 20.0  # m after the exit gate


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


def centre_path(lanes: list[Lane], spacing: float = 0.05):
    """The drivers' path: the marked lanes' centre lines, joined by straight lines across sections 2 and 4, from
    RUN_IN before the entry gate to RUN_OUT after the exit gate."""
    first, side, last = lanes
    centre = [(lane.right + lane.left) / 2 for lane in lanes]
    xs = [-RUN_IN, first.start, first.end, side.start, side.end, last.start, last.end, last.end + RUN_OUT]
    ys = [centre[0]] * 3 + [centre[1]] * 2 + [centre[2]] * 3
    x = np.arange(xs[0], xs[-1] + spacing / 2, spacing)
    return x, np.interp(x, xs, ys)


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


@dataclass(frozen=True)
class Touch:
    """The first cone a run touches: the marked section (1, 3 or 5), its limit's side, where, and when (sample)."""

    section: int
    side: str
    x: float
    index: int

    def early(self, lanes: list[Lane]) -> bool:
        """A driver that turned in too early: it touches section 1 (before the first lane change), or the right
        limit of section 3 in its second half (turning back before the second); any other touch is late."""
        side_lane = lanes[1]
        return self.section == 1 or (self.section == 3 and self.side == "right"
                                     and self.x > (side_lane.start + side_lane.end) / 2)

    def __str__(self) -> str:
        return f"section {self.section}, {self.side} limit, at x = {self.x:.1f} m"


def first_touch(trace, length: float, width: float, lanes: list[Lane]) -> Touch | None:
    """The footprint's first crossing of a marked limit, in time, or None."""
    touches = []
    for number, lane in zip((1, 3, 5), lanes):
        high, low = footprint_limits(trace, length, width, lane)
        for side, beyond in (("left", high > lane.left), ("right", low < lane.right)):
            hits = np.nonzero(np.nan_to_num(beyond, nan=0.0).astype(bool))[0]
            if hits.size:
                touches.append(Touch(number, side, float(trace["x_m"][hits[0]]), int(hits[0])))
    return min(touches, key=lambda touch: touch.index) if touches else None


def cone_touch(trace, length: float, width: float, lanes: list[Lane]) -> str | None:
    """Where the footprint first crosses a marked limit ("section 3, left limit at x = 30.2 m"), or None."""
    touch = first_touch(trace, length, width, lanes)
    return None if touch is None else str(touch)


def corner_beyond(state, length: float, width: float, lanes: list[Lane]) -> bool:
    """Whether a corner of the footprint lies beyond a marked limit now: a touch for certain (the run can end; the
    trace's exact check, edges included, then says where it first touched)."""
    c, s = math.cos(state.psi), math.sin(state.psi)
    for lx, ly in ((length / 2, width / 2), (length / 2, -width / 2), (-length / 2, -width / 2),
                   (-length / 2, width / 2)):
        x, y = state.x + lx * c - ly * s, state.y + lx * s + ly * c
        for lane in lanes:
            if lane.start <= x <= lane.end and not lane.right <= y <= lane.left:
                return True
    return False


def lane_change_run(model, speed: float, lanes: list[Lane], preview_time: float):
    """One run of the driver with this preview time at this entry speed, ended at the exit or at a certain touch."""
    path = centre_path(lanes)
    follower = PathFollower(*path, model.wheelbase, preview_time=preview_time, min_lookahead=MIN_LOOKAHEAD)
    end = lanes[-1].end + model.length

    def law(time, state):
        return 0.0, 0.0, follower.steer(state)  # throttle released at the entry gate (time 0)

    def done(time, state):
        return state.x > end or state.v < 1.0 or corner_beyond(state, model.length, model.width, lanes)

    return drive(model, speed, law, 30.0, settle=RUN_IN / speed, start={"x": -RUN_IN, "y": path[1][0]},
                 settle_steer=follower.steer, stop=done)


def run(model) -> Outcome:
    outcome = Outcome("double_lane_change", STANDARD)
    lanes = track(model.width)
    # every run; (speed, tau) of late and early touches: a driver that turns in late at a speed is late above it too,
    # one that turns in early is early below it too (the band of clean drivers moves to longer previews with speed)
    tried, late, early = [], [], []

    def attempt(kmh: float, tau: float):
        """(None for a clean run, else "early", "late" or "failed"; what happened; the trace or None)."""
        try:
            trace = lane_change_run(model, kmh * KILOMETRE_PER_HOUR, lanes, tau)
        except ManoeuvreFailed as failure:
            tried.append({"entry_speed_kmh": kmh, "preview_time_s": tau, "touched": None, "failed": str(failure)})
            return "failed", str(failure), None
        touch = first_touch(trace, model.length, model.width, lanes)
        if touch is None and trace["x_m"][-1] <= lanes[-1].end + model.length:
            what = (f"the vehicle does not get through the track at {kmh:.1f} km/h (stops at x = "
                    f"{trace['x_m'][-1]:.1f} m)")
            tried.append({"entry_speed_kmh": kmh, "preview_time_s": tau, "touched": None, "failed": what})
            return "failed", what, trace
        kind = None if touch is None else ("early" if touch.early(lanes) else "late")
        tried.append({"entry_speed_kmh": kmh, "preview_time_s": tau, "touched": None if touch is None else str(touch),
                      "turned_in": kind})
        if kind is not None:
            (late if kind == "late" else early).append((kmh, tau))
        return kind, None if touch is None else str(touch), trace

    def clean_driver(kmh: float, guess: float):
        """(tau of a clean run at this speed or None, its trace or the last one, what went wrong)."""
        low = max([TAU_RANGE[0], *(tau for speed, tau in late if speed <= kmh)])
        high = min([TAU_RANGE[1], *(tau for speed, tau in early if speed >= kmh)])
        tau = min(max(guess, low), high)
        kind, what, trace = None, None, None
        for _ in range(TAU_STEPS):
            kind, what, trace = attempt(kmh, tau)
            if kind is None:
                return tau, trace, None
            if kind == "failed":
                break
            if kind == "late":
                low = tau
            else:
                high = tau
            if high - low < TAU_RESOLUTION:
                break
            tau = (low + high) / 2
        return None, trace, what

    tau, best_trace, what = clean_driver(LOW_SPEED_KMH, PREVIEW_TIME)
    if tau is None:
        raise ManoeuvreFailed(f"no driver of the family gets through cleanly even at {LOW_SPEED_KMH:.0f} km/h ({what})")
    low, best_tau = LOW_SPEED_KMH, tau
    high, high_trace, high_what = None, None, None
    while high is None and low + SPEED_STEP_KMH <= HIGH_SPEED_KMH:
        speed = low + SPEED_STEP_KMH
        tau, trace, what = clean_driver(speed, best_tau)
        if tau is None:
            high, high_trace, high_what = speed, trace, what
        else:
            low, best_tau, best_trace = speed, tau, trace
    while high is not None and high - low > RESOLUTION_KMH:
        speed = (low + high) / 2
        tau, trace, what = clean_driver(speed, best_tau)
        if tau is None:
            high, high_trace, high_what = speed, trace, what
        else:
            low, best_tau, best_trace = speed, tau, trace
    outcome.runs = [(f"{low:.2f} km/h, preview {best_tau:.3f} s (fastest clean run)", best_trace)]
    if high_trace is not None:
        outcome.runs.append((f"{high:.2f} km/h (no clean driver: {high_what})", high_trace))
    driver = {"kind": "pure pursuit of the lane centres", "preview_time_s": best_tau, "min_lookahead_m": MIN_LOOKAHEAD}
    outcome.metrics = {"max_entry_speed_kmh": low, "driver": driver, "preview_time_range_s": list(TAU_RANGE),
                       "first_touch_kmh": high, "first_touch": high_what, "runs": tried}
    outcome.criteria = [f"ISO 3888-2 sets no limit: reported (the fastest of a family of drivers: pure pursuit, "
                        f"preview {best_tau:.3f} s)"]
    path_x, path_y = centre_path(lanes)
    outcome.plot = {"lanes": [lane.__dict__ for lane in lanes], "length": model.length, "width": model.width,
                    "path": [path_x[::20].tolist(), path_y[::20].tolist()]}
    return outcome
