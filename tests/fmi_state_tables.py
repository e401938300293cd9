"""The FMI standard's tables of the states in which each function may be called, written out, and the reader of a
runtime's MASK_fmi2<Function> / MASK_fmi3<Function> lines: shared by test_state_tables.py (the ego FMUs' runtime) and
test_scenario_fmu.py (the scenario FMU's runtime). The letters are the runtime's states (test_state_tables.py)."""

import re
from pathlib import Path

from sdl_fmu.fmu.codegen import RUNTIME_DIRECTORY

LETTER = {"MODE_INSTANTIATED": "I", "MODE_INITIALIZATION": "N", "MODE_EVENT": "E", "MODE_CONTINUOUS_TIME": "C",
          "MODE_STEP": "S", "MODE_TERMINATED": "T", "MODE_ERROR": "X"}
ANY = "INECSTX"

# FMI 2.0.4, section 3.2.3 (model exchange) and 4.2.4 (co-simulation), the tables of allowed calls.
FMI2 = {
    "SetDebugLogging": ANY, "SetupExperiment": "I", "EnterInitializationMode": "I", "ExitInitializationMode": "N",
    "Terminate": "ECS", "Reset": ANY,
    **{f"Get{t}": "NECSTX" for t in ("Real", "Integer", "Boolean", "String")},
    "SetReal": "INECS", **{f"Set{t}": "INES" for t in ("Integer", "Boolean", "String")},
    "GetFMUstate": ANY, "SetFMUstate": ANY, "FreeFMUstate": ANY, "SerializedFMUstateSize": ANY,
    "SerializeFMUstate": ANY, "DeSerializeFMUstate": ANY,
    "GetDirectionalDerivative": "NECSTX",
    # model exchange
    "EnterEventMode": "EC", "NewDiscreteStates": "E", "EnterContinuousTimeMode": "E", "CompletedIntegratorStep": "C",
    "SetTime": "EC", "SetContinuousStates": "C", "GetEventIndicators": "NECTX", "GetContinuousStates": "NECTX",
    "GetDerivatives": "ECTX", "GetNominalsOfContinuousStates": "IECTX",
    # co-simulation
    "SetRealInputDerivatives": "INS", "GetRealOutputDerivatives": "STX", "DoStep": "S",
    "CancelStep": "",  # stepInProgress only
    **{f"Get{t}Status": "ST" for t in ("", "Real", "Integer", "Boolean", "String")},
}
# Deliberate deviations, each a stricter answer: a state saved in the Error state could never be restored
# (fmi2SetFMUstate refuses the Error state), so fmi2GetFMUstate refuses to save it.
FMI2_DEVIATIONS = {"GetFMUstate": "INECST"}

# FMI 3.0, sections 3.2 (model exchange) and 4.2 (co-simulation) state machines, for the rows this runtime
# implements. (fmi3Get<Type> and the FMU-state functions are allowed in every state here.)
FMI3 = {
    "EnterInitializationMode": "I", "ExitInitializationMode": "N", "Terminate": "ECS", "Reset": ANY,
    "SetDebugLogging": ANY, "SetFloat64": "INECS", "SetInt32": "INES", "SetBoolean": "INES",
    "GetDirectionalDerivative": "NECST", "GetAdjointDerivative": "NECST",
    # model exchange
    "EnterEventMode": "C", "UpdateDiscreteStates": "E", "EnterContinuousTimeMode": "E", "CompletedIntegratorStep": "C",
    "SetTime": "C", "SetContinuousStates": "C",
    "GetContinuousStateDerivatives": "NECT", "GetEventIndicators": "NECT", "GetContinuousStates": "NECT",
    "GetNominalsOfContinuousStates": "NECT",
    "GetNumberOfEventIndicators": "IE", "GetNumberOfContinuousStates": "IE",
    # co-simulation
    "DoStep": "S",
}
FMI3_DEVIATIONS = {"GetFMUState": "INECST"}  # as in FMI 2.0


def mask_table(version: int, path: Path | None = None) -> dict:
    """{function without prefix: allowed state letters} from the MASK_ lines (of the ego FMUs' runtime, or of the
    file `path`), and the check of every use."""
    source = (path or RUNTIME_DIRECTORY / f"fmi{version}Functions.c").read_text()
    table = {}
    for name, expression in re.findall(rf"^#define MASK_fmi{version}(\w+)\s+(.*)$", source, re.M):
        expression = re.sub(r"/\*.*?\*/", "", expression).strip()
        value = expression.replace("ANY_MODE", "(" + " | ".join(LETTER) + ")")
        for mode in LETTER:
            value = re.sub(rf"\b{mode}\b", str(1 << list(LETTER).index(mode)), value)
        bits = eval(value, {"__builtins__": {}})  # only integers and | & ~ ( ) are left
        table[name] = "".join(letter for i, letter in enumerate(ANY) if bits & (1 << list(LETTER).index(
            next(m for m, x in LETTER.items() if x == letter))))
    # every state check of a function uses its own line (nothing inline)
    for function, argument in re.findall(rf'checked\w*\(c, "fmi{version}(\w+)", ([^,)]+)', source):
        assert argument == f"MASK_fmi{version}{function}", (function, argument)
    return table
