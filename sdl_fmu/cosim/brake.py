"""The BRK controller: holds the pedals from the event until its threshold or a stop (docs/scenarios.md)."""

from __future__ import annotations

from dataclasses import dataclass

from ..sdl.events import Brake
from .ego import EgoState
from .geometry import reach_time_scalar


@dataclass(frozen=True)
class BrakeHold:
    """A BRK event in force since time_on, distance_on and speed_on (SI)."""

    event: Brake
    time_on: float
    distance_on: float
    speed_on: float

    def release_reason(self, state: EgoState) -> str | None:
        """Why the brakes come off at this state, or None while they stay on."""
        threshold, magnitude = self.event.threshold, self.event.magnitude
        if threshold == "time" and state.time >= self.time_on + magnitude:
            return "time"
        if threshold == "distance" and state.s - self.distance_on >= magnitude:
            return "distance"
        if threshold == "velocity" and state.v < magnitude:
            return "velocity"
        if threshold == "relative_velocity" and self.speed_on - state.v >= magnitude:
            return "relative_velocity"
        if state.stopped:
            return "stopped"
        return None

    def earliest_release(self, state: EgoState, acceleration: float) -> float:
        """A lower bound on the instant the brakes could come off, with |dv/dt| <= acceleration: the earlier of
        the threshold's bound and the stop's (SDL's BRK: a car braked to a complete stop is released, whatever
        the threshold; a threshold beyond the stop, such as a drop larger than the onset speed, never binds).
        The time threshold is that instant exactly (the master steps to it)."""
        threshold, magnitude = self.event.threshold, self.event.magnitude
        stop = state.time + state.v / acceleration
        if threshold == "time":
            reach = self.time_on + magnitude
        elif threshold == "distance":
            reach = state.time + reach_time_scalar(self.distance_on + magnitude - state.s, state.v, acceleration)
        elif threshold == "velocity":
            reach = state.time + max(state.v - magnitude, 0.0) / acceleration
        else:  # relative_velocity: the speed must fall to speed_on - magnitude, which may be below 0
            reach = state.time + max(state.v - (self.speed_on - magnitude), 0.0) / acceleration
        return min(reach, stop)
