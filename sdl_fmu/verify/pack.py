"""The vehicle test pack: runs the manoeuvres against one vehicle, each failure contained in its manoeuvre."""

from __future__ import annotations

import time as clock
from typing import Callable, Iterable

from . import braking, circular, lane_change, sine_with_dwell, split_mu, step_steer
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
    return [run_manoeuvre(model, name) for name in MANOEUVRES if name in chosen]
