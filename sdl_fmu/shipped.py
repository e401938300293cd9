"""The shipped models and controllers on the run side: each one's FMU from the per-user cache, built on first use,
with its shipped vehicle or controller map. This joins the build side (fmu/) and the run side (vehicle/) from above,
so neither imports the other."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Callable

from .names import Dynamics, shipped_controller_map_path, shipped_map_path
from .vehicle import EgoModel


def announce_build(path: Path) -> None:
    """The one line a build on first use prints on stderr (a terminal also gets the build's progress bar)."""
    print(f"building {path.name} into the cache {path.parent.parent} (first use)", file=sys.stderr)


def shipped_fmu(name: Dynamics | str = "simple", fmi_version: int = 2,
                announce: Callable[[Path], None] | None = announce_build) -> Path:
    """The cached FMU of the shipped model or controller `name` (names.BUILT) in this FMI version, built (and
    announced) if missing."""
    from .fmu.cache import cached_fmu  # the build side: CasADi and the compilers, loaded only to build or look up

    return cached_fmu(name, fmi_version, announce=announce)


def shipped_model(name: Dynamics = "simple", fmi_version: int = 2,
                  announce: Callable[[Path], None] | None = None) -> EgoModel:
    """A shipped model: its cached build (built on first use) driven through its shipped map."""
    return EgoModel.open(shipped_fmu(name, fmi_version, announce), shipped_map_path(name))


def shipped_controller(name: str) -> tuple[Path, Path]:
    """(FMU, controller map) of a shipped controller (names.SHIPPED_CONTROLLERS): its cached build (built on first
    use) and its shipped map."""
    return shipped_fmu(name), shipped_controller_map_path(name)
