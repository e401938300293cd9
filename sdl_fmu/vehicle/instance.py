"""One co-simulation instance of an EgoModel, FMI 2.0 or 3.0 through fmpy, its per-step calls bound once as ctypes
function objects (the master's fast path), reading sdl-fmu's quantities in SI and deriving those the FMU lacks."""

from __future__ import annotations

import functools
import math
from ctypes import POINTER, byref, c_bool, c_double, c_int, c_size_t, c_uint, c_uint32, c_void_p, pointer
from typing import NamedTuple


STANDSTILL_SPEED = 0.5  # m/s: a `stopped` output is read only below this speed (far above any model's hold speed)
STOPPED_SPEED = 0.01  # m/s: an FMU without a `stopped` output is taken as stopped below this speed
# SI: an output beyond this (or not a number) ends the run with an FmuError naming the variable and the instant.
# 1e9 m is 1800 times the longest distance a run can cover, 1e9 m/s three times the speed of light: no vehicle's
# output, and far below where squares and products of outputs overflow a double (1e154).
OUTPUT_LIMIT = 1e9


class EgoState(NamedTuple):
    """The ego's outputs at one instant (SI, ISO 8855 inertial frame); a named tuple: made at every
    communication point and bisection probe, it must be cheap."""

    time: float
    x: float
    y: float
    psi: float
    s: float
    v: float
    vx: float
    vy: float
    ax: float
    ay: float
    yaw_rate: float
    stopped: bool


# the vehicle map's output names of EgoState's Real fields (x .. yaw_rate), in the order the fast path reads them
MAP_NAMES = {"psi": "yaw", "s": "distance", "v": "speed"}
STATE_OUTPUTS = tuple(MAP_NAMES.get(name, name) for name in EgoState._fields[1:-1])
# EgoState._make without its Python-level length check (read() always passes all fields)
_make_state = functools.partial(tuple.__new__, EgoState)
SPEED = EgoState._fields.index("v") - 1  # index of v among the Real outputs


class FmuError(RuntimeError):
    """The FMU refused a call or could not be loaded."""


class EgoInstance:
    """An ego FMU instantiated for co-simulation and initialized; see EgoModel.instantiate."""

    def __init__(self, model, start: dict[str, float], parameters: dict[str, float], instance_name: str = "ego"):
        self.model = model
        self.time = 0.0
        self.warnings: list[str] = []
        self.fmi3 = model.fmi_version == "3.0"
        from .fmu_log import FmuLog
        from .unpack import UnpackError

        name = model.fmu_path.name
        try:
            self._unzipped = model.unzipped()  # once per process, shared by the FMU's instances, removed at its end
        except UnpackError as error:
            raise FmuError(str(error)) from None
        try:
            if self.fmi3:
                from fmpy.fmi3 import FMU3Slave as Slave
            else:
                from fmpy.fmi2 import FMU2Slave as Slave
            self.slave = Slave(guid=model.guid, unzipDirectory=self._unzipped,
                               modelIdentifier=model.model_identifier, instanceName=instance_name)
        except Exception as error:  # fmpy reports a binary that cannot be loaded as a plain Exception
            raise FmuError(f"{model.fmu_path}: the FMU's binary cannot be loaded: {error}") from None
        self._log = FmuLog(name)
        try:
            if self.fmi3:
                self.slave.instantiate(logMessage=self._log.fmi3_log_message())
            else:
                self.slave.instantiate(callbacks=self._log.fmi2_callbacks())
        except Exception:  # noqa: BLE001 - fmpy: "Failed to instantiate model" (a plain Exception)
            self.slave = None
            self._log.release()
            raise FmuError(f"{self._prefix_of()}Instantiate returned NULL (its GUID or instantiation token "
                           f"{model.guid!r} is not the binary's, or it cannot run here)") from None
        try:
            self._initialize(start, parameters)
        except FmuError:
            self.close()
            raise
        except Exception as error:  # noqa: BLE001 - fmpy's FMICallException and anything else of the FMU's start
            self.close()
            raise FmuError(f"it could not be initialised: {_first_line(error)}") from None

    def _prefix_of(self) -> str:
        return "fmi3" if self.fmi3 else "fmi2"

    def _initialize(self, start: dict[str, float], parameters: dict[str, float]) -> None:
        model = self.model
        self._bind_step_path()
        if not self.fmi3:
            self.slave.setupExperiment(startTime=0.0)
        values = {}
        for quantity, value in start.items():
            conversion = model.start_inputs.get(quantity)
            if conversion is not None:
                values[conversion.variable] = conversion.factor * value + conversion.offset
        self._set_by_name({**values, **parameters})
        if self.fmi3:
            self.slave.enterInitializationMode(startTime=0.0)
        else:
            self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()
        self._start_derivation(start)
        self.read()  # the outputs at the start, checked as every later one

    # ---- binding ----------------------------------------------------------------------------------------------

    def _bind_step_path(self) -> None:
        """The per-step calls (doStep, the outputs, the inputs, the snapshots) bound once, with their ctypes
        buffers. fmpy's function objects declare pointer argtypes, whose conversion costs about 1 µs per
        call, behind a Python wrapper; the calls here go through function objects of their own without
        argtypes, so every argument must be (and is) a ctypes object of its C type: the c_void_p component,
        arrays of value references and of the values, a c_size_t count, byref(c_void_p) for a state.
        doStep passes floats: it keeps argtypes."""
        model = self.model
        dll = self.slave.dll
        component = c_void_p(self.slave.component)
        self._component = component
        prefix = "fmi3" if self.fmi3 else "fmi2"
        self._reference_type = c_uint32 if self.fmi3 else c_uint
        self._boolean_type = c_bool if self.fmi3 else c_int

        def function(name: str, argtypes=None):
            function = dll[name]  # a new function object (fmpy's keeps its own argtypes)
            function.restype = c_int
            function.argtypes = argtypes
            return function

        if self.fmi3:
            do_step = function("fmi3DoStep", (c_void_p, c_double, c_double, c_bool, POINTER(c_bool), POINTER(c_bool),
                                              POINTER(c_bool), POINTER(c_double)))
            flags = [pointer(c_bool()) for _ in range(3)] + [pointer(c_double())]
            self._do_step = lambda component, t, h, no_set_prior: do_step(component, t, h, no_set_prior, *flags)
            get_real, set_real = function("fmi3GetFloat64"), function("fmi3SetFloat64")
            get_boolean = function("fmi3GetBoolean")
        else:
            self._do_step = function("fmi2DoStep", (c_void_p, c_double, c_double, c_int))
            get_real, set_real = function("fmi2GetReal"), function("fmi2SetReal")
            get_boolean = function("fmi2GetBoolean")

        def call(function, references, buffer):
            count = c_size_t(len(references))
            refs = (self._reference_type * len(references))(*references)
            if self.fmi3:
                return functools.partial(function, component, refs, count, buffer, count)
            return functools.partial(function, component, refs, count, buffer)

        outputs = model.outputs
        # the fast path: the FMU has every Real output sdl-fmu reads, as Float64, in SI with no sign or offset
        self._direct = all(q in outputs and outputs[q].identity and outputs[q].type in ("Real", "Float64")
                           for q in STATE_OUTPUTS)
        self._real_outputs = [q for q in STATE_OUTPUTS if q in outputs and outputs[q].type in ("Real", "Float64")]
        self._output_values = (c_double * len(self._real_outputs))()
        self._get_real = call(get_real, [outputs[q].reference for q in self._real_outputs], self._output_values)
        self._other_outputs = [q for q in STATE_OUTPUTS if q in outputs and q not in self._real_outputs]
        self._stopped_value = (self._boolean_type * 1)()
        self._get_boolean = (call(get_boolean, [outputs["stopped"].reference], self._stopped_value)
                             if "stopped" in outputs else None)
        # the controls: one call for throttle, brake and steer
        inputs = [model.inputs[q] for q in ("throttle", "brake", "steer")]
        self._control_values = (c_double * 3)()
        self._set_controls = call(set_real, [c.reference for c in inputs], self._control_values)
        self._control_identity = all(c.identity for c in inputs)
        self._control_factors = tuple((c.factor, c.offset) for c in inputs)
        friction = model.friction
        if friction is not None and friction.real:
            self._friction_values = (c_double * len(friction.references))()
            self._set_friction = call(set_real, list(friction.references), self._friction_values)
        # the bisection's snapshots (an FMU state is a c_void_p, passed by reference to get and free)
        names = ("fmi3GetFMUState", "fmi3SetFMUState", "fmi3FreeFMUState") if self.fmi3 else \
            ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate")
        if model.can_roll_back:
            self._get_state, self._set_state, self._free_state = (function(name) for name in names)
        # sdl-fmu's runtime updates a snapshot given to GetFMUstate in place (as FMI allows): a discarded snapshot is
        # kept for the next save instead of freed and allocated again (0.3 µs against 6 µs a save and discard);
        # other FMUs' snapshots are freed
        own = (getattr(model.description, "generationTool", None) or "").startswith("sdl-fmu ")
        self._spare_states: list | None = [] if own and model.can_roll_back else None
        self._prefix = prefix

    def _set_by_name(self, values: dict[str, float]) -> None:
        """Values by variable name, each with its type's setter (FMI 2.0 value references are per type)."""
        by_type: dict[str, dict[int, float]] = {}
        for name, value in values.items():
            variable = self.model.variables.get(name)
            if variable is None:
                raise FmuError(f"the FMU {self.model.fmu_path.name} has no variable {name!r}")
            by_type.setdefault(variable.type, {})[variable.valueReference] = value
        for kind, group in by_type.items():
            self._typed_set(kind, list(group), list(group.values()))

    def _typed_set(self, kind: str, references: list[int], values: list) -> None:
        slave = self.slave
        try:
            if kind in ("Real", "Float64"):
                (slave.setFloat64 if self.fmi3 else slave.setReal)(references, [float(v) for v in values])
            elif kind == "Float32":
                slave.setFloat32(references, [float(v) for v in values])
            elif kind == "Boolean":
                slave.setBoolean(references, [bool(v) for v in values])
            elif self.fmi3:
                getattr(slave, f"set{'Int64' if kind == 'Enumeration' else kind}")(references, [int(v) for v in values])
            else:
                slave.setInteger(references, [int(v) for v in values])
        except Exception as error:
            names = {v.valueReference: n for n, v in self.model.variables.items() if v.type == kind}
            shown = {names.get(r, r): v for r, v in zip(references, values)}
            raise FmuError(f"the FMU refused the values {shown}: {error}") from None

    # ---- outputs ----------------------------------------------------------------------------------------------

    def _raw(self) -> dict[str, float]:
        """The FMU's Real outputs in SI (by quantity) and its `stopped` output if it has one."""
        if self._get_real() > 1:
            raise FmuError(f"the FMU refused to return its outputs at t = {self.time:.6f} s")
        outputs = self.model.outputs
        values = {}
        for quantity, raw in zip(self._real_outputs, self._output_values):
            conversion = outputs[quantity]
            values[quantity] = conversion.factor * raw + conversion.offset
        for quantity in self._other_outputs:
            conversion = outputs[quantity]
            raw = getattr(self.slave, f"get{conversion.type}")([conversion.reference])[0]
            values[quantity] = conversion.factor * float(raw) + conversion.offset
        for quantity, value in values.items():
            if not -OUTPUT_LIMIT <= value <= OUTPUT_LIMIT:
                self._bad_output(quantity, value)
        return values

    def _bad_output(self, quantity: str, value: float):
        """Ends the run: an output that is not a number or beyond OUTPUT_LIMIT (in SI)."""
        variable = self.model.outputs[quantity].variable
        what = "not a finite number" if not math.isfinite(value) else f"beyond {OUTPUT_LIMIT:g} in SI units"
        raise FmuError(f"its output {variable!r} ({quantity}) is {value:g} at t = {self.time:.6f} s: {what}")

    def _start_derivation(self, start: dict[str, float]) -> None:
        """The derived outputs' memory (distance, the previous communication point) and, for start quantities the
        map does not set in the FMU, the offsets that move the FMU's own start onto sdl-fmu's."""
        if self._direct:
            return
        model = self.model
        values = self._raw()
        self._shift = None
        moved = [q for q in ("x", "y", "yaw") if q in start and q not in model.start_inputs]
        if moved:
            dpsi = start.get("yaw", values["yaw"]) - values["yaw"] if "yaw" in moved else 0.0
            self._shift = (values["x"], values["y"], start.get("x", values["x"]) if "x" in moved else values["x"],
                           start.get("y", values["y"]) if "y" in moved else values["y"], dpsi,
                           math.cos(dpsi), math.sin(dpsi))
        if "speed" in start and "speed" not in model.start_inputs:
            self.warnings.append(f"the vehicle map has no [start] speed: the vehicle starts at its own initial speed "
                                 f"({values['speed']:.3g} m/s), not {start['speed']:.3g} m/s")
        dpsi = 0.0 if self._shift is None else self._shift[4]
        self._memory = (0.0, values["speed"], values["yaw"] + dpsi, values.get("distance", 0.0), 0.0)
        self._state = self._derive(values)

    def _derive(self, values: dict[str, float]) -> EgoState:
        """sdl-fmu's state from the FMU's outputs; what the FMU lacks is derived (docs/vehicle-maps.md)."""
        time = self.time
        t0, v0, psi0, s0, rate0 = self._memory
        h = time - t0
        v, psi = values["speed"], values["yaw"]
        x, y = values["x"], values["y"]
        if self._shift is not None:
            fx, fy, sx, sy, dpsi, c, s = self._shift
            x, y, psi = sx + c * (x - fx) - s * (y - fy), sy + s * (x - fx) + c * (y - fy), psi + dpsi
        distance = values["distance"] if "distance" in values else s0 + 0.5 * (v0 + v) * h
        if "yaw_rate" in values:
            yaw_rate = values["yaw_rate"]
        else:
            yaw_rate = (psi - psi0) / h if h > 0 else rate0
        vy = values.get("vy", 0.0)
        vx = values["vx"] if "vx" in values else math.sqrt(max(v * v - vy * vy, 0.0))
        ax = values["ax"] if "ax" in values else ((v - v0) / h if h > 0 else 0.0)
        ay = values["ay"] if "ay" in values else v * yaw_rate
        if self._get_boolean is not None:
            stopped = False
            if not v >= STANDSTILL_SPEED:
                if self._get_boolean() > 1:
                    raise FmuError(f"the FMU refused to return its outputs at t = {time:.6f} s")
                stopped = bool(self._stopped_value[0])
        else:
            stopped = abs(v) < STOPPED_SPEED
        self._memory = (time, v, psi, distance, yaw_rate)
        return _make_state((time, x, y, psi, distance, v, vx, vy, ax, ay, yaw_rate, stopped))

    def read(self) -> EgoState:
        if not self._direct:
            return self._state
        if self._get_real() > 1:
            raise FmuError(f"the FMU refused to return its outputs at t = {self.time:.6f} s")
        values = self._output_values
        for quantity, value in zip(STATE_OUTPUTS, values):
            if not -OUTPUT_LIMIT <= value <= OUTPUT_LIMIT:
                self._bad_output(quantity, value)
        # `stopped` means held at standstill: it is asked for only below STANDSTILL_SPEED (one FMI call less)
        stopped = False
        if not values[SPEED] >= STANDSTILL_SPEED:
            if self._get_boolean is None:
                stopped = abs(values[SPEED]) < STOPPED_SPEED
            else:
                if self._get_boolean() > 1:
                    raise FmuError(f"the FMU refused to return its outputs at t = {self.time:.6f} s")
                stopped = self._stopped_value[0] != 0
        return _make_state((self.time, *values[:], stopped))

    # ---- inputs -----------------------------------------------------------------------------------------------

    def set_controls(self, throttle: float, brake: float, steer: float) -> None:
        """Pedals 0..1 and the road-wheel steering angle (rad, positive left), through the map's conversions."""
        values = self._control_values
        if self._control_identity:
            values[0], values[1], values[2] = throttle, brake, steer
        else:
            (a0, b0), (a1, b1), (a2, b2) = self._control_factors
            values[0], values[1], values[2] = a0 * throttle + b0, a1 * brake + b1, a2 * steer + b2
        if self._set_controls() > 1:
            raise FmuError(f"the FMU refused the controls throttle={throttle}, brake={brake}, steer={steer}")

    def set_friction(self, values) -> None:
        """Per wheel (fl, fr, rl, rr) in the model's friction meaning; per axle or for the car the mean of its
        wheels' mu, or the attribute of its first wheel (fl, rl). Nothing to do without a friction input."""
        friction = self.model.friction
        if friction is None:
            return
        count = len(friction.references)
        if count == 4:
            grouped = list(values)
        elif friction.meaning == "mu":
            grouped = [(values[0] + values[1]) / 2, (values[2] + values[3]) / 2] if count == 2 else [sum(values) / 4]
        else:
            grouped = [values[0], values[2]] if count == 2 else [values[0]]
        a, b = friction.scale, friction.offset
        if not (a == 1.0 and b == 0.0):
            grouped = [a * value + b for value in grouped]
        if friction.real:
            self._friction_values[:] = grouped
            if self._set_friction() > 1:
                raise FmuError(f"the FMU refused the friction values {grouped}")
        else:
            for kind, reference, value in zip(friction.types, friction.references, grouped):
                self._typed_set(kind, [reference], [value])

    # ---- time -------------------------------------------------------------------------------------------------

    def step_to(self, end: float) -> None:
        """Steps to exactly `end` (the communication point's time is `end` itself, not a sum of steps)."""
        if self._do_step(self._component, self.time, end - self.time, True) > 1:
            raise FmuError(f"{self._prefix}DoStep at t = {self.time:.6f} s (step {end - self.time:g} s) failed")
        self.time = end
        if not self._direct:
            self._state = self._derive(self._raw())

    def step(self, h: float) -> None:
        self.step_to(self.time + h)

    def save(self):
        """A snapshot of the instance (FMI GetFMUstate) to step again from, with the FMU's outputs at it."""
        spare = self._spare_states
        state = spare.pop() if spare else c_void_p()
        if self._get_state(self._component, byref(state)) > 1:
            raise FmuError(f"{self._prefix}GetFMUstate at t = {self.time:.6f} s failed")
        return state, self.time, None if self._direct else (self._memory, self._state), self._outputs_now()

    def _outputs_now(self) -> tuple:
        """The FMU's Real outputs as it returns them (the round-trip check of its state's save and restore)."""
        if self._get_real() > 1:
            raise FmuError(f"the FMU refused to return its outputs at t = {self.time:.6f} s")
        return tuple(self._output_values)

    def restore(self, snapshot) -> None:
        """Back to a snapshot; the FMU's outputs must be those it had when the snapshot was taken (an FMU that
        declares canGetAndSetFMUstate but restores nothing, or not all, would silently give other results)."""
        state, time, derived, outputs = snapshot
        if self._set_state(self._component, state) > 1:
            raise FmuError(f"{self._prefix}SetFMUstate to t = {time:.6f} s failed")
        now = self._outputs_now()
        # equal tuples: restored (one comparison in C); otherwise which output differs, a nan in both being equal
        changed = None if now == outputs else \
            next((i for i, (a, b) in enumerate(zip(now, outputs)) if a != b and not (a != a and b != b)), None)
        if changed is not None:
            quantity = self._real_outputs[changed]
            raise FmuError(f"it declares canGetAndSetFMUstate, but {self._prefix}SetFMUstate did not restore its state "
                           f"of t = {time:.6f} s: its output {self.model.outputs[quantity].variable!r} is "
                           f"{now[changed]:g} after the restore, {outputs[changed]:g} when the state was saved")
        self.time = time
        if derived is not None:
            self._memory, self._state = derived

    def discard(self, snapshot) -> None:
        if self._spare_states is not None:
            self._spare_states.append(snapshot[0])
        elif self._free_state(self._component, byref(snapshot[0])) > 1:
            raise FmuError(f"{self._prefix}FreeFMUstate failed")

    def close(self) -> None:
        """Terminates and frees the instance (the unpacked FMU stays for the process's other instances)."""
        if getattr(self, "slave", None) is None:
            return
        for state in getattr(self, "_spare_states", None) or ():
            self._free_state(self._component, byref(state))
        self._spare_states = None
        end_instance(self.slave)
        self.slave = None
        self._log.release()

    def __enter__(self) -> EgoInstance:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def end_instance(slave) -> None:
    """Terminates and frees an fmpy instance, whatever state it is in (closing after an error: its statuses are not
    the user's business then)."""
    try:
        slave.terminate()
    except Exception:
        pass
    try:
        slave.freeInstance()
    except Exception:
        pass


def _first_line(error: BaseException) -> str:
    text = str(error).strip() or type(error).__name__
    return text.splitlines()[0]
