"""The scenario FMU driven through ctypes (the fuzzer's signatures), FMI 2.0 or 3.0: instantiated with its resources,
its parameters and inputs set by name, stepped, its outputs read by name, and its event log (category logEvents)
parsed into summary.json-like entries. Also the replay of a recorded `sdl-fmu run` through it."""

from __future__ import annotations

import ctypes
import re
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

    def __init__(self, fmu: Path, directory: Path, early_return: bool = False, name: bytes = b"scenario"):
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(directory)
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

    def free(self) -> None:
        getattr(self.library, f"fmi{self.version}FreeInstance")(self.component)


EGO_INPUTS = {"ego_x": "x", "ego_y": "y", "ego_psi": "psi", "ego_v": "v", "ego_s": "s", "ego_vx": "vx",
              "ego_vy": "vy", "ego_yaw_rate": "yaw_rate", "ego_ax": "ax", "ego_ay": "ay"}


def recorded_inputs(columns: dict, k: int) -> dict:
    """The scenario FMU's ego inputs from a run's sample k (SI columns of RunResult)."""
    values = {name: float(columns[column][k]) for name, column in EGO_INPUTS.items()}
    values["ego_stopped"] = bool(columns["stopped"][k])
    return values
