"""modelDescription.xml and buildDescription.xml, generated from the interface data and the table."""

from __future__ import annotations

import time
import xml.etree.ElementTree as ET

from .. import __version__
from ..interface import INPUT, OUTPUT, PARAMETER, STATE, DISCRETE, Interface
from .codegen import TableEntry
from .structure import DeclaredDependencies

# the modelDescription's author, copyright and license attributes (pyproject.toml: license = MIT)
AUTHOR = "the sdl-fmu authors"
COPYRIGHT = "Copyright (c) 2026 the sdl-fmu authors"
LICENSE = "MIT"

LOG_CATEGORIES = {
    "logEvents": "Events located by the FMU: stops, starts, mode changes (debug logging)",
    "logStatusWarning": "Warnings: partial derivatives that are not finite",
    "logStatusError": "Errors: misuse of the FMI API, failed evaluations",
}


def _xml_number(value) -> str:
    """A number as an XML attribute: exact (repr), a whole number without '.0'."""
    number = float(value)
    return str(int(number)) if number.is_integer() and abs(number) < 1e15 else repr(number)


def derivative_unit(unit: str, units: dict) -> str:
    """The unit of der(v) for a state v of this unit: the unit in units.json whose base is v's divided by s."""
    base = dict(units[unit]["base"])
    base["s"] = base.get("s", 0) - 1
    base = {name: exponent for name, exponent in base.items() if exponent}
    for name, definition in units.items():
        if definition["base"] == base:
            return name
    raise ValueError(f"units.json has no unit for the derivative of a quantity in {unit} (base units {base})")


def entry_unit(entry: TableEntry, table: list[TableEntry], interface: Interface) -> str | None:
    """The unit of a variable of the table: its own, its state's over s for der(...), None for the event
    indicators (only their sign counts) and for Integer and Boolean variables (FMI gives them no unit)."""
    if entry.variable is not None:
        return entry.variable.unit
    if entry.derivative_of is not None:
        return derivative_unit(table[entry.derivative_of - 1].variable.unit, interface.units)
    return None


EVENT_INDICATOR_DESCRIPTION = ("Event indicator {}: the model's discrete update happens where it changes sign; only "
                               "its sign is meaningful (its magnitude's unit changes with the mode), so it has no unit")


def entry_description(entry: TableEntry, table: list[TableEntry]) -> str:
    """The description of a variable of the table (der(...) and event indicators included)."""
    if entry.variable is not None:
        return entry.variable.description
    if entry.derivative_of is not None:
        state = table[entry.derivative_of - 1].variable
        return f"Time derivative of the state {state.name} ({state.description})"
    return EVENT_INDICATOR_DESCRIPTION.format(entry.event_indicator + 1)


def _unit_definitions(parent: ET.Element, interface: Interface, table: list[TableEntry],
                      extra: tuple[str, ...] = ()) -> None:
    unit_definitions(parent, interface, {entry_unit(e, table, interface) for e in table} - {None} | set(extra))


def unit_definitions(parent: ET.Element, interface: Interface, used: set[str]) -> None:
    """The <UnitDefinitions> of these units of the interface (sorted by name), with their display units: the ego
    FMUs' and the scenario FMU's model descriptions."""
    definitions = ET.SubElement(parent, "UnitDefinitions")
    for name in sorted(used):
        unit = interface.units[name]
        element = ET.SubElement(definitions, "Unit", name=name)
        ET.SubElement(element, "BaseUnit", {k: str(e) for k, e in unit["base"].items()})
        for display, conversion in unit.get("display", {}).items():
            attributes = {"name": display, "factor": repr(conversion["factor"])}
            if conversion.get("offset"):
                attributes["offset"] = repr(conversion["offset"])
            ET.SubElement(element, "DisplayUnit", attributes)


def _scalar_variable(parent: ET.Element, entry: TableEntry, value_reference: int, table: list[TableEntry],
                     interface: Interface) -> None:
    v = entry.variable
    if v is None:  # der(state) or an event indicator
        element = ET.SubElement(parent, "ScalarVariable", name=entry.name, valueReference=str(value_reference),
                                description=entry_description(entry, table), causality="local",
                                variability="continuous")
        if entry.event_indicator is not None:
            ET.SubElement(element, "Real")
        else:
            ET.SubElement(element, "Real", derivative=str(entry.derivative_of),
                          unit=entry_unit(entry, table, interface))
        return
    attributes = {"name": v.name, "valueReference": str(value_reference), "causality": v.causality,
                  "variability": v.variability}
    if v.description:
        attributes["description"] = v.description
    if v.role in (STATE, DISCRETE, OUTPUT):
        attributes["initial"] = "calculated"
    element = ET.SubElement(parent, "ScalarVariable", attributes)
    ET.SubElement(element, v.type, _value_attributes(v))


def _value_attributes(v) -> dict[str, str]:
    """start, unit, nominal, min and max of a variable: the attributes FMI 2.0 puts on its type element and
    FMI 3.0 on the variable itself."""
    attributes = {}
    if v.role in (INPUT, PARAMETER):
        attributes["start"] = _xml_number(v.start) if v.type != "Boolean" else ("true" if v.start else "false")
    if v.type == "Real":
        attributes["unit"] = v.unit
        if v.nominal is not None:
            attributes["nominal"] = _xml_number(v.nominal)
    if v.type in ("Real", "Integer"):
        if v.min is not None:
            attributes["min"] = _xml_number(v.min)
        if v.max is not None:
            attributes["max"] = _xml_number(v.max)
    return attributes


def _log_categories_and_experiment(root: ET.Element, interface: Interface) -> None:
    """LogCategories and DefaultExperiment: the same elements, in the same place, in FMI 2.0 and 3.0."""
    categories = ET.SubElement(root, "LogCategories")
    for name, description in LOG_CATEGORIES.items():
        ET.SubElement(categories, "Category", name=name, description=description)
    experiment = interface.default_experiment
    if experiment:
        ET.SubElement(root, "DefaultExperiment", {k: _xml_number(v) for k, v in experiment.items()})


def _source_files(parent: ET.Element, sources: list[str]) -> None:
    files = ET.SubElement(parent, "SourceFiles")
    for source in sources:
        ET.SubElement(files, "File", name=source)


def _dependency_attributes(dependencies: list[tuple[int, str]]) -> dict:
    """dependencies / dependenciesKind of one unknown (empty lists: it depends on no known)."""
    return {"dependencies": " ".join(str(vr) for vr, _ in dependencies),
            "dependenciesKind": " ".join(kind for _, kind in dependencies)}


def _structure_lists(table: list[TableEntry]) -> tuple[list[int], list[int], list[int], list[int]]:
    """Value references of the outputs, derivatives, initial unknowns and event indicators (table order)."""
    outputs = [i for i, e in enumerate(table, 1) if e.variable is not None and e.variable.causality == "output"]
    derivatives = [i for i, e in enumerate(table, 1) if e.derivative_of is not None]
    local_states = [i for i, e in enumerate(table, 1)
                    if e.variable is not None and e.variable.causality == "local" and e.variable.role == STATE]
    initial = sorted(set(outputs + derivatives + local_states))
    indicators = [i for i, e in enumerate(table, 1) if e.event_indicator is not None]
    return outputs, derivatives, initial, indicators


def _generation_attributes(interface: Interface) -> dict[str, str]:
    """The root attributes both FMI versions share, after the version, model name and GUID/token."""
    return {"description": interface.description,
            "author": AUTHOR, "version": __version__, "copyright": COPYRIGHT, "license": LICENSE,
            "generationTool": f"sdl-fmu {__version__} (CasADi code generation)",
            "generationDateAndTime": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "variableNamingConvention": "structured"}


def model_description(interface: Interface, table: list[TableEntry], guid: str, event_indicators: int,
                      sources: list[str], dependencies: DeclaredDependencies) -> bytes:
    """FMI 2.0 modelDescription.xml."""
    model = interface.model_name
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0",
        "modelName": model,
        "guid": guid,
        **_generation_attributes(interface),
        "numberOfEventIndicators": str(event_indicators),
    })
    common = {"modelIdentifier": model, "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true",
              "canNotUseMemoryManagementFunctions": "false", "providesDirectionalDerivative": "true"}
    # FMI 2.0 names the sources in each interface element; buildDescription.xml says the same for FMI 3 tools
    model_exchange = ET.SubElement(root, "ModelExchange", {**common, "completedIntegratorStepNotNeeded": "true"})
    _source_files(model_exchange, sources)
    co_simulation = ET.SubElement(root, "CoSimulation", {**common, "canHandleVariableCommunicationStepSize": "true",
                                                         "canInterpolateInputs": "false",
                                                         "maxOutputDerivativeOrder": "0"})
    _source_files(co_simulation, sources)
    _unit_definitions(root, interface, table)
    _log_categories_and_experiment(root, interface)
    variables = ET.SubElement(root, "ModelVariables")
    for position, entry in enumerate(table, start=1):
        _scalar_variable(variables, entry, position, table, interface)

    structure = ET.SubElement(root, "ModelStructure")
    outputs, derivatives, initial, _ = _structure_lists(table)
    for name, unknowns, declared in (("Outputs", outputs, dependencies.continuous),
                                     ("Derivatives", derivatives, dependencies.continuous),
                                     ("InitialUnknowns", initial, dependencies.initial)):
        if unknowns:
            element = ET.SubElement(structure, name)
            for i in unknowns:
                ET.SubElement(element, "Unknown", {"index": str(i), **_dependency_attributes(declared[i])})
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


_FMI3_TYPE = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}


def _fmi3_variable(parent: ET.Element, entry: TableEntry, value_reference: int, reinit: set[int],
                   table: list[TableEntry], interface: Interface) -> None:
    v = entry.variable
    attributes = {"name": entry.name, "valueReference": str(value_reference)}
    if v is None:  # der(state) or an event indicator
        attributes.update(description=entry_description(entry, table), causality="local", variability="continuous")
        if entry.derivative_of is not None:
            attributes.update(unit=entry_unit(entry, table, interface), derivative=str(entry.derivative_of))
        ET.SubElement(parent, "Float64", attributes)
        return
    if v.description:
        attributes["description"] = v.description
    attributes.update(causality=v.causality, variability=v.variability)
    if v.role in (STATE, DISCRETE, OUTPUT):
        attributes["initial"] = "calculated"
    attributes.update(_value_attributes(v))
    if v.role == STATE and v.index in reinit:
        attributes["reinit"] = "true"  # the discrete update may set it at an event
    ET.SubElement(parent, _FMI3_TYPE[v.type], attributes)


def model_description_fmi3(interface: Interface, table: list[TableEntry], guid: str,
                           dependencies: DeclaredDependencies, reinit: set[int]) -> bytes:
    """FMI 3.0 modelDescription.xml: the same variables (value references 1..n) plus the independent
    variable time (value reference 0); the sources are named by sources/buildDescription.xml."""
    model = interface.model_name
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "3.0",
        "modelName": model,
        "instantiationToken": guid,
        **_generation_attributes(interface),
    })
    common = {"modelIdentifier": model, "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
              "providesDirectionalDerivatives": "true", "providesAdjointDerivatives": "true"}
    ET.SubElement(root, "ModelExchange", {**common, "needsCompletedIntegratorStep": "false"})
    ET.SubElement(root, "CoSimulation", {**common, "canHandleVariableCommunicationStepSize": "true",
                                         "hasEventMode": "false", "maxOutputDerivativeOrder": "0"})
    _unit_definitions(root, interface, table, extra=("s",))  # time
    _log_categories_and_experiment(root, interface)
    variables = ET.SubElement(root, "ModelVariables")
    ET.SubElement(variables, "Float64", name="time", valueReference="0", causality="independent",
                  variability="continuous", unit="s", description="Simulation time")
    for position, entry in enumerate(table, start=1):
        _fmi3_variable(variables, entry, position, reinit, table, interface)

    structure = ET.SubElement(root, "ModelStructure")
    outputs, derivatives, initial, indicators = _structure_lists(table)
    for name, unknowns, declared in (("Output", outputs, dependencies.continuous),
                                     ("ContinuousStateDerivative", derivatives, dependencies.continuous),
                                     ("InitialUnknown", initial, dependencies.initial),
                                     ("EventIndicator", indicators, dependencies.continuous)):
        for i in unknowns:
            ET.SubElement(structure, name, {"valueReference": str(i), **_dependency_attributes(declared[i])})
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
