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

from .codegen import (RUNTIME_DIRECTORY, RUNTIME_HEADERS, RUNTIME_SOURCES, generate_casadi, generate_model_source,
                      model_guid, variable_table)
from .xml import build_description, model_description

# dynamics name -> (model name, module with equations())
MODELS = {
    "simple": ("EgoVehicleSimple", "sdl_fmu.dynamics.simple"),
    "advanced": ("EgoVehicleAdvanced", "sdl_fmu.dynamics.advanced"),
}
WARNING_FLAGS = ["-Wall", "-Wextra", "-Werror"]


class BuildError(RuntimeError):
    """The FMU could not be built (compiler missing or failing)."""


def fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def fmu_path(out_dir: Path, dynamics: str, fmi_version: int = 2) -> Path:
    return Path(out_dir) / f"fmi{fmi_version}" / f"{MODELS[dynamics][0]}.fmu"


def compile_binary(sources_dir: Path, sources: list[str], output: Path, compiler: str | None = None) -> None:
    compiler = compiler or os.environ.get("CC", "gcc")
    if shutil.which(compiler) is None:
        raise BuildError(f"C compiler {compiler!r} not found: install gcc (Debian: apt-get install gcc)")
    output.parent.mkdir(parents=True, exist_ok=True)
    command = [compiler, "-std=c99", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", *WARNING_FLAGS,
               f"-I{fmi_headers()}", f"-I{sources_dir}", *[str(sources_dir / s) for s in sources],
               "-o", str(output), "-lm"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"compiling {output.name} failed:\n{' '.join(command)}\n{result.stderr}")


def build_fmu(dynamics: str = "simple", out_dir: Path = Path("dist"), fmi_version: int = 2) -> Path:
    """Builds dist/fmi<version>/<Model>.fmu for one dynamics model and returns its path."""
    if fmi_version != 2:
        raise BuildError("only FMI 2.0 FMUs can be built so far")
    model, module = MODELS[dynamics]
    equations = importlib.import_module(module).equations()
    target = fmu_path(out_dir, dynamics, fmi_version)
    with tempfile.TemporaryDirectory(prefix=f"{model}-") as work:
        root = Path(work) / "fmu"
        sources_dir = root / "sources"
        sources_dir.mkdir(parents=True)
        for name in RUNTIME_SOURCES + RUNTIME_HEADERS:
            shutil.copy(RUNTIME_DIRECTORY / name, sources_dir / name)
        functions, casadi_source = generate_casadi(equations, sources_dir)
        guid = model_guid(equations.interface, casadi_source)
        model_source = generate_model_source(equations, functions, guid, sources_dir)
        sources = [*RUNTIME_SOURCES, model_source.name]
        (sources_dir / "buildDescription.xml").write_bytes(build_description(model, sources))
        table = variable_table(equations.interface)
        nz = functions["event_indicators"].size1_out(0)
        (root / "modelDescription.xml").write_bytes(model_description(equations.interface, table, guid, nz, sources))
        compile_binary(sources_dir, sources, root / "binaries" / "linux64" / f"{model}.so")

        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_suffix(".fmu.partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(root).as_posix())
        partial.replace(target)  # atomic: a failed build never leaves a half-written FMU
    return target
