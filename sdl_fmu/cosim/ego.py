"""The ego-vehicle FMU as the orchestrator sees it: one fmpy FMU2Slave instance, stepped with rollback."""

from __future__ import annotations

import functools
import shutil
from ctypes import byref, c_double, c_int, c_size_t, c_void_p
from pathlib import Path
from typing import Callable, NamedTuple

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2Boolean, fmi2Real, fmi2ValueReference

REAL_OUTPUTS = ("x", "y", "psi", "s", "v", "vx", "vy", "ax", "ay", "yaw_rate")
SPEED = REAL_OUTPUTS.index("v")
STANDSTILL_SPEED = 0.5  # m/s, far above the models' hold speeds (0.01 and 0.05 m/s): `stopped` is read below it


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


# EgoState._make without its Python-level length check (read() always passes all fields)
_make_state = functools.partial(tuple.__new__, EgoState)


def parameter_defaults(model_description) -> dict[str, float]:
    """Start values of the FMU's Real parameters, by name (SI)."""
    return {v.name: float(v.start) for v in model_description.modelVariables
            if v.causality == "parameter" and v.type == "Real"}


class FmuError(RuntimeError):
    """The FMU refused a call or could not be loaded."""


class EgoFMU:
    """An ego FMU instantiated for co-simulation, initialized with the given start values."""

    def __init__(self, fmu_path: str | Path, start_values: dict[str, float] | None = None, instance_name: str = "ego"):
        self.model_description = read_model_description(str(fmu_path))
        if self.model_description.fmiVersion != "2.0":
            raise FmuError(f"{fmu_path}: FMI {self.model_description.fmiVersion} FMU; the orchestrator co-simulates "
                           "FMI 2.0 FMUs (dist/fmi2/)")
        if self.model_description.coSimulation is None:
            raise FmuError(f"{fmu_path}: the FMU has no co-simulation interface")
        self.variables = {v.name: v for v in self.model_description.modelVariables}
        self._unzipped = extract(str(fmu_path))
        try:
            self.slave = FMU2Slave(
                guid=self.model_description.guid,
                unzipDirectory=self._unzipped,
                modelIdentifier=self.model_description.coSimulation.modelIdentifier,
                instanceName=instance_name,
            )
        except Exception as error:  # fmpy reports a binary that cannot be loaded as a plain Exception
            shutil.rmtree(self._unzipped, ignore_errors=True)
            raise FmuError(f"{fmu_path}: the FMU's binary cannot be loaded: {error}") from None
        self.time = 0.0
        try:
            self.slave.instantiate()
            self._bind_step_path()
            self.slave.setupExperiment(startTime=0.0)
            self.set(**(start_values or {}))
            self.slave.enterInitializationMode()
            self.slave.exitInitializationMode()
        except Exception:
            self.close()
            raise

    def _bind_step_path(self) -> None:
        """The per-step calls (doStep, the outputs, the inputs, the snapshots) bound once, with their ctypes
        buffers. fmpy's function objects declare pointer argtypes, whose conversion costs about 1 µs per
        call, behind a Python wrapper; the calls here go through function objects of their own without
        argtypes, so every argument must be (and is) a ctypes object of its C type: the c_void_p component,
        arrays of fmi2ValueReference and of the values, a c_size_t count, byref(c_void_p) for a state.
        doStep passes floats: it keeps argtypes."""
        dll = self.slave.dll
        component = c_void_p(self.slave.component)
        self._component = component

        def function(name: str, argtypes=None):
            function = dll[name]  # a new function object (fmpy's, dll.<name>, keeps its own argtypes)
            function.restype = c_int
            function.argtypes = argtypes
            return function

        self._do_step = function("fmi2DoStep", (c_void_p, c_double, c_double, c_int))
        self._output_values = (fmi2Real * len(REAL_OUTPUTS))()
        self._stopped_value = (fmi2Boolean * 1)()
        self._get_real = functools.partial(
            function("fmi2GetReal"), component,
            (fmi2ValueReference * len(REAL_OUTPUTS))(*(self.reference(name) for name in REAL_OUTPUTS)),
            c_size_t(len(REAL_OUTPUTS)), self._output_values)
        self._get_boolean = functools.partial(
            function("fmi2GetBoolean"), component, (fmi2ValueReference * 1)(self.reference("stopped")),
            c_size_t(1), self._stopped_value)
        self._set_real = function("fmi2SetReal")
        # the bisection's snapshots (an FMU state is a c_void_p, passed by reference to get and free)
        self._get_state, self._set_state, self._free_state = (
            function(name) for name in ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate"))

    def reference(self, name: str) -> int:
        try:
            return self.variables[name].valueReference
        except KeyError:
            known = ", ".join(v for v, d in self.variables.items() if d.causality in ("parameter", "input"))
            raise FmuError(f"the FMU has no variable {name!r} (parameters and inputs: {known})") from None

    def set(self, **values: float) -> None:
        """Sets inputs or (before initialization) parameters by name; Integer variables get ints."""
        reals, integers = {}, {}
        for name, value in values.items():
            vr = self.reference(name)
            kind = self.variables[name].type
            if kind == "Integer":
                integers[vr] = int(value)
            elif kind == "Real":
                reals[vr] = float(value)
            else:
                raise FmuError(f"{name} is {kind}; only Real and Integer variables can be set here")
        try:
            if reals:
                self.slave.setReal(list(reals), list(reals.values()))
            if integers:
                self.slave.setInteger(list(integers), list(integers.values()))
        except Exception as error:
            raise FmuError(f"the FMU refused the values {values}: {error}") from None

    def read(self) -> EgoState:
        if self._get_real() > 1:
            raise FmuError(f"the FMU refused to return its outputs at t = {self.time:.6f} s")
        values = self._output_values
        # `stopped` means held at standstill: both models zero the velocities while it holds (v == 0 exactly),
        # so it is asked for only below STANDSTILL_SPEED, not at every step (one FMI call less)
        stopped = False
        if not values[SPEED] >= STANDSTILL_SPEED:
            if self._get_boolean() > 1:
                raise FmuError(f"the FMU refused to return its outputs at t = {self.time:.6f} s")
            stopped = self._stopped_value[0] != 0
        return _make_state((self.time, *values[:], stopped))

    def real_setter(self, names: tuple[str, ...]) -> Callable[[tuple[float, ...]], None]:
        """A function that sets these Real inputs (values in this order) in one FMI call, its ctypes
        buffers made once: the master's per-step path (`set` is the general one)."""
        refs = (fmi2ValueReference * len(names))(*(self.reference(name) for name in names))
        if any(self.variables[name].type != "Real" for name in names):
            raise FmuError(f"real_setter: not all of {names} are Real variables")
        buffer = (fmi2Real * len(names))()
        call = functools.partial(self._set_real, self._component, refs, c_size_t(len(names)), buffer)

        def setter(values) -> None:
            buffer[:] = values
            if call() > 1:
                raise FmuError(f"the FMU refused the values {dict(zip(names, values))}")

        return setter

    def get(self, name: str) -> float:
        return self.slave.getReal([self.reference(name)])[0]

    def step(self, h: float) -> None:
        self.step_to(self.time + h)

    def step_to(self, end: float) -> None:
        """Steps to exactly `end` (the communication point's time is `end` itself, not a sum of steps)."""
        if self._do_step(self._component, self.time, end - self.time, 1) > 1:
            raise FmuError(f"fmi2DoStep at t = {self.time:.6f} s (step {end - self.time:g} s) failed")
        self.time = end

    def save(self):
        """A snapshot of the instance (FMI GetFMUstate) to step again from."""
        state = c_void_p()
        if self._get_state(self._component, byref(state)) > 1:
            raise FmuError(f"fmi2GetFMUstate at t = {self.time:.6f} s failed")
        return state, self.time

    def restore(self, snapshot) -> None:
        state, time = snapshot
        if self._set_state(self._component, state) > 1:
            raise FmuError(f"fmi2SetFMUstate to t = {time:.6f} s failed")
        self.time = time

    def discard(self, snapshot) -> None:
        if self._free_state(self._component, byref(snapshot[0])) > 1:
            raise FmuError("fmi2FreeFMUstate failed")

    def close(self) -> None:
        try:
            self.slave.terminate()
        except Exception:
            pass
        try:
            self.slave.freeInstance()
        except Exception:
            pass
        shutil.rmtree(self._unzipped, ignore_errors=True)


def step_until(ego: EgoFMU, h: float, condition, tolerance: float = 1e-9) -> bool:
    """Steps by h; if `condition(ego.read())` becomes true inside the step, rolls back and bisects so
    the instance ends just past the instant it became true (within `tolerance` seconds).
    Returns whether the condition became true in this step."""
    return step_until_time(ego, ego.time + h, condition, tolerance)


def step_until_time(ego: EgoFMU, end: float, condition, tolerance: float = 1e-9) -> bool:
    """step_until to the absolute time `end`, every probe stepped to an absolute time."""
    base = ego.save()  # the snapshot sits at time `low`
    low = ego.time
    ego.step_to(end)
    if not condition(ego.read()):
        ego.discard(base)
        return False
    high = end
    while high - low > tolerance:
        middle = 0.5 * (low + high)
        ego.restore(base)
        ego.step_to(middle)
        if condition(ego.read()):
            high = middle
        else:
            ego.discard(base)
            base, low = ego.save(), middle
    ego.restore(base)
    ego.step_to(high)
    ego.discard(base)
    return True
