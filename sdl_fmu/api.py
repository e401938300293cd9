"""sdl-fmu from Python: the one public API that the command line, the sweep and the tests call.

    from sdl_fmu import api

    result = api.run("demo", until_time=20.0, params={"mass": 1800.0})   # a shipped example or a path
    result.arrays["speed_ft/s"]       # the time series as NumPy arrays, columns as in timeseries.csv
    result.events, result.warnings    # summary.json's events (scenario units) and every warning
    result.write("runs/demo")         # timeseries.csv, summary.json, plot.png (a results folder)

Every user mistake raises an `InputError` (a bad option, FMU, tire file or results folder; the message
names the option or file) or a `ScenarioError` (the scenario file; one line per problem, each naming
file, line and field). Anything else is a bug.
"""

from __future__ import annotations

import functools
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from .paths import SCENARIO_DIRECTORY
from .results import summary, timeseries_table, write_results
from .run_result import RunResult
from .sdl import Scenario, ScenarioError, SdlError, SurfaceAttribute, check_models, load_scenario, load_vehicle_table
from .units import Units
from .vehicle.vehicle_map import Dynamics

__all__ = ["InputError", "RunTimeout", "ScenarioError", "Result", "load", "run", "shipped_scenarios",
           "resolve_scenario", "ego_fmu", "ego_model", "controller_model", "tire_slot_starts", "LIMITS", "DRIVERS",
           "ON_COLLISION"]

# Option ranges (SI). A run never goes beyond MAX_TIME (cosim.master), and a distance the fastest ego
# cannot reach within it could never end a run.
MAX_SPEED = 150.0  # m/s (335 mph)
MAX_TIME = 3600.0  # s
LIMITS = {
    "speed": (0.0, MAX_SPEED),  # scenario units on input, checked in m/s
    "step": (1e-5, 10.0),  # s
    "driver_period": (1e-3, 1.0),  # s
    "until_time": (0.0, MAX_TIME),  # s, > 0
    "until_distance": (0.0, MAX_SPEED * MAX_TIME),  # m, > 0
    "seed": (0, 2**63 - 1),
}


def _shipped_variables() -> tuple[str, ...]:
    """The FMU variables both shipped vehicle maps name (their common interface: docs/fmu-runtime.md, Variables)."""
    from .vehicle import SHIPPED, load_vehicle_map, shipped_map_path

    named = []
    for name in SHIPPED:
        vehicle_map = load_vehicle_map(shipped_map_path(name))
        channels = [*vehicle_map.inputs.values(), *vehicle_map.outputs.values(), *vehicle_map.start.values()]
        named.append([c.variable for c in channels]
                     + [v for v in vehicle_map.vehicle.values() if isinstance(v, str)])
    return tuple(v for v in named[0] if all(v in other for other in named[1:]))


EGO_VARIABLES = _shipped_variables()
DRIVERS = ("lane", "follow")  # the built-in drivers (docs/controllers.md); lane is the default
ON_COLLISION = ("continue", "stop")  # what the first contact does; continue is the default
MAX_INPUT_FILE = 10 * 2**20  # bytes: tire and attribute files are small texts


class InputError(ValueError):
    """A user mistake outside the scenario file: a bad option, FMU, tire file or results folder.

    `option` is the keyword (e.g. "until_time", "params", "fmu"). The message names it as the API spells it
    (`until_time nan: must be a finite number`); `command_line()` gives the same line with the command
    line's flag (`--until-time nan: ...`)."""

    def __init__(self, option: str | None, message: str, subject: str | None = None):
        self.option = option
        self.subject = subject  # the value and reason ("nan: must be ..."), when the message is keyword + subject
        super().__init__(message if subject is None else f"{option} {subject}")

    def command_line(self) -> str:
        """The message as the command line words it: the keyword replaced by its flag."""
        if self.subject is None:
            return str(self)
        return f"--{COMMAND_LINE_FLAGS.get(self.option, self.option.replace('_', '-'))} {self.subject}"


# keywords whose command-line flag is not the keyword with - for _
COMMAND_LINE_FLAGS = {"params": "param"}


class RunTimeout(RuntimeError):
    """A run stopped because it exceeded its wall-clock `timeout` (run(..., timeout=...))."""


def _option_error(option: str, value, reason: str) -> InputError:
    return InputError(option, "", subject=f"{value}: {reason}")


# --- scenarios ----------------------------------------------------------------------------------


def shipped_scenarios() -> dict[str, Path]:
    """The example scenarios shipped in the package, by short name (file name without .sdl)."""
    return {path.stem: path for path in sorted(SCENARIO_DIRECTORY.glob("*.sdl"))}


def resolve_scenario(name: str | os.PathLike) -> Path:
    """A scenario path: `name` itself if a file of that name exists, or if it has a folder part; else the shipped
    example of that short name (with or without .sdl). A short name that is also a folder here, or whose other
    spelling (with or without .sdl) is a file here, is ambiguous: a ScenarioError of one line."""
    path, raw = Path(name), os.fspath(name)
    if any(separator in raw for separator in {"/", os.sep}) or os.path.isfile(path):  # ./demo is a path
        return path
    short = path.name.removesuffix(".sdl")
    shipped = shipped_scenarios().get(short)
    if shipped is None:
        return path
    here = [spelling for spelling in (path.name, short, f"{short}.sdl") if os.path.lexists(spelling)]
    if here:
        what = "a folder" if os.path.isdir(here[0]) else "a file"
        raise ScenarioError([SdlError(os.fspath(name), 0, "file",
                                      f"ambiguous: '{here[0]}' is {what} in the working folder and '{short}' is also "
                                      f"a shipped example ({shipped}); give a path such as ./{here[0]}, or the "
                                      "example's path")])
    return shipped


@functools.lru_cache(maxsize=None)
def _vehicle_table():
    from .sdl import default_vehicle_table_path

    return load_vehicle_table(default_vehicle_table_path())


def load(scenario: str | os.PathLike, *, skip_unsupported: bool = False, dynamics: Dynamics | None = None) -> Scenario:
    """Reads and checks a scenario file (or a shipped example by name); raises ScenarioError listing every
    problem. skip_unsupported: lines sdl-fmu does not simulate become warnings (one per code). dynamics:
    also apply that model's rules (advanced: RSA values are whole attribute numbers), as `run` does."""
    path = resolve_scenario(scenario)
    if not os.path.lexists(path) and isinstance(scenario, str):
        names = ", ".join(shipped_scenarios())
        raise ScenarioError([SdlError(os.fspath(scenario), 0, "file",
                                      f"no such file (shipped examples by name: {names})")])
    loaded = load_scenario(path, skip_unsupported=skip_unsupported)
    problems = check_models(loaded, _vehicle_table())
    if problems:
        raise ScenarioError(problems)
    if dynamics is not None:
        from .vehicle import load_vehicle_map

        friction = load_vehicle_map(_shipped_map(dynamics)).friction
        if friction is not None and friction.meaning == "attribute":
            _whole_attributes(loaded)
    return loaded


# --- options -----------------------------------------------------------------------------------


def _checked_option(option: str, value, units: Units | None = None, low_open: bool = False):
    """A numeric option's value checked: a finite number within LIMITS[option] (given in scenario units when
    `units`); returns SI."""
    from .units import from_si, length_label, speed_label, to_si

    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise _option_error(option, value, "must be a number")
    value = float(value)
    if not math.isfinite(value):
        raise _option_error(option, f"{value:g}", "must be a finite number")
    si = to_si(value, units) if units else value
    low, high = LIMITS[option]
    if si < low or (low_open and si == low) or si > high:
        if units:
            label = speed_label(units) if option == "speed" else length_label(units)
            low, high = from_si(low, units), from_si(high, units)
        else:
            label = "s"
        relation = ">" if low_open else ">="
        raise _option_error(option, f"{value:g}", f"must be {relation} {low:g} and <= {high:.6g} {label}")
    return si


def _seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise _option_error("seed", seed, "must be a whole number")
    low, high = LIMITS["seed"]
    if not low <= seed <= high:
        raise _option_error("seed", seed, f"must be from {low} to {high}")
    return int(seed)


def _regular_file(option: str, path: str | os.PathLike) -> Path:
    """An input file that exists, is a regular file and is not absurdly large."""
    path = Path(path)
    if not path.exists():
        raise _option_error(option, path, "no such file")
    if path.is_dir():
        raise _option_error(option, path, "is a folder, not a file")
    if not path.is_file():
        raise _option_error(option, path, "is not a regular file")
    return path


def _first_line(error: BaseException) -> str:
    text = str(error).strip() or type(error).__name__
    return text.splitlines()[0]


def _shipped_map(dynamics: Dynamics) -> Path:
    """The shipped vehicle map of `dynamics`; InputError naming `dynamics` for a name that is not shipped."""
    from .vehicle import SHIPPED, shipped_map_path

    if dynamics not in SHIPPED:
        raise _option_error("dynamics", dynamics, f"must be one of {', '.join(SHIPPED)}")
    return shipped_map_path(dynamics)


def ego_model(dynamics: Dynamics | None = None, fmu: str | os.PathLike | None = None,
              vehicle: str | os.PathLike | None = None):
    """The run's EgoModel: `fmu` (or the map's own `fmu`) driven through the vehicle map `vehicle`; without a map,
    the shipped map of `dynamics` (default simple) with `fmu` or the cached build (built on first use).
    Raises InputError naming the map file and key, or the FMU."""
    from .vehicle import EgoModel, VehicleMapError

    if vehicle is not None and dynamics is not None:
        raise _option_error("dynamics", dynamics, "give either a shipped model (dynamics) or a vehicle map "
                            "(vehicle), not both")
    dynamics = "simple" if dynamics is None else dynamics
    shipped_map = _shipped_map(dynamics)
    try:
        if vehicle is not None:
            return EgoModel.open(fmu, _regular_file("vehicle", vehicle))
        if fmu is not None:
            return EgoModel.open(_regular_file("fmu", fmu), shipped_map)
    except VehicleMapError as error:
        text = str(error)
        if vehicle is None and not text.startswith("--fmu"):  # the FMU does not fit the shipped map
            text = f"--fmu {fmu}: does not fit the shipped {dynamics} map: {text}"
        option = "fmu" if vehicle is None or text.startswith("--fmu") else "vehicle"
        if text.startswith(f"--{option} "):  # the keyword form for the API, the flag form for the command line
            raise InputError(option, "", subject=text[len(option) + 3:]) from None
        raise InputError(option, text) from None
    from .fmu.cache import cached_fmu

    path = cached_fmu(dynamics, announce=lambda path: print(f"building {path.name} into the cache "
                                                            f"{path.parent.parent} (first use)", file=sys.stderr))
    return EgoModel.open(path, shipped_map)


def controller_model(controller: str | os.PathLike | None = None, controller_map: str | os.PathLike | None = None):
    """The run's ControllerModel (docs/controllers.md): `controller` (or the map's own `fmu`) driven through the
    controller map `controller_map`; None when neither is given. Raises InputError naming the map file and key, or
    the FMU."""
    from .vehicle.controller import ControllerMapError, ControllerModel

    if controller is None and controller_map is None:
        return None
    if controller_map is None:
        raise _option_error("controller", controller, "needs a controller map (controller_map, a TOML file: "
                                                      "docs/controllers.md)")
    try:
        return ControllerModel.open(None if controller is None else _regular_file("controller", controller),
                                    _regular_file("controller_map", controller_map))
    except ControllerMapError as error:
        text = str(error)
        for option in ("controller_map", "controller"):  # the keyword form for the API, the flag form for the CLI
            flag = f"--{option.replace('_', '-')} "
            if text.startswith(flag):
                raise InputError(option, "", subject=text[len(flag):]) from None
        raise InputError("controller_map", text) from None


def _choice(option: str, value, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise _option_error(option, value, f"must be one of {', '.join(choices)}")
    return value


def _parameters(params: dict | None, model) -> dict[str, float]:
    """params checked against the FMU: an existing Real parameter, finite, within its min/max."""
    from .vehicle.model import REAL_TYPES

    description, fmu = model.description, model.fmu_path
    checked = {}
    variables = {v.name: v for v in description.modelVariables}
    for name, value in (params or {}).items():
        shown = f"{name}={value}"
        variable = variables.get(name)
        if variable is None or variable.causality != "parameter":
            known = ", ".join(v.name for v in description.modelVariables
                              if v.causality == "parameter" and not v.name.startswith("tire"))
            raise _option_error("params", shown, f"{fmu.name} has no parameter {name!r} (parameters: {known}, "
                                "tire<slot>_<KEY>)")
        if variable.type not in REAL_TYPES:
            raise _option_error("params", shown, f"{name} is {variable.type}; only Real parameters can be set")
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise _option_error("params", shown, "the value must be a number (SI units)")
        value = float(value)
        if not math.isfinite(value):
            raise _option_error("params", shown, "the value must be a finite number")
        unit = f" {variable.unit}" if variable.unit and variable.unit != "1" else ""
        low = None if variable.min is None else float(variable.min)
        high = None if variable.max is None else float(variable.max)
        if low is not None and value < low:
            raise _option_error("params", shown, f"below the declared minimum {low:g}{unit} of {name}")
        if high is not None and value > high:
            raise _option_error("params", shown, f"above the declared maximum {high:g}{unit} of {name}")
        checked[name] = value
    if checked:  # the vehicle's properties that follow from the parameters, each within its range
        from .vehicle import VehicleMapError

        try:
            model.with_parameters(checked)
        except VehicleMapError as error:
            name = next((n for n in checked if f"parameter {n!r}" in str(error)), next(iter(checked)))
            raise _option_error("params", f"{name}={checked[name]:g}", str(error)) from None
    return checked


def ego_fmu(dynamics: Dynamics | None = None, fmu: str | os.PathLike | None = None,
            vehicle: str | os.PathLike | None = None) -> Path:
    """The ego FMU's path: `fmu` if given (checked against the vehicle map, or the shipped map of `dynamics`), else
    the map's own FMU or the cached build for `dynamics` (built on first use)."""
    return ego_model(dynamics, fmu, vehicle).fmu_path


def tire_slot_starts(tires: str | os.PathLike | None,
                     model) -> tuple[dict[str, float], dict[int, int] | None, list[str]]:
    """(the tire slots' start values, attribute -> slot for the attributes the file gives, its warnings) from a
    Tire Attribute File (None: the shipped one), for a vehicle whose map declares tire slots; for any other
    vehicle ({}, None, []). Raises InputError naming `tires` for a bad file, or for `tires` given to a vehicle
    without tire slots."""
    if model.friction is None or model.friction.tire_slots is None:
        if tires is not None:
            raise _option_error("tires", tires, "applies to the advanced dynamics only (a vehicle map whose friction "
                                                f"input has tire_slots; {model.name}'s has none)")
        return {}, None, []
    from .dynamics.tires import TireFileError, default_attribute_file, slot_parameters

    path = _regular_file("tires", tires) if tires is not None else default_attribute_file()
    try:
        return slot_parameters(path)
    except TireFileError as error:
        raise InputError("tires", _first_line(error)) from None


def _whole_attributes(scenario: Scenario) -> None:
    """For a vehicle whose friction input means an attribute (the Advanced FMU), an RSA value is an attribute
    number: a fraction is an error naming the line."""
    errors = []
    for event in scenario.events:
        if isinstance(event, SurfaceAttribute):
            for index, (_lane, value) in enumerate(event.settings):
                if value != int(value):
                    errors.append(SdlError(scenario.path, event.line, f"RSA parameter {2 * index + 2} (value)",
                                           f"{value:g}: for this vehicle the value is a surface attribute "
                                           "number and must be whole"))
    if errors:
        raise ScenarioError(errors)


# --- the result ----------------------------------------------------------------------------------


@dataclass
class Result:
    """What a run produced. `raw` is the orchestrator's RunResult (SI); everything else is in the
    scenario's units, as in the results files."""

    raw: RunResult
    scenario: Scenario

    def __repr__(self) -> str:
        """One short line (the time series and events stay in .arrays and .events)."""
        final = self.final
        return (f"<Result {Path(self.scenario.path).stem}: {self.raw.dynamics} dynamics, "
                f"{len(self.raw.columns['time'])} samples to {final.get('time_s', float('nan')):.2f} s, "
                f"{self.collisions} collision(s), {len(self.warnings)} warning(s)>")

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        """The time series as NumPy arrays, keyed by the timeseries.csv headers (units in the names)."""
        return {header: np.asarray(values) for header, values, _ in timeseries_table(self.raw)}

    @property
    def time(self) -> np.ndarray:
        return np.asarray(self.raw.columns["time"], dtype=float)

    def dataframe(self):
        """The time series as a pandas DataFrame (needs pandas, which sdl-fmu does not depend on)."""
        try:
            import pandas
        except ImportError:
            raise ImportError("Result.dataframe() needs pandas (pip install pandas); "
                              "Result.arrays has the same columns as NumPy arrays") from None
        return pandas.DataFrame(self.arrays)

    @property
    def events(self) -> Sequence[dict]:
        """summary.json's events in order: a sequence of dicts read back from the run's event log on disk
        (each read afresh; list(result.events) for a list)."""
        return self.raw.events

    @property
    def warnings(self) -> list[str]:
        return self.raw.warnings

    @property
    def collisions(self) -> int:
        return self.raw.collisions

    @property
    def final(self) -> dict:
        return self.raw.final

    @property
    def criticality(self) -> dict | None:
        """summary.json's `criticality` (docs/results.md): min_distance (scenario units) and its instant, min_ttc_s,
        max_drac (scenario units/s2), min_pet_s, min_headway_s, ..., run-wide and per vehicle (`vehicles`)."""
        return self.raw.criticality

    @property
    def summary(self) -> dict:
        """summary.json's content."""
        return summary(self.raw)

    def write(self, out: str | os.PathLike, plot: bool = True) -> Path:
        """Writes a results folder (timeseries.csv, summary.json, plot.png); see results_folder for the rules."""
        from .results_folder import ResultsFolderError

        try:
            return write_results(self.raw, Path(out), plot=plot)
        except ResultsFolderError as error:
            raise InputError("out", "", subject=str(error)) from None

    def plot(self, path: str | os.PathLike) -> Path:
        """Only the plot, as a PNG at `path`."""
        from . import plots

        plots.plot_run(self.raw, Path(path))
        return Path(path)


# --- running -------------------------------------------------------------------------------------


def _progress_bar(enabled: bool | None, scenario: Scenario) -> Callable | None:
    """A tqdm bar on stderr (by default only when stderr is a terminal), fed by the master each step."""
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        return None
    from tqdm import tqdm

    from .text import unescaped  # the bar's own carriage returns, not escaped
    from .units import from_si, length_label

    state_of = {}

    def update(cosimulation, state) -> None:
        bar = state_of.get("bar")
        if bar is None:
            if math.isfinite(cosimulation.end_distance):
                total, unit, key = from_si(cosimulation.end_distance, scenario.units), length_label(scenario.units), "s"
            else:
                total, unit, key = cosimulation.options.until_time or MAX_TIME, "s", "time"
            # the terminal's size, 80 x 24 where it reports none (a fresh pseudo-terminal says 0 x 0, which
            # makes tqdm print nothing)
            size = shutil.get_terminal_size()
            bar = state_of["bar"] = tqdm(total=round(total, 1), unit=unit, file=unescaped(sys.stderr), leave=False,
                                         ncols=size.columns, nrows=size.lines,
                                         bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} {unit}")
            state_of["key"] = key
        value = state.s if state_of["key"] == "s" else state.time
        if state_of["key"] == "s":
            value = from_si(value, scenario.units)
        value = min(value, bar.total)
        bar.update(value - bar.n)
        if cosimulation.finished:
            bar.close()

    return update


# Test hook, for tests that must catch a run in progress whatever the machine's speed (Ctrl-C, timeouts, a
# worker killed mid-run): when $SDL_FMU_TEST_HOLD names a file that exists, every run, after its first
# communication step, appends its process id to that path + ".running" and then waits until the file is
# removed, its timeout passes (RunTimeout) or it is interrupted.
HOLD_VARIABLE = "SDL_FMU_TEST_HOLD"


def _held(progress: Callable | None, hold: str) -> Callable:
    held = []

    def hold_once(cosimulation, state) -> None:
        if progress is not None:
            progress(cosimulation, state)
        if not held:
            held.append(True)
            with open(hold + ".running", "a", encoding="utf-8") as running:
                running.write(f"{os.getpid()}\n")
            while os.path.exists(hold):
                time.sleep(0.01)
                if progress is not None:
                    progress(cosimulation, state)  # the deadline's check

    return hold_once


def _with_deadline(progress: Callable | None, timeout: float) -> Callable:
    """The master's per-step callback, raising RunTimeout once `timeout` wall seconds have passed."""
    deadline = time.monotonic() + timeout

    def check(cosimulation, state) -> None:
        if progress is not None:
            progress(cosimulation, state)
        if time.monotonic() > deadline:
            raise RunTimeout(f"the run exceeded its time limit of {timeout:g} s (wall clock) at simulated "
                             f"t = {state.time:.2f} s")

    return check


def run(scenario: str | os.PathLike | Scenario, *, dynamics: Dynamics | None = None,
        fmu: str | os.PathLike | None = None, vehicle: str | os.PathLike | None = None,
        speed: float | None = None, seed: int = 1, step: float | None = None,
        driver_period: float | None = None, until_distance: float | None = None,
        until_time: float | None = None, params: dict[str, float] | None = None,
        tires: str | os.PathLike | None = None, skip_unsupported: bool = False, progress: bool | None = False,
        out: str | os.PathLike | None = None, plot: bool = True, timeout: float | None = None,
        controller: str | os.PathLike | None = None, controller_map: str | os.PathLike | None = None,
        driver: str = "lane", on_collision: str = "continue") -> Result:
    """Co-simulates a scenario (a path, a shipped example's name, or a loaded Scenario) and returns the Result.

    speed and until_distance are in the scenario's units (ft, ft/s or m, m/s), until_time and step in s,
    step is the longest communication step (default 1 s; results do not depend on it), driver_period the
    driver model's sampling period (default 0.05 s),
    params are FMU start values (SI) within each parameter's declared min/max. vehicle: a vehicle map (TOML,
    docs/vehicle-maps.md) driving `fmu` (or the map's own `fmu`); without it `dynamics` (default simple) names a
    shipped map and fmu defaults to its cached build. tires: Tire Attribute File (vehicles with tire slots:
    advanced). progress: a bar on stderr (None: only when stderr is a terminal). out: also write the results
    folder; it is checked before the simulation.
    timeout: wall-clock seconds after which the simulation stops with RunTimeout (checked every step).
    controller, controller_map: a controller FMU in the loop and its controller map (TOML, docs/controllers.md; the
    map's own `fmu` when controller is None). driver: the built-in driver, "lane" (holds its lane and speed,
    ignores traffic) or "follow" (also follows the vehicle ahead: Gipps' law). on_collision: "continue" or "stop"
    (the run ends at the first contact).
    Raises InputError or ScenarioError for user mistakes."""
    from .cosim.ego import FmuError
    from .cosim.master import RunOptions, run_scenario
    from .results_folder import ResultsFolderError, check_results_folder
    from .vehicle.controller import ControllerError

    seed = _seed(seed)
    driver = _choice("driver", driver, DRIVERS)
    on_collision = _choice("on_collision", on_collision, ON_COLLISION)
    from .cosim.master import DEFAULT_DRIVER_PERIOD, DEFAULT_STEP

    step = DEFAULT_STEP if step is None else _checked_option("step", step)
    driver_period = DEFAULT_DRIVER_PERIOD if driver_period is None else _checked_option("driver_period", driver_period)
    until_time = _checked_option("until_time", until_time, low_open=True)
    if not isinstance(scenario, Scenario):
        scenario = load(scenario, skip_unsupported=skip_unsupported)
    units = scenario.units
    speed = _checked_option("speed", speed, units)
    until_distance = _checked_option("until_distance", until_distance, units, low_open=True)
    model = ego_model(dynamics, fmu, vehicle)
    if model.surface_meaning == "attribute":
        _whole_attributes(scenario)
    tire_starts, known_attributes, tire_warnings = tire_slot_starts(tires, model)
    in_the_loop = controller_model(controller, controller_map)
    if out is not None:
        try:
            check_results_folder(out)
        except ResultsFolderError as error:
            raise InputError("out", "", subject=str(error)) from None
    fmu_path = model.fmu_path
    parameters = _parameters(params, model)
    options = RunOptions(speed=speed, seed=seed, step=step, driver_period=driver_period,
                         until_distance=until_distance,
                         until_time=until_time, parameters=parameters, tire_parameters=tire_starts,
                         known_attributes=None if known_attributes is None else set(known_attributes),
                         driver=driver, controller=in_the_loop, on_collision=on_collision)
    options.progress = _progress_bar(progress, scenario)
    if timeout is not None:
        options.progress = _with_deadline(options.progress, timeout)
    if os.environ.get(HOLD_VARIABLE) and os.path.exists(os.environ[HOLD_VARIABLE]):
        options.progress = _held(options.progress, os.environ[HOLD_VARIABLE])
    from .vehicle.isolated import FmuTimeout, deadline

    try:
        with deadline(timeout):  # a foreign FMU's host is waited for at most until then, even inside a step
            raw = run_scenario(scenario, model, options, _vehicle_table())
    except FmuTimeout as error:
        raise RunTimeout(f"the run exceeded its time limit of {timeout:g} s (wall clock): the FMU {fmu_path.name} "
                         f"{_first_line(error)}") from None  # "did not answer in fmi2DoStep from t = ..."
    except ControllerError as error:  # the controller's binary, or values it refused or returned
        raise InputError("controller", _first_line(error)) from None
    except FmuError as error:  # a broken binary, or values the model cannot simulate
        raise InputError("fmu", f"the FMU {fmu_path.name} failed: {_first_line(error)}") from None
    except OSError as error:  # the samples' temporary files: a full or unwritable $TMPDIR
        import tempfile

        raise InputError(None, f"cannot write the run's temporary files in {tempfile.gettempdir()}: "
                               f"{error.strerror or error}; nothing was written") from None
    raw.warnings[:0] = [*scenario.warnings, *tire_warnings]
    result = Result(raw, scenario)
    if out is not None:
        result.write(out, plot=plot)
    return result


# --- the vehicle test pack ---------------------------------------------------------------------------------


@dataclass
class VerifyResult:
    """The vehicle test pack's outcome: `outcomes` (verify.Outcome, one per manoeuvre), the vehicle's identity,
    the printed pass/fail `table`, and the results folder (None without `out`)."""

    vehicle: dict
    outcomes: list
    table: str
    folder: Path | None


def verify(*, dynamics: Dynamics | None = None, fmu: str | os.PathLike | None = None,
           vehicle: str | os.PathLike | None = None, only: Sequence[str] | None = None,
           out: str | os.PathLike | None = None) -> VerifyResult:
    """Runs the vehicle test pack (docs/verification.md) against one vehicle: a shipped model (`dynamics`), or `fmu`
    driven through the vehicle map `vehicle`. A manoeuvre the vehicle cannot be driven through fails with its
    reason; only user mistakes (options, FMU, map, results folder) raise InputError."""
    from . import verify as pack
    from .results_folder import ResultsFolderError, check_results_folder

    names = list(pack.MANOEUVRES) if only is None else list(only)
    unknown = [name for name in names if name not in pack.MANOEUVRES]
    if unknown or not names:
        raise _option_error("only", ",".join(names), f"must name manoeuvres among {', '.join(pack.MANOEUVRES)}")
    model = ego_model(dynamics, fmu, vehicle)
    try:  # an FMU that cannot even be instantiated is a bad --fmu, not a manoeuvre's result
        model.instantiate(start={"speed": 0.0, "x": 0.0, "y": 0.0, "yaw": 0.0}, instance_name="probe").close()
    except Exception as error:  # noqa: BLE001 - fmpy reports a binary that cannot be loaded as a plain Exception
        raise InputError("fmu", f"the FMU {model.fmu_path} cannot be instantiated: {_first_line(error)}") from None
    if out is not None:
        try:
            check_results_folder(out)
        except ResultsFolderError as error:
            raise InputError("out", "", subject=str(error)) from None
    identity = {"name": model.name, "fmu": str(model.fmu_path), "guid": model.guid, "fmi_version": model.fmi_version,
                "map": None if model.map_path is None else str(model.map_path),
                "friction": None if model.friction is None else model.friction.meaning}
    outcomes = pack.run_pack(model, names)
    folder = None
    if out is not None:
        try:
            folder = pack.write(out, identity, outcomes)
        except ResultsFolderError as error:
            raise InputError("out", "", subject=str(error)) from None
    return VerifyResult(identity, outcomes, pack.table(outcomes), folder)
