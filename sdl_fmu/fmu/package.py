"""Builds an FMU: CasADi C code + generated table + generic runtime, compiled by gcc, zipped with its
modelDescription.xml and its sources (so any platform can rebuild it)."""

from __future__ import annotations

import importlib
import os
import shutil
import subprocess
import sys
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
# only the fmi* functions are exported: CasADi's generated functions stay internal to the library
EXPORT_FLAGS = ["-fvisibility=hidden", "-DCASADI_SYMBOL_EXPORT="]
# mingw-w64 cross compiler (Debian gcc-mingw-w64-x86-64); override with SDL_FMU_MINGW_CC
MINGW_COMPILER = "x86_64-w64-mingw32-gcc"
# binaries/<platform>/ per FMI version: (Linux, Windows)
PLATFORMS = {2: ("linux64", "win64"), 3: ("x86_64-linux", "x86_64-windows")}


class BuildError(RuntimeError):
    """The FMU could not be built (compiler missing or failing)."""


def fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def fmu_path(out_dir: Path, dynamics: str, fmi_version: int = 2) -> Path:
    return Path(out_dir) / f"fmi{fmi_version}" / f"{MODELS[dynamics][0]}.fmu"


def mingw_compiler() -> str | None:
    """The mingw-w64 cross compiler if it is installed, else None."""
    compiler = os.environ.get("SDL_FMU_MINGW_CC", MINGW_COMPILER)
    return compiler if shutil.which(compiler) else None


def compile_binary(sources_dir: Path, sources: list[str], output: Path, compiler: str | None = None,
                   windows: bool = False, extra_flags: tuple[str, ...] = ()) -> None:
    """Compiles the FMU's sources into one shared library: a Linux .so with gcc, or (windows=True) a Windows
    DLL with mingw-w64 whose runtime libraries are linked statically, so that it needs system DLLs only."""
    compile_binaries([dict(sources_dir=sources_dir, sources=sources, output=output, compiler=compiler,
                           windows=windows, extra_flags=extra_flags)])


def compile_binaries(jobs: list[dict]) -> None:
    """Runs several compile_binary jobs side by side (the Linux and the Windows binary of one FMU)."""
    running = []
    for job in jobs:
        compiler = job.get("compiler") or os.environ.get("CC", "gcc")
        if shutil.which(compiler) is None:
            raise BuildError(f"C compiler {compiler!r} not found: install gcc (Debian: apt-get install gcc)")
        sources_dir, output = job["sources_dir"], job["output"]
        output.parent.mkdir(parents=True, exist_ok=True)
        platform_flags = ["-static-libgcc", "-Wl,--no-insert-timestamp"] if job.get("windows") else ["-fPIC"]
        command = [compiler, "-std=c99", "-O2", *platform_flags, "-shared", *EXPORT_FLAGS, *WARNING_FLAGS,
                   *job.get("extra_flags", ()), f"-I{fmi_headers()}", f"-I{sources_dir}",
                   *[str(sources_dir / s) for s in job["sources"]], "-o", str(output), "-lm"]
        running.append((command, output, subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                                          text=True)))
    failures = []
    for command, output, process in running:
        _, stderr = process.communicate()
        if process.returncode != 0:
            failures.append(f"compiling {output.name} failed:\n{' '.join(command)}\n{stderr}")
    if failures:
        raise BuildError("\n".join(failures))


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
        linux, windows = PLATFORMS[fmi_version]
        jobs = [dict(sources_dir=sources_dir, sources=sources, output=root / "binaries" / linux / f"{model}.so")]
        cross = mingw_compiler()
        if cross:
            jobs.append(dict(sources_dir=sources_dir, sources=sources, compiler=cross, windows=True,
                             output=root / "binaries" / windows / f"{model}.dll"))
        else:
            wanted = os.environ.get("SDL_FMU_MINGW_CC", MINGW_COMPILER)
            print(f"sdl-fmu: {wanted} not found: {target.name} gets no Windows binary (Debian: apt-get install "
                  f"gcc-mingw-w64-x86-64)", file=sys.stderr)
        compile_binaries(jobs)

        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_suffix(".fmu.partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(root).as_posix())
        partial.replace(target)  # atomic: a failed build never leaves a half-written FMU
    return target
