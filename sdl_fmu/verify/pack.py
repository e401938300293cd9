"""The vehicle test pack: runs the manoeuvres against one vehicle, each failure contained in its manoeuvre."""

from __future__ import annotations

import time as clock
from typing import Callable, Iterable

from . import braking, circular, closed_forms, lane_change, sine_with_dwell, split_mu, step_steer
from .drive import ManoeuvreFailed
from .outcome import Outcome

MANOEUVRES: dict[str, tuple[str, Callable]] = {
    "braking": (braking.STANDARD, braking.run),
    "steady_state_circular": (circular.STANDARD, circular.run),
    "step_steer": (step_steer.STANDARD, step_steer.run),
    "sine_with_dwell": (sine_with_dwell.STANDARD, sine_with_dwell.run),
    "split_mu_braking": (split_mu.STANDARD, split_mu.run),
    "double_lane_change": (lane_change.STANDARD, lane_change.run),
}


def run_manoeuvre(model, name: str) -> Outcome:
    """One manoeuvre; a vehicle that cannot be driven through it fails it with a one-line reason."""
    standard, run = MANOEUVRES[name]
    started = clock.perf_counter()
    try:
        outcome = run(model)
    except ManoeuvreFailed as failure:
        outcome = Outcome(name, standard, passed=False, reason=str(failure), criteria=[f"FAIL: {failure}"])
    outcome.seconds = clock.perf_counter() - started
    return outcome


def run_pack(model, names: Iterable[str] | None = None) -> list[Outcome]:
    """The outcomes of the named manoeuvres (default all), in the pack's order, one after the other."""
    chosen = set(MANOEUVRES) if names is None else set(names)
    outcomes = [run_manoeuvre(model, name) for name in MANOEUVRES if name in chosen]
    stop = next((o for o in outcomes if o.name == "braking"), None)
    if stop is not None and model.spec_closed_forms and model.fmi_version == "2.0":
        _add_closed_form_stops(model, stop)
    return outcomes


def _add_closed_form_stops(model, stop: Outcome) -> None:
    """The closed-form braking distances (docs/verification.md), for a vehicle whose map says they hold (the Simple FMU): the 60
    straight-line stops beside the R13-H stop, each within 1e-9 relative."""
    cases = closed_forms.verify(model.fmu_path)
    worst = max(max(abs(c.distance_error), abs(c.time_error)) for c in cases)
    stop.metrics.update(closed_form_cases=len(cases), closed_form_max_relative_error=worst)
    stop.criteria.append(f"{len(cases)} closed-form braking stops, largest relative error "
                         f"{worst:.1e} <= 1e-9: {'pass' if worst <= 1e-9 else 'FAIL'}")
    if stop.passed is not None:
        stop.passed = stop.passed and worst <= 1e-9
