"""The one scenario check (sdl_fmu/sdl/checks.py, through api.load, api.run, api.check and `sdl-fmu check|run|sweep`):
complete before any FMU is built or loaded, the friction meaning read from the vehicle map; and `check` lists the
warnings a run of the whole scenario gives."""

import pytest

from sdl_fmu import api
from sdl_fmu import sweep as sweeping
from sdl_fmu.cli import main
from sdl_fmu.paths import VEHICLE_MAP_DIRECTORY
from sdl_fmu.sdl import ScenarioError, parse_text

FRACTIONAL = "// surfaces\n1000,RSA,1,1\n1100,RSA,1,2.7,-1,3.0\n"
FRACTION_ERROR = (":3: RSA parameter 2 (value): 2.7: for this vehicle the value is a surface attribute number and "
                  "must be whole")


@pytest.fixture
def empty_cache(tmp_path, monkeypatch):
    """An FMU cache with nothing in it, for this test only: whatever is built or looked up there shows."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("SDL_FMU_CACHE", str(cache))
    return cache


def untouched(cache) -> bool:
    return not cache.exists() or not any(cache.iterdir())


@pytest.fixture
def fractional(tmp_path):
    path = tmp_path / "frac.sdl"
    path.write_text(FRACTIONAL)
    return path


def test_run_reports_a_scenario_mistake_on_an_empty_cache_and_builds_nothing(tmp_path, fractional, empty_cache,
                                                                              capsys):
    assert main(["run", str(fractional), "--dynamics", "advanced", "--out", str(tmp_path / "out")]) == 1
    assert capsys.readouterr().err.splitlines() == [f"{fractional}{FRACTION_ERROR}"]
    assert untouched(empty_cache) and not (tmp_path / "out").exists()


def test_check_sweep_and_load_report_the_same_line_and_build_nothing(tmp_path, fractional, empty_cache, capsys):
    assert main(["check", str(fractional), "--dynamics", "advanced"]) == 1
    assert capsys.readouterr().err.splitlines() == [f"{fractional}{FRACTION_ERROR}"]
    with pytest.raises(ScenarioError, match="RSA parameter 2"):
        api.load(fractional, dynamics="advanced")
    with pytest.raises(ScenarioError, match="RSA parameter 2"):
        sweeping.sweep(str(fractional), {"seed": [1, 2]}, tmp_path / "sweep", dynamics="advanced", progress=False)
    assert untouched(empty_cache) and not (tmp_path / "sweep").exists()
    api.load(fractional)  # the Simple map's RSA values are 10 x mu: fractions are fine


def test_a_scenario_object_is_checked_as_a_file_is(empty_cache):
    # an unknown vehicle model and a fractional attribute, in a Scenario built in memory: one line per problem, by
    # line, before anything is built (not a KeyError from deep inside the run)
    scenario = parse_text("100,A,50,600,-6,99\n200,RSA,1,0.5\n", "mine.sdl")
    with pytest.raises(ScenarioError) as caught:
        api.run(scenario, dynamics="advanced")
    lines = str(caught.value).splitlines()
    assert len(lines) == 2 and [error.line for error in caught.value.errors] == [1, 2]
    assert lines[0].startswith("mine.sdl:1: A parameter 4 (model): model 99 is not in the table; the vehicle table "
                               "has models")
    assert lines[1].startswith("mine.sdl:2: RSA parameter 2 (value): 0.5: for this vehicle")
    with pytest.raises(ScenarioError, match=r"^mine.sdl:1: A parameter 4 \(model\): model 99"):
        api.run(parse_text("100,A,50,600,-6,99\n", "mine.sdl"))
    assert untouched(empty_cache)


def test_the_friction_meaning_comes_from_the_vehicle_map_without_its_fmu(tmp_path, fractional, empty_cache):
    # the shipped Advanced map, pointing at an FMU that does not exist: the scenario is refused first (the map says
    # "attribute"), and the FMU is never looked at
    vehicle = tmp_path / "car.toml"
    vehicle.write_text('fmu = "nowhere.fmu"\n' + (VEHICLE_MAP_DIRECTORY / "advanced.toml").read_text())
    with pytest.raises(ScenarioError, match="RSA parameter 2"):
        api.run(fractional, vehicle=vehicle)
    # the shipped Simple map (10 x mu: fractions are fine) with the same FMU: the scenario passes, the FMU does not
    vehicle.write_text('fmu = "nowhere.fmu"\n' + (VEHICLE_MAP_DIRECTORY / "simple.toml").read_text())
    with pytest.raises(api.InputError, match=r"^fmu \S*nowhere.fmu: no such file"):
        api.run(fractional, vehicle=vehicle)
    assert untouched(empty_cache)


# BRK ignored (line 2), attribute 9 without a tire (line 3, lane 1; lane -1's 2, packed snow, has one),
# attribute 6 on the right shoulder (line 4): what a run of the whole scenario with the Advanced FMU warns of
WARNED = "English\n100,BRK,100,0,3\n200,RSA,1,9,-1,2\n300,RSA,101,6\n400,ES\n"


def test_check_lists_the_warnings_a_run_gives(tmp_path, advanced_fmu, capsys):
    path = tmp_path / "warned.sdl"
    path.write_text(WARNED)
    ran = api.run(path, dynamics="advanced", fmu=advanced_fmu).warnings
    assert ran == ["line 2: BRK ignored: brake events act only with simple dynamics",
                   "line 3: RSA attribute 9 (lane 1) has no entry in the Tire Attribute File: attribute 0 (standard "
                   "tires) is used",
                   "line 4: RSA attribute 6 (lane 101) has no entry in the Tire Attribute File: attribute 0 (standard "
                   "tires) is used"]
    assert api.check(path, dynamics="advanced").warnings == ran
    assert main(["check", str(path), "--dynamics", "advanced"]) == 0
    assert capsys.readouterr().err.splitlines() == [f"warning: {warning}" for warning in ran]
    assert api.check(path).warnings == []  # with simple dynamics BRK acts and every RSA value is a mu


def test_check_lists_the_warnings_of_a_vehicle_without_friction(tmp_path, simple_fmu):
    map_text = (VEHICLE_MAP_DIRECTORY / "simple.toml").read_text()
    map_text = "\n".join(line for line in map_text.splitlines() if not line.startswith("friction"))
    vehicle = tmp_path / "grip.toml"
    vehicle.write_text(f"fmu = '{simple_fmu}'\n{map_text}\n")
    path = tmp_path / "warned.sdl"
    path.write_text(WARNED)
    ran = api.run(path, vehicle=vehicle).warnings
    assert len(ran) == 2 and all("RSA has no effect" in warning for warning in ran)
    assert api.check(path, vehicle=vehicle).warnings == ran
