"""The BRK controller: holds the pedals from the event until its threshold or a stop (seed text)."""

from __future__ import annotations

from dataclasses import dataclass

from ..sdl.events import Brake
from .ego import EgoState


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
        if threshold == "time" and state.time - self.time_on >= magnitude:
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
