"""A scenario resolved for the scenario FMU: the data file resources/scenario.sdlfmu (the scenario's events in SI,
random vehicle models drawn from the seed exactly as `sdl-fmu run` draws them) and the start values of the FMU's
parameters (the run's options, the ego vehicle's properties, the trigger bounds), both from the same objects the run
uses (Scenario, EgoModel), so that one meaning of the scenario reaches the C runtime.

The file's format is described in sdl_fmu/export/runtime/scenario_data.c, which reads it. Real numbers are written
as hexadecimal floats (float.hex()): exact, and read without the C library's locale-dependent parsing.
"""

from __future__ import annotations

import hashlib
import math
import random
import re
import uuid
from pathlib import Path

from ..cosim.driver import MAX_STEER
from ..cosim.master import DEFAULT_DRIVER_PERIOD, DEFAULT_SPEED, RUNOUT
from ..cosim.road import surface_map
from ..cosim.traffic import choose_model
from ..cosim.triggers import ego_bounds
from ..sdl.events import ApproachingVehicle, Brake, EndOfScenario, Scenario, SurfaceAttribute
from ..sdl.vehicles import VehicleModel

FORMAT = 1
DEFAULT_SLOTS = 8  # traffic slots at most, unless asked for (fewer when the scenario has fewer A events)
WHERE = {None: 0, "F": 1, "B": 2}
THRESHOLDS = {"time": 0, "distance": 1, "velocity": 2, "relative_velocity": 3}
ARBITRATION = {"driver": 0, "override": 1, "max": 2}
DRIVERS = {"lane": 1, "follow": 2}
# the vehicle map's optional outputs -> the parameter saying whether the ego input is connected
CONNECTED = {"distance": "ego_s_connected", "vx": "ego_vx_connected", "vy": "ego_vy_connected",
             "yaw_rate": "ego_yaw_rate_connected", "ax": "ego_ax_connected", "ay": "ego_ay_connected",
             "stopped": "ego_stopped_connected"}


def _hex(value: float) -> str:
    return float(value).hex()


def _flag(relative: bool) -> str:
    return "1" if relative else "0"


def _text(value: str, limit: int = 70) -> str:
    """A name as one line of printable ASCII (the data file's names are for log lines; others become '?')."""
    cleaned = re.sub(r"[^\x20-\x7e]", "?", value).replace("#", "?").strip() or "?"
    return cleaned[:limit]


def resolve_models(scenario: Scenario, seed: int) -> list[int]:
    """The model number of each A event, in the order they take effect: Cosimulation.fire_event draws them with
    random.Random(seed) one spawn after another, and every A event spawns in that order."""
    rng = random.Random(seed)
    return [choose_model(event, rng) for event in scenario.events if isinstance(event, ApproachingVehicle)]


def default_slots(scenario: Scenario) -> int:
    return min(DEFAULT_SLOTS, sum(isinstance(event, ApproachingVehicle) for event in scenario.events))


def _event_line(event, model: int | None) -> str:
    head = f"{event.line} {_hex(event.distance)}"
    if isinstance(event, ApproachingVehicle):
        actions = "".join(f" {_hex(a.trigger.seconds)} {WHERE[a.trigger.where]} {_hex(a.lateral.value)} "
                          f"{_flag(a.lateral.relative)} {_hex(a.speed.value)} {_flag(a.speed.relative)} "
                          f"{_hex(a.duration)}" for a in event.actions)
        initial = event.initial
        start = "0" if initial is None else (f"1 {_hex(initial.lateral.value)} {_flag(initial.lateral.relative)} "
                                             f"{_hex(initial.speed.value)} {_flag(initial.speed.relative)} "
                                             f"{_hex(initial.duration)}")
        return (f"A {head} {_hex(event.speed.value)} {_flag(event.speed.relative)} {_hex(event.gap)} "
                f"{_hex(event.lateral.value)} {_flag(event.lateral.relative)} {model} {start} "
                f"{len(event.actions)}{actions}"
                f"  # {event.distance:.6g} m: speed {'*' * event.speed.relative}{event.speed.value:.6g} m/s, "
                f"gap {event.gap:.6g} m, lateral {'*' * event.lateral.relative}{event.lateral.value:.6g} m, "
                f"model {model}, {len(event.actions)} action(s)")
    if isinstance(event, Brake):
        return (f"BRK {head} {_hex(event.pedal)} {THRESHOLDS[event.threshold]} {_hex(event.magnitude)}"
                f"  # {event.distance:.6g} m: pedal {event.pedal * 100:.6g} %, {event.threshold} "
                f"{event.magnitude:.6g}")
    if isinstance(event, SurfaceAttribute):
        settings = "".join(f" {lane} {_hex(value)}" for lane, value in event.settings)
        shown = ", ".join(f"lane {lane} = {value:g}" for lane, value in event.settings)
        return f"RSA {head} {len(event.settings)}{settings}  # {event.distance:.6g} m: {shown}"
    if isinstance(event, EndOfScenario):
        return f"ES {head}  # {event.distance:.6g} m"
    raise TypeError(f"line {event.line}: {type(event).__name__} cannot be exported")


def scenario_data(scenario: Scenario, seed: int, slots: int, vehicle_table: dict[int, VehicleModel],
                  parameters: dict, salt: str = "") -> tuple[str, str]:
    """(the data file's text, its GUID). `parameters`: the start values of the FMU's parameters (the binary's own
    defaults are the interface data's; these are the export's). The GUID is a hash of the text and of `salt` (the
    interface's identity), so that a changed scenario or interface never meets an FMU binary's instance of
    another."""
    models = resolve_models(scenario, seed)
    road = scenario.road
    used = sorted(set(models))
    placed = iter(models)
    events = [_event_line(event, next(placed) if isinstance(event, ApproachingVehicle) else None)
              for event in scenario.events]
    last = max((event.distance for event in scenario.events), default=0.0)
    body = [f"source {_text(Path(scenario.path).name)}",
            f"road {_hex(road.lane_width)} {road.lanes_right} {road.lanes_left}  # lane width {road.lane_width:.6g} m",
            "es none" if scenario.end_distance is None else f"es {_hex(scenario.end_distance)}",
            f"last {_hex(last)}",
            f"start_lateral {_hex(road.lane_center(1))}",
            f"slots {slots}",
            *[f"parameter {name} {_hex(float(value))}  # {value}" for name, value in parameters.items()],
            *[f"vehicle {number} {_hex(vehicle_table[number].length)} {_hex(vehicle_table[number].width)} "
              f"{_text(vehicle_table[number].name)}" for number in used],
            f"events {len(events)}", *events, "end"]
    digest = hashlib.sha256(("\n".join(body) + "\0" + salt).encode()).digest()
    guid = "{" + str(uuid.UUID(bytes=digest[:16])) + "}"
    header = ["# sdl-fmu scenario data, resolved at export (SI: m, m/s, s; numbers are hexadecimal floats, exact;",
              f"# random vehicle models drawn with seed {seed}). Read by the scenario FMU's binary at instantiation.",
              f"sdl-fmu-scenario {FORMAT}", f"guid {guid}"]
    return "\n".join(header + body) + "\n", guid


def end_distance(scenario: Scenario, until_distance: float | None, until_time: float | None) -> float:
    """Where the run ends by distance (Cosimulation._end_distance)."""
    candidates = [d for d in (scenario.end_distance, until_distance) if d is not None]
    if candidates:
        return min(candidates)
    if until_time is not None:
        return math.inf
    return max((event.distance for event in scenario.events), default=0.0) + RUNOUT


def parameter_starts(scenario: Scenario, ego, *, speed: float | None, until_distance: float | None,
                     until_time: float | None, driver_period: float | None, driver: str = "lane",
                     on_collision: str = "continue",
                     arbitration: dict[str, str] | None = None) -> dict[str, float | int | bool]:
    """The start values of the scenario FMU's parameters: the options as `sdl-fmu run` takes them (SI), the ego's
    properties from its EgoModel, and the trigger bounds `sdl-fmu run` derives for it (Cosimulation.__init__)."""
    speed = DEFAULT_SPEED if speed is None else float(speed)
    surfaces = surface_map(scenario, ego.default_surface)
    mu_max = ego.peak_friction([value for values in surfaces.values.values() for value in values])
    wheel_arm = max(math.hypot(x, y) for x, y in ego.wheels)
    bounds = ego_bounds(ego, mu_max, speed, wheel_arm, MAX_STEER)
    starts: dict[str, float | int | bool] = {
        "speed": speed, "until_distance": 0.0 if until_distance is None else float(until_distance),
        "until_time": 0.0 if until_time is None else float(until_time),
        "driver_period": DEFAULT_DRIVER_PERIOD if driver_period is None else float(driver_period),
        "driver": DRIVERS[driver], "trigger_prediction": True, "on_collision_stop": on_collision == "stop",
        "ego_length": ego.length, "ego_width": ego.width, "ego_cg_to_front_axle": ego.cg_to_front,
        "ego_cg_to_rear_axle": ego.cg_to_rear, "ego_track_front": ego.track_front, "ego_track_rear": ego.track_rear,
        "ego_mass": ego.mass, "ego_drive_accel_max": ego.drive_accel_max, "ego_drive_power_max": ego.drive_power_max,
        "ego_brake_decel_max": ego.brake_decel_max, "ego_rolling_resistance": ego.rolling_resistance,
        "ego_drag_area": ego.drag_area, "ego_air_density": ego.air_density,
        "ego_max_acceleration": bounds.acceleration, "ego_max_yaw_rate": bounds.yaw_rate,
        "brk_acts": bool(ego.brk_acts),
        **{name: quantity in ego.outputs for quantity, name in CONNECTED.items()},
    }
    for channel, mode in {"throttle": "override", "brake": "max", "steer": "driver", **(arbitration or {})}.items():
        starts[f"arbitration_{channel}"] = ARBITRATION[mode]
    return starts
