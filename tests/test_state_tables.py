"""Each FMI version's allowed states sit in one table of MASK_fmi2<Function> / MASK_fmi3<Function> lines
(sdl_fmu/fmu/runtime/fmi2Functions.c, fmi3Functions.c), and every FMI function that checks its state uses its
own line. The tables are compared here with the standard's state tables, written out below.

States of this runtime: I Instantiated, N Initialization Mode, E Event Mode, C Continuous-Time Mode (model
exchange), S Step Mode (co-simulation: FMI 2.0 "stepComplete"), T Terminated, X Error. States the runtime never
enters are left out of the expected sets: FMI 2.0 stepInProgress, stepFailed, stepCanceled (fmi2DoStep always
completes or fails into Error), FMI 3.0 Configuration, Reconfiguration, Step Discarded, Clock Activation and
Intermediate Update Mode (no structural parameters, no clocks, hasEventMode="false", no early return).
One mask serves both interface types: a function's model-exchange states (I N E C T X) and co-simulation states
(I N S T X) are united; functions of one interface type refuse the other type before the table is consulted."""

import re
from pathlib import Path

import pytest

RUNTIME = Path(__file__).parents[1] / "sdl_fmu" / "fmu" / "runtime"
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
    source = (path or RUNTIME / f"fmi{version}Functions.c").read_text()
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


@pytest.mark.parametrize("version, expected, deviations", [(2, FMI2, FMI2_DEVIATIONS), (3, FMI3, FMI3_DEVIATIONS)],
                         ids=["fmi2", "fmi3"])
def test_state_table_is_the_standards(version, expected, deviations):
    table = mask_table(version)
    for function, states in {**expected, **deviations}.items():
        assert function in table, f"no MASK_fmi{version}{function} line"
        assert set(table[function]) == set(states), (function, table[function], states)
    if version == 2:  # FMI 2.0: every line is compared
        assert set(table) == set(expected) | set(deviations)
