"""Runs the AEB car-to-car grid: each test a run through sdl_fmu.api, on Dask (the sweep's cluster and file shipping:
the ego FMU, its map, the controller FMU and map go to the workers as bytes), or in this process (workers=0).

A test's run: the ego at the test speed, the built-in lane driver, the controller in the loop, ended at contact
(on_collision "stop") or when the ego no longer closes on the target (until_not_closing), with a time limit as a
fail-safe, and a wall-clock limit per test (`--test-timeout`, options.DEFAULT_TEST_TIMEOUT): a run that outlasts it
ends as `timeout` (a hung controller's host is killed). Every failure is the test's result (its error), never the
pack's. `Progress` says on stderr how far the pack is."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Callable, TextIO

from ...options import DEFAULT_TEST_TIMEOUT, RunTimeout
from ...shipping import client as cluster_client
from ...shipping import materialize, one_file, passed_on
from ...units import KILOMETRE_PER_HOUR
from .outcome import TestOutcome, evaluate
from .protocol import GROUPS, Group, Test
from .scenario import TARGET, scenario_of

TEST_TIME_LIMIT = 60.0  # s simulated: a test that has neither touched nor stopped closing by then ends (time_limit)
SHIPPED_OPTIONS = ("fmu", "vehicle", "controller", "controller_map")  # the file-valued options, sent as bytes
Footprint = tuple[float, float]  # the ego's length and width (m), as the run uses them


def run_test(test: Test, options: dict, run: Callable, footprint: Footprint,
             timeout: float = DEFAULT_TEST_TIMEOUT) -> TestOutcome:
    """One test through `run` (sdl_fmu.api.run) with `options` (its keyword options: dynamics, fmu, vehicle, params,
    controller, controller_map), stopped after `timeout` s of wall clock; always returns the outcome, with the error
    when the run failed (end `timeout`: it was stopped)."""
    began = time.perf_counter()
    try:
        result = run(scenario_of(test, *footprint), speed=test.ego_speed_kmh * KILOMETRE_PER_HOUR,
                     until_time=TEST_TIME_LIMIT, until_not_closing=TARGET, on_collision="stop",
                     timeout=timeout, plot=False, **options)
        outcome = evaluate(test, result)
    except RunTimeout as error:
        outcome = TestOutcome(test, end="timeout", error=_first_line(error))
    except Exception as error:  # noqa: BLE001 - an FMU error or a bug: the test's result
        outcome = TestOutcome(test, error=_first_line(error))
    outcome.wall_s = time.perf_counter() - began
    return outcome


def _first_line(error: BaseException) -> str:
    return (str(error).strip() or type(error).__name__).splitlines()[0]


def _run_shipped(bundles: dict, test: Test, options: dict, run: Callable, footprint: Footprint,
                 timeout: float) -> TestOutcome:
    """run_test on a worker, its files from the shipped bundles (materialised once per worker)."""
    try:
        paths = {option: str(materialize(bundle)) for option, bundle in bundles.items()}
    except OSError as error:
        return _lost(test, f"cannot write the shipped files: {error}")
    return run_test(test, {**options, **paths}, run, footprint, timeout)


def _lost(test: Test, error: str) -> TestOutcome:
    """A test that could not run for want of its worker (not the test's result: a resumed pack runs it again)."""
    return TestOutcome(test, error=error, extra={"rerun": True})


def run_grid(tests: list[Test], options: dict, run: Callable, footprint: Footprint, *, workers: int | None = None,
             scheduler: str | None = None, client=None, timeout: float = DEFAULT_TEST_TIMEOUT,
             progress: Callable[[TestOutcome], None] | None = None) -> list[TestOutcome]:
    """Every test, in the grid's order, each stopped after `timeout` s of wall clock. workers=0: one after the other
    in this process; else on Dask, as a sweep runs (`client`, or `scheduler`'s address, or a LocalCluster of `workers`
    processes, default one per core). `progress` is called with each outcome as it comes. `run` is sdl_fmu.api.run
    (given, so that this pack, which the API runs, does not import it)."""
    if not tests:
        return []
    if workers == 0 and scheduler is None and client is None:
        outcomes = []
        for test in tests:
            outcomes.append(run_test(test, options, run, footprint, timeout))
            if progress is not None:
                progress(outcomes[-1])
        return outcomes
    from distributed import as_completed

    bundles = {option: one_file(Path(options[option])) for option in SHIPPED_OPTIONS if options.get(option)}
    common = {key: value for key, value in options.items() if key not in bundles}
    owned = []
    try:
        if client is None:
            client, owned = cluster_client(workers, scheduler, len(tests))
        shipped = {option: client.submit(passed_on, bundle, key=f"sdl-fmu-files-{bundle.digest}")
                   for option, bundle in bundles.items()}
        futures = {client.submit(_run_shipped, shipped, test, common, run, footprint, timeout, pure=False): k
                   for k, test in enumerate(tests)}
        outcomes: list[TestOutcome | None] = [None] * len(tests)
        for future in as_completed(futures):
            k = futures[future]
            try:
                outcomes[k] = future.result()
            except Exception as error:  # noqa: BLE001 - the worker died or the task could not run
                outcomes[k] = _lost(tests[k], f"{type(error).__name__}: {error}")
            if progress is not None:
                progress(outcomes[k])
        for future in shipped.values():
            future.release()
        return outcomes
    finally:
        for thing in owned:
            thing.close()


def totals(outcomes: list[TestOutcome]) -> dict[Group, dict]:
    """Per group: tests, impacts, failed runs (errors), runs stopped by the timeout (timeouts), points and the
    maximum, the share of the maximum (%), tests passed."""
    summary = {}
    for group in GROUPS:
        mine = [o for o in outcomes if o.test.group == group]
        if not mine:
            continue
        points = sum(o.score or 0.0 for o in mine)
        summary[group] = {"tests": len(mine), "impacts": sum(bool(o.impact) for o in mine),
                          "errors": sum(o.failed for o in mine), "timeouts": sum(o.timed_out for o in mine),
                          "points": points,
                          "max_points": float(len(mine)), "score_pct": 100.0 * points / len(mine),
                          "passed": sum(o.passed for o in mine)}
    return summary


class Progress:
    """The pack's progress on stderr, after each test: `aeb-ccr: 37/120 tests done, 2 failed, 1 timed out, 41 s` (the
    tests kept from an interrupted pack count as done). `every`: a line per test; else a line only for a test that
    failed or timed out (what a pack run into a log shows). On a terminal (`live`) the line is rewritten in place."""

    def __init__(self, total: int, kept: list[TestOutcome], *, every: bool = True, live: bool = False,
                 stream: TextIO | None = None):
        self.total, self.every, self.live = total, every, live
        self.stream = sys.stderr if stream is None else stream
        self.done, self.failed, self.timed_out = len(kept), sum(o.failed for o in kept), sum(o.timed_out for o in kept)
        self.began = time.monotonic()

    def line(self) -> str:
        return (f"aeb-ccr: {self.done}/{self.total} tests done, {self.failed} failed, {self.timed_out} timed out, "
                f"{time.monotonic() - self.began:.0f} s")

    def __call__(self, outcome: TestOutcome) -> None:
        self.done += 1
        self.failed += outcome.failed
        self.timed_out += outcome.timed_out
        if self.live:
            self.stream.write(f"\r{self.line()}\x1b[K")
        elif self.every or outcome.error is not None:
            self.stream.write(self.line() + "\n")
        self.stream.flush()

    def close(self) -> None:
        """Ends a live line (the table follows on stdout)."""
        if self.live and self.done:
            self.stream.write("\n")
            self.stream.flush()
