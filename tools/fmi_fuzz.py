"""Fuzzer for the FMUs' C runtime: random FMI 2.0 and FMI 3.0 call sequences through ctypes, judged by an oracle.

The oracle knows the state tables of the standard (FMI 2.0 sections 3.2.3 and 4.2.4, FMI 3.0 section 3.2: which
function may be called in which state, on a model-exchange or a co-simulation instance) and the
modelDescription (value
references, types, causality, variability, min/max), plus the runtime's documented argument rules (README:
non-finite or out-of-range values, a step not at the FMU's time, time that cannot advance, the internal-step
budget, corrupted serialized states). A call that returns OK where an error is required is a violation (a
communication step of 0 included); so is any non-OK return (Warning, Discard, Error, Fatal) without a log message
of a non-OK status during the call.

Sequences run in batches, each batch in a worker subprocess that is restarted after a crash; a watchdog kills a
worker whose current call takes longer than the hang timeout. Every sequence is reproducible from (seed, index).

    python tools/fmi_fuzz.py dist/fmi2/EgoVehicleSimple.fmu dist/fmi3/EgoVehicleSimple.fmu --sequences 20000

It fuzzes the scenario FMU (sdl_fmu/export: co-simulation only, its scenario read from resources/) the same way: an
FMU without a model-exchange interface gets co-simulation instances only, and an FMU with resources/ gets their
location (FMI 2.0: a file: URI; FMI 3.0: the folder's path).

A development tool of the repository, not part of the installed package (the wheel does not contain it). It needs
fmpy, and for --sanitize the sdl_fmu package (installed, or this checkout's, found beside tools/).
"""

from __future__ import annotations

import argparse
import ctypes
import json
import math
import os
import random
import select
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import zipfile
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

# cosimulation.c: MAX_INTERNAL_STEPS, the internal steps one doStep may take
INTERNAL_STEP_BUDGET = 50000
# the scenario FMU (sdl_fmu/export/runtime/scenario.h): MAX_SAMPLES_PER_STEP, the driver samples one doStep may hold
SAMPLE_BUDGET = 100000
# cosimulation.c accepts a communication point within 1e-9 relative of the FMU's time; clearly wrong is more
TIME_MISMATCH = 1e-6
HANG_TIMEOUT = 5.0  # s
STARTUP_TIMEOUT = 120.0  # s for a worker to start Python and load the FMU (not a call: no hang)
WORKER_COMMAND = [sys.executable, str(Path(__file__).resolve())]  # a worker runs batches of sequences

OK, WARNING, DISCARD, ERROR, FATAL = range(5)
STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal")
ME, CS = 0, 1

# ---- ctypes view of the FMI 2.0 API -------------------------------------------------------------------------

Real, Integer, Boolean, Status = ctypes.c_double, ctypes.c_int, ctypes.c_int, ctypes.c_int
Component = ctypes.c_void_p
# the runtime logs as logger(..., "%s", text); on x86-64 the variadic text arrives like a sixth argument
Logger = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                          ctypes.c_void_p)
Allocate = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_size_t, ctypes.c_size_t)
Free = ctypes.CFUNCTYPE(None, ctypes.c_void_p)
StepFinished = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int)


class Callbacks(ctypes.Structure):
    _fields_ = [("logger", Logger), ("allocateMemory", Allocate), ("freeMemory", Free),
                ("stepFinished", StepFinished), ("componentEnvironment", ctypes.c_void_p)]


class EventInfo(ctypes.Structure):
    _fields_ = [("newDiscreteStatesNeeded", Boolean), ("terminateSimulation", Boolean),
                ("nominalsOfContinuousStatesChanged", Boolean), ("valuesOfContinuousStatesChanged", Boolean),
                ("nextEventTimeDefined", Boolean), ("nextEventTime", Real)]


P = ctypes.POINTER
SIGNATURES = {
    "fmi2Instantiate": (Component, [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p, P(Callbacks),
                                    Boolean, Boolean]),
    "fmi2FreeInstance": (None, [Component]),
    "fmi2SetupExperiment": (Status, [Component, Boolean, Real, Real, Boolean, Real]),
    "fmi2EnterInitializationMode": (Status, [Component]),
    "fmi2ExitInitializationMode": (Status, [Component]),
    "fmi2Terminate": (Status, [Component]),
    "fmi2Reset": (Status, [Component]),
    "fmi2GetReal": (Status, [Component, P(ctypes.c_uint), ctypes.c_size_t, P(Real)]),
    "fmi2GetInteger": (Status, [Component, P(ctypes.c_uint), ctypes.c_size_t, P(Integer)]),
    "fmi2GetBoolean": (Status, [Component, P(ctypes.c_uint), ctypes.c_size_t, P(Boolean)]),
    "fmi2SetReal": (Status, [Component, P(ctypes.c_uint), ctypes.c_size_t, P(Real)]),
    "fmi2SetInteger": (Status, [Component, P(ctypes.c_uint), ctypes.c_size_t, P(Integer)]),
    "fmi2SetBoolean": (Status, [Component, P(ctypes.c_uint), ctypes.c_size_t, P(Boolean)]),
    "fmi2GetFMUstate": (Status, [Component, P(ctypes.c_void_p)]),
    "fmi2SetFMUstate": (Status, [Component, ctypes.c_void_p]),
    "fmi2FreeFMUstate": (Status, [Component, P(ctypes.c_void_p)]),
    "fmi2SerializedFMUstateSize": (Status, [Component, ctypes.c_void_p, P(ctypes.c_size_t)]),
    "fmi2SerializeFMUstate": (Status, [Component, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t]),
    "fmi2DeSerializeFMUstate": (Status, [Component, ctypes.c_char_p, ctypes.c_size_t, P(ctypes.c_void_p)]),
    "fmi2EnterEventMode": (Status, [Component]),
    "fmi2NewDiscreteStates": (Status, [Component, P(EventInfo)]),
    "fmi2EnterContinuousTimeMode": (Status, [Component]),
    "fmi2CompletedIntegratorStep": (Status, [Component, Boolean, P(Boolean), P(Boolean)]),
    "fmi2SetTime": (Status, [Component, Real]),
    "fmi2SetContinuousStates": (Status, [Component, P(Real), ctypes.c_size_t]),
    "fmi2GetDerivatives": (Status, [Component, P(Real), ctypes.c_size_t]),
    "fmi2GetEventIndicators": (Status, [Component, P(Real), ctypes.c_size_t]),
    "fmi2GetContinuousStates": (Status, [Component, P(Real), ctypes.c_size_t]),
    "fmi2GetNominalsOfContinuousStates": (Status, [Component, P(Real), ctypes.c_size_t]),
    "fmi2DoStep": (Status, [Component, Real, Real, Boolean]),
    "fmi2GetStatus": (Status, [Component, ctypes.c_int, P(Status)]),
    "fmi2GetRealStatus": (Status, [Component, ctypes.c_int, P(Real)]),
    "fmi2GetIntegerStatus": (Status, [Component, ctypes.c_int, P(Integer)]),
    "fmi2GetBooleanStatus": (Status, [Component, ctypes.c_int, P(Boolean)]),
    "fmi2GetStringStatus": (Status, [Component, ctypes.c_int, P(ctypes.c_char_p)]),
}

Instance3 = ctypes.c_void_p
Bool3 = ctypes.c_bool
LogMessage3 = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)
IntermediateUpdate3 = ctypes.c_void_p  # unused: passed as NULL
SIGNATURES3 = {
    "fmi3InstantiateCoSimulation": (Instance3, [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, Bool3, Bool3,
                                                Bool3, Bool3, P(ctypes.c_uint), ctypes.c_size_t, ctypes.c_void_p,
                                                LogMessage3, IntermediateUpdate3]),
    "fmi3InstantiateModelExchange": (Instance3, [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, Bool3, Bool3,
                                                 ctypes.c_void_p, LogMessage3]),
    "fmi3FreeInstance": (None, [Instance3]),
    "fmi3EnterInitializationMode": (Status, [Instance3, Bool3, Real, Real, Bool3, Real]),
    "fmi3ExitInitializationMode": (Status, [Instance3]),
    "fmi3Terminate": (Status, [Instance3]),
    "fmi3Reset": (Status, [Instance3]),
    "fmi3GetFloat64": (Status, [Instance3, P(ctypes.c_uint), ctypes.c_size_t, P(Real), ctypes.c_size_t]),
    "fmi3GetInt32": (Status, [Instance3, P(ctypes.c_uint), ctypes.c_size_t, P(ctypes.c_int32), ctypes.c_size_t]),
    "fmi3GetBoolean": (Status, [Instance3, P(ctypes.c_uint), ctypes.c_size_t, P(Bool3), ctypes.c_size_t]),
    "fmi3SetFloat64": (Status, [Instance3, P(ctypes.c_uint), ctypes.c_size_t, P(Real), ctypes.c_size_t]),
    "fmi3SetInt32": (Status, [Instance3, P(ctypes.c_uint), ctypes.c_size_t, P(ctypes.c_int32), ctypes.c_size_t]),
    "fmi3SetBoolean": (Status, [Instance3, P(ctypes.c_uint), ctypes.c_size_t, P(Bool3), ctypes.c_size_t]),
    "fmi3GetFMUState": (Status, [Instance3, P(ctypes.c_void_p)]),
    "fmi3SetFMUState": (Status, [Instance3, ctypes.c_void_p]),
    "fmi3FreeFMUState": (Status, [Instance3, P(ctypes.c_void_p)]),
    "fmi3SerializedFMUStateSize": (Status, [Instance3, ctypes.c_void_p, P(ctypes.c_size_t)]),
    "fmi3SerializeFMUState": (Status, [Instance3, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t]),
    "fmi3DeserializeFMUState": (Status, [Instance3, ctypes.c_char_p, ctypes.c_size_t, P(ctypes.c_void_p)]),
    "fmi3EnterEventMode": (Status, [Instance3]),
    "fmi3UpdateDiscreteStates": (Status, [Instance3, P(Bool3), P(Bool3), P(Bool3), P(Bool3), P(Bool3), P(Real)]),
    "fmi3EnterContinuousTimeMode": (Status, [Instance3]),
    "fmi3CompletedIntegratorStep": (Status, [Instance3, Bool3, P(Bool3), P(Bool3)]),
    "fmi3SetTime": (Status, [Instance3, Real]),
    "fmi3SetContinuousStates": (Status, [Instance3, P(Real), ctypes.c_size_t]),
    "fmi3GetContinuousStateDerivatives": (Status, [Instance3, P(Real), ctypes.c_size_t]),
    "fmi3GetEventIndicators": (Status, [Instance3, P(Real), ctypes.c_size_t]),
    "fmi3GetContinuousStates": (Status, [Instance3, P(Real), ctypes.c_size_t]),
    "fmi3GetNominalsOfContinuousStates": (Status, [Instance3, P(Real), ctypes.c_size_t]),
    "fmi3DoStep": (Status, [Instance3, Real, Real, Bool3, P(Bool3), P(Bool3), P(Bool3), P(Real)]),
}
# the worker speaks FMI 2.0 names; FMI 3.0 calls the same operations so
FMI3_NAMES = {
    "fmi2EnterInitializationMode": "fmi3EnterInitializationMode", "fmi2ExitInitializationMode": "fmi3ExitInitializationMode",
    "fmi2Terminate": "fmi3Terminate", "fmi2Reset": "fmi3Reset",
    "fmi2GetReal": "fmi3GetFloat64", "fmi2GetInteger": "fmi3GetInt32", "fmi2GetBoolean": "fmi3GetBoolean",
    "fmi2SetReal": "fmi3SetFloat64", "fmi2SetInteger": "fmi3SetInt32", "fmi2SetBoolean": "fmi3SetBoolean",
    "fmi2GetFMUstate": "fmi3GetFMUState", "fmi2SetFMUstate": "fmi3SetFMUState", "fmi2FreeFMUstate": "fmi3FreeFMUState",
    "fmi2SerializedFMUstateSize": "fmi3SerializedFMUStateSize", "fmi2SerializeFMUstate": "fmi3SerializeFMUState",
    "fmi2DeSerializeFMUstate": "fmi3DeserializeFMUState", "fmi2EnterEventMode": "fmi3EnterEventMode",
    "fmi2NewDiscreteStates": "fmi3UpdateDiscreteStates", "fmi2EnterContinuousTimeMode": "fmi3EnterContinuousTimeMode",
    "fmi2CompletedIntegratorStep": "fmi3CompletedIntegratorStep", "fmi2SetTime": "fmi3SetTime",
    "fmi2SetContinuousStates": "fmi3SetContinuousStates", "fmi2GetDerivatives": "fmi3GetContinuousStateDerivatives",
    "fmi2GetEventIndicators": "fmi3GetEventIndicators", "fmi2GetContinuousStates": "fmi3GetContinuousStates",
    "fmi2GetNominalsOfContinuousStates": "fmi3GetNominalsOfContinuousStates", "fmi2DoStep": "fmi3DoStep",
}
TYPE_NAMES = {"Float64": "Real", "Int32": "Integer"}  # FMI 3.0 type -> the worker's (FMI 2.0) type

# ---- the oracle's tables -------------------------------------------------------------------------------------

# states: instantiated, init, step (CS stepComplete), event, cont (ME), terminated; None = unknown (after an
# error the oracle did not predict, e.g. a numerical failure: only state-independent rules are checked)
ALLOWED = {  # function -> {interface type: states where the standard allows it}; elsewhere it must fail
    "fmi2SetupExperiment": {CS: {"instantiated"}, ME: {"instantiated"}},
    "fmi2EnterInitializationMode": {CS: {"instantiated"}, ME: {"instantiated"}},
    "fmi2ExitInitializationMode": {CS: {"init"}, ME: {"init"}},
    "fmi2Terminate": {CS: {"step"}, ME: {"event", "cont"}},
    "fmi2Reset": {CS: "any", ME: "any"},
    "get": {CS: {"init", "step", "terminated"}, ME: {"init", "event", "cont", "terminated"}},
    "fmi2DoStep": {CS: {"step"}, ME: set()},
    "fmi2GetXXXStatus": {CS: {"step", "terminated"}, ME: set()},
    "fmi2EnterEventMode": {CS: set(), ME: {"event", "cont"}},
    "fmi2NewDiscreteStates": {CS: set(), ME: {"event"}},
    "fmi2EnterContinuousTimeMode": {CS: set(), ME: {"event"}},
    "fmi2CompletedIntegratorStep": {CS: set(), ME: {"cont"}},
    "fmi2SetTime": {CS: set(), ME: {"event", "cont"}},
    "fmi2SetContinuousStates": {CS: set(), ME: {"cont"}},
    "fmi2GetDerivatives": {CS: set(), ME: {"event", "cont", "terminated"}},
    "fmi2GetEventIndicators": {CS: set(), ME: {"init", "event", "cont", "terminated"}},
    "fmi2GetContinuousStates": {CS: set(), ME: {"init", "event", "cont", "terminated"}},
    "fmi2GetNominalsOfContinuousStates": {CS: set(), ME: {"instantiated", "event", "cont", "terminated"}},
    "state": {CS: "any", ME: "any"},
}
# FMI 3.0 differs: Event Mode is entered from Continuous-Time Mode only, the time is set in Continuous-Time Mode
# only, the nominals are not available before initialization; the getters' states are not checked
ALLOWED3 = {"fmi2EnterEventMode": {CS: set(), ME: {"cont"}}, "get": {CS: "any", ME: "any"},
            "fmi2SetTime": {CS: set(), ME: {"cont"}},
            "fmi2GetDerivatives": {CS: set(), ME: {"init", "event", "cont", "terminated"}},
            "fmi2GetNominalsOfContinuousStates": {CS: set(), ME: {"init", "event", "cont", "terminated"}}}


@dataclass(frozen=True)
class Variable:
    name: str
    vr: int
    type: str
    causality: str
    variability: str
    min: float
    max: float
    start: float | None


def may_set_in(variable: Variable, state: str, kind: int) -> bool:
    """FMI 2.0 tables: which variables fmi2SetXXX may change in which state."""
    if variable.causality not in ("input", "parameter") or variable.variability == "constant":
        return False
    if state in ("instantiated", "init"):
        return True
    tunable_or_input = variable.causality == "input" or variable.variability == "tunable"
    if state == "step" and kind == CS or state == "event" and kind == ME:
        return tunable_or_input
    if state == "cont" and kind == ME:
        return variable.causality == "input" and variable.type == "Real" and variable.variability == "continuous"
    return False


def _as_int(value) -> int:
    # a Real value passed to fmi2SetInteger/Boolean (a type error the oracle already requires to fail)
    return int(value) if math.isfinite(value) and abs(value) < 2**31 else 0


def load_library(path, fmi_version: int) -> ctypes.CDLL:
    """An FMU binary loaded with ctypes, every function the fuzzer calls declared with its C signature."""
    library = ctypes.CDLL(str(path))
    for name, (restype, argtypes) in (SIGNATURES if fmi_version == 2 else SIGNATURES3).items():
        function = getattr(library, name)
        function.restype, function.argtypes = restype, argtypes
    return library


def fmi2_callbacks(logger: Logger) -> Callbacks:
    """fmi2CallbackFunctions with this logger and the C library's calloc and free."""
    libc = ctypes.CDLL(None)
    return Callbacks(logger, ctypes.cast(libc.calloc, Allocate), ctypes.cast(libc.free, Free), StepFinished(), None)


# ---- the worker: runs sequences and judges every call ---------------------------------------------------------


class Worker:
    def __init__(self, config: dict):
        self.version = config["fmi_version"]
        self.library = load_library(config["library"], self.version)
        self.log_message3 = LogMessage3(self._log3)
        self.guid = config["guid"].encode()
        self.variables = [Variable(**v) for v in config["variables"]]
        self.by_vr = {v.vr: v for v in self.variables}
        self.settable = [v for v in self.variables if v.causality in ("input", "parameter")]
        self.nx, self.nz = config["nx"], config["nz"]
        self.unknown_vr = max(self.by_vr) + 1000
        self.solver_step = next((v for v in self.variables if v.name == "solver_step"), None)
        self.driver_period = next((v for v in self.variables if v.name == "driver_period"), None)
        self.model_exchange = config.get("model_exchange", True)
        self.resources = config.get("resources", "").encode()
        self.seed = config["seed"]
        self.log_non_ok = 0  # messages of any non-OK status during the current call
        self.last_message = ""
        self.callbacks = fmi2_callbacks(Logger(self._log))
        self.stats = Counter()
        self.wild = (ctypes.c_double * 64)()  # memory that is no FMU state: the wild handle points here
        self.wild_buffer = ctypes.create_string_buffer(1 << 16)

    def _log3(self, environment, status, category, message):
        self._log(environment, None, status, category, message, None)

    def _log(self, environment, name, status, category, message, argument):
        if status != OK:
            self.log_non_ok += 1
        if status >= ERROR:
            if message == b"%s" and argument:
                message = ctypes.string_at(argument)
            self.last_message = message.decode(errors="replace") if message else ""

    def emit(self, *words) -> None:
        sys.stdout.write(" ".join(str(w) for w in words) + "\n")
        sys.stdout.flush()

    # -- one call, judged ---------------------------------------------------------------------------------
    def call(self, name: str, must_fail: bool, may_fail: bool, *args):
        """Runs one FMI call; checks the oracle; returns the status."""
        self.emit("c", self.index, self.count, name)
        self.count += 1
        self.log_non_ok = 0
        if self.version == 3:
            name = FMI3_NAMES[name]
            args = self.fmi3_arguments(name, args)
        status = getattr(self.library, name)(*args)
        self.stats[f"{name} {STATUS_NAMES[status]}"] += 1
        if must_fail and status in (OK, WARNING):
            self.emit("V", self.index, self.count - 1, name, "returned OK where an error is required:", self.why)
        if status != OK and self.log_non_ok == 0:
            self.emit("V", self.index, self.count - 1, name, f"returned {STATUS_NAMES[status]} without a log message")
        if status >= ERROR and not (must_fail or may_fail):
            self.state = None  # an error the oracle did not predict (e.g. numerical): state unknown
            self.stats["unpredicted errors"] += 1
            self.emit("U", self.index, self.count - 1, name, self.last_message)
        return status

    def fmi3_arguments(self, name: str, args: tuple) -> tuple:
        """FMI 3.0 passes a few arguments differently from FMI 2.0."""
        if name.startswith(("fmi3GetFloat64", "fmi3SetFloat64", "fmi3GetInt32", "fmi3SetInt32", "fmi3GetBoolean",
                            "fmi3SetBoolean")):
            c, vrs, n, values = args
            if name.endswith("Int32"):
                values = (ctypes.c_int32 * max(n, 1))(*list(values)[:n])
            elif name.endswith("Boolean"):
                values = (Bool3 * max(n, 1))(*[bool(x) for x in list(values)[:n]])
            return c, vrs, n, values, n
        if name == "fmi3DoStep":
            c, t, h, no_set = args
            flags = [ctypes.byref(Bool3()) for _ in range(3)]
            return c, t, h, bool(no_set), *flags, ctypes.byref(Real())
        if name == "fmi3UpdateDiscreteStates":
            outputs = [ctypes.byref(Bool3()) for _ in range(5)] + [ctypes.byref(Real())]
            if args[1] is None:  # the probe of a null output: one of the six, at random
                outputs[self.rng.randrange(len(outputs))] = None
            return args[0], *outputs
        if name == "fmi3CompletedIntegratorStep":
            return args[0], bool(args[1]), ctypes.byref(Bool3()), ctypes.byref(Bool3())
        if name == "fmi3EnterInitializationMode":
            start, stop_defined, stop = self.pending_times
            return args[0], False, 0.0, start, stop_defined, stop
        return args

    def allowed(self, key: str) -> bool | None:
        """True/False from the state table; None when the oracle does not know the state."""
        states = (ALLOWED3.get(key) or ALLOWED[key])[self.kind] if self.version == 3 else ALLOWED[key][self.kind]
        if states == "any":
            return True
        if not states:
            return False  # the wrong interface type: required to fail in every state
        if self.state is None:
            return None
        return self.state in states

    def state_rule(self, key: str) -> tuple[bool, bool]:
        allowed = self.allowed(key)
        if allowed is False:
            self.why = f"{key} in state {self.state} of a {'CS' if self.kind == CS else 'ME'} instance"
        return allowed is False, allowed is None

    # -- value generators -----------------------------------------------------------------------------------
    def good_value(self, v: Variable):
        r = self.rng
        if v.type == "Boolean":
            return r.random() < 0.5
        if v.name == "solver_step":
            return 10 ** r.uniform(math.log10(max(v.min, 1e-5)), -2)
        low = v.min if math.isfinite(v.min) else -1e3
        high = v.max if math.isfinite(v.max) else low + 10 ** r.uniform(-2, 4)
        if v.start is not None and r.random() < 0.3:
            value = v.start
        elif r.random() < 0.1:
            value = r.choice([low, high])
        else:
            value = r.uniform(low, high)
        return int(round(value)) if v.type == "Integer" else value

    def bad_value(self, v: Variable):
        r = self.rng
        if v.type == "Boolean":
            return None  # every Boolean value is valid
        choices = []
        if math.isfinite(v.min):
            choices += [v.min - 1.0, v.min - abs(v.min) * 1e-6 - 1e-9, -1e300]
        if math.isfinite(v.max):
            choices += [v.max + 1.0, v.max + abs(v.max) * 1e-6 + 1e-9, 1e300]
        if v.type == "Real":
            choices += [math.nan, math.inf, -math.inf]
        if not choices:
            return None
        value = r.choice(choices)
        if v.type == "Integer":
            if not math.isfinite(value) or abs(value) > 2**31 - 1:
                return None
            value = math.floor(value) if value < v.min else math.ceil(value)
            if v.min <= value <= v.max:
                return None
        return value

    # -- calls ----------------------------------------------------------------------------------------------
    def do_set(self, progress: bool) -> None:
        r = self.rng
        kind_name = r.choice(["Real", "Real", "Integer", "Boolean"])
        candidates = [v for v in self.settable if v.type == kind_name] or self.settable
        picks = r.sample(candidates, min(len(candidates), r.randint(1, 3)))
        vrs, values, must, self.why = [], [], False, ""
        for v in picks:
            vrs.append(v.vr)
            value = None if progress else (self.bad_value(v) if r.random() < 0.4 else None)
            if value is None:
                value = self.good_value(v)
            else:
                must, self.why = True, f"{v.name} = {value} outside [{v.min}, {v.max}]"
            values.append(value)
            if v.type != kind_name:
                must, self.why = True, f"{v.name} is {v.type}, set as {kind_name}"
            if self.state is not None and not may_set_in(v, self.state, self.kind):
                must, self.why = True, f"{v.name} ({v.causality}, {v.variability}) set in state {self.state}"
        if not progress and r.random() < 0.1:
            vrs[0], must, self.why = self.unknown_vr, True, "unknown value reference"
        if not progress and r.random() < 0.05:
            output = r.choice([v for v in self.variables if v.causality == "output"])
            vrs[0], must, self.why = output.vr, True, f"output {output.name} set"
        ctype = {"Real": Real, "Integer": Integer, "Boolean": Boolean}[kind_name]
        array = (ctype * len(values))(*[float(x) if ctype is Real else _as_int(x) for x in values])
        uncertain = self.state is None and not must
        status = self.call(f"fmi2Set{kind_name}", must, uncertain or must, self.component,
                           (ctypes.c_uint * len(vrs))(*vrs), len(vrs), array)
        if status == OK and self.solver_step is not None and self.solver_step.vr in vrs:
            self.current_solver_step = float(values[vrs.index(self.solver_step.vr)])
        if status == OK and self.driver_period is not None and self.driver_period.vr in vrs:
            self.current_driver_period = float(values[vrs.index(self.driver_period.vr)])

    def do_get(self) -> None:
        r = self.rng
        kind_name = r.choice(["Real", "Real", "Integer", "Boolean"])
        v = r.choice(self.variables)
        must, uncertain = self.state_rule("get")
        if v.type != kind_name:
            must, self.why = True, f"{v.name} is {v.type}, read as {kind_name}"
        vr = v.vr
        if r.random() < 0.05:
            vr, must, self.why = self.unknown_vr, True, "unknown value reference"
        ctype = {"Real": Real, "Integer": Integer, "Boolean": Boolean}[kind_name]
        self.call(f"fmi2Get{kind_name}", must, uncertain or must, self.component, (ctypes.c_uint * 1)(vr), 1,
                  (ctype * 1)())

    def do_setup(self, progress: bool) -> None:
        r = self.rng
        if self.version == 3:  # no fmi3SetupExperiment: the times go with fmi3EnterInitializationMode
            self.do_enter_initialization(progress)
            return
        start = 0.0 if progress else r.choice([0.0, r.uniform(-10, 10), math.nan, math.inf, 1e16, -1.0])
        stop_defined = r.random() < 0.5
        stop = start + r.choice([10.0, 100.0, 1.0]) if progress or r.random() < 0.7 else r.choice(
            [math.nan, start - 1.0, math.inf])
        must, uncertain = self.state_rule("fmi2SetupExperiment")
        if not math.isfinite(start) or stop_defined and not (math.isfinite(stop) and stop >= start):
            must, self.why = True, f"start {start}, stop {stop}"
        status = self.call("fmi2SetupExperiment", must, must or uncertain, self.component, 0, 0.0, start,
                           int(stop_defined), stop)
        if status == OK:
            self.time, self.stop = start, (stop if stop_defined else math.inf)

    def do_enter_initialization(self, progress: bool) -> None:
        r = self.rng
        start, stop_defined, stop = 0.0, r.random() < 0.5, 10.0
        if self.version == 3 and not progress and r.random() < 0.4:
            start = r.choice([math.nan, math.inf, 1e16, -1.0, r.uniform(-10, 10)])
            stop = r.choice([start + 1.0, start - 1.0, math.nan])
        self.pending_times = (start, stop_defined, stop)
        must, uncertain = self.state_rule("fmi2EnterInitializationMode")
        if not math.isfinite(start) or stop_defined and not (math.isfinite(stop) and stop >= start):
            must, self.why = True, f"start {start}, stop {stop}"
        status = self.call("fmi2EnterInitializationMode", must, must or uncertain, self.component)
        if status == OK:
            self.state = "init"
            if self.version == 3:
                self.time, self.stop = start, (stop if stop_defined else math.inf)

    def do_transition(self, name: str, to: str | None) -> None:
        must, uncertain = self.state_rule(name)
        if name == "fmi2Reset":
            uncertain = False
        status = self.call(name, must, must or uncertain, self.component)
        if status == OK and to is not None:
            self.state = to
            if name == "fmi2Reset":
                self.time, self.stop = 0.0, math.inf
                self.current_solver_step = self.solver_step.start if self.solver_step else 1e-3
                self.current_driver_period = self.driver_period.start if self.driver_period else 0.05

    def do_step(self, progress: bool) -> None:
        r = self.rng
        t = self.time
        h = 10 ** r.uniform(-4, -1.3)
        if not progress:
            roll = r.random()
            if roll < 0.35:
                h = r.choice([0.0, -0.01, math.nan, math.inf, 1e300, 5e-12, 1e-300, 1.0, 2.0,
                              self.current_solver_step * (INTERNAL_STEP_BUDGET + 10)
                              if self.driver_period is None else self.current_driver_period * (SAMPLE_BUDGET + 10)])
            elif roll < 0.5:
                t = r.choice([t + 1.0, t - 0.5, math.nan, math.inf, t + 1e-12])
        must, uncertain = self.state_rule("fmi2DoStep")
        may = False
        ss = self.current_solver_step
        if not (math.isfinite(t) and math.isfinite(h)) or h <= 0:  # FMI 2.0.4 / 3.0: the step must be > 0
            must, self.why = True, f"doStep({t}, {h})"
        elif abs(t - self.time) > TIME_MISMATCH * max(1.0, abs(t)):
            must, self.why = True, f"doStep at {t}, FMU at {self.time}"
        elif self.driver_period is not None and not t + h > t:  # the scenario FMU: one step, no internal ones
            must, self.why = True, f"time cannot advance: {t} + {h}"
        elif self.driver_period is not None and h / self.current_driver_period > SAMPLE_BUDGET:
            must, self.why = True, f"step {h} holds more than {SAMPLE_BUDGET} driver samples"
        elif self.driver_period is None and h > 0 and not t + h / max(1.0, math.ceil(h / ss - 1e-9)) > t:
            must, self.why = True, f"time cannot advance: {t} + internal steps of {h} split by {ss}"
        elif self.driver_period is None and h / ss > INTERNAL_STEP_BUDGET:
            must, self.why = True, f"step {h} needs more than {INTERNAL_STEP_BUDGET} internal steps of {ss}"
        elif t + h > self.stop:
            may = True  # past the stop time: the FMU may refuse
        if self.state is None:
            may = True
        status = self.call("fmi2DoStep", must, must or may or uncertain, self.component, t, h, 1)
        if status == OK:
            self.time = t + h

    def do_me(self, progress: bool) -> None:
        r = self.rng
        choice = r.choice(["fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetDerivatives", "fmi2GetEventIndicators",
                           "fmi2GetContinuousStates", "fmi2GetNominalsOfContinuousStates",
                           "fmi2CompletedIntegratorStep", "fmi2EnterEventMode", "fmi2NewDiscreteStates",
                           "fmi2EnterContinuousTimeMode"])
        must, uncertain = self.state_rule(choice)
        may = must or uncertain
        c = self.component
        if choice == "fmi2SetTime":
            t = self.time + r.uniform(0, 0.01) if progress or r.random() < 0.8 else r.choice([math.nan, math.inf])
            if not math.isfinite(t):
                must, self.why = True, f"time {t}"
            if self.call(choice, must, must or may, c, t) == OK:
                self.time = t
        elif choice == "fmi2SetContinuousStates":
            x = (Real * self.nx)()
            n = self.nx
            get_states = getattr(self.library, "fmi2GetContinuousStates" if self.version == 2 else "fmi3GetContinuousStates")
            if self.state != "cont" or not get_states(c, x, self.nx) == OK:
                x = (Real * self.nx)(*[r.uniform(-1, 1) for _ in range(self.nx)])
            if not progress and r.random() < 0.3:
                if r.random() < 0.5 or self.nx == 0:
                    n, must, self.why = self.nx + 1, True, "wrong number of states"
                    x = (Real * n)()
                else:
                    x[r.randrange(self.nx)], must, self.why = math.nan, True, "NaN state"
            self.call(choice, must, must or may, c, x, n)
        elif choice in ("fmi2GetDerivatives", "fmi2GetEventIndicators", "fmi2GetContinuousStates",
                        "fmi2GetNominalsOfContinuousStates"):
            n = self.nz if choice == "fmi2GetEventIndicators" else self.nx
            if not progress and r.random() < 0.1:
                n, must, self.why = n + 1, True, "wrong vector length"
            self.call(choice, must, must or may, c, (Real * (n + 1))(), n)
        elif choice == "fmi2CompletedIntegratorStep":
            self.call(choice, must, may, c, 1, ctypes.byref(Boolean()), ctypes.byref(Boolean()))
        elif choice == "fmi2EnterEventMode":
            self.do_transition(choice, "event")
        elif choice == "fmi2NewDiscreteStates":
            if r.random() < 0.25:  # a null output (FMI 3.0: one of its six) must be refused, state unchanged
                self.stats["null output probes"] += 1
                self.why = "a null output argument"
                self.call(choice, True, True, c, None)
            else:
                self.call(choice, must, may, c, ctypes.byref(EventInfo()))
        else:
            self.do_transition(choice, "cont")

    def do_fmu_state(self) -> None:
        r = self.rng
        c = self.component
        choice = r.choice(["get", "get", "set", "free", "serialize", "deserialize", "deserialize", "bad handle"])
        if choice == "deserialize" and not self.blobs:
            choice = "serialize"
        if choice == "bad handle":
            self.do_bad_handle()
        elif choice == "get" or not self.handles:
            handle = ctypes.c_void_p()
            if self.call("fmi2GetFMUstate", False, True, c, ctypes.byref(handle)) == OK:
                self.issued(handle)
                self.handles.append((handle, (self.state, self.time, self.stop, self.current_solver_step,
                                              self.current_driver_period)))
        elif choice == "set":
            handle, saved = r.choice(self.handles)
            if self.call("fmi2SetFMUstate", False, True, c, handle) == OK:
                # the stop time belongs to the experiment, not to the FMU state: it stays
                self.state, self.time, _, self.current_solver_step, self.current_driver_period = saved
        elif choice == "free":
            handle, _ = self.handles.pop(r.randrange(len(self.handles)))
            value = handle.value
            if self.call("fmi2FreeFMUstate", False, False, c, ctypes.byref(handle)) == OK:
                self.freed.add(value)
                if r.random() < 0.5:  # the freed handle used at once (before its address can be issued again)
                    self.do_bad_handle("freed")
        elif choice == "serialize":
            handle, saved = r.choice(self.handles)
            size = ctypes.c_size_t()
            if self.call("fmi2SerializedFMUstateSize", False, False, c, handle, ctypes.byref(size)) != OK:
                return
            buffer = ctypes.create_string_buffer(size.value)
            if self.call("fmi2SerializeFMUstate", False, False, c, handle, buffer, size.value) == OK:
                self.blobs.append((buffer.raw, saved))
        elif self.blobs:
            blob, saved = r.choice(self.blobs)
            must = False
            data = bytearray(blob)
            roll = r.random()
            if roll < 0.3:
                data[r.randrange(len(data))] ^= 1 << r.randrange(8)
                must, self.why = True, "a bit flipped in the serialized state"
            elif roll < 0.4:
                data = data[:r.randrange(len(data))]
                must, self.why = True, "truncated serialized state"
            handle = ctypes.c_void_p()
            status = self.call("fmi2DeSerializeFMUstate", must, True, c, bytes(data), len(data), ctypes.byref(handle))
            if status == OK:
                self.issued(handle)
                self.handles.append((handle, saved))

    def issued(self, handle) -> None:
        """A handle the FMU issued: an address freed before may be issued again, and is then valid."""
        self.freed.discard(handle.value)

    def do_bad_handle(self, kind: str | None = None) -> None:
        """A handle the instance did not issue or has freed, or NULL: the size, serialization and restore of it
        must each be refused (the runtime looks handles up in its registry, never reads through them)."""
        r = self.rng
        kind = kind or r.choice(["freed", "wild", "null"] if self.freed else ["wild", "null"])
        value = {"freed": lambda: r.choice(sorted(self.freed)), "wild": lambda: ctypes.addressof(self.wild),
                 "null": lambda: None}[kind]()
        self.stats["bad handle probes"] += 1
        self.why = f"a {kind} FMU state handle"
        handle = ctypes.c_void_p(value)
        size = ctypes.c_size_t(123)
        self.call("fmi2SerializedFMUstateSize", True, True, self.component, handle, ctypes.byref(size))
        if r.random() < 0.5:
            self.call("fmi2SerializeFMUstate", True, True, self.component, handle, self.wild_buffer,
                      len(self.wild_buffer))
        else:
            self.call("fmi2SetFMUstate", True, True, self.component, handle)

    # -- sequences ------------------------------------------------------------------------------------------
    def progress_call(self) -> None:
        state, r = self.state, self.rng
        if state == "instantiated":
            r.choice([lambda: self.do_setup(True), lambda: self.do_set(True),
                      lambda: self.do_enter_initialization(True)])()
        elif state == "init":
            r.choice([lambda: self.do_set(True), self.do_get,
                      lambda: self.do_transition("fmi2ExitInitializationMode", "step" if self.kind == CS else "event")])()
        elif state == "step":
            r.choice([lambda: self.do_step(True), lambda: self.do_step(True), lambda: self.do_set(True), self.do_get])()
        elif state in ("event", "cont"):
            self.do_me(True)
        else:
            self.do_transition("fmi2Reset", "instantiated")

    def random_call(self) -> None:
        r = self.rng
        r.choice([
            lambda: self.do_set(False), lambda: self.do_set(False), self.do_get, lambda: self.do_step(False),
            lambda: self.do_setup(False), lambda: self.do_me(False), self.do_fmu_state, self.do_fmu_state,
            lambda: self.do_enter_initialization(False),
            lambda: self.do_transition("fmi2ExitInitializationMode", "step" if self.kind == CS else "event"),
            lambda: self.do_transition("fmi2Terminate", "terminated"),
            lambda: self.do_transition("fmi2Reset", "instantiated"),
            self.do_status,
        ])()

    def do_status(self) -> None:
        """One of the five fmi2Get*Status functions with a kind of fmi2StatusKind (0..3) or outside it; a kind the
        FMU does not report may give Discard, which (like every non-OK return) needs a log message."""
        if self.version == 3:  # FMI 3.0 has no fmi3Get*Status
            return
        name, value = self.rng.choice([("fmi2GetStatus", Status()), ("fmi2GetRealStatus", Real()),
                                       ("fmi2GetIntegerStatus", Integer()), ("fmi2GetBooleanStatus", Boolean()),
                                       ("fmi2GetStringStatus", ctypes.c_char_p())])
        kind = self.rng.choice([0, 1, 2, 3, 3, -1, 7])
        must, _ = self.state_rule("fmi2GetXXXStatus")
        self.call(name, must, True, self.component, kind, ctypes.byref(value))

    def sequence(self, index: int) -> None:
        self.rng = r = random.Random(self.seed * 1_000_003 + index)
        self.index, self.count = index, 0
        self.kind = CS if r.random() < 0.6 or not self.model_exchange else ME
        guid = self.guid if r.random() > 0.02 else b"{00000000-0000-0000-0000-000000000000}"
        self.emit("c", index, -1, "fmi2Instantiate")
        if self.version == 2:
            self.component = self.library.fmi2Instantiate(b"fuzz", self.kind, guid, self.resources,
                                                          ctypes.byref(self.callbacks), 0, 0)
        elif self.kind == CS:
            self.component = self.library.fmi3InstantiateCoSimulation(b"fuzz", guid, self.resources, False, False,
                                                                      False, False, None, 0, None, self.log_message3,
                                                                      None)
        else:
            self.component = self.library.fmi3InstantiateModelExchange(b"fuzz", guid, self.resources, False, False,
                                                                       None, self.log_message3)
        if guid != self.guid:
            if self.component:
                self.emit("V", index, -1, "fmi2Instantiate", "accepted a wrong GUID")
                getattr(self.library, "fmi2FreeInstance" if self.version == 2 else "fmi3FreeInstance")(self.component)
            return
        if not self.component:
            self.emit("V", index, -1, "fmi2Instantiate", "failed")
            return
        self.state, self.time, self.stop = "instantiated", 0.0, math.inf
        self.current_solver_step = self.solver_step.start if self.solver_step else 1e-3
        self.current_driver_period = self.driver_period.start if self.driver_period else 0.05
        self.handles, self.blobs, self.freed = [], [], set()
        self.pending_times = (0.0, False, 0.0)
        for _ in range(r.randint(5, 40)):
            if r.random() < 0.65 and self.state is not None:
                self.progress_call()
            else:
                self.random_call()
        free_state, free_instance = (("fmi2FreeFMUstate", "fmi2FreeInstance") if self.version == 2
                                     else ("fmi3FreeFMUState", "fmi3FreeInstance"))
        for handle, _ in self.handles:
            getattr(self.library, free_state)(self.component, ctypes.byref(handle))
        getattr(self.library, free_instance)(self.component)

    def run(self, first: int, count: int) -> None:
        for index in range(first, first + count):
            self.sequence(index)
        self.emit("D", json.dumps(self.stats))


# ---- the parent: batches, crash restarts, watchdog --------------------------------------------------------------


@dataclass
class Report:
    sequences: int = 0
    calls: int = 0
    crashes: list = field(default_factory=list)
    hangs: list = field(default_factory=list)
    violations: list = field(default_factory=list)
    unpredicted: list = field(default_factory=list)  # errors the oracle did not predict (numerical failures)
    statuses: Counter = field(default_factory=Counter)
    seconds: float = 0.0

    def summary(self) -> str:
        unpredicted = self.statuses.get("unpredicted errors", 0)
        errors = sum(n for k, n in self.statuses.items() if k.endswith(" Error"))
        return (f"{self.sequences} sequences, {self.calls} calls ({errors} returned Error, {unpredicted} of them "
                f"numerical), {len(self.crashes)} crashes, {len(self.hangs)} hangs, "
                f"{len(self.violations)} oracle violations, {self.seconds:.1f} s")


def model_config(unzipped: Path, library: Path, seed: int) -> dict:
    from fmpy import read_model_description

    description = read_model_description(str(unzipped))

    def bound(text, default):
        return float(text) if text is not None else default

    variables = [dict(name=v.name, vr=v.valueReference, type=TYPE_NAMES.get(v.type, v.type), causality=v.causality,
                      variability=v.variability, min=bound(v.min, -math.inf), max=bound(v.max, math.inf),
                      start=None if v.start is None or v.type == "Boolean" else float(v.start))
                 for v in description.modelVariables]
    resources = unzipped / "resources"
    location = "" if not resources.is_dir() else (
        resources.as_uri() if description.fmiVersion.startswith("2") else str(resources) + os.sep)
    return {"library": str(library), "guid": description.guid, "variables": variables,
            "fmi_version": int(description.fmiVersion[0]), "model_exchange": description.modelExchange is not None,
            "resources": location,
            "nx": description.numberOfContinuousStates, "nz": description.numberOfEventIndicators, "seed": seed}


def sanitized_library(unzipped: Path, output: Path) -> Path:
    """Compiles the FMU's own sources with AddressSanitizer and UBSan (aborting on the first finding)."""
    try:
        from sdl_fmu.fmu.package import compile_binary
    except ImportError:  # not installed: the checkout this tool lives in
        sys.path.append(str(Path(__file__).resolve().parents[1]))
        from sdl_fmu.fmu.package import compile_binary
    from fmpy.model_description import read_build_description

    configuration, = read_build_description(str(unzipped))
    compile_binary(unzipped / "sources", configuration.sourceFileSets[0].sourceFiles, output,
                   extra_flags=("-g", "-O1", "-fno-omit-frame-pointer", "-fsanitize=address,undefined",
                                "-fno-sanitize-recover=all"))
    return output


def sanitizer_environment() -> dict:
    runtime = subprocess.run(["gcc", "-print-file-name=libasan.so"], capture_output=True, text=True).stdout.strip()
    return {**os.environ, "LD_PRELOAD": runtime, "ASAN_OPTIONS": "detect_leaks=0:abort_on_error=1",
            "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1"}


def fuzz(fmu: Path, sequences: int = 1000, seed: int = 1, batch: int = 250, hang_timeout: float = HANG_TIMEOUT,
         sanitize: bool = False, log=None) -> Report:
    """Runs `sequences` random call sequences against the FMU's Linux binary (or a sanitized build of its
    sources) and returns what happened."""
    report = Report()
    began = time.monotonic()
    work = Path(tempfile.mkdtemp(prefix="sdl-fmu-fuzz-"))
    try:
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(work)
        from fmpy import read_model_description

        description = read_model_description(str(work))
        identifier = description.coSimulation.modelIdentifier
        platform = "linux64" if description.fmiVersion.startswith("2") else "x86_64-linux"
        library = work / "binaries" / platform / f"{identifier}.so"
        environment = dict(os.environ)
        if sanitize:
            library = sanitized_library(work, work / f"{identifier}-sanitized.so")
            environment = sanitizer_environment()
        config = work / "config.json"
        config.write_text(json.dumps(model_config(work, library, seed)))
        stderr_path = work / "stderr.txt"
        next_index = 0
        while next_index < sequences:
            count = min(batch, sequences - next_index)
            next_index = _run_batch(config, next_index, count, hang_timeout, environment, stderr_path, report, log)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    report.seconds = time.monotonic() - began
    return report


def _run_batch(config: Path, first: int, count: int, hang_timeout: float, environment: dict, stderr_path: Path,
               report: Report, log) -> int:
    """Runs one worker; returns the index of the next sequence to run."""
    with open(stderr_path, "wb") as stderr:
        worker = subprocess.Popen([*WORKER_COMMAND, "--worker", str(config), str(first), str(count)],
                                  stdout=subprocess.PIPE, stderr=stderr, env=environment)
    current, last_call, buffer, done = first, "", b"", False
    try:
        while True:
            # the watchdog times calls; before the first one the worker is still starting
            ready, _, _ = select.select([worker.stdout], [], [], hang_timeout if last_call else STARTUP_TIMEOUT)
            if not ready:
                worker.kill()
                worker.wait()
                if not last_call:
                    report.crashes.append(f"sequence {first}: the worker did not start in {STARTUP_TIMEOUT} s")
                    return first + 1
                report.hangs.append(f"sequence {current}: {last_call} ran longer than {hang_timeout} s")
                if log:
                    log(f"HANG in sequence {current} at {last_call}")
                return current + 1
            chunk = os.read(worker.stdout.fileno(), 65536)
            if not chunk:
                break
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            for line in lines:
                words = line.decode(errors="replace").split(" ", 3)
                if words[0] == "c":
                    current, last_call = int(words[1]), " ".join(words[2:])
                    if words[2] == "-1":
                        report.sequences += 1
                    else:
                        report.calls += 1
                elif words[0] == "V":
                    report.violations.append(line.decode(errors="replace")[2:])
                    if log:
                        log("VIOLATION " + line.decode(errors="replace")[2:])
                elif words[0] == "U":
                    report.unpredicted.append(line.decode(errors="replace")[2:])
                elif words[0] == "D":
                    report.statuses.update(json.loads(line.decode()[2:]))
                    done = True
    finally:
        if worker.poll() is None:
            worker.kill()
        worker.wait()
        worker.stdout.close()
    if done and worker.returncode == 0:
        return first + count
    tail = stderr_path.read_text(errors="replace")[-3000:]
    report.crashes.append(f"sequence {current}: {last_call}: exit status {worker.returncode}\n{tail}")
    if log:
        log(f"CRASH in sequence {current} at {last_call} (exit status {worker.returncode})\n{tail}")
    return current + 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python tools/fmi_fuzz.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("fmu", nargs="+", type=Path)
    parser.add_argument("--sequences", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--batch", type=int, default=250)
    parser.add_argument("--hang-timeout", type=float, default=HANG_TIMEOUT)
    parser.add_argument("--sanitize", action="store_true",
                        help="compile the FMU's sources with AddressSanitizer + UBSan and fuzz that build")
    arguments = parser.parse_args(argv)
    failed = False
    for fmu in arguments.fmu:
        report = fuzz(fmu, arguments.sequences, arguments.seed, arguments.batch, arguments.hang_timeout,
                      arguments.sanitize, log=lambda text: print(text, file=sys.stderr))
        print(f"{fmu.parent.name}/{fmu.name}: {report.summary()}")
        for line in report.unpredicted[:10]:
            print(f"    error not predicted by the oracle (sequence, call, function, message): {line}")
        failed |= bool(report.crashes or report.hangs or report.violations)
    return 1 if failed else 0


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--worker":
        Worker(json.loads(Path(sys.argv[2]).read_text())).run(int(sys.argv[3]), int(sys.argv[4]))
    else:
        sys.exit(main())
