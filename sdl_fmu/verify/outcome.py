"""What one manoeuvre of the vehicle test pack hands to the report: metrics, verdict, time series, plot data."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from .drive import Trace

ManoeuvreName = Literal["braking", "steady_state_circular", "step_steer", "sine_with_dwell", "split_mu_braking",
                        "double_lane_change"]


@dataclass
class Outcome:
    name: ManoeuvreName
    standard: str  # the public source of the input and the criteria
    metrics: dict = field(default_factory=dict)  # JSON-ready, SI names with units in the keys
    passed: bool | None = None  # None: the manoeuvre has no criterion, or does not apply
    reason: str | None = None  # one line: why it failed or does not apply
    criteria: list[str] = field(default_factory=list)  # each criterion, with its verdict, for the report
    runs: list[tuple[str, Trace]] = field(default_factory=list)  # (run label, its time series)
    plot: dict = field(default_factory=dict)  # what the manoeuvre's standard plot needs beyond the traces
    seconds: float = 0.0  # wall time

    def to_json(self) -> dict:
        return {"standard": self.standard, **self.metrics, "passed": self.passed, "reason": self.reason,
                "criteria": self.criteria, "wall_time_s": round(self.seconds, 3)}
