"""What one manoeuvre of the vehicle test pack hands to the report: metrics, verdict, time series, plot data.

Each criterion has a verdict (`Verdict`): pass, FAIL, n/a (it does not apply to this vehicle: no wheel that locks, no
friction input; always with its reason) or report (the standard sets no limit). An n/a criterion is never a
failure: the manoeuvre's `passed` and --strict count only FAIL."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from .drive import Trace

Verdict = Literal["pass", "FAIL", "n/a", "report"]
VERDICTS: tuple[Verdict, ...] = ("pass", "FAIL", "n/a", "report")
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
    # per criterion (the same order as `criteria`): {"criterion", "verdict", "reason"}; judge() fills both
    verdicts: list[dict] = field(default_factory=list)

    def judge(self, text: str, ok: bool | None, reason: str | None = None) -> bool | None:
        """Records a criterion: ok True (pass), False (FAIL), None with a reason (n/a: it does not apply to this
        vehicle) or None without one (report: no limit). Returns ok."""
        verdict: Verdict = "report" if ok is None and not reason else "n/a" if ok is None else "pass" if ok else "FAIL"
        self.criteria.append(f"{text}: {verdict}" + (f" ({reason})" if reason else ""))
        self.verdicts.append({"criterion": text, "verdict": verdict, "reason": reason})
        return ok

    def criterion_verdicts(self) -> list[dict]:
        """Every criterion with its verdict: those recorded by judge(), the others read from their text (a criterion
        written as text ends in its verdict: ": pass", ": FAIL"; "not applicable"; else a report)."""
        judged = {entry["criterion"] + f": {entry['verdict']}" + (f" ({entry['reason']})" if entry["reason"] else "")
                  : entry for entry in self.verdicts}
        entries = []
        for text in self.criteria:
            if text in judged:
                entries.append(judged[text])
                continue
            verdict: Verdict = ("FAIL" if text.endswith(": FAIL") or text.startswith("FAIL") else
                                "pass" if text.endswith(": pass") else
                                "n/a" if text.startswith("not applicable") else "report")
            entries.append({"criterion": text, "verdict": verdict,
                            "reason": self.reason if verdict in ("n/a", "FAIL") and text.startswith(("not", "FAIL"))
                            else None})
        return entries

    def to_json(self) -> dict:
        return {"standard": self.standard, **self.metrics, "passed": self.passed, "reason": self.reason,
                "criteria": self.criteria,
                "verdicts": self.criterion_verdicts(), "wall_time_s": round(self.seconds, 3)}
