"""The vehicle table: SDL model numbers -> name and footprint (m), used to place and collide traffic."""

from __future__ import annotations

import bisect
import csv
import math
import re
import os
from dataclasses import dataclass
from pathlib import Path

from ..paths import VEHICLE_TABLE
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
    """The table shipped with the scenarios: scenarios/vehicles.csv."""
    return VEHICLE_TABLE


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
        number = int(number_text) if re.fullmatch(r"[0-9]{1,18}", number_text) else 0  # ASCII digits only
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
    return ", ".join(str(low) if low == high else f"{low}-{high}" for low, high in _runs(numbers))


def _runs(numbers: list[int]) -> list[tuple[int, int]]:
    """Sorted numbers as (first, last) of each run of consecutive ones."""
    runs: list[tuple[int, int]] = []
    for number in numbers:
        if runs and runs[-1][1] + 1 == number:
            runs[-1] = (runs[-1][0], number)
        else:
            runs.append((number, number))
    return runs


def missing_models(low: int, high: int, known: list[int]) -> list[tuple[int, int]]:
    """The (first, last) stretches of low..high that are not in `known` (sorted model numbers): arithmetic on
    the table's runs, never a list of the range, so '*1~99999999999999999999' costs what '*1~8' does."""
    gaps, position = [], low
    for first, last in _runs(known[bisect.bisect_left(known, low):bisect.bisect_right(known, high)]):
        if first > position:
            gaps.append((position, first - 1))
        position = last + 1
    if position <= high:
        gaps.append((position, high))
    return gaps


def check_models(scenario: Scenario, table: dict[int, VehicleModel]) -> list[SdlError]:
    """Every model an A event could use (fixed, or anywhere in its random range) must be in the table."""
    errors = []
    numbers = sorted(table)
    known = f"the vehicle table has models {_ranges(numbers)}"
    for event in scenario.events:
        if not isinstance(event, ApproachingVehicle):
            continue
        model = event.model
        missing = missing_models(model.low, model.high, numbers)
        if not missing:
            continue
        if model.is_random:
            shown = ", ".join(str(a) if a == b else f"{a}-{b}" for a, b in missing)
            reason = f"'*{model.low}~{model.high}': models {shown} are not in the table; {known}"
        else:
            reason = f"model {model.low} is not in the table; {known}"
        errors.append(SdlError(scenario.path, event.line, "A parameter 4 (model)", reason))
    return errors
