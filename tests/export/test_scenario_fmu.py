"""The scenario FMU (sdl_fmu/export): one generic native binary, the scenario as data in resources/, FMI 2.0 and
3.0 co-simulation, documented, hardened like the ego FMUs; and one meaning of a scenario: replaying `api.run`'s
recorded ego states through it (without prediction, at the run's communication points) gives the run's events,
collisions, commands, surfaces and lead signals bit for bit, on every shipped scenario and on generated ones."""

import ctypes
import json
import os
import random
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

import fmi_fuzz
from sdl_fmu import api
from sdl_fmu.export.binary import MODEL_IDENTIFIER, cached_binaries
from sdl_fmu.export.scenario_fmu import ScenarioFmuError, sdl_text, write_scenario_fmu
from sdl_fmu.sdl.parser import decode_text

from helpers import windows_tools_required
from scenario_generator import random_scenario
from scenario_harness import ScenarioInstance, recorded_inputs, replay

TESTS = Path(__file__).resolve().parents[1]  # tests/
SYSTEM_DLLS = {"kernel32.dll", "msvcrt.dll"}
LINUX_LIBRARIES = {"libc.so.6", "libm.so.6"}
SHIPPED = sorted(api.shipped_scenarios())

pytestmark = pytest.mark.usefixtures("simple_fmus", "scenario_binaries")  # the FMUs of the cache the tests export


@pytest.fixture(scope="module")
def simple_model():
    return api.ego_model("simple")


@pytest.fixture(scope="module")
def demo_fmus(tmp_path_factory, simple_model):
    """The demo's scenario FMU in FMI 2.0 and 3.0 for the Simple ego."""
    folder = tmp_path_factory.mktemp("demo-fmus")
    scenario = api.load("demo")
    return {version: write_scenario_fmu(scenario, folder / f"demo{version}.fmu", ego=simple_model,
                                        fmi_version=version) for version in (2, 3)}


def unzipped(fmu, folder: Path) -> Path:
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    return folder


# ---- the FMU as a file ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("version", [2, 3])
def test_the_fmu_validates_and_holds_its_parts(demo_fmus, version, tmp_path):
    fmu = demo_fmus[version]
    assert validate_fmu(str(fmu.path)) == []
    folder = unzipped(fmu.path, tmp_path)
    linux, windows = ("linux64", "win64") if version == 2 else ("x86_64-linux", "x86_64-windows")
    assert (folder / "binaries" / linux / f"{MODEL_IDENTIFIER}.so").is_file()
    assert (folder / "binaries" / windows / f"{MODEL_IDENTIFIER}.dll").is_file() or not windows_tools_required()
    assert (folder / "sources" / "buildDescription.xml").is_file()
    # the SDL text, as the parser reads it, in resources/ and in the documentation
    text = decode_text((TESTS.parent / "scenarios" / "demo.sdl").read_bytes())[0]
    assert (folder / "resources" / "scenario.sdl").read_text(encoding="utf-8") == text
    documentation = (folder / "documentation" / "index.html").read_text(encoding="utf-8")
    assert "7000,A,60,3000,-6,7,8,-2,60,1.5,3,-6,60,1" in documentation and "Wiring" in documentation
    description = read_model_description(str(folder))
    for variable in description.modelVariables:  # the variable table
        assert f"<code>{variable.name}</code>" in documentation or variable.name == "time"
    assert (folder / "documentation" / "licenses" / "license.txt").is_file()
    # the data names this FMU's GUID, and its parameter lines are the modelDescription's start values
    data = (folder / "resources" / "scenario.sdlfmu").read_text()
    assert f"guid {description.guid}" in data.splitlines()
    starts = {v.name: v.start for v in description.modelVariables if v.causality == "parameter"}
    written = dict(re.findall(r"^parameter (\S+) (\S+)", data, flags=re.M))
    assert set(written) == set(starts) == set(fmu.parameters)
    for name, value in written.items():
        declared = starts[name]
        as_number = 1.0 if declared == "true" else 0.0 if declared == "false" else float(declared)
        assert float.fromhex(value) == as_number == float(fmu.parameters[name]), name


def test_one_binary_serves_every_scenario(demo_fmus, simple_model, tmp_path):
    """Exporting compiles nothing: the binaries and sources of two scenarios' FMUs are the cached generic build."""
    other = write_scenario_fmu(api.load("head_on"), tmp_path / "head_on.fmu", ego=simple_model)
    cache = cached_binaries(2)
    with zipfile.ZipFile(demo_fmus[2].path) as a, zipfile.ZipFile(other.path) as b:
        shared = [name for name in a.namelist() if name.startswith(("binaries/", "sources/"))]
        assert shared and all(a.read(name) == b.read(name) == (cache / name).read_bytes() for name in shared)
        assert a.read("resources/scenario.sdlfmu") != b.read("resources/scenario.sdlfmu")
    assert read_model_description(str(demo_fmus[2].path)).guid != read_model_description(str(other.path)).guid


def test_the_linux_binary_needs_libc_and_libm_only(demo_fmus, tmp_path):
    library = unzipped(demo_fmus[2].path, tmp_path) / "binaries" / "linux64" / f"{MODEL_IDENTIFIER}.so"
    needed = set(re.findall(r"\(NEEDED\)\s+Shared library: \[(\S+)\]", subprocess.run(
        ["readelf", "-d", str(library)], capture_output=True, text=True, check=True).stdout, flags=re.M))
    assert needed == LINUX_LIBRARIES
    exported = subprocess.run(["nm", "-D", "--defined-only", str(library)], capture_output=True, text=True,
                              check=True).stdout.split()
    functions = [word for word in exported if word.startswith(("fmi", "scenario", "instance", "view"))]
    assert functions and all(name.startswith("fmi2") for name in functions), functions


@pytest.mark.parametrize("version, platform, prefix", [(2, "win64", "fmi2"), (3, "x86_64-windows", "fmi3")])
def test_the_windows_binary_needs_system_dlls_only(demo_fmus, tmp_path, version, platform, prefix):
    objdump = shutil.which("x86_64-w64-mingw32-objdump")
    if objdump is None:
        if windows_tools_required():
            pytest.fail("x86_64-w64-mingw32-objdump is not installed (Debian: gcc-mingw-w64-x86-64)")
        pytest.skip("mingw-w64 is not installed: the FMUs carry no Windows binary")
    dll = unzipped(demo_fmus[version].path, tmp_path) / "binaries" / platform / f"{MODEL_IDENTIFIER}.dll"
    headers = subprocess.run([objdump, "-p", str(dll)], capture_output=True, text=True, check=True).stdout
    imported = {name.lower() for name in re.findall(r"DLL Name: (\S+)", headers)}
    assert imported and imported <= SYSTEM_DLLS, imported
    table = headers.split("[Ordinal/Name Pointer] Table", 1)[1].split("\n\n", 1)[0]
    exported = re.findall(r"\]\s+(\w+)", table)
    assert f"{prefix}DoStep" in exported and all(name.startswith(prefix) for name in exported), exported


def test_exporting_refuses_values_outside_the_fmus_ranges(tmp_path, simple_model):
    scenario = api.load("demo")
    with pytest.raises(ScenarioFmuError, match=r"^speed = 200 is outside the scenario FMU's range \[0, 150\]$"):
        write_scenario_fmu(scenario, tmp_path / "x.fmu", ego=simple_model, speed=200.0)
    with pytest.raises(ScenarioFmuError, match="fmi_version 4"):
        write_scenario_fmu(scenario, tmp_path / "x.fmu", ego=simple_model, fmi_version=4)
    assert not (tmp_path / "x.fmu").exists() and not list(tmp_path.glob("*.partial"))


def test_a_scenario_made_in_python_carries_its_description():
    scenario = api.load("head_on")
    made = type(scenario)(path="made in Python", units=scenario.units, road=scenario.road, events=scenario.events,
                          end_distance=scenario.end_distance)
    text = sdl_text(made)
    assert text.startswith("// made in Python") and "A" in text


# ---- one meaning: the replay ------------------------------------------------------------------------------------


def replay_scenario(scenario, dynamics, folder: Path, until_time=None, driver="lane"):
    model = api.ego_model(dynamics)
    result = api.run(scenario, dynamics=dynamics, until_time=until_time, driver=driver)
    fmu = write_scenario_fmu(scenario, folder / "scenario.fmu", ego=model, until_time=until_time, driver=driver)
    return replay(result, fmu.path, folder / "unzipped", model.length, model.width), result


def test_replaying_the_demo_gives_the_run_bit_for_bit(tmp_path):
    problems, result = replay_scenario(api.load("demo"), "simple", tmp_path)
    assert problems == []
    assert len(list(result.events)) == 29  # spawns, actions, departures, RSA, BRK on and off, the end


def test_replaying_a_follow_driver_run_gives_the_run_bit_for_bit(tmp_path):
    """The follow driver (Gipps' law, deciding every 2/3 s, its decisions merged with the driver's samples): the
    demo's traffic ahead limits it."""
    problems, result = replay_scenario(api.load("demo"), "simple", tmp_path, until_time=60.0, driver="follow")
    assert problems == [] and len(list(result.events)) > 10


@pytest.mark.slow
@pytest.mark.parametrize("driver", ["lane", "follow"])
@pytest.mark.parametrize("dynamics", ["simple", "advanced"])
@pytest.mark.parametrize("name", SHIPPED)
@pytest.mark.usefixtures("dynamics_fmus")
def test_replaying_every_shipped_scenario_gives_the_run_bit_for_bit(name, dynamics, driver, tmp_path):
    problems, _ = replay_scenario(api.load(name, skip_unsupported=True, dynamics=dynamics), dynamics, tmp_path,
                                  driver=driver)
    assert problems == []


def generated(seed: int, folder: Path, dynamics: str):
    path = folder / f"generated{seed}.sdl"
    path.write_text(random_scenario(seed))
    return api.load(path, dynamics=dynamics)


@pytest.mark.parametrize("seed", [0, 1])
def test_replaying_generated_scenarios_gives_the_run_bit_for_bit(seed, tmp_path):
    problems, result = replay_scenario(generated(seed, tmp_path, "simple"), "simple", tmp_path, until_time=100.0)
    assert problems == []
    assert result.collisions > 0  # seeds 0 and 1 hit traffic: contacts counted alike


@pytest.mark.slow
@pytest.mark.parametrize("driver", ["lane", "follow"])
@pytest.mark.parametrize("dynamics", ["simple", "advanced"])
@pytest.mark.parametrize("seed", range(2, 30))
@pytest.mark.usefixtures("dynamics_fmus")
def test_replaying_many_generated_scenarios_gives_the_run_bit_for_bit(seed, dynamics, driver, tmp_path):
    problems, _ = replay_scenario(generated(seed, tmp_path, dynamics), dynamics, tmp_path, until_time=100.0,
                                  driver=driver)
    assert problems == []


def test_the_models_are_drawn_from_the_seed_as_the_run_draws_them(tmp_path, simple_model):
    """demo's random models (two A events with *1~8): the data holds, for every A event, the model the run with the
    same seed spawns; different seeds draw different ones."""
    scenario = api.load("demo")
    drawn = []
    for seed in (1, 2, 3):
        result = api.run(scenario, seed=seed, until_time=40.0)
        fmu = write_scenario_fmu(scenario, tmp_path / f"{seed}.fmu", ego=simple_model, seed=seed, until_time=40.0)
        assert replay(result, fmu.path, tmp_path / f"u{seed}", simple_model.length, simple_model.width) == []
        models = [e["model"] for e in result.events if e["action"] == "spawn"]
        data = zipfile.ZipFile(fmu.path).read("resources/scenario.sdlfmu").decode()
        written = [int(line.split()[8]) for line in data.splitlines() if line.startswith("A ")]
        assert written[:len(models)] == models
        drawn.append(written)
    assert len({tuple(models) for models in drawn}) > 1


# ---- hardening ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("version", [2, 3])
def test_non_finite_inputs_are_refused_with_a_message(demo_fmus, version, tmp_path):
    instance = ScenarioInstance(demo_fmus[version].path, tmp_path)
    instance.initialize({}, {"ego_v": 26.8, "ego_y": -1.8288})
    for name, value in (("ego_x", float("nan")), ("ego_v", float("inf")), ("ego_ax", float("-inf")),
                        ("request_brake", float("nan")), ("request_deceleration", float("inf")),
                        # beyond +-1e9, sdl-fmu run's bound of a controller's requests (SI): refused as run refuses it
                        ("request_brake", 1e308), ("request_deceleration", -2e9), ("request_steer", 1.0000001e9)):
        instance.messages.clear()
        assert instance.set(**{name: value}) == fmi_fuzz.ERROR
        assert any(status == fmi_fuzz.ERROR and name in text for status, _, text in instance.messages), name
    # the instance goes on: nothing was changed
    assert instance.step(0.0, 0.01)[0] == fmi_fuzz.OK and instance.get("throttle") >= 0.0
    # a controller's requests beyond the pedals' and the steer's range are taken (sdl-fmu run takes them and limits
    # them in the arbitration: test_the_controller_requests_are_arbitrated_as_the_run_arbitrates)
    assert instance.set(request_active=True, request_brake=1.5, request_throttle=-0.1, request_steer=-4.0,
                        request_deceleration=-3.0) == fmi_fuzz.OK
    assert (instance.get("throttle"), instance.get("brake")) == (0.0, 1.0)  # the defaults: override, max
    assert instance.set(request_brake=1e9, request_deceleration=-1e9) == fmi_fuzz.OK  # the bound itself is taken
    assert instance.get("brake") == 1.0
    assert instance.set(speed=10.0) == fmi_fuzz.ERROR  # a fixed parameter after initialization
    instance.free()


@pytest.mark.parametrize("version", [2, 3])
def test_wrong_token_missing_resources_and_other_interfaces_are_refused(demo_fmus, version, tmp_path):
    fmu = demo_fmus[version]
    folder = unzipped(fmu.path, tmp_path)
    description = read_model_description(str(folder))
    library = fmi_fuzz.load_library(folder / "binaries" / ("linux64" if version == 2 else "x86_64-linux") /
                                    f"{MODEL_IDENTIFIER}.so", version)
    messages = []
    resources = folder / "resources"
    if version == 2:
        callbacks = fmi_fuzz.fmi2_callbacks(fmi_fuzz.Logger(
            lambda env, name, status, category, message, argument: messages.append(ctypes.string_at(argument))))
        instantiate = lambda token, location, kind=fmi_fuzz.CS: library.fmi2Instantiate(  # noqa: E731
            b"x", kind, token, location, ctypes.byref(callbacks), 0, 0)
        location = resources.as_uri().encode()
    else:
        logger = fmi_fuzz.LogMessage3(lambda env, status, category, message: messages.append(message))
        instantiate = lambda token, location, early_mode=False: library.fmi3InstantiateCoSimulation(  # noqa: E731
            b"x", token, location, False, False, early_mode, False, None, 0, None, logger, None)
        location = (str(resources) + "/").encode()
    token = description.guid.encode()
    component = instantiate(token, location)
    assert component
    getattr(library, f"fmi{version}FreeInstance")(component)
    for bad_token, bad_location, reason in ((b"{0}", location, b"wrong GUID"), (token, b"", b"no resource location"),
                                            (token, location.replace(b"resources", b"nowhere"), b"cannot open")):
        messages.clear()
        assert not instantiate(bad_token, bad_location)
        assert any(reason in message for message in messages), messages
    messages.clear()
    if version == 2:
        assert not instantiate(token, location, fmi_fuzz.ME)
        assert any(b"co-simulation only" in message for message in messages)
    else:
        assert not instantiate(token, location, True)  # event mode
        assert any(b"event mode is not supported" in message for message in messages)


MUTATIONS = ["", "nan", "inf", "-inf", "0x1p+99999", "0x", "0x1.p", "1e309", "99999999999999999999", "-1", "0", "7",
             "0x1.fffffffffffffffffffffp+0", "abc", "0x1p+0", "-0x1p+0", "1000000", "0x1p+40", "\t", "none", "#", "%s%n"]

MUTATE = r"""
import ctypes, random, sys, zipfile
from pathlib import Path
sys.path[:0] = [sys.argv[4], sys.argv[5]]
import fmi_fuzz
folder, seed, count = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
text = (folder / "resources" / "scenario.sdlfmu").read_text()
guid = [l.split()[1] for l in text.splitlines() if l.startswith("guid ")][0].encode()
library = fmi_fuzz.load_library(folder / "binaries" / "linux64" / "SdlScenario.so", 2)
messages = []
def log(env, name, status, category, message, argument):
    messages.append((status, ctypes.string_at(argument).decode() if argument else ""))  # ASCII only
callbacks = fmi_fuzz.fmi2_callbacks(fmi_fuzz.Logger(log))
rng = random.Random(seed)
words = %r
refused = accepted = 0
for k in range(count):
    lines = text.splitlines(keepends=True)
    kind = rng.randrange(7)
    if kind == 0:
        mutated = text[:rng.randrange(len(text))]
    elif kind == 1:
        del lines[rng.randrange(len(lines))]; mutated = "".join(lines)
    elif kind == 2:
        i = rng.randrange(len(lines)); lines.insert(i, lines[rng.randrange(len(lines))]); mutated = "".join(lines)
    elif kind == 3:
        i = rng.randrange(len(lines)); tokens = lines[i].split(" ")
        tokens[rng.randrange(len(tokens))] = rng.choice(words); lines[i] = " ".join(tokens); mutated = "".join(lines)
    elif kind == 4:
        data = bytearray(text.encode()); data[rng.randrange(len(data))] = rng.randrange(256)
        mutated = data.decode("latin-1")
    elif kind == 5:
        i, j = rng.randrange(len(lines)), rng.randrange(len(lines)); lines[i], lines[j] = lines[j], lines[i]
        mutated = "".join(lines)
    else:
        i = rng.randrange(len(lines)); lines[i] = lines[i].rstrip("\n") + " " + rng.choice(words) + "\n"
        mutated = "".join(lines)
    (folder / "resources" / "scenario.sdlfmu").write_bytes(mutated.encode("latin-1"))
    messages.clear()
    c = library.fmi2Instantiate(b"m", 1, guid, (folder / "resources").as_uri().encode(), ctypes.byref(callbacks), 0, 0)
    if not c:
        refused += 1
        assert messages and messages[-1][0] == 3 and "fmi2Instantiate: " in messages[-1][1], messages
        assert "resources/scenario.sdlfmu:" in messages[-1][1] or "wrong GUID" in messages[-1][1], messages
        continue
    accepted += 1  # a harmless change (a value within its range): it must run
    assert library.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == 0
    assert library.fmi2EnterInitializationMode(c) == 0
    assert library.fmi2ExitInitializationMode(c) == 0
    t = 0.0
    for step in range(20):
        assert library.fmi2DoStep(c, t, 0.5, 1) in (0, 3)
        t += 0.5
    library.fmi2FreeInstance(c)
print(refused, accepted)
"""


def test_a_malformed_resources_file_is_an_fmi_error_with_a_log_line(demo_fmus, tmp_path):
    """1000 seeded corruptions of resources/scenario.sdlfmu (truncated, lines deleted, duplicated, swapped, fields
    replaced by garbage, NaN, inf, huge or negative numbers, bytes changed): each is refused at instantiation with
    one error message naming the file and line, or (a harmless change) runs; never a crash (the loop runs in a
    subprocess: a crash would fail the test with its exit status)."""
    folder = unzipped(demo_fmus[2].path, tmp_path)
    completed = subprocess.run([sys.executable, "-c", MUTATE % MUTATIONS, str(folder), "20261126", "1000",
                                str(TESTS), str(TESTS.parent / "tools")], capture_output=True, text=True, timeout=600)
    assert completed.returncode == 0, completed.stderr[-3000:]
    refused, accepted = map(int, completed.stdout.split())
    assert refused + accepted == 1000 and refused > 500 and accepted > 0


def test_the_resources_file_names_the_line_of_a_problem(demo_fmus, tmp_path):
    original = zipfile.ZipFile(demo_fmus[2].path).read("resources/scenario.sdlfmu").decode()
    lines = original.splitlines()
    brake = next(i for i, line in enumerate(lines) if line.startswith("BRK "))
    pedal = lines[brake].split()[3]
    cases = {"range": (brake, lines[brake].replace(pedal, "0x1.8p+0", 1),
                       rf"resources/scenario.sdlfmu:{brake + 1}: pedal: 1.5 is outside \[0, 1\]"),
             "decimal": (brake, lines[brake].replace(pedal, "1.0", 1),
                         rf"resources/scenario.sdlfmu:{brake + 1}: pedal: '1.0' is not a hexadecimal floating-point"),
             "truncated": (len(lines) - 1, "", r"resources/scenario.sdlfmu:\d+: 'end' expected, the file ends"),
             "unknown": (brake, "XYZ 1 2", rf"resources/scenario.sdlfmu:{brake + 1}: an event \(A, BRK, RSA or ES\) "
                                           "expected, found 'XYZ'")}
    for name, (index, replacement, expected) in cases.items():
        changed = list(lines)
        changed[index] = replacement
        instance = ScenarioInstance(demo_fmus[2].path, tmp_path / name, resources_text="\n".join(changed) + "\n")
        assert not instance.component
        assert [text for _, _, text in instance.messages if re.search(expected, text)], (name, instance.messages)


# ---- what a master sees ------------------------------------------------------------------------------------------


def drive(instance, seconds: float, h: float = 0.01, speed: float = 26.8224, lateral: float = -1.8288, t0: float = 0.0):
    """Steps the instance with an ego at a constant speed along lane 1 (its inputs set by hand) from t0."""
    t = t0
    for k in range(int(round(seconds / h))):
        t = t0 + k * h
        assert instance.set(ego_x=speed * t, ego_y=lateral, ego_v=speed, ego_s=speed * t, ego_vx=speed) == 0
        status = instance.step(t, h)
        assert status[0] == 0, instance.messages[-3:]
    return t0 + round(seconds / h) * h


@pytest.mark.parametrize("version", [2, 3])
def test_inputs_changed_after_initialization_give_the_start_of_the_first_step(version, tmp_path, simple_model):
    """Masters (libcosim, ecos) pass the ego's outputs on in initialization mode; a vehicle FMU that fills them only
    when it leaves initialization hands over an ego at rest at the origin there, and its start only before the first
    step. The first doStep takes the start again from its inputs (docs/scenario-fmu.md, Wiring): from its outputs on,
    everything is bit for bit as if the inputs had been right in initialization mode (here a car spawned at distance
    0 in the ego's lane, *0: beside the ego's start, not on the dividing line; the driver's first sample), the start's
    events are logged once, and a warning says that the start was taken again. Unchanged inputs: no warning."""
    path = tmp_path / "spawn_at_start.sdl"
    path.write_text("English\n0,A,40,300,*0,2\n1600,ES\n")
    fmu = write_scenario_fmu(api.load(path), tmp_path / "spawn.fmu", ego=simple_model, fmi_version=version)
    speed, lateral = 26.8224, -1.8288
    start = {"ego_v": speed, "ego_vx": speed, "ego_y": lateral}
    outputs = ("throttle", "brake", "steer", "events", "tv1_present", "tv1_x", "tv1_y", "tv1_v", "lead_gap",
               "last_event_time")
    runs = {}
    for name, initial in (("given in initialization", start), ("given after it", {"ego_y": 0.0, "ego_v": 0.0})):
        instance = ScenarioInstance(fmu.path, tmp_path / name.replace(" ", "-"))
        instance.debug_logging(True)
        instance.initialize({}, initial)
        read_then = (instance.get("tv1_y"), instance.get("throttle"))  # what a master passes on before the step
        if initial is not start:
            assert read_then[0] == 0.0 and read_then[1] == 1.0  # from the ego at rest on the dividing line
            assert instance.set(**start) == 0
        rows = []
        for k in range(10):
            t = k * 0.01
            assert instance.set(ego_x=speed * t, ego_s=speed * t) == 0
            assert instance.step(t, 0.01)[0] == 0, instance.messages[-3:]
            rows.append(tuple(instance.get(name) for name in outputs))
        warnings = [text for status, category, text in instance.messages if category == "logStatusWarning"]
        runs[name] = rows, [(e.code, e.action, e.time, e.detail) for e in instance.events()], warnings
        instance.free()
    right, late = runs["given in initialization"], runs["given after it"]
    assert late[0] == right[0] and late[1] == right[1]
    assert right[0][0][6] == lateral and [e[:2] for e in right[1]] == [("A", "spawn")]  # beside the ego, logged once
    assert right[2] == [] and len(late[2]) == 1 and "changed between initialization and the first step" in late[2][0]


@pytest.mark.parametrize("version", [2, 3])
def test_the_end_is_reported_as_termination_and_nothing_fires_after_it(version, tmp_path, simple_model):
    """head_on: a car in the ego's lane from 200 ft on, ES at 1600 ft (18.2 s at 88 ft/s): a contact, then the end."""
    fmu = write_scenario_fmu(api.load("head_on"), tmp_path / "head_on.fmu", ego=simple_model, fmi_version=version)
    instance = ScenarioInstance(fmu.path, tmp_path / "unzipped")
    instance.debug_logging(True)
    instance.initialize({}, {"ego_v": 26.8224, "ego_vx": 26.8224, "ego_y": -1.8288})
    end_time = 1600 * 0.3048 / 26.8224  # s: the ES distance at the start speed
    t = drive(instance, 18.0)
    assert not instance.get("ended") and instance.get("end_reason") == 0
    assert instance.get("collisions") == 1 and instance.get("last_event_code") == 1
    t = drive(instance, 0.5, t0=t)
    assert instance.get("ended") and instance.get("end_reason") == 1  # scenario (ES)
    assert instance.get("last_event_code") == 4 and instance.get("last_event_action") == 8
    assert abs(instance.get("last_event_time") - end_time) < 1e-6
    if version == 2:
        assert instance.terminated()
    events, collisions = instance.get("events"), instance.get("collisions")
    before = len(instance.events())
    for k in range(50):  # the master may go on: OK, terminate flagged, nothing counted
        status, _, _, terminate = instance.step(t + k * 0.01, 0.01)
        assert status == 0 and (terminate or version == 2)
    assert (instance.get("events"), instance.get("collisions"), len(instance.events())) == (events, collisions, before)
    assert [(e.code, e.action) for e in instance.events()] == [("A", "spawn"), ("A", "collision"), ("A", "despawn"),
                                                               ("ES", "end")]
    instance.free()


@pytest.mark.parametrize("version", [2, 3])
def test_fmu_states_round_trip_and_foreign_or_inconsistent_ones_are_refused(demo_fmus, version, tmp_path,
                                                                            simple_model):
    instance = ScenarioInstance(demo_fmus[version].path, tmp_path / "a")
    instance.initialize({}, {"ego_v": 26.8224, "ego_vx": 26.8224, "ego_y": -1.8288})
    t = drive(instance, 8.0)  # one vehicle spawned (500 ft)
    state = instance.get_state()
    outputs = [instance.get(name) for name in ("throttle", "lead_gap", "tv1_x", "events")]
    drive(instance, 4.0, t0=t)
    assert [instance.get(name) for name in ("throttle", "lead_gap", "tv1_x", "events")] != outputs
    assert instance.set_state(state) == 0
    assert [instance.get(name) for name in ("throttle", "lead_gap", "tv1_x", "events")] == outputs
    # serialized, changed and re-signed: the checksum matches, the scenario check refuses it
    size = ctypes.c_size_t()
    prefix = "fmi2" if version == 2 else "fmi3"
    sized = getattr(instance.library, f"{prefix}SerializedFMU{'state' if version == 2 else 'State'}Size")
    sized.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.POINTER(ctypes.c_size_t)]
    assert sized(instance.component, state, ctypes.byref(size)) == 0
    buffer = ctypes.create_string_buffer(size.value)
    assert instance.call("SerializeFMUstate" if version == 2 else "SerializeFMUState", state, buffer, size.value) == 0
    blob = bytearray(buffer.raw)
    header = 9 * 8  # magic, GUID hash, nx nd nu np, mode, time, solver step (instance.c)
    for field, value in ((2, 1e9), (12, 0.5)):  # D_NEXT_EVENT out of range; D_FINISHED neither 0 nor 1
        changed = bytearray(blob)
        changed[header + 8 * field: header + 8 * field + 8] = struct_pack(value)
        changed[-8:] = fnv1a(bytes(changed[:-8])).to_bytes(8, sys.byteorder)
        copy = ctypes.c_void_p()
        instance.messages.clear()
        assert instance.call("DeSerializeFMUstate" if version == 2 else "DeserializeFMUState", bytes(changed),
                             len(changed), ctypes.byref(copy)) == fmi_fuzz.ERROR
        assert any("inconsistent" in text for _, _, text in instance.messages)
    # another scenario's state: same sizes impossible to mix up (GUID hash), so the message says so
    other_fmu = write_scenario_fmu(api.load("head_on"), tmp_path / "other.fmu", ego=simple_model, fmi_version=version)
    other = ScenarioInstance(other_fmu.path, tmp_path / "b")
    other.initialize({}, {"ego_v": 26.8224})
    instance.messages.clear()
    assert instance.set_state(other.get_state()) == fmi_fuzz.ERROR
    assert instance.free_state(state) == 0
    other.free()
    instance.free()


def struct_pack(value: float) -> bytes:
    import struct

    return struct.pack("=d", value)


def fnv1a(data: bytes) -> int:
    """The serialized state's checksum (instance.c): 64-bit FNV-1a."""
    value = 14695981039346656037
    for byte in data:
        value = ((value ^ byte) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return value


def test_each_event_is_a_log_line_and_the_last_one_is_in_the_outputs(demo_fmus, tmp_path):
    instance = ScenarioInstance(demo_fmus[2].path, tmp_path)
    instance.initialize({}, {"ego_v": 26.8224, "ego_vx": 26.8224, "ego_y": -1.8288})
    drive(instance, 6.0)  # 500 ft at 88 ft/s: 5.68 s; no logging asked for: no debug lines
    assert instance.get("events") == 1 and instance.events() == []
    assert instance.debug_logging(True) == 0
    t = drive(instance, 6.0, t0=6.0)  # 900 ft: the second spawn, a random model
    spawn = instance.events()[-1]
    assert (spawn.code, spawn.action, spawn.vehicle, spawn.line) == ("A", "spawn", 2, 10)  # demo.sdl line 10
    assert re.fullmatch(r"vehicle 2 \(model \d [a-zA-Z ]+\)", spawn.detail), spawn.detail
    assert (instance.get("last_event_code"), instance.get("last_event_action"), instance.get("last_event_vehicle"),
            instance.get("last_event_line"), instance.get("last_event_time")) == (1, 1, 2, 10, spawn.time)
    assert abs(spawn.time - 900 * 0.3048 / 26.8224) < 1e-6 and instance.get("events") == 2 < t
    assert instance.get("traffic_count") == 2 and instance.get("tv2_id") == 2 and instance.get("tv2_present")


def test_the_controller_requests_are_arbitrated_as_the_run_arbitrates(demo_fmus, tmp_path):
    """arbitration.arbitrate (the run's) and the FMU's outputs, bit for bit, for every rule of every channel and 40
    random requests each (pedals inside and outside 0..1, steer beyond the driver's limit and beyond +-pi/2,
    decelerations negative and beyond brake_decel_max, inactive requests), against the driver's commands of the
    moment: the FMU takes every request within +-1e9, as the run does, and limits it as arbitrate does."""
    import itertools

    from sdl_fmu.cosim.arbitration import arbitrate
    from sdl_fmu.vehicle.controller import Request

    rules = ("driver", "override", "max")
    rng = random.Random(20261126)
    brake_decel_max = demo_fmus[2].parameters["ego_brake_decel_max"]
    for number, (throttle_rule, brake_rule, steer_rule) in enumerate(itertools.product(range(3), repeat=3)):
        instance = ScenarioInstance(demo_fmus[2].path, tmp_path / str(number))
        speed = rng.choice([10.0, 40.0])  # below the target: the driver accelerates; above: it brakes
        instance.initialize({"arbitration_throttle": throttle_rule, "arbitration_brake": brake_rule,
                             "arbitration_steer": steer_rule}, {"ego_v": speed, "ego_vx": speed, "ego_y": -1.0})
        driver = tuple(instance.get(name) for name in ("driver_throttle", "driver_brake", "driver_steer"))
        for _ in range(40):
            request = Request(rng.random() < 0.8, rng.choice([0.0, rng.random(), 1.0, rng.uniform(-3, 4)]),
                              rng.choice([0.0, rng.random(), 1.0, rng.uniform(-3, 4)]),
                              rng.choice([rng.uniform(-1.5, 1.5), rng.uniform(-10, 10)]),
                              rng.choice([0.0, rng.uniform(0, 15), rng.uniform(-15, 40)]))
            assert instance.set(request_active=request.active, request_throttle=request.throttle,
                                request_brake=request.brake, request_steer=request.steer,
                                request_deceleration=request.deceleration) == 0
            want = arbitrate(driver, request, {"throttle": rules[throttle_rule], "brake": rules[brake_rule],
                                               "steer": rules[steer_rule]}, brake_decel_max)
            assert tuple(instance.get(name) for name in ("throttle", "brake", "steer")) == want, (request, want)
        instance.free()


@pytest.mark.slow
@pytest.mark.parametrize("version", [2, 3])
def test_random_call_sequences(demo_fmus, version):
    report = fmi_fuzz.fuzz(demo_fmus[version].path, sequences=1000, seed=20261126, hang_timeout=120.0)
    assert report.sequences == 1000 and report.calls > 10000
    assert report.crashes == [] and report.hangs == [] and report.violations == []
    # no error the oracle does not predict: the scenario FMU has no numerical failure, and a step that ran to its
    # budget (a sample never taken at a negative start time did, before the fix) is one
    assert report.unpredicted == []
    statuses = report.statuses
    assert sum(n for key, n in statuses.items() if key.endswith("DoStep OK")) > 1000
    assert sum(n for key, n in statuses.items() if key.endswith("SetFMUstate OK") or key.endswith("SetFMUState OK"))


@pytest.mark.slow
def test_the_binary_rebuilds_from_its_sources_with_the_documented_line(demo_fmus, tmp_path):
    """The compiler line of documentation/index.html, run in the unzipped FMU, builds a binary that replays the
    demo as the shipped one does."""
    folder = unzipped(demo_fmus[2].path, tmp_path / "fmu")
    documentation = (folder / "documentation" / "index.html").read_text()
    line = re.search(r"<pre>(cc -std=c99 [^<]+)</pre>", documentation)[1]
    built = subprocess.run(line.replace("-o SdlScenario.so", "-o binaries/linux64/SdlScenario.so"), shell=True,
                           cwd=folder, capture_output=True, text=True)
    assert built.returncode == 0, built.stderr
    rebuilt = tmp_path / "rebuilt.fmu"
    shutil.make_archive(str(rebuilt.with_suffix("")), "zip", folder)
    rebuilt.with_suffix(".zip").rename(rebuilt)
    model = api.ego_model("simple")
    result = api.run("demo")
    assert replay(result, rebuilt, tmp_path / "replayed", model.length, model.width) == []


# ---- the Windows binary under wine --------------------------------------------------------------------------------

HOST_OUTPUTS = ("tv1_x", "lead_gap", "throttle", "steer")


@pytest.fixture(scope="module")
def hosts(tmp_path_factory, c_host):
    """The plain C host (tests/hosts/fmi_host.c) for Linux and, built with mingw-w64, for Windows."""
    from sdl_fmu.fmu.package import fmi_headers, mingw_compiler

    compiler = mingw_compiler()
    if compiler is None:
        message = "x86_64-w64-mingw32-gcc is not installed (Debian: apt-get install gcc-mingw-w64-x86-64)"
        if windows_tools_required():
            pytest.fail(message)
        pytest.skip(message)
    windows = tmp_path_factory.mktemp("host") / "fmi_host.exe"
    subprocess.run([compiler, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-static-libgcc",
                    f"-I{fmi_headers()}", str(TESTS / "hosts" / "fmi_host.c"), "-o", str(windows)], check=True)
    return c_host, windows


def host_run(runner, host, fmu, folder: Path, version: int, windows: bool):
    """head_on's scenario FMU in the C host for 15 s at 10 ms, an ego held at 70 m along lane 1 (its inputs
    constant): the car in its lane spawns at initialization (200 ft) and approaches; every output once a second."""
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    description = read_model_description(str(folder))
    vr = {v.name: v.valueReference for v in description.modelVariables}
    platform = {(2, False): "linux64", (2, True): "win64", (3, False): "x86_64-linux", (3, True): "x86_64-windows"}
    library = folder / "binaries" / platform[version, windows] / f"{MODEL_IDENTIFIER}.{'dll' if windows else 'so'}"
    resources = folder / "resources"
    if windows:
        native = "Z:" + str(resources).replace("/", "\\")
        location = ("file:///" + native.replace("\\", "/")) if version == 2 else native + "\\"
        library = "Z:" + str(library).replace("/", "\\")
    else:
        location = resources.as_uri() if version == 2 else str(resources) + "/"
    inputs = {"ego_x": 70.0, "ego_s": 70.0, "ego_y": -1.8288, "ego_v": 26.8224, "ego_vx": 26.8224}
    arguments = [*(["--fmi3"] if version == 3 else []), library, description.guid, "0.01", "15", "--every", "100",
                 "--resources", location, *[f"r:{vr[name]}={value!r}" for name, value in inputs.items()],
                 *[f"o:{vr[name]}" for name in HOST_OUTPUTS], f"b:{vr['lead_present']}"]
    completed = runner([host, *arguments])
    assert completed.returncode == 0, completed.stderr[-3000:]
    return [line.split()[1:] for line in completed.stdout.splitlines() if line.startswith("RESULT")]


@pytest.mark.slow
@pytest.mark.parametrize("version", [2, 3])
def test_the_windows_binary_under_wine_runs_as_the_linux_one(hosts, wine, tmp_path, version, simple_model):
    """The same IEEE 754 bits for the traffic and the lead gap (no transcendental function of a non-zero angle
    in them here); the driver's commands to 1e-12 (mingw-w64's libm against glibc's)."""
    import struct

    fmu = write_scenario_fmu(api.load("head_on"), tmp_path / "head_on.fmu", ego=simple_model, fmi_version=version)

    linux = host_run(lambda arguments: subprocess.run(list(map(str, arguments)), capture_output=True, text=True,
                                                      timeout=300),
                     hosts[0], fmu.path, tmp_path / "linux", version, windows=False)
    windows = host_run(wine, hosts[1], fmu.path, tmp_path / "windows", version, windows=True)
    assert len(linux) == len(windows) == 16
    value = lambda word: struct.unpack(">d", bytes.fromhex(word))[0]  # noqa: E731
    for ours, theirs in zip(linux, windows):
        assert ours[:3] == theirs[:3]  # time, tv1_x, lead_gap
        assert all(abs(value(a) - value(b)) <= 1e-12 * max(1.0, abs(value(a))) for a, b in zip(ours[3:], theirs[3:]))
    assert value(linux[-1][1]) < value(linux[0][1]) and value(linux[-1][-1]) == 1.0  # approaching, the lead vehicle


# ---- one FMI layer: the ego FMUs' ----------------------------------------------------------------------------------

MODEL_EXCHANGE = {2: ("EnterEventMode", "NewDiscreteStates", "EnterContinuousTimeMode", "CompletedIntegratorStep",
                      "SetTime", "SetContinuousStates", "GetEventIndicators", "GetContinuousStates", "GetDerivatives",
                      "GetNominalsOfContinuousStates"),
                  3: ("EnterEventMode", "UpdateDiscreteStates", "EnterContinuousTimeMode", "CompletedIntegratorStep",
                      "SetTime", "SetContinuousStates", "GetContinuousStateDerivatives", "GetEventIndicators",
                      "GetContinuousStates", "GetNominalsOfContinuousStates", "GetNumberOfEventIndicators",
                      "GetNumberOfContinuousStates")}
SIZE, VRS, REALS = ctypes.c_size_t, ctypes.POINTER(ctypes.c_uint), ctypes.POINTER(ctypes.c_double)
NOT_PROVIDED = {2: {"GetDirectionalDerivative": (VRS, SIZE, VRS, SIZE, REALS, REALS)},
                3: {name: (VRS, SIZE, VRS, SIZE, REALS, SIZE, REALS, SIZE)
                    for name in ("GetDirectionalDerivative", "GetAdjointDerivative")}}
EXTRA_SIGNATURES = {3: {"GetNumberOfEventIndicators": (ctypes.POINTER(SIZE),),
                        "GetNumberOfContinuousStates": (ctypes.POINTER(SIZE),)}}


@pytest.mark.parametrize("version", [2, 3])
def test_the_scenario_fmu_runs_on_the_ego_fmus_fmi_layer(demo_fmus, version, tmp_path):
    """One FMI layer per version serves every FMU (docs/fmu-runtime.md): the scenario FMU is built from the ego FMUs'
    fmi2Functions.c / fmi3Functions.c as they are, so its state table is the one tests/fmu/test_state_tables.py compares
    with the standard's. What differs is the model's data (ModelHooks): it has no model-exchange interface, so every
    model-exchange function of that layer refuses, in every state, with a message, and it provides no partial
    derivatives."""
    from sdl_fmu.export.binary import EGO_RUNTIME_DIRECTORY

    folder = unzipped(demo_fmus[version].path, tmp_path)
    sources = folder / "sources"
    layer = f"fmi{version}Functions.c"
    assert (sources / layer).read_bytes() == (EGO_RUNTIME_DIRECTORY / layer).read_bytes()
    assert sorted(path.name for path in sources.glob("fmi*Functions.c")) == [layer]
    library = fmi_fuzz.load_library(folder / "binaries" / ("linux64" if version == 2 else "x86_64-linux") /
                                    f"{MODEL_IDENTIFIER}.so", version)
    token = read_model_description(str(folder)).guid.encode()
    messages = []
    if version == 2:
        callbacks = fmi_fuzz.fmi2_callbacks(fmi_fuzz.Logger(
            lambda env, name, status, category, message, argument: messages.append(ctypes.string_at(argument))))
        component = library.fmi2Instantiate(b"x", fmi_fuzz.CS, token, (folder / "resources").as_uri().encode(),
                                            ctypes.byref(callbacks), 0, 0)
    else:
        logger = fmi_fuzz.LogMessage3(lambda env, status, category, message: messages.append(message))
        component = library.fmi3InstantiateCoSimulation(b"x", token, (str(folder / "resources") + "/").encode(),
                                                        False, False, False, False, None, 0, None, logger, None)
    assert component
    prefix = f"fmi{version}"

    def refused(name, argtypes, reason):
        function = getattr(library, prefix + name)
        if argtypes is not None:
            function.restype, function.argtypes = ctypes.c_int, [ctypes.c_void_p, *argtypes]
        arguments = [0.0 if kind in (ctypes.c_double,) else 0 if kind in (ctypes.c_int, SIZE, ctypes.c_bool)
                     else None for kind in function.argtypes[1:]]
        messages.clear()
        assert function(component, *arguments) == fmi_fuzz.ERROR, name
        assert any(reason in message for message in messages), (name, messages)

    def refuse_all(derivatives=False):
        for name in MODEL_EXCHANGE[version]:
            refused(name, EXTRA_SIGNATURES.get(version, {}).get(name), b"co-simulation only")
        for name, argtypes in NOT_PROVIDED[version].items() if derivatives else ():  # where the state table allows
            refused(name, argtypes, b"not provided")

    refuse_all()  # Instantiated
    if version == 2:
        assert library.fmi2SetupExperiment(component, 0, 0.0, 0.0, 0, 0.0) == fmi_fuzz.OK
        assert library.fmi2EnterInitializationMode(component) == fmi_fuzz.OK
        refuse_all()  # Initialization Mode
        assert library.fmi2ExitInitializationMode(component) == fmi_fuzz.OK
    else:
        assert library.fmi3EnterInitializationMode(component, False, 0.0, 0.0, False, 0.0) == fmi_fuzz.OK
        refuse_all()
        assert library.fmi3ExitInitializationMode(component) == fmi_fuzz.OK
    refuse_all(derivatives=True)  # Step Mode
    getattr(library, f"{prefix}FreeInstance")(component)


@pytest.mark.parametrize("version", [2, 3])
def test_the_documentations_fmpy_example_runs_as_written(version, tmp_path, simple_model, simple_fmus):
    """documentation/index.html's example: the scenario FMU and the Simple ego FMU in a fixed-step master written
    out with fmpy; head_on ends at ES (1600 ft at 88 ft/s: 18.18 s) with its 4 events and the one collision. It
    leaves nothing in its temporary folder (the FMUs it unpacks are removed)."""
    import html

    fmu = write_scenario_fmu(api.load("head_on"), tmp_path / "scenario.fmu", ego=simple_model, fmi_version=version)
    shutil.copy(simple_fmus[version], tmp_path / "EgoVehicleSimple.fmu")
    documentation = zipfile.ZipFile(fmu.path).read("documentation/index.html").decode()
    code = html.unescape(re.search(r"<h2>Using it with fmpy</h2>.*?<pre>(.*?)</pre>", documentation, re.S)[1])
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    completed = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                               timeout=300, env={**os.environ, "TMPDIR": str(temporary)})
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.strip() == "ended at 18.19 s: [4, 1]"
    assert os.listdir(temporary) == []


@pytest.mark.parametrize("start", [-1.0, 7.3])
def test_a_start_time_other_than_zero_shifts_the_scenario_in_time(demo_fmus, tmp_path, start):
    """The clocks count from the start time (driver samples at start + k x driver_period): the same inputs at the
    same times after the start give the same commands and events (found by the fuzzer: with a negative start time
    a sample was never taken and the step ran to its budget)."""
    runs = []
    for offset in (0.0, start):
        instance = ScenarioInstance(demo_fmus[2].path, tmp_path / str(offset))
        instance.initialize({}, {"ego_v": 26.0, "ego_vx": 26.0, "ego_y": -1.8288}, start_time=offset)
        commands = []
        for k in range(500):  # 5 s, the speed passing the driver's target (26.8 m/s); no event before 500 ft
            t, v = offset + k * 0.01, 26.0 + 0.004 * k
            assert instance.set(ego_x=v * k * 0.01, ego_s=v * k * 0.01, ego_v=v, ego_vx=v) == 0
            assert instance.step(t, 0.01)[0] == 0, instance.messages[-2:]
            commands.append((instance.get("throttle"), instance.get("steer")))
        runs.append(commands)
        instance.free()
    assert runs[0] == runs[1]
    assert len(set(runs[0])) == 101  # the driver sampled at t = start + k x 0.05 s, 100 times, and at the start


def braking_target(tmp_path):
    """A Scenario made in Python, as the vehicle test packs make them: a car 40 m ahead in the ego's lane, moving its
    way at 20 m/s and braking to rest over 5 s from its spawn (an `initial` transition, which SDL text cannot give)."""
    import dataclasses

    from sdl_fmu.sdl.events import Action, ApproachingVehicle, ClosureTrigger, ModelChoice, Relative

    base = api.load("head_on")
    target = ApproachingVehicle(line=1, distance=0.0, speed=Relative(-20.0, False), gap=40.0,
                                lateral=Relative(0.0, True), model=ModelChoice(1, 1), actions=(),
                                initial=Action(ClosureTrigger(1.0, None), Relative(0.0, True), Relative(0.0, False),
                                               5.0))
    return dataclasses.replace(base, path=str(tmp_path / "braking_target"), events=(target,), end_distance=None)


@pytest.mark.parametrize("driver, on_collision", [("follow", "continue"), ("lane", "stop")])
def test_a_scenario_made_in_python_with_an_initial_transition_replays_bit_for_bit(driver, on_collision, tmp_path,
                                                                                 simple_model):
    """The follow driver stops behind the braking car; the lane driver hits it and, with on_collision stop, the run
    ends there (end_reason 6)."""
    scenario = braking_target(tmp_path)
    result = api.run(scenario, until_time=20.0, driver=driver, on_collision=on_collision)
    fmu = write_scenario_fmu(scenario, tmp_path / "target.fmu", ego=simple_model, until_time=20.0, driver=driver,
                             on_collision=on_collision)
    assert replay(result, fmu.path, tmp_path / "replayed", simple_model.length, simple_model.width) == []
    assert result.collisions == (1 if driver == "lane" else 0)
    last = list(result.events)[-1]
    assert last["code"] == "ES" and last["reason"] == ("collision" if on_collision == "stop" else "until_time")
