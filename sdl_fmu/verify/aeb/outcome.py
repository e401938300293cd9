"""What one test of the AEB car-to-car pack gives: impact, impact speeds, speed reduction, closest approach, the
protocol's points, and how the test ended (docs/verification.md)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from ...units import KILOMETRE_PER_HOUR
from .protocol import COLOURS, Test, score
from .scenario import TARGET

End = Literal["contact", "stopped", "slower", "time_limit", "timeout", "error"]  # timeout: --test-timeout passed
# km/h: below this the ego counts as stopped where a test ends by no longer closing on a stationary target (the
# run's end is located where the speeds meet: a stop gives exactly 0 in the shipped FMUs)
STOPPED_KMH = 1e-3


@dataclass
class TestOutcome:
    test: Test
    impact: bool | None = None  # None: the run failed (error)
    impact_speed_kmh: float | None = None  # the ego's speed at contact
    relative_impact_speed_kmh: float | None = None  # the ego's minus the target's speed at contact; 0 avoided
    speed_reduction_kmh: float | None = None  # test speed minus the ego's speed at contact (or at the end)
    min_gap_m: float | None = None  # the smallest distance between the footprints (0 at contact)
    min_ttc_s: float | None = None  # the smallest time to collision (None: never on a collision course)
    score: float | None = None  # the protocol's points, 0 .. 1
    end: End = "error"
    end_time_s: float | None = None
    error: str | None = None
    wall_s: float = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """A test passes when it scores the full points (the green band); a run that failed or timed out does not."""
        return self.score is not None and self.score >= 1.0

    @property
    def timed_out(self) -> bool:
        """The run was stopped by the pack's per-test wall-clock limit (verify --test-timeout)."""
        return self.end == "timeout"

    @property
    def failed(self) -> bool:
        """The run failed otherwise (an FMU's or controller's error, a worker lost)."""
        return self.error is not None and not self.timed_out

    @property
    def colour(self) -> str:
        return "grey" if self.score is None else COLOURS[self.score]

    def to_json(self) -> dict:
        return {**self.test.parameters(), "impact": self.impact, "impact_speed_kmh": self.impact_speed_kmh,
                "relative_impact_speed_kmh": self.relative_impact_speed_kmh,
                "speed_reduction_kmh": self.speed_reduction_kmh, "min_gap_m": self.min_gap_m,
                "min_ttc_s": self.min_ttc_s, "score": self.score, "passed": self.passed, "end": self.end,
                "end_time_s": self.end_time_s, "error": self.error, "wall_time_s": round(self.wall_s, 3)}

    @classmethod
    def from_json(cls, test: Test, data: dict) -> TestOutcome:
        """The outcome of `test` as to_json wrote it (a finished test kept in the pack's journal)."""
        return cls(test, **{key: data.get(key) for key in RESULT_KEYS}, end=data.get("end", "error"),
                   wall_s=data.get("wall_time_s") or 0.0)


# the results to_json writes under their own names (from_json reads them back)
RESULT_KEYS = ("impact", "impact_speed_kmh", "relative_impact_speed_kmh", "speed_reduction_kmh", "min_gap_m",
               "min_ttc_s", "score", "end_time_s", "error")


def target_speed(test: Test, time: float) -> float:
    """The target's speed (m/s) at a time of the test: constant, or braking from the start (CCRb) to a stop."""
    speed = test.target_speed_kmh * KILOMETRE_PER_HOUR
    if test.group == "CCRb":
        speed = max(speed - test.target_decel_mps2 * time, 0.0)
    return speed


def evaluate(test: Test, result) -> TestOutcome:
    """The outcome of a test from its run (an api.Result of the test's Metric scenario)."""
    events = list(result.events)
    contact = next((e for e in events if e["code"] == "A" and e["action"] == "collision"), None)
    end = next((e for e in events if e["code"] == "ES"), None)
    final_speed = result.final["speed"]  # m/s: Metric
    vehicle = next((v for v in (result.criticality or {}).get("vehicles", []) if v["vehicle"] == TARGET), {})
    outcome = TestOutcome(test, min_gap_m=vehicle.get("min_distance"), min_ttc_s=vehicle.get("min_ttc_s"))
    if contact is not None:
        ego = contact["speed"]
        outcome.impact = True
        outcome.impact_speed_kmh = ego / KILOMETRE_PER_HOUR
        outcome.relative_impact_speed_kmh = (ego - target_speed(test, contact["time_s"])) / KILOMETRE_PER_HOUR
        outcome.speed_reduction_kmh = test.ego_speed_kmh - outcome.impact_speed_kmh
        outcome.end, outcome.end_time_s = "contact", contact["time_s"]
    else:
        outcome.impact = False
        outcome.relative_impact_speed_kmh = 0.0
        outcome.speed_reduction_kmh = test.ego_speed_kmh - final_speed / KILOMETRE_PER_HOUR
        outcome.end_time_s = end["time_s"] if end else result.final["time_s"]
        if end is not None and end.get("reason") == "not_closing":
            outcome.end = "stopped" if final_speed / KILOMETRE_PER_HOUR < STOPPED_KMH else "slower"
        else:
            outcome.end = "time_limit"
    outcome.score = score(test, outcome.relative_impact_speed_kmh)
    return outcome
