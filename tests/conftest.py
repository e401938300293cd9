"""Shared fixtures: the real FMUs, built once per test session (FMI 2.0 and 3.0 of each model from one code
generation) into a private per-user FMU cache, which every sdl-fmu subprocess of the tests uses too; wine,
started once."""

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

# Every test (and every sdl-fmu subprocess it starts) uses a private FMU cache, never the user's: a fresh one
# per session, or $SDL_FMU_TEST_CACHE, kept between sessions (the developer loop; the cache is keyed by a hash
# of every build input, so a changed model is rebuilt there too).
KEPT_CACHE = os.environ.get("SDL_FMU_TEST_CACHE")
os.environ["SDL_FMU_CACHE"] = KEPT_CACHE or tempfile.mkdtemp(prefix="sdl-fmu-test-cache-")

from sdl_fmu.fmu.cache import cached_fmus  # noqa: E402
from sdl_fmu.fmu.package import FMI_VERSIONS  # noqa: E402


@pytest.fixture(scope="session")
def simple_fmus():
    """{2: FMI 2.0 FMU, 3: FMI 3.0 FMU} of the Simple model."""
    return dict(zip(FMI_VERSIONS, cached_fmus("simple", FMI_VERSIONS)))


@pytest.fixture(scope="session")
def advanced_fmus():
    """{2: FMI 2.0 FMU, 3: FMI 3.0 FMU} of the Advanced model."""
    return dict(zip(FMI_VERSIONS, cached_fmus("advanced", FMI_VERSIONS)))


@pytest.fixture(scope="session")
def simple_fmu(simple_fmus):
    return simple_fmus[2]


@pytest.fixture(scope="session")
def advanced_fmu(advanced_fmus):
    return advanced_fmus[2]


@pytest.fixture(scope="session")
def defaults_simple(simple_fmu):
    from fmpy import read_model_description

    return {v.name: float(v.start) for v in read_model_description(str(simple_fmu)).modelVariables
            if v.causality == "parameter"}


VEHICLES = Path(__file__).parent / "vehicles"
FOREIGN_CAR_MAP = VEHICLES / "foreign_car.toml"
# the weak variant: at most 9 kW of drive power, so its top speed (84.7 km/h, test_foreign_vehicle.py) stays below
# 100 km/h; for "cannot reach the entry speed"
WEAK_PARAMETERS = {"max_engine_power": 9000.0}


def build_foreign_car(folder: Path, fmi_version: int = 3) -> Path:
    """Packages the foreign car (tests/vehicles) into folder with another tool, in a subprocess through its
    command line: pythonfmu3 for FMI 3.0, PythonFMU for FMI 2.0. Returns the FMU's path."""
    script, tool, name = {3: ("foreign_car.py", "pythonfmu3", "ForeignCar"),
                          2: ("foreign_car_fmi2.py", "pythonfmu", "ForeignCarFmi2")}[fmi_version]
    built = subprocess.run([sys.executable, "-m", tool, "build", "-f", str(VEHICLES / script), "-d", str(folder),
                            str(VEHICLES / "foreign_car_dynamics.py")], capture_output=True, text=True)
    if built.returncode != 0:
        pytest.fail(f"{tool} could not build {script}:\n{built.stdout}{built.stderr}")
    return folder / f"{name}.fmu"


def foreign_vehicle_map(folder: Path, weak: bool = False) -> Path:
    """The foreign car's vehicle map; weak: a copy in folder whose [parameters] (the map's last table) cap the
    drive power (WEAK_PARAMETERS)."""
    if not weak:
        return FOREIGN_CAR_MAP
    text = FOREIGN_CAR_MAP.read_text()
    assert text.rstrip().endswith("[parameters]"), "foreign_car.toml must end with its [parameters] table"
    path = folder / "foreign_car_weak.toml"
    path.write_text(text + "".join(f"{name} = {value!r}\n" for name, value in WEAK_PARAMETERS.items()))
    return path


@pytest.fixture(scope="session")
def foreign_vehicle(tmp_path_factory):
    """A function (fmi_version=3, weak=False) -> (fmu_path, map_path): the foreign car, built once per session
    and FMI version by PythonFMU / pythonfmu3, and its vehicle map (weak: the drive-power-capped variant)."""
    folder = tmp_path_factory.mktemp("foreign-car")
    built = {}

    def vehicle(fmi_version: int = 3, weak: bool = False) -> tuple[Path, Path]:
        if fmi_version not in built:
            built[fmi_version] = build_foreign_car(folder, fmi_version)
        return built[fmi_version], foreign_vehicle_map(folder, weak)

    return vehicle


def foreign_parameters(fmu: Path) -> dict[str, float]:
    """The foreign car's parameter start values, in its own units."""
    from fmpy import read_model_description

    return {v.name: float(v.start) for v in read_model_description(str(fmu)).modelVariables
            if v.causality == "parameter"}


class FmpyCar:
    """A co-simulation FMU (FMI 2.0 or 3.0) opened directly through fmpy, driven by variable name:
    car = FmpyCar(fmu, {"v_init": 100.0}); car.set(brake_pressure=60.0); car.step(0.05); car.get("veh_speed")."""

    def __init__(self, fmu: Path, start: dict[str, float]):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        from fmpy.fmi3 import FMU3Slave

        self.description = read_model_description(str(fmu))
        self.refs = {v.name: v.valueReference for v in self.description.modelVariables}
        self.fmi3 = self.description.fmiVersion.startswith("3")
        self._folder = extract(str(fmu))
        common = dict(unzipDirectory=self._folder, modelIdentifier=self.description.coSimulation.modelIdentifier,
                      instanceName="car")
        if self.fmi3:
            self.fmu = FMU3Slave(guid=self.description.guid, **common)
            self.fmu.instantiate()
            self.fmu.enterInitializationMode(startTime=0.0)
        else:
            self.fmu = FMU2Slave(guid=self.description.guid, **common)
            self.fmu.instantiate()
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
        self.set(**start)
        self.fmu.exitInitializationMode()
        self.time = 0.0

    def set(self, **values: float) -> None:
        setter = self.fmu.setFloat64 if self.fmi3 else self.fmu.setReal
        setter([self.refs[name] for name in values], [float(value) for value in values.values()])

    def get(self, *names: str) -> list[float]:
        getter = self.fmu.getFloat64 if self.fmi3 else self.fmu.getReal
        return list(getter([self.refs[name] for name in names]))

    def step(self, h: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.time += h

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self._folder, ignore_errors=True)


def rewritten_fmu(source: Path, target: Path, edit_description=None, drop=lambda name: False) -> Path:
    """A copy of an FMU with its modelDescription.xml passed through edit_description(text) -> text and the
    archive members for which drop(name) is true left out (an FMU that lacks a capability or a binary)."""
    import zipfile

    with zipfile.ZipFile(source) as original, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as copy:
        for item in original.infolist():
            if drop(item.filename):
                continue
            data = original.read(item)
            if item.filename == "modelDescription.xml" and edit_description is not None:
                data = edit_description(data.decode("utf-8")).encode("utf-8")
            copy.writestr(item, data)
    return target


def windows_tools_required() -> bool:
    """CI (.ci/run) installs mingw-w64 and wine and sets this: there a missing tool is a failure, not a skip."""
    return os.environ.get("SDL_FMU_REQUIRE_WINDOWS") == "1"


def wine_loader() -> str | None:
    # Debian's wine64 package installs its loader outside PATH; the wine package adds /usr/bin/wine
    for candidate in ("wine64", "wine", "/usr/lib/wine/wine64"):
        if shutil.which(candidate):
            return shutil.which(candidate)
    return None


@pytest.fixture(scope="session")
def wine(tmp_path_factory):
    """Runs a Windows program under wine in a fresh prefix; wine's server stays up for the whole session."""
    loader = wine_loader()
    if loader is None:
        if windows_tools_required():
            pytest.fail("wine is not installed (Debian: apt-get install wine64)")
        pytest.skip("wine is not installed (Debian: apt-get install wine64)")
    environment = {**os.environ, "WINEPREFIX": str(tmp_path_factory.mktemp("wineprefix")), "WINEDEBUG": "-all"}
    server = next((s for s in (shutil.which("wineserver"), "/usr/lib/wine/wineserver64") if s and Path(s).exists()),
                  None)
    if server:
        subprocess.run([server, "-p"], env=environment, check=False)  # persistent: no restart per program
    # create the prefix once; wine's background services inherit these null handles (with pipes, a caller
    # reading the output would wait for the services to end)
    subprocess.run([loader, "wineboot", "--init"], env=environment, stdin=subprocess.DEVNULL,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=300, check=False)
    outputs = tmp_path_factory.mktemp("wine-output")

    def run(arguments, timeout=120):
        """Runs a program under wine; its output goes through files, never pipes a service could hold open."""
        with open(outputs / "stdout", "w+") as stdout, open(outputs / "stderr", "w+") as stderr:
            completed = subprocess.run([loader, *map(str, arguments)], env=environment, stdin=subprocess.DEVNULL,
                                       stdout=stdout, stderr=stderr, timeout=timeout)
            stdout.seek(0)
            stderr.seek(0)
            return subprocess.CompletedProcess(completed.args, completed.returncode, stdout.read(), stderr.read())

    yield run
    if server:
        subprocess.run([server, "-k"], env=environment, check=False)  # ends this prefix's server only


def pytest_unconfigure(config):
    if not KEPT_CACHE:
        shutil.rmtree(os.environ["SDL_FMU_CACHE"], ignore_errors=True)
