"""Builds an FMU: CasADi C code + generated table + generic runtime, compiled by gcc (Linux) and mingw-w64
(Windows), zipped with its modelDescription.xml and its sources (so any platform can rebuild it)."""

from __future__ import annotations

import concurrent.futures
import importlib
import inspect
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Literal

from ..names import BUILT, Dynamics, equations_module
from .codegen import (RUNTIME_DIRECTORY, RUNTIME_HEADERS, generate_casadi, generate_derivatives_source,
                      generate_model_source, model_guid, runtime_sources, variable_table)
from .documentation import DOCUMENTATION, LICENSE_ENTRY, index_html, license_text
from .structure import declared_dependencies, reinitialized_states
from .xml import build_description, model_description, model_description_fmi3

FmiVersion = Literal[2, 3]  # the FMI standard's major version an FMU is built for

WARNING_FLAGS = ["-Wall", "-Wextra", "-Werror"]
# Optimisation: -O2 for the runtime and the model functions (<Model>_model.c, MODEL_OPTIMIZATION) the solver calls
# every step; -O0 for the derivative sweeps (<Model>_derivatives.c), which only fmi2GetDirectionalDerivative /
# fmi3GetDirectionalDerivative / fmi3GetAdjointDerivative call. Nearly all of a build is gcc and mingw-w64 on the
# Advanced FMU's generated C: its 5.2 MB of model functions took 104 s of gcc CPU at -O2, 65 s at -O1, 47 s at -O0
# (side by side on a loaded machine), and give the same bits at every level (IEEE double in SSE2, -std=c99 keeps
# -ffp-contract=off, no -ffast-math); but at -O1 a co-simulation step of the Advanced FMU took 1.75 to 2.2 times as
# long (a model-exchange interval 1.2 times), so the model functions stay at -O2 (docs/fmu-runtime.md, The FMU cache).
OPTIMIZATION = "-O2"
MODEL_OPTIMIZATION = "-O2"
DERIVATIVES_OPTIMIZATION = "-O0"
# only the fmi* functions are exported: CasADi's generated functions stay internal to the library
EXPORT_FLAGS = ["-fvisibility=hidden", "-DCASADI_SYMBOL_EXPORT="]
# mingw-w64 cross compiler (Debian gcc-mingw-w64-x86-64); override with SDL_FMU_MINGW_CC
MINGW_COMPILER = "x86_64-w64-mingw32-gcc"
FMI_VERSIONS: tuple[FmiVersion, ...] = (2, 3)
# binaries/<platform>/ of each binary, as each FMI version names the platform
LINUX_BINARY_DIRECTORY = {2: "linux64", 3: "x86_64-linux"}
WINDOWS_BINARY_DIRECTORY = {2: "win64", 3: "x86_64-windows"}
# the date of every entry of an FMU's zip (the zip format's earliest): an FMU does not change with the clock
ZIP_DATE = (1980, 1, 1, 0, 0, 0)
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
    return Path(out_dir) / f"fmi{fmi_version}" / f"{BUILT[dynamics]}.fmu"


def mingw_compiler() -> str | None:
    """The mingw-w64 cross compiler if it is installed, else None."""
    compiler = os.environ.get("SDL_FMU_MINGW_CC", MINGW_COMPILER)
    return compiler if shutil.which(compiler) else None


def _compiler(compiler: str | None) -> str:
    compiler = compiler or os.environ.get("CC", "gcc")
    if shutil.which(compiler) is None:
        raise BuildError(f"C compiler {compiler!r} not found: install gcc (Debian: apt-get install gcc)")
    return compiler


def _compile_flags(sources_dir: Path, windows: bool, extra_flags: tuple[str, ...],
                   optimization: str = OPTIMIZATION) -> list[str]:
    position_independent = [] if windows else ["-fPIC"]  # Windows code is always position independent
    return ["-std=c99", optimization, *position_independent, *EXPORT_FLAGS, *WARNING_FLAGS, *extra_flags,
            f"-I{fmi_headers()}", f"-I{sources_dir}"]


def _object_command(sources_dir: Path, source: str, output: Path, compiler: str | None = None,
                    windows: bool = False, extra_flags: tuple[str, ...] = (),
                    optimization: str = OPTIMIZATION) -> list[str]:
    output.parent.mkdir(parents=True, exist_ok=True)
    return [_compiler(compiler), *_compile_flags(sources_dir, windows, extra_flags, optimization), "-c",
            str(sources_dir / source), "-o", str(output)]


def binary_command(sources_dir: Path, sources: list[str], output: Path, compiler: str | None = None,
                   objects: tuple[Path, ...] = (), windows: bool = False,
                   extra_flags: tuple[str, ...] = ()) -> list[str]:
    """The compiler line that compiles `sources` (in `sources_dir`) with `objects` into the shared library `output`
    (a Linux .so, or with windows=True and a mingw-w64 `compiler` a DLL); -lm last, so that libm is a dependency of
    the binary itself."""
    # a Windows DLL links libgcc statically, so that it needs system DLLs only (KERNEL32, msvcrt)
    link_flags = ["-static-libgcc", "-Wl,--no-insert-timestamp"] if windows else []
    output.parent.mkdir(parents=True, exist_ok=True)
    return [_compiler(compiler), *_compile_flags(sources_dir, windows, extra_flags), "-shared", *link_flags,
            *[str(sources_dir / s) for s in sources], *map(str, objects), "-o", str(output), "-lm"]


def run_compilers(commands: list[list[str]], progress: _Progress | None = None) -> None:
    """Runs compiler commands side by side (gcc and mingw-w64 at once, each file its own process); raises
    BuildError naming each failure by the file the command writes (its -o argument). `progress` advances as each
    command ends. The compilers' own temporary files go into a private folder (their $TMPDIR), removed once they have
    all ended: a compiler interrupted mid-way (Ctrl-C reaches the whole process group) can leave its assembler file
    (ccXXXXXX.s), which would otherwise stay in the user's $TMPDIR."""
    failures = []
    scratch = tempfile.mkdtemp(prefix="sdl-fmu-cc-")
    environment = {**os.environ, "TMPDIR": scratch}
    try:
        with concurrent.futures.ThreadPoolExecutor(max_workers=max(len(commands), 1)) as pool:
            running = {pool.submit(subprocess.run, command, capture_output=True, text=True, env=environment): command
                       for command in commands}
            for done in concurrent.futures.as_completed(running):
                command, completed = running[done], done.result()
                if completed.returncode != 0:
                    failures.append(f"compiling {_output_of(command)} failed:\n{' '.join(command)}\n"
                                    f"{completed.stderr}")
                if progress is not None:
                    progress.advance()
    finally:
        shutil.rmtree(scratch, ignore_errors=True)  # after the pool: every compiler has ended
    if failures:
        raise BuildError("\n".join(failures))


def _output_of(command: list[str]) -> str:
    """The name of the file a compiler command writes (the argument after -o; a link line ends with -lm)."""
    return Path(command[command.index("-o") + 1]).name if "-o" in command[:-1] else command[0]


class _Progress:
    """The build's progress on stderr, on a terminal only (elsewhere nothing, so that what tests read from stderr
    stays the same): a tqdm bar over the build's steps (the code generation, each compiler run, each FMU's zip),
    labelled with the stage and its elapsed time. A compiler run is one step whatever its length: the bar shows
    that the build is alive and how far it is, not a time estimate."""

    def __init__(self, model: str, total: int, enabled: bool | None):
        self.model = model
        self.bar = None
        if enabled if enabled is not None else sys.stderr.isatty():
            from tqdm import tqdm

            # every step drawn (a few dozen at most); the terminal's width, 80 where it reports none
            self.bar = tqdm(total=total, file=sys.stderr, leave=False, unit="step", mininterval=0,
                            ncols=shutil.get_terminal_size().columns,
                            bar_format="{desc}: {bar} {n_fmt}/{total_fmt} steps, {elapsed}")

    def stage(self, text: str) -> None:
        if self.bar is not None:
            self.bar.set_description_str(f"{self.model}: {text}")

    def advance(self) -> None:
        if self.bar is not None:
            self.bar.update()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def compile_binary(sources_dir: Path, sources: list[str], output: Path, compiler: str | None = None,
                   objects: tuple[Path, ...] = (), windows: bool = False, extra_flags: tuple[str, ...] = ()) -> None:
    """Compiles and links the FMU's shared library (a Linux .so, or with windows=True and mingw-w64 a DLL);
    -lm last, so libm is a dependency of the binary itself."""
    run_compilers([binary_command(sources_dir, sources, output, compiler, objects, windows, extra_flags)])


def build_fmu(dynamics: Dynamics = "simple", out_dir: Path = Path("dist"), fmi_version: FmiVersion = 2) -> Path:
    """Builds dist/fmi<version>/<Model>.fmu (FMI 2.0 or 3.0) for one dynamics model and returns its path."""
    return build_fmus(dynamics, out_dir, (fmi_version,))[0]


def build_fmus(dynamics: Dynamics = "simple", out_dir: Path = Path("dist"),
               fmi_versions: tuple[FmiVersion, ...] = FMI_VERSIONS, progress: bool | None = None) -> list[Path]:
    """Builds the FMUs of one dynamics model in several FMI versions from one code generation; the model
    code (CasADi's C and the variable table) is compiled once per platform and linked into each version's
    binaries. Without mingw-w64, one line on stderr says so and the FMUs carry the Linux binary only.
    progress: a bar on stderr while building (None: only when stderr is a terminal)."""
    for version in fmi_versions:
        if version not in FMI_VERSIONS:
            raise BuildError(f"FMI version {version!r} is not supported: choose one of "
                             f"{', '.join(map(str, FMI_VERSIONS))}")
    model = BUILT[dynamics]
    equations = importlib.import_module(equations_module(dynamics)).equations()
    cross = mingw_compiler()
    if cross is None:
        wanted = os.environ.get("SDL_FMU_MINGW_CC", MINGW_COMPILER)
        print(f"sdl-fmu: {wanted} not found: the {model} FMUs get no Windows binary (Debian: apt-get install "
              f"gcc-mingw-w64-x86-64)", file=sys.stderr)
    platforms = 2 if cross else 1
    shown = _Progress(model, 1 + 2 * platforms + len(fmi_versions) * (platforms + 1), progress)
    try:
        return _build(dynamics, equations, out_dir, fmi_versions, cross, shown)
    finally:
        shown.close()


def _build(dynamics: Dynamics, equations, out_dir: Path, fmi_versions: tuple[FmiVersion, ...], cross: str | None,
           shown: _Progress) -> list[Path]:
    model, module = BUILT[dynamics], equations_module(dynamics)
    with tempfile.TemporaryDirectory(prefix=f"{model}-") as work:
        shown.stage("generating the C code")
        generated = Path(work) / "generated"
        generated.mkdir()
        functions, casadi_source = generate_casadi(equations, generated)
        guid = model_guid(equations.interface, casadi_source)
        model_sources = [generate_model_source(equations, functions, guid, generated).name,
                         generate_derivatives_source(equations, generated).name]
        for name in RUNTIME_HEADERS:
            shutil.copy(RUNTIME_DIRECTORY / name, generated / name)
        shown.advance()
        # the model code, compiled once per platform (gcc and mingw-w64 side by side, each file its own
        # process), linked into each version; the derivative sweeps at DERIVATIVES_OPTIMIZATION
        levels = [MODEL_OPTIMIZATION, DERIVATIVES_OPTIMIZATION]
        linux_objects = [Path(work) / "linux" / (Path(source).stem + ".o") for source in model_sources]
        windows_objects = [Path(work) / "windows" / (Path(source).stem + ".o") for source in model_sources]
        commands = [_object_command(generated, source, output, optimization=level)
                    for source, output, level in zip(model_sources, linux_objects, levels)]
        if cross:
            commands += [_object_command(generated, source, output, cross, windows=True, optimization=level)
                         for source, output, level in zip(model_sources, windows_objects, levels)]
        shown.stage(f"compiling the model code ({len(commands)} compiler runs)")
        run_compilers(commands, shown)
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
            links.append(binary_command(sources_dir, runtime,
                                        root / "binaries" / LINUX_BINARY_DIRECTORY[version] / f"{model}.so",
                                        objects=tuple(linux_objects)))
            if cross:
                links.append(binary_command(sources_dir, runtime,
                                            root / "binaries" / WINDOWS_BINARY_DIRECTORY[version] / f"{model}.dll",
                                            cross, objects=tuple(windows_objects), windows=True))
            roots.append((root, fmu_path(out_dir, dynamics, version)))
        shown.stage(f"compiling the runtime and linking ({len(links)} binaries)")
        run_compilers(links, shown)
        shown.stage("packaging")
        targets = []
        for root, target in roots:
            targets.append(zip_fmu(root, target))
            shown.advance()
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


def zip_fmu(root: Path, target: Path) -> Path:
    """Zips the FMU's folder `root` into `target`, written aside and renamed into place (a failed write never leaves
    a half-written FMU). The same files give the same bytes: entries in sorted order, each dated ZIP_DATE and with
    a fixed mode (binaries/ 0755, the rest 0644), whatever the files' own dates and modes."""
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_name(target.name + ".partial")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(root.rglob("*")):
            if path.is_file():
                name = path.relative_to(root).as_posix()
                entry = zipfile.ZipInfo(name, ZIP_DATE)
                entry.compress_type = zipfile.ZIP_DEFLATED
                entry.external_attr = (0o755 if name.startswith("binaries/") else 0o644) << 16
                archive.writestr(entry, path.read_bytes())
    partial.replace(target)
    return target
