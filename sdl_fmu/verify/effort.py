"""The brake effort at which a vehicle's wheels begin to lock, found from its motion alone.

A vehicle FMU shows no wheels, but a wheel that locks shows in the car's deceleration: its braking force no longer
grows with the pedal (it slides, at its sliding friction, which may be below the peak). Braked from a speed with a
pedal p held, the car's deceleration d(p) (its mean over PROBE_TIME after the application) grows with p at a rate
set by the brakes while every wheel rolls, and at a lower rate (or falls) once a wheel has locked. locking_limit
finds the highest pedal below the first lock that its caller's `minimum_growth` (m/s^2 per unit pedal) can tell:
runs at pedals rising by STEP find the first step over which d does not grow by minimum_growth x the step (successive
runs of rising effort, as a test driver makes them); bisection then on p with the predicate 'd grows by
minimum_growth from p to p + RESOLUTION' narrows the limit. The largest p that passes lies below the lock: a wheel
that locks between p and p + RESOLUTION takes its share of the growth away. A vehicle whose deceleration grows all the
way (ABS, or brakes weaker than its tires) gets full pedal.
"""

from __future__ import annotations

from .drive import drive

STEP = 0.1  # pedal between successive runs
RESOLUTION = 0.005  # pedal: the bisection's end
PROBE_TIME = (0.3, 0.8)  # s after the application: the deceleration (v(t0) - v(t1)) / (t1 - t0)


class Probes:
    """The deceleration of brake applications from one speed on one surface, each pedal run once."""

    def __init__(self, model, speed: float, friction=None):
        self.model, self.speed, self.friction = model, speed, friction
        self.runs: list[dict] = []
        self._measured: dict[float, float] = {}

    def __call__(self, pedal: float) -> float:
        pedal = round(pedal, 9)
        if pedal not in self._measured:
            trace = drive(self.model, self.speed, lambda t, state: (0.0, pedal, 0.0), PROBE_TIME[1],
                          friction=self.friction, settle=0.0)
            start, end = PROBE_TIME
            self._measured[pedal] = (trace.at("speed_mps", start) - trace.at("speed_mps", end)) / (end - start)
            self.runs.append({"brake": pedal, "deceleration_mps2": self._measured[pedal]})
        return self._measured[pedal]


def locking_limit(probes: Probes, minimum_growth: float) -> float:
    """The highest pedal at which the deceleration still grows by minimum_growth (m/s^2 per unit pedal)."""

    def grows(low: float, high: float) -> bool:
        return probes(high) - probes(low) >= minimum_growth * (high - low)

    low = 0.0
    steps = int(round(1 / STEP))
    for k in range(1, steps + 1):
        if not grows(low, k * STEP):
            high = k * STEP
            break
        low = k * STEP
    else:
        return 1.0  # the deceleration grows up to full pedal
    low = max(low - RESOLUTION, 0.0)  # the last step grew as a whole; the limit may lie inside it
    while high - low > RESOLUTION:
        middle = (low + high) / 2
        if grows(middle, middle + RESOLUTION):
            low = middle
        else:
            high = middle
    return low
