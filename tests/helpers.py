"""Helpers shared by the test files (the fixtures that use them are in conftest.py): the constants of the vehicle
tests, parameter defaults, fmpy runs and their input tables, the command line in a subprocess, the closed form of a
straight stop, the foreign car's build, FMU copies, ctypes wrappers of the FMU binaries and the plain C test host."""

import ctypes
import dataclasses
import math
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

import fmi_fuzz as fuzz
from sdl_fmu.results import scenario_units
from sdl_fmu.sdl import default_vehicle_table_path, load_vehicle_table
from sdl_fmu.units import STANDARD_GRAVITY as G

TESTS = Path(__file__).parent
WHEELS = ("fl", "fr", "rl", "rr")
NO_RESISTANCES = {"drag_area": 0.0, "rolling_resistance": 0.0}
TABLE = load_vehicle_table(default_vehicle_table_path())  # the shipped vehicle table, read once per session


# ---- the FMUs through fmpy ------------------------------------------------------------------------------------


def parameter_defaults(fmu) -> dict[str, float]:
    """{parameter name: start value} of an FMU, read from its model description."""
    return {v.name: float(v.start) for v in read_model_description(str(fmu)).modelVariables
            if v.causality == "parameter"}


def simulate(fmu, stop_time, start, step=0.01, inputs=None, *, output):
    """fmpy's co-simulation run of an FMU, sampled every `step` seconds."""
    return simulate_fmu(str(fmu), fmi_type="CoSimulation", start_values=start, input=inputs, output=list(output),
                        stop_time=stop_time, output_interval=step)


def input_table(time, **signals):
    """fmpy's input table: one row per instant of `time`, one column per signal."""
    return np.array(list(zip(time, *signals.values())), dtype=[("time", float)] + [(n, float) for n in signals])


# ---- the straight stop of the closed-form braking distances (Simple FMU; docs/verification.md) ---------------

MU = 0.6
V0 = 30.0


def braking_distance(v0, deceleration, rolling_resistance, drag_factor):
    """Stopping distance of dv/dt = -(A + K v^2), A = deceleration + f_r g, K = rho CdA / (2 m).

    v dv/ds = -(A + K v^2)  =>  ds = -v dv / (A + K v^2)  =>  s = ln(1 + K v0^2 / A) / (2K);
    the limit K -> 0 is v0^2 / (2A).
    """
    a = deceleration + rolling_resistance * G
    if drag_factor == 0:
        return v0**2 / (2 * a)
    return math.log(1 + drag_factor * v0**2 / a) / (2 * drag_factor)


def start_values(resistances, mu=MU, brake=1.0, v0=V0):
    """Start values of a straight stop on uniform mu, and the brake pedal as an fmpy input table."""
    values = {"v0": v0, **{f"mu_{w}": mu for w in WHEELS}}
    if not resistances:
        values.update(drag_area=0.0, rolling_resistance=0.0)
    return values, np.array([(0.0, brake)], dtype=[("time", float), ("brake", float)])


def expected_distance(defaults, resistances, mu=MU, brake=1.0, v0=V0):
    deceleration = min(brake * defaults["brake_decel_max"], mu * G)
    if not resistances:
        return braking_distance(v0, deceleration, 0.0, 0.0)
    drag_factor = defaults["air_density"] * defaults["drag_area"] / (2 * defaults["mass"])
    return braking_distance(v0, deceleration, defaults["rolling_resistance"], drag_factor)


# Tolerances, far tighter than 1e-6 (no resistances) and 1e-4 (with them), because the numerics allow it:
# with constant deceleration v(t) is linear and s(t) quadratic, which RODAS4 (order 4) integrates
# exactly at any step, so only round-off remains (~1e4 steps x 1e-16 relative). With drag, v' = -w,
# w = A + K v^2, and s^(5) = v'''' = 16 K^2 v w^2 + 8 K^3 v^3 w <= 2.1e-3 m/s^5 (K = 2.9e-4 1/m, v <= 30 m/s,
# w <= 7.3 m/s^2); an internal step h (error-controlled, at most solver_step = 0.1 s) has the local error
# C h^5 s^(5) with RODAS4's error constant C ~ 1e-2, so the <= 46 steps of the 4.6 s stop add up to
# ~46 x 1e-2 x 1e-5 x 2.1e-3 = 1e-8 m = 2e-10 relative; the stop itself is located to 1e-12 s, where v ~ 0.
# 1e-9 relative bounds all of that with room for the platform's libm. Measured: 7e-14 at 1 and 10 ms
# communication steps, 3.3e-12 at 100 ms (internal steps up to 0.1 s).
COSIM_TOLERANCE = 1e-9
# CVode controls the local error to rtol = 1e-10; over the few hundred steps of a stop the global
# error stays within ~1e3 x rtol, and the stop is a state event that CVode's root finder locates.
MODEL_EXCHANGE_TOLERANCE = 1e-7


# ---- the command line -----------------------------------------------------------------------------------------


def local_cluster(workers: int):
    """An in-process Dask cluster for a test's sweep (threads, no worker processes): no dashboard, and the
    scheduler's HTTP server (started all the same) on a free port, not on 8787, where it warns when another
    cluster of the machine holds it (as sdl_fmu.shipping starts its own). Use it as a context manager."""
    import distributed

    return distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=False, dashboard_address=None,
                                    scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})


def sdl_fmu(*args, cwd=None, timeout=300, **options) -> subprocess.CompletedProcess:
    """`sdl-fmu ARGS` in a subprocess (python -m sdl_fmu.cli), its output captured as text."""
    return subprocess.run([sys.executable, "-m", "sdl_fmu.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout, **options)


def windows_tools_required() -> bool:
    """CI (.ci/run) installs mingw-w64 and wine and sets this: there a missing tool is a failure, not a skip."""
    return os.environ.get("SDL_FMU_REQUIRE_WINDOWS") == "1"


def wine_loader() -> str | None:
    # Debian's wine64 package installs its loader outside PATH; the wine package adds /usr/bin/wine
    for candidate in ("wine64", "wine", "/usr/lib/wine/wine64"):
        if shutil.which(candidate):
            return shutil.which(candidate)
    return None


# ---- the foreign car (tests/vehicles), built by other tools -----------------------------------------------------

VEHICLES = TESTS / "vehicles"
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


COMMONROAD_ST_MAP = VEHICLES / "commonroad_st.toml"


def build_commonroad_st(folder: Path) -> Path:
    """Packages CommonRoad's single-track BMW 320i (tests/vehicles/commonroad_st.py) into folder with PythonFMU, in a
    subprocess through its command line. Returns the FMU's path."""
    built = subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(VEHICLES / "commonroad_st.py"),
                            "-d", str(folder)], capture_output=True, text=True)
    if built.returncode != 0:
        pytest.fail(f"pythonfmu could not build commonroad_st.py:\n{built.stdout}{built.stderr}")
    return folder / "CommonRoadSt.fmu"


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


def foreign_parameters(fmu: Path) -> dict[str, float]:
    """The foreign car's parameter start values, in its own units."""
    return parameter_defaults(fmu)


# ---- the foreign controller (tests/controllers), built by other tools ----------------------------------------------

CONTROLLERS = TESTS / "controllers"
FOREIGN_AEB_MAP = CONTROLLERS / "foreign_aeb.toml"


def build_foreign_controller(folder: Path, fmi_version: int = 2, handle_state: bool = False) -> Path:
    """Packages the foreign AEB controller (tests/controllers) into folder with another tool, in a subprocess through
    its command line: PythonFMU for FMI 2.0, pythonfmu3 for FMI 3.0; handle_state: the FMU can get and set its state
    (canGetAndSetFMUstate). Returns the FMU's path."""
    script, tool, name = {3: ("foreign_aeb.py", "pythonfmu3", "ForeignAeb"),
                          2: ("foreign_aeb_fmi2.py", "pythonfmu", "ForeignAebFmi2")}[fmi_version]
    folder = Path(folder) / ("with-state" if handle_state else "without-state")
    folder.mkdir(parents=True, exist_ok=True)
    built = subprocess.run([sys.executable, "-m", tool, "build", "-f", str(CONTROLLERS / script), "-d", str(folder),
                            *(["--handle-state"] if handle_state else []), str(CONTROLLERS / "foreign_aeb_logic.py")],
                           capture_output=True, text=True)
    if built.returncode != 0:
        pytest.fail(f"{tool} could not build {script}:\n{built.stdout}{built.stderr}")
    return folder / f"{name}.fmu"


class FmpyCar:
    """A co-simulation FMU (FMI 2.0 or 3.0) opened directly through fmpy, driven by variable name:
    car = FmpyCar(fmu, {"v_init": 100.0}); car.set(brake_pressure=60.0); car.step(0.05); car.get("veh_speed")."""

    def __init__(self, fmu: Path, start: dict[str, float]):
        from fmpy import extract
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
    with zipfile.ZipFile(source) as original, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as copy:
        for item in original.infolist():
            if drop(item.filename):
                continue
            data = original.read(item)
            if item.filename == "modelDescription.xml" and edit_description is not None:
                data = edit_description(data.decode("utf-8")).encode("utf-8")
            copy.writestr(item, data)
    return target


# ---- the FMU binaries through ctypes (the fuzzer's signatures) ------------------------------------------------

OK, ERROR = fuzz.OK, fuzz.ERROR


def unpacked_binary(fmu, directory, fmi_version: int):
    """The FMU unzipped into directory: its model description, its Linux binary loaded with the fuzzer's ctypes
    signatures, and the value reference of each variable by name."""
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(directory)
    description = read_model_description(str(directory))
    platform = "linux64" if fmi_version == 2 else "x86_64-linux"
    library = fuzz.load_library(
        directory / "binaries" / platform / f"{description.coSimulation.modelIdentifier}.so", fmi_version)
    return description, library, {v.name: v.valueReference for v in description.modelVariables}


class Raw:
    """One FMI 2.0 FMU binary loaded with ctypes; every call returns its status and records the log messages."""

    def __init__(self, fmu, directory):
        self.description, self.library, self.vr = unpacked_binary(fmu, directory, 2)
        self.messages = []
        self.callbacks = fuzz.fmi2_callbacks(fuzz.Logger(self._log))
        self.component = None

    def _log(self, environment, name, status, category, message, argument):
        if message == b"%s" and argument:
            message = ctypes.string_at(argument)
        self.messages.append((status, message.decode()))

    def instantiate(self, kind=fuzz.CS):
        self.component = self.library.fmi2Instantiate(b"test", kind, self.description.guid.encode(), b"",
                                                      ctypes.byref(self.callbacks), 0, 0)
        assert self.component
        return self

    def __call__(self, name, *args):
        self.messages.clear()
        status = getattr(self.library, f"fmi2{name}")(self.component, *args)
        if status == ERROR:  # every error says why
            assert any(s == ERROR for s, _ in self.messages), f"fmi2{name} returned an error without a message"
        return status

    def set_real(self, **values):
        vrs = [self.vr[n] for n in values]
        return self("SetReal", (ctypes.c_uint * len(vrs))(*vrs), len(vrs),
                    (ctypes.c_double * len(vrs))(*values.values()))

    def get_real(self, *names):
        values = (ctypes.c_double * len(names))()
        assert self("GetReal", (ctypes.c_uint * len(names))(*[self.vr[n] for n in names]), len(names), values) == OK
        return list(values)

    def start(self, start_time=0.0, **values):
        assert self("SetupExperiment", 0, 0.0, start_time, 0, 0.0) == OK
        assert self.set_real(**values) == OK
        assert self("EnterInitializationMode") == OK
        assert self("ExitInitializationMode") == OK
        return self

    def free(self):
        self.library.fmi2FreeInstance(self.component)

    def serialize(self):
        state = ctypes.c_void_p()
        assert self("GetFMUstate", ctypes.byref(state)) == OK
        size = ctypes.c_size_t()
        assert self("SerializedFMUstateSize", state, ctypes.byref(size)) == OK
        buffer = ctypes.create_string_buffer(size.value)
        assert self("SerializeFMUstate", state, buffer, size.value) == OK
        assert self("FreeFMUstate", ctypes.byref(state)) == OK
        return buffer.raw

    def deserialize_and_set(self, data):
        state = ctypes.c_void_p()
        status = self("DeSerializeFMUstate", bytes(data), len(data), ctypes.byref(state))
        if status == OK:
            status = self("SetFMUstate", state)
            self("FreeFMUstate", ctypes.byref(state))
        return status


class Raw3:
    """An FMI 3.0 binary loaded with ctypes (the fuzzer's signatures); calls return their status."""

    def __init__(self, fmu, directory, cosimulation=True):
        self.description, self.library, self.vr = unpacked_binary(fmu, directory, 3)
        self.messages = []
        self.logger = fuzz.LogMessage3(lambda environment, status, category, message: self.messages.append(status))
        token = self.description.guid.encode()
        if cosimulation:
            self.instance = self.library.fmi3InstantiateCoSimulation(b"test", token, b"", False, False, False, False,
                                                                     None, 0, None, self.logger, None)
        else:
            self.instance = self.library.fmi3InstantiateModelExchange(b"test", token, b"", False, False, None,
                                                                      self.logger)
        assert self.instance

    def __call__(self, name, *args):
        self.messages.clear()
        status = getattr(self.library, f"fmi3{name}")(self.instance, *args)
        if status == ERROR:
            assert ERROR in self.messages, f"fmi3{name} returned an error without a message"
        return status

    def set_float64(self, **values):
        vrs = [self.vr[n] for n in values]
        return self("SetFloat64", (ctypes.c_uint * len(vrs))(*vrs), len(vrs),
                    (ctypes.c_double * len(vrs))(*values.values()), len(vrs))

    def do_step(self, t, h):
        flags = [ctypes.byref(ctypes.c_bool()) for _ in range(3)]
        return self("DoStep", t, h, True, *flags, ctypes.byref(ctypes.c_double()))

    def free(self):
        self.library.fmi3FreeInstance(self.instance)


# ---- the plain C host (tests/hosts/fmi_host.c), compiled once per session in conftest.py ----------------------

HOST_SOURCE = TESTS / "hosts" / "fmi_host.c"
HOST_STEP = 0.01  # s, the host's communication step
# Simple FMU: straight braking on mu 0.6 without drag and rolling resistance: a = min(b a_max, mu g) = mu g
# (a_max = 9.81 > 0.6 g), stopping distance v0^2 / (2 a).
SIMPLE_START = {"v0": V0, "brake": 1.0, "drag_area": 0.0, "rolling_resistance": 0.0,
                **{f"mu_{w}": MU for w in WHEELS}}
PLATFORMS = {(2, "so"): "linux64", (2, "dll"): "win64", (3, "so"): "x86_64-linux", (3, "dll"): "x86_64-windows"}


def extract_binary(fmu, directory, version, suffix):
    """Unzips an FMU into directory; returns the path of its binary for the platform (suffix "so" or "dll")."""
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(directory)
    return directory / "binaries" / PLATFORMS[version, suffix] / f"{Path(fmu).stem}.{suffix}"


def host_arguments(fmu, library, start, outputs, stop_time, booleans=()):
    """The C host's command line: start values, outputs printed every second, booleans."""
    description = read_model_description(str(fmu))
    variables = {v.name: v for v in description.modelVariables}
    every = int(round(1.0 / HOST_STEP))
    return [*(["--fmi3"] if description.fmiVersion.startswith("3") else []), library, description.guid,
            repr(HOST_STEP), repr(stop_time), "--every", str(every),
            *[f"r:{variables[n].valueReference}={v!r}" for n, v in start.items()],
            *[f"o:{variables[n].valueReference}" for n in outputs],
            *[f"b:{variables[n].valueReference}" for n in booleans]]


def as_written(record):
    """A run's record (SI) with its events, final state and criticality in the scenario's units, as summary.json
    and api.Result give them (results/scenario_units.py); its time series and tracks stay SI."""
    return dataclasses.replace(record, events=list(scenario_units.Events(record.events, record.units)),
                               final=scenario_units.final(record.final, record.units),
                               criticality=scenario_units.criticality(record.criticality, record.units))
