"""Shared fixtures: the real FMUs, built once per test session (FMI 2.0 and 3.0 of each model from one code
generation) into a private per-user FMU cache, which every sdl-fmu subprocess of the tests uses too; their parameter
defaults; the foreign car and the C host, built once; wine, started once. Plain helpers are in helpers.py."""

import os
import shutil
import subprocess
import tempfile
import uuid
from pathlib import Path

import pytest

# Every test (and every sdl-fmu subprocess it starts) uses a private FMU cache, never the user's: a fresh one
# per run, or $SDL_FMU_TEST_CACHE, kept between runs (the developer loop; the cache is keyed by a hash of every
# build input, so a changed model is rebuilt there too). The workers of one `pytest -n N` run (pytest-xdist) share
# one fresh cache, named by the run's id, so each FMU is built once per run: a worker that finds a build in
# progress waits for it (sdl_fmu/fmu/cache.py, build_lock); the controller process removes the cache at the end.
KEPT_CACHE = os.environ.get("SDL_FMU_TEST_CACHE")
RUN_ID = os.environ.get("PYTEST_XDIST_TESTRUNUID") if os.environ.get("PYTEST_XDIST_WORKER") else None


def run_cache(run_id: str) -> Path:
    """The FMU cache the workers of the xdist run `run_id` share."""
    return Path(tempfile.gettempdir()) / f"sdl-fmu-test-cache-{run_id}"


if KEPT_CACHE:
    os.environ["SDL_FMU_CACHE"] = KEPT_CACHE
elif RUN_ID:
    run_cache(RUN_ID).mkdir(exist_ok=True)
    os.environ["SDL_FMU_CACHE"] = str(run_cache(RUN_ID))
else:
    os.environ["SDL_FMU_CACHE"] = tempfile.mkdtemp(prefix="sdl-fmu-test-cache-")

from sdl_fmu.fmu.cache import cached_fmus  # noqa: E402
from sdl_fmu.fmu.package import FMI_VERSIONS  # noqa: E402

from helpers import (HOST_SOURCE, build_foreign_car, foreign_vehicle_map, parameter_defaults,  # noqa: E402
                     windows_tools_required, wine_loader)


@pytest.fixture(scope="session")
def simple_fmus():
    """{2: FMI 2.0 FMU, 3: FMI 3.0 FMU} of the Simple model."""
    return dict(zip(FMI_VERSIONS, cached_fmus("simple", FMI_VERSIONS)))


@pytest.fixture(scope="session")
def advanced_fmus():
    """{2: FMI 2.0 FMU, 3: FMI 3.0 FMU} of the Advanced model."""
    return dict(zip(FMI_VERSIONS, cached_fmus("advanced", FMI_VERSIONS)))


@pytest.fixture(scope="session", params=["simple", "advanced"])
def ego_fmus(request):
    """{2: FMI 2.0 FMU, 3: FMI 3.0 FMU} of each shipped ego model in turn (a test taking it runs once per model;
    `@pytest.mark.parametrize("ego_fmus", ["simple"], indirect=True)` picks models): the FMUs of the fixtures above."""
    return dict(zip(FMI_VERSIONS, cached_fmus(request.param, FMI_VERSIONS)))


@pytest.fixture
def dynamics_fmus(dynamics):
    """The FMUs of the shipped model a test parametrised by `dynamics` runs through the cache (api.run, sdl-fmu run
    without --fmu), built as the test's setup rather than in its body."""
    return dict(zip(FMI_VERSIONS, cached_fmus(dynamics, FMI_VERSIONS)))


@pytest.fixture(scope="session")
def example_aeb_fmus():
    """{2: FMI 2.0 FMU, 3: FMI 3.0 FMU} of the example AEB controller (sdl_fmu/controllers/)."""
    return dict(zip(FMI_VERSIONS, cached_fmus("example-aeb", FMI_VERSIONS)))


@pytest.fixture(scope="session")
def scenario_binaries():
    """{2: folder, 3: folder} of the scenario FMU's generic binary (sdl_fmu/export/binary.py) in the cache, which
    write_scenario_fmu copies."""
    from sdl_fmu.export.binary import cached_binaries

    return {version: cached_binaries(version) for version in FMI_VERSIONS}


@pytest.fixture(scope="session")
def simple_fmu(simple_fmus):
    return simple_fmus[2]


@pytest.fixture(scope="session")
def advanced_fmu(advanced_fmus):
    return advanced_fmus[2]


@pytest.fixture(scope="session")
def defaults_simple(simple_fmu):
    """The Simple FMU's parameter start values."""
    return parameter_defaults(simple_fmu)


@pytest.fixture(scope="session")
def defaults_advanced(advanced_fmu):
    """The Advanced FMU's parameter start values."""
    return parameter_defaults(advanced_fmu)


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


@pytest.fixture(scope="session")
def c_host(tmp_path_factory):
    """The plain C host (tests/hosts/fmi_host.c) compiled for Linux, once per session."""
    from sdl_fmu.fmu.package import fmi_headers

    host = tmp_path_factory.mktemp("host") / "fmi_host"
    subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", f"-I{fmi_headers()}", str(HOST_SOURCE),
                    "-o", str(host), "-ldl"], check=True)
    return host


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


def pytest_configure(config):
    if RUN_ID is None and hasattr(config.option, "testrunuid") and config.option.testrunuid is None:
        config.option.testrunuid = uuid.uuid4().hex  # pytest-xdist gives it to the workers: their cache's name


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist's own, which reads the groups
def pytest_collection_modifyitems(config, items):
    """The tests that run programs under wine share one worker (`--dist loadgroup`), so one wine prefix is made."""
    for item in items:
        if "wine" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.xdist_group("wine"))


def pytest_unconfigure(config):
    if KEPT_CACHE or RUN_ID:
        return  # kept, or the controller's to remove
    shutil.rmtree(os.environ["SDL_FMU_CACHE"], ignore_errors=True)
    if getattr(config.option, "testrunuid", None):
        shutil.rmtree(run_cache(config.option.testrunuid), ignore_errors=True)
