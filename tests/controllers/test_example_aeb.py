"""The shipped example AEB controller (ExampleAeb, sdl_fmu/controllers/example_aeb.md) as an FMU through fmpy, FMI 2.0
and 3.0: its stages switched on the TTC with openPASS's deactivation at 1.5 x the threshold, the brake-to-stop hold,
outputs that answer the inputs of the same instant, a state that can be got and set, both binaries, a model
description fmpy accepts."""

import zipfile

import fmpy
import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from helpers import local_cluster
from sdl_fmu.fmu.cache import cached_fmus
from sdl_fmu.fmu.package import FMI_VERSIONS, mingw_compiler

# the shipped parameters (modelDescription/ExampleAeb.json): thresholds (s) and decelerations (m/s2)
WARNING, PARTIAL, FULL, FACTOR = 2.6, 1.2, 0.6, 1.5
A_PARTIAL, A_FULL = 3.0, 10.0


@pytest.fixture(scope="module")
def aeb_fmus():
    return dict(zip(FMI_VERSIONS, cached_fmus("example-aeb", FMI_VERSIONS)))


class Aeb:
    """An instance through fmpy's FMI 2.0 or 3.0 slave: set (ttc, relative speed), read the outputs, step."""

    def __init__(self, fmu, version, tmp_path, parameters=None):
        self.description = read_model_description(str(fmu))
        self.refs = {v.name: v.valueReference for v in self.description.modelVariables}
        unzipped = fmpy.extract(str(fmu), unzipdir=str(tmp_path / f"aeb{version}"))
        cls = FMU2Slave if version == 2 else FMU3Slave
        self.slave = cls(guid=self.description.guid, unzipDirectory=unzipped,
                         modelIdentifier=self.description.coSimulation.modelIdentifier, instanceName="aeb")
        self.version, self.time = version, 0.0
        self.slave.instantiate()
        if version == 2:
            self.slave.setupExperiment(startTime=0.0)
            self.slave.enterInitializationMode()
        else:
            self.slave.enterInitializationMode(startTime=0.0)
        for name, value in (parameters or {}).items():
            if isinstance(value, bool):
                self.slave.setBoolean([self.refs[name]], [value])
            else:
                self._set_real([self.refs[name]], [value])
        self.slave.exitInitializationMode()

    def _set_real(self, refs, values):
        (self.slave.setReal if self.version == 2 else self.slave.setFloat64)(refs, values)

    def __call__(self, ttc, relative_speed):
        """Sets the inputs, reads (stage, deceleration request, active, warning, throttle request), steps 10 ms."""
        r = self.refs
        self._set_real([r["ttc"], r["relative_speed"]], [ttc, relative_speed])
        get_real = self.slave.getReal if self.version == 2 else self.slave.getFloat64
        get_int = self.slave.getInteger if self.version == 2 else self.slave.getInt32
        stage = get_int([r["stage"]])[0]
        deceleration, throttle = get_real([r["deceleration_request"], r["throttle_request"]])
        active, warning = (bool(b) for b in self.slave.getBoolean([r["active"], r["warning"]]))
        self.slave.doStep(self.time, 0.01)
        self.time += 0.01
        return stage, deceleration, active, warning, throttle

    def close(self):
        self.slave.terminate()
        self.slave.freeInstance()


@pytest.mark.parametrize("version", FMI_VERSIONS)
def test_stages_come_on_below_their_thresholds_and_go_off_above_1_5_times_them(aeb_fmus, version, tmp_path):
    aeb = Aeb(aeb_fmus[version], version, tmp_path, {"brake_to_stop": False})
    closing = -5.0
    # (TTC, expected stage, deceleration): each row follows from the one before by the rule
    # on' = TTC <= 1.5 T if on else TTC < T, with T = 2.6 (warning), 1.2 (partial), 0.6 (full); the TTCs stay 0.01 s
    # off 1.5 T, which is not a double (1.5 x 1.2 = 1.7999999999999998 in binary)
    rows = [(5.0, 0, 0.0),            # all off
            (WARNING, 0, 0.0),        # not below 2.6: off
            (2.59, 1, 0.0),           # warning on
            (3.89, 1, 0.0),           # 3.89 <= 1.5 x 2.6: stays on
            (3.91, 0, 0.0),           # above 3.9: off
            (1.19, 2, A_PARTIAL),     # warning and partial on
            (1.79, 2, A_PARTIAL),     # 1.79 <= 1.5 x 1.2: partial stays
            (0.59, 3, A_FULL),        # full on
            (0.89, 3, A_FULL),        # 0.89 <= 1.5 x 0.6: full stays
            (0.91, 2, A_PARTIAL),     # full off, partial (0.91 <= 1.8) stays
            (1.81, 1, 0.0),           # partial off, warning (1.81 <= 3.9) stays
            (0.61, 2, A_PARTIAL)]     # below 1.2: partial on again; not below 0.6: full stays off
    for ttc, stage, deceleration in rows:
        got = aeb(ttc, closing)
        assert got[:2] == (stage, deceleration), (ttc, got)
        assert got[2] == (stage >= 2) and got[3] == (stage >= 1) and got[4] == 0.0
    aeb.close()


@pytest.mark.parametrize("version", FMI_VERSIONS)
def test_a_braking_stage_that_acted_holds_the_partial_deceleration_while_the_ego_closes(aeb_fmus, version, tmp_path):
    aeb = Aeb(aeb_fmus[version], version, tmp_path)  # brake_to_stop = true, the shipped default
    assert aeb(1.0, -3.0)[:3] == (2, A_PARTIAL, True)  # partial on
    assert aeb(50.0, -0.1)[:3] == (2, A_PARTIAL, True)  # TTC far above 1.8, still closing: held
    assert aeb(0.5, -2.0)[:3] == (3, A_FULL, True)  # full on top of the hold
    assert aeb(1000.0, 0.0)[:3] == (0, 0.0, False)  # no longer closing (stopped): released
    assert aeb(50.0, -0.1)[:3] == (0, 0.0, False)  # closing again, far: nothing (the hold needs a stage)
    aeb.close()


@pytest.mark.parametrize("version", FMI_VERSIONS)
def test_the_state_rolls_back(aeb_fmus, version, tmp_path):
    aeb = Aeb(aeb_fmus[version], version, tmp_path)
    assert aeb.description.coSimulation.canGetAndSetFMUstate
    aeb(1.0, -3.0)  # partial on, and held
    state, then = aeb.slave.getFMUState(), aeb.time
    assert aeb(1000.0, 0.0)[0] == 0  # released
    aeb.slave.setFMUState(state)
    aeb.time = then
    assert aeb(50.0, -0.1)[:2] == (2, A_PARTIAL)  # the hold is back
    aeb.slave.freeFMUState(state)
    aeb.close()


@pytest.mark.parametrize("version", FMI_VERSIONS)
def test_the_fmu_is_valid_and_its_outputs_depend_on_the_inputs_at_once(aeb_fmus, version):
    fmu = aeb_fmus[version]
    assert validate_fmu(str(fmu)) == []
    description = read_model_description(str(fmu))
    dependencies = {o.variable.name: {d.name for d in o.dependencies or []} for o in description.outputs}
    assert dependencies["deceleration_request"] == {"ttc", "relative_speed"}
    assert dependencies["warning"] == {"ttc"} and dependencies["throttle_request"] == set()
    names = zipfile.ZipFile(fmu).namelist()
    platform = {2: ("linux64", "win64"), 3: ("x86_64-linux", "x86_64-windows")}[version]
    assert f"binaries/{platform[0]}/ExampleAeb.so" in names
    if mingw_compiler():
        assert f"binaries/{platform[1]}/ExampleAeb.dll" in names


def test_example_aeb_by_name_in_run_and_sweep(tmp_path, simple_fmu):
    # `controller="example-aeb"` without a map is the cached FMU with the shipped map: in run the same run as with the
    # two given as paths, array for array; in sweep (whose workers get the FMU and the map as files) runs that end ok
    import distributed
    import numpy as np

    from sdl_fmu import api
    from sdl_fmu import sweep as sweeping

    by_name = api.run("demo", until_distance=1000.0, controller="example-aeb", plot=False)
    fmu, cmap = api.example_controller()
    by_path = api.run("demo", until_distance=1000.0, controller=fmu, controller_map=cmap, plot=False)
    assert by_name.summary["controller"]["name"] == "ExampleAeb" == by_path.summary["controller"]["name"]
    for name, values in by_path.arrays.items():
        assert np.array_equal(by_name.arrays[name], values, equal_nan=True), name
    with local_cluster(1) as cluster, distributed.Client(cluster) as client:
        rows = sweeping.sweep("demo", {"speed": [60.0, 80.0]}, tmp_path / "sweep", client=client, progress=False,
                              until_distance=1000.0, controller="example-aeb")
    assert [row["status"] for row in rows] == ["ok", "ok"], rows
