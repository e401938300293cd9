"""A real package (issue 7, item 2): a wheel built from the checkout runs the demo from any folder and
leaves only its results there; FMUs come from a per-user cache keyed by everything that goes into them."""

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from sdl_fmu import api
from sdl_fmu.cli import main
from sdl_fmu.fmu import cache
from sdl_fmu.results_folder import MANIFEST_NAME

CHECKOUT = Path(__file__).resolve().parents[1]
RESULTS = sorted([MANIFEST_NAME, "plot.png", "summary.json", "timeseries.csv"])


@pytest.mark.slow
def test_a_wheel_installed_in_a_fresh_venv_runs_the_demo_from_any_folder(tmp_path):
    # The wheel is built from a copy of the checkout (a build writes build/ and *.egg-info beside the sources)
    # without build isolation, so nothing is downloaded; the fresh venv borrows this venv's dependencies
    # through a .pth line (which does not run this venv's own .pth files, so its editable sdl_fmu stays out).
    source = tmp_path / "source"
    shutil.copytree(CHECKOUT, source, ignore=shutil.ignore_patterns(
        ".venv", ".git", "build", "dist", "runs", "*.egg-info", "__pycache__", ".pytest_cache"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q",
                    "-w", tmp_path / "wheels", source], check=True, capture_output=True)
    (wheel,) = (tmp_path / "wheels").glob("sdl_fmu-*.whl")
    # development tools stay in the checkout (tools/): the FMI call-sequence fuzzer is not installed
    assert [name for name in zipfile.ZipFile(wheel).namelist() if "fuzz" in name] == []

    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", venv], check=True)
    python = venv / "bin" / "python"
    site_packages = Path(subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                        check=True, capture_output=True, text=True).stdout.strip())
    (site_packages / "borrowed_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run([python, "-m", "pip", "install", "--no-deps", "--no-index", "-q", wheel], check=True,
                   capture_output=True)

    work, home = tmp_path / "anywhere", tmp_path / "home"
    work.mkdir()
    home.mkdir()
    env = {key: value for key, value in os.environ.items() if key not in (cache.CACHE_VARIABLE, "PYTHONPATH")}
    env.update(HOME=str(home), XDG_CACHE_HOME=str(tmp_path / "xdg-cache"), PATH=f"{venv / 'bin'}:{env['PATH']}")
    located = subprocess.run([python, "-c", "import sdl_fmu; print(sdl_fmu.__file__)"], cwd=work, env=env,
                             check=True, capture_output=True, text=True).stdout
    assert located.startswith(str(site_packages)), located

    completed = subprocess.run([venv / "bin" / "sdl-fmu", "run", "demo"], cwd=work, env=env, capture_output=True,
                               text=True, timeout=300)
    assert completed.returncode == 0, completed.stderr
    assert "Traceback" not in completed.stderr
    assert os.listdir(work) == ["runs"] and os.listdir(work / "runs") == ["demo"]
    assert sorted(os.listdir(work / "runs" / "demo")) == RESULTS
    assert "demo.sdl: simple dynamics" in completed.stdout
    # the FMU went into the per-user cache ($XDG_CACHE_HOME/sdl-fmu), nowhere near the working folder
    (fmu,) = (tmp_path / "xdg-cache" / "sdl-fmu").glob("EgoVehicleSimple-fmi2-*/fmi2/EgoVehicleSimple.fmu")
    assert zipfile.ZipFile(fmu).testzip() is None
    assert list(home.rglob("*sdl*")) == []  # (matplotlib keeps its own font cache under HOME)


def test_the_cache_location_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(cache.CACHE_VARIABLE, str(tmp_path / "mine"))
    assert cache.cache_directory() == tmp_path / "mine"
    monkeypatch.delenv(cache.CACHE_VARIABLE)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_directory() == tmp_path / "xdg" / "sdl-fmu"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache.cache_directory() == tmp_path / "home" / ".cache" / "sdl-fmu"


@pytest.mark.parametrize("changed", ["dynamics/simple.py", "interfaces/EgoVehicleSimple.json", "fmu/runtime/instance.c",
                                     "fmu/runtime/model.h", "fmu/codegen.py", "fmu/package.py",
                                     "scenarios/tires/dry_asphalt.tir", "scenarios/tires/attributes.txt",
                                     "interface.py", "units.py", "CC", "fmi"])
def test_the_cache_key_changes_with_every_input_of_the_build(changed, monkeypatch, tmp_path):
    package = tmp_path / "sdl_fmu"
    shutil.copytree(cache.PACKAGE_DIRECTORY, package, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(cache, "PACKAGE_DIRECTORY", package)
    before = cache.build_key("simple")
    assert cache.build_key("simple") == before and cache.build_key("advanced") != before
    if changed == "CC":
        monkeypatch.setenv("CC", "cc")
        assert cache.build_key("simple") != before
        return
    if changed == "fmi":
        assert cache.build_key("simple", fmi_version=3) != before
        return
    with open(package / changed, "a") as file:
        file.write("\n")  # even a blank line: the key does not guess what matters
    assert cache.build_key("simple") != before


@pytest.mark.slow
def test_two_processes_building_at_once_leave_one_good_fmu(tmp_path):
    env = {**os.environ, cache.CACHE_VARIABLE: str(tmp_path / "cache")}
    # and the temporary folder of a build that was killed (a process id that no longer exists) goes away
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    abandoned = tmp_path / "cache" / f".building-{dead.stdout.strip()}-x1y2"
    abandoned.mkdir(parents=True)
    (abandoned / "half.fmu").write_bytes(b"PK")
    code = "from sdl_fmu.fmu.cache import cached_fmu; print(cached_fmu('simple'))"
    builders = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True) for _ in range(2)]
    outputs = [builder.communicate(timeout=300) for builder in builders]
    assert [builder.returncode for builder in builders] == [0, 0], outputs
    paths = {out.strip() for out, _ in outputs}
    assert len(paths) == 1
    (folder,) = os.listdir(tmp_path / "cache")  # no temporary build folder left behind
    assert folder.startswith("EgoVehicleSimple-fmi2-")
    fmu = Path(paths.pop())
    assert zipfile.ZipFile(fmu).testzip() is None and fmu.parent.parent == tmp_path / "cache" / folder


def test_a_cached_fmu_is_reused(simple_fmu):
    assert cache.cached_fmu("simple") == simple_fmu


@pytest.mark.slow
def test_build_still_exports_to_a_folder(tmp_path, capsys):
    assert main(["build", "--dynamics", "simple", "--out", str(tmp_path / "export")]) == 0
    exported = [tmp_path / "export" / f"fmi{version}" / "EgoVehicleSimple.fmu" for version in (2, 3)]
    assert capsys.readouterr().out.split() == [str(path) for path in exported]
    for path in exported:
        assert "modelDescription.xml" in zipfile.ZipFile(path).namelist()


def test_shipped_examples_run_by_short_name_from_any_folder_unless_a_file_has_that_name(tmp_path, monkeypatch,
                                                                                        capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["check", "demo"]) == 0
    assert "demo.sdl" in capsys.readouterr().out
    assert main(["check", "head_on.sdl"]) == 0
    assert capsys.readouterr().out.startswith(str(api.shipped_scenarios()["head_on"]))
    (tmp_path / "demo").write_text("Metric\n10,ES\n")  # a file of that name wins
    assert main(["check", "demo"]) == 0
    report = capsys.readouterr().out
    assert report.splitlines()[0] == "demo" and "units: Metric" in report
    assert main(["check", "no_such_example"]) == 1
    assert "shipped examples by name: approaching_vehicle, brake_examples, demo" in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == ["demo"]
