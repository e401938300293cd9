"""Names every stage shares, defined once: the shipped models, the shipped controllers and the wheels. The build
side (dynamics/, controllers/, fmu/), the run side (vehicle/, cosim/), the output stage and the command line all read
them here; nothing here imports the rest of the package but paths.py.

A shipped model is a name (`--dynamics simple`), an FMU model name, the module of its equations
(`sdl_fmu.dynamics.<name>`) and a shipped vehicle map (`scenarios/vehicles/<name>.toml`). Adding one is an entry in
SHIPPED_MODELS, its module and its map. A shipped controller is the same with `sdl_fmu.controllers.<name>` (- as _)
and a controller map (`scenarios/controllers/<name>.toml`). The FMU cache builds both (BUILT).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, get_args

from .paths import CONTROLLER_MAP_DIRECTORY, VEHICLE_MAP_DIRECTORY

Dynamics = Literal["simple", "advanced"]  # the shipped models (the type checkers' spelling of SHIPPED)
SHIPPED: tuple[Dynamics, ...] = get_args(Dynamics)
# the shipped model -> its FMU's model name (modelIdentifier, and modelDescription/<model name>.json)
SHIPPED_MODELS: dict[Dynamics, str] = {"simple": "EgoVehicleSimple", "advanced": "EgoVehicleAdvanced"}
EXAMPLE_CONTROLLER = "example-aeb"  # --controller's name of the shipped example AEB (its cached FMU and its map)
# the shipped controller -> its FMU's model name
SHIPPED_CONTROLLERS: dict[str, str] = {EXAMPLE_CONTROLLER: "ExampleAeb"}
BUILT: dict[str, str] = {**SHIPPED_MODELS, **SHIPPED_CONTROLLERS}  # every FMU sdl-fmu builds, by name

WHEELS = ("fl", "fr", "rl", "rr")  # the wheels' order everywhere (FMU variables, contact points, results columns)


def equations_module(name: str) -> str:
    """The module whose equations() builds the shipped model or controller `name` (BUILT)."""
    if name in SHIPPED_CONTROLLERS:
        return f"{__package__}.controllers.{name.replace('-', '_')}"
    return f"{__package__}.dynamics.{name}"


def shipped_map_path(name: Dynamics) -> Path:
    """The shipped vehicle map of the shipped model `name` (`--dynamics name` means this map)."""
    return VEHICLE_MAP_DIRECTORY / f"{name}.toml"


def shipped_controller_map_path(name: str) -> Path:
    """The shipped controller map of the shipped controller `name`."""
    return CONTROLLER_MAP_DIRECTORY / f"{name}.toml"
