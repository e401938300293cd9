"""The scenario FMU driven through ctypes (the fuzzer's signatures), FMI 2.0 or 3.0: instantiated with its resources,
its parameters and inputs set by name, stepped, its outputs read by name, and its event log (category logEvents)
parsed into summary.json-like entries. Also the replay of a recorded `sdl-fmu run` through it."""

from __future__ import annotations

import ctypes
import re
import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path

import fmi_fuzz as fuzz
from fmpy import read_model_description

EVENT_LINE = re.compile(r"t = (?P<time>\S+) s, s = (?P<s>\S+) m, v = (?P<v>\S+) m/s: (?P<code>\S+) (?P<action>\S+)"
                        r"(?: (?P<detail>.*))? \(line (?P<line>\d+)\); events (?P<events>\d+), collisions "
                        r"(?P<collisions>\d+)$")
VEHICLE = re.compile(r"vehicle (\d+)")
ACTION_INDEX = re.compile(r"action (\d+)")


@dataclass
class Event:
    code: str
    action: str
    time: float
    vehicle: int | None
    index: int | None
    line: int
    detail: str


def parse_event(message: str) -> Event | None:
    match = EVENT_LINE.match(message)
    if not match:
        return None
    detail = match["detail"] or ""
    vehicle = VEHICLE.search(detail) if match["code"] == "A" else None
    index = ACTION_INDEX.search(detail)
    return Event(match["code"], match["action"], float(match["time"]), int(vehicle[1]) if vehicle else None,
                 int(index[1]) if index else None, int(match["line"]), detail)


class ScenarioInstance:
    """One instance of a scenario FMU's Linux binary."""

    def __init__(self, fmu: Path, directory: Path, early_return: bool = False, name: bytes = b"scenario",
                 resources_text: str | None = None):
        """resources_text: what resources/scenario.sdlfmu holds instead of the FMU's own."""
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(directory)
        if resources_text is not None:
            (Path(directory) / "resources" / "scenario.sdlfmu").write_text(resources_text)
        self.directory = Path(directory)
        self.description = read_model_description(str(directory))
        self.fmi3 = self.description.fmiVersion.startswith("3")
        self.version = 3 if self.fmi3 else 2
        platform = "x86_64-linux" if self.fmi3 else "linux64"
        self.library = fuzz.load_library(self.directory / "binaries" / platform / "SdlScenario.so", self.version)
        logging = getattr(self.library, f"fmi{self.version}SetDebugLogging")
        logging.restype = ctypes.c_int
        logging.argtypes = [ctypes.c_void_p, ctypes.c_bool if self.fmi3 else ctypes.c_int, ctypes.c_size_t,
                            ctypes.c_void_p]
        self.variables = {v.name: v for v in self.description.modelVariables}
        self.messages: list[tuple[int, str, str]] = []  # status, category, text
        token = self.description.guid.encode()
        resources = self.directory / "resources"
        if self.fmi3:
            self.logger3 = fuzz.LogMessage3(self._log3)
            self.component = self.library.fmi3InstantiateCoSimulation(
                name, token, (str(resources) + "/").encode(), False, False, False, early_return, None, 0, None,
                self.logger3, None)
        else:
            self.callbacks = fuzz.fmi2_callbacks(fuzz.Logger(self._log2))
            self.component = self.library.fmi2Instantiate(name, fuzz.CS, token, resources.as_uri().encode(),
                                                          ctypes.byref(self.callbacks), 0, 0)

    def _log2(self, environment, name, status, category, message, argument):
        if message == b"%s" and argument:
            message = ctypes.string_at(argument)
        self.messages.append((status, category.decode(), message.decode(errors="replace")))

    def _log3(self, environment, status, category, message):
        self.messages.append((status, category.decode(), message.decode(errors="replace")))

    def call(self, name: str, *args) -> int:
        return getattr(self.library, f"fmi{self.version}{name}")(self.component, *args)

    def events(self) -> list[Event]:
        return [event for status, category, text in self.messages if category == "logEvents"
                for event in [parse_event(text)] if event is not None]

    def debug_logging(self, on: bool = True) -> int:
        return self.call("SetDebugLogging", on, 0, None)

    # -- values by name ------------------------------------------------------------------------------------------
    def set(self, **values) -> int:
        status = fuzz.OK
        for name, value in values.items():
            v = self.variables[name]
            vr = (ctypes.c_uint * 1)(v.valueReference)
            if v.type in ("Real", "Float64"):
                array = (ctypes.c_double * 1)(float(value))
                status = max(status, self.call("SetReal" if not self.fmi3 else "SetFloat64", vr, 1, array,
                                               *([1] if self.fmi3 else [])))
            elif v.type in ("Integer", "Int32"):
                array = (ctypes.c_int * 1)(int(value))
                status = max(status, self.call("SetInteger" if not self.fmi3 else "SetInt32", vr, 1, array,
                                               *([1] if self.fmi3 else [])))
            else:
                array = (ctypes.c_bool * 1)(bool(value)) if self.fmi3 else (ctypes.c_int * 1)(int(bool(value)))
                status = max(status, self.call("SetBoolean", vr, 1, array, *([1] if self.fmi3 else [])))
        return status

    def get(self, name: str):
        v = self.variables[name]
        vr = (ctypes.c_uint * 1)(v.valueReference)
        if v.type in ("Real", "Float64"):
            array = (ctypes.c_double * 1)()
            status = self.call("GetReal" if not self.fmi3 else "GetFloat64", vr, 1, array, *([1] if self.fmi3 else []))
        elif v.type in ("Integer", "Int32"):
            array = (ctypes.c_int32 * 1)()
            status = self.call("GetInteger" if not self.fmi3 else "GetInt32", vr, 1, array, *([1] if self.fmi3 else []))
        else:
            array = (ctypes.c_bool * 1)() if self.fmi3 else (ctypes.c_int * 1)()
            status = self.call("GetBoolean", vr, 1, array, *([1] if self.fmi3 else []))
        assert status == fuzz.OK, (name, self.messages[-3:])
        return array[0]

    def initialize(self, parameters: dict | None = None, inputs: dict | None = None, start_time: float = 0.0) -> None:
        if not self.fmi3:
            assert self.call("SetupExperiment", 0, 0.0, start_time, 0, 0.0) == fuzz.OK
        assert self.set(**(parameters or {})) == fuzz.OK, self.messages[-3:]
        if self.fmi3:
            assert self.call("EnterInitializationMode", False, 0.0, start_time, False, 0.0) == fuzz.OK
        else:
            assert self.call("EnterInitializationMode") == fuzz.OK
        assert self.set(**(inputs or {})) == fuzz.OK, self.messages[-3:]
        assert self.call("ExitInitializationMode") == fuzz.OK, self.messages[-3:]

    def step(self, t: float, h: float) -> tuple[int, bool, float, bool]:
        """(status, returned early, last successful time, terminate)."""
        if not self.fmi3:
            status = self.call("DoStep", t, h, 1)
            return status, False, t + h, False
        event, terminate, early, reached = ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(), ctypes.c_double()
        status = self.call("DoStep", t, h, True, ctypes.byref(event), ctypes.byref(terminate), ctypes.byref(early),
                           ctypes.byref(reached))
        return status, early.value, reached.value, terminate.value

    def terminated(self) -> bool:
        if self.fmi3:
            raise NotImplementedError
        value = ctypes.c_int()
        assert self.call("GetBooleanStatus", 3, ctypes.byref(value)) == fuzz.OK  # fmi2Terminated
        return bool(value.value)

    def get_state(self) -> ctypes.c_void_p:
        state = ctypes.c_void_p()
        assert self.call("GetFMUstate" if not self.fmi3 else "GetFMUState", ctypes.byref(state)) == fuzz.OK
        return state

    def set_state(self, state: ctypes.c_void_p) -> int:
        return self.call("SetFMUstate" if not self.fmi3 else "SetFMUState", state)

    def free_state(self, state: ctypes.c_void_p) -> int:
        return self.call("FreeFMUstate" if not self.fmi3 else "FreeFMUState", ctypes.byref(state))

    def free(self) -> None:
        getattr(self.library, f"fmi{self.version}FreeInstance")(self.component)


EGO_INPUTS = {"ego_x": "x", "ego_y": "y", "ego_psi": "psi", "ego_v": "v", "ego_s": "s", "ego_vx": "vx",
              "ego_vy": "vy", "ego_yaw_rate": "yaw_rate", "ego_ax": "ax", "ego_ay": "ay"}


def recorded_inputs(columns: dict, k: int) -> dict:
    """The scenario FMU's ego inputs from a run's sample k (SI columns of RunRecord)."""
    values = {name: float(columns[column][k]) for name, column in EGO_INPUTS.items()}
    values["ego_stopped"] = bool(columns["stopped"][k])
    return values


# ---- the replay of a recorded run --------------------------------------------------------------------------------

CONTROLS = ("throttle", "brake", "steer")
LEAD = ("lead_present", "lead_id", "lead_gap", "lead_speed", "lead_relative_speed", "lead_ttc", "lead_lateral_offset")


def run_lead(columns: dict, tracks: list, k: int, ego_length: float, ego_width: float):
    """The lead-vehicle signals at the run's sample k from signals.py, over the vehicles on the road there (their
    tracks are the run's closed-form motions at the sample times)."""
    from sdl_fmu.cosim.signals import lead_vehicle

    present = [(track.vehicle - 1, track) for track in tracks if track.first <= k < track.first + len(track.station)]
    lead = lead_vehicle(float(columns["x"][k]), float(columns["y"][k]), float(columns["psi"][k]),
                        float(columns["vx"][k]), float(columns["vy"][k]), ego_length, ego_width,
                        [track.station[k - track.first] for _, track in present],
                        [track.lateral[k - track.first] for _, track in present],
                        [track.speed[k - track.first] for _, track in present],
                        [track.length for _, track in present], [track.width for _, track in present],
                        [index for index, _ in present])
    return (lead.present, lead.vehicle_id, lead.gap, lead.speed, lead.relative_speed, lead.ttc, lead.lateral_offset)


def replay(result, fmu: Path, directory: Path, ego_length: float, ego_width: float) -> list:
    """Replays a run (api.Result) through its scenario FMU without prediction: the recorded ego state of every
    sample set as the inputs, the FMU stepped from sample to sample. Returns every difference from the run (empty:
    the same bits): the commands after each step against the run's controls of that sample, the surfaces under
    the wheels and the lead signals at each sample (the latter where nothing fired there: the FMU fires what is
    due at a sample inside its step, after the outputs of that sample were read), the traffic slots against the
    tracks, and the events (code, action, vehicle, instant, order) and the collisions."""
    raw = result.raw
    columns = raw.columns
    samples = len(columns["time"])
    instance = ScenarioInstance(fmu, directory)
    assert instance.component, instance.messages
    assert instance.debug_logging(True) == fuzz.OK
    instance.initialize({"trigger_prediction": False}, recorded_inputs(columns, 0))
    tracks = list(raw.vehicles)
    fired_at = {event["time_s"] for event in result.events}
    wheels = [name for name in columns if name.startswith(("mu_", "surface_"))]
    slots = sum(1 for name in instance.variables if name.endswith("_present") and name.startswith("tv"))
    problems = []
    for k in range(samples):
        t = float(columns["time"][k])
        h = float(columns["time"][k + 1]) - t if k + 1 < samples else 0.01
        if k > 0:
            assert instance.set(**recorded_inputs(columns, k)) == fuzz.OK, instance.messages[-3:]
        for name in wheels:
            if instance.get(name) != float(columns[name][k]):
                problems.append(("surface", k, name, instance.get(name), float(columns[name][k])))
        if t not in fired_at:
            got = tuple(float(instance.get(name)) for name in LEAD)
            want = tuple(map(float, run_lead(columns, tracks, k, ego_length, ego_width)))
            if got != want:
                problems.append(("lead", k, got, want))
            for slot in range(1, slots + 1):
                if not instance.get(f"tv{slot}_present"):
                    continue
                track = tracks[instance.get(f"tv{slot}_id") - 1]
                if not track.first <= k < track.first + len(track.station):
                    problems.append(("slot", k, slot, "not on the road in the run"))
                    continue
                got = (instance.get(f"tv{slot}_x"), instance.get(f"tv{slot}_y"))
                want = (float(track.station[k - track.first]), -float(track.lateral[k - track.first]))
                if got != want:
                    problems.append(("slot", k, slot, got, want))
        status = instance.step(t, h)[0]
        assert status == fuzz.OK, instance.messages[-3:]
        got = [instance.get(name) for name in CONTROLS]
        want = [float(columns[name][k]) for name in CONTROLS]
        if got != want:
            problems.append(("controls", k, got, want))
    events, run_events = instance.events(), list(result.events)
    for ours, theirs in zip(events, run_events):
        if (ours.code, ours.action, ours.vehicle, ours.time) != (theirs["code"], theirs["action"],
                                                                 theirs.get("vehicle"), theirs["time_s"]):
            problems.append(("event", ours, theirs))
            break
    if len(events) != len(run_events):
        problems.append(("events", len(events), len(run_events)))
    if instance.get("collisions") != result.collisions:
        problems.append(("collisions", instance.get("collisions"), result.collisions))
    instance.free()
    return problems


# ---- a fixed-step master: the scenario FMU and an ego FMU side by side ------------------------------------------

EGO_OUTPUTS = ("x", "y", "psi", "v", "s", "vx", "vy", "yaw_rate", "ax", "ay")


def path_acceleration(outputs: dict) -> float:
    """dv/dt of the ego from its outputs: (vx ax + vy ay) / v (ax, ay: its acceleration in its body frame), the
    rate of the speed the scenario FMU's prediction uses."""
    v = outputs["v"]
    return (outputs["vx"] * outputs["ax"] + outputs["vy"] * outputs["ay"]) / v if v > 0 else outputs["ax"]


class Ego:
    """An ego FMU of sdl-fmu's interface through fmpy, stepped by a master."""

    def __init__(self, fmu: Path, start: dict):
        from fmpy import extract
        from fmpy.fmi2 import FMU2Slave
        from fmpy.fmi3 import FMU3Slave

        description = read_model_description(str(fmu))
        self.fmi3 = description.fmiVersion.startswith("3")
        self.vr = {v.name: v.valueReference for v in description.modelVariables}
        self.types = {v.name: v.type for v in description.modelVariables}
        slave_type = FMU3Slave if self.fmi3 else FMU2Slave
        self._folder = extract(str(fmu))  # removed by close()
        self.slave = slave_type(guid=description.guid, unzipDirectory=self._folder,
                                modelIdentifier=description.coSimulation.modelIdentifier, instanceName="ego")
        self.slave.instantiate()
        if not self.fmi3:
            self.slave.setupExperiment(startTime=0.0)
        self.set(**start)
        if self.fmi3:
            self.slave.enterInitializationMode(startTime=0.0)
        else:
            self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()
        self.time = 0.0

    def set(self, **values) -> None:
        for name, value in values.items():
            kind = self.types[name]
            if kind in ("Real", "Float64"):
                (self.slave.setFloat64 if self.fmi3 else self.slave.setReal)([self.vr[name]], [float(value)])
            elif kind in ("Integer", "Int32"):
                (self.slave.setInt32 if self.fmi3 else self.slave.setInteger)([self.vr[name]], [int(value)])
            else:
                self.slave.setBoolean([self.vr[name]], [bool(value)])

    def outputs(self) -> dict:
        get = self.slave.getFloat64 if self.fmi3 else self.slave.getReal
        values = dict(zip(EGO_OUTPUTS, get([self.vr[n] for n in EGO_OUTPUTS])))
        values["stopped"] = bool(self.slave.getBoolean([self.vr["stopped"]])[0])
        return values

    def step_to(self, end: float) -> None:
        self.slave.doStep(self.time, end - self.time)
        self.time = end

    def save(self):
        return self.slave.getFMUState() if self.fmi3 else self.slave.getFMUstate()

    def restore(self, state, time: float) -> None:
        (self.slave.setFMUState if self.fmi3 else self.slave.setFMUstate)(state)
        self.time = time

    def discard(self, state) -> None:
        (self.slave.freeFMUState if self.fmi3 else self.slave.freeFMUstate)(state)

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()
        shutil.rmtree(self._folder, ignore_errors=True)


def scenario_inputs(outputs: dict) -> dict:
    return {**{f"ego_{name}": outputs[name] for name in EGO_OUTPUTS}, "ego_stopped": outputs["stopped"]}


def wheel_names(dynamics: str) -> tuple[str, ...]:
    prefix = "mu" if dynamics == "simple" else "surface"
    return tuple(f"{prefix}_{w}" for w in ("fl", "fr", "rl", "rr"))
