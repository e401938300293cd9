"""Tire data files, read on both sides: TNO/MF-Tyre `.tir` property files and Tire Attribute Files, and the Magic
Formula coefficients a tire slot holds. The build side (dynamics/tires.py) takes the Advanced FMU's slot start values
from them; the run side (vehicle/) fills the tire slots of a vehicle whose map declares `tire_slots` (`--tires`).
Nothing here imports the rest of the package but paths.py.

A tire slot is one set of the coefficients in SLOT_COEFFICIENTS, as FMU parameters named by the slot rule
`slot_parameter(prefix, slot, key)`: the prefix (a vehicle map's `tire_slots`, e.g. "tire{slot}_") with the slot
number, then the key (tire3_PDX1). An FMU with slots uses slot = attribute for 0 <= attribute < its slot count and
slot 0 (standard tires) for any other number.

slot_values(attribute_file, slot_count) turns a Tire Attribute File into the slots' coefficients: attribute k fills
slot k; slots whose attribute has no entry hold a copy of attribute 0 (standard tires), and attributes >= slot_count
cannot be represented (warning; they fall back to attribute 0 too).

Subset of the .tir format read (MF 5.2 / 6.1 names; everything else in the file is ignored):
  [UNITS]                      LENGTH, FORCE, ANGLE must be SI (meter, newton, radian) when given
  [VERTICAL]                   FNOMIN
  [DIMENSION]                  UNLOADED_RADIUS (read for information; the vehicle's wheel_radius is used)
  [LONGITUDINAL_COEFFICIENTS]  PCX1 PDX1 PDX2 PEX1 PEX2 PEX3 PKX1 PKX2 PKX3 RBX1 RBX2 RCX1 REX1 REX2
  [LATERAL_COEFFICIENTS]       PCY1 PDY1 PDY2 PEY1 PEY2 PKY1 PKY2 RBY1 RBY2 RBY3 RCY1 REY1 REY2
  [SCALING_COEFFICIENTS]       LFZO LMUX LMUY LKX LKY LXAL LYKA
Syntax: `[SECTION]` headers, `KEY = value` lines, `$` and `!` start comments (outside quotes), values are
numbers (Fortran `D` exponents accepted) or quoted/bare strings; lines that are not `KEY = value` are
allowed only in sections the model does not read (e.g. the [SHAPE] table).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from .paths import TIRE_DIRECTORY

DEFAULT_ATTRIBUTE_FILE = TIRE_DIRECTORY / "attributes.txt"

_LONGITUDINAL, _LATERAL, _SCALING = "LONGITUDINAL_COEFFICIENTS", "LATERAL_COEFFICIENTS", "SCALING_COEFFICIENTS"
REQUIRED = None  # marks a coefficient without a default: the file must give it


@dataclass(frozen=True)
class Coefficient:
    """One Magic Formula coefficient of a slot: where it lives in a .tir file and its default."""

    key: str
    section: str
    default: float | None  # REQUIRED (None): the file must give it


# The slot layout: order and names of the tire<slot>_<KEY> parameters (modelDescription JSON lists the same).
# Defaults follow MF-Tyre: missing shape/shift terms are 0, missing scaling factors are 1.
SLOT_COEFFICIENTS = (
    Coefficient("FNOMIN", "VERTICAL", REQUIRED),
    Coefficient("PCX1", _LONGITUDINAL, REQUIRED),
    Coefficient("PDX1", _LONGITUDINAL, REQUIRED),
    Coefficient("PDX2", _LONGITUDINAL, 0.0),
    Coefficient("PEX1", _LONGITUDINAL, 0.0),
    Coefficient("PEX2", _LONGITUDINAL, 0.0),
    Coefficient("PEX3", _LONGITUDINAL, 0.0),
    Coefficient("PKX1", _LONGITUDINAL, REQUIRED),
    Coefficient("PKX2", _LONGITUDINAL, 0.0),
    Coefficient("PKX3", _LONGITUDINAL, 0.0),
    Coefficient("RBX1", _LONGITUDINAL, REQUIRED),
    Coefficient("RBX2", _LONGITUDINAL, 0.0),
    Coefficient("RCX1", _LONGITUDINAL, REQUIRED),
    Coefficient("REX1", _LONGITUDINAL, 0.0),
    Coefficient("REX2", _LONGITUDINAL, 0.0),
    Coefficient("PCY1", _LATERAL, REQUIRED),
    Coefficient("PDY1", _LATERAL, REQUIRED),
    Coefficient("PDY2", _LATERAL, 0.0),
    Coefficient("PEY1", _LATERAL, 0.0),
    Coefficient("PEY2", _LATERAL, 0.0),
    Coefficient("PKY1", _LATERAL, REQUIRED),
    Coefficient("PKY2", _LATERAL, REQUIRED),
    Coefficient("RBY1", _LATERAL, REQUIRED),
    Coefficient("RBY2", _LATERAL, 0.0),
    Coefficient("RBY3", _LATERAL, 0.0),
    Coefficient("RCY1", _LATERAL, REQUIRED),
    Coefficient("REY1", _LATERAL, 0.0),
    Coefficient("REY2", _LATERAL, 0.0),
    Coefficient("LFZO", _SCALING, 1.0),
    Coefficient("LMUX", _SCALING, 1.0),
    Coefficient("LMUY", _SCALING, 1.0),
    Coefficient("LKX", _SCALING, 1.0),
    Coefficient("LKY", _SCALING, 1.0),
    Coefficient("LXAL", _SCALING, 1.0),
    Coefficient("LYKA", _SCALING, 1.0),
)
SLOT_KEYS = tuple(c.key for c in SLOT_COEFFICIENTS)
# Coefficients that must be > 0 (they divide, or a zero makes the model meaningless)
_POSITIVE = ("FNOMIN", "PCX1", "PCY1", "LFZO")
_NONZERO = ("PDX1", "PDY1", "PKY2")
_NONNEGATIVE = ("LMUX", "LMUY", "LKX", "LKY", "LXAL", "LYKA")
_SI_UNITS = {"LENGTH": {"meter", "meters", "metre", "metres", "m"}, "FORCE": {"newton", "newtons", "n"},
             "ANGLE": {"radian", "radians", "rad"}}


class TireFileError(ValueError):
    """A tire or Tire Attribute File cannot be used; names the file, line and key (or field)."""

    def __init__(self, path: Path | str, line: int | None, key: str, reason: str):
        self.path, self.line, self.key, self.reason = str(path), line, key, reason
        where = f"{self.path}:{line}" if line else self.path
        super().__init__(f"{where}: {key}: {reason}")


@dataclass(frozen=True)
class Entry:
    """One KEY = value of a .tir file, with its line number."""

    value: float | str
    line: int


@dataclass(frozen=True)
class TireFile:
    """A parsed .tir file: section -> key -> Entry (section and key names upper case)."""

    path: Path
    sections: dict

    def number(self, section: str, key: str, default: float | None = REQUIRED) -> float:
        """A numeric value; the default when absent, or an error naming the file if it is required."""
        entry = self.sections.get(section, {}).get(key)
        if entry is None:
            elsewhere = [name for name, keys in self.sections.items() if key in keys]
            if elsewhere:
                line = self.sections[elsewhere[0]][key].line
                raise TireFileError(self.path, line, key, f"found in [{elsewhere[0]}], expected in [{section}]")
            if default is REQUIRED:
                raise TireFileError(self.path, None, key, f"missing; the tire model needs it in [{section}]")
            return default
        if isinstance(entry.value, str):
            raise TireFileError(self.path, entry.line, key, f"'{entry.value}' is not a number")
        return entry.value


@dataclass(frozen=True)
class AttributeEntry:
    """One line `<attribute number> = <tire file>` of a Tire Attribute File."""

    attribute: int
    tire_file: Path
    line: int


_SECTION = re.compile(r"\[\s*([A-Za-z0-9_]+)\s*\]")
_KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eEdD][+-]?\d+)?")
# sections whose lines must all be KEY = value (the ones the model reads)
_READ_SECTIONS = {"UNITS", "VERTICAL", "DIMENSION", _LONGITUDINAL, _LATERAL, _SCALING}


def _strip_comment(text: str, markers: tuple[str, ...]) -> str:
    """The text before the first comment marker that is not inside quotes."""
    quote = None
    i = 0
    while i < len(text):
        char = text[i]
        if quote:
            if char == quote:
                quote = None
        elif char in "'\"":
            quote = char
        elif any(text.startswith(marker, i) for marker in markers):
            return text[:i]
        i += 1
    return text


def _value(text: str, path: Path, line: int, key: str) -> float | str:
    text = text.strip()
    if text == "":
        raise TireFileError(path, line, key, "no value after '='")
    if text[0] in "'\"":
        if len(text) < 2 or text[-1] != text[0]:
            raise TireFileError(path, line, key, f"unterminated string {text}")
        return text[1:-1]
    if _NUMBER.fullmatch(text):
        return float(text.replace("D", "E").replace("d", "e"))
    if re.search(r"\s", text) or not re.fullmatch(r"[A-Za-z0-9_.+-]+", text):
        raise TireFileError(path, line, key, f"'{text}' is neither a number nor a string")
    return text


def parse_tir(text: str, path: Path | str = "<text>") -> TireFile:
    """Parses .tir text (see the module docstring for the subset and syntax)."""
    path = Path(path)
    sections: dict[str, dict[str, Entry]] = {}
    current = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = _strip_comment(raw, ("$", "!")).strip()
        if not line:
            continue
        header = _SECTION.fullmatch(line)
        if header:
            current = header.group(1).upper()
            sections.setdefault(current, {})
            continue
        key, equals, rest = line.partition("=")
        key = key.strip()
        if not equals or not _KEY.fullmatch(key):
            if current is None or current in _READ_SECTIONS:
                where = f"[{current}]" if current else "before the first [SECTION]"
                raise TireFileError(path, number, key or line, f"expected KEY = value in {where}: {line!r}")
            continue  # tables of sections the model does not read, e.g. [SHAPE]
        if current is None:
            raise TireFileError(path, number, key, "KEY = value before the first [SECTION] header")
        key = key.upper()
        if key in sections[current]:
            raise TireFileError(path, number, key,
                                f"given twice in [{current}] (first on line {sections[current][key].line})")
        sections[current][key] = Entry(_value(rest, path, number, key), number)
    tire = TireFile(path, sections)
    for key, allowed in _SI_UNITS.items():
        entry = sections.get("UNITS", {}).get(key)
        if entry is not None and str(entry.value).strip().lower() not in allowed:
            raise TireFileError(path, entry.line, key,
                                f"unit '{entry.value}' is not supported; the model reads SI ({sorted(allowed)[0]})")
    return tire


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8", errors="replace")
    except OSError as error:
        raise TireFileError(path, None, "file", f"cannot be read: {error.strerror or error}") from None


def read_tir(path: Path | str) -> TireFile:
    """Reads a .tir property file."""
    path = Path(path)
    return parse_tir(_read_text(path), path)


def mf_coefficients(tire: TireFile) -> dict[str, float]:
    """The slot coefficients (SLOT_KEYS) of a tire file, with MF-Tyre defaults, checked for usability."""
    values = {c.key: tire.number(c.section, c.key, c.default) for c in SLOT_COEFFICIENTS}
    sections = {c.key: c.section for c in SLOT_COEFFICIENTS}

    def fail(key: str, reason: str):
        entry = tire.sections.get(sections[key], {}).get(key)
        raise TireFileError(tire.path, entry.line if entry else None, key, reason)

    for key in _POSITIVE:
        if not values[key] > 0:
            fail(key, f"{values[key]} must be > 0")
    for key in _NONZERO:
        if values[key] == 0:
            fail(key, "must not be 0")
    for key in _NONNEGATIVE:
        if values[key] < 0:
            fail(key, f"{values[key]} must be >= 0")
    return values


def parse_attribute_file(text: str, path: Path | str = "<text>") -> list[AttributeEntry]:
    """Parses a Tire Attribute File: `<attribute number> = <tire file>` per line, `//` or `#` comments;
    relative tire paths are resolved from the attribute file's folder."""
    path = Path(path)
    folder = path.parent
    entries: list[AttributeEntry] = []
    seen: dict[int, int] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = _strip_comment(raw, ("//", "#")).strip()
        if not line:
            continue
        left, equals, right = line.partition("=")
        left, right = left.strip(), right.strip()
        if not equals:
            raise TireFileError(path, number, "line", f"expected '<attribute number> = <tire file>', got {line!r}")
        if not re.fullmatch(r"[+-]?\d+", left):
            raise TireFileError(path, number, "attribute number", f"'{left}' is not a whole number")
        attribute = int(left)
        if attribute < 0:
            raise TireFileError(path, number, "attribute number", f"{attribute} must be >= 0")
        if attribute in seen:
            raise TireFileError(path, number, "attribute number",
                                f"{attribute} is given twice (first on line {seen[attribute]})")
        if len(right) >= 2 and right[0] == right[-1] and right[0] in "'\"":
            right = right[1:-1].strip()
        if not right:
            raise TireFileError(path, number, "tire file", "missing after '='")
        tire_file = Path(right).expanduser()
        if not tire_file.is_absolute():
            tire_file = folder / tire_file
        seen[attribute] = number
        entries.append(AttributeEntry(attribute, tire_file, number))
    return entries


def read_attribute_file(path: Path | str) -> list[AttributeEntry]:
    """Reads a Tire Attribute File (see parse_attribute_file)."""
    path = Path(path)
    return parse_attribute_file(_read_text(path), path)


def default_attribute_file() -> Path:
    """The shipped Tire Attribute File (scenarios/tires/attributes.txt), which the Advanced FMU's slot defaults come
    from."""
    return DEFAULT_ATTRIBUTE_FILE


def slot_parameter(prefix: str, slot: int, key: str) -> str:
    """The FMU parameter of one coefficient of one slot: the rule every side names slots by (prefix "tire{slot}_",
    slot 3, key PDX1: tire3_PDX1)."""
    return prefix.format(slot=slot) + key


def slot_values(attribute_file: Path | str,
                slot_count: int) -> tuple[list[dict[str, float]], dict[int, int], list[str]]:
    """The coefficients (SLOT_KEYS) of each of `slot_count` tire slots from a Tire Attribute File.

    Returns (per slot its coefficients, attribute -> slot for every attribute the file defines and the slots can
    represent, warnings). Slots without an attribute entry hold attribute 0's tire; a file without attribute 0 gets
    the shipped standard tire (warning)."""
    attribute_file = Path(attribute_file)
    warnings: list[str] = []
    cache: dict[Path, dict[str, float]] = {}

    def coefficients(entry: AttributeEntry, source: Path) -> dict[str, float]:
        key = entry.tire_file.resolve()
        if key not in cache:
            if not entry.tire_file.is_file():
                raise TireFileError(source, entry.line, "tire file", f"{entry.tire_file} does not exist")
            try:
                cache[key] = mf_coefficients(read_tir(entry.tire_file))
            except TireFileError as error:
                raise TireFileError(error.path, error.line, error.key,
                                    f"{error.reason} (tire of attribute {entry.attribute}, {source}:{entry.line})"
                                    ) from None
        return cache[key]

    by_attribute: dict[int, dict[str, float]] = {}
    for entry in read_attribute_file(attribute_file):
        if entry.attribute >= slot_count:
            warnings.append(f"{Path(attribute_file).name}:{entry.line}: attribute {entry.attribute} is beyond the "
                            f"FMU's {slot_count} tire slots (0..{slot_count - 1}); surfaces with attribute "
                            f"{entry.attribute} use attribute 0 (standard tires)")
            continue
        by_attribute[entry.attribute] = coefficients(entry, attribute_file)
    if 0 not in by_attribute:
        standard = next(e for e in read_attribute_file(DEFAULT_ATTRIBUTE_FILE) if e.attribute == 0)
        by_attribute[0] = coefficients(standard, DEFAULT_ATTRIBUTE_FILE)
        warnings.append(f"{Path(attribute_file).name}: no attribute 0 (standard tires); using the shipped standard "
                        f"tire {Path(standard.tire_file).name}")  # file names: a result names no path of the machine
    slots = [by_attribute.get(slot, by_attribute[0]) for slot in range(slot_count)]
    return slots, {attribute: attribute for attribute in sorted(by_attribute)}, warnings
