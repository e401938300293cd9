"""SSP 1.0 archives in the portable subset that libcosim (libcosimpy), ecos (ecospy) and fmpy's simulate_ssp all
run (docs/export.md, The portable subset): a `System` described as data here is written as SystemStructure.ssd, one
parameter set per component in resources/<component>.ssv, and the FMUs under resources/.

What the subset is, and why (measured with the three masters):
- `version="1.0"`: ecos refuses any other version, and fmpy's schema has no 2.0;
- the literal prefixes `ssd:`, `ssc:`, `ssv:` (and `osp:` for the step annotation): libcosim's and ecos' readers
  look elements up by their prefixed names, so the `ns0:` that a serializer invents fails there;
- connectors typed (ssc:Real, ssc:Integer, ssc:Boolean) on both ends: ecos refuses a connection whose two
  connectors differ in type, libcosim refuses an untyped connector; an input connector only where a connection
  feeds it (fmpy's simulate_ssp fails on an unconnected one);
- a connection's scale, offset and unit conversion folded into one `ssc:LinearTransformation` (target = factor *
  source + offset), with `suppressUnitConversion="true"`: libcosim and ecos apply the transformation and convert no
  units, and a master that does convert the connectors' units does not convert them twice. Identity connections
  carry none (libcosim adds a function to the system for each);
- one named parameter set per component (ecos applies a set only when `init(parameter_set=NAME)` names it;
  libcosim applies a component's first set; fmpy's simulate_ssp reads none: it is passed as `parameter_set`);
- the step as the OSP annotation `osp:FixedStepAlgorithm baseStepSize` in the DefaultExperiment (libcosim's step;
  ecos and fmpy take theirs from the caller).
- every file under resources/ named so that its URI needs no escaping: a `source` is a URI (written escaped here),
  which libcosim decodes (`a%20b.fmu` is the file `a b.fmu`) and ecos and fmpy read as the file's name as it is
  (`a%20b.fmu`); only a name whose escape is itself is the same file to all three (the export's names are safe
  identifiers: sdl_fmu/text.py, safe_identifier).

The writer is deterministic: the same system gives the same bytes (fixed zip dates; elements in the order given).
Every document is validated against the SSP 1.0 schemas that fmpy ships before anything is written.
"""

from __future__ import annotations

import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Literal
from urllib.parse import quote

from ..text import printable

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
OSP_ANNOTATION = "com.opensimulationplatform"
SSD_NAME = "SystemStructure.ssd"
RESOURCES = "resources"
ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # the zip format's earliest date: the archive does not change with the clock

ValueType = Literal["Real", "Integer", "Boolean"]
Kind = Literal["input", "output", "parameter"]
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


class SspError(ValueError):
    """A system that cannot be written as a portable SSP (a bug of the caller: the export checks its input first)."""


@dataclass(frozen=True)
class Unit:
    """An ssc:Unit: SI exponents, and value_SI = factor * value + offset."""

    name: str
    exponents: dict[str, int]
    factor: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Connector:
    name: str
    kind: Kind
    type: ValueType
    unit: str | None = None  # the name of a Unit of the system


@dataclass(frozen=True)
class Parameter:
    name: str
    type: ValueType
    value: float | int | bool


@dataclass(frozen=True)
class Component:
    """An FMU in the system: `fmu` is the file on disk, stored as resources/<file_name> (default: its own name)."""

    name: str
    fmu: Path
    connectors: tuple[Connector, ...]
    parameters: tuple[Parameter, ...] = ()
    file_name: str | None = None

    @property
    def source(self) -> str:
        return f"{RESOURCES}/{self.file_name or self.fmu.name}"

    @property
    def parameter_source(self) -> str:
        return f"{RESOURCES}/{self.name}.ssv"


@dataclass(frozen=True)
class Connection:
    """start (component, connector) -> end (component, connector); target = factor * source + offset."""

    start: tuple[str, str]
    end: tuple[str, str]
    factor: float = 1.0
    offset: float = 0.0

    @property
    def identity(self) -> bool:
        return self.factor == 1.0 and self.offset == 0.0


@dataclass(frozen=True)
class System:
    name: str
    components: tuple[Component, ...]
    connections: tuple[Connection, ...]
    stop_time: float
    step: float
    parameter_set: str = "start"  # the name of every component's parameter set
    units: tuple[Unit, ...] = ()
    description: str | None = None
    generation_tool: str | None = None

    def component(self, name: str) -> Component:
        return next(c for c in self.components if c.name == name)


def _number(value: float) -> str:
    """A float as xs:double: the shortest text that reads back as the same double."""
    if not math.isfinite(value):
        raise SspError(f"{value!r} is not a finite number")
    return repr(float(value))


def _value(parameter: Parameter) -> str:
    if parameter.type == "Real":
        return _number(parameter.value)
    if parameter.type == "Boolean":
        return "true" if parameter.value else "false"
    return str(int(parameter.value))


def uri(path: str) -> str:
    """A relative path inside the SSP as a URI reference (an SSD's `source`): each part percent-escaped."""
    return quote(path, safe="/")


def check(system: System) -> None:
    """The system's own consistency: unique names, typed connectors on both ends of each connection, the same type
    on both, a transformation only between Real connectors, finite numbers, a unit for each unit named."""
    names = [c.name for c in system.components]
    if len(set(names)) != len(names):
        raise SspError(f"component names repeat: {names}")
    sources = [c.source for c in system.components]
    if len(set(sources)) != len(sources) or any(c.parameter_source in sources for c in system.components):
        raise SspError(f"two components' files would share a name under {RESOURCES}/: {sources}")
    for source in (*sources, *(c.parameter_source for c in system.components)):
        if uri(source) != source:
            raise SspError(f"{printable(source, keep_lines=False)}: a file name an SSP's source URI must escape "
                           f"({uri(source)}), which ecos and fmpy do not undo and libcosim does")
    units = {u.name for u in system.units}
    connectors = {}
    for component in system.components:
        seen = set()
        for connector in component.connectors:
            if connector.name in seen:
                raise SspError(f"{component.name}.{connector.name}: the connector repeats")
            seen.add(connector.name)
            if connector.unit is not None and connector.unit not in units:
                raise SspError(f"{component.name}.{connector.name}: unit {connector.unit!r} is not defined")
            connectors[(component.name, connector.name)] = connector
        for parameter in component.parameters:
            _value(parameter)
    ends = set()
    for connection in system.connections:
        start, end = connectors.get(connection.start), connectors.get(connection.end)
        shown = f"{'.'.join(connection.start)} -> {'.'.join(connection.end)}"
        if start is None or end is None:
            raise SspError(f"{shown}: a connector is not declared")
        if start.kind != "output" or end.kind != "input":
            raise SspError(f"{shown}: must go from an output to an input")
        if start.type != end.type:
            raise SspError(f"{shown}: {start.type} -> {end.type} (ecos refuses connectors of different types)")
        if not connection.identity and start.type != "Real":
            raise SspError(f"{shown}: a linear transformation needs Real connectors")
        if connection.end in ends:
            raise SspError(f"{shown}: the input is connected twice")
        ends.add(connection.end)
        _number(connection.factor), _number(connection.offset)
    unconnected = [f"{c}.{n}" for (c, n), connector in connectors.items() if connector.kind == "input"
                   and (c, n) not in ends]
    if unconnected:
        raise SspError(f"{unconnected[0]}: an input connector must be connected (fmpy's simulate_ssp fails on one "
                       "that is not)")
    if not (system.step > 0 and system.stop_time > 0):
        raise SspError(f"step {system.step} and stop time {system.stop_time} must be > 0")


def _element(parent, namespace: str, tag: str, attributes: dict | None = None):
    from lxml import etree

    return etree.SubElement(parent, f"{{{namespace}}}{tag}", {k: v for k, v in (attributes or {}).items()
                                                              if v is not None})


def ssd(system: System) -> bytes:
    """SystemStructure.ssd of the system."""
    from lxml import etree

    check(system)
    root = etree.Element(f"{{{SSD}}}SystemStructureDescription", nsmap={"ssd": SSD, "ssc": SSC, "ssv": SSV,
                                                                        "osp": OSP})
    root.set("version", "1.0")
    root.set("name", printable(system.name, keep_lines=False))  # text XML can hold
    if system.description:
        root.set("description", printable(system.description, keep_lines=False))
    if system.generation_tool:
        root.set("generationTool", system.generation_tool)
    node = _element(root, SSD, "System", {"name": root.get("name")})
    elements = _element(node, SSD, "Elements")
    for component in system.components:
        element = _element(elements, SSD, "Component", {"name": component.name, "source": uri(component.source),
                                                        "type": "application/x-fmu-sharedlibrary"})
        if component.connectors:
            connectors = _element(element, SSD, "Connectors")
            for connector in component.connectors:
                entry = _element(connectors, SSD, "Connector", {"name": connector.name, "kind": connector.kind})
                _element(entry, SSC, connector.type, {"unit": connector.unit} if connector.type == "Real" else None)
        bindings = _element(element, SSD, "ParameterBindings")
        _element(bindings, SSD, "ParameterBinding", {"source": uri(component.parameter_source)})
    if system.connections:
        connections = _element(node, SSD, "Connections")
        for connection in system.connections:
            entry = _element(connections, SSD, "Connection", {
                "startElement": connection.start[0], "startConnector": connection.start[1],
                "endElement": connection.end[0], "endConnector": connection.end[1],
                "suppressUnitConversion": None if connection.identity else "true"})
            if not connection.identity:
                _element(entry, SSC, "LinearTransformation", {"factor": _number(connection.factor),
                                                              "offset": _number(connection.offset)})
    if system.units:
        units = _element(root, SSD, "Units")
        for unit in system.units:
            entry = _element(units, SSC, "Unit", {"name": unit.name})
            attributes = {k: str(v) for k, v in unit.exponents.items() if v}
            if unit.factor != 1.0:
                attributes["factor"] = _number(unit.factor)
            if unit.offset != 0.0:
                attributes["offset"] = _number(unit.offset)
            _element(entry, SSC, "BaseUnit", attributes)
    experiment = _element(root, SSD, "DefaultExperiment", {"startTime": "0.0",
                                                           "stopTime": _number(system.stop_time)})
    annotation = _element(_element(experiment, SSD, "Annotations"), SSC, "Annotation", {"type": OSP_ANNOTATION})
    algorithm = _element(annotation, OSP, "Algorithm")
    _element(algorithm, OSP, "FixedStepAlgorithm", {"baseStepSize": _number(system.step)})
    text = etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
    validate(text, "SystemStructureDescription.xsd")
    return text


def ssv(system: System, component: Component) -> bytes:
    """resources/<component>.ssv: the component's parameter set, named system.parameter_set."""
    from lxml import etree

    root = etree.Element(f"{{{SSV}}}ParameterSet", nsmap={"ssv": SSV, "ssc": SSC})
    root.set("version", "1.0")
    root.set("name", system.parameter_set)
    parameters = _element(root, SSV, "Parameters")
    for parameter in component.parameters:
        entry = _element(parameters, SSV, "Parameter", {"name": parameter.name})
        _element(entry, SSV, parameter.type, {"value": _value(parameter)})
    text = etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
    validate(text, "SystemStructureParameterValues.xsd")
    return text


def schema_directory() -> Path:
    """The SSP 1.0 schemas that fmpy ships (fmpy validates an SSD against them before simulating it)."""
    import fmpy.ssp

    return Path(fmpy.ssp.__file__).parent / "schema"


def validate(document: bytes, schema: str) -> None:
    """Raises SspError listing the schema's complaints about the document."""
    from lxml import etree

    checker = _schema(schema)
    if not checker.validate(etree.fromstring(document)):
        problems = "; ".join(f"line {e.line}: {e.message}" for e in checker.error_log)
        raise SspError(f"{schema}: {problems}")


_SCHEMAS: dict = {}


def _schema(name: str):
    from lxml import etree

    if name not in _SCHEMAS:
        _SCHEMAS[name] = etree.XMLSchema(etree.parse(str(schema_directory() / name)))
    return _SCHEMAS[name]


def _entry(name: str, compression: int) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, ZIP_DATE)
    info.compress_type = compression
    info.external_attr = 0o644 << 16  # rw-r--r--: an unzip that applies the modes gets readable files
    return info


def write_ssp(system: System, path: Path) -> Path:
    """Writes the SSP archive: SystemStructure.ssd, resources/<component>.ssv, resources/<FMU>."""
    entries = [(SSD_NAME, ssd(system))]
    entries += [(component.parameter_source, ssv(system, component)) for component in system.components]
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, data in entries:
            archive.writestr(_entry(name, zipfile.ZIP_DEFLATED), data)
        for component in system.components:
            # FMUs are zip archives already: stored, not compressed again
            with archive.open(_entry(component.source, zipfile.ZIP_STORED), "w") as target, \
                    open(component.fmu, "rb") as source:
                while chunk := source.read(1 << 20):
                    target.write(chunk)
    return path
