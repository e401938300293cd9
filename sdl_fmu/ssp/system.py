"""The exported system (docs/export.md): the scenario FMU and the ego FMU as SSP components, connected through the
ego's vehicle map, each with its parameter set.

Every connection is one vehicle-map entry: the scenario FMU's commands (throttle, brake, steer, the friction under
the wheels) go to the map's inputs, and the map's outputs (x, y, yaw, speed, distance, yaw rate, ax, stopped) come
back as the scenario FMU's `ego_*` inputs. A map entry's scale, offset and unit are the conversion that `sdl-fmu run`
applies (EgoModel's, docs/vehicle-maps.md), written as the connection's linear transformation:
- into the ego: FMU value = factor * sdl-fmu's SI value + offset (a pedal: scale * pedal + offset as it is);
- out of the ego: sdl-fmu's SI value = factor * FMU value + offset.
The ego's parameter set holds its start state (the map's [start]: speed, x, y, yaw, converted the same way), the map's
[parameters] and, for a vehicle with Magic Formula tire slots, the slots `sdl-fmu run` fills from the shipped Tire
Attribute File; the scenario's parameter set holds the options its FMU takes as parameters."""

from __future__ import annotations

from pathlib import Path

from ..text import UnsafeName, safe_identifier
from ..vehicle.model import INTEGER_TYPES, REAL_TYPES, EgoModel
from .document import BASE_UNITS, Component, Connection, Connector, Parameter, System, Unit, ValueType

SCENARIO, EGO, CONTROLLER = "scenario", "ego", "controller"  # the components' names (libcosim's slave names, ecos'
#                                                                "ego::v" prefixes)

# the vehicle map's output quantities -> the scenario FMU's inputs they feed
EGO_SIGNALS = {"x": "ego_x", "y": "ego_y", "yaw": "ego_psi", "speed": "ego_v", "distance": "ego_s", "vx": "ego_vx",
               "vy": "ego_vy", "yaw_rate": "ego_yaw_rate", "ax": "ego_ax", "ay": "ego_ay", "stopped": "ego_stopped"}
REQUIRED_SIGNALS = ("ego_x", "ego_y", "ego_psi", "ego_v")
COMMANDS = ("throttle", "brake", "steer")  # the scenario FMU's outputs of the same names -> the map's inputs
# the scenario FMU's friction outputs a map's friction variables are fed from, by (meaning, number of variables):
# what `sdl-fmu run` sends (EgoInstance.set_friction): per wheel, the axle's or the car's mean mu, or the attribute of
# the axle's or the car's first wheel
FRICTION_SOURCES = {("mu", 4): ("mu_fl", "mu_fr", "mu_rl", "mu_rr"), ("mu", 2): ("mu_front", "mu_rear"),
                    ("mu", 1): ("mu_mean",),
                    ("attribute", 4): ("surface_fl", "surface_fr", "surface_rl", "surface_rr"),
                    ("attribute", 2): ("surface_fl", "surface_rl"), ("attribute", 1): ("surface_fl",)}


# a controller's requests -> the scenario FMU's inputs they feed (it turns a deceleration into brake pedal)
REQUEST_INPUTS = {"active": "request_active", "throttle": "request_throttle", "brake": "request_brake",
                  "deceleration": "request_deceleration", "steer": "request_steer"}


class ExportError(ValueError):
    """The vehicle (its FMU and map) cannot be connected in an SSP: one line naming the map file and key, or the
    FMU."""


def fmu_file_name(fmu: Path, label: str) -> str:
    """The name an FMU is stored under in the SSP (resources/) and beside it: its file name's stem as a safe
    identifier (sdl_fmu/text.py; docs/export.md, Names) and ".fmu". ExportError naming `label` (the option and the
    file) when the name cannot be made safe."""
    try:
        return f"{safe_identifier(Path(fmu).stem)}.fmu"
    except UnsafeName as error:
        raise ExportError(f"{label}: the export names this FMU after its file name, "
                          f"and this one cannot name a file: {error}; rename the file") from None


def ssp_type(variable) -> ValueType | None:
    """The SSP 1.0 connector type of an FMI 2.0 or 3.0 variable (None: a type SSP 1.0 cannot connect)."""
    if variable.type in REAL_TYPES:
        return "Real"
    if variable.type in INTEGER_TYPES:
        return "Integer"
    if variable.type == "Boolean":
        return "Boolean"
    return None


def _declared_unit(variable) -> str | None:
    if variable.unit:
        return variable.unit
    declared = getattr(variable, "declaredType", None)
    return declared.unit if declared is not None and declared.unit else None


class _Units:
    """The units the connectors carry: those the FMUs define in their UnitDefinitions, each once (a name two FMUs
    define differently is left off the later connector: the transformation carries the conversion anyway)."""

    def __init__(self):
        self.units: dict[str, Unit] = {}

    def of(self, description, variable) -> str | None:
        name = _declared_unit(variable)
        if name is None or ssp_type(variable) != "Real":
            return None
        definition = next((u for u in description.unitDefinitions if u.name == name), None)
        if definition is None or definition.baseUnit is None:
            return None
        base = definition.baseUnit
        unit = Unit(name, {k: int(getattr(base, k)) for k in BASE_UNITS if getattr(base, k, 0)},
                    float(base.factor), float(base.offset))
        known = self.units.setdefault(name, unit)
        return name if known == unit else None


class _Side:
    """One component's connectors, declared as its connections and outputs need them."""

    def __init__(self, name: str, description, units: _Units, label: str):
        self.name, self.description, self.units, self.label = name, description, units, label
        self.variables = {v.name: v for v in description.modelVariables}
        self.connectors: dict[str, Connector] = {}

    def has(self, name: str, causality: str) -> bool:
        variable = self.variables.get(name)
        return variable is not None and variable.causality == causality

    def connector(self, name: str, kind: str) -> Connector:
        if name not in self.connectors:
            variable = self.variables[name]
            kind_type = ssp_type(variable)
            if kind_type is None:
                raise ExportError(f"{self.label}: {name!r} is {variable.type}; an SSP 1.0 connection carries Real, "
                                  "Integer or Boolean")
            self.connectors[name] = Connector(name, kind, kind_type, self.units.of(self.description, variable))
        return self.connectors[name]


def _parameter(model: EgoModel, name: str, value: float, key: str) -> Parameter:
    variable = model.variables[name]
    kind = ssp_type(variable)
    if kind == "Real":
        return Parameter(name, "Real", float(value))
    if kind == "Boolean":
        return Parameter(name, "Boolean", bool(value))
    if kind == "Integer" and float(value) == int(value):
        return Parameter(name, "Integer", int(value))
    raise ExportError(f"{model.map.label}: {key}: {name!r} is {variable.type}; its value {value!r} cannot be set "
                      "through an SSP parameter set")


def ego_parameters(model: EgoModel, start: dict[str, float]) -> tuple[Parameter, ...]:
    """The ego's parameter set: what `sdl-fmu run` sets before initialising it (EgoInstance), with run's precedence:
    the start state through the map's [start], then the map's [parameters], then the model's overrides (the tire
    slots and FMU start values of the run)."""
    missing = [q for q in ("speed", "x", "y", "yaw") if q not in model.start_inputs]
    if missing:
        raise ExportError(f"{model.map.label}: start.{missing[0]}: missing; an exported system sets the ego's start "
                          "state (speed, x, y, yaw) through its parameter set, so the map needs a [start] entry for "
                          "each (`sdl-fmu run` can instead move the FMU's outputs; an SSP connection cannot)")
    values: dict[str, tuple[float, str]] = {}
    for quantity, conversion in model.start_inputs.items():
        values[conversion.variable] = (conversion.factor * start[quantity] + conversion.offset, f"start.{quantity}")
    for name, value in {**model.map.parameters, **model.overrides}.items():
        values[name] = (value, f"parameters.{name}")
    return tuple(_parameter(model, name, value, key) for name, (value, key) in values.items())


def _scenario_parameters(side: _Side, values: dict, connected: set[str]) -> tuple[Parameter, ...]:
    """The scenario FMU's parameter set: every parameter's start value as its writer chose it (and start values of
    inputs given in `values`), and for each optional ego input the flag `<input>_connected` saying whether the SSP
    connects it (else the FMU derives it as `sdl-fmu run` derives what a vehicle map lacks)."""
    values = dict(values)
    for name, variable in side.variables.items():
        if name.endswith("_connected") and variable.causality == "parameter":
            values[name] = name.removesuffix("_connected") in connected
    parameters = []
    for name, value in values.items():
        variable = side.variables.get(name)
        kind = None if variable is None else ssp_type(variable)
        if kind is None or variable.causality not in ("parameter", "input"):
            raise ExportError(f"{side.label}: has no parameter {name!r} of a type an SSP parameter set can hold")
        parameters.append(Parameter(name, kind, float(value) if kind == "Real" else
                                    bool(value) if kind == "Boolean" else int(value)))
    return tuple(parameters)


def _typed(variables: dict, name: str, value, label: str) -> Parameter:
    variable = variables[name]
    kind = ssp_type(variable)
    if kind == "Boolean" or isinstance(value, bool):
        return Parameter(name, "Boolean", bool(value))
    if kind == "Integer" and float(value) == int(value):
        return Parameter(name, "Integer", int(value))
    if kind == "Real":
        return Parameter(name, "Real", float(value))
    raise ExportError(f"{label}: parameters.{name}: {name!r} is {variable.type}; its value {value!r} cannot be set "
                      "through an SSP parameter set")


def build_system(name: str, scenario_fmu: Path, scenario_description, model: EgoModel, *, start: dict[str, float],
                 scenario_parameters: dict[str, float | int | bool], stop_time: float,
                 step: float, description: str | None = None, generation_tool: str | None = None,
                 ego_signals: dict[str, str] = EGO_SIGNALS, controller=None) -> System:
    """The scenario FMU and the ego FMU, connected through the ego's vehicle map, and with `controller` (a
    ControllerModel) the controller between them, connected through its controller map. Raises ExportError for a
    vehicle or controller that cannot be connected (naming the map file and key)."""
    units = _Units()
    scenario = _Side(SCENARIO, scenario_description, units, f"the scenario FMU {scenario_fmu.name}")
    ego = _Side(EGO, model.description, units, f"--fmu {model.fmu_path}")
    label = model.map.label
    connections: list[Connection] = []

    def connect(start_side: _Side, output: str, end_side: _Side, input_: str, factor: float = 1.0,
                offset: float = 0.0) -> None:
        source, target = start_side.connector(output, "output"), end_side.connector(input_, "input")
        if source.type != target.type:
            raise ExportError(f"{label}: {start_side.name}.{output} is {source.type} and {end_side.name}.{input_} is "
                              f"{target.type}; an SSP connection joins connectors of one type")
        if (factor, offset) != (1.0, 0.0) and source.type != "Real":
            raise ExportError(f"{label}: {end_side.name}.{input_}: scale and offset apply to Real variables only in "
                              f"an SSP connection ({source.type} here)")
        connections.append(Connection((start_side.name, output), (end_side.name, input_), factor, offset))

    # the commands: the scenario FMU's arbitrated throttle, brake and steer -> the map's inputs
    for quantity in COMMANDS:
        conversion = model.inputs[quantity]
        connect(scenario, quantity, ego, conversion.variable, conversion.factor, conversion.offset)
    # the road under the wheels
    friction = model.friction
    if friction is not None:
        sources = FRICTION_SOURCES[(friction.meaning, len(friction.variables))]
        for source, variable in zip(sources, friction.variables):
            if not scenario.has(source, "output"):
                raise ExportError(f"{label}: inputs.friction: the scenario FMU has no output {source!r} to feed "
                                  f"{variable!r} from")
            connect(scenario, source, ego, variable, friction.scale, friction.offset)
    # the ego's state -> the scenario FMU's ego_* inputs
    for quantity, conversion in model.outputs.items():
        signal = ego_signals.get(quantity)
        if signal is None or not scenario.has(signal, "input"):
            ego.connector(conversion.variable, "output")  # declared for the masters that record connectors only
            continue
        connect(ego, conversion.variable, scenario, signal, conversion.factor, conversion.offset)
    for signal in REQUIRED_SIGNALS:
        if not any(c.end == (SCENARIO, signal) for c in connections):
            raise ExportError(f"the scenario FMU {scenario_fmu.name} has no input {signal!r}")
    # every output of the scenario FMU is a connector: fmpy's simulate_ssp records connectors only
    for variable in scenario_description.modelVariables:
        if variable.causality == "output" and ssp_type(variable) is not None:
            scenario.connector(variable.name, "output")
    scenario_starts = dict(scenario_parameters)
    # the ego's start state as the start values of the scenario FMU's inputs it feeds: a master passes a transformed
    # connection's value only when it transfers at a communication point (libcosim through a function, ecos through
    # a modifier), not before the FMUs leave initialization, where the scenario FMU takes its first driver sample
    initial = {"ego_x": start["x"], "ego_y": start["y"], "ego_psi": start["yaw"], "ego_v": start["speed"],
               "ego_s": 0.0, "ego_vx": start["speed"], "ego_vy": 0.0, "ego_yaw_rate": 0.0}
    scenario_starts.update({name: value for name, value in initial.items()
                            if any(c.end == (SCENARIO, name) for c in connections)})
    extra: list[Component] = []
    if controller is not None:
        part, always_active = _controller(controller, model, scenario, ego, units, connect)
        extra.append(part)
        if always_active:  # a map without `active`: the controller's requests always count
            scenario_starts["request_active"] = True
    connected = {c.end[1] for c in connections if c.end[0] == SCENARIO}
    labels = {SCENARIO: f"the scenario FMU {scenario_fmu}", EGO: f"--fmu {model.fmu_path}",
              CONTROLLER: f"--controller {controller.fmu_path}" if controller is not None else ""}
    files: set[str] = set()
    components = []
    for component in (Component(SCENARIO, scenario_fmu, tuple(scenario.connectors.values()),
                                _scenario_parameters(scenario, scenario_starts, connected)),
                      Component(EGO, model.fmu_path, tuple(ego.connectors.values()), ego_parameters(model, start)),
                      *extra):  # each FMU under its own safe name, prefixed with the component's where two clash
        file_name = fmu_file_name(component.fmu, labels[component.name])
        while file_name.lower() in files:  # told apart by case only: one file where case does not count
            file_name = f"{component.name}_{file_name}"
        files.add(file_name.lower())
        components.append(Component(component.name, component.fmu, component.connectors, component.parameters,
                                    file_name=file_name))
    return System(name, tuple(components), tuple(connections), stop_time, step, units=tuple(units.units.values()),
                  description=description, generation_tool=generation_tool)


def _controller(controller, model: EgoModel, scenario: _Side, ego: _Side, units: _Units, connect):
    """The controller as a component: its signals from the scenario FMU's outputs, or for the ego's state straight
    from the ego's outputs (the vehicle map's conversion and the controller map's, composed), its requests into the
    scenario FMU's request_* inputs. Returns (the component, whether its map lacks `active`)."""
    side = _Side(CONTROLLER, controller.description, units, f"--controller {controller.fmu_path}")
    label = controller.map.label
    by_signal = {signal: quantity for quantity, signal in EGO_SIGNALS.items()}
    for port in controller.inputs:
        key = f"inputs.{port.name}"
        if port.name in by_signal:  # the ego's state: the scenario FMU reads it, and the controller too
            conversion = model.outputs.get(by_signal[port.name])
            if conversion is None:
                raise ExportError(f"{label}: {key}: the vehicle map of {model.name} has no "
                                  f"outputs.{by_signal[port.name]} to connect (`sdl-fmu run` derives it; an SSP "
                                  "connection cannot)")
            _connect_checked(connect, label, key, ego, conversion.variable, side, port.variable,
                             port.factor * conversion.factor, port.factor * conversion.offset + port.offset)
        elif scenario.has(port.name, "output"):
            _connect_checked(connect, label, key, scenario, port.name, side, port.variable, port.factor, port.offset)
        else:
            raise ExportError(f"{label}: {key}: the scenario FMU has no output {port.name!r}")
    requested = {port.name for port in controller.outputs}
    for port in controller.outputs:
        if not scenario.has(REQUEST_INPUTS[port.name], "input"):
            raise ExportError(f"{label}: outputs.{port.name}: the scenario FMU has no input "
                              f"{REQUEST_INPUTS[port.name]!r}")
        _connect_checked(connect, label, f"outputs.{port.name}", side, port.variable, scenario,
                         REQUEST_INPUTS[port.name], port.factor, port.offset)
    parameters = tuple(_typed(side.variables, name, value, label) for name, value in controller.parameters.items())
    component = Component(CONTROLLER, controller.fmu_path, tuple(side.connectors.values()), parameters)
    return component, "active" not in requested


def _connect_checked(connect, label: str, key: str, start: _Side, output: str, end: _Side, input_: str,
                     factor: float, offset: float) -> None:
    """connect(), a refusal naming the controller map's file and key."""
    try:
        connect(start, output, end, input_, factor, offset)
    except ExportError as error:
        reason = str(error).split(": ", 2)[-1]
        raise ExportError(f"{label}: {key}: {reason}") from None
