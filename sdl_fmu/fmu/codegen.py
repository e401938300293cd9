"""C code of one model: CasADi's generated equations plus the variable table the runtime reads."""

from __future__ import annotations

import hashlib
import uuid
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import casadi as ca

from ..dynamics.equations import MODEL_EXCHANGE, Equations
from ..interface import DISCRETE, INPUT, OUTPUT, PARAMETER, STATE, Interface, Variable
from .structure import DERIVATIVE_FUNCTIONS, derivative_functions

RUNTIME_DIRECTORY = Path(str(resources.files(__package__) / "runtime"))  # package data (pyproject.toml)
RUNTIME_SOURCES = ("instance.c", "cosimulation.c", "derivatives.c")  # shared by FMI 2.0 and 3.0
FMI_SOURCES = {2: "fmi2Functions.c", 3: "fmi3Functions.c"}  # the FMI layer of each version
RUNTIME_HEADERS = ("model.h", "instance.h", "derivatives.h")
MODEL_FUNCTIONS = ("derivatives", "jacobian", "outputs", "event_indicators", "discrete_update", "initial_state")
FUNCTION_ORDER = (*MODEL_FUNCTIONS, *DERIVATIVE_FUNCTIONS)  # the ModelFunction fields of ModelInfo


def runtime_sources(fmi_version: int) -> tuple[str, ...]:
    """The runtime's C files that an FMU of this FMI version compiles."""
    return (*RUNTIME_SOURCES, FMI_SOURCES[fmi_version])

_STORE = {STATE: "STORE_STATE", DISCRETE: "STORE_DISCRETE", INPUT: "STORE_INPUT", PARAMETER: "STORE_PARAMETER",
          OUTPUT: "STORE_OUTPUT"}
_KIND = {"Real": "KIND_REAL", "Integer": "KIND_INTEGER", "Boolean": "KIND_BOOLEAN"}


@dataclass(frozen=True)
class TableEntry:
    """One FMI variable as the C runtime and the XML see it; value reference = position + 1."""

    name: str
    kind: str
    store: str
    index: int
    settable: str
    variable: Variable | None  # None for the der(...) and event indicator variables
    derivative_of: int | None = None  # value reference of the state, for der(...)
    event_indicator: int | None = None  # position in z, for the event indicator variables


def event_indicator_name(index: int) -> str:
    return f"event_indicator_{index + 1}"


def variable_table(interface: Interface, event_indicators: int = 0) -> list[TableEntry]:
    """Interface variables, then der(state) per state, then one Real local per event indicator (FMI 3.0's
    ModelStructure names event indicators by variable; FMI 2.0 FMUs carry the same table)."""
    entries = []
    for v in interface.variables:
        if v.role == INPUT:
            settable = "SET_INPUT"
        elif v.role == PARAMETER:
            settable = "SET_TUNABLE" if v.variability == "tunable" else "SET_FIXED"
        else:
            settable = "SET_NEVER"
        entries.append(TableEntry(v.name, _KIND[v.type], _STORE[v.role], v.index, settable, v))
    state_references = {v.index: i + 1 for i, v in enumerate(interface.variables) if v.role == STATE}
    for state in interface.of_role(STATE):
        entries.append(
            TableEntry(f"der({state.name})", "KIND_REAL", "STORE_DERIVATIVE", state.index, "SET_NEVER", None,
                       derivative_of=state_references[state.index])
        )
    for k in range(event_indicators):
        entries.append(TableEntry(event_indicator_name(k), "KIND_REAL", "STORE_EVENT_INDICATOR", k, "SET_NEVER", None,
                                  event_indicator=k))
    return entries


def _c_number(value) -> str:
    return repr(float(value))


def _c_bound(value, missing: str) -> str:
    return missing if value is None else _c_number(value)


def _c_range(entry: TableEntry) -> str:
    v = entry.variable
    low, high = (v.min, v.max) if v is not None else (None, None)
    return f"{_c_bound(low, '-INFINITY')}, {_c_bound(high, 'INFINITY')}"


def _c_array(name: str, values) -> str:
    body = ", ".join(_c_number(v) for v in values) or "0.0"  # C has no empty arrays
    return f"static const double {name}[] = {{{body}}};"


def model_guid(interface: Interface, casadi_source: str) -> str:
    """Deterministic GUID: the same interface and equations always give the same FMU identity."""
    digest = hashlib.sha256((repr(interface) + casadi_source).encode()).digest()
    return "{" + str(uuid.UUID(bytes=digest[:16], version=4)) + "}"


def generate_casadi(equations: Equations, directory: Path) -> tuple[dict, str]:
    """Writes <Model>_casadi.c/.h (the model functions) and <Model>_casadi_derivatives.c/.h (the derivative
    sweeps, a translation unit of their own so the two compile in parallel); returns the functions and the C
    source of both."""
    model = equations.interface.model_name
    functions = {**equations.functions(), **derivative_functions(equations, model)}
    sources = []
    for name, keys in ((f"{model}_casadi", MODEL_FUNCTIONS), (f"{model}_casadi_derivatives", DERIVATIVE_FUNCTIONS)):
        generator = ca.CodeGenerator(f"{name}.c", {"with_header": True, "casadi_int": "long long int"})
        for key in keys:
            generator.add(functions[key])
        generator.generate(str(directory) + "/")
        sources.append((directory / f"{name}.c").read_text())
    return functions, "".join(sources)


def generate_derivatives_source(equations: Equations, directory: Path) -> Path:
    """Writes <Model>_derivatives.c, the translation unit of CasADi's derivative sweeps."""
    model = equations.interface.model_name
    path = directory / f"{model}_derivatives.c"
    path.write_text(f"""/* Generated by sdl-fmu: CasADi's forward and reverse sweeps of {model} (model.h), do not edit. */
/* CasADi's generated code passes every function the same arguments, used or not */
#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif
#include "{model}_casadi_derivatives.c"
""")
    return path


def generate_model_source(equations: Equations, functions: dict, guid: str, directory: Path) -> Path:
    """Writes <Model>_model.c: the variable table and ModelInfo around CasADi's functions."""
    interface = equations.interface
    model = interface.model_name
    nz = functions["event_indicators"].size1_out(0)
    table = variable_table(interface, nz)
    inputs = interface.of_role(INPUT)
    parameters = interface.of_role(PARAMETER)
    states = interface.of_role(STATE)
    solver_step = next((p.index for p in parameters if p.name == "solver_step"), -1)
    solver_tolerance = next((p.index for p in parameters if p.name == "solver_tolerance"), -1)
    runtime_parameters = equations.symbols.p.numel() - len(parameters)  # after the interface's, set by the runtime
    model_exchange = len(parameters) if MODEL_EXCHANGE in equations.symbols.by_name else -1
    rows = ",\n".join(
        f'    {{{i + 1}u, "{e.name}", {e.kind}, {e.store}, {e.index}, {e.settable}, {_c_range(e)}}}'
        for i, e in enumerate(table)
    )
    function_fields = ",\n".join(
        f"    {{{functions[key].name()}, {functions[key].name()}_work}}" for key in FUNCTION_ORDER
    )
    source = f"""/* Generated by sdl-fmu from modelDescription/{model}.json and the CasADi model: do not edit. */
#include <math.h>

#include "model.h"

/* CasADi's generated code passes every function the same arguments, used or not */
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif
#include "{model}_casadi.c"
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif
#include "{model}_casadi_derivatives.h" /* compiled in {model}_derivatives.c */

static const ModelVariable variables[] = {{
{rows}
}};

{_c_array("input_start", [v.start for v in inputs])}
{_c_array("parameter_start", [v.start for v in parameters] + [0.0] * runtime_parameters)}
{_c_array("state_nominal", [v.nominal or 1.0 for v in states])}

const ModelInfo model_info = {{
    "{model}",
    "{guid}",
    {len(states)}, {len(interface.of_role(DISCRETE))}, {len(inputs)}, {len(parameters) + runtime_parameters}, {len(interface.of_role(OUTPUT))}, {nz},
    input_start,
    parameter_start,
    state_nominal,
    variables,
    {len(table)},
    {solver_step},
    {solver_tolerance},
    {model_exchange},
{function_fields},
    NULL /* no hooks: the generic FMI layers do everything */
}};
"""
    path = directory / f"{model}_model.c"
    path.write_text(source)
    return path
