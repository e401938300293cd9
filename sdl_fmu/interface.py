"""FMU interfaces as data: reads modelDescription/<Model>.json, the one source of variable names,
causalities, units, start values and descriptions (the XML, the C variable table and the CasADi symbols
are all generated from it).

An entry of "variables" may also be a repeated group, for families of identical variables:
    {"repeat": {"placeholder": "slot", "count": 8}, "variables": [<variable templates>]}
expands in place to count copies of the templates (copy 0 first), with "{slot}" in names and
descriptions replaced by the copy number. Start values that only exist at build time (e.g. read from
data files) are left out of the JSON and passed to load_interface(..., starts={name: value}).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from .paths import MODEL_DESCRIPTION_DIRECTORY

# as FMPy's model_description.py types them (the values the interfaces use)
Causality = Literal["parameter", "calculatedParameter", "input", "output", "local", "independent"]
Variability = Literal["constant", "fixed", "tunable", "discrete", "continuous"]
FmiType = Literal["Real", "Integer", "Boolean"]  # FMI 2.0's names; the FMI 3.0 XML writes Float64, Int32, Boolean
# roles: where a variable lives in the model function arguments (x, d, u, p) or results (y)
Role = Literal["state", "discrete", "input", "parameter", "output"]
STATE: Role = "state"
DISCRETE: Role = "discrete"
INPUT: Role = "input"
PARAMETER: Role = "parameter"
OUTPUT: Role = "output"


@dataclass(frozen=True)
class Variable:
    name: str
    causality: Causality
    type: FmiType
    role: Role
    index: int  # position within its role's vector
    unit: str | None = None
    start: float | None = None
    min: float | None = None
    max: float | None = None
    nominal: float | None = None
    variability: Variability = "continuous"
    description: str = ""


@dataclass
class Interface:
    model_name: str
    description: str
    default_experiment: dict
    variables: list[Variable]
    units: dict = field(default_factory=dict)

    def of_role(self, role: Role) -> list[Variable]:
        return [v for v in self.variables if v.role == role]

    def names(self, role: Role) -> list[str]:
        return [v.name for v in self.of_role(role)]

    def variable(self, name: str) -> Variable:
        for v in self.variables:
            if v.name == name:
                return v
        raise KeyError(f"{self.model_name} has no variable {name!r}")


def _role(entry: dict) -> Role:
    if entry.get("state"):
        return STATE
    if entry.get("discrete_state"):
        return DISCRETE
    if entry["causality"] == "input":
        return INPUT
    if entry["causality"] == "parameter":
        return PARAMETER
    return OUTPUT


def _variability(entry: dict, role: Role, type_: FmiType) -> Variability:
    if role == PARAMETER:
        return entry.get("variability", "fixed")
    if type_ != "Real" or role == DISCRETE:
        return "discrete"
    return "continuous"


def load_units(directory: Path = MODEL_DESCRIPTION_DIRECTORY) -> dict:
    return json.loads((directory / "units.json").read_text())["units"]


def _expand_repeats(model: str, entries: list) -> list[dict]:
    """The variable entries with every repeated group expanded in place."""
    expanded = []
    for entry in entries:
        if "repeat" not in entry:
            expanded.append(entry)
            continue
        repeat = entry["repeat"]
        placeholder, count = "{" + repeat["placeholder"] + "}", repeat["count"]
        if not isinstance(count, int) or count < 0:
            raise ValueError(f"{model}: repeated group count {count!r} must be a whole number >= 0")
        for template in entry["variables"]:
            if placeholder not in template["name"]:
                raise ValueError(f"{model}: repeated variable {template['name']!r} lacks {placeholder} in its name")
        for copy in range(count):
            for template in entry["variables"]:
                variable = dict(template)
                for key in ("name", "description"):
                    if key in variable:
                        variable[key] = variable[key].replace(placeholder, str(copy))
                expanded.append(variable)
    return expanded


def parse_interface(data: dict, units: dict, starts: dict[str, float] | None = None) -> Interface:
    """Builds an Interface from its JSON data, checking what the generators rely on.

    starts: start values given at build time, by variable name; they override the JSON's."""
    counters: dict[str, int] = {}
    variables = []
    seen = set()
    entries = _expand_repeats(data["modelName"], data["variables"])
    if starts:
        unknown = sorted(set(starts) - {entry["name"] for entry in entries})
        if unknown:
            raise ValueError(f"{data['modelName']}: start values given for unknown variables {unknown[:5]}")
        entries = [{**entry, "start": starts[entry["name"]]} if entry["name"] in starts else entry
                   for entry in entries]
    for entry in entries:
        name = entry["name"]
        if name in seen:
            raise ValueError(f"{data['modelName']}: variable {name!r} is declared twice")
        seen.add(name)
        type_ = entry.get("type", "Real")
        role = _role(entry)
        unit = entry.get("unit")
        if type_ == "Real" and unit is None:
            raise ValueError(f"{data['modelName']}: Real variable {name!r} has no unit")
        if unit is not None and unit not in units:
            raise ValueError(f"{data['modelName']}: variable {name!r} has unit {unit!r}, not in units.json")
        if role in (INPUT, PARAMETER) and "start" not in entry:
            raise ValueError(f"{data['modelName']}: {role} {name!r} needs a start value "
                             "(in the JSON, or given at build time through starts=)")
        index = counters.get(role, 0)
        counters[role] = index + 1
        variables.append(
            Variable(
                name=name,
                causality=entry["causality"],
                type=type_,
                role=role,
                index=index,
                unit=unit,
                start=entry.get("start"),
                min=entry.get("min"),
                max=entry.get("max"),
                nominal=entry.get("nominal"),
                variability=_variability(entry, role, type_),
                description=entry.get("description", ""),
            )
        )
    return Interface(
        model_name=data["modelName"],
        description=data.get("description", ""),
        default_experiment=data.get("defaultExperiment", {}),
        variables=variables,
        units=units,
    )


def load_interface(model_name: str, directory: Path = MODEL_DESCRIPTION_DIRECTORY,
                   starts: dict[str, float] | None = None) -> Interface:
    """The interface of one FMU, e.g. load_interface('EgoVehicleSimple'); starts: build-time start values."""
    path = directory / f"{model_name}.json"
    if not path.exists():
        raise FileNotFoundError(f"{path} not found: no interface data for model {model_name!r}")
    return parse_interface(json.loads(path.read_text()), load_units(directory), starts)
