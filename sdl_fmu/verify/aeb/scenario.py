"""One test of the grid as a scenario: generated, not read from SDL (a CCRb target brakes from the start, which SDL
text cannot say). Metric units; the ego starts at the test speed in lane 1's centre, the target is traffic vehicle 1
(an A vehicle with a negative speed, so it moves the ego's way), spawned at the start."""

from __future__ import annotations

from ...sdl.events import (DEFAULT_ROAD, Action, ApproachingVehicle, ClosureTrigger, ModelChoice, Relative,
                           Scenario)
from ...units import KILOMETRE_PER_HOUR, METRIC
from .protocol import START_TTC_S, TARGET_LENGTH_M, TARGET_MODEL, TARGET_WIDTH_M, Test, lateral_offset

TARGET = 1  # the target's vehicle id in the run (the first and only traffic vehicle)


def start_gap(test: Test) -> float:
    """The bumper-to-bumper gap at the start (m): the CCRb headway, else the gap closed in START_TTC_S at the test's
    closing speed."""
    if test.group == "CCRb":
        return test.headway_m
    return START_TTC_S * (test.ego_speed_kmh - test.target_speed_kmh) * KILOMETRE_PER_HOUR


def scenario_of(test: Test, ego_length: float, ego_width: float) -> Scenario:
    """The scenario of one test for an ego of this footprint (m)."""
    target_speed = test.target_speed_kmh * KILOMETRE_PER_HOUR
    lateral = Relative(lateral_offset(test.overlap_pct, ego_width, TARGET_WIDTH_M), relative=True)
    initial = None
    if test.group == "CCRb":  # brakes to a stop at a constant deceleration from the start
        initial = Action(ClosureTrigger(0.0, None), lateral, Relative(0.0, relative=False),
                         target_speed / test.target_decel_mps2)
    target = ApproachingVehicle(line=0, distance=0.0, speed=Relative(-target_speed, relative=False),
                                gap=start_gap(test) + (ego_length + TARGET_LENGTH_M) / 2, lateral=lateral,
                                model=ModelChoice(TARGET_MODEL, TARGET_MODEL), actions=(), initial=initial)
    return Scenario(path=f"aeb-ccr/{test.name.replace(' ', '_').replace('/', '')}", units=METRIC,
                    road=DEFAULT_ROAD, events=(target,), end_distance=None)
