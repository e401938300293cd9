"""The scenario FMU's modelDescription.xml (FMI 2.0 and 3.0) and documentation/index.html, from its interface data
(runtime/SdlScenario.json) with the scenario's traffic slots and start values."""

from __future__ import annotations

import html
import xml.etree.ElementTree as ET

from .. import __version__
from ..fmu.documentation import STYLE
from ..fmu.xml import AUTHOR, COPYRIGHT, LICENSE, LOG_CATEGORIES, unit_definitions
from ..interface import INPUT, OUTPUT, PARAMETER, Interface
from .binary import MODEL_IDENTIFIER

# the outputs that depend on inputs directly (the commands on the controller's requests; what the FMU observes of
# the ego, when it evaluates at the communication points without prediction): the ModelStructure declares them
COMMAND_DEPENDENCIES = {"throttle": ("request_active", "request_throttle", "request_brake"),
                        "brake": ("request_active", "request_brake"),
                        "steer": ("request_active", "request_steer")}
OBSERVED_FROM = ("ego_x", "ego_y", "ego_psi", "ego_v", "ego_vx", "ego_vy")
OBSERVATIONS = ("mu_", "surface_", "lead_")
_FMI3_TYPE = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
LOG_EVENTS = "Each event the scenario fires (as summary.json lists it), with its instant; BRK ignored"


def _number(value) -> str:
    number = float(value)
    return str(int(number)) if number.is_integer() and abs(number) < 1e15 else repr(number)


def _value_attributes(v) -> dict[str, str]:
    attributes = {}
    if v.role in (INPUT, PARAMETER):
        attributes["start"] = ("true" if v.start else "false") if v.type == "Boolean" else _number(v.start)
    if v.type == "Real":
        attributes["unit"] = v.unit
    if v.type in ("Real", "Integer"):
        if v.min is not None:
            attributes["min"] = _number(v.min)
        if v.max is not None:
            attributes["max"] = _number(v.max)
    return attributes


def _unit_definitions(root: ET.Element, interface: Interface, extra: tuple[str, ...] = ()) -> None:
    unit_definitions(root, interface, {v.unit for v in interface.variables if v.unit} | set(extra))


def _common(root: ET.Element, experiment: dict) -> None:
    categories = ET.SubElement(root, "LogCategories")
    for name, description in {**LOG_CATEGORIES, "logEvents": LOG_EVENTS}.items():
        ET.SubElement(categories, "Category", name=name, description=description)
    ET.SubElement(root, "DefaultExperiment", {k: _number(v) for k, v in experiment.items()})


def dependencies(interface: Interface) -> dict[str, list[str]]:
    """Per output, the inputs it depends on directly."""
    result = {}
    for v in interface.of_role(OUTPUT):
        if v.name in COMMAND_DEPENDENCIES:
            result[v.name] = list(COMMAND_DEPENDENCIES[v.name])
        elif v.name.startswith(OBSERVATIONS):
            result[v.name] = list(OBSERVED_FROM)
        else:
            result[v.name] = []
    return result


def _root_attributes(interface: Interface, description: str) -> dict[str, str]:
    return {"description": description, "author": AUTHOR, "version": __version__, "copyright": COPYRIGHT,
            "license": LICENSE, "generationTool": f"sdl-fmu {__version__} (the generic scenario runtime)",
            "variableNamingConvention": "structured"}  # no generationDateAndTime: the same export, the same bytes


def model_description(interface: Interface, guid: str, fmi_version: int, description: str, experiment: dict,
                      sources: list[str], model_name: str = MODEL_IDENTIFIER) -> bytes:
    """The modelDescription.xml; `model_name` is the scenario's name as written (the modelIdentifier is the generic
    binary's, the same for every scenario)."""
    references = {v.name: position for position, v in enumerate(interface.variables, start=1)}
    depends = dependencies(interface)
    outputs = [v for v in interface.variables if v.role == OUTPUT]
    common = {"modelIdentifier": MODEL_IDENTIFIER, "canHandleVariableCommunicationStepSize": "true"}
    if fmi_version == 2:
        root = ET.Element("fmiModelDescription", {"fmiVersion": "2.0", "modelName": model_name, "guid": guid,
                                                  **_root_attributes(interface, description),
                                                  "numberOfEventIndicators": "0"})
        co_simulation = ET.SubElement(root, "CoSimulation", {
            **common, "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true",
            "canNotUseMemoryManagementFunctions": "false", "providesDirectionalDerivative": "false",
            "canInterpolateInputs": "false", "maxOutputDerivativeOrder": "0"})
        files = ET.SubElement(co_simulation, "SourceFiles")
        for source in sources:
            ET.SubElement(files, "File", name=source)
        _unit_definitions(root, interface)
        _common(root, experiment)
        variables = ET.SubElement(root, "ModelVariables")
        for v in interface.variables:
            attributes = {"name": v.name, "valueReference": str(references[v.name]), "description": v.description,
                          "causality": v.causality, "variability": v.variability}
            if v.role == OUTPUT:
                attributes["initial"] = "calculated"
            element = ET.SubElement(variables, "ScalarVariable", attributes)
            ET.SubElement(element, v.type, _value_attributes(v))
        structure = ET.SubElement(root, "ModelStructure")
        for name, initial in (("Outputs", False), ("InitialUnknowns", True)):
            element = ET.SubElement(structure, name)
            for v in outputs:
                attributes = {"index": str(references[v.name])}
                if not initial:  # initial unknowns: on every known (no attribute)
                    attributes["dependencies"] = " ".join(str(references[n]) for n in depends[v.name])
                    attributes["dependenciesKind"] = " ".join("dependent" for _ in depends[v.name])
                ET.SubElement(element, "Unknown", attributes)
    else:
        root = ET.Element("fmiModelDescription", {"fmiVersion": "3.0", "modelName": model_name,
                                                  "instantiationToken": guid,
                                                  **_root_attributes(interface, description)})
        ET.SubElement(root, "CoSimulation", {
            **common, "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
            "providesDirectionalDerivatives": "false", "providesAdjointDerivatives": "false",
            "hasEventMode": "false", "mightReturnEarlyFromDoStep": "true", "maxOutputDerivativeOrder": "0"})
        _unit_definitions(root, interface, extra=("s",))
        _common(root, experiment)
        variables = ET.SubElement(root, "ModelVariables")
        ET.SubElement(variables, "Float64", name="time", valueReference="0", causality="independent",
                      variability="continuous", unit="s", description="Simulation time")
        for v in interface.variables:
            attributes = {"name": v.name, "valueReference": str(references[v.name]), "description": v.description,
                          "causality": v.causality, "variability": v.variability}
            if v.role == OUTPUT:
                attributes["initial"] = "calculated"
            attributes.update(_value_attributes(v))
            ET.SubElement(variables, _FMI3_TYPE[v.type], attributes)
        structure = ET.SubElement(root, "ModelStructure")
        for v in outputs:
            ET.SubElement(structure, "Output", {
                "valueReference": str(references[v.name]),
                "dependencies": " ".join(str(references[n]) for n in depends[v.name]),
                "dependenciesKind": " ".join("dependent" for _ in depends[v.name])})
        for v in outputs:
            ET.SubElement(structure, "InitialUnknown", {"valueReference": str(references[v.name])})
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def _shown(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return f"{float(value):.6g}"


def _table(interface: Interface, role, with_start: bool) -> str:
    references = {v.name: position for position, v in enumerate(interface.variables, start=1)}
    head = "<tr><th>name</th><th>value reference</th><th>type</th><th>unit</th>"
    head += "<th>start</th><th>min</th><th>max</th>" if with_start else ""
    head += "<th>description</th></tr>"
    rows = []
    for v in interface.of_role(role):
        cells = [f"<code>{html.escape(v.name)}</code>", str(references[v.name]), v.type, html.escape(v.unit or "")]
        if with_start:
            cells += [_shown(v.start), _shown(v.min), _shown(v.max)]
        cells.append(html.escape(v.description))
        rows.append("<tr>" + "".join(f"<td>{cell}</td>" for cell in cells) + "</tr>")
    return f"<table>\n{head}\n" + "\n".join(rows) + "\n</table>"


# how the scenario FMU and an ego vehicle FMU with the shipped FMUs' interface are connected
WIRING = (("ego.x", "scenario.ego_x"), ("ego.y", "scenario.ego_y"), ("ego.psi", "scenario.ego_psi"),
          ("ego.v", "scenario.ego_v"), ("ego.s", "scenario.ego_s"), ("ego.vx", "scenario.ego_vx"),
          ("ego.vy", "scenario.ego_vy"), ("ego.yaw_rate", "scenario.ego_yaw_rate"), ("ego.ax", "scenario.ego_ax"),
          ("ego.ay", "scenario.ego_ay"), ("ego.stopped", "scenario.ego_stopped"),
          ("scenario.throttle", "ego.throttle"), ("scenario.brake", "ego.brake"), ("scenario.steer", "ego.steer"),
          ("scenario.mu_fl .. mu_rr", "ego.mu_fl .. mu_rr (Simple) or scenario.surface_fl .. surface_rr -> "
                                      "ego.surface_fl .. surface_rr (Advanced)"))


def documentation(interface: Interface, fmi_version: int, sdl_text: str, source: str, description: str,
                  starts: dict, start_lateral: float, warnings: list[str], linux: str, windows: str,
                  sources: list[str]) -> str:
    wiring = "\n".join(f"<tr><td><code>{html.escape(a)}</code></td><td><code>{html.escape(b)}</code></td></tr>"
                       for a, b in WIRING)
    listed_warnings = "".join(f"<li>{html.escape(w)}</li>" for w in warnings) or "<li>none</li>"
    compile_line = (f"cc -std=c99 -O2 -ffp-contract=off -fPIC -shared -Isources "
                    f"{' '.join(f'sources/{s}' for s in sources)} -o {MODEL_IDENTIFIER}.so -lm")
    example = f"""import shutil

from fmpy import extract, read_model_description
from fmpy.fmi{fmi_version} import FMU{fmi_version}Slave

folders = []  # where the FMUs are unpacked, removed at the end

def open_fmu(path):
    description = read_model_description(path)
    folders.append(extract(path))
    slave = FMU{fmi_version}Slave(guid=description.guid, unzipDirectory=folders[-1], instanceName=path,
                      modelIdentifier=description.coSimulation.modelIdentifier)
    slave.instantiate()
    return slave, {{v.name: v.valueReference for v in description.modelVariables}}

# this FMU and an ego FMU of sdl-fmu's interface (sdl-fmu build --out dist: dist/fmi{fmi_version}/EgoVehicleSimple.fmu)
scenario, s = open_fmu("scenario.fmu")
ego, e = open_fmu("EgoVehicleSimple.fmu")
{"ego.setupExperiment(startTime=0.0)" if fmi_version == 2 else "# (FMI 3.0: the start time goes with enterInitializationMode)"}
ego.{"setReal" if fmi_version == 2 else "setFloat64"}([e["v0"], e["y0"]], [{starts["speed"]!r}, {-start_lateral!r}])  # the scenario's start
ego.enterInitializationMode()
ego.exitInitializationMode()
motion = ["x", "y", "psi", "v", "s", "vx", "vy", "yaw_rate", "ax", "ay"]
commands = ["throttle", "brake", "steer", "mu_fl", "mu_fr", "mu_rl", "mu_rr"]
get, put = ({"(ego.getReal, scenario.setReal)" if fmi_version == 2 else "(ego.getFloat64, scenario.setFloat64)"})


def ego_to_scenario():
    put([s["ego_" + name] for name in motion], get([e[name] for name in motion]))
    scenario.setBoolean([s["ego_stopped"]], ego.getBoolean([e["stopped"]]))


{"scenario.setupExperiment(startTime=0.0)" if fmi_version == 2 else ""}
scenario.enterInitializationMode()
ego_to_scenario()
scenario.exitInitializationMode()
t, h = 0.0, 0.01  # a fixed-step (Jacobi) master: both FMUs step t -> t + h with each other's outputs at t
while not scenario.getBoolean([s["ended"]])[0]:
    values = scenario.{"getReal" if fmi_version == 2 else "getFloat64"}([s[name] for name in commands])
    ego_to_scenario()
    ego.{"setReal" if fmi_version == 2 else "setFloat64"}([e[name] for name in commands], values)
    ego.doStep(t, h)
    scenario.doStep(t, h)
    t += h
print(f"ended at {{t:.2f}} s:", scenario.{"getInteger" if fmi_version == 2 else "getInt32"}([s["events"], s["collisions"]]))
for fmu in (scenario, ego):
    fmu.terminate()
    fmu.freeInstance()
for folder in folders:
    shutil.rmtree(folder, ignore_errors=True)"""
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{MODEL_IDENTIFIER}: {html.escape(source)}</title>
<style>{STYLE}</style>
</head>
<body>
<h1>{MODEL_IDENTIFIER}: the SDL scenario {html.escape(source)}</h1>
<p>{html.escape(description)}</p>
<p>FMI {fmi_version}.0 for Co-Simulation, sdl-fmu {__version__}. {html.escape(COPYRIGHT)}; licence: {LICENSE}
(<a href="licenses/license.txt">licenses/license.txt</a>). Binaries: Linux (<code>binaries/{linux}/</code>) and,
when it was built with mingw-w64, Windows (<code>binaries/{windows}/</code>); they need libc and libm only, no
Python. The binary is the same for every scenario: the scenario is data, <code>resources/scenario.sdlfmu</code>
(resolved at export: SI units, random vehicle models drawn from the seed as <code>sdl-fmu run</code> draws them);
<code>resources/scenario.sdl</code> is the text it came from.</p>

<h2>The scenario</h2>
<pre>{html.escape(sdl_text)}</pre>
<p>Warnings when it was read: <ul>{listed_warnings}</ul></p>

<h2>Wiring</h2>
<p>The FMU drives the ego vehicle: connect the ego's outputs to the scenario's inputs and the scenario's commands and
surfaces to the ego's inputs. With an ego vehicle FMU of sdl-fmu's interface (the shipped Simple and Advanced FMUs):
</p>
<table><tr><th>from</th><th>to</th></tr>
{wiring}
</table>
<p>Set the ego's start state to the scenario's: <code>v0</code> = the parameter <code>speed</code>
({_shown(starts.get("speed"))} m/s here), <code>x0</code> = 0, <code>y0</code> = minus the centre of lane 1,
<code>psi0</code> = 0. An ego without some of the optional outputs (distance, body velocities, yaw rate,
accelerations, stopped): leave the input unconnected and set its <code>ego_*_connected</code> parameter to false; the
FMU then derives it as <code>sdl-fmu run</code> does. A controller in the loop connects its requests to
<code>request_*</code> and reads the <code>lead_*</code> signals; the arbitration parameters say which channels it
takes over (its requests may take any finite value: the arbitration limits them).</p>
<p>The start (the events at distance 0, the driver's first sample) is taken from the inputs when the FMU leaves
initialization mode and again from those of the first <code>doStep</code> (a warning in the log if they differ): an
ego that fills its outputs only when it leaves initialization is still started right, but its own first step has
the commands the master read before. Give the ego's outputs in initialization mode, as FMI 2.0 asks.</p>

<h2>Stepping: triggers inside a step</h2>
<p>With <code>trigger_prediction</code> (the default), <code>doStep(t, h)</code> knows the ego at t only (its inputs)
and predicts its path over the step from its pose, velocity, acceleration and yaw rate. Every trigger (an event
distance, a BRK threshold or stop, a closure time, a contact, a departure, the run's end) is located on that path
(to 1e-9 s) and fires there; <code>last_event_time</code> is its instant, and the outputs at t + h show what fired.
In a master stepping at a fixed h, an event thus takes effect at the first communication point at or after its
instant; an instant within 1e-9 relative after a communication point (rounding: masters form their clocks
differently) counts as that point's. The prediction's error over one step is at most (a jump of the ego's
acceleration inside the step) x h<sup>2</sup> / 2 in position, so an instant is located within that distance divided by the closing speed of the
trigger; only an event whose true instant lies that close to a communication point can fall on the neighbouring
one. FMI 3.0: an importer that allows early return gets <code>fmi3DoStep</code> back at the instant of the first
event (<code>earlyReturn</code>, <code>lastSuccessfulTime</code>) and can synchronise every FMU there. Without
prediction, everything is evaluated at the communication points with the ego's inputs there (for a master that
steps to the trigger instants itself, or the replay of a recorded run).</p>

<h2>Events</h2>
<p>The counters <code>events</code> and <code>collisions</code> count as summary.json does (one event per A spawn,
maneuver, collision and despawn, BRK on and off, RSA lane setting, the end); <code>last_event_code</code>,
<code>last_event_action</code>, <code>last_event_vehicle</code>, <code>last_event_line</code> and
<code>last_event_time</code> identify the last one; each event is also one log line through the FMI logger,
category <code>logEvents</code> (switch it on with SetDebugLogging). <code>ended</code> becomes true at ES or the
run's end (until_distance, until_time, 1000 ft past the last event, 3600 s): FMI 2.0 reports it through
<code>fmi2GetBooleanStatus(fmi2Terminated)</code>, FMI 3.0 as <code>terminateSimulation</code>; the FMU steps on
after it (nothing fires, traffic keeps moving).</p>

<h2>Variables</h2>
<h3>Inputs</h3>
{_table(interface, INPUT, True)}
<h3>Outputs</h3>
{_table(interface, OUTPUT, False)}
<h3>Parameters</h3>
{_table(interface, PARAMETER, True)}

<h2>Using it with fmpy</h2>
<p>The scenario FMU beside the shipped Simple ego FMU, stepped by a fixed-step master written out (an SSP master
does the same from the SSP's connections):</p>
<pre>{html.escape(example)}</pre>
<p><code>sources/</code> holds every C file of the binary and <code>sources/buildDescription.xml</code> lists them;
one compiler line, run in the unzipped FMU, rebuilds it:</p>
<pre>{html.escape(compile_line)}</pre>
</body>
</html>
"""
