"""Both FMUs as files: valid for fmpy, native (no Python, no CasADi), rebuildable from their sources."""

import os
import re
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

import pytest
from fmpy.model_description import read_build_description
from fmpy.validation import validate_fmu

from sdl_fmu.fmu.package import build_fmu

from helpers import windows_tools_required

# what every 64-bit Windows has; the DLL must need nothing else (libgcc is linked statically)
SYSTEM_DLLS = {"kernel32.dll", "msvcrt.dll"}


@pytest.fixture
def fmu(ego_fmus):
    """(the FMI 2.0 FMU, its model identifier) of each shipped model in turn."""
    return ego_fmus[2], ego_fmus[2].stem


def test_fmu_validates(fmu):
    path, _ = fmu
    assert validate_fmu(str(path)) == []


def test_binary_links_no_python_or_casadi(fmu, tmp_path):
    path, model = fmu
    with zipfile.ZipFile(path) as archive:
        archive.extractall(tmp_path)
    linked = subprocess.run(["ldd", str(tmp_path / f"binaries/linux64/{model}.so")],
                            capture_output=True, text=True, check=True).stdout
    assert "python" not in linked.lower() and "casadi" not in linked.lower()
    configuration, = read_build_description(str(tmp_path), validate=True)  # against the FMI 3 schema
    assert configuration.modelIdentifier == model


@pytest.mark.parametrize("version, platform, prefix", [(2, "win64", "fmi2"), (3, "x86_64-windows", "fmi3")])
def test_windows_binary_needs_system_dlls_only(ego_fmus, tmp_path, version, platform, prefix):
    path = ego_fmus[version]
    model = path.stem
    objdump = shutil.which("x86_64-w64-mingw32-objdump")
    if objdump is None:
        if windows_tools_required():
            pytest.fail("x86_64-w64-mingw32-objdump is not installed (Debian: gcc-mingw-w64-x86-64)")
        pytest.skip("mingw-w64 is not installed: the FMUs carry no Windows binary")
    with zipfile.ZipFile(path) as archive:
        archive.extract(f"binaries/{platform}/{model}.dll", tmp_path)
    headers = subprocess.run([objdump, "-p", str(tmp_path / f"binaries/{platform}/{model}.dll")],
                             capture_output=True, text=True, check=True).stdout
    imported = {name.lower() for name in re.findall(r"DLL Name: (\S+)", headers)}
    assert imported and imported <= SYSTEM_DLLS, imported
    table = headers.split("[Ordinal/Name Pointer] Table", 1)[1].split("\n\n", 1)[0]
    exported = re.findall(r"\]\s+(\w+)", table)
    assert f"{prefix}DoStep" in exported and all(name.startswith(prefix) for name in exported), exported


@pytest.mark.slow
def test_build_without_mingw_says_so_in_one_line_and_builds_linux(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("SDL_FMU_MINGW_CC", "no-such-x86_64-w64-mingw32-gcc")
    path = build_fmu("simple", tmp_path)
    said = capsys.readouterr().err.strip().splitlines()
    assert said == ["sdl-fmu: no-such-x86_64-w64-mingw32-gcc not found: the EgoVehicleSimple FMUs get no Windows "
                    "binary (Debian: apt-get install gcc-mingw-w64-x86-64)"]
    names = zipfile.ZipFile(path).namelist()
    assert "binaries/linux64/EgoVehicleSimple.so" in names and not any("win64" in n for n in names)


def test_the_build_progress_shows_on_a_terminal_only(capsys):
    from sdl_fmu.fmu.package import _Progress

    shown = _Progress("EgoVehicleX", 3, True)
    shown.stage("compiling the model code (2 compiler runs)")
    shown.advance()
    shown.close()
    said = capsys.readouterr().err
    assert "EgoVehicleX: compiling the model code (2 compiler runs)" in said and "1/3 steps" in said
    quiet = _Progress("EgoVehicleX", 3, None)  # None: a bar only when stderr is a terminal (here it is not)
    quiet.stage("compiling")
    quiet.advance()
    quiet.close()
    assert capsys.readouterr().err == ""


@pytest.mark.slow
def test_a_build_compiles_the_derivative_sweeps_at_their_own_level_and_shows_its_stages(tmp_path, monkeypatch,
                                                                                         capsys):
    # the model code at -O2 (every solver step calls it), the sweeps at -O0 (only the directional and adjoint
    # derivatives call them), the runtime and links at -O2; on a terminal (progress=True) each stage shows
    from sdl_fmu.fmu import package

    commands = []
    original = package.run_compilers

    def recorded(batch, progress=None):
        commands.extend(batch)
        return original(batch, progress)

    monkeypatch.setattr(package, "run_compilers", recorded)
    package.build_fmus("simple", tmp_path, (2,), progress=True)
    def level(command) -> str:
        return next(flag for flag in command if re.fullmatch(r"-O\d", flag))

    objects = {Path(command[command.index("-c") + 1]).name: level(command) for command in commands if "-c" in command}
    assert objects == {"EgoVehicleSimple_model.c": "-O2", "EgoVehicleSimple_derivatives.c": "-O0"}
    links = [level(command) for command in commands if "-shared" in command]
    assert len(links) == 2 and set(links) == {"-O2"}  # the runtime, compiled and linked for Linux and Windows
    said = capsys.readouterr().err
    for stage in ("generating the C code", "compiling the model code", "compiling the runtime and linking",
                  "packaging"):
        assert f"EgoVehicleSimple: {stage}" in said


@pytest.mark.slow
def test_the_model_code_gives_the_same_bits_at_every_optimisation_level(tmp_path):
    # The optimisation level of the model code (MODEL_OPTIMIZATION, DERIVATIVES_OPTIMIZATION) is a cost choice that
    # must change no result: every level computes the same IEEE double operations (x86-64 SSE2, -std=c99 keeps
    # -ffp-contract=off, no -ffast-math), so the one generated model object at -O0, -O1 and -O2 gives the same bits
    # for all six model functions on 400 pseudo-random (x, d, u, p) (tests/fmu/model_bits.c hashes every result).
    import importlib

    from sdl_fmu.fmu import codegen, package

    equations = importlib.import_module("sdl_fmu.dynamics.simple").equations()
    generated = tmp_path / "generated"
    generated.mkdir()
    functions, casadi_source = codegen.generate_casadi(equations, generated)
    guid = codegen.model_guid(equations.interface, casadi_source)
    model = codegen.generate_model_source(equations, functions, guid, generated).name
    sweeps = codegen.generate_derivatives_source(equations, generated).name
    for name in codegen.RUNTIME_HEADERS:
        shutil.copy(codegen.RUNTIME_DIRECTORY / name, generated / name)
    shutil.copy(Path(__file__).parent / "model_bits.c", generated / "model_bits.c")
    sweeps_object = tmp_path / "sweeps.o"
    objects = {level: tmp_path / f"model{level}.o" for level in ("-O0", "-O1", "-O2", package.MODEL_OPTIMIZATION)}
    package.run_compilers(
        [package._object_command(generated, sweeps, sweeps_object, optimization=package.DERIVATIVES_OPTIMIZATION)]
        + [package._object_command(generated, model, path, optimization=level) for level, path in objects.items()])
    said = {}
    for level, path in objects.items():
        program = tmp_path / f"bits{level}"
        subprocess.run([package._compiler(None), "-std=c99", "-Wall", "-Wextra", "-Werror", f"-I{generated}",
                        str(generated / "model_bits.c"), str(path), str(sweeps_object), "-o", str(program), "-lm"],
                       check=True, capture_output=True)
        said[level] = subprocess.run([str(program), "400"], capture_output=True, text=True, check=True).stdout
    assert len(set(said.values())) == 1, said
    assert int(said["-O2"].split()[2]) > 10_000  # nonzero results: the cases exercise the functions


def test_a_failed_compile_names_the_file_it_was_to_write(tmp_path):
    # a link line ends with -lm: the message names the output (its -o argument), not the last argument
    from sdl_fmu.fmu.package import BuildError, binary_command, run_compilers

    (tmp_path / "broken.c").write_text("int broken(void) { return }\n")
    command = binary_command(tmp_path, ["broken.c"], tmp_path / "out" / "Broken.so")
    assert command[-1] == "-lm"
    with pytest.raises(BuildError) as raised:
        run_compilers([command])
    first = str(raised.value).splitlines()[0]
    assert first == "compiling Broken.so failed:", first
    assert "broken.c" in str(raised.value)  # the compiler's own message follows


def test_the_compilers_temporary_files_go_with_their_private_folder(tmp_path, monkeypatch):
    # a compiler that leaves a file in its $TMPDIR, as gcc interrupted mid-way can (its ccXXXXXX.s), then compiles:
    # its $TMPDIR was a private folder, gone afterwards with the file, and the user's $TMPDIR stays empty
    from sdl_fmu.fmu.package import binary_command, run_compilers

    users = tmp_path / "tmp"
    users.mkdir()
    monkeypatch.setenv("TMPDIR", str(users))
    monkeypatch.setattr(tempfile, "tempdir", str(users))
    compiler = tmp_path / "leaving-gcc"
    compiler.write_text('#!/bin/sh\necho "$TMPDIR" > "$(dirname "$0")/tmpdir"\ntouch "$TMPDIR/ccLeft01.s"\n'
                        'exec gcc "$@"\n')
    compiler.chmod(0o755)
    (tmp_path / "fine.c").write_text("int fine(void) { return 1; }\n")
    run_compilers([binary_command(tmp_path, ["fine.c"], tmp_path / "out" / "Fine.so", str(compiler))])
    private = Path((tmp_path / "tmpdir").read_text().strip())
    assert (tmp_path / "out" / "Fine.so").is_file()
    assert private.parent == users and private.name.startswith("sdl-fmu-cc-") and not private.exists()
    assert os.listdir(users) == []
