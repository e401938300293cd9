"""The vehicle table: SDL model numbers -> name and footprint (m), used to place and collide traffic."""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path

from .events import ApproachingVehicle, Scenario
from .parser import SdlError

COLUMNS = ("model", "name", "length_m", "width_m")


@dataclass(frozen=True)
class VehicleModel:
    """One row of the vehicle table: a model number, its name and its footprint in metres."""

    number: int
    name: str
    length: float
    width: float


def default_vehicle_table_path() -> Path:
    """The table shipped with the scenarios: sdl_fmu/scenarios/vehicles.csv."""
    from ..interface import SCENARIO_DIRECTORY

    return SCENARIO_DIRECTORY / "vehicles.csv"


def _positive(text: str) -> float:
    value = float(text)
    if not math.isfinite(value) or value <= 0:
        raise ValueError
    return value


def load_vehicle_table(path: str | os.PathLike) -> dict[int, VehicleModel]:
    """Read a vehicle table CSV; raises ValueError listing every bad row as 'file:line: field: reason'."""
    name = os.fspath(path)
    try:
        with open(name, newline="", encoding="utf-8-sig") as file:
            rows = list(csv.reader(file))
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{name}:0: file: cannot be read: {getattr(exc, 'strerror', None) or exc}") from exc
    if not rows or tuple(cell.strip() for cell in rows[0]) != COLUMNS:
        raise ValueError(f"{name}:1: header: expected '{','.join(COLUMNS)}'")

    table: dict[int, VehicleModel] = {}
    errors: list[str] = []
    for line, row in enumerate(rows[1:], start=2):
        cells = [cell.strip() for cell in row]
        if not any(cells):
            continue
        if len(cells) != len(COLUMNS):
            errors.append(f"{name}:{line}: row: expected {len(COLUMNS)} fields ({','.join(COLUMNS)}), got {len(cells)}")
            continue
        number_text, model_name, length_text, width_text = cells
        row_errors = []
        number = int(number_text) if number_text.isdigit() else 0
        if number < 1:
            row_errors.append(f"{name}:{line}: model: '{number_text}' must be a whole number >= 1")
        elif number in table:
            row_errors.append(f"{name}:{line}: model: {number} is listed twice")
        if not model_name:
            row_errors.append(f"{name}:{line}: name: empty")
        sizes = []
        for column, text in (("length_m", length_text), ("width_m", width_text)):
            try:
                sizes.append(_positive(text))
            except ValueError:
                row_errors.append(f"{name}:{line}: {column}: '{text}' must be a number of metres > 0")
        errors.extend(row_errors)
        if not row_errors:
            table[number] = VehicleModel(number, model_name, *sizes)
    if not table and not errors:
        errors.append(f"{name}:1: table: no vehicles listed")
    if errors:
        raise ValueError("\n".join(errors))
    return table


def _ranges(numbers: list[int]) -> str:
    """Sorted numbers as compact ranges, e.g. '1-8, 10'."""
    parts, start = [], None
    for index, number in enumerate(numbers):
        if start is None:
            start = number
        if index + 1 == len(numbers) or numbers[index + 1] != number + 1:
            parts.append(str(start) if start == number else f"{start}-{number}")
            start = None
    return ", ".join(parts)


def check_models(scenario: Scenario, table: dict[int, VehicleModel]) -> list[SdlError]:
    """Every model an A event could use (fixed, or anywhere in its random range) must be in the table."""
    errors = []
    known = f"the vehicle table has models {_ranges(sorted(table))}"
    for event in scenario.events:
        if not isinstance(event, ApproachingVehicle):
            continue
        model = event.model
        missing = [n for n in range(model.low, model.high + 1) if n not in table]
        if not missing:
            continue
        if model.is_random:
            reason = f"'*{model.low}~{model.high}': models {_ranges(missing)} are not in the table; {known}"
        else:
            reason = f"model {model.low} is not in the table; {known}"
        errors.append(SdlError(scenario.path, event.line, "A parameter 4 (model)", reason))
    return errors
