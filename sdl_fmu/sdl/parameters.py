"""Scenario parameters (docs/scenarios.md, Parameters): what varies in a scenario file, by name or by address.

- By name: a comment line `// @param NAME = VALUE [UNIT] [in LOW..HIGH]` declares NAME (any SDL reader takes the line
  for a comment), and `$NAME` (or `${NAME}`; `*$NAME` keeps the `*`) in any numeric field of an event uses it.
- By address, with no change to the file: `LINE.N` is parameter N of the event on line LINE (0: its distance);
  `rsa.LINE` every value of the RSA event on that line, `rsa.LINE.LANE` the value of one lane.

The substitution is textual and happens before a field is read (Substitution.line, called by the parser for every
event line it reads), so a value is held to the field's own limits by the field's own parser, its error names the
file, line, field and the parameter, and the substituted text is plain SDL that any reader runs (`resolve`). This
module knows the text only; what a field is (its label, unit, whether it is whole) is the parser's."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Mapping

from .events import Parameter

NAME = r"[A-Za-z_][A-Za-z0-9_]*"
NUMBER = r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"  # the parser's numbers
UNITS = ("ft", "m", "ft/s", "m/s", "s", "%")  # the units a field of this format is in
DECLARATION_FORM = "// @param NAME = VALUE [UNIT] [in LOW..HIGH]"
_DECLARATION = re.compile(rf"\s*@param\b\s*(?P<body>.*)")
_BODY = re.compile(rf"(?P<name>{NAME})\s*=\s*(?P<value>{NUMBER})(?:\s+(?P<unit>(?!in\s)\S+))?"
                   rf"(?:\s+in\s+(?P<low>{NUMBER})\s*\.\.\s*(?P<high>{NUMBER}))?\s*")
_USE = re.compile(rf"\$(?:\{{({NAME})\}}|({NAME}))")
_ADDRESS = re.compile(r"([0-9]{1,9})\.([0-9]{1,3})")
_RSA_ADDRESS = re.compile(r"rsa\.([0-9]{1,9})(?:\.([+-]?[0-9]{1,4}))?")


class ParameterError(ValueError):
    """A value set for a scenario that is no mistake of the file: an unknown name, a value that is no finite number,
    one parameter set twice. `name` is the name as given; the message is one line."""

    def __init__(self, name: str, message: str):
        self.name = name
        super().__init__(message)


@dataclass(frozen=True)
class Address:
    """A place in the file: parameter `index` of the event on `line` (0: its distance), or (`rsa`) the values of the
    RSA event on `line`, all lanes or lane `lane`."""

    text: str
    line: int
    index: int | None = None
    rsa: bool = False
    lane: int | None = None


def address(name: str) -> Address | None:
    """The Address that `name` spells (`12.3`, `rsa.4`, `rsa.4.-1`), else None."""
    match = _ADDRESS.fullmatch(name)
    if match:
        return Address(name, int(match[1]), index=int(match[2]))
    match = _RSA_ADDRESS.fullmatch(name)
    if match:
        return Address(name, int(match[1]), rsa=True, lane=None if match[2] is None else int(match[2]))
    return None


def parameter_name(name: str) -> str | None:
    """The declared name that `name` spells (`gap` or `$gap`), else None."""
    bare = name[1:] if name.startswith("$") else name
    return bare if re.fullmatch(NAME, bare) else None


def value_text(value: float) -> str:
    """A value as it is written into a field: a whole number without a point (so that whole fields take it), else the
    shortest text that reads back as the same double."""
    value = float(value)
    if value.is_integer() and abs(value) < 2**53:
        return str(int(value))
    return repr(value)


def _number(value) -> float | None:
    if isinstance(value, bool):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


@dataclass
class _Declared:
    name: str
    default: float
    unit: str | None
    low: float | None
    high: float | None
    line: int
    uses: list[tuple[int, str]] = field(default_factory=list)
    whole: bool = True


@dataclass
class Note:
    """How one field of a line was substituted: the names it used (declared or not) or the address that set it, and
    the text it was given."""

    text: str
    names: list[str] = field(default_factory=list)
    undeclared: list[str] = field(default_factory=list)
    address: str | None = None

    def describe(self, values: Mapping[str, float]) -> str:
        if self.address is not None:
            return f"address {self.address} = {self.text}"
        return ", ".join(f"${name} = {value_text(values[name])}" for name in self.names if name in values)


class Substitution:
    """The parameters of one scenario text and the values set for it: `problems` of the declarations (line, field,
    reason), the values in effect, and per event line (line()) the substituted field texts. ParameterError for a
    value that names nothing the text could have (an unknown name) or is no finite number."""

    def __init__(self, lines: list[tuple[int, str]], values: Mapping[str, float] | None = None, path: str = ""):
        """lines: (number, comment text after '//') of every line holding a comment that starts with @param."""
        self.problems: list[tuple[int, str, str]] = []
        self.declared: dict[str, _Declared] = {}
        for number, comment in lines:
            self._declare(number, comment)
        self.values = {name: declared.default for name, declared in self.declared.items()}
        self.addresses: dict[tuple[int, int], tuple[str, float]] = {}  # (line, index) -> (address, value)
        self.rsa: dict[int, list[tuple[Address, float]]] = {}
        self.applied: set[str] = set()
        self.resolved: dict[int, str] = {}  # line -> its event text with every value substituted
        given: dict[str, str] = {}
        for name, value in (values or {}).items():
            number = _number(value)
            if number is None:
                raise ParameterError(name, f"{name}={value!r}: the value must be a finite number (in the file's units)")
            place = address(name)
            if place is not None:
                if place.rsa:
                    self.rsa.setdefault(place.line, []).append((place, number))
                else:
                    key = (place.line, place.index)
                    if key in self.addresses:
                        raise ParameterError(name, f"{name}: address {self.addresses[key][0]} is the same field")
                    self.addresses[key] = (name, number)
                continue
            bare = parameter_name(name)
            if bare is None or bare not in self.declared:
                declared = ", ".join(self.declared) or "none"
                raise ParameterError(name, f"{name}: {path or 'the scenario'} declares no parameter "
                                           f"{bare or name!r} (declared: {declared}); an address is LINE.N "
                                           "(parameter N of the event on line LINE, 0 its distance) or "
                                           "rsa.LINE[.LANE]")
            if bare in given:
                raise ParameterError(name, f"{name}: set twice ({given[bare]} and {name})")
            given[bare] = name
            declared = self.declared[bare]
            if not _inside(number, declared):
                self.problems.append((declared.line, f"@param {bare}", f"{value_text(number)} (set) is outside its "
                                      f"range {_range_text(declared)}"))
            self.values[bare] = number
        self.address_lines = {line for line, _ in self.addresses} | set(self.rsa)

    def _declare(self, number: int, comment: str) -> None:
        body = _DECLARATION.match(comment)["body"]
        match = _BODY.fullmatch(body)
        if not match:
            self.problems.append((number, "@param", f"'{body[:40]}': expected '{DECLARATION_FORM}'"))
            return
        name, unit = match["name"], match["unit"]
        if name in self.declared:
            self.problems.append((number, f"@param {name}", f"declared twice (first on line "
                                                            f"{self.declared[name].line})"))
            return
        if unit is not None and unit not in UNITS:
            self.problems.append((number, f"@param {name}", f"unit {unit!r} is not a unit of this format's fields "
                                  f"({', '.join(UNITS)}; lengths and speeds in the file's units)"))
            return
        values = [float(match[key]) if match[key] is not None else None for key in ("value", "low", "high")]
        if any(value is not None and not math.isfinite(value) for value in values):
            self.problems.append((number, f"@param {name}", "a number is too large"))
            return
        default, low, high = values
        declared = _Declared(name, default, unit, low, high, number)
        if low is not None and low > high:
            self.problems.append((number, f"@param {name}", f"range {_range_text(declared)}: low end above high end"))
            return
        if not _inside(default, declared):
            self.problems.append((number, f"@param {name}", f"{match['value']} is outside its range "
                                                            f"{_range_text(declared)}"))
        self.declared[name] = declared

    def line(self, number: int, content: str, code: str, texts: list[str]
             ) -> tuple[list[str], dict[int, Note], list[tuple[str, str]]]:
        """An event line's field texts (distance, then the parameters) with the values substituted: (texts, notes per
        substituted field index, (field, reason) of addresses that do not fit the line)."""
        if "$" not in content and number not in self.address_lines:
            return texts, {}, []
        texts, notes, problems = list(texts), {}, []
        for index, text in enumerate(texts):
            if "$" in text:
                note = Note("")

                def substituted(match: re.Match) -> str:
                    name = match[1] or match[2]
                    if name not in self.declared:
                        note.undeclared.append(name)
                        return match[0]
                    note.names.append(name)
                    return value_text(self.values[name])

                note.text = texts[index] = _USE.sub(substituted, text)
                if note.names or note.undeclared:
                    notes[index] = note
        for (line, index), (name, value) in self.addresses.items():
            if line != number:
                continue
            self.applied.add(name)
            if index >= len(texts):
                problems.append((f"address {name}", f"the {code} event on line {line} has {len(texts) - 1} "
                                                    f"parameters ({line}.0 is its distance)"))
                continue
            texts[index] = _in_form(texts[index], value)
            notes[index] = Note(texts[index], address=name)
        for place, value in self.rsa.get(number, ()):
            self.applied.add(place.text)
            if code != "RSA":
                problems.append((f"address {place.text}", f"line {number} is not an RSA event (it is {code})"))
                continue
            lanes = [(index, texts[index].lstrip("+")) for index in range(1, len(texts) - 1, 2)]
            hits = [index + 1 for index, lane in lanes
                    if place.lane is None or (re.fullmatch(r"-?[0-9]+", lane) and int(lane) == place.lane)]
            if not hits:
                problems.append((f"address {place.text}", f"the RSA event on line {number} does not set lane "
                                                          f"{place.lane}"))
            for index in hits:
                texts[index] = value_text(value)
                notes[index] = Note(texts[index], address=place.text)
        return texts, notes, problems

    def used(self, name: str, line: int, label: str, whole: bool) -> None:
        declared = self.declared[name]
        declared.uses.append((line, label))
        declared.whole = declared.whole and whole

    def unit_problem(self, name: str, unit: str | None) -> str | None:
        """Why parameter `name` cannot be used in a field whose unit is `unit` (None: a number without a unit), or
        None when it can: a declared unit must be the field's own (a unit checks, never converts)."""
        declared = self.declared[name].unit
        if declared is None or declared == unit:
            return None
        if unit is None:
            return f"${name} is declared in {declared} (line {self.declared[name].line}), but this field has no unit"
        return (f"${name} is declared in {declared} (line {self.declared[name].line}), but this field is in {unit} "
                "(a declared unit is checked against the field's, never converted)")

    def unapplied(self) -> list[tuple[int, str, str]]:
        """Addresses whose line held no event the parser read: (line, field, reason)."""
        names = [(line, name) for (line, _), (name, _) in self.addresses.items()]
        names += [(place.line, place.text) for places in self.rsa.values() for place, _ in places]
        return [(line, f"address {name}", f"line {line} holds no event sdl-fmu reads (blank, a comment, a units "
                                          "line, a skipped line, or beyond the end of the file)")
                for line, name in names if name not in self.applied]

    def parameters(self) -> tuple[Parameter, ...]:
        return tuple(Parameter(d.name, self.values[d.name], d.default, d.unit, d.low, d.high, d.line,
                               tuple(d.uses), d.whole and bool(d.uses)) for d in self.declared.values())

    def unused(self) -> list[str]:
        return [f"line {d.line}: @param {d.name} is declared but no field uses ${d.name}"
                for d in self.declared.values() if not d.uses]


def _inside(value: float, declared: _Declared) -> bool:
    return declared.low is None or declared.low <= value <= declared.high


def _range_text(declared: _Declared) -> str:
    return f"{value_text(declared.low)}..{value_text(declared.high)}"


def _in_form(text: str, value: float) -> str:
    """An address's value in the form of the field it replaces: a leading `*` (relative to the ego) and a closure
    time's F/B suffix stay; a model range `*lo~hi` becomes the one model."""
    shown = value_text(value)
    if "~" in text:
        return shown
    prefix = "*" if text.startswith("*") else ""
    suffix = text[-1] if text[-1:] in ("F", "f", "B", "b") else ""
    return f"{prefix}{shown}{suffix}"


def declaration_lines(text: str) -> list[tuple[int, str]]:
    """(line, comment text) of every line whose comment starts with @param; [] at once for a text without one."""
    if "@param" not in text:
        return []
    found = []
    for number, raw in enumerate(text.replace("\r\n", "\n").replace("\r", "\n").split("\n"), start=1):
        head, separator, comment = raw.partition("//")
        if separator and _DECLARATION.match(comment):
            found.append((number, comment.rstrip("\r")))
    return found


def resolved_text(text: str, substitution: Substitution) -> str:
    """`text` (its line endings made \\n) with every substituted event line written out and every declaration made a
    plain comment that records the value used; one line for each line, so line numbers stay."""
    lines = text.split("\n")
    for number, content in substitution.resolved.items():
        raw = lines[number - 1]
        _, separator, comment = raw.partition("//")
        lines[number - 1] = content + (f" //{comment}" if separator else "")
    for name, declared in substitution.declared.items():
        raw = lines[declared.line - 1]
        head, _, comment = raw.partition("//")
        value = substitution.values[name]
        unit = f" {declared.unit}" if declared.unit else ""
        lines[declared.line - 1] = (f"{head}// resolved parameter {name} = {value_text(value)}{unit} "
                                    f"(was: {comment.strip()})")
    return "\n".join(lines)
