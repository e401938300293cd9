"""EgoModel: everything the run side knows about the ego vehicle, built once per run from the FMU's model
description and a vehicle map (docs/vehicle-maps.md). The master, the road, the driver, the triggers and the results ask it;
no other module looks at the FMU's variable names or at which model it is."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Literal, NoReturn

import numpy as np

from ..names import WHEELS
from ..tire_files import SLOT_KEYS, TireFileError, default_attribute_file, slot_parameter, slot_values
from ..units import STANDARD_GRAVITY
from .vehicle_map import (Channel, FrictionMeaning, VehicleMap, VehicleMapError, declared_range_problem,
                          load_vehicle_map, vehicle_value_problem)

# surface value of a lane nobody set, per friction meaning: 10 x the nominal mu 0.8, or attribute 0
DEFAULT_SURFACE = {"mu": 8.0, "attribute": 0.0, None: 8.0}
# [vehicle] values a map may leave out, SI (the driver model's feed-forward and the trigger bounds use them)
VEHICLE_DEFAULTS = {"mass": 1500.0, "drive_accel_max": 3.0, "drive_power_max": 1e5, "brake_decel_max": 9.80665,
                    "rolling_resistance": 0.0, "drag_area": 0.0, "air_density": 1.225}
DEFAULT_PEAK_FRICTION = 1.5  # the friction bound of a vehicle whose map gives none: above any road tire's peak
REAL_TYPES = ("Real", "Float64", "Float32")
INTEGER_TYPES = ("Integer", "Enumeration", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64")
# the value range of each FMI 3.0 integer type (a declared min/max narrows it; FMI 2.0's Integer is 32-bit)
INTEGER_RANGES = {"Integer": (-2**31, 2**31 - 1), "Enumeration": (-2**31, 2**31 - 1),
                  **{f"Int{bits}": (-2**(bits - 1), 2**(bits - 1) - 1) for bits in (8, 16, 32, 64)},
                  **{f"UInt{bits}": (0, 2**bits - 1) for bits in (8, 16, 32, 64)}}
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


def mapped_variable(variables: dict, fmu_name: str, name: str, causalities: tuple[str, ...]) -> tuple:
    """(the FMU's variable `name` a map entry names, None) if it exists with one of `causalities` and is a scalar; else
    (None, the reason it cannot be used). The vehicle and controller models' check of each entry."""
    variable = variables.get(name)
    if variable is None:
        return None, f"the FMU {fmu_name} has no variable {name!r}"
    if variable.causality not in causalities:
        return None, f"{name!r} is an {variable.causality} of the FMU; this entry needs {' or '.join(causalities)}"
    if getattr(variable, "dimensions", None):  # an FMI 3.0 array: read and set by one value reference per scalar
        return None, f"{name!r} is an array; this entry needs a scalar variable"
    return variable, None


def one_reference(entries, fail: Callable[[str, str], NoReturn]) -> None:
    """Each FMU variable a map writes has one writer also through aliases: two differently named variables with one
    value reference and type (an FMI 2.0 alias) are one variable, so two keys on them (the map's one_writer check sees
    two names) are one line naming both. entries: (key, FMU variable) in the map's order."""
    first: dict[tuple[str, int], tuple[str, str]] = {}
    for key, variable in entries:
        slot = (variable.type, variable.valueReference)
        if slot in first and first[slot][1] != variable.name:
            other_key, other = first[slot]
            fail(key, f"{variable.name!r} is an alias of {other!r}, {other_key}'s variable (value reference "
                      f"{variable.valueReference}): one FMU variable cannot take two values (map each to a variable "
                      "of its own)")
        first.setdefault(slot, (key, variable.name))


def parameter_defaults(description) -> dict[str, float]:
    """Start values of the FMU's scalar Real (Float) parameters, by name (FMI 3.0 arrays are left out)."""
    return {v.name: float(v.start) for v in description.modelVariables
            if v.causality == "parameter" and v.type in REAL_TYPES and v.start is not None
            and not getattr(v, "dimensions", None)}


class EgoModel:
    """The ego vehicle of one run: an FMU and its vehicle map, resolved against each other.

    What the run asks of it: docs/vehicle-maps.md; everything here is in SI."""

    def __init__(self, fmu_path: Path, vehicle_map: VehicleMap, description, overrides: dict[str, float] | None = None,
                 known_attributes: frozenset[int] | None = None, warnings: tuple[str, ...] = ()):
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
        written = [*((c.key, c.variable) for c in (*vehicle_map.inputs.values(), *vehicle_map.start.values())),
                   *(() if vehicle_map.friction is None else
                     ((f"{vehicle_map.friction.key}.variables[{i}]", name)
                      for i, name in enumerate(vehicle_map.friction.variables))),
                   *((f"parameters.{name}", name) for name in vehicle_map.parameters)]
        one_reference(((key, self.variables[name]) for key, name in written), self._fail)
        self.overrides = dict(overrides or {})
        self.parameters = {**parameter_defaults(description), **vehicle_map.parameters, **self.overrides}
        # the surface attribute numbers the run's Tire Attribute File gives (None: no tire file), and what reading
        # it warned of
        self.known_attributes = known_attributes
        self.warnings = warnings
        self._resolve_vehicle()
        self._unzipped: str | None = None

    # ---- construction -------------------------------------------------------------------------------------

    @classmethod
    def open(cls, fmu: str | Path | None = None, vehicle: str | Path | VehicleMap | None = None) -> EgoModel:
        """The model of an FMU driven through a vehicle map (fmu None: the map's own `fmu` key). Raises
        VehicleMapError (one line naming the map file and key, or the FMU) before anything runs."""
        if vehicle is None:
            raise VehicleMapError("vehicle", "a vehicle map is needed to drive an FMU (see docs/vehicle-maps.md)")
        vehicle_map = vehicle if isinstance(vehicle, VehicleMap) else load_vehicle_map(vehicle)
        if fmu is None:
            if vehicle_map.fmu is None:
                raise VehicleMapError("vehicle", f"{vehicle_map.label}: fmu: missing (give the FMU as the fmu option "
                                                 "or in the map)")
            fmu = vehicle_map.fmu
        return cls(Path(fmu), vehicle_map, read_description(Path(fmu)))

    def _with(self, overrides: dict[str, float], **changes) -> EgoModel:
        fields = {"known_attributes": self.known_attributes, "warnings": self.warnings, **changes}
        return EgoModel(self.fmu_path, self.map, self.description, {**self.overrides, **overrides}, **fields)

    def with_parameters(self, values: dict[str, float] | None) -> EgoModel:
        """This model with these FMU start values for the run (the `params` option, SI), each checked against the
        FMU: a parameter it declares, Real (a finite number) or Integer (a whole number), within its declared min and
        max. The model's properties follow them (the [vehicle] values that name a parameter). VehicleMapError
        naming `params` and the assignment otherwise."""
        checked = {name: self._checked_parameter(name, value) for name, value in (values or {}).items()}
        try:
            return self._with(checked)
        except VehicleMapError as error:  # a [vehicle] value that follows a parameter, outside its range: that one
            name = next((name for name in checked if f"parameter {name!r}" in str(error)), None)
            if name is None:
                raise
            raise VehicleMapError.of("params", f"{name}={checked[name]:g}", str(error)) from None

    def with_tires(self, attribute_file: str | Path | None = None) -> EgoModel:
        """This model with its tire slots (the map's `tire_slots`) filled from a Tire Attribute File (None: the
        shipped one), each slot's coefficients named by the map's prefix (tire_files.slot_parameter); it then knows
        the attribute numbers the file gives (`known_attributes`) and carries the file's warnings. VehicleMapError
        naming `tires` for a bad file, or for a file given to a vehicle without tire slots; without either, the
        model itself."""
        prefix = None if self.friction is None else self.friction.tire_slots
        if prefix is None:
            if attribute_file is not None:
                raise VehicleMapError.of("tires", attribute_file, "applies to the advanced dynamics only (a vehicle "
                                         f"map whose friction input has tire_slots; {self.name}'s has none)")
            return self
        path = default_attribute_file() if attribute_file is None else Path(attribute_file)
        slots = self.tire_slot_numbers()
        try:
            values, attributes, warnings = slot_values(path, len(slots))
        except TireFileError as error:
            raise VehicleMapError("tires", str(error).strip().splitlines()[0]) from None
        starts = {}
        for slot, coefficients in zip(slots, values):
            for key in SLOT_KEYS:
                name = slot_parameter(prefix, slot, key)
                if name not in self.variables:
                    self._fail(f"{self.friction_key}.tire_slots", f"the FMU {self.fmu_path.name} has no tire slot "
                                                                  f"parameter {name!r}")
                starts[name] = coefficients[key]
        return self._with(starts, known_attributes=frozenset(attributes), warnings=(*self.warnings, *warnings))

    def _checked_parameter(self, name: str, value) -> float | int:
        shown = f"{name}={value}"
        variable = self.variables.get(name)
        if variable is None or variable.causality != "parameter":
            raise VehicleMapError.of("params", shown, f"{self.fmu_path.name} has no parameter {name!r} "
                                                      f"(parameters: {', '.join(self.parameter_names())})")
        if variable.type not in (*REAL_TYPES, *INTEGER_TYPES):
            raise VehicleMapError.of("params", shown, f"{name} is {variable.type}; only Real and Integer parameters "
                                                      "can be set")
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise VehicleMapError.of("params", shown, "the value must be a number (SI units)")
        if not math.isfinite(value):
            raise VehicleMapError.of("params", shown, "the value must be a finite number")
        unit = f" {variable.unit}" if variable.unit and variable.unit != "1" else ""
        low = None if variable.min is None else float(variable.min)
        high = None if variable.max is None else float(variable.max)
        if variable.type in INTEGER_TYPES:
            if value != int(value):
                raise VehicleMapError.of("params", shown,
                                         f"{name} is {variable.type}: the value must be a whole number")
            value = int(value)
            smallest, largest = INTEGER_RANGES[variable.type]
            low = smallest if low is None else max(low, smallest)
            high = largest if high is None else min(high, largest)
        else:
            value = float(value)
        if low is not None and value < low:
            raise VehicleMapError.of("params", shown, f"below the declared minimum {low:g}{unit} of {name}")
        if high is not None and value > high:
            raise VehicleMapError.of("params", shown, f"above the declared maximum {high:g}{unit} of {name}")
        return value

    def parameter_names(self) -> list[str]:
        """The FMU's parameters, as an error lists them: the tire slots (the map's `tire_slots`) as one pattern
        (tire<slot>_<KEY>), any other parameter by its name."""
        prefix = None if self.friction is None else self.friction.tire_slots
        slots = [prefix.format(slot=k) for k in self.tire_slot_numbers()] if prefix is not None else []
        names = [v.name for v in self.description.modelVariables
                 if v.causality == "parameter" and not any(v.name.startswith(slot) for slot in slots)]
        return [*names, slot_parameter(prefix, "<slot>", "<KEY>")] if slots else names

    @property
    def friction_key(self) -> str:
        return self.map.friction.key if self.map.friction is not None else "inputs.friction"

    def _fail(self, key: str, reason: str):
        raise VehicleMapError("vehicle", f"{self.map.label}: {key}: {reason}")

    def _variable(self, key: str, name: str, causalities: tuple[str, ...]):
        variable, reason = mapped_variable(self.variables, self.fmu_path.name, name, causalities)
        if reason is not None:
            self._fail(key, reason)
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
            prefix = self.friction.tire_slots
            p = self.parameters
            peaks = []
            for k in self.tire_slot_numbers():
                for axis in "XY":
                    pd1, pd2, lmu = (slot_parameter(prefix, k, key)
                                     for key in (f"PD{axis}1", f"PD{axis}2", f"LMU{axis}"))
                    if pd1 in p:
                        peaks.append((abs(p[pd1]) + abs(p.get(pd2, 0.0))) * p.get(lmu, 1.0))
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

    def top_speed(self) -> float:
        """The highest steady speed the vehicle can hold on a level road, m/s, from its [vehicle] properties: where
        the drive force at full throttle, min(m drive_accel_max, drive_power_max / v), equals the rolling resistance
        m g f_r and the drag m K v^2 (K = rho CdA / (2 m)); inf without any resistance. Both sides are monotonic in
        v (the drive falls, the resistance rises), so the crossing is found by bisection to machine precision."""
        g, f_r, k = STANDARD_GRAVITY, self.rolling_resistance, self.drag_factor

        def surplus(v: float) -> float:  # drive minus resistance per unit mass at full throttle
            drive = self.drive_accel_max if v <= 0 else min(self.drive_accel_max,
                                                            self.drive_power_max / (self.mass * v))
            return drive - g * f_r - k * v * v

        if surplus(0.0) <= 0:
            return 0.0
        if k <= 0 and (f_r <= 0 or surplus(1e12) > 0):
            return math.inf
        low, high = 0.0, 1.0
        while surplus(high) > 0:
            low, high = high, 2 * high
        for _ in range(200):
            middle = (low + high) / 2
            if middle in (low, high):
                break
            low, high = (middle, high) if surplus(middle) > 0 else (low, middle)
        return low

    def summary(self) -> dict:
        """What summary.json records about the vehicle."""
        return {"name": self.name, "fmu": str(self.fmu_path.name), "fmi_version": self.fmi_version,
                "map": None if self.map_path is None else self.map_path.name, "can_roll_back": self.can_roll_back,
                "friction": self.surface_meaning, "brk_acts": self.brk_acts}

    def unzipped(self) -> str:
        """The FMU unpacked once for all of this process's instances of it (vehicle/unpack.py: checked, what an
        instance on this platform loads, removed at the process's end on every path); UnpackError (one line naming
        the FMU) when it cannot be."""
        if self._unzipped is None:
            from .unpack import unpacked

            self._unzipped = str(unpacked(self.fmu_path))
        return self._unzipped

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


def read_description(fmu: Path, option: str = "fmu"):
    """The FMU's model description, checked to be a co-simulation FMI 2.0 or 3.0 FMU with a binary for this
    platform; VehicleMapError naming the option it came through (`option`: fmu, controller) and the FMU otherwise."""
    import fmpy

    from .unpack import UnpackError, check_archive, check_identifier

    if not fmu.is_file():
        raise VehicleMapError.of(option, fmu, "no such file" if not fmu.exists() else "not a file")
    try:  # member names and sizes, before anything is read from it
        names = [member.filename for member in check_archive(fmu)]
    except UnpackError as error:
        raise VehicleMapError(option, "", subject=str(error)) from None
    try:
        description = _read_description(str(fmu.resolve()), fmu.stat().st_mtime_ns, fmu.stat().st_size)
    except Exception as error:  # fmpy raises zip, XML and its own errors alike: all mean "not an FMU"
        text = (str(error).strip() or type(error).__name__).splitlines()[0]
        raise VehicleMapError.of(option, fmu, f"is not a readable FMU ({text})") from None
    if description.fmiVersion not in ("2.0", "3.0"):
        raise VehicleMapError.of(option, fmu, f"FMI {description.fmiVersion}; sdl-fmu drives FMI 2.0 and 3.0 FMUs")
    if description.coSimulation is None:
        what = "the vehicle" if option == "fmu" else "it"
        raise VehicleMapError.of(option, fmu, f"has no co-simulation interface (sdl-fmu co-simulates {what})")
    try:  # it names the binary's file
        check_identifier(fmu, description.coSimulation.modelIdentifier)
    except UnpackError as error:
        raise VehicleMapError(option, "", subject=str(error)) from None
    binary = f"binaries/{_platform(description.fmiVersion)}/{description.coSimulation.modelIdentifier}" \
             f"{fmpy.sharedLibraryExtension}"
    if binary not in names:
        raise VehicleMapError.of(option, fmu, f"has no binary for this platform ({binary})")
    return description


def _platform(fmi_version: str) -> str:
    import fmpy

    return fmpy.platform if fmi_version == "2.0" else fmpy.platform_tuple


@functools.lru_cache(maxsize=16)
def _read_description(path: str, mtime: int, size: int):
    from fmpy import read_model_description

    return read_model_description(path, validate=False)
