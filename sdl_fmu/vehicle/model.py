"""EgoModel: everything the run side knows about the ego vehicle, built once per run from the FMU's model
description and a vehicle map (docs/vehicle-maps.md). The master, the road, the driver, the triggers and the results ask it;
no other module looks at the FMU's variable names or at which model it is."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Literal, NoReturn

from ..interface import WHEELS
from .vehicle_map import (Channel, Dynamics, FrictionMeaning, VehicleMap, VehicleMapError, declared_range_problem,
                          load_vehicle_map, shipped_map_path, vehicle_value_problem)

if TYPE_CHECKING:
    from ..fmu.package import FmiVersion

# surface value of a lane nobody set, per friction meaning: 10 x the nominal mu 0.8, or attribute 0
DEFAULT_SURFACE = {"mu": 8.0, "attribute": 0.0, None: 8.0}
# [vehicle] values a map may leave out, SI (the driver model's feed-forward and the trigger bounds use them)
VEHICLE_DEFAULTS = {"mass": 1500.0, "drive_accel_max": 3.0, "drive_power_max": 1e5, "brake_decel_max": 9.80665,
                    "rolling_resistance": 0.0, "drag_area": 0.0, "air_density": 1.225}
DEFAULT_PEAK_FRICTION = 1.5  # the friction bound of a vehicle whose map gives none: above any road tire's peak
REAL_TYPES = ("Real", "Float64", "Float32")
INTEGER_TYPES = ("Integer", "Enumeration", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64")
# SI unit each quantity is in inside sdl-fmu (pedals and friction are taken as given, without units)
SI_UNITS = {"steer": "rad", "x": "m", "y": "m", "distance": "m", "yaw": "rad", "speed": "m/s", "vx": "m/s",
            "vy": "m/s", "yaw_rate": "rad/s", "ax": "m/s**2", "ay": "m/s**2"}
# FMI BaseUnit exponents of those SI units (rad is not compared: FMUs declare angles with or without it)
SI_EXPONENTS = {"rad": {}, "m": {"m": 1}, "m/s": {"m": 1, "s": -1}, "rad/s": {"s": -1}, "m/s**2": {"m": 1, "s": -2},
                "s": {"s": 1}}
UNIT_TOLERANCE = 1e-9  # relative: two declarations of one unit agree (km/h: 1/3.6 written to 16 digits or computed)


@dataclass(frozen=True)
class Conversion:
    """value_out = factor * value_in + offset (inputs: SI -> FMU; outputs: FMU -> SI)."""

    variable: str
    reference: int
    type: str
    factor: float = 1.0
    offset: float = 0.0

    @property
    def identity(self) -> bool:
        return self.factor == 1.0 and self.offset == 0.0


@dataclass(frozen=True)
class FrictionInput:
    meaning: FrictionMeaning
    variables: tuple[str, ...]
    references: tuple[int, ...]
    types: tuple[str, ...]
    scale: float = 1.0
    offset: float = 0.0
    tire_slots: str | None = None

    @property
    def real(self) -> bool:
        return all(t in REAL_TYPES for t in self.types)


BoundsSource = Literal["vehicle map", "vehicle properties"]


def _pint_conversion(unit: str, si: str) -> tuple[float, float] | None:
    """(factor, offset) from `unit` to `si` through pint; None if pint does not know the unit or it is of
    another dimension. The unit string is read by a small grammar first (vehicle/unit_text.py): pint alone would
    evaluate `10**10**10*m` as arithmetic."""
    from .unit_text import conversion

    return conversion(unit, si)


def _shown_unit(unit: str) -> str:
    """A unit string in a message: quoted, shortened, and why the grammar refused it (if it did)."""
    from .unit_text import refusal

    shown = repr(unit if len(unit) <= 40 else unit[:32] + "...")
    reason = refusal(unit)
    return shown if reason is None else f"{shown} (not a unit string sdl-fmu reads: {reason})"


def _agree(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return (math.isclose(a[0], b[0], rel_tol=UNIT_TOLERANCE)
            and math.isclose(a[1], b[1], rel_tol=UNIT_TOLERANCE, abs_tol=UNIT_TOLERANCE * abs(a[0])))


def si_conversion(key: str, variable, unit_definitions: dict, map_unit: str | None, si: str,
                  fail: Callable[[str, str], NoReturn]) -> tuple[float, float]:
    """(factor, offset) taking a variable's values to the SI unit `si`: from the FMU's UnitDefinitions (by unit
    name) where it declares the unit, else from the map's `unit` (through pint), which must agree with the FMU's
    where both exist; neither: SI as it is. A mistake calls fail(key, reason) (one line naming the map's key). The
    vehicle map and the controller map convert through this one function."""
    declared = variable.declaredType.unit if variable.declaredType is not None and not variable.unit \
        else variable.unit
    fmu_conversion = None
    if declared:
        definition = unit_definitions.get(declared)
        base = definition.baseUnit if definition is not None else None
        if base is not None:
            exponents = {k: getattr(base, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd")
                         if getattr(base, k)}
            if exponents != SI_EXPONENTS[si]:
                fail(key, f"the FMU declares {variable.name!r} in {declared!r}, not a unit of {si}")
            fmu_conversion = (float(base.factor), float(base.offset))
        else:
            fmu_conversion = _pint_conversion(declared, si)
            if fmu_conversion is None:
                fail(key, f"the FMU declares {variable.name!r} in {_shown_unit(declared)}, an unknown unit or not "
                          f"one of {si}")
    map_conversion = None
    if map_unit is not None:
        map_conversion = _pint_conversion(map_unit, si)
        if map_conversion is None:
            fail(f"{key}.unit", f"{_shown_unit(map_unit)} is an unknown unit or not a unit of {si}")
    if fmu_conversion is not None and map_conversion is not None and not _agree(fmu_conversion, map_conversion):
        fail(f"{key}.unit", f"{map_unit!r} disagrees with the FMU's unit {declared!r} of {variable.name!r}")
    return fmu_conversion or map_conversion or (1.0, 0.0)


def parameter_defaults(description) -> dict[str, float]:
    """Start values of the FMU's scalar Real (Float) parameters, by name (FMI 3.0 arrays are left out)."""
    return {v.name: float(v.start) for v in description.modelVariables
            if v.causality == "parameter" and v.type in REAL_TYPES and v.start is not None
            and not getattr(v, "dimensions", None)}


class EgoModel:
    """The ego vehicle of one run: an FMU and its vehicle map, resolved against each other.

    Interface pinned in EGO_MODEL_INTERFACE.md; everything here is in SI."""

    def __init__(self, fmu_path: Path, vehicle_map: VehicleMap, description, overrides: dict[str, float] | None = None):
        self.fmu_path = Path(fmu_path)
        self.map = vehicle_map
        self.map_path = vehicle_map.path
        self.description = description
        self.fmi_version: Literal["2.0", "3.0"] = description.fmiVersion
        self.guid = description.guid
        self.name = vehicle_map.name or description.modelName
        self.model_identifier = description.coSimulation.modelIdentifier
        self.can_roll_back = bool(description.coSimulation.canGetAndSetFMUstate)
        self.variables = {v.name: v for v in description.modelVariables}
        self._units = {u.name: u for u in description.unitDefinitions}
        self.inputs = {name: self._input(channel) for name, channel in vehicle_map.inputs.items()}
        self.outputs = {name: self._output(channel) for name, channel in vehicle_map.outputs.items()}
        self.start_inputs = {name: self._input(channel, start=True) for name, channel in vehicle_map.start.items()}
        self.friction = self._friction()
        for name, value in vehicle_map.parameters.items():
            problem = declared_range_problem(self._variable(f"parameters.{name}", name, ("parameter", "input")), value)
            if problem:
                self._fail(f"parameters.{name}", problem)
        self.overrides = dict(overrides or {})
        self.parameters = {**parameter_defaults(description), **vehicle_map.parameters, **self.overrides}
        self._resolve_vehicle()

    # ---- construction -------------------------------------------------------------------------------------

    @classmethod
    def open(cls, fmu: str | Path | None = None, vehicle: str | Path | VehicleMap | None = None) -> EgoModel:
        """The model of an FMU driven through a vehicle map (fmu None: the map's own `fmu` key). Raises
        VehicleMapError (one line naming the map file and key, or the FMU) before anything runs."""
        if vehicle is None:
            raise VehicleMapError("--vehicle: a vehicle map is needed to drive an FMU (see docs/vehicle-maps.md)")
        vehicle_map = vehicle if isinstance(vehicle, VehicleMap) else load_vehicle_map(vehicle)
        if fmu is None:
            if vehicle_map.fmu is None:
                raise VehicleMapError(f"{vehicle_map.label}: fmu: missing (give the FMU with --fmu or in the map)")
            fmu = vehicle_map.fmu
        return cls(Path(fmu), vehicle_map, read_description(Path(fmu)))

    def with_parameters(self, overrides: dict[str, float]) -> EgoModel:
        """This model with these FMU start values (--param, tire slots) for the run: its properties follow."""
        return EgoModel(self.fmu_path, self.map, self.description, {**self.overrides, **overrides})

    def _fail(self, key: str, reason: str):
        raise VehicleMapError(f"{self.map.label}: {key}: {reason}")

    def _variable(self, key: str, name: str, causalities: tuple[str, ...]):
        variable = self.variables.get(name)
        if variable is None:
            self._fail(key, f"the FMU {self.fmu_path.name} has no variable {name!r}")
        if variable.causality not in causalities:
            self._fail(key, f"{name!r} is an {variable.causality} of the FMU; this entry needs "
                            f"{' or '.join(causalities)}")
        return variable

    def _si(self, key: str, variable, map_unit: str | None, si: str) -> tuple[float, float]:
        return si_conversion(key, variable, self._units, map_unit, si, self._fail)

    def _input(self, channel: Channel, start: bool = False) -> Conversion:
        """FMU value = (scale * SI + offset) in the variable's unit; pedals: scale * pedal + offset as they are."""
        quantity = channel.key.split(".")[1]
        variable = self._variable(channel.key, channel.variable, ("parameter", "input") if start else ("input",))
        if variable.type not in REAL_TYPES:
            self._fail(channel.key, f"{channel.variable!r} is {variable.type}; this entry needs a Real variable")
        if quantity in ("throttle", "brake"):
            return Conversion(variable.name, variable.valueReference, variable.type, channel.scale, channel.offset)
        factor, offset = self._si(channel.key, variable, channel.unit, SI_UNITS[quantity])
        return Conversion(variable.name, variable.valueReference, variable.type, channel.scale / factor,
                          (channel.offset - offset) / factor)

    def _output(self, channel: Channel) -> Conversion:
        """SI = scale * (the variable's value in SI) + offset."""
        quantity = channel.key.split(".")[1]
        variable = self._variable(channel.key, channel.variable, ("output",))
        if quantity == "stopped":
            if variable.type != "Boolean":
                self._fail(channel.key, f"{channel.variable!r} is {variable.type}; stopped needs a Boolean")
            return Conversion(variable.name, variable.valueReference, variable.type)
        if variable.type not in REAL_TYPES:
            self._fail(channel.key, f"{channel.variable!r} is {variable.type}; this output needs a Real variable")
        factor, offset = self._si(channel.key, variable, channel.unit, SI_UNITS[quantity])
        return Conversion(variable.name, variable.valueReference, variable.type, channel.scale * factor,
                          channel.scale * offset + channel.offset)

    def _friction(self) -> FrictionInput | None:
        entry = self.map.friction
        if entry is None:
            return None
        variables = [self._variable(f"{entry.key}.variables", name, ("input",)) for name in entry.variables]
        for variable in variables:
            if variable.type not in (*REAL_TYPES, *INTEGER_TYPES):
                self._fail(f"{entry.key}.variables", f"{variable.name!r} is {variable.type}; friction needs Real or "
                                                     "Integer variables")
        return FrictionInput(entry.meaning, entry.variables, tuple(v.valueReference for v in variables),
                             tuple(v.type for v in variables), entry.scale, entry.offset, entry.tire_slots)

    def _resolve_vehicle(self) -> None:
        """[vehicle]: numbers, or FMU parameters' values in this run; the wheelbase rule (CG midway between the
        axles unless the map places it) and the drive limit from a wheel torque are written here once."""
        values = {}
        for key, value in self.map.vehicle.items():
            if isinstance(value, str):
                self._variable(f"vehicle.{key}", value, ("parameter",))
                if value not in self.parameters:
                    self._fail(f"vehicle.{key}", f"the FMU parameter {value!r} has no Real start value")
                problem = vehicle_value_problem(key, float(self.parameters[value]))
                if problem:
                    self._fail(f"vehicle.{key}", f"the FMU parameter {value!r}: {problem}")
                value = self.parameters[value]
            values[key] = float(value)
        self.length, self.width = values["length"], values["width"]
        values.setdefault("wheelbase", math.nan)  # (only a map without geometry: see parse_vehicle_map)
        if "track_front" not in values:
            values.setdefault("track", math.nan)
        if "cg_to_front_axle" in values and "cg_to_rear_axle" in values:
            self.cg_to_front, self.cg_to_rear = values["cg_to_front_axle"], values["cg_to_rear_axle"]
            self.wheelbase = self.cg_to_front + self.cg_to_rear
        else:
            self.wheelbase = values["wheelbase"]
            self.cg_to_front = self.cg_to_rear = self.wheelbase / 2
        if "track_front" in values and "track_rear" in values:
            self.track_front, self.track_rear = values["track_front"], values["track_rear"]
        else:
            self.track_front = self.track_rear = values["track"]
        self.track = values.get("track", (self.track_front + self.track_rear) / 2)
        self.wheels = ((self.cg_to_front, self.track_front / 2), (self.cg_to_front, -self.track_front / 2),
                       (-self.cg_to_rear, self.track_rear / 2), (-self.cg_to_rear, -self.track_rear / 2))
        self.defaulted = sorted(k for k in VEHICLE_DEFAULTS if k not in values
                                and not (k == "drive_accel_max" and "drive_torque_max" in values))
        known = {**VEHICLE_DEFAULTS, **values}
        self.mass = known["mass"]
        if "drive_accel_max" not in values and "drive_torque_max" in values:
            # a drive stated as a wheel torque: a = T / (m R)
            self.drive_accel_max = values["drive_torque_max"] / (self.mass * values["wheel_radius"])
        else:
            self.drive_accel_max = known["drive_accel_max"]
        self.drive_power_max = known["drive_power_max"]
        self.brake_decel_max = known["brake_decel_max"]
        self.rolling_resistance = known["rolling_resistance"]
        self.drag_area = known["drag_area"]
        self.air_density = known["air_density"]
        self.drag_factor = self.air_density * self.drag_area / (2 * self.mass)  # rho CdA / (2 m), 1/m
        self.peak_friction_given = values.get("peak_friction")
        self.brk_acts = self.map.flags.get("brk_acts", True)
        self.spec_closed_forms = self.map.flags.get("spec_closed_forms", False)
        # the trigger prediction's bounds: the map's (m/s2, rad/s), else None: derived per run (cosim.triggers)
        given = "max_acceleration" in values
        self.bounds = {"acceleration": values.get("max_acceleration"), "yaw_rate": values.get("max_yaw_rate"),
                       "source": "vehicle map" if given else "vehicle properties"}

    # ---- what the run asks ------------------------------------------------------------------------------------

    @property
    def default_surface(self) -> float:
        """The RSA value of a lane nobody set."""
        return DEFAULT_SURFACE[None if self.friction is None else self.friction.meaning]

    @property
    def surface_meaning(self) -> FrictionMeaning | None:
        return None if self.friction is None else self.friction.meaning

    @property
    def wheel_columns(self) -> tuple[str, ...]:
        """The results' per-wheel columns of what the wheels stand on (mu_fl.. or surface_fl..)."""
        if self.friction is None:
            return ()
        prefix = "mu" if self.friction.meaning == "mu" else "surface"
        return tuple(f"{prefix}_{wheel}" for wheel in WHEELS)

    def wheel_values(self, surfaces: tuple[float, ...]) -> tuple[float, ...]:
        """Per wheel, what its RSA value means for this vehicle: mu = value / 10, or the attribute number."""
        if self.friction is None:
            return ()
        if self.friction.meaning == "mu":
            return tuple([value / 10 for value in surfaces])
        return tuple([int(value) for value in surfaces])

    def peak_friction(self, surface_values) -> float:
        """A bound on the friction coefficient the tires can reach in this run: the map's peak_friction, else
        the highest mu the scenario sets (meaning "mu"), else the Magic Formula tire slots' peak at zero load
        (mu = (|PD1| + |PD2|) LMU, the load term dfz >= -1), else DEFAULT_PEAK_FRICTION."""
        if self.peak_friction_given is not None:
            return self.peak_friction_given
        if self.friction is not None and self.friction.meaning == "mu":
            return max([self.default_surface, *surface_values]) / 10
        if self.friction is not None and self.friction.tire_slots is not None:
            slot = self.friction.tire_slots
            p = self.parameters
            peaks = []
            for k in self.tire_slot_numbers():
                prefix = slot.format(slot=k)
                for axis in "XY":
                    if f"{prefix}PD{axis}1" in p:
                        peaks.append((abs(p[f"{prefix}PD{axis}1"]) + abs(p.get(f"{prefix}PD{axis}2", 0.0)))
                                     * p.get(f"{prefix}LMU{axis}", 1.0))
            if peaks:
                return max(peaks)
        return DEFAULT_PEAK_FRICTION

    def tire_slot_numbers(self) -> list[int]:
        """The tire slots the FMU has (k with a parameter named tire_slots.format(slot=k)... ), counted from its
        model description."""
        if self.friction is None or self.friction.tire_slots is None:
            return []
        numbers, k = [], 0
        prefix = self.friction.tire_slots
        names = self.variables
        while any(name.startswith(prefix.format(slot=k)) for name in names):
            numbers.append(k)
            k += 1
        return numbers

    def summary(self) -> dict:
        """What summary.json records about the vehicle."""
        return {"name": self.name, "fmu": str(self.fmu_path.name), "fmi_version": self.fmi_version,
                "map": None if self.map_path is None else str(self.map_path), "can_roll_back": self.can_roll_back,
                "friction": self.surface_meaning, "brk_acts": self.brk_acts}

    def instantiate(self, start: dict[str, float] | None = None, parameters: dict[str, float] | None = None,
                    instance_name: str = "ego"):
        """An initialized co-simulation instance. start: sdl-fmu's initial state (speed, x, y, yaw; SI);
        parameters: FMU start values as given (over the map's [parameters] and this model's overrides)."""
        from .instance import EgoInstance
        from .isolated import IsolatedInstance, runs_in_process

        kind = EgoInstance if runs_in_process(self.fmu_path) else IsolatedInstance  # a foreign FMU: out of process
        return kind(self, start or {}, {**self.map.parameters, **self.overrides, **(parameters or {})}, instance_name)

    def __repr__(self) -> str:
        return f"EgoModel({self.name!r}, {self.fmu_path}, FMI {self.fmi_version})"


def read_description(fmu: Path, option: str = "--fmu"):
    """The FMU's model description, checked to be a co-simulation FMI 2.0 or 3.0 FMU with a binary for this
    platform; VehicleMapError naming the FMU (as `option` FMU: ...) otherwise."""
    import fmpy

    from .unpack import UnpackError, check_archive, check_identifier

    if not fmu.is_file():
        raise VehicleMapError(f"{option} {fmu}: no such file" if not fmu.exists() else f"{option} {fmu}: not a file")
    try:  # member names and sizes, before anything is read from it
        names = [member.filename for member in check_archive(fmu)]
    except UnpackError as error:
        raise VehicleMapError(f"{option} {error}") from None
    try:
        description = _read_description(str(fmu.resolve()), fmu.stat().st_mtime_ns, fmu.stat().st_size)
    except Exception as error:  # fmpy raises zip, XML and its own errors alike: all mean "not an FMU"
        text = (str(error).strip() or type(error).__name__).splitlines()[0]
        raise VehicleMapError(f"{option} {fmu}: is not a readable FMU ({text})") from None
    if description.fmiVersion not in ("2.0", "3.0"):
        raise VehicleMapError(f"{option} {fmu}: FMI {description.fmiVersion}; sdl-fmu drives FMI 2.0 and 3.0 FMUs")
    if description.coSimulation is None:
        what = "the vehicle" if option == "--fmu" else "it"
        raise VehicleMapError(f"{option} {fmu}: has no co-simulation interface (sdl-fmu co-simulates {what})")
    try:  # it names the binary's file
        check_identifier(fmu, description.coSimulation.modelIdentifier)
    except UnpackError as error:
        raise VehicleMapError(f"{option} {error}") from None
    binary = f"binaries/{_platform(description.fmiVersion)}/{description.coSimulation.modelIdentifier}" \
             f"{fmpy.sharedLibraryExtension}"
    if binary not in names:
        raise VehicleMapError(f"{option} {fmu}: has no binary for this platform ({binary})")
    return description


def _platform(fmi_version: str) -> str:
    import fmpy

    return fmpy.platform if fmi_version == "2.0" else fmpy.platform_tuple


@functools.lru_cache(maxsize=16)
def _read_description(path: str, mtime: int, size: int):
    from fmpy import read_model_description

    return read_model_description(path, validate=False)


def shipped_model(name: Dynamics = "simple", fmi_version: FmiVersion = 2, announce=None) -> EgoModel:
    """A shipped model: its cached build (built on first use) driven through its shipped map."""
    from ..fmu.cache import cached_fmu

    map_path = shipped_map_path(name)
    return EgoModel.open(cached_fmu(name, fmi_version, announce=announce), map_path)
