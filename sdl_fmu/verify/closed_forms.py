"""`sdl-fmu verify`: straight-line braking of the Simple FMU against its closed forms (docs/verification.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import product
from pathlib import Path

from fmpy import read_model_description

from ..cosim.ego import EgoFMU, parameter_defaults, step_until
from ..names import WHEELS
from ..units import STANDARD_GRAVITY


@dataclass(frozen=True)
class BrakingCase:
    v0: float  # m/s
    mu: float
    brake: float  # pedal 0..1
    resistances: bool  # drag and rolling resistance on (the FMU's defaults) or set to 0


@dataclass(frozen=True)
class BrakingResult:
    case: BrakingCase
    expected_distance: float
    simulated_distance: float
    expected_time: float
    simulated_time: float

    @property
    def distance_error(self) -> float:
        return (self.simulated_distance - self.expected_distance) / self.expected_distance

    @property
    def time_error(self) -> float:
        return (self.simulated_time - self.expected_time) / self.expected_time


def default_cases() -> list[BrakingCase]:
    return [BrakingCase(v0, mu, brake, resistances)
            for resistances, v0, mu, brake in product((False, True), (15.0, 35.0), (0.2, 0.4, 0.6, 0.8, 1.0), (0.25, 0.5, 1.0))]


def closed_form(case: BrakingCase, parameters: dict[str, float]) -> tuple[float, float]:
    """Stopping distance and time of dv/dt = -(A + K v^2), A = min(b a_max, mu g) + f_r g, K = rho CdA / (2 m).

    K = 0: s = v0^2 / (2A), t = v0 / A.  K > 0: s = ln(1 + K v0^2 / A) / (2K), t = atan(v0 sqrt(K/A)) / sqrt(A K).
    """
    g = STANDARD_GRAVITY
    deceleration = min(case.brake * parameters["brake_decel_max"], case.mu * g)
    rolling = parameters["rolling_resistance"] if case.resistances else 0.0
    k = parameters["air_density"] * parameters["drag_area"] / (2 * parameters["mass"]) if case.resistances else 0.0
    a = deceleration + rolling * g
    if k == 0.0:
        return case.v0**2 / (2 * a), case.v0 / a
    return math.log(1 + k * case.v0**2 / a) / (2 * k), math.atan(case.v0 * math.sqrt(k / a)) / math.sqrt(a * k)


def simulate_stop(fmu: Path, case: BrakingCase, step: float = 0.1) -> tuple[float, float]:
    """Stopping distance and time through fmpy co-simulation; the stop instant is bisected to 1e-9 s."""
    start = {"v0": case.v0, "brake": case.brake, **{f"mu_{w}": case.mu for w in WHEELS}}
    if not case.resistances:
        start.update(drag_area=0.0, rolling_resistance=0.0)
    ego = EgoFMU(fmu, start, instance_name="verify")
    try:
        for _ in range(int(600 / step)):
            if step_until(ego, step, lambda state: state.stopped):
                state = ego.read()
                return state.s, state.time
        raise RuntimeError(f"{case}: the vehicle did not stop within 600 s")
    finally:
        ego.close()


def verify(fmu: Path, cases: list[BrakingCase] | None = None) -> list[BrakingResult]:
    parameters = parameter_defaults(read_model_description(str(fmu)))
    results = []
    for case in cases or default_cases():
        expected_distance, expected_time = closed_form(case, parameters)
        simulated_distance, simulated_time = simulate_stop(fmu, case)
        results.append(BrakingResult(case, expected_distance, simulated_distance, expected_time, simulated_time))
    return results


def format_table(results: list[BrakingResult]) -> str:
    header = (f"{'v0 m/s':>7} {'mu':>4} {'brake':>6} {'drag+rr':>7} {'s exact m':>12} {'s sim m':>12} {'rel err':>9}"
              f" {'t exact s':>10} {'t sim s':>10} {'rel err':>9}")
    lines = [header, "-" * len(header)]
    for r in results:
        c = r.case
        lines.append(f"{c.v0:7.1f} {c.mu:4.1f} {c.brake * 100:5.0f}% {'on' if c.resistances else 'off':>7}"
                     f" {r.expected_distance:12.6f} {r.simulated_distance:12.6f} {r.distance_error:9.1e}"
                     f" {r.expected_time:10.6f} {r.simulated_time:10.6f} {r.time_error:9.1e}")
    worst = max(abs(r.distance_error) for r in results)
    lines.append(f"{len(results)} cases, largest relative distance error {worst:.1e}")
    return "\n".join(lines)
