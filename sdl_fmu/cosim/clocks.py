"""The sampled parts of the loop and their instants: the driver model (`driver`, --driver-period), the follow
driver's decisions (`follow`, Gipps' reaction time) and a controller in the loop (`controller`, its map's period).
Each samples at k x its period from the start (k = 0, 1, ...); the master steps to every such instant, so the sampled
parts are never stepped or read inside a located step (docs/controllers.md, Exactness)."""

from __future__ import annotations

# s: instants of different clocks closer than this are one instant (k x 0.01 and j x 0.05 differ in their last bit):
# the master steps to the earliest, and every clock due within MERGE of it samples there. Far below any period
# (>= 1e-3 s), far above the rounding of k x period (4.5e-13 s at the 3600 s time limit).
MERGE = 1e-9


class SampleClocks:
    """Per clock its period and the k of its next sample; `earliest` is the next instant any clock samples at."""

    def __init__(self, periods: dict[str, float]):
        self.periods = dict(periods)
        # per clock [name, period, k of the next sample, its instant]: lists, read and moved on at every step end
        self._clocks = [[name, period, 1, period] for name, period in self.periods.items()]
        self.earliest = min(clock[3] for clock in self._clocks)

    def due(self, t: float) -> dict[str, int]:
        """The clocks that sample at t (a step that ended at `earliest`), each with the k of this sample, and moves
        them on; {} before `earliest` (a step that ended at a trigger's instant)."""
        if t < self.earliest:
            return {}
        limit = t + MERGE
        due = {}
        for clock in self._clocks:
            if clock[3] <= limit:
                period, k = clock[1], clock[2] + 1
                while k * period <= limit:
                    k += 1
                due[clock[0]] = k - 1
                clock[2], clock[3] = k, k * period
        clocks = self._clocks
        self.earliest = clocks[0][3] if len(clocks) == 1 else min(clock[3] for clock in clocks)
        return due
