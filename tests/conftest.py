"""Shared fixtures: the real FMUs, built once per test session (FMI 2.0 and 3.0 of each model from one code
generation) into a private per-user FMU cache, which every sdl-fmu subprocess of the tests uses too; their parameter
defaults; the foreign car and the C host, built once; wine, started once. Plain helpers are in helpers.py."""

import os
import shutil
import subprocess
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

from helpers import (HOST_SOURCE, build_foreign_car, foreign_vehicle_map, parameter_defaults,  # noqa: E402
                     windows_tools_required, wine_loader)
from helpers import rewritten_fmu  # noqa: E402, F401  (test_criticality_runs.py still imports it from here)


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


def pytest_unconfigure(config):
    if not KEPT_CACHE:
        shutil.rmtree(os.environ["SDL_FMU_CACHE"], ignore_errors=True)
