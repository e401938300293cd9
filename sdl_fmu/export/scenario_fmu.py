"""The scenario FMU of one SDL scenario: the generic binary (built once into the FMU cache, binary.py), the scenario
as data in resources/ (resolve.py), the modelDescription.xml and the documentation (description.py), zipped into
one .fmu (written atomically).

    from sdl_fmu import api
    from sdl_fmu.export.scenario_fmu import write_scenario_fmu

    scenario = api.load("demo")
    fmu = write_scenario_fmu(scenario, "demo-scenario.fmu", ego=api.ego_model("simple"), seed=1)
    fmu.path, fmu.parameters
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..fmu.documentation import LICENSE_ENTRY, license_text
from ..fmu.package import LINUX_BINARY_DIRECTORY, WINDOWS_BINARY_DIRECTORY, FmiVersion, zip_fmu
from ..sdl.events import Scenario
from ..sdl.parser import decode_text, describe
from ..sdl.vehicles import VehicleModel, default_vehicle_table_path, load_vehicle_table
from ..text import printable
from .binary import INTERFACE_FILE, MODEL_IDENTIFIER, binary_key, cached_binaries, compiled_sources, scenario_interface
from .description import documentation, model_description
from .resolve import ARBITRATION, DRIVERS, default_slots, end_distance, parameter_starts, scenario_data

DATA_ENTRY = "resources/scenario.sdlfmu"
TEXT_ENTRY = "resources/scenario.sdl"
DOCUMENTATION_ENTRY = "documentation/index.html"
MAX_SLOTS = 64
# relative (of max(1 s, |t|)): an instant this close after a communication point t belongs to the step that ends at
# t (runtime/scenario.h, TIE_TOLERANCE; docs/scenario-fmu.md, Stepping, ties)
TIE_TOLERANCE = 1e-9


def tie_tolerance(t: float) -> float:
    """How far after the communication point t (s) an instant still shows at t: a driver sample, a trigger's located
    instant (`last_event_time`), an end by time."""
    return TIE_TOLERANCE * max(1.0, abs(t))


class ScenarioFmuError(ValueError):
    """The scenario FMU cannot be written for these inputs (one line naming what)."""


@dataclass(frozen=True)
class ScenarioFmu:
    path: Path
    parameters: dict  # every parameter's start value as written, by name (what an SSP binds to the component)
    guid: str


def sdl_text(scenario: Scenario) -> str:
    """The SDL text the scenario came from, decoded as the parser decodes it (a Scenario made in Python: its
    description)."""
    try:
        return decode_text(Path(scenario.path).read_bytes())[0]
    except Exception:  # noqa: BLE001 - no file (a Scenario built in Python) or unreadable: describe it instead
        return "// made in Python, no SDL text; as sdl-fmu check describes it:\n" + "\n".join(
            f"// {line}" for line in describe(scenario).splitlines())


def _experiment(scenario: Scenario, starts: dict, step: float, until_distance, until_time) -> dict:
    """The DefaultExperiment: until_time, else the time to the run's end distance at the start speed, plus a half."""
    if until_time is not None:
        stop = until_time
    else:
        distance = end_distance(scenario, until_distance, until_time)
        speed = starts["speed"]
        stop = 3600.0 if not math.isfinite(distance) or speed <= 0 else min(3600.0, math.ceil(1.5 * distance / speed))
    return {"startTime": 0.0, "stopTime": float(stop), "stepSize": float(step)}


def _check_starts(interface, starts: dict) -> None:
    for v in interface.variables:
        if v.name not in starts:
            continue
        value = starts[v.name]
        if v.type != "Boolean" and not math.isfinite(float(value)):
            raise ScenarioFmuError(f"{v.name} = {value}: not a finite number")
        if (v.min is not None and value < v.min) or (v.max is not None and value > v.max):
            raise ScenarioFmuError(f"{v.name} = {value:g} is outside the scenario FMU's range [{v.min:g}, {v.max:g}]")


def write_scenario_fmu(scenario: Scenario, out_path: str | os.PathLike, *, ego, fmi_version: FmiVersion = 2,
                       speed: float | None = None, seed: int = 1, until_distance: float | None = None,
                       until_time: float | None = None, driver_period: float | None = None, driver: str = "lane",
                       on_collision: str = "continue", step: float = 0.01, traffic_slots: int | None = None, arbitration: dict[str, str] | None = None,
                       vehicle_table: dict[int, VehicleModel] | None = None) -> ScenarioFmu:
    """Writes the scenario FMU of `scenario` (a loaded Scenario) for the ego vehicle `ego` (an EgoModel) to
    `out_path`. Options in SI as `sdl-fmu run` takes them after conversion (speed m/s, until_distance m,
    until_time s, driver_period s), `driver` "lane" or "follow", `on_collision` "continue" or "stop", `arbitration` the controller map's rules per channel
    ("driver", "override", "max"; a channel the controller does not request: "driver"); `step` is only the
    DefaultExperiment's stepSize. Raises ScenarioFmuError (one
    line) for values the FMU cannot take; building the generic binary the first time raises BuildError without a C
    compiler."""
    if fmi_version not in (2, 3):
        raise ScenarioFmuError(f"fmi_version {fmi_version!r}: choose 2 or 3")
    if driver not in DRIVERS:
        raise ScenarioFmuError(f"driver {driver!r}: choose one of {', '.join(DRIVERS)}")
    if on_collision not in ("continue", "stop"):
        raise ScenarioFmuError(f"on_collision {on_collision!r}: choose continue or stop")
    for channel, rule in (arbitration or {}).items():
        if channel not in ("throttle", "brake", "steer") or rule not in ARBITRATION:
            raise ScenarioFmuError(f"arbitration {channel} = {rule!r}: the channels are throttle, brake, steer and the "
                                   f"rules {', '.join(ARBITRATION)}")
    slots = default_slots(scenario) if traffic_slots is None else int(traffic_slots)
    if not 0 <= slots <= MAX_SLOTS:
        raise ScenarioFmuError(f"traffic_slots {traffic_slots}: must be from 0 to {MAX_SLOTS}")
    table = vehicle_table if vehicle_table is not None else load_vehicle_table(default_vehicle_table_path())
    starts = parameter_starts(scenario, ego, speed=speed, until_distance=until_distance, until_time=until_time,
                              driver_period=driver_period, driver=driver, on_collision=on_collision,
                              arbitration=arbitration)
    interface = scenario_interface(slots, starts)
    _check_starts(interface, starts)
    salt = f"{binary_key(fmi_version)} {INTERFACE_FILE.read_text(encoding='utf-8')} slots {slots}"
    data, guid = scenario_data(scenario, seed, slots, table, starts, salt)
    source = printable(Path(scenario.path).name, keep_lines=False)  # as written, in text XML can hold
    description = (f"The SDL scenario {source} as a co-simulation unit (seed {seed}): traffic, BRK, RSA surfaces, "
                   "the built-in driver, collisions and the run's end of `sdl-fmu run`, driven by the ego's pose and "
                   "speed. Road frame, SI, ISO 8855.")
    binaries = cached_binaries(fmi_version)
    sources = compiled_sources(fmi_version)
    experiment = _experiment(scenario, starts, step, until_distance, until_time)

    out_path = Path(out_path)
    with tempfile.TemporaryDirectory(prefix="sdl-scenario-fmu-") as work:
        root = Path(work) / "fmu"
        shutil.copytree(binaries / "binaries", root / "binaries")
        shutil.copytree(binaries / "sources", root / "sources")
        (root / "resources").mkdir()
        (root / DATA_ENTRY).write_text(data, encoding="utf-8", newline="\n")
        text = sdl_text(scenario)
        (root / TEXT_ENTRY).write_text(text, encoding="utf-8")
        (root / "modelDescription.xml").write_bytes(
            model_description(interface, guid, fmi_version, description, experiment, sources,
                              printable(Path(scenario.path).stem, keep_lines=False)))
        (root / DOCUMENTATION_ENTRY).parent.mkdir(parents=True)
        (root / DOCUMENTATION_ENTRY).write_text(
            documentation(interface, fmi_version, text, source, description, starts, scenario.road.lane_center(1),
                          list(scenario.warnings),
                          LINUX_BINARY_DIRECTORY[fmi_version], WINDOWS_BINARY_DIRECTORY[fmi_version], sources),
            encoding="utf-8")
        (root / LICENSE_ENTRY).parent.mkdir(parents=True)
        (root / LICENSE_ENTRY).write_text(license_text(), encoding="utf-8")
        zip_fmu(root, out_path)  # atomic, and the same scenario and options give the same bytes (no dates)
    return ScenarioFmu(out_path, {name: starts[name] for name in interface.names("parameter")}, guid)


__all__ = ["MODEL_IDENTIFIER", "TIE_TOLERANCE", "ScenarioFmu", "ScenarioFmuError", "tie_tolerance",
           "write_scenario_fmu"]
