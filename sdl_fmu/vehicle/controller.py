"""ControllerModel: a controller FMU (AEB, ACC, lane keeping, a driver model) and its controller map
(controller_map.py, docs/controllers.md), resolved against each other once per run, beside EgoModel and asked the same
way; and ControllerInstance, its co-simulation instance, stepped at its period;
IsolatedController, the same instance in a host process for a controller FMU sdl-fmu did not build (isolated.py).

At each sample instant t_k = k x period (an instant the master steps to) the instance is given the signals at t_k,
stepped over [t_k, t_(k+1)] and read: its requests (`Request`, SI) hold from t_k until the next sample. It is never
stepped anywhere else, so it never needs rolling back (docs/controllers.md, Exactness)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal, Mapping, NamedTuple

from .controller_map import (REQUESTS, SIGNALS, ControllerMap, ControllerMapError, Kind, Rule,
                             load_controller_map)
from .instance import OUTPUT_LIMIT, FmuError, end_instance
from .isolated import FmuTimeout, Hosted, HostEnded, runs_in_process
from .model import INTEGER_TYPES, REAL_TYPES, mapped_variable, one_reference, read_description, si_conversion
from .vehicle_map import Channel, VehicleMapError


class ControllerError(FmuError):
    """The controller FMU refused a call, could not be loaded, or returned a value that is not a number."""


class Request(NamedTuple):
    """A controller's requests at one sample, SI; None where the map does not map that output. `active` is True when
    the map has no `active` output."""

    active: bool
    throttle: float | None
    brake: float | None
    steer: float | None
    deceleration: float | None


NO_REQUEST = Request(False, None, None, None, None)


class Port(NamedTuple):
    """One mapped controller variable: FMU value = factor * SI + offset (inputs), SI = factor * FMU value + offset
    (outputs); booleans and integers as they are."""

    name: str  # the signal or request
    kind: Kind
    variable: str
    reference: int
    type: str  # the FMU variable's type (Real, Float64, Boolean, Integer, Int32, ...)
    factor: float = 1.0
    offset: float = 0.0


class ControllerModel:
    """A controller FMU and its map: the variables to set and read with their conversions, the period, the
    arbitration rules, the parameters, whether it can roll back, its identity."""

    def __init__(self, fmu_path: Path, controller_map: ControllerMap, description):
        self.fmu_path = Path(fmu_path)
        self.map = controller_map
        self.map_path = controller_map.path
        self.description = description
        self.fmi_version: Literal["2.0", "3.0"] = description.fmiVersion
        self.guid = description.guid
        self.name = controller_map.name or description.modelName
        self.model_identifier = description.coSimulation.modelIdentifier
        self.can_roll_back = bool(description.coSimulation.canGetAndSetFMUstate)
        self.period = controller_map.period
        self.rules: dict[str, Rule] = dict(controller_map.rules)
        self.variables = {v.name: v for v in description.modelVariables}
        self._units = {u.name: u for u in description.unitDefinitions}
        self.inputs = tuple(self._port(name, channel, SIGNALS[name], "input")
                            for name, channel in controller_map.inputs.items())
        self.outputs = tuple(self._port(name, channel, REQUESTS[name], "output")
                             for name, channel in controller_map.outputs.items())
        self.requests = frozenset(port.name for port in self.outputs)
        for name, value in controller_map.parameters.items():
            variable = self._variable(f"parameters.{name}", name, ("parameter", "input"))
            if isinstance(value, bool) != (variable.type == "Boolean"):
                self._fail(f"parameters.{name}", f"{value!r} does not fit {name!r}, a {variable.type} variable")
            if variable.type in INTEGER_TYPES and value != int(value):
                self._fail(f"parameters.{name}", f"{value!r}: {name!r} is {variable.type} (a whole number)")
        one_reference([*((port_key, self.variables[port.variable]) for port_key, port in
                         zip((c.key for c in controller_map.inputs.values()), self.inputs)),
                       *((f"parameters.{name}", self.variables[name]) for name in controller_map.parameters)],
                      self._fail)
        self.parameters = dict(controller_map.parameters)
        self._unzipped: str | None = None

    @classmethod
    def open(cls, fmu: str | Path | None = None, controller_map: str | Path | ControllerMap | None = None
             ) -> ControllerModel:
        """The model of a controller FMU driven through a controller map (fmu None: the map's own `fmu` key).
        Raises ControllerMapError (one line naming the map file and key, or the FMU) before anything runs."""
        if controller_map is None:
            raise ControllerMapError("controller_map", "a controller map is needed to put a controller in the loop "
                                                       "(see docs/controllers.md)")
        if not isinstance(controller_map, ControllerMap):
            controller_map = load_controller_map(controller_map)
        if fmu is None:
            if controller_map.fmu is None:
                raise ControllerMapError("controller_map", f"{controller_map.label}: fmu: missing (give the FMU as the "
                                                           "controller option or in the map)")
            fmu = controller_map.fmu
        try:
            description = read_description(Path(fmu), "controller")
        except VehicleMapError as error:  # naming the controller option
            raise ControllerMapError(error.option, str(error) if error.subject is None else "",
                                     subject=error.subject) from None
        return cls(Path(fmu), controller_map, description)

    def _fail(self, key: str, reason: str):
        raise ControllerMapError("controller_map", f"{self.map.label}: {key}: {reason}")

    def _variable(self, key: str, name: str, causalities: tuple[str, ...]):
        variable, reason = mapped_variable(self.variables, self.fmu_path.name, name, causalities)
        if reason is not None:
            self._fail(key, reason)
        return variable

    def _port(self, name: str, channel: Channel, kind: Kind, causality: str) -> Port:
        variable = self._variable(channel.key, channel.variable, (causality,))
        kinds = {"boolean": ("Boolean", *INTEGER_TYPES, *REAL_TYPES), "integer": (*INTEGER_TYPES, *REAL_TYPES)}
        allowed = kinds.get(kind, REAL_TYPES)
        if variable.type not in allowed:
            need = "a Real" if allowed is REAL_TYPES else "a Boolean, Integer or Real" if kind == "boolean" \
                else "an Integer or Real"
            self._fail(channel.key, f"{channel.variable!r} is {variable.type}; this entry needs {need} variable")
        if kind in ("boolean", "integer", "pedal"):
            factor, offset = channel.scale, channel.offset
        else:
            unit_factor, unit_offset = si_conversion(channel.key, variable, self._units, channel.unit, kind, self._fail)
            if causality == "input":  # FMU value = (scale * SI + offset) in the variable's unit
                factor, offset = channel.scale / unit_factor, (channel.offset - unit_offset) / unit_factor
            else:  # SI = scale * (the variable's value in SI) + offset
                factor, offset = channel.scale * unit_factor, channel.scale * unit_offset + channel.offset
        return Port(name, kind, variable.name, variable.valueReference, variable.type, factor, offset)

    def summary(self) -> dict:
        """What summary.json records about the controller (docs/controllers.md)."""
        return {"name": self.name, "fmu": self.fmu_path.name, "fmi_version": self.fmi_version, "guid": self.guid,
                "map": None if self.map_path is None else Path(self.map_path).name, "period_s": self.period,
                "can_roll_back": self.can_roll_back, "inputs": [port.name for port in self.inputs],
                "outputs": [port.name for port in self.outputs], "arbitration": dict(self.rules)}

    def unzipped(self) -> str:
        """The FMU unpacked once for all of this process's instances of it (vehicle/unpack.py, as EgoModel's)."""
        if self._unzipped is None:
            from .unpack import unpacked

            self._unzipped = str(unpacked(self.fmu_path))
        return self._unzipped

    def instantiate(self, instance_name: str = "controller") -> ControllerInstance | IsolatedController:
        """An initialized instance: in this process for an FMU sdl-fmu built (the shipped example AEB), else in a
        host process (vehicle/isolated.py: a crash, an exit or a hang of the controller is one line)."""
        kind = ControllerInstance if runs_in_process(self.fmu_path) else IsolatedController
        return kind(self, instance_name)

    def __repr__(self) -> str:
        return f"ControllerModel({self.name!r}, {self.fmu_path}, FMI {self.fmi_version})"


def _accessor(kind: str, fmi3: bool) -> str:
    """The fmpy get/set suffix of an FMU variable type."""
    if kind in ("Real", "Float64"):
        return "Float64" if fmi3 else "Real"
    if kind == "Boolean":
        return "Boolean"
    if fmi3:
        return "Int64" if kind == "Enumeration" else kind
    return "Integer"


class ControllerInstance:
    """A controller FMU instantiated for co-simulation and initialized with the map's parameters; `sample(k,
    signals)` steps it over its k-th period."""

    def __init__(self, model: ControllerModel, instance_name: str = "controller"):
        from .fmu_log import FmuLog
        from .unpack import UnpackError

        self.model = model
        self.fmi3 = model.fmi_version == "3.0"
        try:  # once per process, with the archive's limits; removed at the process's end (vehicle/unpack.py)
            self._unzipped = model.unzipped()
        except UnpackError as error:
            raise ControllerError(f"--controller {error}") from None
        self._log = FmuLog(model.fmu_path.name)  # its log lines: stderr, decoded leniently, escaped, bounded
        try:
            if self.fmi3:
                from fmpy.fmi3 import FMU3Slave as Slave
            else:
                from fmpy.fmi2 import FMU2Slave as Slave
            self.slave = Slave(guid=model.guid, unzipDirectory=self._unzipped,
                               modelIdentifier=model.model_identifier, instanceName=instance_name)
        except Exception as error:  # fmpy reports a binary that cannot be loaded as a plain Exception
            raise ControllerError(f"the controller {model.fmu_path.name}'s binary cannot be loaded: "
                                  f"{_first_line(error)}") from None
        self._instantiated = False
        try:
            if self.fmi3:
                self.slave.instantiate(logMessage=self._log.fmi3_log_message())
            else:
                self.slave.instantiate(callbacks=self._log.fmi2_callbacks())
            self._instantiated = True
            if not self.fmi3:
                self.slave.setupExperiment(startTime=0.0)
            self._set({model.variables[name]: value for name, value in model.parameters.items()})
            if self.fmi3:
                self.slave.enterInitializationMode(startTime=0.0)
            else:
                self.slave.enterInitializationMode()
            self.slave.exitInitializationMode()
        except Exception as error:
            self.close()
            raise ControllerError(f"the controller {model.fmu_path.name} could not be initialized: "
                                  f"{_first_line(error)}") from None
        # the per-sample calls: one set per input type, one get per output type, prepared once
        self._inputs = _grouped(model.inputs, self.fmi3)
        self._outputs = _grouped(model.outputs, self.fmi3)
        self._active_mapped = "active" in model.requests

    def _set(self, values: dict) -> None:
        groups: dict[str, tuple[list, list]] = {}
        for variable, value in values.items():
            references, numbers = groups.setdefault(_accessor(variable.type, self.fmi3), ([], []))
            references.append(variable.valueReference)
            numbers.append(value)
        for accessor, (references, numbers) in groups.items():
            convert = bool if accessor == "Boolean" else float if accessor.startswith(("Float", "Real")) else int
            getattr(self.slave, f"set{accessor}")(references, [convert(v) for v in numbers])

    def sample(self, k: int, signals: Mapping[str, float]) -> Request:
        """Sets the inputs to the signals (SI) at t_k = k x period, steps over [t_k, t_(k+1)] and returns the
        requests read after the step (SI; pedals and steer as requested, not yet limited)."""
        slave, period = self.slave, self.model.period
        t = k * period
        try:
            for accessor, references, ports in self._inputs:
                values = []
                for port in ports:
                    value = signals[port.name]
                    if port.kind == "boolean":
                        value = bool(value) if accessor == "Boolean" else (1 if value else 0)
                    elif port.kind == "integer":
                        value = int(value)
                    else:
                        value = port.factor * value + port.offset
                    values.append(float(value) if accessor in ("Real", "Float64", "Float32") else value)
                getattr(slave, f"set{accessor}")(references, values)
            slave.doStep(currentCommunicationPoint=t, communicationStepSize=(k + 1) * period - t)
            read = {}
            for accessor, references, ports in self._outputs:
                for port, raw in zip(ports, getattr(slave, f"get{accessor}")(references)):
                    value = raw if accessor == "Boolean" else float(raw)
                    if port.kind != "boolean":
                        value = port.factor * value + port.offset
                    if not math.isfinite(raw):  # a Real `active` too: NaN is neither on nor off
                        raise ControllerError(f"its output {port.variable!r} ({port.name}) is {raw} at "
                                              f"t = {t:.6f} s: not a finite number")
                    if port.kind != "boolean" and not -OUTPUT_LIMIT <= value <= OUTPUT_LIMIT:
                        # the ego's outputs' bound (in SI, after the map's conversion, which may overflow): no
                        # request beyond it means anything, and the results (ft, ft/s2) and the plot never
                        # overflow below it (docs/controllers.md)
                        raise ControllerError(f"its output {port.variable!r} ({port.name}) is {raw:g} at "
                                              f"t = {t:.6f} s: beyond {OUTPUT_LIMIT:g} in SI units")
                    if port.kind == "boolean":
                        read[port.name] = bool(value) if accessor == "Boolean" else value > 0.5
                    else:
                        read[port.name] = value
        except ControllerError as error:
            raise ControllerError(f"the controller {self.model.fmu_path.name} failed: {error}") from None
        except Exception as error:  # fmpy raises its own exception for an FMI call that returned an error
            raise ControllerError(f"the controller {self.model.fmu_path.name} failed at t = {t:.6f} s: "
                           f"{_first_line(error)}") from None
        return Request(read.get("active", True) if self._active_mapped else True, read.get("throttle"),
                       read.get("brake"), read.get("steer"), read.get("deceleration"))

    def close(self) -> None:
        if self._instantiated:
            end_instance(self.slave)
            self._instantiated = False
        self._log.release()

    def __enter__(self) -> ControllerInstance:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class ControllerTimeout(FmuTimeout, ControllerError):
    """The wall-clock deadline passed while the controller was working (its host was killed)."""

    def __init__(self, text: str, model: ControllerModel):
        super().__init__(text)
        self.subject = f"the controller {model.fmu_path.name}"


class IsolatedController(Hosted):
    """A ControllerInstance in a host process (vehicle/isolated.py), for a controller FMU sdl-fmu did not build:
    `sample(k, signals)` is one request (the signals the map reads, out; the requests, back). What ends its host (a
    crash, an exit) or outlasts the deadline is a ControllerError naming the controller, the call and the instant."""

    def __init__(self, model: ControllerModel, instance_name: str = "controller"):
        self.model = model
        self._names = tuple(port.name for port in model.inputs)
        self._translated(lambda: self._open(model, ("open-controller", instance_name)))

    def _error(self, text: str) -> ControllerError:
        return ControllerError(f"--controller {text}")

    def _translated(self, call):
        """The call, its errors as the controller's: the FMU's own refusals as the host words them (as
        ControllerInstance does), the end of its host with the controller named, a timeout as ControllerTimeout."""
        try:
            return call()
        except FmuTimeout as error:
            raise ControllerTimeout(_first_line(error), self.model) from None
        except HostEnded as error:
            raise ControllerError(f"the controller {self.model.fmu_path.name} failed: {_first_line(error)}") from None
        except ControllerError:
            raise
        except FmuError as error:
            raise ControllerError(_first_line(error)) from None

    def sample(self, k: int, signals: Mapping[str, float]) -> Request:
        """As ControllerInstance.sample, in the host."""
        period = self.model.period

        def where() -> str:  # formatted only for a message
            return f"in {self._prefix}DoStep from t = {k * period:.6f} s to {(k + 1) * period:.6f} s"

        request = ("sample", None, None, (k, {name: signals[name] for name in self._names}))
        return Request(*self._translated(lambda: self._send(request, where)))


def _grouped(ports, fmi3: bool) -> list[tuple[str, list[int], list[Port]]]:
    """The ports grouped by their fmpy accessor: (accessor, value references, ports)."""
    groups: dict[str, tuple[list, list]] = {}
    for port in ports:
        references, members = groups.setdefault(_accessor(port.type, fmi3), ([], []))
        references.append(port.reference)
        members.append(port)
    return [(accessor, references, members) for accessor, (references, members) in groups.items()]


def _first_line(error: BaseException) -> str:
    text = str(error).strip() or type(error).__name__
    return text.splitlines()[0]


__all__ = ["ControllerModel", "ControllerInstance", "IsolatedController", "ControllerMapError", "ControllerError",
           "ControllerTimeout", "Request", "NO_REQUEST"]
