"""Builds an FMU: CasADi C code + generated table + generic runtime, compiled by gcc, zipped with its
modelDescription.xml and its sources (so any platform can rebuild it)."""

from __future__ import annotations

import importlib
import os
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

from .codegen import (RUNTIME_DIRECTORY, RUNTIME_HEADERS, generate_casadi, generate_derivatives_source,
                      generate_model_source, model_guid, runtime_sources, variable_table)
from .structure import declared_dependencies, reinitialized_states
from .xml import build_description, model_description, model_description_fmi3

# dynamics name -> (model name, module with equations())
MODELS = {
    "simple": ("EgoVehicleSimple", "sdl_fmu.dynamics.simple"),
    "advanced": ("EgoVehicleAdvanced", "sdl_fmu.dynamics.advanced"),
}
WARNING_FLAGS = ["-Wall", "-Wextra", "-Werror"]
FMI_VERSIONS = (2, 3)
# binaries/<platform>/ of this machine's binary, as each FMI version names the platform
LINUX_BINARY_DIRECTORY = {2: "linux64", 3: "x86_64-linux"}
# the standard's headers (BSD-2-Clause, shipped with fmpy), copied into sources/ so that one compiler line
# rebuilds the binary anywhere, without an FMI SDK
FMI_HEADERS = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
               3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}


class BuildError(RuntimeError):
    """The FMU could not be built (compiler missing or failing)."""


def fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def fmu_path(out_dir: Path, dynamics: str, fmi_version: int = 2) -> Path:
    return Path(out_dir) / f"fmi{fmi_version}" / f"{MODELS[dynamics][0]}.fmu"


def _compiler(compiler: str | None) -> str:
    compiler = compiler or os.environ.get("CC", "gcc")
    if shutil.which(compiler) is None:
        raise BuildError(f"C compiler {compiler!r} not found: install gcc (Debian: apt-get install gcc)")
    return compiler


def _run_compiler(command: list[str], output: Path) -> None:
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"compiling {output.name} failed:\n{' '.join(command)}\n{result.stderr}")


def _compile_flags(sources_dir: Path) -> list[str]:
    return ["-std=c99", "-O2", "-fPIC", "-fvisibility=hidden", *WARNING_FLAGS, f"-I{fmi_headers()}",
            f"-I{sources_dir}"]


def compile_objects(sources_dir: Path, sources: list[str], directory: Path, compiler: str | None = None) -> list[Path]:
    """Compiles sources into objects side by side (one compiler process each), e.g. the model code that the
    FMI 2.0 and 3.0 binaries share."""
    compiler = _compiler(compiler)
    directory.mkdir(parents=True, exist_ok=True)
    jobs = []
    for source in sources:
        output = directory / (Path(source).stem + ".o")
        command = [compiler, *_compile_flags(sources_dir), "-c", str(sources_dir / source), "-o", str(output)]
        jobs.append((command, output, subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                                        text=True)))
    failures = []
    for command, output, process in jobs:
        _, errors = process.communicate()
        if process.returncode != 0:
            failures.append(f"compiling {output.name} failed:\n{' '.join(command)}\n{errors}")
    if failures:
        raise BuildError("\n".join(failures))
    return [output for _, output, _ in jobs]


def compile_binary(sources_dir: Path, sources: list[str], output: Path, compiler: str | None = None,
                   objects: tuple[Path, ...] = ()) -> None:
    """Compiles and links the FMU's shared library; -lm last, so libm is a dependency of the binary itself."""
    compiler = _compiler(compiler)
    output.parent.mkdir(parents=True, exist_ok=True)
    command = [compiler, *_compile_flags(sources_dir), "-shared", *[str(sources_dir / s) for s in sources],
               *map(str, objects), "-o", str(output), "-lm"]
    _run_compiler(command, output)


def build_fmu(dynamics: str = "simple", out_dir: Path = Path("dist"), fmi_version: int = 2) -> Path:
    """Builds dist/fmi<version>/<Model>.fmu (FMI 2.0 or 3.0) for one dynamics model and returns its path."""
    return build_fmus(dynamics, out_dir, (fmi_version,))[0]


def build_fmus(dynamics: str = "simple", out_dir: Path = Path("dist"),
               fmi_versions: tuple[int, ...] = FMI_VERSIONS) -> list[Path]:
    """Builds the FMUs of one dynamics model in several FMI versions from one code generation; the model
    code (CasADi's C and the variable table) is compiled once and linked into each version's binary."""
    for version in fmi_versions:
        if version not in FMI_VERSIONS:
            raise BuildError(f"FMI version {version!r} is not supported: choose one of "
                             f"{', '.join(map(str, FMI_VERSIONS))}")
    model, module = MODELS[dynamics]
    equations = importlib.import_module(module).equations()
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
        model_objects = compile_objects(generated, model_sources, Path(work) / "objects")
        nz = functions["event_indicators"].size1_out(0)
        table = variable_table(equations.interface, nz)
        dependencies = declared_dependencies(equations, table)

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
            compile_binary(sources_dir, list(runtime_sources(version)),
                           root / "binaries" / LINUX_BINARY_DIRECTORY[version] / f"{model}.so",
                           objects=tuple(model_objects))
            targets.append(_zip_fmu(root, fmu_path(out_dir, dynamics, version)))
    return targets


def _zip_fmu(root: Path, target: Path) -> Path:
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_suffix(".fmu.partial")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(root.rglob("*")):
            if path.is_file():
                archive.write(path, path.relative_to(root).as_posix())
    partial.replace(target)  # atomic: a failed build never leaves a half-written FMU
    return target
