"""The ego-vehicle FMU as the orchestrator sees it: one fmpy FMU2Slave instance, stepped with rollback."""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

REAL_OUTPUTS = ("x", "y", "psi", "s", "v", "vx", "vy", "ax", "ay", "yaw_rate")


@dataclass(frozen=True)
class EgoState:
    """The ego's outputs at one instant (SI, ISO 8855 inertial frame)."""

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
        self._real_outputs = [self.reference(name) for name in REAL_OUTPUTS]
        self._stopped = [self.reference("stopped")]
        self.time = 0.0
        try:
            self.slave.instantiate()
            self.slave.setupExperiment(startTime=0.0)
            self.set(**(start_values or {}))
            self.slave.enterInitializationMode()
            self.slave.exitInitializationMode()
        except Exception:
            self.close()
            raise

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
        values = self.slave.getReal(self._real_outputs)
        stopped = bool(self.slave.getBoolean(self._stopped)[0])
        return EgoState(self.time, *values, stopped)

    def get(self, name: str) -> float:
        return self.slave.getReal([self.reference(name)])[0]

    def step(self, h: float) -> None:
        try:
            self.slave.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        except Exception as error:
            raise FmuError(f"fmi2DoStep at t = {self.time:.6f} s failed: {error}") from None
        self.time += h

    def save(self):
        """A snapshot of the instance (FMI GetFMUstate) to step again from."""
        return self.slave.getFMUstate(), self.time

    def restore(self, snapshot) -> None:
        state, self.time = snapshot
        self.slave.setFMUstate(state)

    def discard(self, snapshot) -> None:
        self.slave.freeFMUstate(snapshot[0])

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
    base = ego.save()  # the snapshot sits at offset `low` into the step
    ego.step(h)
    if not condition(ego.read()):
        ego.discard(base)
        return False
    low, high = 0.0, h
    while high - low > tolerance:
        middle = 0.5 * (low + high)
        ego.restore(base)
        ego.step(middle - low)
        if condition(ego.read()):
            high = middle
        else:
            ego.discard(base)
            base, low = ego.save(), middle
    ego.restore(base)
    ego.step(high - low)
    ego.discard(base)
    return True
