"""The ego FMU as the master steps it: the stepping with rollback (bisection of a trigger's instant), and EgoFMU,
an instance of an FMU with the shipped models' interface (docs/fmu-runtime.md, Variables) addressed by variable
name, for the FMU-level tests and tools. The instance itself is sdl_fmu.vehicle's EgoInstance."""

from __future__ import annotations

import tomllib
from functools import cache
from pathlib import Path

from ..vehicle import EgoInstance, EgoModel, EgoState, FmuError, parameter_defaults, read_description, shipped_map_path
from ..vehicle.vehicle_map import parse_vehicle_map
from .locate import first_instant

__all__ = ["EgoFMU", "EgoState", "FmuError", "parameter_defaults", "step_until", "step_until_time"]

@cache
def spec_interface() -> dict:
    """The interface common to the shipped FMUs (docs/fmu-runtime.md), as a vehicle map: the shipped Simple map's
    inputs (but its friction: the shipped FMUs' friction inputs differ, and EgoFMU sets them by name), outputs, start
    values and footprint."""
    data = tomllib.loads(shipped_map_path("simple").read_text(encoding="utf-8"))
    return {"inputs": {key: value for key, value in data["inputs"].items() if key != "friction"},
            "outputs": data["outputs"], "start": data["start"],
            "vehicle": {key: data["vehicle"][key] for key in ("length", "width")}}


class EgoFMU(EgoInstance):
    """An FMU with the shipped FMUs' common interface, instantiated and initialized with start values by variable
    name."""

    def __init__(self, fmu_path: str | Path, start_values: dict[str, float] | None = None, instance_name: str = "ego"):
        try:
            model = EgoModel(Path(fmu_path), parse_vehicle_map(spec_interface(), complete=False),
                             read_description(Path(fmu_path)))
        except ValueError as error:  # VehicleMapError: not an FMU of this interface
            raise FmuError(str(error)) from None
        super().__init__(model, {}, dict(start_values or {}), instance_name)
        self.model_description = model.description
        self.variables = model.variables

    def reference(self, name: str) -> int:
        try:
            return self.variables[name].valueReference
        except KeyError:
            known = ", ".join(v for v, d in self.variables.items() if d.causality in ("parameter", "input"))
            raise FmuError(f"the FMU has no variable {name!r} (parameters and inputs: {known})") from None

    def set(self, **values: float) -> None:
        """Sets inputs or (before initialization) parameters by name."""
        for name in values:
            self.reference(name)  # an unknown name is an FmuError naming it
        self._set_by_name(values)

    def get(self, name: str) -> float:
        return self.slave.getFloat64([self.reference(name)])[0] if self.fmi3 else \
            self.slave.getReal([self.reference(name)])[0]


def step_until(ego: EgoInstance, h: float, condition, tolerance: float = 1e-9) -> bool:
    """Steps by h; if `condition(ego.read())` becomes true inside the step, rolls back and bisects so
    the instance ends just past the instant it became true (within `tolerance` seconds).
    Returns whether the condition became true in this step."""
    return step_until_time(ego, ego.time + h, condition, tolerance)


def step_until_time(ego: EgoInstance, end: float, condition, tolerance: float = 1e-9) -> bool:
    """step_until to the absolute time `end`, every probe stepped to an absolute time from a snapshot at the
    bracket's low end (locate.first_instant)."""
    snapshot = ego.save()  # the snapshot sits at the bracket's low end
    low = ego.time
    ego.step_to(end)
    if not condition(ego.read()):
        ego.discard(snapshot)
        return False

    def probe(t: float) -> EgoState:
        ego.restore(snapshot)
        ego.step_to(t)
        return ego.read()

    def below(t: float) -> None:  # the condition is false at t, where the instance now is: the snapshot moves here
        nonlocal snapshot
        ego.discard(snapshot)
        snapshot = ego.save()

    high, _, _ = first_instant(probe, low, end, condition, tolerance, below=below)
    ego.restore(snapshot)
    ego.step_to(high)
    ego.discard(snapshot)
    return True
