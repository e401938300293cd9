"""The locator: the instant inside a communication step at which something turns true, found by probing the
ego FMU from a saved state (`probe(t)` steps it there and reads it). Triggers (ego.step_until_time) and the
criticality record's extremes (follower.py) both use it: `first_instant` bisects a condition,
`root_instant` finds where a rate turns from < 0 to >= 0 in fewer probes where the rate is smooth."""

from __future__ import annotations

import math
from typing import Callable

from ..vehicle import EgoState

TIME_TOLERANCE = 1e-6  # s, how exactly a trigger's instant is located
# s, how exactly a criticality extreme's instant is located (a bracket this wide holds the root, so that two
# runs at different steps agree within TIME_TOLERANCE)
CRITICALITY_TOLERANCE = TIME_TOLERANCE / 4
# the fraction of the way to a flat extreme's extended root a probe goes (root_instant): short of it, so that
# the probes approach it from below, where the rate is known
FLAT_STEP = 0.98

Probe = Callable[[float], EgoState]
# known(middle, (instant, state) probed last below, (instant, state) probed last above): True / False, or None
Known = Callable[[float, tuple, tuple], 'bool | None']


def first_instant(probe: Probe, low: float, high: float, condition: Callable[[EgoState], bool], tolerance: float,
                  high_state: EgoState | None = None, below: Callable[[float], None] | None = None,
                  known: Known | None = None) -> tuple[float, EgoState | None, EgoState | None]:
    """Bisects (low, high], where the condition is false at low and true at high, to a bracket no wider than
    `tolerance`: (its high end, the state probed at its low end, the state at its high end; None where that
    end was not probed, high_state for the given high end). `below(t)` is called after each probe at which the
    condition is false (the caller may then move its snapshot there). With `known(middle, (instant, state)
    probed last below, (instant, state) probed last above)`, a test that is True or False where it can tell the
    condition without a probe (None: a probe): the same midpoints and outcomes, fewer probes, and the state at
    the final high end probed once if it was not (the state at the low end is then that of the last probe
    below)."""
    low_state = None
    last_below, last_above = (low, None), (high, high_state)
    while high - low > tolerance:
        middle = 0.5 * (low + high)
        outcome = None if known is None else known(middle, last_below, last_above)
        probed = None
        if outcome is None:
            probed = probe(middle)
            outcome = condition(probed)
        if outcome:
            high, high_state = middle, probed
            if probed is not None:
                last_above = (middle, probed)
        else:
            low, low_state = middle, probed
            if probed is not None:
                last_below = (middle, probed)
                if below is not None:
                    below(middle)
    if known is not None:
        if high_state is None:
            high_state = probe(high)
        low_state = last_below[1]
    return high, low_state, high_state


def root_instant(probe: Probe, low: float, high: float, value: Callable[[EgoState], float], low_value: float,
                 high_value: float, tolerance: float, high_state: EgoState) -> tuple[EgoState | None, EgoState]:
    """first_instant for `value(state) >= 0` of a rate turning from < 0 at low to >= 0 at high: the same bracket
    to `tolerance`, with fewer probes where the rate is smooth (regula falsi, Illinois variant; each estimate
    kept tolerance / 2 inside the bracket, so that once near the root the next probe closes the bracket from
    the other side; bisection whenever a probe did not halve it). Returns (state before, state at) the root.
    While the rate at high is exactly 0 (a flat extreme: the distance to a car passing in the next lane, whose
    rate rises continuously to 0 at the root and stays 0 after it) the secant to high only ever points at high:
    the estimate is then the secant through the last two probes below the root, extended to 0, taken FLAT_STEP
    of the way (or bisection before there are two, and after a probe past the root that did not halve the
    bracket)."""
    low_state = None
    side, halve = 0, False
    rising, earlier = low_value, None  # the rate at low (unscaled), and (instant, rate) of the low before
    while high - low > tolerance:
        width = high - low
        slope = high_value - low_value
        guess = 0.5 * (low + high)
        flat = high_value == 0.0
        if halve:
            pass
        elif flat:
            if earlier is not None and rising > earlier[1]:
                extended = low - rising * (low - earlier[0]) / (rising - earlier[1])
                if extended < high:
                    # FLAT_STEP of the way, to stay below the root (then the next extension is nearer), and
                    # once it is within tolerance / 2, a probe there to close the bracket
                    guess = low + FLAT_STEP * (extended - low)
        elif slope > 0.0 and math.isfinite(slope):
            guess = low - low_value * width / slope
        guess = min(max(guess, low + 0.5 * tolerance), high - 0.5 * tolerance)
        probed = probe(guess)
        rate = value(probed)
        if rate >= 0:
            high, high_state, high_value = guess, probed, rate
            if side > 0:
                low_value *= 0.5
            side = 1
        else:
            earlier = (low, rising)
            low, low_state, low_value, rising = guess, probed, rate, rate
            if side < 0:
                high_value *= 0.5
            side = -1
        halve = high - low > 0.5 * width and not (flat and rate < 0)
    return low_state, high_state
