"""Both FMUs as files: valid for fmpy, native (no Python, no CasADi), rebuildable from their sources."""

import re
import shutil
import subprocess
import zipfile

import pytest
from fmpy.model_description import read_build_description
from fmpy.validation import validate_fmu

from sdl_fmu.fmu.package import build_fmu

from helpers import windows_tools_required

# what every 64-bit Windows has; the DLL must need nothing else (libgcc is linked statically)
SYSTEM_DLLS = {"kernel32.dll", "msvcrt.dll"}


@pytest.fixture(params=[("simple_fmu", "EgoVehicleSimple"), ("advanced_fmu", "EgoVehicleAdvanced")],
                ids=["simple", "advanced"])
def fmu(request):
    fixture, model = request.param
    return request.getfixturevalue(fixture), model


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
def test_windows_binary_needs_system_dlls_only(fmu, request, tmp_path, version, platform, prefix):
    _, model = fmu
    path = request.getfixturevalue("simple_fmus" if model == "EgoVehicleSimple" else "advanced_fmus")[version]
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
