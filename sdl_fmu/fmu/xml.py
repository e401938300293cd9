"""modelDescription.xml and buildDescription.xml, generated from the interface data and the table."""

from __future__ import annotations

import time
import xml.etree.ElementTree as ET

from .. import __version__
from ..interface import INPUT, OUTPUT, PARAMETER, STATE, DISCRETE, Interface
from .codegen import TableEntry

LOG_CATEGORIES = {
    "logEvents": "Events located by the FMU: stops, starts, mode changes (debug logging)",
    "logStatusError": "Errors: misuse of the FMI API, failed evaluations",
}


def _number(value) -> str:
    number = float(value)
    return str(int(number)) if number.is_integer() and abs(number) < 1e15 else repr(number)


def _unit_definitions(parent: ET.Element, interface: Interface) -> None:
    used = sorted({v.unit for v in interface.variables if v.unit is not None})
    definitions = ET.SubElement(parent, "UnitDefinitions")
    for name in used:
        unit = interface.units[name]
        element = ET.SubElement(definitions, "Unit", name=name)
        ET.SubElement(element, "BaseUnit", {k: str(e) for k, e in unit["base"].items()})
        for display, conversion in unit.get("display", {}).items():
            attributes = {"name": display, "factor": repr(conversion["factor"])}
            if conversion.get("offset"):
                attributes["offset"] = repr(conversion["offset"])
            ET.SubElement(element, "DisplayUnit", attributes)


def _scalar_variable(parent: ET.Element, entry: TableEntry, value_reference: int) -> None:
    v = entry.variable
    if v is None:  # der(state)
        element = ET.SubElement(parent, "ScalarVariable", name=entry.name, valueReference=str(value_reference),
                                causality="local", variability="continuous")
        ET.SubElement(element, "Real", derivative=str(entry.derivative_of))
        return
    attributes = {"name": v.name, "valueReference": str(value_reference), "causality": v.causality,
                  "variability": v.variability}
    if v.description:
        attributes["description"] = v.description
    if v.role in (STATE, DISCRETE, OUTPUT):
        attributes["initial"] = "calculated"
    element = ET.SubElement(parent, "ScalarVariable", attributes)
    typed = {}
    if v.role in (INPUT, PARAMETER):
        typed["start"] = _number(v.start) if v.type != "Boolean" else ("true" if v.start else "false")
    if v.type == "Real":
        typed["unit"] = v.unit
        if v.nominal is not None:
            typed["nominal"] = _number(v.nominal)
    if v.type in ("Real", "Integer"):
        if v.min is not None:
            typed["min"] = _number(v.min)
        if v.max is not None:
            typed["max"] = _number(v.max)
    ET.SubElement(element, v.type, typed)


def _source_files(parent: ET.Element, sources: list[str]) -> None:
    files = ET.SubElement(parent, "SourceFiles")
    for source in sources:
        ET.SubElement(files, "File", name=source)


def model_description(interface: Interface, table: list[TableEntry], guid: str, event_indicators: int,
                      sources: list[str]) -> bytes:
    model = interface.model_name
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0",
        "modelName": model,
        "guid": guid,
        "description": interface.description,
        "generationTool": f"sdl-fmu {__version__} (CasADi code generation)",
        "generationDateAndTime": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "variableNamingConvention": "structured",
        "numberOfEventIndicators": str(event_indicators),
    })
    common = {"modelIdentifier": model, "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true",
              "canNotUseMemoryManagementFunctions": "false", "providesDirectionalDerivative": "false"}
    # FMI 2.0 names the sources in each interface element; buildDescription.xml says the same for FMI 3 tools
    model_exchange = ET.SubElement(root, "ModelExchange", {**common, "completedIntegratorStepNotNeeded": "true"})
    _source_files(model_exchange, sources)
    co_simulation = ET.SubElement(root, "CoSimulation", {**common, "canHandleVariableCommunicationStepSize": "true",
                                                         "canInterpolateInputs": "false",
                                                         "maxOutputDerivativeOrder": "0"})
    _source_files(co_simulation, sources)
    _unit_definitions(root, interface)
    categories = ET.SubElement(root, "LogCategories")
    for name, description in LOG_CATEGORIES.items():
        ET.SubElement(categories, "Category", name=name, description=description)
    experiment = interface.default_experiment
    if experiment:
        ET.SubElement(root, "DefaultExperiment", {k: _number(v) for k, v in experiment.items()})
    variables = ET.SubElement(root, "ModelVariables")
    for position, entry in enumerate(table, start=1):
        _scalar_variable(variables, entry, position)

    structure = ET.SubElement(root, "ModelStructure")
    outputs = [i for i, e in enumerate(table, 1) if e.variable is not None and e.variable.causality == "output"]
    derivatives = [i for i, e in enumerate(table, 1) if e.variable is None]
    local_states = [i for i, e in enumerate(table, 1)
                    if e.variable is not None and e.variable.causality == "local" and e.variable.role == STATE]
    if outputs:
        element = ET.SubElement(structure, "Outputs")
        for i in outputs:
            ET.SubElement(element, "Unknown", index=str(i))
    if derivatives:
        element = ET.SubElement(structure, "Derivatives")
        for i in derivatives:
            ET.SubElement(element, "Unknown", index=str(i))
    initial = sorted(set(outputs + derivatives + local_states))
    if initial:
        element = ET.SubElement(structure, "InitialUnknowns")
        for i in initial:
            ET.SubElement(element, "Unknown", index=str(i))
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def build_description(model: str, sources: list[str]) -> bytes:
    """sources/buildDescription.xml (FMI 3 format, as the Reference-FMUs ship it in FMI 2 FMUs too)."""
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    configuration = ET.SubElement(root, "BuildConfiguration", modelIdentifier=model)
    file_set = ET.SubElement(configuration, "SourceFileSet", language="C99")
    for source in sources:
        ET.SubElement(file_set, "SourceFile", name=source)
    ET.SubElement(configuration, "Library", name="m", description="libm (CasADi's generated code uses math.h)")
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")
