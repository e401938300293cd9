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

import contextlib
import functools
import math
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Literal, Mapping, Sequence

import numpy as np
from fmpy import read_model_description

from . import __version__
from .cosim import master
from .cosim.ego import FmuError
from .hold import HOLD_VARIABLE, hold_here, holding  # noqa: F401 (HOLD_VARIABLE: the tests' name for it)
from .names import EXAMPLE_CONTROLLER, SHIPPED, Dynamics
from .options import (DEFAULT_DRIVER_PERIOD, DEFAULT_SPEED, DEFAULT_STEP, DEFAULT_TEST_TIMEOUT, DRIVERS, LIMITS,
                      MAX_TIME, ON_COLLISION, InputError, RunTimeout, checked_choice, checked_option, checked_seed,
                      option_error, regular_file)
from .paths import SCENARIO_DIRECTORY
from .results import RunRecord, scenario_units, summary, timeseries_table, write_results
from .results.folder import ResultsFolderError, check_results_folder
from .sdl import Scenario, ScenarioError, SdlError, default_vehicle_table_path, load_scenario, load_vehicle_table
from .sdl.checks import check_scenario, vehicle_warnings
from .sdl.parameters import ParameterError, address, parameter_name
from .sdl.parser import resolve_text, with_values
from .shipped import shipped_controller, shipped_fmu
from .shipping import ClusterError
from .ssp.folder import check_export_folder, write_export
from .ssp.system import ExportError, build_system, fmu_file_name
from .text import UnsafeName, safe_identifier, unescaped
from .tire_files import TireFileError, default_attribute_file, read_attribute_file, slot_values
from .units import from_si, length_label, speed_label
from .vehicle import EgoModel, VehicleMap, VehicleMapError, load_vehicle_map, shipped_map_path
from .vehicle.controller import ControllerError, ControllerModel
from .vehicle.isolated import FmuTimeout, deadline

__all__ = ["InputError", "RunTimeout", "ScenarioError", "Result", "load", "check", "run", "run_options", "verify",
           "export", "Export", "shipped_scenarios", "resolve_scenario", "ego_fmu", "ego_model", "controller_model",
           "set_parameters", "resolve", "write_resolved", "value_target", "apply_values", "check_value_names",
           "check_settings",
           "LIMITS", "RUN_OPTIONS", "VALUE_OPTIONS", "DRIVERS", "ON_COLLISION"]


def _first_line(error: BaseException) -> str:
    text = str(error).strip() or type(error).__name__
    return text.splitlines()[0]


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
    return load_vehicle_table(default_vehicle_table_path())


def _vehicle_map(dynamics: Dynamics | None, vehicle: str | os.PathLike | VehicleMap | None) -> VehicleMap:
    """The vehicle map a run would drive: the map file `vehicle`, else the shipped map of `dynamics` (default simple);
    read without its FMU. InputError naming `dynamics` or `vehicle`."""
    if vehicle is not None and dynamics is not None:
        raise option_error("dynamics", dynamics, "give either a shipped model (dynamics) or a vehicle map "
                           "(vehicle), not both")
    if isinstance(vehicle, VehicleMap):
        return vehicle
    if vehicle is not None:
        return load_vehicle_map(regular_file("vehicle", vehicle))
    dynamics = "simple" if dynamics is None else dynamics
    if dynamics not in SHIPPED:
        raise option_error("dynamics", dynamics, f"must be one of {', '.join(SHIPPED)}")
    return load_vehicle_map(shipped_map_path(dynamics))


def _read(scenario: str | os.PathLike, skip_unsupported: bool) -> Scenario:
    path = resolve_scenario(scenario)
    if not os.path.lexists(path) and isinstance(scenario, str):
        names = ", ".join(shipped_scenarios())
        raise ScenarioError([SdlError(os.fspath(scenario), 0, "file",
                                      f"no such file (shipped examples by name: {names})")])
    return load_scenario(path, skip_unsupported=skip_unsupported)


def _checked(scenario: str | os.PathLike | Scenario, vehicle_map: VehicleMap, skip_unsupported: bool,
             values: dict[str, float] | None = None) -> Scenario:
    """The one scenario check: a file read (or a Scenario as given), its parameters set to `values`, and checked
    against the vehicle table and the map's friction meaning. Costs a parse; nothing is built or loaded. ScenarioError
    listing every problem."""
    if not isinstance(scenario, Scenario):
        scenario = _read(scenario, skip_unsupported)
    if values:
        scenario = set_parameters(scenario, values)
    friction = vehicle_map.friction
    check_scenario(scenario, _vehicle_table(), None if friction is None else friction.meaning)
    return scenario


def load(scenario: str | os.PathLike, *, skip_unsupported: bool = False, dynamics: Dynamics | None = None,
         vehicle: str | os.PathLike | None = None, set: Mapping[str, float] | None = None) -> Scenario:
    """Reads and checks a scenario file (or a shipped example by name) for the vehicle `run` would drive (the map
    `vehicle`, else the shipped map of `dynamics`, default simple: for advanced, RSA values are whole attribute
    numbers); raises ScenarioError listing every problem. skip_unsupported: lines sdl-fmu does not simulate become
    warnings (one per code). set: scenario parameters' values (see set_parameters)."""
    return _checked(scenario, _vehicle_map(dynamics, vehicle), skip_unsupported, set)


# --- scenario parameters (docs/scenarios.md, Parameters) ---------------------------------------------------------


def set_parameters(scenario: str | os.PathLike | Scenario, values: Mapping[str, float] | None, *,
                   skip_unsupported: bool = False) -> Scenario:
    """The scenario (a path, a shipped example's name, or a Scenario read from a file) with its parameters set: each
    key of `values` a declared parameter (`NAME` or `$NAME`, a `// @param` line of the file) or an address (`LINE.N`:
    parameter N of the event on line LINE, 0 its distance; `rsa.LINE`, `rsa.LINE.LANE`), each value in the file's
    units. Values set earlier on the same Scenario stay unless set again. The values go into the text before it is
    read, so each is checked as the field it reaches says (ScenarioError naming file, line, field and parameter), and
    against its declared range and unit; a key that names nothing is an InputError of option `set`. Not checked
    against a vehicle (load and run do that)."""
    if not isinstance(scenario, Scenario):
        scenario = _read(scenario, skip_unsupported)
    if not values:
        return scenario
    try:
        return with_values(scenario, dict(values))
    except ParameterError as error:
        raise InputError("set", "", subject=str(error)) from None


def resolve(scenario: str | os.PathLike | Scenario, values: Mapping[str, float] | None = None, *,
            skip_unsupported: bool = False) -> str:
    """The scenario's SDL text with every parameter's value (declared, set on the Scenario, then `values`) written
    into the fields that use it and each `// @param` line made a plain comment recording the value: plain SDL that any
    reader runs to the same results, line for line (lines keep their numbers). The checks of set_parameters."""
    if not isinstance(scenario, Scenario):
        scenario = _read(scenario, skip_unsupported)
    try:
        return resolve_text(scenario, dict(values or {}))
    except ParameterError as error:
        raise InputError("set", "", subject=str(error)) from None


def write_resolved(scenario: str | os.PathLike | Scenario, out: str | os.PathLike,
                   values: Mapping[str, float] | None = None, *, skip_unsupported: bool = False) -> Path:
    """resolve() written to the new file `out` (UTF-8): written whole under a temporary name, then linked into place,
    so an existing file is never replaced (InputError naming `out`) and an interruption leaves nothing."""
    text = resolve(scenario, values, skip_unsupported=skip_unsupported)
    target = Path(out)
    if os.path.lexists(target):
        raise option_error("out", out, "exists; resolve writes a new file and never replaces one")
    try:
        descriptor, partial = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".partial",
                                               dir=target.parent if str(target.parent) else ".")
    except OSError as error:
        raise option_error("out", out, f"cannot be written: {error.strerror or error}") from None
    try:
        with os.fdopen(descriptor, "w", encoding="utf-8", newline="\n") as file:
            file.write(text)
        os.link(partial, target)  # fails if `out` appeared meanwhile: never replaced
    except FileExistsError:
        raise option_error("out", out, "exists; resolve writes a new file and never replaces one") from None
    except OSError as error:
        raise option_error("out", out, f"cannot be written: {error.strerror or error}") from None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(partial)
    return target


VALUE_OPTIONS = ("speed", "seed", "until_distance", "until_time")  # run options a {name: value} mapping may set

ValueTarget = Literal["option", "scenario", "fmu"]


def value_target(name: str, scenario: Scenario) -> ValueTarget:
    """What a name of a {name: value} mapping (sweep --vary's names) sets: a run option (VALUE_OPTIONS), a scenario
    parameter (`$NAME`, a NAME the scenario declares, an address `LINE.N`, `rsa.LINE[.LANE]`), or an FMU parameter
    (`param.NAME`, or any other NAME). Whether that FMU parameter exists is check_value_names's question."""
    if name in VALUE_OPTIONS:
        return "option"
    if name.startswith("param."):
        return "fmu"
    if address(name) is not None or name.startswith("$"):
        return "scenario"
    if parameter_name(name) in {parameter.name for parameter in scenario.parameters}:
        return "scenario"
    return "fmu"


def check_value_names(scenario: Scenario, names: Sequence[str], model: EgoModel | None = None,
                      option: str = "vary") -> None:
    """InputError (of `option`) for the first name that sets nothing: not a run option, not a parameter the scenario
    declares or an address, not a parameter of the FMU (`model`; None: FMU names not checked), or a bare NAME that is
    both a declared scenario parameter and an FMU parameter (write $NAME or param.NAME). Reads no value: the values
    are checked where they go (set_parameters, run)."""
    declared = [parameter.name for parameter in scenario.parameters]
    seen: dict[str, str] = {}
    for name in names:
        target = value_target(name, scenario)
        same = parameter_name(name) if target == "scenario" and address(name) is None else None
        if same is not None and same in seen:
            raise option_error(option, name, f"is the parameter {seen[same]} names too; give it once")
        if same is not None:
            seen[same] = name
        fmu_name = name.removeprefix("param.")
        has_fmu = model is not None and fmu_name in model.variables and \
            model.variables[fmu_name].causality == "parameter"
        if target == "scenario" and name.startswith("$") and parameter_name(name) not in declared:
            raise option_error(option, name, f"{Path(scenario.path).name} declares no parameter "
                                             f"{name[1:]!r} (declared: {', '.join(declared) or 'none'})")
        if target == "scenario" and not name.startswith("$") and address(name) is None and has_fmu:
            raise option_error(option, name, f"is both a parameter of {Path(scenario.path).name} and an FMU "
                                             f"parameter of {model.name}: write ${name} or param.{name}")
        if target == "fmu" and model is not None and not has_fmu and name.startswith("param."):
            raise option_error(option, name, f"the FMU {model.name} has no parameter {fmu_name!r} (parameters: "
                                             f"{', '.join(model.parameter_names())})")
        if target == "fmu" and model is not None and not has_fmu:
            raise option_error(option, name, "is no run option (" + ", ".join(VALUE_OPTIONS) + "), no parameter "
                               f"of {Path(scenario.path).name} (declared: {', '.join(declared) or 'none'}; or an "
                               f"address LINE.N, rsa.LINE[.LANE]) and no parameter of the FMU {model.name} "
                               f"({', '.join(model.parameter_names())})")


def check_settings(scenario: Scenario, settings: Iterable[Mapping[str, float]], *, dynamics: Dynamics | None = None,
                   vehicle: str | os.PathLike | None = None) -> int:
    """Each mapping of scenario values (set_parameters) applied to the scenario and checked as load() checks it for
    the vehicle (its map read once): the first that a field, a declared range or the vehicle refuses raises, before
    anything runs. Returns how many were checked."""
    vehicle_map = _vehicle_map(dynamics, vehicle)
    count = 0
    for values in settings:
        _checked(scenario, vehicle_map, False, values)
        count += 1
    return count


def apply_values(scenario: str | os.PathLike | Scenario, values: Mapping[str, float],
                 options: Mapping | None = None) -> tuple[Scenario, dict]:
    """One run's {name: value} mapping (as sweep --vary names them: value_target) applied: the scenario with its
    scenario parameters set (set_parameters: each value checked by its field), and run's keyword options `options`
    with the run options and the FMU parameters (into `params`) added. `run(scenario, **options)` with what it
    returns is the run of that mapping; a sweep's row is run so (sweep.run_one)."""
    options = dict(options or {})
    if not isinstance(scenario, Scenario):
        scenario = _read(scenario, options.get("skip_unsupported", False))
    params = dict(options.pop("params", None) or {})
    settings = {}
    for name, value in values.items():
        target = value_target(name, scenario)
        if target == "option":
            options[name] = value
        elif target == "fmu":
            params[name.removeprefix("param.")] = value
        else:
            settings[name] = value
    if settings:
        scenario = set_parameters(scenario, settings)
    if params:
        options["params"] = params
    return scenario, options


@dataclass
class Check:
    """What `check` found: the scenario and every warning a whole run with this vehicle would give because of the
    scenario (the file's own, the Tire Attribute File's, then per event: BRK ignored, an RSA the vehicle cannot feel,
    an attribute number without a tire)."""

    scenario: Scenario
    warnings: list[str]


def check(scenario: str | os.PathLike | Scenario, *, skip_unsupported: bool = False, dynamics: Dynamics | None = None,
          vehicle: str | os.PathLike | None = None, tires: str | os.PathLike | None = None,
          set: Mapping[str, float] | None = None) -> Check:
    """load() and the warnings a run of the whole scenario would print for this vehicle and Tire Attribute File,
    without building or loading its FMU (`sdl-fmu check`); `set`: scenario parameters' values (set_parameters). Not
    the warnings of what never took effect in a run (an action never fired, a BRK overridden: cosim/effects.py), which
    depend on how the run goes."""
    vehicle_map = _vehicle_map(dynamics, vehicle)
    loaded = _checked(scenario, vehicle_map, skip_unsupported, set)
    friction = vehicle_map.friction
    known, tire_warnings = None, []
    if friction is not None and friction.tire_slots is not None:
        known, tire_warnings = _tire_file_check(tires)
    elif tires is not None:
        raise _no_tire_slots(tires, vehicle_map.name or vehicle_map.label)
    warnings = vehicle_warnings(loaded, vehicle_map.name or vehicle_map.label,
                                None if friction is None else friction.meaning, vehicle_map.flags.get("brk_acts", True),
                                known)
    hold_here()  # the test hook (hold.py)
    return Check(loaded, [*loaded.warnings, *tire_warnings, *warnings])


def _no_tire_slots(tires, name: str) -> InputError:
    return option_error("tires", tires, f"applies to the advanced dynamics only (a vehicle map whose friction input "
                                        f"has tire_slots; {name}'s has none)")


def _tire_file_check(tires: str | os.PathLike | None) -> tuple[frozenset[int], list[str]]:
    """(the attribute numbers it gives, its warnings) of a Tire Attribute File (None: the shipped one), read before any
    FMU is loaded; InputError naming `tires`. How many tire slots the FMU has is known only once it is loaded: here
    every attribute the file gives counts (EgoModel.with_tires then reads the file for the FMU's slots)."""
    path = default_attribute_file() if tires is None else regular_file("tires", tires)
    try:  # as many slots as the file has attributes: how many the FMU has is known once it is loaded
        count = 1 + max((entry.attribute for entry in read_attribute_file(path)), default=0)
        _, attributes, warnings = slot_values(path, count)
    except TireFileError as error:
        raise InputError("tires", _first_line(error)) from None
    return frozenset(attributes), warnings


# --- the vehicle --------------------------------------------------------------------------------


def ego_model(dynamics: Dynamics | None = None, fmu: str | os.PathLike | None = None,
              vehicle: str | os.PathLike | VehicleMap | None = None, fmi_version: int = 2) -> EgoModel:
    """The run's EgoModel: `fmu` (or the map's own `fmu`) driven through the vehicle map `vehicle`; without a map,
    the shipped map of `dynamics` (default simple) with `fmu` or the cached build of that FMI version (built on first
    use, with one line on stderr). Raises InputError naming the map file and key, or the FMU."""
    vehicle_map = _vehicle_map(dynamics, vehicle)
    if vehicle is not None:
        return EgoModel.open(None if fmu is None else regular_file("fmu", fmu), vehicle_map)
    dynamics = "simple" if dynamics is None else dynamics
    if fmu is None:
        return EgoModel.open(shipped_fmu(dynamics, fmi_version), vehicle_map)
    try:
        return EgoModel.open(regular_file("fmu", fmu), vehicle_map)
    except VehicleMapError as error:
        if error.option == "fmu":
            raise
        raise InputError("fmu", "", subject=f"{fmu}: does not fit the shipped {dynamics} map: {error}") from None


def ego_fmu(dynamics: Dynamics | None = None, fmu: str | os.PathLike | None = None,
            vehicle: str | os.PathLike | None = None) -> Path:
    """The ego FMU's path: `fmu` if given (checked against the vehicle map, or the shipped map of `dynamics`), else
    the map's own FMU or the cached build for `dynamics` (built on first use)."""
    return ego_model(dynamics, fmu, vehicle).fmu_path


def controller_model(controller: str | os.PathLike | None = None,
                     controller_map: str | os.PathLike | None = None) -> ControllerModel | None:
    """The run's ControllerModel (docs/controllers.md): `controller` (or the map's own `fmu`) driven through the
    controller map `controller_map`; `controller="example-aeb"` without a map: the shipped example AEB (its cached
    FMU, built on first use, and its shipped map); None when neither is given. Raises InputError naming the map file
    and key, or the option and its value."""
    if controller is None and controller_map is None:
        return None
    if controller_map is None and os.fspath(controller) == EXAMPLE_CONTROLLER:  # the shipped example AEB
        controller, controller_map = example_controller()
    if controller_map is None:
        raise option_error("controller", controller, "needs a controller map (controller_map, a TOML file: "
                                                     "docs/controllers.md), or is example-aeb")
    return ControllerModel.open(None if controller is None else regular_file("controller", controller),
                                regular_file("controller_map", controller_map))


# --- the result ----------------------------------------------------------------------------------


@dataclass
class Result:
    """What a run produced. `raw` is the orchestrator's RunRecord (SI); everything else is in the
    scenario's units, as in the results files."""

    raw: RunRecord
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
        """summary.json's events in order, in the scenario's units: a sequence of dicts read back from the run's
        event log on disk (each read afresh; list(result.events) for a list)."""
        return scenario_units.Events(self.raw.events, self.raw.units)

    @property
    def warnings(self) -> list[str]:
        return self.raw.warnings

    @property
    def collisions(self) -> int:
        return self.raw.collisions

    @functools.cached_property
    def final(self) -> dict:
        """summary.json's `final`, in the scenario's units."""
        return scenario_units.final(self.raw.final, self.raw.units)

    @functools.cached_property
    def criticality(self) -> dict | None:
        """summary.json's `criticality` (docs/results.md): min_distance (scenario units) and its instant, min_ttc_s,
        max_drac (scenario units/s2), min_pet_s, min_headway_s, ..., run-wide and per vehicle (`vehicles`)."""
        return scenario_units.criticality(self.raw.criticality, self.raw.units)

    @property
    def summary(self) -> dict:
        """summary.json's content."""
        return summary(self.raw)

    def write(self, out: str | os.PathLike, plot: bool | os.PathLike = True) -> Path:
        """Writes a results folder (timeseries.csv, summary.json, plot.png); see results/folder.py for the rules.
        `plot`: False for none, or the path of this result's plot already drawn (Result.plot), copied in."""
        try:
            return write_results(self.raw, Path(out), plot=plot if isinstance(plot, bool) else Path(plot))
        except ResultsFolderError as error:
            raise InputError("out", "", subject=str(error)) from None

    def plot(self, path: str | os.PathLike) -> Path:
        """Only the plot, as a PNG at `path`."""
        from .results.plots import plot_run  # matplotlib: loaded only to plot

        plot_run(self.raw, Path(path))
        return Path(path)


# --- running -------------------------------------------------------------------------------------


def _progress_bar(enabled: bool | None, scenario: Scenario) -> Callable | None:
    """A tqdm bar on stderr (by default only when stderr is a terminal), fed by the master each step."""
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        return None
    from tqdm import tqdm  # loaded only for a bar

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


def _held(progress: Callable | None) -> Callable:
    """The test hook's hold point of a run (sdl_fmu/hold.py): after its first communication step, until released,
    its timeout passes (RunTimeout) or it is interrupted."""
    held = []

    def hold_once(cosimulation, state) -> None:
        if progress is not None:
            progress(cosimulation, state)
        if not held:
            held.append(True)
            # while held, the deadline's check
            hold_here(None if progress is None else lambda: progress(cosimulation, state))

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
        driver: str = "lane", on_collision: str = "continue", until_not_closing: int | None = None,
        set: Mapping[str, float] | None = None) -> Result:
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
    map's own `fmu` when controller is None; controller "example-aeb" without a map: the shipped example AEB).
    driver: the built-in driver, "lane" (holds its lane and speed, ignores traffic) or "follow" (also follows the
    vehicle ahead: Gipps' law). on_collision: "continue" or "stop" (the run ends at the first contact).
    until_not_closing: a vehicle id: the run ends (ES reason not_closing) once the ego, having closed on that vehicle,
    no longer does (its speed along the road has fallen to the vehicle's or below: a stop behind a stopped one), as a
    test of the AEB car-to-car pack ends.
    set: scenario parameters' values, in the file's units (set_parameters: declared names and addresses LINE.N).
    Raises InputError or ScenarioError for user mistakes, each before anything is built or loaded where it can be
    told without the FMU (the options, the scenario, the map, the tire file, the results folder)."""
    vehicle_map = _vehicle_map(dynamics, vehicle)
    scenario = _checked(scenario, vehicle_map, skip_unsupported, set)
    options = run_options(scenario, speed=speed, seed=seed, step=step, driver_period=driver_period,
                          until_distance=until_distance, until_time=until_time, driver=driver,
                          on_collision=on_collision)
    friction = vehicle_map.friction
    if friction is not None and friction.tire_slots is not None:
        _tire_file_check(tires)
    elif tires is not None:
        raise _no_tire_slots(tires, vehicle_map.name or vehicle_map.label)
    options.controller = controller_model(controller, controller_map)
    options.until_not_closing = until_not_closing
    if out is not None:
        try:
            check_results_folder(out, "run")
        except ResultsFolderError as error:
            raise InputError("out", "", subject=str(error)) from None
    model = ego_model(dynamics, fmu, vehicle_map if vehicle is not None else None)
    model = model.with_tires(tires).with_parameters(params)
    options.progress = _progress_bar(progress, scenario)
    if timeout is not None:
        options.progress = _with_deadline(options.progress, timeout)
    if holding():
        options.progress = _held(options.progress)
    try:
        with deadline(timeout):  # a foreign FMU's host is waited for at most until then, even inside a step
            raw = master.run_scenario(scenario, model, options, _vehicle_table())
    except FmuTimeout as error:  # the ego's, or the controller's (its subject names it)
        raise RunTimeout(f"the run exceeded its time limit of {timeout:g} s (wall clock): "
                         f"{error.subject or 'the FMU ' + model.fmu_path.name} {_first_line(error)}"
                         ) from None  # "did not answer in fmi2DoStep ..."
    except ControllerError as error:  # the controller's binary, or values it refused or returned
        raise InputError("controller", _first_line(error)) from None
    except FmuError as error:  # a broken binary, or values the model cannot simulate
        raise InputError("fmu", f"the FMU {model.fmu_path.name} failed: {_first_line(error)}") from None
    except OSError as error:  # the samples' temporary files: a full or unwritable $TMPDIR
        raise InputError(None, f"cannot write the run's temporary files in {tempfile.gettempdir()}: "
                               f"{error.strerror or error}; nothing was written") from None
    raw.warnings[:0] = [*scenario.warnings, *model.warnings, *_speed_warnings(model, options.speed, scenario.units)]
    result = Result(raw, scenario)
    if out is not None:
        result.write(out, plot=plot)
    return result


# run's options that are values (not files)
RUN_OPTIONS = ("speed", "seed", "step", "driver_period", "until_distance", "until_time", "driver", "on_collision")


def run_options(scenario: Scenario, *, speed: float | None = None, seed: int = 1, step: float | None = None,
                driver_period: float | None = None, until_distance: float | None = None,
                until_time: float | None = None, driver: str = "lane",
                on_collision: str = "continue") -> master.RunOptions:
    """run's value options (RUN_OPTIONS) checked, as run takes them (speed and until_distance in the scenario's
    units), and in SI: InputError naming the first bad one. The sweep checks its fixed options with it."""
    units = scenario.units
    return master.RunOptions(
        driver=checked_choice("driver", driver, DRIVERS),
        on_collision=checked_choice("on_collision", on_collision, ON_COLLISION),
        seed=checked_seed(seed), step=DEFAULT_STEP if step is None else checked_option("step", step),
        driver_period=DEFAULT_DRIVER_PERIOD if driver_period is None else checked_option("driver_period",
                                                                                         driver_period),
        until_time=checked_option("until_time", until_time, low_open=True), speed=checked_option("speed", speed, units),
        until_distance=checked_option("until_distance", until_distance, units, low_open=True))


def _speed_warnings(model: EgoModel, speed: float | None, units) -> list[str]:
    """One warning when the driver's target speed is above the vehicle's top speed (EgoModel.top_speed)."""
    target = DEFAULT_SPEED if speed is None else speed
    top = model.top_speed()
    if not target > top:
        return []
    label = speed_label(units)
    return [f"speed {from_si(target, units):g} {label}: above the top speed of {model.name}, {from_si(top, units):.1f} "
            f"{label} (where its drive at full throttle, at most {model.drive_power_max / 1000:g} kW, meets its "
            "rolling resistance and drag): the driver holds full throttle below the target"]


# --- the test packs ---------------------------------------------------------------------------------------------

PACKS = ("vehicle", "aeb-ccr")  # verify's packs (docs/verification.md); vehicle is the default


@dataclass
class VerifyResult:
    """A test pack's outcome: `outcomes` (verify.Outcome per manoeuvre, or verify.aeb.TestOutcome per test), the
    vehicle's identity, the printed `table`, the results folder (None without `out`), `passed` (no criterion failed:
    --strict's test) and the pack's name."""

    vehicle: dict
    outcomes: list
    table: str
    folder: Path | None
    passed: bool = True
    pack: str = "vehicle"


def example_controller() -> tuple[Path, Path]:
    """(FMU, controller map) of the shipped example AEB: its cached build (built on first use) and its map."""
    return shipped_controller(EXAMPLE_CONTROLLER)


def verify(*, dynamics: Dynamics | None = None, fmu: str | os.PathLike | None = None,
           vehicle: str | os.PathLike | None = None, only: Sequence[str] | None = None,
           out: str | os.PathLike | None = None, pack: str = "vehicle", params: dict[str, float] | None = None,
           controller: str | os.PathLike | None = None, controller_map: str | os.PathLike | None = None,
           workers: int | None = None, scheduler: str | None = None, test_timeout: float | None = None,
           progress: bool | None = False) -> VerifyResult:
    """Runs a test pack (docs/verification.md) against one vehicle: a shipped model (`dynamics`), or `fmu` driven
    through the vehicle map `vehicle`, with FMU start values `params` (SI, as run's). pack "vehicle": the standard
    manoeuvres (`only`: some of them); a manoeuvre the vehicle cannot be driven through fails with its reason.
    pack "aeb-ccr": the Euro NCAP car-to-car rear grid (`only`: some of CCRs, CCRm, CCRb) with the controller
    `controller` and its map `controller_map` in the loop (`controller="example-aeb"`: the shipped example AEB;
    none: the vehicle alone), run on Dask as a sweep runs (`workers` processes, default one per core, or
    `scheduler`'s cluster; workers=0: in this process), each test stopped after `test_timeout` s of wall clock
    (default options.DEFAULT_TEST_TIMEOUT; its end is then `timeout`). With `out`, each finished test is kept there as
    it finishes, and a pack interrupted (KeyboardInterrupt) is resumed by the same call: the tests kept are not run
    again (docs/verification.md). progress: a line on stderr per test (tests done, failed, timed out, elapsed); None:
    rewritten in place on a terminal, else a line per test that failed or timed out. Only user mistakes (options,
    FMU, map, results folder) raise InputError; a test or manoeuvre that fails is a result."""
    from . import verify as vehicle_pack  # matplotlib for its report: loaded only to verify
    from .verify.datasheet import datasheet, provenance

    if pack not in PACKS:
        raise option_error("pack", pack, f"must be one of {', '.join(PACKS)}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 0):
        raise option_error("workers", workers, "must be a whole number >= 0")
    if pack == "vehicle":
        known = list(vehicle_pack.MANOEUVRES)
        if controller is not None or controller_map is not None:
            raise option_error("controller", controller or controller_map,
                               "applies to the aeb-ccr pack (the vehicle pack drives the vehicle alone)")
        if test_timeout is not None:
            raise option_error("test_timeout", test_timeout, "applies to the aeb-ccr pack")
    else:
        from .verify import aeb

        known = list(aeb.GROUPS)
        test_timeout = (DEFAULT_TEST_TIMEOUT if test_timeout is None
                        else checked_option("test_timeout", test_timeout, low_open=True))
    names = known if only is None else list(only)
    unknown = [name for name in names if name not in known]
    if unknown or not names:
        what = "manoeuvres" if pack == "vehicle" else "test groups"
        raise option_error("only", ",".join(names), f"must name {what} among {', '.join(known)}")
    model = ego_model(dynamics, fmu, vehicle)
    tuned = model.with_parameters(params)  # checked by the model; the vehicle the pack drives
    params = dict(tuned.overrides)
    try:  # an FMU that cannot even be instantiated is a bad --fmu, not a manoeuvre's result
        tuned.instantiate(start={"speed": 0.0, "x": 0.0, "y": 0.0, "yaw": 0.0}, instance_name="probe").close()
    except Exception as error:  # noqa: BLE001 - fmpy reports a binary that cannot be loaded as a plain Exception
        raise InputError("fmu", f"the FMU {model.fmu_path} cannot be instantiated: {_first_line(error)}") from None
    if out is not None:
        try:
            check_results_folder(out, "verify")
        except ResultsFolderError as error:
            raise InputError("out", "", subject=str(error)) from None
    # the files by name: no machine's path in results (docs/results.md)
    identity = {"name": model.name, "fmu": model.fmu_path.name, "guid": model.guid, "fmi_version": model.fmi_version,
                "map": None if model.map_path is None else Path(model.map_path).name,
                "friction": None if model.friction is None else model.friction.meaning}
    sheet, tool = datasheet(model, params), provenance()
    try:
        if pack == "vehicle":
            outcomes = vehicle_pack.run_pack(tuned, names)
            folder = None if out is None else vehicle_pack.write(out, identity, outcomes, sheet, tool)
            return VerifyResult(identity, outcomes, vehicle_pack.table(outcomes), folder,
                                vehicle_pack.passed(outcomes), pack)
        controller = controller_model(controller, controller_map)  # checked before anything runs
        options = {"dynamics": dynamics if vehicle is None else None, "fmu": str(model.fmu_path),
                   "vehicle": None if vehicle is None else str(Path(vehicle).absolute()), "params": params,
                   "controller": None if controller is None else str(controller.fmu_path.absolute()),
                   "controller_map": None if controller is None else str(Path(controller.map_path).absolute())}
        options = {key: value for key, value in options.items() if value}
        outcomes = _aeb_grid(aeb, aeb.grid(names), options, (tuned.length, tuned.width), out, workers, scheduler,
                             test_timeout, progress)
        folder = None if out is None else aeb.write(out, outcomes, identity, sheet, _controller_identity(controller),
                                                    tool)
        return VerifyResult(identity, outcomes, aeb.table(outcomes), folder, aeb.passed(outcomes), pack)
    except ResultsFolderError as error:
        raise InputError("out", "", subject=str(error)) from None


def _aeb_grid(aeb, tests: list, options: dict, footprint, out, workers, scheduler, timeout: float,
              progress: bool | None) -> list:
    """The AEB pack's outcomes in the grid's order: those kept in `out`'s journal by an interrupted pack of the same
    identity, and the rest run (each kept there as it finishes)."""
    from .verify.aeb import kept

    pack = None if out is None else kept.identity(options, __version__)
    done = {} if out is None else {kept.key(o.test): o for o in kept.finished(out, tests, pack, timeout)}
    todo = [test for test in tests if kept.key(test) not in done]
    live = progress is None and sys.stderr.isatty()
    shown = aeb.Progress(len(tests), list(done.values()), every=bool(progress) or live, live=live,
                         stream=unescaped(sys.stderr) if live else None)
    record = None if out is None else kept.Recorder(Path(out), pack, timeout)

    def finished(outcome) -> None:
        if record is not None:
            record(outcome)
        if progress is not False:
            shown(outcome)

    try:
        ran = aeb.run_grid(todo, options, run, footprint, workers=workers, scheduler=scheduler, timeout=timeout,
                           progress=finished)
    except ClusterError as error:
        raise InputError("workers" if scheduler is None else "scheduler", str(error)) from None
    finally:
        if record is not None:
            record.close()
        shown.close()
    done.update((kept.key(outcome.test), outcome) for outcome in ran)
    return [done[kept.key(test)] for test in tests]


def _controller_identity(controller) -> dict | None:
    """What the AEB report says of the controller (a ControllerModel): its FMU's identity, its map, period and
    parameters."""
    if controller is None:
        return None
    from .verify.datasheet import fmu_identity

    return {**fmu_identity(controller.fmu_path, controller.description, controller.map_path, controller.name),
            "period_s": controller.period, "parameters": dict(controller.parameters)}


# --- the scenario as a co-simulation unit ------------------------------------------------------------------


@dataclass
class Export:
    """What `export` wrote (docs/export.md): the export folder, the SSP, the FMUs beside it (by component), the
    system's stop time and step (s), the parameter set's name and values (by component), and `reference`, the
    `sdl-fmu run` of the same options whose end gives the stop time."""

    folder: Path
    ssp: Path
    fmus: dict[str, Path]
    stop_time: float
    step: float
    fmi_version: int
    parameter_set: str
    parameters: dict[str, dict[str, float | int | bool]]
    reference: Result
    warnings: list[str]


DEFAULT_EXPORT_STEP = 0.01  # s, the exported system's communication step (the OSP annotation)


STOP_MARGIN = (1.0, 0.01)  # s and a share of the end: how far past `run`'s end an exported system's stop time lies


def _stop_time(reference: Result, step: float, until_time: float | None) -> float:
    """The exported system's stop time, on the step grid: `until_time` and one step (a master whose clock is a
    running sum of steps arrives a hair before a time on the grid), else the end of `sdl-fmu run` of the same options
    plus one second or one per cent of it, whichever is more: a master's ego runs a little behind run's (it gets each
    command a step later: docs/export.md), so its end comes later than run's (0.04 s in the demo); past the end
    nothing fires."""
    if until_time is not None:
        steps = math.ceil(until_time / step - 1e-9) + 1
    else:
        end = float(reference.final["time_s"])
        steps = math.ceil((end + max(STOP_MARGIN[0], STOP_MARGIN[1] * end)) / step - 1e-9)
    return float(f"{steps * step:.15g}")  # 2.01, not 2.0100000000000002: the product's last bits are noise


@contextlib.contextmanager
def _scenario_fmu(scenario: Scenario, name: str, model, **options):
    """The scenario FMU of these options (docs/export.md), written into a temporary folder as <name>.fmu."""
    from .export.scenario_fmu import ScenarioFmuError, write_scenario_fmu  # the build side: its writer and runtime

    with tempfile.TemporaryDirectory(prefix="sdl-fmu-export-") as folder:
        try:
            unit = write_scenario_fmu(scenario, Path(folder) / f"{name}.fmu", ego=model, **options)
        except ScenarioFmuError as error:
            raise InputError(None, f"the scenario FMU cannot be written: {error}") from None
        yield unit


def _export_name(scenario: Scenario) -> str:
    """What an export of the scenario names its files after (`<name>.ssp`, `<name>.fmu`; docs/export.md, Names): its
    file name's stem as a safe identifier. InputError (one line naming the file) when it cannot be made safe."""
    path = Path(scenario.path)
    try:
        return safe_identifier(path.stem)
    except UnsafeName as error:
        raise InputError("scenario", f"{path}: an export names its files after the scenario's file name, and this "
                                     f"one cannot name a file: {error}; rename the file") from None


def export(scenario: str | os.PathLike | Scenario, *, out: str | os.PathLike, dynamics: Dynamics | None = None,
           fmu: str | os.PathLike | None = None, vehicle: str | os.PathLike | None = None,
           speed: float | None = None, seed: int = 1, until_distance: float | None = None,
           until_time: float | None = None, step: float | None = None, fmi_version: int = 2,
           skip_unsupported: bool = False, controller: str | os.PathLike | None = None,
           controller_map: str | os.PathLike | None = None, driver: str = "lane",
           on_collision: str = "continue") -> Export:
    """Writes the scenario as a co-simulation unit into the export folder `out` (docs/export.md): `<scenario>.ssp`,
    an SSP 1.0 system of the scenario FMU and the ego FMU connected through the vehicle map, and the FMUs beside it.

    The options mean what `run`'s do (speed and until_distance in the scenario's units; until_distance and
    until_time exclusive); step is the system's communication step (s, default 0.01); fmi_version (2 or 3) that of
    the scenario FMU and of a shipped ego (a user's FMU goes in as it is). controller and controller_map: a
    controller between the scenario and the ego (docs/controllers.md), a third component of the system; driver
    ("lane" or "follow") and on_collision ("continue" or "stop") as run's. `out` is a
    new or empty folder or an earlier export folder. Raises InputError or ScenarioError for user mistakes; nothing is
    written then."""
    step = DEFAULT_EXPORT_STEP if step is None else checked_option("step", step)
    if isinstance(fmi_version, bool) or fmi_version not in (2, 3):
        raise option_error("fmi_version", fmi_version, "must be 2 or 3")
    if until_time is not None and until_distance is not None:
        raise option_error("until_time", until_time, "give until_distance or until_time, not both")
    vehicle_map = _vehicle_map(dynamics, vehicle)
    scenario = _checked(scenario, vehicle_map, skip_unsupported)
    name = _export_name(scenario)
    options = run_options(scenario, speed=speed, seed=seed, until_distance=until_distance, until_time=until_time,
                          driver=driver, on_collision=on_collision)
    in_the_loop = controller_model(controller, controller_map)
    try:
        check_export_folder(out)
    except ResultsFolderError as error:
        raise InputError("out", "", subject=str(error)) from None
    model = ego_model(dynamics, fmu, vehicle_map if vehicle is not None else None, fmi_version).with_tires(None)
    for option, part in (("fmu", model), ("controller", in_the_loop)):  # the FMUs' names in the SSP, made safe
        try:
            if part is not None:
                fmu_file_name(part.fmu_path, f"--{option} {part.fmu_path}")
        except ExportError as error:
            raise InputError(option, str(error)) from None
    # what a run of this scenario with this vehicle warns of (`sdl-fmu check`'s warnings): the scenario FMU does the same
    warnings = [*scenario.warnings, *model.warnings,
                *vehicle_warnings(scenario, model.name, model.surface_meaning, model.brk_acts, model.known_attributes)]
    if model.fmi_version != f"{fmi_version}.0":
        warnings.append(f"the ego FMU {model.fmu_path.name} is FMI {model.fmi_version} and the scenario FMU FMI "
                        f"{fmi_version}.0: " + ("libcosim and fmpy's simulate_ssp load FMI 2.0 FMUs only"
                                                if model.fmi_version == "3.0" else "only ecos runs FMI 3.0"))
    if in_the_loop is not None and abs(in_the_loop.period - step) > 1e-12 * step:
        warnings.append(f"the controller {in_the_loop.name} is stepped at the system's step {step:g} s, not at its "
                        f"map's period {in_the_loop.period:g} s: an SSP master steps every FMU on one grid")
    start = {"speed": DEFAULT_SPEED if options.speed is None else options.speed, "x": 0.0,
             "y": -scenario.road.lane_center(1), "yaw": 0.0}  # where run starts the ego (cosim/master.py)
    arbitration = None if in_the_loop is None else dict(in_the_loop.rules)
    with _scenario_fmu(scenario, name, model, fmi_version=fmi_version, speed=options.speed, seed=options.seed,
                       until_distance=options.until_distance, until_time=options.until_time, step=step,
                       arbitration=arbitration, driver=options.driver, on_collision=options.on_collision) as unit:
        description = read_model_description(str(unit.path), validate=False)

        def system_until(stop_time: float):
            try:
                return build_system(name, unit.path, description, model, start=start,
                                    scenario_parameters=unit.parameters, stop_time=stop_time, step=step,
                                    description=f"the SDL scenario {Path(scenario.path).name} and the ego vehicle "
                                                f"{model.name}, exported by sdl-fmu",
                                    generation_tool=f"sdl-fmu {__version__}", controller=in_the_loop)
            except ExportError as error:
                text = str(error)
                option = "controller_map" if in_the_loop is not None and text.startswith(
                    (in_the_loop.map.label, "--controller")) else "vehicle" if vehicle is not None else "fmu"
                raise InputError(option, text) from None

        system_until(step)  # every connection checked before anything runs
        # the reference run: `sdl-fmu run` of the same options; its end gives the system's stop time
        reference = run(scenario, dynamics=dynamics, fmu=model.fmu_path, vehicle=vehicle, speed=speed, seed=seed,
                        until_distance=until_distance, until_time=until_time, plot=False,
                        controller=None if in_the_loop is None else in_the_loop.fmu_path,
                        controller_map=None if in_the_loop is None else in_the_loop.map_path, driver=driver,
                        on_collision=on_collision)
        stop_time = _stop_time(reference, step, options.until_time)
        system = system_until(stop_time)
        try:
            folder = write_export(out, f"{name}.ssp", system)
        except ResultsFolderError as error:
            raise InputError("out", "", subject=str(error)) from None
    fmus = {c.name: folder / c.source.split("/", 1)[1] for c in system.components}
    parameters = {c.name: {p.name: p.value for p in c.parameters} for c in system.components}
    return Export(folder, folder / f"{name}.ssp", fmus, stop_time, step, fmi_version, system.parameter_set,
                  parameters, reference, warnings)
