"""The FMI 3.0 FMUs, loaded through fmpy: valid, the same trajectories as the FMI 2.0 FMUs (same model code),
the closed-form braking distances at the FMI 2.0 tests' tolerances, FMU state, variable communication steps, misuse."""

import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from helpers import COSIM_TOLERANCE, MODEL_EXCHANGE_TOLERANCE, FmpyCar, expected_distance, sdl_fmu, start_values

MODELS = {"simple": "EgoVehicleSimple", "advanced": "EgoVehicleAdvanced"}


@pytest.fixture
def fmus(request, simple_fmus, advanced_fmus):
    return {"simple": simple_fmus, "advanced": advanced_fmus}


@pytest.mark.parametrize("model", list(MODELS))
def test_fmi3_fmu_validates(fmus, model):
    """fmpy validate: 0 problems (the FMI 2.0 twins are validated in test_fmu_binaries.py)."""
    path = fmus[model][3]
    assert path.parent.name == "fmi3" and path.name == f"{MODELS[model]}.fmu"
    assert validate_fmu(str(path)) == []


def interface_attributes(path):
    """ModelExchange / CoSimulation attributes as written in the modelDescription.xml."""
    import xml.etree.ElementTree as ET

    with zipfile.ZipFile(path) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    return {kind: dict(root.find(kind).attrib) for kind in ("ModelExchange", "CoSimulation")}


def test_fmi3_layout_and_interface(simple_fmus, advanced_fmus):
    for fmus, model in ((simple_fmus, "EgoVehicleSimple"), (advanced_fmus, "EgoVehicleAdvanced")):
        with zipfile.ZipFile(fmus[3]) as archive:
            names = archive.namelist()
        assert f"binaries/x86_64-linux/{model}.so" in names
        assert "sources/fmi3Functions.c" in names and "sources/fmi2Functions.c" not in names
        md3, md2 = read_model_description(str(fmus[3])), read_model_description(str(fmus[2]))
        assert md3.fmiVersion == "3.0" and md3.instantiationToken == md2.guid  # one model code, one identity
        capabilities = {version: interface_attributes(fmus[version]) for version in (2, 3)}
        for kind in ("ModelExchange", "CoSimulation"):
            assert {"providesDirectionalDerivatives": "true", "providesAdjointDerivatives": "true",
                    "canGetAndSetFMUState": "true",
                    "canSerializeFMUState": "true"}.items() <= capabilities[3][kind].items()
            assert capabilities[2][kind]["providesDirectionalDerivative"] == "true"
        assert capabilities[3]["CoSimulation"]["canHandleVariableCommunicationStepSize"] == "true"
        # the same variables, value references, types, units and starts in both versions
        variables2 = {v.name: v for v in md2.modelVariables}
        types = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
        for v in md3.modelVariables:
            if v.causality == "independent":
                assert v.name == "time" and v.valueReference == 0
                continue
            twin = variables2[v.name]
            assert (v.valueReference, v.type, v.causality, v.variability, v.unit, v.start) == (
                twin.valueReference, types[twin.type], twin.causality, twin.variability, twin.unit, twin.start)
        assert len(md3.modelVariables) == len(md2.modelVariables) + 1
        units = {u.name: u for u in md3.unitDefinitions}
        assert {d.name for d in units["m"].displayUnits} >= {"ft"}
        assert {d.name for d in units["m/s"].displayUnits} >= {"ft/s"}
        assert md3.numberOfEventIndicators == md2.numberOfEventIndicators > 0
        assert md3.numberOfContinuousStates == md2.numberOfContinuousStates


# ---- the same trajectories as FMI 2.0 -------------------------------------------------------------------


def scenario(model):
    """Start values and an input table that accelerate, steer, brake to a stop (and cross surfaces)."""
    time = [0.0, 1.0, 1.5, 3.0, 3.5]
    signals = {"throttle": [0.4, 0.4, 0.0, 0.0, 0.0], "brake": [0.0, 0.0, 0.0, 0.6, 0.9],
               "steer": [0.0, 0.03, 0.03, -0.02, 0.0]}
    if model == "simple":
        signals["mu_fl"] = [0.8, 0.8, 0.3, 0.3, 0.8]
    dtype = [("time", float)] + [(name, float) for name in signals]
    table = np.array(list(zip(time, *signals.values())), dtype=dtype)
    start = {"v0": 15.0}
    if model == "advanced":
        start["surface_fr"] = 1
    return start, table


# CVode's error control gives results that depend only on the function values and event indicators, which
# are the same machine code in both versions; co-simulation is the same RODAS4 steps. So the trajectories are
# identical up to round-off; held to 1e-9 relative to max(1, |value|) (docs/verification.md).
TRAJECTORY_TOLERANCE = 1e-9


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
@pytest.mark.parametrize("model", list(MODELS))
def test_fmi3_reproduces_fmi2_trajectories(fmus, model, fmi_type):
    start, inputs = scenario(model)
    outputs = ["x", "y", "psi", "s", "v", "ax", "ay", "yaw_rate", "stopped"]
    stop_time = 8.0 if model == "simple" else 4.0
    results = {version: simulate_fmu(str(fmus[model][version]), fmi_type=fmi_type, start_values=start, input=inputs,
                                     output=outputs, stop_time=stop_time, output_interval=0.01, solver="CVode",
                                     relative_tolerance=1e-6)
               for version in (2, 3)}
    two, three = results[2], results[3]
    assert len(two) == len(three) and np.array_equal(two["time"], three["time"])
    for name in outputs:
        a, b = two[name].astype(float), three[name].astype(float)
        assert np.all(np.abs(a - b) <= TRAJECTORY_TOLERANCE * np.maximum(1.0, np.abs(a))), name
    if model == "simple":
        assert two["stopped"][-1]  # the scenario reaches the event of interest


# ---- closed-form braking distances with the FMI 3.0 FMU (tolerances derived in test_simple_fmu.py) -------


@pytest.mark.parametrize("step", [0.001, 0.1])
@pytest.mark.parametrize("resistances", [False, True], ids=["no-resistances", "drag+rolling"])
def test_fmi3_braking_distance_cosimulation(simple_fmus, defaults_simple, step, resistances):
    values, brake = start_values(resistances)
    result = simulate_fmu(simple_fmus[3], fmi_type="CoSimulation", start_values=values, input=brake,
                          output=["s", "v", "stopped"], stop_time=10.0, output_interval=step)
    expected = expected_distance(defaults_simple, resistances)
    assert result["stopped"][-1]
    assert abs(result["s"][-1] - expected) / expected < COSIM_TOLERANCE


@pytest.mark.parametrize("resistances", [False, True], ids=["no-resistances", "drag+rolling"])
def test_fmi3_braking_distance_model_exchange(simple_fmus, defaults_simple, resistances):
    values, brake = start_values(resistances)
    result = simulate_fmu(simple_fmus[3], fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-10,
                          start_values=values, input=brake, output=["s", "v", "stopped"], stop_time=10.0,
                          output_interval=0.01)
    expected = expected_distance(defaults_simple, resistances)
    assert result["stopped"][-1] and result["v"][-1] == 0.0
    assert abs(result["s"][-1] - expected) / expected < MODEL_EXCHANGE_TOLERANCE


class Slave3(FmpyCar):
    """An FMI 3.0 co-simulation instance through fmpy's low-level API, whose steps end where asked, without an
    event or an early return."""

    def step(self, h):
        event, terminate, early, last = self.fmu.doStep(self.time, h)
        assert not (event or terminate or early) and last == pytest.approx(self.time + h, abs=1e-12)
        self.time += h


def test_fmi3_stop_located_inside_a_long_step(simple_fmus, defaults_simple):
    # one 6 s communication step covers the whole stop (t_stop = v0 / (mu g) = 5.1 s): located inside the step
    values, _ = start_values(False)
    slave = Slave3(simple_fmus[3], {**values, "brake": 1.0})
    slave.step(6.0)
    assert slave.fmu.getBoolean([slave.refs["stopped"]]) == [True]
    expected = expected_distance(defaults_simple, False)
    assert abs(slave.get("s")[0] - expected) / expected < COSIM_TOLERANCE
    assert slave.fmu.getFloat64([0]) == [6.0]  # time has value reference 0
    slave.close()


def test_fmi3_variable_communication_steps(simple_fmus, defaults_simple):
    values, _ = start_values(True)
    slave = Slave3(simple_fmus[3], {**values, "brake": 1.0})
    rng = np.random.default_rng(3)
    while slave.time < 10.0:
        slave.step(min(rng.choice([0.001, 0.013, 0.25, 0.7, 1.9]), 10.0 - slave.time))
    expected = expected_distance(defaults_simple, True)
    assert abs(slave.get("s")[0] - expected) / expected < COSIM_TOLERANCE
    slave.close()


def test_fmi3_fmu_state_rollback_and_serialization(advanced_fmus):
    slave = Slave3(advanced_fmus[3], {"v0": 20.0, "brake": 0.5, "steer": 0.02})
    names = ("x", "y", "psi", "s", "vx", "vy", "yaw_rate")
    slave.step(0.5)
    state = slave.fmu.getFMUState()
    serialized = slave.fmu.serializeFMUState(state)
    slave.step(0.5)
    ahead = slave.get(*names)
    slave.fmu.setFMUState(state)
    slave.time = 0.5
    slave.step(0.5)
    assert slave.get(*names) == ahead  # bit-identical
    slave.step(0.3)
    restored = slave.fmu.deserializeFMUState(serialized)
    slave.fmu.setFMUState(restored)
    slave.time = 0.5
    slave.step(0.5)
    assert slave.get(*names) == ahead
    slave.fmu.freeFMUState(state)
    slave.fmu.freeFMUState(restored)
    with pytest.raises(FMICallException):
        slave.fmu.deserializeFMUState(serialized[:-8])  # truncated
    slave.close()


def test_fmi3_misuse_returns_error_status_not_a_crash(simple_fmus, tmp_path):
    md = read_model_description(str(simple_fmus[3]))
    directory = extract(str(simple_fmus[3]), unzipdir=str(tmp_path / "unzipped"))
    wrong = FMU3Slave(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=directory,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="wrong")
    with pytest.raises(Exception):
        wrong.instantiate()  # wrong instantiation token: no instance
    slave = Slave3(simple_fmus[3], {"v0": 10.0})
    references = slave.refs
    with pytest.raises(FMICallException):
        slave.fmu.doStep(1.0, 0.1)  # not at the FMU's time
    with pytest.raises(FMICallException):
        slave.fmu.setFloat64([0], [1.0])  # time
    with pytest.raises(FMICallException):
        slave.fmu.setFloat64([references["s"]], [1.0])  # an output
    with pytest.raises(FMICallException):
        slave.fmu.getInt32([references["v"]])  # a Float64 read as Int32
    with pytest.raises(FMICallException):
        slave.fmu.getInt8([references["v"]])  # no Int8 variables
    with pytest.raises(FMICallException):
        slave.fmu.updateDiscreteStates()  # model exchange only
    with pytest.raises(FMICallException):
        slave.fmu.enterInitializationMode()  # wrong state
    slave.step(0.1)  # still usable after argument errors
    assert slave.get("s")[0] == pytest.approx(1.0, rel=1e-2)
    slave.close()


@pytest.mark.slow
def test_build_command_writes_both_versions(tmp_path):
    completed = sdl_fmu("build", "--dynamics", "simple", "--fmi-version", "all", "--out", tmp_path)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.split() == [str(tmp_path / "fmi2" / "EgoVehicleSimple.fmu"),
                                        str(tmp_path / "fmi3" / "EgoVehicleSimple.fmu")]
    completed = sdl_fmu("build", "--fmi-version", "4", timeout=60)
    assert completed.returncode == 2 and "Traceback" not in completed.stderr and "--fmi-version" in completed.stderr


def _numbers_agree(a, b, tolerance: float) -> bool:
    """Two summary values (dicts, lists, numbers, strings) equal, numbers within `tolerance`."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_numbers_agree(a[k], b[k], tolerance) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_numbers_agree(x, y, tolerance) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        return abs(a - b) <= tolerance
    return a == b


@pytest.mark.parametrize("model, scenario", [("simple", "head_on"), ("simple", "brake_examples"), ("simple", "spin"),
                                             ("advanced", "road_surface_advanced")])
def test_fmi3_build_through_fmu_reproduces_the_fmi2_run(fmus, model, scenario):
    """The shipped FMI 3.0 build given with --fmu goes through the same path as the FMI 2.0 build (its shipped map,
    fmpy's FMI 3 classes, the bound ctypes step path). Both builds compile one generated C model with one runtime,
    so every output agrees to rounding; the runs' events and final state agree to 1e-9 (the contract)."""
    from sdl_fmu import api

    runs = {version: api.run(scenario, dynamics=model, fmu=fmus[model][version]) for version in (2, 3)}
    assert runs[3].raw.vehicle["fmi_version"] == "3.0" and runs[2].raw.vehicle["fmi_version"] == "2.0"
    events = [list(runs[version].events) for version in (2, 3)]
    assert len(events[0]) > 1 and _numbers_agree(events[0], events[1], 1e-9)
    assert _numbers_agree(runs[2].final, runs[3].final, 1e-9)
    assert runs[2].collisions == runs[3].collisions


def test_command_line_runs_an_fmi3_fmu(simple_fmus, tmp_path):
    scenario = tmp_path / "s.sdl"
    scenario.write_text("Metric\n10,ES\n")
    completed = sdl_fmu("run", scenario, "--fmu", simple_fmus[3], "--out", tmp_path / "out", timeout=120, cwd=tmp_path)
    assert completed.returncode == 0, completed.stderr
    import json

    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["vehicle"]["fmi_version"] == "3.0" and summary["final"]["distance"] >= 10.0
