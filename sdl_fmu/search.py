"""Worst-case search: an optimiser proposes the varied values, the sweep's Dask runs try them, round after round.

    sdl-fmu search SCENARIO --vary NAME=LOW..HIGH ... (--minimize MEASURE | --maximize MEASURE | --spec STL)
                   --budget N [--method tpe|cmaes|random] [--seed S] [--workers N | --scheduler ADDRESS] --out DIR

NAME is any name a sweep varies (sweep.py: speed, until_time, until_distance, seed, an FMU parameter, rsa.LINE), each
over a range: a trial draws it from LOW..HIGH (seed: whole numbers). Two trials per worker thread of the cluster are
kept running (sweep.run_rows: the same shipped files, the same one run per trial through sdl_fmu.api); as each comes
back the optimiser is told its objective and proposes the next: optuna's TPE (multivariate, the constant liar for
the trials still running) or its random sampler, or CMA-ES (the `cma` package, a generation proposed once the last is
back). The objective is a measure of the run (summary.json's and the sweep table's numeric keys,
computed on the worker) or the robustness of a signal temporal logic formula over timeseries.csv's columns (rtamt,
dense time), which the search minimises (negative: the formula is violated).

Every finished trial is appended at once to DIR/search-trials.jsonl, each proposal before its run starts, so
an interrupted search resumes: the finished trials are told to a new optimiser again (TPE and random take them as
they are; CMA-ES replays its generations from the seed, each proposal checked equal to the one recorded) and are
never run again; the proposals that were not finished are run with the values they had. A proposal's sampler is
seeded from --seed and the proposal's number, so nothing of an optimiser's state is stored but the trials.

DIR then holds search.parquet and search.csv (every trial: its values, status, objective, the best so far, the run's
table row), worst.sdl (the scenario of the worst trial with its scenario values written in), worst/ (that trial run
again here: its results folder), search.png, report.html and search.json (the search's description and the worst
case, with the command line that reproduces it)."""

from __future__ import annotations

import base64
import contextlib
import dataclasses
import html
import json
import math
import os
import re
import shlex
import sys
from pathlib import Path
from typing import Literal

from . import sweep as sweeping
from .distributions import finite_number, shown_assignment
from .journal import append as append_row, line as row_line
from .results.folder import SEARCH_MANIFEST_FORMAT, SEARCH_MANIFEST_NAME
from .shipping import ClusterError

Method = Literal["tpe", "cmaes", "random"]
METHODS: tuple[Method, ...] = ("tpe", "cmaes", "random")
Direction = Literal["minimize", "maximize"]
TABLE_NAME, CSV_NAME, JOURNAL_NAME, SPEC_NAME, PLOT_NAME, REPORT_NAME, WORST_SDL, WORST_FOLDER = (
    "search.parquet", "search.csv", "search-trials.jsonl", "search.json", "search.png", "report.html", "worst.sdl",
    "worst")
WORST_PLOT = ".worst-plot.png"  # the worst run's plot for the report, while it is written
OWN_FILES = {TABLE_NAME, CSV_NAME, JOURNAL_NAME, SPEC_NAME, PLOT_NAME, REPORT_NAME, WORST_SDL}
MANIFEST_NAME, MANIFEST_FORMAT = SEARCH_MANIFEST_NAME, SEARCH_MANIFEST_FORMAT
PARTIAL = ".partial"
MAX_BUDGET = 100_000
DEFAULT_TIMEOUT = sweeping.DEFAULT_TIMEOUT
# what a measure may be spelled as: a table column (with an optional unit suffix and AN_ / brkN_ prefix) of these
MEASURES = ("collisions", "final_time_s", "final_distance", "final_speed", "final_lateral", "sim_wall_s",
            "real_time_factor", "warnings", "impact_speed", "relative_impact_speed", "min_distance",
            "min_distance_time_s", "min_ttc_s", "min_ttc_time_s", "max_drac", "max_drac_time_s", "min_pet_s",
            "min_headway_s", "min_headway_time_s", "on_time_s", "off_time_s", "distance", "stop_distance")
UNIT_SUFFIXES = ("_ft/s2", "_m/s2", "_ft/s", "_m/s", "_ft", "_m")
SUMMARY_KEYS = ("collisions", "final", "criticality", "timing", "seed", "controller", "driver", "vehicle")
# rtamt's words: never a timeseries column
STL_WORDS = {"always", "eventually", "historically", "once", "until", "since", "and", "or", "not", "implies", "iff",
             "xor", "rise", "fall", "prev", "next", "abs", "sqrt", "exp", "pow", "true", "false", "G", "F", "H", "O",
             "U", "S", "s", "ms", "us", "ns"}


class SearchError(ClusterError):
    """A mistake in the search's arguments or output folder, or a cluster it cannot use (one line)."""


class ObjectiveError(ValueError):
    """The objective cannot be computed from a run's results (a --spec naming no column of timeseries.csv)."""


# ---- what varies, and the objective ----------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Range:
    """A varied name and the range a trial draws it from (whole numbers for seed)."""

    name: str
    low: float
    high: float
    integer: bool = False

    def value(self, unit: float):
        """The value at `unit` in 0..1 of the range (CMA-ES proposes there)."""
        value = self.low + min(max(unit, 0.0), 1.0) * (self.high - self.low)
        return int(round(value)) if self.integer else value


def parse_ranges(assignments: list[str]) -> dict[str, Range]:
    """NAME=LOW..HIGH, each name once; finite LOW <= HIGH (seed: whole numbers in 0 .. 2^63 - 1). NAME alone: a
    scenario parameter's declared range (`// @param NAME = VALUE in LOW..HIGH`), read with the scenario (declared)."""
    from .options import LIMITS

    ranges: dict[str, Range] = {}
    for assignment in assignments:
        name, separator, text = assignment.partition("=")
        name, text = name.strip(), text.strip()
        if not separator and re.fullmatch(r"\$?[A-Za-z_]\w*", name, flags=re.ASCII):
            if name in ranges:
                raise SearchError(f"--vary {name} is given twice")
            ranges[name] = Range(name, math.nan, math.nan)  # the declared range, filled in by declared()
            continue
        low, dots, high = text.partition("..")
        try:
            if not separator or not name or not dots:
                raise ValueError
            low_value, high_value = finite_number(low), finite_number(high)
            if high_value < low_value:
                raise ValueError
        except ValueError:
            raise SearchError(f"--vary {shown_assignment(name, text)}: expected NAME=LOW..HIGH (finite numbers, "
                              "LOW <= HIGH)") from None
        if name in ranges:
            raise SearchError(f"--vary {name} is given twice")
        integer = name == "seed"
        if integer:
            lowest, highest = LIMITS["seed"]
            if low_value != int(low_value) or high_value != int(high_value) or not (
                    lowest <= low_value and high_value <= highest):
                raise SearchError(f"--vary {name}={text}: seeds are whole numbers from {lowest} to {highest}")
        ranges[name] = Range(name, low_value, high_value, integer)
    if not ranges:
        raise SearchError("give at least one --vary NAME=LOW..HIGH")
    return ranges


def declared(ranges: dict[str, Range], scenario) -> dict[str, Range]:
    """The ranges with each NAME given alone taken from the scenario's declaration (whole numbers where every field
    using it takes one); SearchError for a name the scenario declares without a range, or does not declare."""
    parameters = {parameter.name: parameter for parameter in scenario.parameters}
    filled = {}
    for name, r in ranges.items():
        if math.isnan(r.low):
            parameter = parameters.get(name.removeprefix("$"))
            if parameter is None or parameter.low is None or parameter.high is None:
                what = "declares no range for it" if parameter is not None else "declares no parameter of that name"
                declared = name.removeprefix("$")
                raise SearchError(f"--vary {name}: {Path(scenario.path).name} {what} (// @param {declared} = VALUE "
                                  "in LOW..HIGH); give NAME=LOW..HIGH")
            r = Range(name, float(parameter.low), float(parameter.high), parameter.whole)
        elif not r.integer and name not in ("seed",):
            parameter = parameters.get(name.removeprefix("$"))
            if parameter is not None and parameter.whole:
                r = Range(name, r.low, r.high, True)
        filled[name] = r
    return filled


@dataclasses.dataclass(frozen=True)
class Objective:
    """What a trial is scored by: a measure of the run (`kind` "measure", `text` its name), minimised or maximised,
    or the robustness of an STL formula over timeseries.csv's columns (`kind` "spec", minimised)."""

    kind: Literal["measure", "spec"]
    text: str
    direction: Direction

    @property
    def label(self) -> str:
        return f"robustness of {self.text}" if self.kind == "spec" else self.text

    def __call__(self, result, row: dict) -> dict:
        """The trial's objective from its run (on the worker), as the run's results files give it, so that
        `sdl-fmu run worst.sdl` shows the same number: a measure rounded as summary.json writes it (6 decimals), a
        formula's robustness over the columns as timeseries.csv writes them. {"objective": value or None}."""
        if self.kind == "spec":
            return {"objective": robustness(self.text, as_written(result, spec_variables(self.text)))}
        value = measure_value(self.text, row, result.summary)
        return {"objective": None if value is None else round(value, SUMMARY_DECIMALS)}

    def better(self, a: float, b: float) -> bool:
        return a < b if self.direction == "minimize" else a > b


def objective_of(minimize: str | None, maximize: str | None, spec: str | None) -> Objective:
    given = [(kind, text) for kind, text in (("minimize", minimize), ("maximize", maximize), ("spec", spec))
             if text is not None]
    if len(given) != 1:
        raise SearchError("give one objective: --minimize MEASURE, --maximize MEASURE or --spec STL")
    kind, text = given[0]
    text = text.strip()
    if kind == "spec":
        _parsed(text, {name: None for name in spec_variables(text)})  # its grammar, before anything runs
        return Objective("spec", text, "minimize")
    check_measure(text, f"--{kind}")
    return Objective("measure", text, kind)


def check_measure(name: str, option: str) -> None:
    """A measure is a sweep-table column (`min_ttc_s`, `min_distance_ft`, `A1_min_ttc_s`, `impact_speed`: its unit
    may be left off) or a numeric key of summary.json (`collisions`, `final.speed`, `criticality.min_distance`)."""
    head = name.split(".", 1)[0]
    if "." in name and head in SUMMARY_KEYS:
        return
    base = re.sub(r"^(A\d+|brk\d+)_", "", name)
    for suffix in UNIT_SUFFIXES:
        if base.endswith(suffix) and base[:-len(suffix)] in MEASURES:
            return
    if base in MEASURES:
        return
    raise SearchError(f"{option} {name}: not a measure; give a column of the sweep table (min_ttc_s, min_distance, "
                      "impact_speed, collisions, A1_min_distance, ...: docs/search.md) or a summary.json key "
                      "(final.speed, criticality.max_drac, ...)")


def measure_value(name: str, row: dict, summary: dict) -> float | None:
    """The measure's value in a run: its table column (unit left off: the column of that name and a unit), else its
    summary.json key (a dotted path, or a key of `criticality`); None where it never applied."""
    value = row.get(name, _missing)
    if value is _missing:
        for suffix in UNIT_SUFFIXES:
            if name + suffix in row:
                value = row[name + suffix]
                break
    if value is _missing:
        value = summary
        for part in name.split("."):
            value = value.get(part, _missing) if isinstance(value, dict) else _missing
        if value is _missing and "." not in name:
            value = (summary.get("criticality") or {}).get(name, None)
    if value is _missing or value is None or isinstance(value, str):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


_missing = object()


SUMMARY_DECIMALS = 6  # summary.json's floats (results/files.py)


def as_written(result, names: list[str]) -> dict:
    """time_s and the timeseries.csv columns a formula reads (by identifier), each value as the file writes it (its
    printf format, read back; an empty cell: NaN)."""
    import numpy as np

    from .results import timeseries_table

    wanted = {"time_s", *names}
    arrays = {}
    for header, values, form in timeseries_table(result.raw):
        if identifier(header) in wanted:
            arrays[header] = np.array([float(form % v) if math.isfinite(v) else math.nan
                                       for v in np.asarray(values, dtype=float).tolist()])
    return arrays


def identifier(column: str) -> str:
    """A timeseries.csv column's name in an STL formula: every character but letters, digits and _ written _
    (`speed_m/s` -> `speed_m_s`)."""
    return re.sub(r"\W", "_", column, flags=re.ASCII)


def spec_variables(text: str) -> list[str]:
    """The names a formula reads (identifiers that are not rtamt's words)."""
    names = re.findall(r"(?<![\w.])[A-Za-z_]\w*", text, flags=re.ASCII)
    return sorted({name for name in names if name not in STL_WORDS})


def _parsed(text: str, variables: dict):
    import rtamt

    specification = rtamt.StlDenseTimeSpecification()
    for name in variables:
        specification.declare_var(name, "float")
    specification.spec = text
    try:
        with contextlib.redirect_stdout(sys.stderr):
            specification.parse()
    except Exception as error:  # noqa: BLE001 - rtamt's parse errors are of several kinds
        message = (str(error).strip() or type(error).__name__).splitlines()[0]
        raise SearchError(f"--spec {text!r}: {message}") from None
    return specification


def robustness(text: str, arrays: dict) -> float | None:
    """The formula's robustness at the run's start, dense time (the samples joined linearly), over the samples where
    every column it reads is a number (a vehicle's columns are empty while it is not on the road); None without
    any such sample."""
    import numpy as np

    columns = {identifier(column): column for column in arrays}
    names = spec_variables(text)
    missing = [name for name in names if name not in columns]
    if missing:
        raise ObjectiveError(f"--spec: timeseries.csv has no column {missing[0]} (a column's name with every "
                             "character but letters, digits and _ written _, e.g. speed_m_s)")
    time = np.asarray(arrays["time_s"], dtype=float)
    values = {name: np.asarray(arrays[columns[name]], dtype=float) for name in names}
    keep = np.isfinite(time)
    for series in values.values():
        keep &= np.isfinite(series)
    keep[:-1] &= np.diff(time) > 0  # one sample per instant: the last of equal times
    if not keep.any():
        return None
    specification = _parsed(text, values)
    times = time[keep].tolist()
    signals = [[name, [list(pair) for pair in zip(times, series[keep].tolist())]] for name, series in values.items()]
    with contextlib.redirect_stdout(sys.stderr):
        result = specification.evaluate(*signals) if signals else []
    if not result:
        return None
    value = float(result[0][1])
    return value if math.isfinite(value) else None


# ---- the optimisers ------------------------------------------------------------------------------------------


def _round_seed(seed: int, round_number: int) -> int:
    return (seed * 1_000_003 + round_number * 7_919 + 1) % 2**32


class _Optuna:
    """optuna's TPE (multivariate, constant liar) or random sampler over an in-memory study; a round's sampler is
    seeded from the search's seed and the round's number. Finished trials are told again on resume (add_trial)."""

    def __init__(self, method: Method, ranges: dict[str, Range], seed: int, direction: Direction):
        import optuna

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        self.optuna, self.method, self.seed = optuna, method, seed
        self.distributions = {
            name: optuna.distributions.IntDistribution(int(r.low), int(r.high)) if r.integer else
            optuna.distributions.FloatDistribution(r.low, r.high) for name, r in ranges.items()}
        self.study = optuna.create_study(direction=direction)
        self.asked: dict[int, object] = {}

    def ask(self, numbers: list[int], round_number: int) -> dict[int, dict]:
        import warnings

        seed = _round_seed(self.seed, round_number)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # multivariate and constant_liar are marked experimental
            self.study.sampler = (self.optuna.samplers.RandomSampler(seed=seed) if self.method == "random" else
                                  self.optuna.samplers.TPESampler(seed=seed, multivariate=True, constant_liar=True))
        proposed = {}
        for number in numbers:
            trial = self.study.ask(self.distributions)
            self.asked[number] = trial
            proposed[number] = dict(trial.params)
        return proposed

    def tell(self, number: int, params: dict, value: float | None) -> None:
        state = self.optuna.trial.TrialState
        trial = self.asked.pop(number, None)
        if trial is not None:
            if value is None:
                self.study.tell(trial, state=state.FAIL)
            else:
                self.study.tell(trial, value)
        elif value is not None:  # finished in an earlier process
            self.study.add_trial(self.optuna.trial.create_trial(params=params, distributions=self.distributions,
                                                                value=value))

    def replay(self, number: int, params: dict) -> None:
        """A trial proposed by an earlier process and not finished: it is run again with its values."""


class _CmaEs:
    """CMA-ES (the `cma` package) over the ranges scaled to 0..1, starting at their middles with step 0.3; a generation
    is told when all its trials are back (a failed run or a missing objective: the worst value of the search so far).
    Its random numbers come from its own generator seeded by the search's seed, so a resume replays it."""

    def __init__(self, ranges: dict[str, Range], seed: int, direction: Direction):
        import cma
        import numpy as np

        self.ranges, self.sign = list(ranges.values()), 1.0 if direction == "minimize" else -1.0
        generator = np.random.default_rng(seed)
        options = {"bounds": [0.0, 1.0], "seed": seed % (2**32 - 1) + 1, "verbose": -9, "verb_log": 0,
                   "verb_disp": 0, "randn": lambda *shape: generator.standard_normal(shape)}
        dimension = len(self.ranges)
        with contextlib.redirect_stdout(sys.stderr):
            if dimension == 1:  # cma runs in 2 dimensions at least: a second, ignored coordinate
                options["bounds"] = [[0.0, 0.0], [1.0, 1.0]]
            self.strategy = cma.CMAEvolutionStrategy([0.5] * max(dimension, 2), 0.3, options)
        self.population = self.strategy.popsize
        self.generation: list = []  # this generation's proposals (unit coordinates)
        self.first = 0  # the trial number of its first
        self.values: dict[int, float | None] = {}
        self.worst: float | None = None

    def _params(self, point) -> dict:
        return {r.name: r.value(float(x)) for r, x in zip(self.ranges, point)}

    def _next_generation(self, first: int) -> None:
        with contextlib.redirect_stdout(sys.stderr):
            self.generation = self.strategy.ask()
        self.first, self.values = first, {}

    def _point(self, number: int):
        if not self.generation or number >= self.first + len(self.generation):
            if self.generation and len(self.values) < len(self.generation):
                raise RuntimeError("CMA-ES: a generation was left before all its trials were told")
            if self.generation:
                self._tell_generation()
            self._next_generation(number)
        return self.generation[number - self.first]

    def ask(self, numbers: list[int], round_number: int) -> dict[int, dict]:
        return {number: self._params(self._point(number)) for number in numbers}

    def capacity(self, next_number: int) -> int:
        """How many trials can be proposed now: the rest of the generation, or a new one once this one is told."""
        if not self.generation or next_number >= self.first + len(self.generation):
            return self.population if not self.generation or len(self.values) == len(self.generation) else 0
        return self.first + len(self.generation) - next_number

    def replay(self, number: int, params: dict) -> None:
        """A trial proposed by an earlier process: the same proposal again (checked), to be run."""
        if self._params(self._point(number)) != params:
            raise SearchError("cannot resume: CMA-ES, replayed from its seed, proposes other values than those "
                              f"recorded for trial {number} (another version of cma?); choose a new --out")

    def tell(self, number: int, params: dict, value: float | None) -> None:
        self.replay(number, params)
        f = None if value is None else self.sign * value
        if f is not None:
            self.worst = f if self.worst is None else max(self.worst, f)
        self.values[number] = f
        if len(self.values) == len(self.generation):
            self._tell_generation()
            self.generation = []

    def _tell_generation(self) -> None:
        penalty = 0.0 if self.worst is None else self.worst
        values = [penalty if self.values.get(self.first + k) is None else self.values[self.first + k]
                  for k in range(len(self.generation))]
        with contextlib.redirect_stdout(sys.stderr):
            self.strategy.tell(self.generation, values)


def optimiser(method: Method, ranges: dict[str, Range], seed: int, direction: Direction):
    if method == "cmaes":
        return _CmaEs(ranges, seed, direction)
    return _Optuna(method, ranges, seed, direction)


# ---- the search ----------------------------------------------------------------------------------------------


@dataclasses.dataclass
class SearchResult:
    """What a search found: every trial (rows, in trial order), the worst one (None when no trial gave an
    objective), the folder, the command line that reproduces the worst case, and whether its run here gave the same
    objective."""

    rows: list[dict]
    worst: dict | None
    folder: Path
    objective: Objective
    command: list[str] | None = None
    reproduced: bool | None = None
    values: dict = dataclasses.field(default_factory=dict)  # the worst trial's varied values, by name


def search(scenario: str, ranges: dict[str, Range], out: str | os.PathLike, *, objective: Objective, budget: int,
           method: Method = "tpe", seed: int = 0, workers: int | None = None, scheduler: str | None = None,
           client=None, timeout: float = DEFAULT_TIMEOUT, progress: bool | None = None, batch: int | None = None,
           report: bool = True, **fixed) -> SearchResult:
    """Searches `ranges` for the trial with the worst `objective` in `budget` trials (module docstring).
    `client`: an existing distributed.Client (tests); else `scheduler` or a LocalCluster of `workers` processes.
    `batch`: trials per round (default: the cluster's worker threads). `report=False`: only the table and the
    journal (no worst.sdl, worst/, search.png, report.html: a benchmark's many searches). `fixed`: api.run's options
    for every run."""
    from . import ownership

    if method not in METHODS:
        raise SearchError(f"--method {method}: must be one of {', '.join(METHODS)}")
    if isinstance(budget, bool) or not isinstance(budget, int) or not 1 <= budget <= MAX_BUDGET:
        raise SearchError(f"--budget {budget}: must be a whole number from 1 to {MAX_BUDGET}")
    from .options import LIMITS

    if isinstance(seed, bool) or not isinstance(seed, int) or not LIMITS["seed"][0] <= seed <= LIMITS["seed"][1]:
        raise SearchError(f"--seed {seed}: must be a whole number from {LIMITS['seed'][0]} to {LIMITS['seed'][1]}")
    if batch is not None and (isinstance(batch, bool) or not isinstance(batch, int) or batch < 1):
        raise SearchError(f"batch {batch}: must be a whole number >= 1")
    if not timeout > 0:
        raise SearchError(f"--timeout {timeout}: must be > 0")
    sweeping.check_workers(workers if client is None and not scheduler else None)
    sweeping.check_scheduler(scheduler)
    given = _given(fixed)
    scenario_path, loaded, model, fixed, bundles = sweeping.prepare(scenario, fixed)
    ranges = declared(ranges, loaded)
    _check_names(ranges, loaded, model, fixed)
    columns = sweeping.column_names(list(ranges), loaded.units, model)
    out = Path(out).absolute()
    spec = {"scenario": scenario_path, "vary": {name: [r.low, r.high] for name, r in ranges.items()},
            "objective": dataclasses.asdict(objective), "method": method, "seed": seed,
            "fixed": json.loads(json.dumps(fixed, default=str)),
            "files": {option: bundle.digest for option, bundle in bundles.items()}}
    if out.exists() and not out.is_dir():
        raise SearchError(f"--out {out}: exists and is not a folder")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise SearchError(f"--out {out}: cannot be made: {error.strerror or error}") from None
    held = False
    try:
        with ownership.locked(out):
            held = True
            found, result = _search_into(out, spec, bundles, ranges, columns, objective, budget, method, seed, fixed,
                                         loaded, workers, scheduler, client, timeout, progress, batch, given,
                                         report)
        if result is not None:  # a results folder is put in place under its parent's lock: once the search's is let go
            drawn = out / WORST_PLOT  # the worst run's plot, drawn once for the report and worst/ alike
            try:
                result.write(out / WORST_FOLDER, plot=drawn if drawn.exists() else True)
            finally:
                drawn.unlink(missing_ok=True)
        return found
    except ownership.Locked:
        raise SearchError(f"--out {out}: another search is writing into it; wait until it ends, or choose another "
                          "folder") from None
    except OSError as error:
        done = (out / JOURNAL_NAME).exists()
        raise SearchError(f"--out {out}: cannot write: {error.strerror or error}; "
                          + ("the finished trials are kept: the same command resumes the search" if done else
                             "nothing was written")) from None
    finally:
        if created and held:
            with contextlib.suppress(OSError):
                out.rmdir()


def _given(fixed: dict) -> dict:
    """The options as the user gave them, files as absolute paths (the worst case's command line)."""
    from .names import EXAMPLE_CONTROLLER

    given = dict(fixed)
    for option in sweeping.SHIPPED:
        if given.get(option) is not None and not (option == "controller" and given[option] == EXAMPLE_CONTROLLER):
            given[option] = str(Path(given[option]).absolute())
    return given


def _check_names(ranges: dict[str, Range], loaded, model, fixed: dict) -> None:
    """Every varied name sets something (api.check_value_names: a run option, a scenario parameter or address, an FMU
    parameter) and both ends of its range are values it takes (an option's limits, the field's and the declared range,
    the FMU parameter's declared min/max): refused now, before any cluster starts."""
    from . import api

    try:
        api.check_value_names(loaded, list(ranges), model, option="vary")
    except api.InputError as error:
        raise SearchError(error.command_line()) from None
    for name, r in ranges.items():
        target = api.value_target(name, loaded)
        for value in (r.low, r.high):
            try:
                if target == "option" and name != "seed":
                    api.run_options(loaded, **{name: value})
                elif target == "scenario":
                    api.set_parameters(loaded, {name: value})
                elif target == "fmu":
                    model.with_parameters({**(fixed.get("params") or {}), name.removeprefix("param."): value})
            except (api.InputError, api.ScenarioError) as error:
                text = error.command_line() if isinstance(error, api.InputError) else str(error)
                raise SearchError(f"--vary {name}={r.low:g}..{r.high:g}: {text.strip().splitlines()[0]}") from None


def _batch_size(client, batch: int | None) -> int:
    """The trials kept running at once: `batch`, else two per worker thread of the cluster (one running, one queued
    behind it, so that no worker waits for the optimiser)."""
    if batch is not None:
        return batch
    client.wait_for_workers(1)
    threads = sum(client.nthreads().values())  # asked of the scheduler (the client's scheduler_info may lag)
    return max(1, 2 * threads)


def _search_into(out, spec, bundles, ranges, columns, objective, budget, method, seed, fixed, loaded, workers,
                 scheduler, client, timeout, progress, batch, given, report=True):
    """The search proper, with `out`'s lock held: (SearchResult, the worst case's api.Result or None)."""
    from tqdm import tqdm

    from . import ownership
    from .text import unescaped

    finished, proposed = _check_folder(out, spec)
    chooser = optimiser(method, ranges, seed, objective.direction)
    # the earlier trials told again, in the order they were proposed; CMA-ES checks each proposal as it replays
    for number in sorted(proposed):
        if number in finished:
            chooser.tell(number, finished[number]["params"], _told(finished[number]))
        elif isinstance(chooser, _CmaEs):
            chooser.replay(number, proposed[number]["params"])
    todo = [number for number in sorted(proposed) if number not in finished and number < budget]
    next_number = max(proposed, default=-1) + 1
    round_number = max((p["round"] for p in proposed.values()), default=-1) + 1
    owned = []
    bar = tqdm(total=budget, initial=min(len(finished), budget), unit="trial", file=unescaped(sys.stderr),
               disable=progress is False or (progress is None and not sys.stderr.isatty()))
    try:
        if len(finished) < budget and client is None:
            client, owned = sweeping._client(workers, scheduler, budget - len(finished))
        if not (out / SPEC_NAME).exists():
            ownership.write_json(out / SPEC_NAME, spec)
        _keep_only(out / JOURNAL_NAME, finished, proposed)
        if len(finished) < budget:
            in_flight = _batch_size(client, batch)
            shipped = sweeping.ship(client, bundles)
            try:
                with open(out / JOURNAL_NAME, "a", encoding="utf-8") as journal:
                    outstanding = set(todo)
                    failure: list[str] = []
                    state = {"next": next_number, "round": round_number}

                    def more():
                        """The next trials, to keep `in_flight` running: proposed, journaled, then run."""
                        count = min(in_flight - len(outstanding), budget - state["next"])
                        if isinstance(chooser, _CmaEs):
                            count = min(count, chooser.capacity(state["next"]))
                        if count <= 0 or failure:
                            return []
                        numbers = list(range(state["next"], state["next"] + count))
                        asked = chooser.ask(numbers, state["round"])
                        for number in numbers:
                            proposed[number] = {"kind": "proposed", "trial": number, "round": state["round"],
                                                "params": asked[number]}
                            _append(journal, proposed[number])
                        state["next"] += count
                        state["round"] += 1
                        outstanding.update(numbers)
                        return [(number, _values(proposed[number]["params"])) for number in numbers]

                    def arrived(row, number, values):
                        outstanding.discard(number)
                        if str(row.get("error") or "").startswith("ObjectiveError: "):
                            failure.append(row["error"].removeprefix("ObjectiveError: "))
                            return
                        record = {"kind": "trial", "trial": number, "round": proposed[number]["round"],
                                  "params": proposed[number]["params"], "row": row}
                        _append(journal, record)
                        finished[number] = record
                        chooser.tell(number, record["params"], _told(record))
                        bar.update()

                    runs = [(number, _values(proposed[number]["params"])) for number in todo]
                    sweeping.run_rows(client, shipped, runs, fixed, timeout, arrived, objective, more)
                    if failure:
                        if not finished:  # a mistake in the objective: nothing is left of this search
                            journal.close()
                            for name in (JOURNAL_NAME, SPEC_NAME, MANIFEST_NAME):
                                (out / name).unlink(missing_ok=True)
                        raise SearchError(failure[0])
            finally:
                sweeping.release(shipped)
    finally:
        bar.close()
        for thing in owned:
            thing.close()
    return _write_outputs(out, spec, finished, ranges, columns, objective, fixed, given, loaded, report)


def _values(params: dict) -> dict:
    return dict(params)


def _told(record: dict) -> float | None:
    row = record["row"]
    return row.get("objective") if row.get("status") == "ok" else None


def _append(journal, record: dict) -> None:
    from . import ownership

    append_row(journal, ownership.signed(record))


# ---- the folder ----------------------------------------------------------------------------------------------


def _proved(out: Path) -> set[str] | None:
    from . import ownership

    data = _manifest(out)
    if data is None:
        return None
    files = data.get("files")
    if not isinstance(files, dict):
        return None
    return {name for name, entry in files.items() if name in OWN_FILES and ownership.unchanged(out / name, entry)}


def _manifest(out: Path) -> dict | None:
    from . import ownership

    try:
        data = json.loads((out / MANIFEST_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT or not ownership.authentic(data):
        return None
    return data


def _write_manifest(out: Path, coming: dict[str, Path] | None = None) -> None:
    """The manifest of the search's files as they are now; `coming`: files about to replace some of them, listed in
    both forms meanwhile (as the sweep's)."""
    from . import ownership

    coming = coming or {}
    earlier = (_manifest(out) or {}).get("files") or {}
    files = {}
    for name in sorted(OWN_FILES):
        journal = name == JOURNAL_NAME
        now = ownership.record(out / name, prefix=journal) if (out / name).is_file() else None
        kept = earlier.get(name)
        if journal and name not in coming and kept is not None and ownership.unchanged(out / name, kept):
            files[name] = kept
        elif name in coming:
            files[name] = [now, ownership.record(coming[name], prefix=journal)]
        elif now is not None:
            files[name] = now
    ownership.write_json(out / MANIFEST_NAME, ownership.signed({"format": MANIFEST_FORMAT, "files": files}))


def _check_folder(out: Path, spec: dict) -> tuple[dict[int, dict], dict[int, dict]]:
    """The finished trials and the proposals of an earlier search of the same description in `out` (resume), or
    nothing for a new folder. A folder holding what the search did not write, or another search, is refused."""
    from . import ownership
    from .results.folder import folder_kind, other_kind_text

    kind = folder_kind(out)
    if kind not in (None, "search"):
        raise SearchError(f"--out {other_kind_text(str(out), kind, 'search')}")
    names = sorted(entry.name for entry in out.iterdir())
    proved = _proved(out)
    leftovers = [name for name in names if name.endswith(PARTIAL) and name[:-len(PARTIAL)] in
                 {*OWN_FILES, MANIFEST_NAME, WORST_PLOT}]
    own = {*OWN_FILES, MANIFEST_NAME} | ({WORST_FOLDER} if proved is not None else set())
    foreign = [name for name in names if name not in own and not (proved is not None and name in leftovers)]
    if foreign:
        raise SearchError(f"--out {out}: holds files a search did not write ({', '.join(foreign[:3])}); choose a new "
                          "or empty folder")
    unproved = [name for name in names if name in OWN_FILES and name not in (proved or set())]
    if unproved:
        raise SearchError(f"--out {out}: its {unproved[0]} was not written by sdl-fmu's search, or was changed since; "
                          "move it away, or choose another folder")
    for name in leftovers:
        (out / name).unlink(missing_ok=True)
    if not (out / SPEC_NAME).exists():
        return {}, {}
    try:
        earlier = json.loads((out / SPEC_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise SearchError(f"--out {out}: its {SPEC_NAME} cannot be read ({error}); choose another folder") from None
    earlier = {key: earlier.get(key) for key in spec} if isinstance(earlier, dict) else None
    if earlier != spec:
        differ = [part for part in spec if (earlier or {}).get(part) != spec[part]]
        raise SearchError(f"--out {out}: holds a different search (its {' and '.join(differ)} differ); choose another "
                          "folder")
    finished, proposed = {}, {}
    if (out / JOURNAL_NAME).exists():
        for line in (out / JOURNAL_NAME).read_text(encoding="utf-8").splitlines():
            try:
                record = json.loads(line)
            except ValueError:
                continue  # cut short by the interruption: that trial is run again
            if not (isinstance(record, dict) and ownership.authentic(record) and type(record.get("trial")) is int
                    and isinstance(record.get("params"), dict) and type(record.get("round")) is int):
                continue
            record.pop("signature", None)
            if record.get("kind") == "proposed":
                proposed[record["trial"]] = record
            elif record.get("kind") == "trial" and isinstance(record.get("row"), dict):
                finished[record["trial"]] = record
    finished = {number: record for number, record in finished.items() if number in proposed}
    return finished, proposed


def _keep_only(journal: Path, finished: dict, proposed: dict) -> None:
    """The journal compacted: the proposals, then the finished trials."""
    partial = journal.with_name(journal.name + PARTIAL)
    try:
        from . import ownership

        records = [*(proposed[n] for n in sorted(proposed)), *(finished[n] for n in sorted(finished))]
        lines = [row_line(ownership.signed(record)) for record in records]
        partial.write_text("".join(lines), encoding="utf-8")
        _write_manifest(journal.parent, {journal.name: partial})
        os.replace(partial, journal)
        _write_manifest(journal.parent)
    finally:
        partial.unlink(missing_ok=True)


# ---- the outputs ---------------------------------------------------------------------------------------------


def table_rows(finished: dict[int, dict], columns: dict[str, str], objective: Objective) -> list[dict]:
    """One row per finished trial, in trial order: trial, round, the varied values (their table columns), status,
    error, objective, best_so_far, then the run's table row."""
    rows, best = [], None
    for number in sorted(finished):
        record = finished[number]
        row = dict(record["row"])
        value = row.pop("objective", None)
        if row.get("status") != "ok":
            value = None
        if value is not None and (best is None or objective.better(value, best)):
            best = value
        rows.append({"trial": number, "round": record["round"],
                     **{columns[name]: v for name, v in record["params"].items()},
                     "status": row.pop("status"), "error": row.pop("error", None), "objective": value,
                     "best_so_far": best, **{k: v for k, v in row.items() if k != "traceback"}})
    return rows


def worst_row(rows: list[dict], objective: Objective) -> dict | None:
    """The trial with the worst (best for the search) objective; the first of equals."""
    best = None
    for row in rows:
        if row["status"] == "ok" and row["objective"] is not None and (
                best is None or objective.better(row["objective"], best["objective"])):
            best = row
    return best


def split_values(values: dict, scenario) -> tuple[dict, dict]:
    """A trial's values: (those the scenario takes, written into worst.sdl; the run's options and FMU parameters)."""
    from . import api

    inside = {name: value for name, value in values.items() if api.value_target(name, scenario) == "scenario"}
    return inside, {name: value for name, value in values.items() if name not in inside}


def command_line(worst_sdl: Path, values: dict, fixed: dict, out: Path) -> list[str]:
    """`sdl-fmu run worst.sdl ...`: the worst trial's run from the command line (values written exactly); `values`:
    the trial's options and FMU parameters (its scenario values are in worst.sdl)."""
    command = ["sdl-fmu", "run", str(worst_sdl)]
    options, params = _run_arguments(values, fixed)
    options.pop("skip_unsupported", None)
    params = options.pop("params", {})
    for key, value in options.items():
        if value is not None:
            command += [f"--{key.replace('_', '-')}", repr(value) if isinstance(value, float) else str(value)]
    for name, value in params.items():
        command += ["--param", f"{name}={value!r}"]
    if fixed.get("skip_unsupported"):
        command.append("--skip-unsupported")
    return command + ["--out", str(out)]


def _write_outputs(out, spec, finished, ranges, columns, objective, fixed, given, loaded, report=True):
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    import pyarrow.parquet as pq

    from . import api, ownership

    rows = table_rows(finished, columns, objective)
    worst = worst_row(rows, objective)
    command = reproduced = None
    partials = {name: out / (name + PARTIAL) for name in (TABLE_NAME, CSV_NAME, PLOT_NAME, REPORT_NAME, WORST_SDL,
                                                           SPEC_NAME, WORST_PLOT)}
    result = None
    try:
        first = ["trial", "round", *columns.values(), "status", "error", "objective", "best_so_far"]
        rest = sorted({key for row in rows for key in row} - set(first), key=sweeping._column_order)
        table = pa.table({name: pa.array([row.get(name) for row in rows], from_pandas=True)
                          for name in [*first, *rest]})
        pq.write_table(table, partials[TABLE_NAME])
        pa_csv.write_csv(table, partials[CSV_NAME])
        worst_summary = None
        description = dict(spec)
        if worst is not None and report:
            values = finished[worst["trial"]]["params"]
            inside, outside = split_values(values, loaded)
            text = api.resolve(loaded, inside)
            partials[WORST_SDL].write_text(text, encoding="utf-8", newline="\n")
            # the worst case run again here from worst.sdl, as the command line below runs it
            worst_sdl = out / WORST_SDL
            os.replace(partials[WORST_SDL], worst_sdl)
            _write_manifest(out)
            command = command_line(worst_sdl, outside, given, out / WORST_FOLDER)
            run_options, _ = _run_arguments(outside, fixed)
            from .results.folder import check_results_folder

            check_results_folder(out / WORST_FOLDER, "run")
            result = api.run(str(worst_sdl), **run_options)
            result.plot(partials[WORST_PLOT])
            again = objective(result, sweeping._summarise(result))["objective"]
            reproduced = again == worst["objective"]
            worst_summary = result.summary
            description["worst"] = {"trial": worst["trial"], "values": values, "objective": worst["objective"],
                                    "objective_again": again, "reproduced": reproduced, "command": command}
        description["trials"] = len(rows)
        if report:
            plot_search(rows, ranges, columns, objective, worst, partials[PLOT_NAME])
            partials[REPORT_NAME].write_text(report_html(description, rows, ranges, columns, objective, worst,
                                                         worst_summary, partials[PLOT_NAME], partials[WORST_PLOT]),
                                             encoding="utf-8")
        ownership.write_json(partials[SPEC_NAME], description)
        coming = {name: path for name, path in partials.items()
                  if name not in (WORST_SDL, WORST_PLOT) and path.exists()}
        _write_manifest(out, coming)
        for name, path in coming.items():
            os.replace(path, out / name)
        _write_manifest(out)
        if result is not None and partials[WORST_PLOT].exists():
            os.replace(partials[WORST_PLOT], out / WORST_PLOT)  # for worst/ (search() writes it and removes this)
    finally:
        for path in partials.values():
            path.unlink(missing_ok=True)
    values = {} if worst is None else dict(finished[worst["trial"]]["params"])
    return SearchResult(rows, worst, out, objective, command, reproduced, values), result


def _run_arguments(values: dict, fixed: dict) -> tuple[dict, dict]:
    """api.run's keyword options of a trial's options and FMU parameters (`values`) over the fixed ones."""
    from . import api

    options = {key: value for key, value in fixed.items() if key != "params"}
    params = dict(fixed.get("params") or {})
    for name, value in values.items():
        if name in api.VALUE_OPTIONS:
            options[name] = value
        else:
            params[name.removeprefix("param.")] = value
    if params:
        options["params"] = params
    return options, params


def influence(rows: list[dict], column: str) -> float:
    """|Spearman's rank correlation| between a varied column and the objective over the trials with one (0 when
    either is constant)."""
    import numpy as np

    pairs = [(row[column], row["objective"]) for row in rows if row["status"] == "ok" and row["objective"] is not None]
    if len(pairs) < 3:
        return 0.0
    ranks = [np.argsort(np.argsort(np.asarray(series, dtype=float), kind="stable")) for series in zip(*pairs)]
    x, y = (r - r.mean() for r in ranks)
    scale = math.sqrt(float((x * x).sum() * (y * y).sum()))
    return abs(float((x * y).sum()) / scale) if scale > 0 else 0.0


def influential(rows: list[dict], ranges: dict[str, Range], columns: dict[str, str]) -> list[str]:
    """The varied columns by influence on the objective, most first (ties: as given)."""
    names = [columns[name] for name in ranges]
    return sorted(names, key=lambda column: -influence(rows, column))


def plot_search(rows, ranges, columns, objective, worst, path: Path) -> None:
    from .text import plain_text

    with plain_text():
        _plot_search(rows, ranges, columns, objective, worst, path)


def _plot_search(rows, ranges, columns, objective, worst, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    shown = influential(rows, ranges, columns)[:2]
    figure = Figure(figsize=(5.0 * (1 + len(shown)), 4.2), dpi=100, layout="constrained")
    FigureCanvasAgg(figure)
    ok = [row for row in rows if row["status"] == "ok" and row["objective"] is not None]
    bad = [row for row in rows if row not in ok]
    ax = figure.add_subplot(1, 1 + len(shown), 1)
    ax.scatter([row["trial"] for row in ok], [row["objective"] for row in ok], s=14, color="C0", label="trial")
    best = [(row["trial"], row["best_so_far"]) for row in rows if row["best_so_far"] is not None]
    if best:
        ax.step(*zip(*best), where="post", color="C3", lw=1.5, label="best so far")
    if bad:
        low = min((row["objective"] for row in ok), default=0.0)
        ax.scatter([row["trial"] for row in bad], [low] * len(bad), marker="x", color="tab:orange", s=18,
                   label="failed or no value")
    ax.set(xlabel="trial", ylabel=objective.label, title=f"{objective.direction} {objective.label}"[:80])
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    for k, column in enumerate(shown):
        ax = figure.add_subplot(1, 1 + len(shown), k + 2)
        points = [(row[column], row["objective"]) for row in ok]
        if points:
            ax.scatter(*zip(*points), s=14, c=[row["trial"] for row in ok], cmap="viridis")
        if worst is not None:
            ax.scatter([worst[column]], [worst["objective"]], s=90, facecolors="none", edgecolors="C3", lw=1.5,
                       label=f"worst (trial {worst['trial']})")
            ax.legend(fontsize=8)
        ax.set(xlabel=sweeping._axis_label(column), ylabel=objective.label,
               title=f"influence {influence(rows, column):.2f} (|Spearman|)")
        ax.grid(True, alpha=0.3)
    figure.suptitle(f"search: {len(rows)} trials, {len(ok)} with an objective", fontsize=11)
    figure.savefig(path, format="png")


def _image(path: Path) -> str:
    return f'<img alt="{html.escape(path.name)}" src="data:image/png;base64,' \
           f'{base64.b64encode(path.read_bytes()).decode()}">' if path.is_file() else ""


def _number(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return html.escape("" if value is None else str(value))


def report_html(description, rows, ranges, columns, objective, worst, summary, plot: Path, worst_plot: Path) -> str:
    """The search's report, one self-contained file (the PNGs embedded): the worst case's plot, values, criticality
    and reproduction, then the search's plot and history."""
    e = html.escape
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>sdl-fmu search</title><style>"
             "body{font-family:sans-serif;margin:2em;max-width:80em}table{border-collapse:collapse;margin:.5em 0}"
             "td,th{border:1px solid #bbb;padding:.2em .5em;text-align:right}th{background:#eee}"
             "img{max-width:100%}code{background:#f4f4f4;padding:.1em .3em}</style></head><body>",
             f"<h1>Worst-case search: {e(Path(description['scenario']).name)}</h1>",
             f"<p>{e(objective.direction)} <b>{e(objective.label)}</b> with {e(description['method'])} "
             f"(seed {description['seed']}) over {len(rows)} trials; varied: "
             + ", ".join(f"<code>{e(name)}</code> in {r.low:g}..{r.high:g}" for name, r in ranges.items())
             + ".</p>"]
    if worst is None:
        parts.append("<p>No trial gave an objective.</p>")
    else:
        w = description["worst"]
        parts += [f"<h2>The worst case: trial {worst['trial']}, objective {_number(worst['objective'])}</h2>",
                  "<table><tr><th>parameter</th><th>value</th></tr>"
                  + "".join(f"<tr><td>{e(columns[name])}</td><td>{value!r}</td></tr>"
                            for name, value in w["values"].items()) + "</table>",
                  f"<p>Reproduce: <code>{e(shlex.join(w['command']))}</code> "
                  f"(run again here: objective {_number(w['objective_again'])}, "
                  f"{'the same' if w['reproduced'] else 'NOT the same'}).</p>"]
        criticality = (summary or {}).get("criticality") or {}
        keys = [k for k in criticality if k != "vehicles"]
        if keys:
            vehicles = criticality.get("vehicles") or []
            parts.append("<h3>Criticality</h3><table><tr><th>measure</th><th>run</th>"
                         + "".join(f"<th>A{v['vehicle']}</th>" for v in vehicles) + "</tr>"
                         + "".join(f"<tr><td>{e(k)}</td><td>{_number(criticality.get(k))}</td>"
                                   + "".join(f"<td>{_number(v.get(k))}</td>" for v in vehicles) + "</tr>"
                                   for k in keys) + "</table>")
        parts += [f"<p>collisions {_number((summary or {}).get('collisions'))}; "
                  + ", ".join(f"{k} {_number(worst.get(k))}" for k in worst if "impact_speed" in k) + "</p>",
                  "<h3>Its run</h3>", _image(worst_plot)]
    parts += ["<h2>The search</h2>", _image(plot), "<h3>History</h3>",
              "<table><tr><th>trial</th><th>round</th>" + "".join(f"<th>{e(columns[n])}</th>" for n in ranges)
              + "<th>status</th><th>objective</th><th>best so far</th></tr>"]
    for row in rows:
        parts.append("<tr" + (" style='background:#fde'" if worst is not None and row is worst else "") + ">"
                     + f"<td>{row['trial']}</td><td>{row['round']}</td>"
                     + "".join(f"<td>{_number(row[columns[n]])}</td>" for n in ranges)
                     + f"<td>{e(row['status'])}</td><td>{_number(row['objective'])}</td>"
                     f"<td>{_number(row['best_so_far'])}</td></tr>")
    parts.append("</table></body></html>\n")
    return "".join(parts)
