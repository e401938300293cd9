"""documentation/index.html and documentation/licenses/ of an FMU, generated from the same interface data,
variable table and model description (the dynamics module's docstring) as the FMU itself."""

from __future__ import annotations

import html
import json
from importlib import resources
from pathlib import Path

from .. import __version__
from ..interface import INPUT, OUTPUT, PARAMETER, Interface
from ..paths import MODEL_DESCRIPTION_DIRECTORY
from .codegen import TableEntry
from .xml import COPYRIGHT, LICENSE, entry_description, entry_unit

LICENSE_FILE = Path(str(resources.files(__package__) / "LICENSE.txt"))  # package data; equal to ./LICENSE
DOCUMENTATION = "documentation/index.html"
LICENSE_ENTRY = "documentation/licenses/license.txt"  # FMI's entry point of the licence information

# what the sources/ folder holds under other licences than the project's
THIRD_PARTY = ("\n\nThird-party files in this FMU\n-----------------------------\n"
               "sources/fmi2*.h, sources/fmi3*.h: the FMI standard's headers, Copyright (C) Modelica Association "
               "Project FMI and the MODELISAR consortium, 2-Clause BSD License (the licence text is in each "
               "header).\n")

STYLE = """body { font-family: sans-serif; max-width: 75em; margin: 1em auto; padding: 0 1em; line-height: 1.4 }
table { border-collapse: collapse; font-size: 90% } td, th { border: 1px solid #ccc; padding: 2px 6px;
text-align: left; vertical-align: top } th { background: #eee } pre { background: #f6f6f6; padding: 0.6em;
overflow-x: auto } code { background: #f6f6f6 }"""


def license_text() -> str:
    """documentation/licenses/license.txt: the project's licence, then the third-party files' licences."""
    return LICENSE_FILE.read_text(encoding="utf-8").rstrip("\n") + THIRD_PARTY


def references(model_name: str) -> list[str]:
    """The literature a model is built on (the "references" of its interface data)."""
    data = json.loads((MODEL_DESCRIPTION_DIRECTORY / f"{model_name}.json").read_text(encoding="utf-8"))
    return data.get("references", [])


def _number(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return f"{float(value):.6g}"


def _variable_rows(rows: list[tuple[int, TableEntry]], table, interface, with_start: bool) -> str:
    head = "<tr><th>name</th><th>value reference</th><th>type</th><th>unit</th>"
    head += "<th>start</th><th>min</th><th>max</th>" if with_start else ""
    head += "<th>description</th></tr>"
    body = []
    for reference, entry in rows:
        v = entry.variable
        cells = [f"<code>{html.escape(entry.name)}</code>", str(reference), v.type if v else "Real",
                 html.escape(entry_unit(entry, table, interface) or "")]
        if with_start:
            cells += [_number(v.start), _number(v.min), _number(v.max)]
        cells.append(html.escape(entry_description(entry, table)))
        body.append("<tr>" + "".join(f"<td>{cell}</td>" for cell in cells) + "</tr>")
    return f"<table>\n{head}\n" + "\n".join(body) + "\n</table>"


def _usage(interface: Interface, fmi_version: int, linux: str, windows: str, sources: list[str]) -> str:
    """How to run the FMU on its own with fmpy, with this model's input names and start values."""
    model = interface.model_name
    inputs = interface.of_role(INPUT)
    columns = ", ".join(f'("{v.name}", {"float" if v.type == "Real" else "int"})' for v in inputs)
    start = ", ".join(_number(v.start) for v in inputs)
    stop = interface.default_experiment.get("stopTime", 10.0)
    outputs = ", ".join(f'"{name}"' for name in interface.names(OUTPUT)[:4])
    compile_line = (f"cc -std=c99 -O2 -fPIC -shared -Isources {' '.join(f'sources/{s}' for s in sources)} "
                    f"-o {model}.so -lm")
    example = f"""import numpy as np
from fmpy import simulate_fmu

# every input at its start value from t = 0 on (the rows are time points; edit them to drive the vehicle)
inputs = np.array([(0.0, {start}), ({_number(stop)}, {start})],
                  dtype=[("time", float), {columns}])
result = simulate_fmu("{model}.fmu", fmi_type="CoSimulation", input=inputs, stop_time={_number(stop)},
                      start_values={{"v0": 20.0}}, output=[{outputs}])
print(result[-1])"""
    return f"""<p>The FMU is self-contained: FMI {fmi_version}.0 for Co-Simulation (its own error-controlled solver
with event location) and for Model Exchange, with binaries for Linux (<code>binaries/{linux}/</code>) and, when it
was built with mingw-w64, Windows (<code>binaries/{windows}/</code>). Any FMI {fmi_version}.0 importer loads it
(fmpy, OMSimulator, libcosim, ecos, FMU containers, a C host); it needs neither Python nor CasADi. Inputs hold
their values between communication points; parameters are set before initialization, each within its declared
min/max (a value outside is refused with an error status and a log message). With
<a href="https://github.com/CATIA-Systems/FMPy">fmpy</a>:</p>
<pre>{html.escape(example)}</pre>
<p><code>sources/</code> holds every C file of the binary and <code>sources/buildDescription.xml</code> lists them:
one compiler line, run in the unzipped FMU, rebuilds the binary (here for Linux; mingw-w64 or MSVC likewise):</p>
<pre>{html.escape(compile_line)}</pre>"""


def index_html(interface: Interface, table: list[TableEntry], fmi_version: int, equations: str,
               linux: str, windows: str, sources: list[str]) -> str:
    """documentation/index.html of one FMU."""
    model = interface.model_name
    numbered = list(enumerate(table, start=1))
    groups = [
        ("Inputs", [r for r in numbered if r[1].variable is not None and r[1].variable.role == INPUT], True),
        ("Outputs", [r for r in numbered if r[1].variable is not None and r[1].variable.causality == "output"],
         False),
        ("Parameters", [r for r in numbered if r[1].variable is not None and r[1].variable.role == PARAMETER],
         True),
        ("Local variables: internal states, derivatives, event indicators",
         [r for r in numbered if r[1].variable is None or r[1].variable.causality == "local"], False),
    ]
    sections = "\n".join(f"<h3>{title} ({len(rows)})</h3>\n{_variable_rows(rows, table, interface, start)}"
                         for title, rows, start in groups)
    listed = "\n".join(f"<li>{html.escape(reference)}</li>" for reference in references(model))
    experiment = ", ".join(f"{key} {_number(value)}" for key, value in interface.default_experiment.items())
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{model}</title>
<style>{STYLE}</style>
</head>
<body>
<h1>{model}</h1>
<p>{html.escape(interface.description)}</p>
<p>FMI {fmi_version}.0, model version {__version__}, generated by sdl-fmu {__version__} from the model's CasADi
equations. {html.escape(COPYRIGHT)}; licence: {LICENSE} (<a href="licenses/license.txt">licenses/license.txt</a>).
Default experiment: {experiment}.</p>

<h2>Using the FMU on its own</h2>
{_usage(interface, fmi_version, linux, windows, sources)}

<h2>Variables</h2>
<p>SI units inside the FMU; the unit definitions offer display units (ft, ft/s, km/h, deg) to FMI tools. Axes
follow ISO 8855: x forward, y left, z up, yaw counter-clockwise. The value references are those of the
modelDescription.xml.</p>
{sections}

<h2>Equations</h2>
<pre>{html.escape(equations.strip())}</pre>

<h2>References</h2>
<ul>
{listed}
</ul>
</body>
</html>
"""
