"""The vehicle map (docs/vehicle-maps.md): a TOML file telling sdl-fmu how to drive a vehicle FMU, read with tomllib and
checked for its shape here (against the FMU in model.py). Every mistake is one VehicleMapError line naming the
file and the key, or the option (`vehicle`, `fmu`) and its value."""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from ..names import Dynamics, shipped_map_path  # noqa: F401 (re-exported by vehicle/: the shipped maps)
from ..options import InputError

FrictionMeaning = Literal["mu", "attribute"]

INPUTS = ("throttle", "brake", "steer")  # required; `friction` is optional
OUTPUTS_REQUIRED = ("x", "y", "yaw", "speed")
OUTPUTS_OPTIONAL = ("distance", "vx", "vy", "yaw_rate", "ax", "ay", "stopped")
STARTS = ("speed", "x", "y", "yaw")
# [vehicle]: SI numbers, or { parameter = "name" } for an FMU parameter's value in this run
VEHICLE_GEOMETRY = ("length", "width", "wheelbase", "track", "cg_to_front_axle", "cg_to_rear_axle", "track_front",
                    "track_rear")
VEHICLE_NUMBERS = (*VEHICLE_GEOMETRY, "mass", "drive_accel_max", "drive_power_max", "drive_torque_max", "wheel_radius",
                   "brake_decel_max", "rolling_resistance", "drag_area", "air_density", "peak_friction",
                   "max_acceleration", "max_yaw_rate")
VEHICLE_FLAGS = ("brk_acts", "spec_closed_forms")
# the range of each [vehicle] value, SI: (low, high, whether low itself is allowed); a number in the map or an FMU
# parameter's value outside it is refused (docs/vehicle-maps.md). Generous for any road vehicle, and far from where
# the driver model's and the trigger bounds' arithmetic (divisions by mass, wheelbase, radius; squares) breaks.
VEHICLE_RANGES = {
    "length": (0.0, 100.0, False), "width": (0.0, 20.0, False), "wheelbase": (0.0, 50.0, False),
    "track": (0.0, 20.0, False), "track_front": (0.0, 20.0, False), "track_rear": (0.0, 20.0, False),
    "cg_to_front_axle": (0.0, 50.0, True), "cg_to_rear_axle": (0.0, 50.0, True),
    "mass": (0.0, 1e6, False), "drive_accel_max": (0.0, 100.0, True), "drive_power_max": (0.0, 1e8, True),
    "drive_torque_max": (0.0, 1e6, False), "wheel_radius": (0.0, 10.0, False),
    "brake_decel_max": (0.0, 100.0, False), "rolling_resistance": (0.0, 1.0, True), "drag_area": (0.0, 100.0, True),
    "air_density": (0.0, 100.0, True), "peak_friction": (0.0, 10.0, False), "max_acceleration": (0.0, 1e4, False),
    "max_yaw_rate": (0.0, 1e3, False)}
SCALE_RANGE = (1e-6, 1e6)  # |scale| of a channel or the friction input
MAX_OFFSET = 1e6  # |offset|
MAX_MAP_BYTES = 1 << 20  # a map is a small text
TOP_LEVEL = ("name", "fmu", "inputs", "outputs", "start", "parameters", "vehicle")


class VehicleMapError(InputError):
    """A vehicle map (or the FMU it names, or a value set on it) that cannot drive a run: one line, its `option` the
    keyword it came through (`vehicle`, `fmu`, `params`, `tires`, `dynamics`); either a message naming the map file and
    the key, or (`subject`) the option's value and the reason, which the API and the command line word their way
    (api.InputError)."""

    @classmethod
    def of(cls, option: str, value, reason: str) -> VehicleMapError:
        """`option value: reason`."""
        return cls(option, "", subject=f"{value}: {reason}")


def declared_range_problem(variable, value: float) -> str | None:
    """Why `value` is outside the FMU variable's declared min/max, or None (no declaration: no limit)."""
    unit = f" {variable.unit}" if getattr(variable, "unit", None) and variable.unit != "1" else ""
    for bound, relation, outside in (("min", "minimum", lambda v, b: v < b), ("max", "maximum", lambda v, b: v > b)):
        declared = getattr(variable, bound, None)
        try:
            limit = None if declared is None else float(declared)
        except (TypeError, ValueError):
            continue
        if limit is not None and outside(value, limit):
            return f"{value!r} is {'below' if bound == 'min' else 'above'} the FMU's declared {relation} {limit:g}{unit}"
    return None


def vehicle_value_problem(key: str, value: float) -> str | None:
    """Why a [vehicle] value is outside its range (VEHICLE_RANGES), or None."""
    low, high, low_allowed = VEHICLE_RANGES[key]
    if not math.isfinite(value) or value > high or value < low or (value == low and not low_allowed):
        relation = ">=" if low_allowed else ">"
        return f"{value!r} is outside its range: {relation} {low:g} and <= {high:g} (SI)"
    return None


@dataclass(frozen=True)
class Channel:
    """One map entry: an FMU variable and the linear map between sdl-fmu's quantity and it."""

    key: str  # e.g. "inputs.steer"
    variable: str
    scale: float = 1.0
    offset: float = 0.0
    unit: str | None = None


@dataclass(frozen=True)
class FrictionEntry:
    key: str
    variables: tuple[str, ...]
    meaning: FrictionMeaning
    scale: float = 1.0
    offset: float = 0.0
    tire_slots: str | None = None  # e.g. "tire{slot}_": the FMU takes Magic Formula tire slots (`tires` fills them)


@dataclass(frozen=True)
class VehicleMap:
    path: Path | None  # None: built in memory
    name: str | None
    fmu: Path | None  # resolved against the map's folder
    inputs: dict[str, Channel]
    friction: FrictionEntry | None
    outputs: dict[str, Channel]
    start: dict[str, Channel]
    parameters: dict[str, float]
    vehicle: dict[str, float | str]  # a number (SI), or the name of an FMU parameter
    flags: dict[str, bool] = field(default_factory=dict)

    @property
    def label(self) -> str:
        return str(self.path) if self.path is not None else "<vehicle map>"


def load_vehicle_map(path: str | Path) -> VehicleMap:
    """Reads and checks a vehicle map's shape (not yet against an FMU)."""
    path = Path(path)
    return parse_vehicle_map(read_map_file(path, VehicleMapError, "vehicle", "vehicle map"), path)


def read_map_file(path: Path, error: type[VehicleMapError], option: str, what: str) -> dict:
    """A map file's TOML (a vehicle map, a controller map): at most MAX_MAP_BYTES; every way it can fail is one
    `error` for `option` naming the file."""
    try:
        with open(path, "rb") as file:
            raw = file.read(MAX_MAP_BYTES + 1)
        if len(raw) > MAX_MAP_BYTES:
            raise error.of(option, path, f"larger than {MAX_MAP_BYTES // 1024} KB; a {what} is a small text")
        return tomllib.loads(raw.decode("utf-8"))
    except RecursionError:  # tomllib reads nested arrays and tables recursively; a map nests three deep
        raise error(option, f"{path}: not TOML sdl-fmu reads (nested too deeply)") from None
    except FileNotFoundError:
        raise error.of(option, path, "no such file") from None
    except IsADirectoryError:
        raise error.of(option, path, "is a folder, not a file") from None
    except UnicodeDecodeError:
        raise error(option, f"{path}: not TOML (not UTF-8 text)") from None
    except tomllib.TOMLDecodeError as err:
        raise error(option, f"{path}: not TOML: {err}") from None
    except OSError as err:
        raise error.of(option, path, f"cannot be read ({err.strerror})") from None


class MapFields:
    """The checks every map's reader makes of its TOML (a vehicle map, a controller map), each failure one `error`
    for `option` naming the map and the key: the top-level keys known, tables, finite numbers, non-empty strings."""

    def __init__(self, data: dict, label: str, error: type[VehicleMapError], option: str, top_level, what: str):
        self.data, self.label, self.error, self.option = data, label, error, option
        for key in data:
            if key not in top_level:
                self.fail(key, f"unknown key (a {what} has {', '.join(top_level)})")

    def fail(self, key: str, reason: str):
        raise self.error(self.option, f"{self.label}: {key}: {reason}")

    def table(self, key: str, required: bool) -> dict:
        value = self.data.get(key)
        if value is None:
            if required:
                self.fail(f"[{key}]", "missing")
            return {}
        if not isinstance(value, dict):
            self.fail(key, "must be a table")
        return value

    def number(self, key: str, value) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            self.fail(key, f"{value!r} must be a finite number")
        return float(value)

    def scale(self, key: str, value) -> float:
        """A channel's scale: a finite number, SCALE_RANGE[0] <= |scale| <= SCALE_RANGE[1]."""
        value = self.number(key, value)
        if not SCALE_RANGE[0] <= abs(value) <= SCALE_RANGE[1]:
            self.fail(key, f"{value!r} is outside its range: {SCALE_RANGE[0]:g} <= |scale| <= {SCALE_RANGE[1]:g}")
        return value

    def offset(self, key: str, value) -> float:
        """A channel's offset: a finite number, |offset| <= MAX_OFFSET."""
        value = self.number(key, value)
        if abs(value) > MAX_OFFSET:
            self.fail(key, f"{value!r} is outside its range: |offset| <= {MAX_OFFSET:g}")
        return value

    def text(self, key: str, value) -> str:
        if not isinstance(value, str) or not value:
            self.fail(key, f"{value!r} must be a non-empty string")
        return value

    def one_writer(self, writers, what: str) -> None:
        """Each FMU variable the map writes (an input sent, a start value set) is written by one key: two keys on one
        variable (a many-to-one wiring) is one line naming both. writers: (key, variable name) in the file's order."""
        first: dict[str, str] = {}
        for key, variable in writers:
            if variable in first:
                self.fail(key, f"{variable!r} is also {first[variable]}'s variable: one {what} cannot take two "
                               "values (map each to a variable of its own)")
            first[variable] = key


def parse_vehicle_map(data: dict, path: Path | None = None, complete: bool = True) -> VehicleMap:
    """complete=False: a map without wheel geometry (an FMU stepped on its own, not driven through a scenario)."""
    label = str(path) if path is not None else "<vehicle map>"
    fields = MapFields(data, label, VehicleMapError, "vehicle", TOP_LEVEL, "vehicle map")
    fail, table, number, text = fields.fail, fields.table, fields.number, fields.text
    scale, offset = fields.scale, fields.offset

    def channel(section: str, name: str, entry, allowed=("variable", "scale", "offset", "unit")) -> Channel:
        key = f"{section}.{name}"
        if not isinstance(entry, dict):
            fail(key, 'must be a table such as { variable = "name" }')
        for field_name in entry:
            if field_name not in allowed:
                fail(f"{key}.{field_name}", f"unknown key (allowed: {', '.join(allowed)})")
        if "variable" not in entry:
            fail(f"{key}.variable", "missing")
        return Channel(key, text(f"{key}.variable", entry["variable"]),
                       scale(f"{key}.scale", entry.get("scale", 1.0)), offset(f"{key}.offset", entry.get("offset", 0.0)),
                       None if entry.get("unit") is None else text(f"{key}.unit", entry["unit"]))

    name = None if data.get("name") is None else text("name", data["name"])
    fmu = None
    if data.get("fmu") is not None:
        fmu = Path(text("fmu", data["fmu"]))
        if not fmu.is_absolute() and path is not None:
            fmu = path.parent / fmu

    inputs_table = table("inputs", True)
    inputs, friction = {}, None
    for key in inputs_table:
        if key not in (*INPUTS, "friction"):
            fail(f"inputs.{key}", f"unknown input (inputs: {', '.join(INPUTS)}, friction)")
    for key in INPUTS:
        if key not in inputs_table:
            fail(f"inputs.{key}", "missing (throttle, brake and steer are required)")
        inputs[key] = channel("inputs", key, inputs_table[key])
    if "friction" in inputs_table:
        entry = inputs_table["friction"]
        key = "inputs.friction"
        if not isinstance(entry, dict):
            fail(key, 'must be a table such as { variables = ["mu_fl", ...], meaning = "mu" }')
        allowed = ("variables", "variable", "meaning", "scale", "offset", "tire_slots")
        for field_name in entry:
            if field_name not in allowed:
                fail(f"{key}.{field_name}", f"unknown key (allowed: {', '.join(allowed)})")
        if ("variables" in entry) == ("variable" in entry):
            fail(f"{key}.variables", "give variables = [...] (1, 2 or 4 names) or variable = \"name\"")
        names = entry["variables"] if "variables" in entry else [entry["variable"]]
        if not isinstance(names, list) or len(names) not in (1, 2, 4):
            fail(f"{key}.variables", "must list 1 (the car), 2 (front, rear axle) or 4 (fl, fr, rl, rr) variables")
        names = tuple(text(f"{key}.variables", n) for n in names)
        meaning = entry.get("meaning")
        if meaning not in ("mu", "attribute"):
            fail(f"{key}.meaning", f"{meaning!r} must be \"mu\" (RSA value / 10) or \"attribute\" (attribute number)")
        slots = entry.get("tire_slots")
        friction = FrictionEntry(key, names, meaning, scale(f"{key}.scale", entry.get("scale", 1.0)),
                                 offset(f"{key}.offset", entry.get("offset", 0.0)),
                                 None if slots is None else text(f"{key}.tire_slots", slots))
        if friction.tire_slots is not None and "{slot}" not in friction.tire_slots:
            fail(f"{key}.tire_slots", "must contain {slot}, e.g. \"tire{slot}_\"")

    outputs_table = table("outputs", True)
    outputs = {}
    for key, entry in outputs_table.items():
        if key not in (*OUTPUTS_REQUIRED, *OUTPUTS_OPTIONAL):
            fail(f"outputs.{key}", f"unknown output (outputs: {', '.join((*OUTPUTS_REQUIRED, *OUTPUTS_OPTIONAL))})")
        outputs[key] = channel("outputs", key, entry)
    for key in OUTPUTS_REQUIRED:
        if key not in outputs:
            fail(f"outputs.{key}", "missing (x, y, yaw and speed are required)")

    start = {}
    for key, entry in table("start", False).items():
        if key not in STARTS:
            fail(f"start.{key}", f"unknown start quantity (start: {', '.join(STARTS)})")
        start[key] = channel("start", key, entry)

    parameters = {str(k): number(f"parameters.{k}", v) for k, v in table("parameters", False).items()}
    fields.one_writer([*((c.key, c.variable) for c in inputs.values()),
                       *(() if friction is None else ((f"{friction.key}.variables[{i}]", n)
                                                     for i, n in enumerate(friction.variables))),
                       *((c.key, c.variable) for c in start.values()),
                       *((f"parameters.{name}", name) for name in parameters)], "FMU variable")

    vehicle, flags = {}, {}
    for key, value in table("vehicle", False).items():
        if key in VEHICLE_FLAGS:
            if not isinstance(value, bool):
                fail(f"vehicle.{key}", f"{value!r} must be true or false")
            flags[key] = value
        elif key in VEHICLE_NUMBERS:
            if isinstance(value, dict):
                if set(value) != {"parameter"}:
                    fail(f"vehicle.{key}", 'must be a number (SI) or { parameter = "name" }')
                vehicle[key] = text(f"vehicle.{key}.parameter", value["parameter"])
            else:
                vehicle[key] = number(f"vehicle.{key}", value)
                problem = vehicle_value_problem(key, vehicle[key])
                if problem:
                    fail(f"vehicle.{key}", problem)
        else:
            fail(f"vehicle.{key}", f"unknown key (vehicle: {', '.join((*VEHICLE_NUMBERS, *VEHICLE_FLAGS))})")
    for key in ("length", "width"):
        if key not in vehicle:
            fail(f"vehicle.{key}", "missing (the footprint: length and width, m)")
    if complete and "wheelbase" not in vehicle and not {"cg_to_front_axle", "cg_to_rear_axle"} <= set(vehicle):
        fail("vehicle.wheelbase", "missing (or give cg_to_front_axle and cg_to_rear_axle)")
    if complete and "track" not in vehicle and not {"track_front", "track_rear"} <= set(vehicle):
        fail("vehicle.track", "missing (or give track_front and track_rear)")
    if "drive_torque_max" in vehicle and "drive_accel_max" not in vehicle and "wheel_radius" not in vehicle:
        fail("vehicle.wheel_radius", "missing (drive_torque_max is a wheel torque: the drive is torque / (mass x "
                                     "wheel_radius); or give drive_accel_max)")
    for first, second in (("cg_to_front_axle", "cg_to_rear_axle"),):
        if all(isinstance(vehicle.get(k), float) for k in (first, second)) and vehicle[first] + vehicle[second] <= 0:
            fail(f"vehicle.{second}", f"{first} + {second} must be > 0 (the wheelbase)")
    if ("max_acceleration" in vehicle) != ("max_yaw_rate" in vehicle):
        fail("vehicle.max_yaw_rate" if "max_acceleration" in vehicle else "vehicle.max_acceleration",
             "give both bounds (max_acceleration, m/s2, and max_yaw_rate, rad/s) or neither")
    return VehicleMap(path, name, fmu, inputs, friction, outputs, start, parameters, vehicle, flags)
