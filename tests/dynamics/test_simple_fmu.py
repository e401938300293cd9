"""The Simple ego FMU, loaded for real through fmpy (and libcosimpy in a subprocess), against the
closed-form braking distances (docs/verification.md)."""

import shutil
import subprocess
import sys
import textwrap
import zipfile

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy import extract, read_model_description

from sdl_fmu.cosim.ego import EgoFMU, step_until

from helpers import COSIM_TOLERANCE, MODEL_EXCHANGE_TOLERANCE, MU, V0, G, expected_distance, start_values


@pytest.mark.parametrize("step", [0.001, 0.01, 0.1])
@pytest.mark.parametrize("resistances", [False, True], ids=["no-resistances", "drag+rolling"])
def test_braking_distance_cosimulation(simple_fmu, defaults_simple, step, resistances):
    values, brake = start_values(resistances)
    result = simulate_fmu(simple_fmu, fmi_type="CoSimulation", start_values=values, input=brake,
                          output=["s", "v", "stopped"], stop_time=10.0, output_interval=step)
    expected = expected_distance(defaults_simple, resistances)
    assert result["stopped"][-1]
    assert abs(result["s"][-1] - expected) / expected < COSIM_TOLERANCE


@pytest.mark.parametrize("resistances", [False, True], ids=["no-resistances", "drag+rolling"])
def test_braking_distance_model_exchange(simple_fmu, defaults_simple, resistances):
    values, brake = start_values(resistances)
    result = simulate_fmu(simple_fmu, fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-10,
                          start_values=values, input=brake, output=["s", "v", "stopped"], stop_time=10.0,
                          output_interval=0.01)
    expected = expected_distance(defaults_simple, resistances)
    assert result["stopped"][-1] and result["v"][-1] == 0.0
    assert abs(result["s"][-1] - expected) / expected < MODEL_EXCHANGE_TOLERANCE


def test_partial_pedal_below_friction_limit(simple_fmu, defaults_simple):
    # 25 % pedal demands 0.25 * brake_decel_max < mu g, so the pedal sets the deceleration
    values, brake = start_values(False, brake=0.25)
    result = simulate_fmu(simple_fmu, fmi_type="CoSimulation", start_values=values, input=brake,
                          output=["s"], stop_time=20.0, output_interval=0.1)
    expected = V0**2 / (2 * 0.25 * defaults_simple["brake_decel_max"])
    assert abs(result["s"][-1] - expected) / expected < COSIM_TOLERANCE


@pytest.mark.parametrize("step", [0.001, 0.1])
def test_standstill_holds_without_creep_or_chatter(simple_fmu, step):
    values, brake = start_values(True)
    result = simulate_fmu(simple_fmu, fmi_type="CoSimulation", start_values=values, input=brake,
                          output=["s", "v", "ax", "stopped"], stop_time=20.0, output_interval=step)
    stop_index = int(np.argmax(result["stopped"]))
    stop_time = result["time"][stop_index]
    assert result["time"][-1] - stop_time >= 10.0  # the hold is observed for at least 10 s
    held = slice(stop_index, None)
    assert result["stopped"][held].all()  # never released: no chatter
    assert (result["v"][held] == 0.0).all() and (result["ax"][held] == 0.0).all()
    assert np.ptp(result["s"][held]) == 0.0  # no creep, not even round-off
    assert (np.diff(result["s"]) >= 0).all()  # never backwards


def test_standstill_releases_when_throttle_exceeds_holding_forces(simple_fmu, defaults_simple):
    # Stop with full brake; then full throttle against full brake (drive_accel_max < brake_decel_max:
    # held); then brake 0.2 with full throttle: net = drive_accel_max - 0.2 brake_decel_max - f_r g > 0.
    values, _ = start_values(True, v0=10.0)
    ego = EgoFMU(simple_fmu, {**values, "brake": 1.0})
    try:
        for _ in range(300):
            ego.step(0.01)
        assert ego.read().stopped
        ego.set(throttle=1.0)
        s_held = ego.read().s
        for _ in range(100):
            ego.step(0.01)
        assert ego.read().stopped and ego.read().s == s_held
        ego.set(brake=0.2)
        ego.step(0.01)
        state = ego.read()
        p = defaults_simple
        net = p["drive_accel_max"] - 0.2 * p["brake_decel_max"] - p["rolling_resistance"] * G
        assert not state.stopped and state.v > 0
        # from rest, v(t) = net t - (drag: K v^2, negligible at 1 cm/s)
        assert state.v == pytest.approx(net * 0.01, rel=1e-6)
    finally:
        ego.close()


def test_no_steering_authority_under_full_braking(simple_fmu):
    # full pedal demands more than mu g: the friction circle is used up longitudinally, no yaw
    values, brake = start_values(False)
    values["steer"] = 0.1
    result = simulate_fmu(simple_fmu, fmi_type="CoSimulation", start_values=values, input=brake,
                          output=["psi", "yaw_rate"], stop_time=1.0, output_interval=0.01)
    assert np.abs(result["yaw_rate"]).max() < 1e-4 and abs(result["psi"][-1]) < 1e-4


def _run(fmu, instances=1, steps=500):
    values, _ = start_values(True)
    egos = [EgoFMU(fmu, {**values, "brake": 0.7, "steer": 0.02}, instance_name=f"ego{i}") for i in range(instances)]
    trajectories = [[] for _ in egos]
    try:
        for _ in range(steps):
            for ego, trajectory in zip(egos, trajectories):
                ego.step(0.01)
                trajectory.append(ego.read())
    finally:
        for ego in egos:
            ego.close()
    return trajectories


def test_two_instances_side_by_side_are_identical(simple_fmu):
    alone, = _run(simple_fmu, 1)
    first, second = _run(simple_fmu, 2)
    assert first == second == alone


def test_instantiate_again_after_free(simple_fmu):
    first, = _run(simple_fmu)
    again, = _run(simple_fmu)
    assert first == again


def test_reset_restarts_from_start_values(simple_fmu):
    ego = EgoFMU(simple_fmu, {"v0": 20.0, "brake": 1.0})
    try:
        for _ in range(50):
            ego.step(0.01)
        before = ego.read()
        ego.slave.reset()
        ego.time = 0.0
        ego.slave.setupExperiment(startTime=0.0)
        ego.set(v0=20.0, brake=1.0)
        ego.slave.enterInitializationMode()
        ego.slave.exitInitializationMode()
        for _ in range(50):
            ego.step(0.01)
        assert ego.read() == before
    finally:
        ego.close()


def test_fmu_state_rollback_and_serialization(simple_fmu):
    ego = EgoFMU(simple_fmu, {"v0": 20.0, "brake": 0.5})
    try:
        ego.step(0.5)
        snapshot = ego.save()
        ego.step(0.5)
        ahead = ego.read()
        ego.restore(snapshot)
        serialized = ego.slave.serializeFMUstate(snapshot[0])
        ego.step(0.5)
        assert ego.read() == ahead
        ego.slave.setFMUstate(ego.slave.deSerializeFMUstate(serialized))
        ego.time = 0.5
        ego.step(0.5)
        assert ego.read() == ahead
        ego.discard(snapshot)
    finally:
        ego.close()


def test_stop_located_inside_a_long_step(simple_fmu, defaults_simple):
    # one 6 s communication step covers the whole stop (t_stop = v0 / (mu g) = 5.1 s); still exact
    values, _ = start_values(False)
    ego = EgoFMU(simple_fmu, {**values, "brake": 1.0})
    try:
        ego.step(6.0)
        assert ego.read().stopped
        expected = expected_distance(defaults_simple, False)
        assert abs(ego.read().s - expected) / expected < COSIM_TOLERANCE
    finally:
        ego.close()


def test_stop_time_by_rollback_matches_closed_form(simple_fmu, defaults_simple):
    # t_stop = v0 / a with constant deceleration a = min(b a_max, mu g)
    values, _ = start_values(False)
    ego = EgoFMU(simple_fmu, {**values, "brake": 1.0})
    try:
        while not step_until(ego, 0.1, lambda state: state.stopped):
            pass
        assert ego.time == pytest.approx(V0 / (MU * G), abs=2e-9)
    finally:
        ego.close()


def _slave(fmu, guid=None):
    description = read_model_description(str(fmu))
    directory = extract(str(fmu))
    slave = FMU2Slave(guid=guid or description.guid, unzipDirectory=directory,
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName="misuse")
    references = {v.name: v.valueReference for v in description.modelVariables}
    return slave, references, directory


def test_misuse_returns_error_status_not_a_crash(simple_fmu):
    slave, references, directory = _slave(simple_fmu)
    try:
        slave.instantiate()
        with pytest.raises(FMICallException):
            slave.doStep(0.0, 0.1)  # before initialization
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        with pytest.raises(FMICallException):
            slave.setReal([references["s"]], [1.0])  # an output
        with pytest.raises(FMICallException):
            slave.setReal([references["mass"]], [2000.0])  # fixed parameter after initialization
        with pytest.raises(FMICallException):
            slave.getReal([100000])  # unknown value reference
        with pytest.raises(FMICallException):
            slave.getReal([references["stopped"]])  # Boolean read as Real
        with pytest.raises(FMICallException):
            slave.setReal([references["brake"]], [float("nan")])
        with pytest.raises(FMICallException):
            slave.doStep(1.0, 0.1)  # not at the FMU's time
        slave.terminate()
    finally:
        slave.freeInstance()
        shutil.rmtree(directory, ignore_errors=True)


def test_wrong_guid_is_refused(simple_fmu):
    slave, _, directory = _slave(simple_fmu, guid="{00000000-0000-0000-0000-000000000000}")
    try:
        with pytest.raises(Exception):
            slave.instantiate()
    finally:
        shutil.rmtree(directory, ignore_errors=True)


@pytest.mark.slow
def test_sources_rebuild_the_binary(simple_fmu, defaults_simple, tmp_path):
    # an importer on another platform compiles sources/ by buildDescription.xml; fmpy does it here
    from fmpy.build import build_platform_binary

    unzipped = tmp_path / "unzipped"
    with zipfile.ZipFile(simple_fmu) as archive:
        archive.extractall(unzipped)
    shutil.rmtree(unzipped / "binaries")
    (tmp_path / "build").mkdir()
    build_platform_binary(unzipped, build_dir=tmp_path / "build")
    rebuilt = tmp_path / "rebuilt.fmu"
    with zipfile.ZipFile(rebuilt, "w") as archive:
        for path in unzipped.rglob("*"):
            archive.write(path, path.relative_to(unzipped).as_posix())
    values, brake = start_values(False)
    result = simulate_fmu(rebuilt, fmi_type="CoSimulation", start_values=values, input=brake, output=["s"],
                          stop_time=10.0, output_interval=0.1)
    expected = expected_distance(defaults_simple, False)
    assert abs(result["s"][-1] - expected) / expected < COSIM_TOLERANCE


LIBCOSIM_SCRIPT = textwrap.dedent("""
    import json, sys
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    fmu, v0, step = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    execution = CosimExecution.from_step_size(step_size=int(round(step * 1e9)))
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=fmu, instance_name="ego"))
    references = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    execution.real_initial_value(index, references["v0"], v0)
    execution.real_initial_value(index, references["brake"], 1.0)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    execution.simulate_until(target_time=int(10e9))
    s, = observer.last_real_values(index, [references["s"]])
    stopped, = observer.last_boolean_values(index, [references["stopped"]])
    print(json.dumps({"s": s, "stopped": stopped}))
""")


@pytest.mark.slow
@pytest.mark.parametrize("step", [0.01, 0.1])
def test_libcosim_gets_the_same_stopping_distance(simple_fmu, defaults_simple, step):
    # libcosim is an independent C++ master; it runs in a subprocess because it aborts the process
    # on FMUs it cannot load. Defaults: mu 0.8, drag and rolling resistance on.
    completed = subprocess.run([sys.executable, "-c", LIBCOSIM_SCRIPT, str(simple_fmu), str(V0), str(step)],
                               capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stderr[-2000:]
    import json

    result = json.loads(next(line for line in completed.stdout.splitlines() if line.startswith("{")))
    expected = expected_distance(defaults_simple, True, mu=0.8)
    assert result["stopped"]
    assert abs(result["s"] - expected) / expected < COSIM_TOLERANCE
