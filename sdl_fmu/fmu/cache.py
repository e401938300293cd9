"""The per-user FMU cache: FMUs are built on first use, keyed by a hash of everything that goes into them.

Location: $SDL_FMU_CACHE if set, else $XDG_CACHE_HOME/sdl-fmu, else ~/.cache/sdl-fmu. One folder per
(model, FMI version, input hash) holds `fmi<version>/<Model>.fmu`. A changed model, interface, tire
file, runtime source, compiler or flag changes the hash, so a stale FMU is never found. Each build goes
into a private temporary folder inside the cache that is renamed into place in one step, so two
processes building at once never see or leave a half-built FMU; a process that finds a build of the same model in
progress waits for it (build_lock) instead of building the same FMU again. The temporary folder of a killed build is
removed by the next build.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Iterator

from .. import __version__, paths
from ..names import BUILT, SHIPPED_CONTROLLERS, Dynamics
from .package import FmiVersion, build_fmus, fmu_path, mingw_compiler

# cache_directory and CACHE_VARIABLE: where the run side finds the cache too
from ..paths import CACHE_VARIABLE, cache_directory, made_cache_directory  # noqa: F401

BUILD_SUFFIXES = {".py", ".json", ".c", ".h", ".tir", ".txt"}


@functools.lru_cache(maxsize=None)
def compiler_identity(compiler: str) -> str:
    """The compiler's own version banner (a different gcc builds a different binary)."""
    try:
        completed = subprocess.run([compiler, "--version"], capture_output=True, text=True, timeout=30)
        return completed.stdout
    except (OSError, subprocess.SubprocessError) as error:
        return f"unavailable: {error}"  # build_fmu reports the missing compiler itself


def build_inputs(dynamics: Dynamics = "simple") -> dict[str, Path]:
    """Everything a build of `dynamics` reads, by its place in the checkout (the same in any install): the model and
    build code, the interface data, the tire files the Advanced FMU's start values come from, the C runtime; for a
    controller (sdl_fmu/controllers/) its module too."""
    package = paths.PACKAGE_DIRECTORY
    inputs = {"sdl_fmu/interface.py": package / "interface.py", "sdl_fmu/units.py": package / "units.py",
              "sdl_fmu/names.py": package / "names.py", "sdl_fmu/tire_files.py": package / "tire_files.py",
              "sdl_fmu/dynamics": package / "dynamics", "sdl_fmu/fmu": package / "fmu",
              "modelDescription": paths.MODEL_DESCRIPTION_DIRECTORY, "scenarios/tires": paths.TIRE_DIRECTORY}
    if dynamics in SHIPPED_CONTROLLERS:
        inputs["sdl_fmu/controllers"] = package / "controllers"
    return inputs


def _input_files(dynamics: Dynamics = "simple") -> list[tuple[str, Path]]:
    """(name in the key, file) of every build input; another model's interface data is not one."""
    others = {f"modelDescription/{model}.json" for name, model in BUILT.items() if name != dynamics}
    files = []
    for name, path in build_inputs(dynamics).items():
        candidates = sorted(path.rglob("*")) if path.is_dir() else [path]
        files += [(f"{name}/{f.relative_to(path).as_posix()}" if path.is_dir() else name, f) for f in candidates
                  if f.is_file() and f.suffix in BUILD_SUFFIXES and "__pycache__" not in f.parts]
    return [(name, f) for name, f in files if name not in others]


def build_key(dynamics: Dynamics, fmi_version: FmiVersion = 2) -> str:
    """SHA-256 of every input of one FMU build: sources, data, compiler identity and flags, versions."""
    import casadi
    import fmpy

    digest = hashlib.sha256()
    compiler = os.environ.get("CC", "gcc")
    cross_compiler = mingw_compiler()  # None: the FMU gets no Windows binary, a different FMU
    for part in (f"sdl-fmu {__version__}", f"model {BUILT[dynamics]}", f"fmi {fmi_version}",
                 f"casadi {casadi.__version__}", f"fmpy {fmpy.__version__}", f"CC {compiler}",
                 compiler_identity(compiler), f"mingw {cross_compiler}",
                 compiler_identity(cross_compiler) if cross_compiler else ""):
        digest.update(part.encode() + b"\0")
    for name, path in _input_files(dynamics):
        digest.update(name.encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def remove_abandoned_builds(root: Path) -> None:
    """Temporary build folders of processes that no longer exist (killed during a build)."""
    for folder in root.glob(".building-*-*"):
        pid = folder.name.split("-")[1]
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            shutil.rmtree(folder, ignore_errors=True)
        except OSError:
            pass  # alive, someone else's


@contextlib.contextmanager
def build_lock(name: str) -> Iterator[None]:
    """Held while the cache builds `name` (a model): a second process (or thread) building it waits here for the build
    in progress, then finds its result instead of building it again. An advisory lock (flock) on the file
    .lock-<name> in the cache, released by the system if its holder dies; the holder removes the file (a waiter that
    locked a removed file locks the new one), so the cache holds no lock file between builds. Without flock
    (Windows) there is no waiting: the renames into place still keep the cache whole."""
    root = made_cache_directory()
    try:
        import fcntl
    except ImportError:
        yield
        return
    path = root / f".lock-{name}"
    while True:
        handle = open(path, "a")
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            if os.stat(path).st_ino == os.fstat(handle.fileno()).st_ino:
                break  # the file in place is the one locked
        except FileNotFoundError:
            pass  # its holder removed it on the way out: lock the next one
        handle.close()
    try:
        yield
    finally:
        os.unlink(path)  # before the unlock: a waiter on this file retries on a new one
        handle.close()


def _cache_folder(dynamics: Dynamics, fmi_version: FmiVersion) -> Path:
    key = build_key(dynamics, fmi_version)
    return cache_directory() / f"{BUILT[dynamics]}-fmi{fmi_version}-{key[:24]}"


def cached_fmus(dynamics: Dynamics = "simple", fmi_versions: tuple[FmiVersion, ...] = (2,),
                announce=None) -> list[Path]:
    """The FMUs of these dynamics in these FMI versions from the cache; the missing ones are built together
    (one code generation, announced through `announce(path)`) and each is renamed into its own folder."""
    folders = {version: _cache_folder(dynamics, version) for version in fmi_versions}
    targets = {version: fmu_path(folder, dynamics, version) for version, folder in folders.items()}
    missing = tuple(version for version, target in targets.items() if not target.is_file())
    if not missing:
        return [targets[version] for version in fmi_versions]
    made_cache_directory()  # a cache that cannot be written: one line before the build is announced
    if announce is not None:
        announce(targets[missing[0]])
    with build_lock(BUILT[dynamics]):  # a build of this model in progress elsewhere: wait for it
        missing = tuple(version for version, target in targets.items() if not target.is_file())
        if missing:
            _build_into_cache(dynamics, missing, folders, targets)
    return [targets[version] for version in fmi_versions]


def _build_into_cache(dynamics: Dynamics, missing: tuple[FmiVersion, ...], folders: dict, targets: dict) -> None:
    """Builds the missing FMI versions together into a temporary folder and renames each into its cache folder."""
    root = cache_directory()
    remove_abandoned_builds(root)
    work = Path(tempfile.mkdtemp(prefix=f".building-{os.getpid()}-", dir=root))
    try:
        build_fmus(dynamics, work / "all", missing)
        for version in missing:
            staging = work / f"fmi{version}-entry"
            fmu_path(staging, dynamics, version).parent.mkdir(parents=True)
            os.rename(fmu_path(work / "all", dynamics, version), fmu_path(staging, dynamics, version))
            try:
                os.rename(staging, folders[version])  # atomic; fails if another process got there first
            except OSError:
                if not targets[version].is_file():
                    raise
    finally:
        shutil.rmtree(work, ignore_errors=True)


def cached_fmu(dynamics: Dynamics = "simple", fmi_version: FmiVersion = 2, announce=None) -> Path:
    """The FMU for these dynamics from the cache, built (and announced through `announce(path)`) if missing."""
    return cached_fmus(dynamics, (fmi_version,), announce)[0]
