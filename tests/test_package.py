"""A real package: a wheel built from the checkout runs the demo from any folder and leaves only its results there;
FMUs come from a per-user cache keyed by everything that goes into them. The top-level scenarios/ and
modelDescription/ ship as package data: importlib.resources reads them from a wheel and from an editable install."""

import ast
import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
import zipfile
from pathlib import Path

import pytest

from sdl_fmu import api, paths
from sdl_fmu.cli import main
from sdl_fmu.fmu import cache
from sdl_fmu.fmu.package import fmu_path
from sdl_fmu.names import BUILT
from sdl_fmu.results.folder import MANIFEST_NAME

CHECKOUT = Path(__file__).resolve().parents[1]
RESULTS = sorted([MANIFEST_NAME, "plot.png", "summary.json", "timeseries.csv"])


SHIPPED_DATA = ("scenarios", "modelDescription")  # top-level folders shipped as sdl_fmu.scenarios, .modelDescription
# In a venv: every shipped data file read through importlib.resources must equal the checkout's (argv[1]); prints
# where sdl_fmu and sdl_fmu.paths find the package and its data.
READ_THROUGH_RESOURCES = """
import sys
from importlib import resources
from pathlib import Path

import sdl_fmu
from sdl_fmu import paths

checkout, read = Path(sys.argv[1]), []
for folder in ("scenarios", "modelDescription"):
    for original in sorted((checkout / folder).rglob("*")):
        if original.is_file() and "__pycache__" not in original.parts:
            shipped = resources.files("sdl_fmu." + folder)
            for part in original.relative_to(checkout / folder).parts:
                shipped = shipped / part
            assert shipped.read_bytes() == original.read_bytes(), original
            read.append(original.relative_to(checkout).as_posix())
print(sdl_fmu.__file__, paths.SCENARIO_DIRECTORY, paths.MODEL_DESCRIPTION_DIRECTORY, *read, sep="\\n")
"""


def checkout_copy(destination: Path) -> Path:
    """A copy of the checkout's sources (a build writes build/ and *.egg-info beside them; the editable install's
    compiled kernel stays out, so that a build compiles its own)."""
    shutil.copytree(CHECKOUT, destination, ignore=shutil.ignore_patterns(
        ".venv", ".git", "build", "dist", "runs", "*.egg-info", "__pycache__", ".pytest_cache", "*.so", "*.pyd"))
    return destination


def fresh_venv(folder: Path) -> tuple[Path, Path]:
    """A venv without sdl-fmu that borrows this venv's dependencies through a .pth line (which does not run this
    venv's own .pth files, so its editable sdl_fmu stays out); returns its python and site-packages."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", folder], check=True)
    python = folder / "bin" / "python"
    site_packages = Path(subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                        check=True, capture_output=True, text=True).stdout.strip())
    (site_packages / "borrowed_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return python, site_packages


def clean_environment(tmp_path: Path, venv: Path) -> dict:
    """No FMU cache, PYTHONPATH or HOME of this session's: the venv's sdl-fmu first on PATH."""
    env = {key: value for key, value in os.environ.items() if key not in (cache.CACHE_VARIABLE, "PYTHONPATH")}
    env.update(HOME=str(tmp_path / "home"), XDG_CACHE_HOME=str(tmp_path / "xdg-cache"),
               PATH=f"{venv / 'bin'}:{env['PATH']}")
    (tmp_path / "home").mkdir()
    return env


def shipped_data_files() -> list[str]:
    return sorted(path.relative_to(CHECKOUT).as_posix() for folder in SHIPPED_DATA
                  for path in (CHECKOUT / folder).rglob("*") if path.is_file() and "__pycache__" not in path.parts)


def read_through_resources(python: Path, env: dict, cwd: Path) -> list[str]:
    completed = subprocess.run([python, "-c", READ_THROUGH_RESOURCES, CHECKOUT], cwd=cwd, env=env,
                               capture_output=True, text=True)
    assert completed.returncode == 0, completed.stderr
    package, scenarios, model_description, *read = completed.stdout.splitlines()
    assert sorted(read) == shipped_data_files()
    assert {"scenarios/demo.sdl", "scenarios/vehicles.csv", "scenarios/tires/attributes.txt",
            "scenarios/tires/dry_asphalt.tir", "scenarios/vehicles/simple.toml", "scenarios/vehicles/advanced.toml",
            "modelDescription/EgoVehicleSimple.json", "modelDescription/units.json"} <= set(read)
    return [package, scenarios, model_description]


def test_the_packages_in_pyproject_are_the_package_folders_and_the_shipped_data():
    # a mapped package cannot join a setuptools `find`, so pyproject.toml lists them: the list must follow the tree
    setuptools = tomllib.loads((CHECKOUT / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = {".".join(init.parent.relative_to(CHECKOUT).parts)
               for init in (CHECKOUT / "sdl_fmu").rglob("__init__.py")}
    assert set(setuptools["packages"]) == folders | {f"sdl_fmu.{name}" for name in SHIPPED_DATA}
    assert setuptools["package-dir"] == {f"sdl_fmu.{name}": name for name in SHIPPED_DATA}
    for name in SHIPPED_DATA:  # a regular package: an editable install maps it, importlib.resources gives real paths
        assert (CHECKOUT / name / "__init__.py").is_file() and not (CHECKOUT / "sdl_fmu" / name).exists()


@pytest.mark.slow
def test_a_wheel_installed_in_a_fresh_venv_ships_the_data_and_runs_the_demo_from_any_folder(tmp_path):
    # built without build isolation, so nothing is downloaded
    source = checkout_copy(tmp_path / "source")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q",
                    "-w", tmp_path / "wheels", source], check=True, capture_output=True)
    (wheel,) = (tmp_path / "wheels").glob("sdl_fmu-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert {f"sdl_fmu/{name}" for name in shipped_data_files()} <= set(names)
    assert not [name for name in names if name.split("/")[0] in SHIPPED_DATA]  # nothing at site-packages' top
    # development tools stay in the checkout (tools/): the FMI call-sequence fuzzer is not installed
    assert [name for name in names if "fuzz" in name] == []
    # the criticality kernel compiled into it (setup.py), and the run takes it (cosim/looks.py)
    assert len([name for name in names if name.startswith("sdl_fmu/cosim/_kernel.") and name.endswith(".so")]) == 1

    venv = tmp_path / "venv"
    python, site_packages = fresh_venv(venv)
    subprocess.run([python, "-m", "pip", "install", "--no-deps", "--no-index", "-q", wheel], check=True,
                   capture_output=True)
    work = tmp_path / "anywhere"
    work.mkdir()
    env = clean_environment(tmp_path, venv)
    package, scenarios, model_description = read_through_resources(python, env, work)
    assert package == str(site_packages / "sdl_fmu" / "__init__.py")
    assert [scenarios, model_description] == [str(site_packages / "sdl_fmu" / name) for name in SHIPPED_DATA]
    kernel = subprocess.run([python, "-c", "from sdl_fmu.cosim import looks; print(looks.arithmetic().__name__)"],
                            cwd=work, env=env, check=True, capture_output=True, text=True).stdout.strip()
    assert kernel == "sdl_fmu.cosim._kernel"

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
    assert list((tmp_path / "home").rglob("*sdl*")) == []  # (matplotlib keeps its own font cache under HOME)


@pytest.mark.slow
def test_an_editable_install_reads_the_top_level_folders_and_a_pythonpath_checkout_reads_its_own(tmp_path):
    source = checkout_copy(tmp_path / "source")
    venv = tmp_path / "venv"
    python, _ = fresh_venv(venv)
    subprocess.run([python, "-m", "pip", "install", "--no-deps", "--no-build-isolation", "--no-index", "-q", "-e",
                    source], check=True, capture_output=True)
    work = tmp_path / "anywhere"
    work.mkdir()
    env = clean_environment(tmp_path, venv)
    assert read_through_resources(python, env, work) == [str(source / "sdl_fmu" / "__init__.py"),
                                                         *(str(source / name) for name in SHIPPED_DATA)]
    completed = subprocess.run([venv / "bin" / "sdl-fmu", "check", "demo"], cwd=work, env=env, capture_output=True,
                               text=True)
    assert completed.returncode == 0 and completed.stdout.startswith(str(source / "scenarios" / "demo.sdl"))

    # this checkout on PYTHONPATH, in a venv whose editable install is another checkout (the copy): sdl_fmu.paths
    # gives this checkout's own folders, whatever importlib.resources finds through the other install
    env["PYTHONPATH"] = str(CHECKOUT)
    located = subprocess.run([python, "-c", "import sdl_fmu, sdl_fmu.paths as p; print(sdl_fmu.__file__, "
                              "p.SCENARIO_DIRECTORY, p.MODEL_DESCRIPTION_DIRECTORY, sep='\\n')"], cwd=work, env=env,
                             check=True, capture_output=True, text=True).stdout.split()
    assert located == [str(CHECKOUT / "sdl_fmu" / "__init__.py"), *(str(CHECKOUT / name) for name in SHIPPED_DATA)]


def test_the_cache_location_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(cache.CACHE_VARIABLE, str(tmp_path / "mine"))
    assert cache.cache_directory() == tmp_path / "mine"
    monkeypatch.delenv(cache.CACHE_VARIABLE)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_directory() == tmp_path / "xdg" / "sdl-fmu"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache.cache_directory() == tmp_path / "home" / ".cache" / "sdl-fmu"


def use_copy_of_build_inputs(root: Path, monkeypatch, installed: bool = False) -> Path:
    """Copies the package and its data to root, as in a checkout (data beside sdl_fmu/) or as a wheel installs
    them (inside sdl_fmu/), and points sdl_fmu.paths at the copy."""
    package = root / "sdl_fmu"
    shutil.copytree(paths.PACKAGE_DIRECTORY, package, ignore=shutil.ignore_patterns("__pycache__"))
    data = package if installed else root
    shutil.copytree(paths.SCENARIO_DIRECTORY, data / "scenarios", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(paths.MODEL_DESCRIPTION_DIRECTORY, data / "modelDescription",
                    ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(paths, "PACKAGE_DIRECTORY", package)
    monkeypatch.setattr(paths, "MODEL_DESCRIPTION_DIRECTORY", data / "modelDescription")
    monkeypatch.setattr(paths, "TIRE_DIRECTORY", data / "scenarios" / "tires")
    return root


def test_the_cache_key_is_the_same_in_a_checkout_and_installed(monkeypatch, tmp_path):
    use_copy_of_build_inputs(tmp_path / "checkout", monkeypatch)
    in_checkout = cache.build_key("simple")
    use_copy_of_build_inputs(tmp_path / "site-packages", monkeypatch, installed=True)
    assert cache.build_key("simple") == in_checkout


@pytest.mark.parametrize("changed", ["sdl_fmu/dynamics/simple.py", "modelDescription/EgoVehicleSimple.json",
                                     "modelDescription/units.json", "sdl_fmu/fmu/runtime/instance.c",
                                     "sdl_fmu/fmu/runtime/model.h", "sdl_fmu/fmu/codegen.py", "sdl_fmu/fmu/package.py",
                                     "scenarios/tires/dry_asphalt.tir", "scenarios/tires/attributes.txt",
                                     "sdl_fmu/interface.py", "sdl_fmu/units.py", "sdl_fmu/names.py",
                                     "sdl_fmu/tire_files.py", "CC", "fmi"])
def test_the_cache_key_changes_with_every_input_of_the_build(changed, monkeypatch, tmp_path):
    root = use_copy_of_build_inputs(tmp_path, monkeypatch)
    before = cache.build_key("simple")
    assert cache.build_key("simple") == before and cache.build_key("advanced") != before
    if changed == "CC":
        monkeypatch.setenv("CC", "cc")
        assert cache.build_key("simple") != before
        return
    if changed == "fmi":
        assert cache.build_key("simple", fmi_version=3) != before
        return
    with open(root / changed, "a") as file:
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


WAITER = """
import sys
from sdl_fmu.fmu import cache

def build(*arguments, **options):
    print("built", flush=True)
    sys.exit(3)

cache.build_fmus = build  # this process must not build: the build in progress elsewhere brings the FMU
print(cache.cached_fmu("simple", 2, announce=lambda path: print("missing", flush=True)), flush=True)
"""


def test_a_process_waits_for_a_build_in_progress_instead_of_building_again(tmp_path, monkeypatch, simple_fmus):
    # The test holds the Simple model's build lock (a build in progress); a second process that finds the FMU
    # missing ("missing": it got past its lookup) must wait; the test then puts the FMU in place, as the build
    # would, and releases the lock: the second process finds it and does not build. Without the lock it would
    # build at once, whatever the machine's speed (it decided so before printing "missing").
    monkeypatch.setenv(cache.CACHE_VARIABLE, str(tmp_path / "cache"))
    target = fmu_path(cache._cache_folder("simple", 2), "simple", 2)
    with cache.build_lock(BUILT["simple"]):
        waiter = subprocess.Popen([sys.executable, "-c", WAITER], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True)
        assert waiter.stdout.readline() == "missing\n"
        target.parent.mkdir(parents=True)
        shutil.copy(simple_fmus[2], target)
    out, err = waiter.communicate(timeout=300)
    assert waiter.returncode == 0, out + err
    assert out.splitlines() == [str(target)]
    assert os.listdir(tmp_path / "cache") == [target.parent.parent.name]  # no lock file left behind


def test_a_cached_fmu_is_reused(simple_fmu):
    assert cache.cached_fmu("simple") == simple_fmu


def test_build_exports_the_fmus_of_the_cache_run_uses(tmp_path, capsys, simple_fmus):
    # the session's cache holds both Simple FMUs (the fixture): build takes them from there, byte for byte
    assert main(["build", "--dynamics", "simple", "--out", str(tmp_path / "export")]) == 0
    exported = [tmp_path / "export" / f"fmi{version}" / "EgoVehicleSimple.fmu" for version in (2, 3)]
    assert capsys.readouterr().out.split() == [str(path) for path in exported]
    for path, version in zip(exported, (2, 3)):
        assert path.read_bytes() == simple_fmus[version].read_bytes()
    assert sorted(p.name for p in (tmp_path / "export").rglob("*") if p.is_file()) == ["EgoVehicleSimple.fmu"] * 2


@pytest.mark.slow
def test_build_fills_the_cache_run_uses(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(cache.CACHE_VARIABLE, str(tmp_path / "cache"))
    assert main(["build", "--dynamics", "simple", "--fmi-version", "2", "--out", str(tmp_path / "export")]) == 0
    (exported,) = capsys.readouterr().out.split()
    assert main(["run", "head_on", "--until-time", "1", "--out", str(tmp_path / "run")]) == 0
    assert "building" not in capsys.readouterr().err  # run found the FMU that build made
    assert api.ego_fmu("simple").read_bytes() == Path(exported).read_bytes()


def python_floor() -> tuple[int, int]:
    floor = tomllib.loads((CHECKOUT / "pyproject.toml").read_text())["project"]["requires-python"]
    assert floor.startswith(">=") and "," not in floor, floor
    major, minor = floor[2:].split(".")[:2]
    return int(major), int(minor)


def test_the_oldest_python_advertised_is_the_one_the_tests_run_on_or_imports_the_package():
    """pyproject's requires-python floor is what is tested: this suite runs on it, or (on a newer Python) the floor's
    interpreter, if installed, imports every module of the package from this checkout. Every module's syntax is
    also that of the floor (ast's feature_version)."""
    floor = python_floor()
    assert sys.version_info[:2] >= floor
    for path in sorted((CHECKOUT / "sdl_fmu").rglob("*.py")):
        ast.parse(path.read_text(encoding="utf-8"), filename=str(path), feature_version=floor)  # a SyntaxError fails
    if sys.version_info[:2] == floor:
        return  # this run is the proof: every test imported the package on the floor's Python
    oldest = shutil.which(f"python{floor[0]}.{floor[1]}")
    if oldest is None:
        pytest.fail(f"requires-python says >={floor[0]}.{floor[1]}, but this suite runs on "
                    f"{sys.version_info[0]}.{sys.version_info[1]} and python{floor[0]}.{floor[1]} is not installed")
    modules = sorted(".".join(p.relative_to(CHECKOUT).with_suffix("").parts).removesuffix(".__init__")
                     for p in (CHECKOUT / "sdl_fmu").rglob("*.py"))
    completed = subprocess.run([oldest, "-c", f"import importlib\nfor m in {modules!r}: importlib.import_module(m)"],
                               cwd=CHECKOUT, env={**os.environ, "PYTHONPATH": str(CHECKOUT)}, capture_output=True,
                               text=True)
    assert completed.returncode == 0, completed.stderr


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
