"""The end of a run when the ego no longer closes on a traffic vehicle (the vehicle test packs' end of a test:
Euro NCAP's car-to-car rear tests end when the ego stops or is slower than the target; docs/verification.md).

The watched vehicle is given by its id. Its relative speed along the road, rel = its velocity along the road - the
ego's (vx cos psi - vy sin psi), is continuous in time, and |d rel / dt| <= A + the vehicle's speed ramp rate (A:
the ego's acceleration bound). Two located triggers follow each other: first the ego *closes* on the vehicle
(rel < 0; true at once when the run starts closing, as in a test from 4 s TTC; located when the two start at the
same speed and the vehicle brakes), then it *no longer closes* (rel >= 0): the run ends there. A stop behind a
stopped vehicle is rel = 0: the end. Both are false at the start of any step, as the trigger schedule requires."""

from __future__ import annotations

import math

from ..vehicle import EgoState
from .traffic import Traffic
from .triggers import EgoBounds


class ClosingEnd:
    """Watches traffic vehicle `vehicle` (its id, 1-based in spawn order)."""

    def __init__(self, vehicle: int, traffic: Traffic, bounds: EgoBounds):
        self.index = vehicle - 1
        self.traffic, self.bounds = traffic, bounds
        self.closing = False  # the ego has closed on the vehicle (rel < 0 at a fired instant)

    def _relative(self, state: EgoState) -> tuple[float, float] | None:
        """(rel, its rate bound) at the state's time, or None while the vehicle is not on the road."""
        traffic = self.traffic
        if self.index >= traffic.size or not traffic.present[self.index]:
            return None
        _, _, speed, _, speed_rate = traffic.motion_of(self.index, state.time)
        along = state.vx * math.cos(state.psi) - state.vy * math.sin(state.psi)
        return -speed - along, self.bounds.acceleration + speed_rate

    def horizon(self, state: EgoState) -> float:
        """A lower bound on the instant the next trigger could become true (absolute time)."""
        relative = self._relative(state)
        if relative is None:
            return math.inf  # the vehicle's spawn fires first, and the bounds are recomputed then
        rel, rate = relative
        margin = -rel if self.closing else rel
        return state.time + max(margin, 0.0) / rate

    def triggered(self, state: EgoState) -> bool:
        relative = self._relative(state)
        if relative is None:
            return False
        return relative[0] >= 0 if self.closing else relative[0] < 0

    def fire(self, state: EgoState) -> bool:
        """At a fired instant: notes that the ego closes on the vehicle; True when the run ends here."""
        relative = self._relative(state)
        if relative is None:
            return False
        if not self.closing:
            self.closing = relative[0] < 0
            return False
        return relative[0] >= 0
