"""The FMUs as FMI tool users expect them (as the Reference-FMUs ship theirs): fmpy validate finds no problem,
every variable has a description and every physical one its unit (der(...) included), the modelDescription
names author, version, copyright and licence, and documentation/ holds an index.html generated from the
interface data, whose example runs, and the licence text."""

import html
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

import sdl_fmu
from sdl_fmu.fmu.documentation import DOCUMENTATION, LICENSE_ENTRY

ROOT = Path(__file__).resolve().parents[2]
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


@pytest.fixture(params=[2, 3], ids=["fmi2", "fmi3"])
def fmu(request, ego_fmus):
    """Each shipped model's FMU in each FMI version."""
    return ego_fmus[request.param]


def test_fmpy_validate_reports_no_problem(fmu):
    assert validate_fmu(str(fmu)) == []


def _base(definition) -> dict:
    base = definition.baseUnit
    return {name: getattr(base, name) for name in BASE_UNITS if base is not None and getattr(base, name)}


def test_every_variable_has_a_description_and_every_real_one_its_unit(fmu):
    description = read_model_description(str(fmu))
    units = {unit.name: unit for unit in description.unitDefinitions}
    indicators = {f"event_indicator_{k}" for k in range(1, 6)}
    unitless = []
    for variable in description.modelVariables:
        assert variable.description, f"{variable.name} has no description"
        if variable.type not in ("Real", "Float64") or variable.causality == "independent" and variable.unit:
            continue
        if variable.unit is None:
            unitless.append(variable.name)
            continue
        assert variable.unit in units, f"{variable.name}: unit {variable.unit} is not defined"
        if variable.derivative is not None:  # der(v): v's base units divided by s
            state = _base(units[variable.derivative.unit])
            state["s"] = state.get("s", 0) - 1
            assert _base(units[variable.unit]) == {k: e for k, e in state.items() if e}, variable.name
    # only the event indicators have none: their sign is what counts, their magnitude mixes units between modes
    assert set(unitless) == indicators
    assert all("only its sign is meaningful" in v.description for v in description.modelVariables
               if v.name in indicators)
    assert sum(v.derivative is not None for v in description.modelVariables) in (7, 13)  # every der(...) checked


def test_model_description_names_author_version_copyright_and_licence(fmu):
    description = read_model_description(str(fmu))
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert description.author == project["authors"][0]["name"]
    assert description.version == sdl_fmu.__version__ == project["version"]
    assert description.license == project["license"]["text"] == "MIT"
    assert description.copyright.startswith("Copyright (c) ") and description.author in description.copyright


def _documentation(fmu) -> str:
    with zipfile.ZipFile(fmu) as archive:
        return archive.read(DOCUMENTATION).decode()


def test_documentation_lists_every_variable_with_its_unit_equations_and_references(fmu):
    text = _documentation(fmu)
    description = read_model_description(str(fmu))
    rows = {}
    for row in re.findall(r"<tr>(.*?)</tr>", text):
        cells = [html.unescape(re.sub(r"<[^>]+>", "", cell)) for cell in re.findall(r"<td>(.*?)</td>", row)]
        if cells:
            rows[cells[0]] = cells
    variables = [v for v in description.modelVariables if v.causality != "independent"]
    assert set(rows) == {v.name for v in variables}
    for variable in variables:
        name, reference, _, unit, *_, text_description = rows[variable.name]
        assert int(reference) == variable.valueReference
        assert unit == (variable.unit or "") and text_description == variable.description
    model = description.modelName
    module = "advanced" if "Advanced" in model else "simple"
    docstring = __import__(f"sdl_fmu.dynamics.{module}", fromlist=["_"]).__doc__.strip().splitlines()[0]
    assert html.escape(docstring) in text  # the equations: the model module's own description
    assert "ISO 8855:2011" in text and ("Pacejka" in text) == (module == "advanced")
    assert 'href="licenses/license.txt"' in text


def test_licence_text_is_the_projects(fmu):
    licence = (ROOT / "LICENSE").read_text()
    assert licence.startswith("MIT License") and (ROOT / "sdl_fmu/fmu/LICENSE.txt").read_text() == licence
    with zipfile.ZipFile(fmu) as archive:
        shipped = archive.read(LICENSE_ENTRY).decode()
    assert shipped.startswith(licence.rstrip("\n")) and "2-Clause BSD" in shipped  # and the FMI headers'


@pytest.mark.parametrize("ego_fmus, version", [("simple", 2), ("advanced", 3)], indirect=["ego_fmus"])
def test_the_documented_example_runs_as_written(ego_fmus, version, tmp_path):
    fmu = ego_fmus[version]
    example = next(html.unescape(block) for block in re.findall(r"<pre>(.*?)</pre>", _documentation(fmu), re.S)
                   if "simulate_fmu" in block)
    shutil.copy(fmu, tmp_path / fmu.name)
    (tmp_path / "example.py").write_text(example)
    completed = subprocess.run([sys.executable, "example.py"], cwd=tmp_path, capture_output=True, text=True,
                               timeout=600)
    assert completed.returncode == 0, completed.stderr
    # the last row: (time, v, ...). Every input at its start (no throttle, no brake) from v0 = 20 m/s: the
    # vehicle coasts, slowed by rolling resistance f_r g = 0.012 * 9.80665 = 0.1177 m/s2 and drag
    # rho CdA v^2 / (2 m) = 1.225 * 0.7 / 3000 * v^2 (0.1143 m/s2 at 20 m/s, 0.0893 at 17.68 m/s).
    # At most 0.1177 + 0.1143 = 0.232 m/s2 for 10 s: v >= 17.68. At least 0.1177 + 0.0893 = 0.207 m/s2,
    # divided by the Advanced model's effective mass factor 1 + 4 I_w / (m R^2) = 1 + 4 / (1500 * 0.09)
    # = 1.0296 (the spinning wheels): 0.201 m/s2, so v <= 17.99.
    last = completed.stdout.strip().strip("()").split(",")
    time, speed = float(last[0]), float(last[1])
    assert time == pytest.approx(10.0) and 17.68 <= speed <= 17.99
