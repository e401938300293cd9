"""SDL scenario text -> typed events in SI, reporting every problem in the file at once."""

from __future__ import annotations

import dataclasses
import functools
import io
import math
import os
import re
from dataclasses import dataclass
from typing import Callable

from ..units import ENGLISH, METRIC, Units, from_si, length_label, speed_label, to_si
from .events import (
    BRAKE_THRESHOLDS,
    DEFAULT_ROAD,
    LEFT_SHOULDER,
    RIGHT_SHOULDER,
    SUPPORTED_CODES,
    Action,
    ApproachingVehicle,
    Brake,
    ClosureTrigger,
    EndOfScenario,
    Event,
    ModelChoice,
    Relative,
    Road,
    Scenario,
    Source,
    SurfaceAttribute,
)
from .parameters import ParameterError, Substitution, address, declaration_lines, parameter_name, resolved_text


@dataclass(frozen=True)
class SdlError:
    """One problem in a scenario file, located by line and field."""

    path: str
    line: int
    field: str
    reason: str

    def __str__(self) -> str:
        where = f"{self.path}:{self.line}" if self.line else self.path  # line 0: the file as a whole
        return f"{where}: {self.field}: {self.reason}"


class ScenarioError(Exception):
    """A scenario file could not be used; carries every problem found, one per line of the message."""

    def __init__(self, errors: list[SdlError]):
        self.errors = list(errors)
        super().__init__("\n".join(str(error) for error in self.errors))


class _Invalid(Exception):
    """A field's text is unacceptable; the message is the reason."""


Report = Callable[[str, str], None]

# Only ASCII digits are digits: [0-9], never \d (which also matches '１', '٣', ...).
_CODE = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
# What real STISIM files also hold, read so that --skip-unsupported can skip it: long-form event names
# ('Crash Settings'), labels ('Pedestrian#5'), and settings lines ('Config_Start_Y = 0{0}').
_LONG_CODE = re.compile(r"([A-Za-z][A-Za-z0-9_]*(?:[ \t]+[A-Za-z0-9_]+)*)(?:#([0-9]+))?")
_SETTING = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)\s*=(?!=)")
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_WHOLE = re.compile(r"[+-]?[0-9]+")
_CLOSURE = re.compile(rf"({_NUMBER.pattern})\s*([FfBb]?)")
_MODEL_RANGE = re.compile(r"\*\s*([+-]?[0-9]+)\s*~\s*([+-]?[0-9]+)")
_UNITS_HEADERS = {"english": ENGLISH, "metric": METRIC}

_A_FIELDS = ("speed", "gap", "lateral position", "model")
_ACTION_FIELDS = ("closure time", "lateral position", "speed", "transition time")
_BRK_FIELDS = ("pedal %", "threshold type", "magnitude")
_ROAD_FIELDS = ("lane width", "lanes", "lanes right of the dividing line")


# --- limits of the format (README, Scenarios): checked on the text, before anything grows with it ----

MAX_NUMBER_CHARS = 32  # characters of one number (sign, digits, point and exponent): 17 digits make a double
MAX_SHOWN_CHARS = 40  # a field longer than this is shown shortened in an error
MAX_LENGTH = 1.0e6  # m: every distance, gap, lateral position and BRK distance (the longest run is 540 km)
MAX_SPEED = 1.0e3  # m/s: every speed (A speeds, *-offsets, the BRK speed thresholds)
MAX_DURATION = 1.0e6  # s: closure and transition times, the BRK time threshold (a run lasts at most 3600 s)
MAX_LANE_WIDTH = 100.0  # m
MAX_LANES_PER_SIDE = RIGHT_SHOULDER - 1  # lanes 1..100 and -1..-100: the numbers +-101 are the shoulders
MAX_LANES = 2 * MAX_LANES_PER_SIDE  # ROAD lanes, both sides together
MAX_SURFACE_VALUE = 1000.0  # RSA value: 10 x mu (Simple) or a surface attribute number (Advanced)
_LIMITS = {"length": MAX_LENGTH, "speed": MAX_SPEED, "time": MAX_DURATION}


def _shown(text: str) -> str:
    """A field's text quoted for an error line, shortened when long (a 1 MB field is not echoed whole)."""
    if len(text) <= MAX_SHOWN_CHARS:
        return f"'{text}'"
    return f"'{text[:MAX_SHOWN_CHARS - 8]}...{text[-5:]}' ({len(text)} characters)"


def _short_enough(text: str) -> None:
    if len(text) > MAX_NUMBER_CHARS:
        raise _Invalid(f"{_shown(text)} is longer than {MAX_NUMBER_CHARS} characters, the longest number this "
                       "format reads")


def _limit_text(kind: str, units: Units) -> str:
    if kind == "time":
        return f"{MAX_DURATION:g} s"
    label = length_label(units) if kind == "length" else speed_label(units)
    return f"{from_si(_LIMITS[kind], units):.7g} {label}"


# --- field parsers: text -> value, or _Invalid(reason) -------------------------------------------
# The parsers of single fields are pure functions of the text, memoised (a bounded cache; failures are not
# cached): the same text in many lines of a long file gives one shared immutable value, not one each.

SHARED_VALUES = 256  # per field parser, the most recent distinct texts whose values are shared


def _shared(parse: Callable) -> Callable:
    return functools.lru_cache(maxsize=SHARED_VALUES)(parse)


@_shared
def _plain_number(text: str) -> float:
    """A field holding a plain decimal number (no '*'), parsed."""
    if text == "":
        raise _Invalid("empty; expected a number")
    _short_enough(text)
    if text.startswith("*"):
        raise _Invalid(f"{_shown(text)}: '*' (relative to the ego) is not allowed here; expected a plain number")
    if not _NUMBER.fullmatch(text):
        raise _Invalid(f"{_shown(text)} is not a number")
    value = float(text)
    if not math.isfinite(value):
        raise _Invalid(f"{_shown(text)} is too large")
    return value


def _whole(text: str) -> int:
    """A whole number written without a decimal point (at most MAX_NUMBER_CHARS characters)."""
    _short_enough(text)
    if not _WHOLE.fullmatch(text):
        _plain_number(text)  # the more specific reason when it is not a number at all
        raise _Invalid(f"{_shown(text)} is not a whole number")
    return int(text)


def _within(value: float, kind: str, units: Units, text: str) -> float:
    """value (SI) if its magnitude is within the format's limit for its kind, else _Invalid."""
    if abs(value) > _LIMITS[kind]:
        raise _Invalid(f"{_shown(text)} is beyond the format's limit of {_limit_text(kind, units)} in magnitude")
    return value


@_shared
def _quantity(text: str, units: Units, kind: str) -> float:
    """A plain number that is a length, speed (converted to SI) or time, within the format's limit."""
    value = _plain_number(text)
    return _within(value if kind == "time" else to_si(value, units), kind, units, text)


@_shared
def _relative(text: str, units: Units, kind: str) -> Relative:
    """A distance or speed, '*' meaning the ego's current value plus this one."""
    if text == "":
        raise _Invalid("empty; expected a number or '*number'")
    _short_enough(text)
    relative = text.startswith("*")
    body = text[1:].strip() if relative else text
    if not _NUMBER.fullmatch(body):
        raise _Invalid(f"{_shown(text)} is not a number or '*number' (relative to the ego)")
    return Relative(_within(to_si(_plain_number(body), units), kind, units, text), relative)


@_shared
def _model_choice(text: str) -> ModelChoice:
    """A model number, or '*lo~hi' for one drawn uniformly from lo..hi."""
    if text.startswith("*"):
        match = _MODEL_RANGE.fullmatch(text)
        if not match:
            raise _Invalid(f"{_shown(text)}: expected a model number or a random range '*low~high' such as '*1~8'")
        _short_enough(match[1])
        _short_enough(match[2])
        low, high = int(match[1]), int(match[2])
        if low < 1:
            raise _Invalid(f"{_shown(text)}: model numbers start at 1, low end is {low}")
        if low > high:
            raise _Invalid(f"{_shown(text)}: low end {low} is above high end {high}")
        return ModelChoice(low, high)
    try:
        model = _whole(text)
    except _Invalid as exc:
        raise _Invalid(f"{exc}; expected a model number or a random range '*low~high' such as '*1~8'") from exc
    if model < 1:
        raise _Invalid(f"model {model}: model numbers start at 1")
    return ModelChoice(model, model)


@_shared
def _closure_trigger(text: str) -> ClosureTrigger:
    """Closure time in s, optionally suffixed F (vehicle in front only) or B (behind only)."""
    _short_enough(text)
    match = _CLOSURE.fullmatch(text)
    if not match:
        if text == "" or text.startswith("*"):
            _plain_number(text)  # the reason for an empty or relative field
        raise _Invalid(f"{_shown(text)}: expected seconds with an optional F or B suffix, such as 10, -5 or 10F")
    seconds = _within(_plain_number(match[1]), "time", ENGLISH, text)
    # A zero closure time could never be met by a finite gap, so the action would never fire.
    if seconds == 0:
        raise _Invalid(f"{_shown(text)}: closure time 0 can never fire; use > 0 (closing) or < 0 (separating)")
    return ClosureTrigger(seconds, match[2].upper() or None)


@_shared
def _settings(texts: tuple[str, ...], settings: tuple) -> tuple:
    """RSA settings, one tuple shared by every line whose parameter texts are the same."""
    return settings


def _checked(report: Report, field: str, parse: Callable, *args):
    """Run one field parser; on failure report it under `field` and return None."""
    try:
        return parse(*args)
    except _Invalid as exc:
        report(field, str(exc))
        return None


def _at_least(value: float | None, low: float, report: Report, field: str, text: str, strict: bool = False):
    """Check a parsed value against a lower bound; None when it fails (or was already bad)."""
    if value is None:
        return None
    if value < low or (strict and value == low):
        report(field, f"{_shown(text)} must be {'>' if strict else '>='} {low:g}")
        return None
    return value


def _at_most(value: float | None, high: float, report: Report, field: str, text: str, shown_high: str):
    """Check a parsed value against the format's upper bound; None when it fails (or was already bad)."""
    if value is None:
        return None
    if value > high:
        report(field, f"{_shown(text)} is beyond the format's limit of {shown_high}")
        return None
    return value


# --- events: parameters -> typed event, or None after reporting ----------------------------------


def _a_field(number: int) -> str:
    if number <= 4:
        return f"A parameter {number} ({_A_FIELDS[number - 1]})"
    action = (number - 5) // 4 + 1
    return f"A parameter {number} (action {action} {_ACTION_FIELDS[(number - 5) % 4]})"


def _approaching_vehicle(line: int, distance: float, params: list[str], units: Units, report: Report):
    """A: speed, gap, lateral, model, then 0..5 sets of (closure time, lateral, speed, transition time)."""
    if len(params) < 4 or len(params) > 24 or len(params) % 4:
        report("A parameters", "A takes 4 parameters plus 0 to 5 action sets of 4 (4, 8, 12, 16, 20 or 24 "
               f"parameters); got {len(params)}")
        return None
    speed = _checked(report, _a_field(1), _relative, params[0], units, "speed")
    gap = _checked(report, _a_field(2), _quantity, params[1], units, "length")
    # A zero gap would put the vehicle on top of the ego; negative means behind it.
    if gap == 0:
        report(_a_field(2), f"{_shown(params[1])}: the vehicle cannot appear at gap 0; use > 0 ahead or < 0 behind")
        gap = None
    lateral = _checked(report, _a_field(3), _relative, params[2], units, "length")
    model = _checked(report, _a_field(4), _model_choice, params[3])
    actions = []
    for first in range(5, len(params) + 1, 4):
        trigger_text, lateral_text, speed_text, duration_text = params[first - 1:first + 3]
        trigger = _checked(report, _a_field(first), _closure_trigger, trigger_text)
        # The STISIM text calls this a move relative to the vehicle's own position, but its worked example
        # (*0 = into the driver's lane, -6 = back into its own lane) only works as a roadway position.
        action_lateral = _checked(report, _a_field(first + 1), _relative, lateral_text, units, "length")
        action_speed = _checked(report, _a_field(first + 2), _relative, speed_text, units, "speed")
        duration = _checked(report, _a_field(first + 3), _quantity, duration_text, units, "time")
        duration = _at_least(duration, 0, report, _a_field(first + 3), duration_text)
        actions.append((trigger, action_lateral, action_speed, duration))
    fields = [speed, gap, lateral, model, *(part for action in actions for part in action)]
    if any(part is None for part in fields):
        return None
    return ApproachingVehicle(
        line=line, distance=distance, speed=speed, gap=gap, lateral=lateral, model=model,
        actions=tuple(Action(trigger, lat, spd, dur) for trigger, lat, spd, dur in actions),
    )


def _brake(line: int, distance: float, params: list[str], units: Units, report: Report):
    """BRK: pedal %, threshold type 0..3, magnitude (s, distance or speed)."""
    if len(params) != 3:
        report("BRK parameters", f"BRK takes 3 parameters (pedal %, threshold type, magnitude); got {len(params)}")
        return None
    field = [f"BRK parameter {n} ({name})" for n, name in enumerate(_BRK_FIELDS, start=1)]
    pedal = _checked(report, field[0], _plain_number, params[0])
    if pedal is not None and not 0 <= pedal <= 100:
        report(field[0], f"{_shown(params[0])} must be a percentage from 0 to 100")
        pedal = None
    threshold = _checked(report, field[1], _whole, params[1])
    if threshold is not None and not 0 <= threshold < len(BRAKE_THRESHOLDS):
        report(field[1], f"{_shown(params[1])} must be 0 (time), 1 (distance), 2 (velocity) or 3 (relative velocity)")
        threshold = None
    name = BRAKE_THRESHOLDS[threshold] if threshold is not None else "time"
    kind = {"time": "time", "distance": "length"}.get(name, "speed")
    magnitude = _checked(report, field[2], _quantity, params[2], units, kind)
    magnitude = _at_least(magnitude, 0, report, field[2], params[2], strict=True)
    if pedal is None or threshold is None or magnitude is None:
        return None
    return Brake(line=line, distance=distance, pedal=pedal / 100, threshold=name, magnitude=magnitude)


def _surface_attribute(line: int, distance: float, params: list[str], units: Units, report: Report):
    """RSA: (lane, value) pairs; lanes are checked against the road once the whole file is read."""
    if not params or len(params) % 2:
        report("RSA parameters", f"RSA takes pairs of (lane, value), at least one pair; got {len(params)} parameters")
        return None
    settings, lanes, ok = [], set(), True
    for first in range(1, len(params), 2):
        lane_field, value_field = f"RSA parameter {first} (lane)", f"RSA parameter {first + 1} (value)"
        lane = _checked(report, lane_field, _whole, params[first - 1])
        if lane is not None and lane in lanes:
            # Two values for one lane in one event would be ambiguous, so it is an error.
            report(lane_field, f"lane {lane} is set twice in this event")
            lane = None
        lanes.add(lane)
        value = _checked(report, value_field, _plain_number, params[first])
        value = _at_least(value, 0, report, value_field, params[first])
        value = _at_most(value, MAX_SURFACE_VALUE, report, value_field, params[first], f"{MAX_SURFACE_VALUE:g}")
        ok = ok and lane is not None and value is not None
        settings.append((lane, value))
    return SurfaceAttribute(line=line, distance=distance, settings=_settings(tuple(params), tuple(settings))) if ok \
        else None


def _road(line: int, distance: float, params: list[str], units: Units, report: Report):
    """ROAD: lane width, number of lanes, lanes right of the dividing line."""
    if len(params) != 3:
        report("ROAD parameters", "ROAD takes 3 parameters (lane width, lanes, lanes right of the dividing line); "
               f"got {len(params)}")
        return None
    field = [f"ROAD parameter {n} ({name})" for n, name in enumerate(_ROAD_FIELDS, start=1)]
    width = _checked(report, field[0], _plain_number, params[0])
    width = _at_least(width, 0, report, field[0], params[0], strict=True)
    width = _at_most(width, from_si(MAX_LANE_WIDTH, units), report, field[0], params[0],
                     f"{from_si(MAX_LANE_WIDTH, units):.7g} {length_label(units)}")
    lanes = _checked(report, field[1], _whole, params[1])
    lanes = _at_least(lanes, 1, report, field[1], params[1])
    lanes = _at_most(lanes, MAX_LANES, report, field[1], params[1], f"{MAX_LANES} lanes")
    lanes_right = _checked(report, field[2], _whole, params[2])
    # The ego starts in the centre of lane 1, so lane 1 must exist.
    if lanes_right is not None and lanes is not None and not 1 <= lanes_right <= lanes:
        report(field[2], f"{_shown(params[2])} must be from 1 to the number of lanes ({lanes}): the ego starts in "
               "lane 1")
        lanes_right = None
    # Lane 101 would be the right shoulder's number, -101 the left's: at most 100 lanes on either side.
    if lanes_right is not None and lanes is not None and max(lanes_right, lanes - lanes_right) > MAX_LANES_PER_SIDE:
        report(field[2], f"{_shown(params[2])} leaves {max(lanes_right, lanes - lanes_right)} lanes on one side; at "
               f"most {MAX_LANES_PER_SIDE} (lane numbers {RIGHT_SHOULDER} and {LEFT_SHOULDER} are the shoulders)")
        lanes_right = None
    if width is None or lanes is None or lanes_right is None:
        return None
    return Road(line=line, distance=distance, lane_width=to_si(width, units), lanes=lanes, lanes_right=lanes_right)


def _end_of_scenario(line: int, distance: float, params: list[str], units: Units, report: Report):
    """ES: no parameters."""
    if params:
        report("ES parameters", f"ES takes no parameters; got {len(params)}")
        return None
    return EndOfScenario(line=line, distance=distance)


_EVENT_PARSERS = {
    "A": _approaching_vehicle,
    "BRK": _brake,
    "RSA": _surface_attribute,
    "ROAD": _road,
    "ES": _end_of_scenario,
}
assert tuple(_EVENT_PARSERS) == SUPPORTED_CODES


# --- the file ------------------------------------------------------------------------------------


def _content_lines(text: str):
    """(line number, text without comment) for every line that has content, read lazily."""
    text = text.removeprefix("\ufeff").replace("\r\n", "\n").replace("\r", "\n")
    for number, raw in enumerate(io.StringIO(text, newline="\n"), start=1):
        content = raw.split("//", 1)[0].strip()
        if content:
            yield number, content


def _lanes_text(road: Road) -> str:
    """The road's lane numbers in a few characters however many lanes it has: '1, 2, -1' or '1..5, -1..-5'."""
    parts = []
    for count, sign in ((road.lanes_right, 1), (road.lanes_left, -1)):
        if count:
            parts.append(", ".join(str(sign * k) for k in range(1, count + 1)) if count <= 3
                         else f"{sign}..{sign * count}")
    return ", ".join(parts)


def _lane_warnings(event: SurfaceAttribute, road: Road) -> list[str]:
    """RSA lanes that the road layout does not have: kept, but they never apply (docs/scenarios.md, Reading files)."""
    return [f"line {event.line}: RSA parameter {2 * index + 1} (lane): lane {lane} is not on the road (it has lanes "
            f"{_lanes_text(road)} and the shoulders {RIGHT_SHOULDER}, {LEFT_SHOULDER}): this setting never applies"
            for index, (lane, _value) in enumerate(event.settings) if not road.has_lane(lane)]


MAX_PARAMETERS = 2 * (MAX_LANES + 2)  # per event line: an RSA may set every lane and both shoulders
MAX_ERRORS = 100  # problems reported per file; reading stops after that many


class _TooManyErrors(Exception):
    pass


def _field_of(code: str, index: int, texts: list[str], units: Units) -> tuple[str, str | None, bool]:
    """(label as the event's parser names it, unit in the file's units or None, whole) of field `index` of an event
    line (0: its distance, then the parameters from 1); the unit is "?" where it cannot be told (a BRK magnitude whose
    threshold type is not 0..3)."""
    length, speed = length_label(units), speed_label(units)
    if index == 0:
        return "distance", length, False
    if code == "A" and index <= 24:
        if index <= 4:
            return _a_field(index), (speed, length, length, None)[index - 1], index == 4
        return _a_field(index), ("s", length, speed, "s")[(index - 5) % 4], False
    if code == "BRK" and index <= 3:
        threshold = texts[2].strip() if len(texts) > 2 else ""
        unit = ("%", None, {"0": "s", "1": length, "2": speed, "3": speed}.get(threshold, "?"))[index - 1]
        return f"BRK parameter {index} ({_BRK_FIELDS[index - 1]})", unit, index == 2
    if code == "RSA":
        return f"RSA parameter {index} ({'lane' if index % 2 else 'value'})", None, index % 2 == 1
    if code == "ROAD" and index <= 3:
        return f"ROAD parameter {index} ({_ROAD_FIELDS[index - 1]})", (length, None, None)[index - 1], index > 1
    return f"{code} parameter {index}", "?", False


def parse_text(text: str, path: str = "<text>", skip_unsupported: bool = False,
               values: dict[str, float] | None = None) -> Scenario:
    """Parse a whole SDL file's text; raises ScenarioError listing every problem (up to MAX_ERRORS).

    Events may appear in any order: they are returned in the order they take effect, by distance, file
    order breaking ties. skip_unsupported: every line sdl-fmu does not simulate (codes outside the supported
    set, long-form names such as 'Crash Settings', labelled events such as 'Pedestrian#5', events triggered
    by '@', 'Config_... = ...' settings) is skipped with one warning per code instead of being an error.
    values: scenario parameters set (sdl/parameters.py: declared names, `$NAME`, addresses `LINE.N`,
    `rsa.LINE[.LANE]`), in the file's units, each checked by the field it reaches; ParameterError for a name that is
    no parameter or a value that is no finite number."""
    return _parse(text, path, skip_unsupported, values)[0]


def _parse(text: str, path: str, skip_unsupported: bool, values: dict[str, float] | None
           ) -> tuple[Scenario, Substitution]:
    substitution = Substitution(declaration_lines(text), values, path)
    errors: list[SdlError] = [SdlError(path, *problem) for problem in substitution.problems]
    warnings: list[str] = []
    skipped: dict[str, tuple[str, list[int]]] = {}  # key -> (what is skipped, its lines)
    units, seen_content = ENGLISH, False
    placed: list[tuple[Event, str]] = []  # each event and its distance as written
    road: Road | None = None
    road_line: int | None = None  # line of the first ROAD, even a bad one
    road_failed = False
    end: EndOfScenario | None = None
    end_line: int | None = None
    supported = ", ".join(SUPPORTED_CODES)

    def skip(key: str, what: str, line: int) -> None:
        skipped.setdefault(key, (what, []))[1].append(line)

    try:
        for number, content in _content_lines(text):
            first, seen_content = not seen_content, True

            decorated: dict[str, str | None] = {}  # a substituted field's label -> the label naming its parameter

            def report(field: str, reason: str) -> None:
                shown = decorated.get(field, field)
                if shown is None:  # a field already reported for an undeclared $NAME
                    return
                errors.append(SdlError(path, number, shown, reason))
                if len(errors) >= MAX_ERRORS:
                    raise _TooManyErrors

            setting = _SETTING.match(content)  # 'Name = value' (the value may hold commas): never an event
            if setting:
                if skip_unsupported:
                    skip(f"={setting[1]}", f"settings line '{_shown(setting[1])[1:-1]} = ...'", number)
                else:
                    report("settings line", f"'{_shown(setting[1])[1:-1]} = ...' (a STISIM configuration "
                           "setting) is not simulated; --skip-unsupported runs the file without it")
                continue
            if "," not in content:
                if content.lower() in _UNITS_HEADERS:
                    if first:
                        units = _UNITS_HEADERS[content.lower()]
                    else:
                        report("units header", f"{_shown(content)} must be the first line that is not blank or a "
                               "comment")
                elif first and not _NUMBER.fullmatch(content):
                    report("units header", f"{_shown(content)} is not a units header; expected English or Metric, "
                           "or an event line '<distance>,<CODE>,<parameters>'")
                else:
                    report("event code", f"{_shown(content)} has no event code; expected "
                           "'<distance>,<CODE>,<parameters>'")
                continue

            head = content.split(",", 2)
            distance_text, code_text = head[0].strip(), head[1].strip()
            rest = head[2] if len(head) > 2 else None
            code = code_text.upper()
            parser = _EVENT_PARSERS.get(code)
            triggered = distance_text.startswith("@")

            if parser is None or triggered:
                long_form = _LONG_CODE.fullmatch(code_text)
                if long_form is None:
                    shown = _shown(code_text) if code_text else "empty"
                    report("event code", f"unsupported event code {shown} (supported: {supported})")
                    continue
                name, label = " ".join(long_form[1].split()), long_form[2]
                if label is not None and name.upper() in _EVENT_PARSERS:
                    report("event code", f"{_shown(code_text)}: a label ('#k') on {name.upper()} is not read; "
                           f"write {name.upper()} without it")
                    continue
                if triggered:
                    if skip_unsupported:
                        skip(f"@{name.upper()}", f"event '{name}' triggered by '@'", number)
                    else:
                        report("distance", f"{_shown(distance_text)}: events triggered by '@' are not simulated "
                               "(sdl-fmu fires events at a distance); --skip-unsupported runs the file without them")
                    continue
                if skip_unsupported:  # a long-form name is shown as first written, a code in capitals
                    skip(name.upper(), f"event code '{name if ' ' in name else name.upper()}'", number)
                else:
                    report("event code", f"unsupported event code {_shown(code_text)} (supported: {supported}); "
                           "--skip-unsupported runs the file without it")
                continue

            if rest is not None and rest.count(",") >= MAX_PARAMETERS:
                report(f"{code} parameters", f"{rest.count(',') + 1} parameters; the format allows at most "
                       f"{MAX_PARAMETERS} on one line")
                continue
            params = [field.strip() for field in rest.split(",")] if rest is not None else []
            if "$" in content or number in substitution.address_lines:
                texts, notes, problems = substitution.line(number, content, code, [distance_text, *params])
                for field, reason in problems:
                    report(field, reason)
                for index, note in notes.items():
                    label, unit, whole = _field_of(code, index, texts, units)
                    for name in note.names:
                        substitution.used(name, number, label, whole)
                        problem = None if unit == "?" else substitution.unit_problem(name, unit)
                        if problem is not None:
                            report(label, problem)
                    for name in note.undeclared:
                        report(label, f"${name} is not declared (declare it on a comment line: "
                                      f"// @param {name} = VALUE [UNIT] [in LOW..HIGH])")
                    described = f"{label}, from {note.describe(substitution.values)}"
                    decorated[label] = None if note.undeclared else described
                distance_text, params = texts[0], texts[1:]
                if notes:
                    substitution.resolved[number] = ",".join([distance_text, code_text, *params])

            distance = _checked(report, "distance", _quantity, distance_text, units, "length")
            distance = _at_least(distance, 0, report, "distance", distance_text)

            if code == "ES" and end_line is not None:
                report("event code", f"a second ES (the first is on line {end_line}); at most one ES is allowed")
            if code == "ROAD":
                if road_line is not None:
                    report("event code", f"a second ROAD (the first is on line {road_line}); "
                           "the road layout is fixed for the whole road, so at most one ROAD is allowed")
                # The layout is fixed for the whole road, so it must be set where the road begins.
                if distance is not None and distance != 0:
                    report("distance", f"ROAD must be at distance 0 (the layout is fixed for the whole road); got "
                           f"{_shown(distance_text)[1:-1]}")

            event = parser(number, distance if distance is not None else 0.0, params, units, report)
            if code == "ROAD":
                if road_line is None:
                    road_line, road, road_failed = number, event, event is None
                continue
            if code == "ES" and end_line is None:
                end_line, end = number, event
            if event is not None and distance is not None:
                placed.append((event, distance_text))
    except _TooManyErrors:
        errors.append(SdlError(path, errors[-1].line, "file", f"stopped reading after {MAX_ERRORS} problems"))
    errors += [SdlError(path, *problem) for problem in substitution.unapplied()]
    warnings += substitution.unused()

    # The run ends at ES: an event beyond it (or at its distance but after it in the file) would never fire.
    if end is not None:
        for event, distance_text in placed:
            if event is not end and (event.distance, event.line) > (end.distance, end.line):
                errors.append(SdlError(path, event.line, "distance",
                                       f"{event.code} at {_shown(distance_text)[1:-1]} is at or beyond the ES on line "
                                       f"{end_line}: it would never fire; ES must be the last event by distance"))
    road = road or DEFAULT_ROAD
    if not road_failed:
        for event, _ in placed:
            if isinstance(event, SurfaceAttribute):
                warnings.extend(_lane_warnings(event, road))
    if errors:
        errors.sort(key=lambda error: error.line)
        raise ScenarioError(errors)
    for what, lines in skipped.values():
        shown = ", ".join(map(str, lines[:10])) + (f" and {len(lines) - 10} more" if len(lines) > 10 else "")
        warnings.append(f"line {lines[0]}: {what} is not simulated: skipped (line{'s' * (len(lines) > 1)} {shown})")
    # Events take effect in order of distance, file order breaking ties (a stable sort keeps it).
    events = tuple(event for event, _ in sorted(placed, key=lambda item: item[0].distance))
    return Scenario(
        path=path, units=units, road=road, events=events,
        end_distance=end.distance if end is not None else None, warnings=tuple(warnings),
        parameters=substitution.parameters(),
        source=Source(text, skip_unsupported, tuple((values or {}).items())),
    ), substitution


def address_unit(scenario: Scenario, line: int, index: int) -> str | None:
    """The unit (in the file's units) of the field at address LINE.N of a scenario read from text, None for a field
    without one or one that cannot be told (no such line or field)."""
    if scenario.source is None:
        return None
    lines = scenario.source.text.removeprefix("\ufeff").replace("\r\n", "\n").replace("\r", "\n").split("\n")
    if not 1 <= line <= len(lines):
        return None
    texts = [part.strip() for part in lines[line - 1].split("//", 1)[0].split(",")]
    if len(texts) < 2 or index >= len(texts) - 1:
        return None
    unit = _field_of(texts[1].upper(), index, [texts[0], *texts[2:]], scenario.units)[1]
    return None if unit == "?" else unit


def _merged(scenario: Scenario, values: dict[str, float] | None) -> tuple[Source, dict[str, float]]:
    """The scenario's source and the values set on it with `values` set too (a later value for the same parameter
    wins: `$gap` and `gap` are one)."""
    source = scenario.source
    if source is None:
        raise ParameterError("", f"{scenario.path}: made in code, not read from a file: its parameters cannot be set")
    merged: dict[str, float] = {}
    for name, value in [*source.values, *(values or {}).items()]:
        key = name if address(name) is not None else (parameter_name(name) or name)
        merged.pop(key, None)
        merged[key] = value
    return source, merged


def with_values(scenario: Scenario, values: dict[str, float] | None) -> Scenario:
    """The scenario read again from its text with these parameter values set as well (see parse_text): ScenarioError
    for a value a field or a declared range refuses, ParameterError for a name that is no parameter."""
    source, merged = _merged(scenario, values)
    parsed = parse_text(source.text, scenario.path, source.skip_unsupported, merged)
    return dataclasses.replace(parsed, warnings=(*source.read_warnings, *parsed.warnings),
                               source=dataclasses.replace(parsed.source, read_warnings=source.read_warnings))


def resolve_text(scenario: Scenario, values: dict[str, float] | None = None) -> str:
    """The scenario's text with every parameter value (declared, set before, and `values`) written into its fields and
    every declaration made a plain comment: SDL that any reader runs, line for line the same file (so lines keep their
    numbers). The same checks as with_values."""
    source, merged = _merged(scenario, values)
    _, substitution = _parse(source.text, scenario.path, source.skip_unsupported, merged)
    return resolved_text(source.text.removeprefix("\ufeff").replace("\r\n", "\n").replace("\r", "\n"),
                         substitution)


MAX_FILE_SIZE = 10 * 2**20  # bytes; far beyond any scenario, and it keeps /dev/zero-like inputs out
_CTRL_Z = "\x1a"  # DOS end-of-file marker


class _Undecodable(Exception):
    """The bytes are no text sdl-fmu reads; args: (line, reason)."""


def _line_of(data: bytes, offset: int) -> int:
    return data[:offset].count(b"\n") + 1


def decode_text(data: bytes) -> tuple[str, int | None]:
    """SDL bytes -> text: UTF-16 with a BOM, UTF-8 (BOM or not), else Windows-1252.

    Returns (text, first line that is not UTF-8 when read as Windows-1252, else None); a trailing
    Ctrl-Z (and anything blank after it) is dropped. Raises _Undecodable(line, reason)."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            text, fallback = data.decode("utf-16"), None
        except UnicodeDecodeError as exc:
            line = data[:exc.start].decode("utf-16", errors="replace").count("\n") + 1
            raise _Undecodable(line, f"is not valid UTF-16 text (byte {exc.start})") from None
    else:
        if b"\0" in data:
            raise _Undecodable(_line_of(data, data.index(b"\0")), "holds a NUL byte: a binary file, not SDL text")
        try:
            text, fallback = data.decode("utf-8-sig"), None
        except UnicodeDecodeError as exc:
            fallback = _line_of(data, exc.start)
            try:
                text = data.decode("cp1252")
            except UnicodeDecodeError as exc1252:
                raise _Undecodable(_line_of(data, exc1252.start),
                                   f"byte 0x{data[exc1252.start]:02x} is neither UTF-8 nor Windows-1252 text") from None
    text = text.removeprefix("\ufeff")
    if _CTRL_Z in text:
        marker = text.index(_CTRL_Z)
        if text[marker:].strip(_CTRL_Z + " \t\r\n"):
            raise _Undecodable(text[:marker].count("\n") + 1,
                               "Ctrl-Z (end-of-file marker) before the end of the file")
        text = text[:marker]
    return text, fallback


def load_scenario(path: str | os.PathLike, skip_unsupported: bool = False) -> Scenario:
    """Read and parse a scenario file (see decode_text for the encodings); any failure is a ScenarioError."""
    name = os.fspath(path)

    def fail(line: int, reason: str) -> ScenarioError:
        return ScenarioError([SdlError(name, line, "file", reason)])

    try:
        if os.path.isdir(name):
            raise fail(0, "is a folder, not a scenario file")
        if os.path.exists(name) and not os.path.isfile(name):
            raise fail(0, "is not a regular file")
        with open(name, "rb") as file:
            data = file.read(MAX_FILE_SIZE + 1)
    except OSError as exc:
        raise fail(0, f"cannot be read: {exc.strerror or exc}") from None
    if len(data) > MAX_FILE_SIZE:
        raise fail(0, f"is larger than {MAX_FILE_SIZE // 2**20} MiB: not an SDL scenario")
    try:
        text, fallback = decode_text(data)
    except _Undecodable as exc:
        raise fail(*exc.args) from None
    scenario = parse_text(text, name, skip_unsupported)
    if fallback is not None:
        warning = (f"line {fallback}: file: is not UTF-8 (first such line); the file was read as Windows-1252")
        scenario = dataclasses.replace(scenario, warnings=(warning, *scenario.warnings),
                                       source=dataclasses.replace(scenario.source, read_warnings=(warning,)))
    return scenario


# --- the report for `sdl-fmu check` --------------------------------------------------------------


def _number_text(value: float) -> str:
    """A number as the check report shows it (10 significant digits)."""
    return f"{value:.10g}"


def _length_text(value: float, units: Units) -> str:
    return f"{_number_text(from_si(value, units))} {length_label(units)}"


def _speed_text(value: float, units: Units) -> str:
    return f"{_number_text(from_si(value, units))} {speed_label(units)}"


def _relative_text(value: Relative, units: Units, label: str) -> str:
    shown = _number_text(from_si(value.value, units))
    if value.relative:
        return f"ego{'' if shown.startswith('-') else '+'}{shown} {label}"
    return f"{shown} {label}"


def _trigger_text(trigger: ClosureTrigger) -> str:
    if trigger.seconds > 0:
        text = f"closing within {_number_text(trigger.seconds)} s"
    else:
        text = f"separating for {_number_text(-trigger.seconds)} s or more"
    return text + {"F": " (vehicle in front)", "B": " (vehicle behind)", None: ""}[trigger.where]


def _event_text(event: Event, units: Units) -> list[str]:
    """One line (A: plus one per action) describing an event in the file's units."""
    if isinstance(event, ApproachingVehicle):
        model = event.model
        model_text = f"{model.low}~{model.high} (random)" if model.is_random else str(model.low)
        place = "ahead" if event.gap > 0 else "behind"
        lines = [f"A model {model_text}, {_length_text(abs(event.gap), units)} {place}, lateral "
                 f"{_relative_text(event.lateral, units, length_label(units))}, speed "
                 f"{_relative_text(event.speed, units, speed_label(units))}"]
        for index, action in enumerate(event.actions, start=1):
            lines.append(f"action {index}: {_trigger_text(action.trigger)} -> lateral "
                         f"{_relative_text(action.lateral, units, length_label(units))}, speed "
                         f"{_relative_text(action.speed, units, speed_label(units))} "
                         f"over {_number_text(action.duration)} s")
        return lines
    if isinstance(event, Brake):
        until = {
            "time": f"time {_number_text(event.magnitude)} s",
            "distance": f"distance {_length_text(event.magnitude, units)}",
            "velocity": f"speed below {_speed_text(event.magnitude, units)}",
            "relative_velocity": f"speed dropped by {_speed_text(event.magnitude, units)}",
        }[event.threshold]
        return [f"BRK {_number_text(event.pedal * 100)} % until {until} (or stopped)"]
    if isinstance(event, SurfaceAttribute):
        return ["RSA " + ", ".join(f"lane {lane} = {_number_text(value)}" for lane, value in event.settings)]
    return ["ES end of scenario"]


def _parameter_text(parameter) -> str:
    """`$gap = 250 ft in 100..500 (declared on line 3, default 300); used on line 12 (A parameter 2 (gap))`."""
    unit = f" {parameter.unit}" if parameter.unit else ""
    span = "" if parameter.low is None else f" in {_number_text(parameter.low)}..{_number_text(parameter.high)}"
    default = "" if parameter.value == parameter.default else f", default {_number_text(parameter.default)}"
    uses = "; ".join(f"line {line} ({label})" for line, label in parameter.uses[:5])
    more = f" and {len(parameter.uses) - 5} more" if len(parameter.uses) > 5 else ""
    return (f"${parameter.name} = {_number_text(parameter.value)}{unit}{span} (line {parameter.line}{default}"
            f"{', whole' if parameter.whole else ''}); used on {uses or 'no line'}{more}")


def describe(scenario: Scenario) -> str:
    """A human-readable report of a parsed scenario, in the file's units, for `sdl-fmu check`."""
    units, road = scenario.units, scenario.road
    source = f"ROAD on line {road.line}" if road.line else "default layout"
    lines = [
        f"{scenario.path}",
        f"  units: {units} ({length_label(units)}, {speed_label(units)})",
        f"  road: {road.lanes} lanes of {_length_text(road.lane_width, units)}, {road.lanes_right} right and "
        f"{road.lanes_left} left of the dividing line ({source})",
        f"  end: {_length_text(scenario.end_distance, units)}" if scenario.end_distance is not None
        else "  end: none (no ES event)",
        f"  events: {len(scenario.events)}",
    ]
    if scenario.parameters:
        lines.append(f"  parameters: {len(scenario.parameters)}")
        lines.extend(f"    {_parameter_text(parameter)}" for parameter in scenario.parameters)
    heads = [(f"line {event.line}", _length_text(event.distance, units)) for event in scenario.events]
    line_width = max((len(line) for line, _ in heads), default=0)
    distance_width = max((len(distance) for _, distance in heads), default=0)
    for event, (line, distance) in zip(scenario.events, heads):
        head = f"  {line:<{line_width}}  {distance:>{distance_width}}  "
        first, *rest = _event_text(event, units)
        lines.append(head + first)
        lines.extend(" " * len(head) + "  " + more for more in rest)
    return "\n".join(lines)
