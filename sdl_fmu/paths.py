"""Where the package's files are: every reader of the shipped scenarios, vehicle table, tire files, vehicle maps
and interface data finds them here.

In the checkout they sit at the top level, scenarios/ and modelDescription/ beside sdl_fmu/; pyproject.toml maps
them to the packages sdl_fmu.scenarios and sdl_fmu.modelDescription. A wheel (`pip install .`) copies them into
the installed package, an editable install (`pip install -e .`) maps them to the checkout, and
importlib.resources finds them in both. A checkout put on PYTHONPATH without an install of its own has no such
mapping: importlib.resources then finds nothing, or another install's copy, so the checkout's own top-level
folder is used. Nothing here imports the rest of the package.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

PACKAGE_DIRECTORY = Path(str(resources.files(__package__)))


def _data_directory(name: str) -> Path:
    """The folder of the package data sdl_fmu.<name> that belongs to this copy of sdl_fmu."""
    inside, beside = PACKAGE_DIRECTORY / name, PACKAGE_DIRECTORY.parent / name  # a wheel's, a checkout's
    try:
        found = resources.files(f"{__package__}.{name}")
    except (ImportError, OSError):  # not installed; or a stale editable install's map to a folder now gone
        return beside
    if isinstance(found, Path) and found.resolve() in (inside.resolve(), beside.resolve()):
        return found
    return beside


SCENARIO_DIRECTORY = _data_directory("scenarios")  # shipped examples, the vehicle table, tires/, vehicles/
TIRE_DIRECTORY = SCENARIO_DIRECTORY / "tires"  # Tire Attribute File and the .tir files it names
VEHICLE_MAP_DIRECTORY = SCENARIO_DIRECTORY / "vehicles"  # the shipped models' vehicle maps, <name>.toml
CONTROLLER_MAP_DIRECTORY = SCENARIO_DIRECTORY / "controllers"  # the shipped controllers' maps, <name>.toml
VEHICLE_TABLE = SCENARIO_DIRECTORY / "vehicles.csv"
MODEL_DESCRIPTION_DIRECTORY = _data_directory("modelDescription")  # <Model>.json and units.json


CACHE_VARIABLE = "SDL_FMU_CACHE"


def cache_directory() -> Path:
    """Where built FMUs (and the user's other sdl-fmu state: the ownership key) are kept for this user:
    $SDL_FMU_CACHE, else $XDG_CACHE_HOME/sdl-fmu, else ~/.cache/sdl-fmu."""
    import os

    if os.environ.get(CACHE_VARIABLE):
        return Path(os.environ[CACHE_VARIABLE]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "sdl-fmu"


def made_cache_directory() -> Path:
    """cache_directory(), made if missing, for a build or a shipped file about to be written there; an InputError
    (option "cache") naming the folder and where its name comes from if it cannot be made or written."""
    import os

    from .options import InputError

    root = cache_directory()
    try:
        root.mkdir(parents=True, exist_ok=True)
        if not os.access(root, os.W_OK | os.X_OK):
            raise PermissionError(13, "Permission denied")
    except OSError as error:
        source = f"${CACHE_VARIABLE}" if os.environ.get(CACHE_VARIABLE) else \
            "$XDG_CACHE_HOME/sdl-fmu" if os.environ.get("XDG_CACHE_HOME") else "~/.cache/sdl-fmu"
        raise InputError("cache", f"the FMU cache {root} ({source}): cannot write there: "
                                  f"{error.strerror or error}") from None
    return root
