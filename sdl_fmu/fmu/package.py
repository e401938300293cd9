"""Builds an FMU: CasADi C code + generated table + generic runtime, compiled by gcc (Linux) and mingw-w64
(Windows), zipped with its modelDescription.xml and its sources (so any platform can rebuild it)."""

from __future__ import annotations

import importlib
import inspect
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from .codegen import (RUNTIME_DIRECTORY, RUNTIME_HEADERS, generate_casadi, generate_derivatives_source,
                      generate_model_source, model_guid, runtime_sources, variable_table)
from .documentation import DOCUMENTATION, LICENSE_ENTRY, index_html, license_text
from .structure import declared_dependencies, reinitialized_states
from .xml import build_description, model_description, model_description_fmi3

if TYPE_CHECKING:
    from ..vehicle.vehicle_map import Dynamics

FmiVersion = Literal[2, 3]  # the FMI standard's major version an FMU is built for

# dynamics name -> (model name, module with equations())
MODELS = {
    "simple": ("EgoVehicleSimple", "sdl_fmu.dynamics.simple"),
    "advanced": ("EgoVehicleAdvanced", "sdl_fmu.dynamics.advanced"),
    "example-aeb": ("ExampleAeb", "sdl_fmu.controllers.example_aeb"),  # the shipped example controller
}
WARNING_FLAGS = ["-Wall", "-Wextra", "-Werror"]
# only the fmi* functions are exported: CasADi's generated functions stay internal to the library
EXPORT_FLAGS = ["-fvisibility=hidden", "-DCASADI_SYMBOL_EXPORT="]
# mingw-w64 cross compiler (Debian gcc-mingw-w64-x86-64); override with SDL_FMU_MINGW_CC
MINGW_COMPILER = "x86_64-w64-mingw32-gcc"
FMI_VERSIONS: tuple[FmiVersion, ...] = (2, 3)
# binaries/<platform>/ of each binary, as each FMI version names the platform
LINUX_BINARY_DIRECTORY = {2: "linux64", 3: "x86_64-linux"}
WINDOWS_BINARY_DIRECTORY = {2: "win64", 3: "x86_64-windows"}
# the standard's headers (BSD-2-Clause, shipped with fmpy), copied into sources/ so that one compiler line
# rebuilds the binary anywhere, without an FMI SDK
FMI_HEADERS = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
               3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}


class BuildError(RuntimeError):
    """The FMU could not be built (compiler missing or failing)."""


def fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def fmu_path(out_dir: Path, dynamics: Dynamics, fmi_version: FmiVersion = 2) -> Path:
    return Path(out_dir) / f"fmi{fmi_version}" / f"{MODELS[dynamics][0]}.fmu"


def mingw_compiler() -> str | None:
    """The mingw-w64 cross compiler if it is installed, else None."""
    compiler = os.environ.get("SDL_FMU_MINGW_CC", MINGW_COMPILER)
    return compiler if shutil.which(compiler) else None


def _compiler(compiler: str | None) -> str:
    compiler = compiler or os.environ.get("CC", "gcc")
    if shutil.which(compiler) is None:
        raise BuildError(f"C compiler {compiler!r} not found: install gcc (Debian: apt-get install gcc)")
    return compiler


def _compile_flags(sources_dir: Path, windows: bool, extra_flags: tuple[str, ...]) -> list[str]:
    position_independent = [] if windows else ["-fPIC"]  # Windows code is always position independent
    return ["-std=c99", "-O2", *position_independent, *EXPORT_FLAGS, *WARNING_FLAGS, *extra_flags,
            f"-I{fmi_headers()}", f"-I{sources_dir}"]


def _object_command(sources_dir: Path, source: str, output: Path, compiler: str | None = None,
                    windows: bool = False, extra_flags: tuple[str, ...] = ()) -> list[str]:
    output.parent.mkdir(parents=True, exist_ok=True)
    return [_compiler(compiler), *_compile_flags(sources_dir, windows, extra_flags), "-c", str(sources_dir / source),
            "-o", str(output)]


def _binary_command(sources_dir: Path, sources: list[str], output: Path, compiler: str | None = None,
                    objects: tuple[Path, ...] = (), windows: bool = False,
                    extra_flags: tuple[str, ...] = ()) -> list[str]:
    # a Windows DLL links libgcc statically, so that it needs system DLLs only (KERNEL32, msvcrt)
    link_flags = ["-static-libgcc", "-Wl,--no-insert-timestamp"] if windows else []
    output.parent.mkdir(parents=True, exist_ok=True)
    return [_compiler(compiler), *_compile_flags(sources_dir, windows, extra_flags), "-shared", *link_flags,
            *[str(sources_dir / s) for s in sources], *map(str, objects), "-o", str(output), "-lm"]


def _run_compilers(commands: list[list[str]]) -> None:
    """Runs compiler commands side by side (gcc and mingw-w64 at once); raises BuildError naming each failure."""
    running = [(command, subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
               for command in commands]
    failures = []
    for command, process in running:
        _, stderr = process.communicate()
        if process.returncode != 0:
            failures.append(f"compiling {Path(command[-1]).name} failed:\n{' '.join(command)}\n{stderr}")
    if failures:
        raise BuildError("\n".join(failures))


def compile_binary(sources_dir: Path, sources: list[str], output: Path, compiler: str | None = None,
                   objects: tuple[Path, ...] = (), windows: bool = False, extra_flags: tuple[str, ...] = ()) -> None:
    """Compiles and links the FMU's shared library (a Linux .so, or with windows=True and mingw-w64 a DLL);
    -lm last, so libm is a dependency of the binary itself."""
    _run_compilers([_binary_command(sources_dir, sources, output, compiler, objects, windows, extra_flags)])


def build_fmu(dynamics: Dynamics = "simple", out_dir: Path = Path("dist"), fmi_version: FmiVersion = 2) -> Path:
    """Builds dist/fmi<version>/<Model>.fmu (FMI 2.0 or 3.0) for one dynamics model and returns its path."""
    return build_fmus(dynamics, out_dir, (fmi_version,))[0]


def build_fmus(dynamics: Dynamics = "simple", out_dir: Path = Path("dist"),
               fmi_versions: tuple[FmiVersion, ...] = FMI_VERSIONS) -> list[Path]:
    """Builds the FMUs of one dynamics model in several FMI versions from one code generation; the model
    code (CasADi's C and the variable table) is compiled once per platform and linked into each version's
    binaries. Without mingw-w64, one line on stderr says so and the FMUs carry the Linux binary only."""
    for version in fmi_versions:
        if version not in FMI_VERSIONS:
            raise BuildError(f"FMI version {version!r} is not supported: choose one of "
                             f"{', '.join(map(str, FMI_VERSIONS))}")
    model, module = MODELS[dynamics]
    equations = importlib.import_module(module).equations()
    cross = mingw_compiler()
    if cross is None:
        wanted = os.environ.get("SDL_FMU_MINGW_CC", MINGW_COMPILER)
        print(f"sdl-fmu: {wanted} not found: the {model} FMUs get no Windows binary (Debian: apt-get install "
              f"gcc-mingw-w64-x86-64)", file=sys.stderr)
    targets = []
    with tempfile.TemporaryDirectory(prefix=f"{model}-") as work:
        generated = Path(work) / "generated"
        generated.mkdir()
        functions, casadi_source = generate_casadi(equations, generated)
        guid = model_guid(equations.interface, casadi_source)
        model_sources = [generate_model_source(equations, functions, guid, generated).name,
                         generate_derivatives_source(equations, generated).name]
        for name in RUNTIME_HEADERS:
            shutil.copy(RUNTIME_DIRECTORY / name, generated / name)
        # the model code, compiled once per platform (gcc and mingw-w64 side by side), linked into each version
        linux_objects = [Path(work) / "linux" / (Path(source).stem + ".o") for source in model_sources]
        windows_objects = [Path(work) / "windows" / (Path(source).stem + ".o") for source in model_sources]
        commands = [_object_command(generated, source, output) for source, output in zip(model_sources, linux_objects)]
        if cross:
            commands += [_object_command(generated, source, output, cross, windows=True)
                         for source, output in zip(model_sources, windows_objects)]
        _run_compilers(commands)
        nz = functions["event_indicators"].size1_out(0)
        table = variable_table(equations.interface, nz)
        dependencies = declared_dependencies(equations, table)

        roots, links = [], []
        for version in fmi_versions:
            root = Path(work) / f"fmi{version}"
            sources_dir = root / "sources"
            shutil.copytree(generated, sources_dir)
            for name in runtime_sources(version):
                shutil.copy(RUNTIME_DIRECTORY / name, sources_dir / name)
            for name in FMI_HEADERS[version]:
                shutil.copy(fmi_headers() / name, sources_dir / name)
            sources = [*runtime_sources(version), *model_sources]
            (sources_dir / "buildDescription.xml").write_bytes(build_description(model, sources))
            if version == 2:
                description = model_description(equations.interface, table, guid, nz, sources, dependencies)
            else:
                description = model_description_fmi3(equations.interface, table, guid, dependencies,
                                                     reinitialized_states(equations))
            (root / "modelDescription.xml").write_bytes(description)
            _write_documentation(root, equations, table, version, sources, module)
            runtime = list(runtime_sources(version))
            links.append(_binary_command(sources_dir, runtime,
                                         root / "binaries" / LINUX_BINARY_DIRECTORY[version] / f"{model}.so",
                                         objects=tuple(linux_objects)))
            if cross:
                links.append(_binary_command(sources_dir, runtime,
                                             root / "binaries" / WINDOWS_BINARY_DIRECTORY[version] / f"{model}.dll",
                                             cross, objects=tuple(windows_objects), windows=True))
            roots.append((root, fmu_path(out_dir, dynamics, version)))
        _run_compilers(links)
        targets = [_zip_fmu(root, target) for root, target in roots]
    return targets


def _write_documentation(root: Path, equations, table, version: int, sources: list[str], module: str) -> None:
    """documentation/index.html (from the interface, the table and the model module's docstring) and the
    licence under documentation/licenses/."""
    documentation = root / DOCUMENTATION
    documentation.parent.mkdir(parents=True)
    text = index_html(equations.interface, table, version, inspect.getdoc(importlib.import_module(module)) or "",
                      LINUX_BINARY_DIRECTORY[version], WINDOWS_BINARY_DIRECTORY[version], sources)
    documentation.write_text(text, encoding="utf-8")
    licence = root / LICENSE_ENTRY
    licence.parent.mkdir(parents=True)
    licence.write_text(license_text(), encoding="utf-8")


def _zip_fmu(root: Path, target: Path) -> Path:
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_suffix(".fmu.partial")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(root.rglob("*")):
            if path.is_file():
                archive.write(path, path.relative_to(root).as_posix())
    partial.replace(target)  # atomic: a failed build never leaves a half-written FMU
    return target
