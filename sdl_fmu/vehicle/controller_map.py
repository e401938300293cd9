"""The controller map (docs/controllers.md): a TOML file telling sdl-fmu how to put a controller FMU between the
scenario and the ego, shaped like the vehicle map (keys are added, never renamed). Read with tomllib and checked for
its shape here (against the FMU in controller.py). Every mistake is one ControllerMapError line naming the file and
the key.

    fmu = "MyAeb.fmu"          # optional, relative to this file
    period = 0.01              # s, how often the controller is stepped
    [inputs]                   # signal names (SIGNALS) -> controller inputs
    [outputs]                  # controller outputs -> requests (REQUESTS)
    [arbitration]              # per channel (CHANNELS): "driver", "override" or "max" (RULES)
    [parameters]               # controller start values, set as given
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from .vehicle_map import Channel, MapFields, VehicleMapError, read_map_file

# What a signal or a request is: an SI unit (a map's `unit` and the FMU's declared unit convert from it through
# pint), "pedal" (a number, 0..1: scale and offset only, as the vehicle map's pedals), "boolean" or "integer"
# (sent or read as they are: `variable` only)
Kind = Literal["m", "m/s", "rad", "rad/s", "m/s**2", "s", "pedal", "boolean", "integer"]

# The signals a controller may read (the scenario FMU's variable names, docs/controllers.md): the ego's state (road
# frame, SI: x along the road from the ego's start, y positive left of the dividing line), the lead-vehicle signals
# (cosim/signals.py), the built-in driver's commands before arbitration (BRK's pedal while a BRK event holds them),
# and the counts of collisions and events so far.
SIGNALS: dict[str, Kind] = {
    "ego_x": "m", "ego_y": "m", "ego_psi": "rad", "ego_v": "m/s", "ego_s": "m", "ego_yaw_rate": "rad/s",
    "ego_ax": "m/s**2",
    "lead_present": "boolean", "lead_id": "integer", "lead_gap": "m", "lead_speed": "m/s",
    "lead_relative_speed": "m/s", "lead_ttc": "s", "lead_lateral_offset": "m",
    "driver_throttle": "pedal", "driver_brake": "pedal", "driver_steer": "rad",
    "collisions": "integer", "events": "integer",
}
# What a controller may request: `active` (true: its requests count; without it the controller is always active),
# pedals 0..1, the road-wheel steer angle (rad, positive left) and a deceleration (m/s2, positive braking), which
# the vehicle turns into brake pedal (brake_decel_max).
REQUESTS: dict[str, Kind] = {"active": "boolean", "throttle": "pedal", "brake": "pedal", "steer": "rad",
                             "deceleration": "m/s**2"}
Rule = Literal["driver", "override", "max"]
RULES: tuple[Rule, ...] = ("driver", "override", "max")
CHANNELS = ("throttle", "brake", "steer")  # the ego's commands the arbitration decides
# a mapped channel without an [arbitration] entry: the brake at least the driver's, throttle and steer the
# controller's while it is active; a channel the controller does not request: the driver's
DEFAULT_RULES: dict[str, Rule] = {"throttle": "override", "brake": "max", "steer": "override"}
PERIOD_RANGE = (1e-3, 1.0)  # s, as the driver model's period
TOP_LEVEL = ("name", "fmu", "period", "inputs", "outputs", "arbitration", "parameters")


class ControllerMapError(VehicleMapError):
    """A controller map (or the FMU it names) that cannot run: one line naming the file and the key (option
    `controller_map`), or the option (`controller_map`, `controller`) and its value (VehicleMapError)."""


@dataclass(frozen=True)
class ControllerMap:
    path: Path | None  # None: built in memory
    name: str | None
    fmu: Path | None  # resolved against the map's folder
    period: float  # s
    inputs: dict[str, Channel]  # signal name -> controller input
    outputs: dict[str, Channel]  # request name -> controller output
    rules: dict[str, Rule]  # every channel of CHANNELS -> its rule (defaults filled in)
    parameters: dict[str, float | bool]

    @property
    def label(self) -> str:
        return str(self.path) if self.path is not None else "<controller map>"

    def requested(self, channel: str) -> bool:
        """Whether the controller requests this channel (the brake also through a deceleration)."""
        return channel in self.outputs or (channel == "brake" and "deceleration" in self.outputs)


def load_controller_map(path: str | Path) -> ControllerMap:
    """Reads and checks a controller map's shape (not yet against an FMU)."""
    path = Path(path)
    return parse_controller_map(read_map_file(path, ControllerMapError, "controller_map", "controller map"), path)


def parse_controller_map(data: dict, path: Path | None = None) -> ControllerMap:
    label = str(path) if path is not None else "<controller map>"
    fields = MapFields(data, label, ControllerMapError, "controller_map", TOP_LEVEL, "controller map")
    fail, table, number, text = fields.fail, fields.table, fields.number, fields.text

    def channel(section: str, name: str, entry, kind: Kind) -> Channel:
        key = f"{section}.{name}"
        if kind in ("boolean", "integer"):
            allowed, what = ("variable",), f"{name} is a {kind}: only variable"
        elif kind == "pedal":
            allowed, what = ("variable", "scale", "offset"), ("a pedal is a number (0..1): variable, scale and "
                                                              "offset (a value in % has scale = 0.01)")
        else:
            allowed, what = ("variable", "scale", "offset", "unit"), "allowed: variable, scale, offset, unit"
        if not isinstance(entry, dict):
            fail(key, 'must be a table such as { variable = "name" }')
        for field_name in entry:
            if field_name not in allowed:
                fail(f"{key}.{field_name}", f"unknown key ({what})")
        if "variable" not in entry:
            fail(f"{key}.variable", "missing")
        return Channel(key, text(f"{key}.variable", entry["variable"]),
                       fields.scale(f"{key}.scale", entry.get("scale", 1.0)),
                       fields.offset(f"{key}.offset", entry.get("offset", 0.0)),
                       None if entry.get("unit") is None else text(f"{key}.unit", entry["unit"]))

    name = None if data.get("name") is None else text("name", data["name"])
    fmu = None
    if data.get("fmu") is not None:
        fmu = Path(text("fmu", data["fmu"]))
        if not fmu.is_absolute() and path is not None:
            fmu = path.parent / fmu

    if "period" not in data:
        fail("period", "missing (how often the controller is stepped, s)")
    period = number("period", data["period"])
    low, high = PERIOD_RANGE
    if not low <= period <= high:
        fail("period", f"{period:g} must be >= {low:g} and <= {high:g} s")

    inputs = {}
    for key, entry in table("inputs", False).items():
        if key not in SIGNALS:
            fail(f"inputs.{key}", f"unknown signal (signals: {', '.join(SIGNALS)})")
        inputs[key] = channel("inputs", key, entry, SIGNALS[key])

    outputs = {}
    for key, entry in table("outputs", True).items():
        if key not in REQUESTS:
            fail(f"outputs.{key}", f"unknown request (requests: {', '.join(REQUESTS)})")
        outputs[key] = channel("outputs", key, entry, REQUESTS[key])
    if not set(outputs) - {"active"}:
        fail("[outputs]", "requests nothing (map at least one of throttle, brake, steer, deceleration)")

    controller_map = ControllerMap(path, name, fmu, period, inputs, outputs, {}, {})
    rules: dict[str, Rule] = {}
    given = table("arbitration", False)
    for key in given:
        if key not in CHANNELS:
            fail(f"arbitration.{key}", f"unknown channel (channels: {', '.join(CHANNELS)}; a deceleration is "
                                       "arbitrated as the brake)")
    for key in CHANNELS:
        requested = controller_map.requested(key)
        if key not in given:
            rules[key] = DEFAULT_RULES[key] if requested else "driver"
            continue
        rule = given[key]
        if rule not in RULES:
            fail(f"arbitration.{key}", f"{rule!r} must be one of {', '.join(repr(r) for r in RULES)}")
        if key == "steer" and rule == "max":
            fail("arbitration.steer", "'max' is not defined for a steering angle (use 'driver' or 'override')")
        if rule != "driver" and not requested:
            what = "brake or deceleration" if key == "brake" else key
            fail(f"arbitration.{key}", f"{rule!r}, but [outputs] has no {what} (the controller requests no {key})")
        rules[key] = rule

    parameters = {}
    for key, value in table("parameters", False).items():
        parameters[str(key)] = value if isinstance(value, bool) else number(f"parameters.{key}", value)
    fields.one_writer([*((c.key, c.variable) for c in inputs.values()),
                       *((f"parameters.{name}", name) for name in parameters)], "controller variable")
    return ControllerMap(path, name, fmu, period, inputs, outputs, rules, parameters)
