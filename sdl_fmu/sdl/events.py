"""Typed SDL events: what a scenario file says, in SI units (m, m/s, s). Slotted: a long scenario holds
one small object per event line."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal, Union

from ..units import ENGLISH, Units, to_si

RIGHT_SHOULDER = 101
LEFT_SHOULDER = -101

BrakeThreshold = Literal["time", "distance", "velocity", "relative_velocity"]
BRAKE_THRESHOLDS: tuple[BrakeThreshold, ...] = ("time", "distance", "velocity", "relative_velocity")
"""BRK parameter 2 values 0..3, by name."""

SUPPORTED_CODES = ("A", "BRK", "RSA", "ROAD", "ES")


@dataclass(frozen=True, slots=True)
class Relative:
    """A value that may be relative to the ego's current value (written with a '*' prefix)."""

    value: float
    relative: bool

    def resolve(self, ego_value: float) -> float:
        """The absolute value, given the ego's current value of the same quantity."""
        return ego_value + self.value if self.relative else self.value


@dataclass(frozen=True, slots=True)
class ModelChoice:
    """A vehicle model number: fixed (low == high) or drawn uniformly from low..high inclusive."""

    low: int
    high: int

    @property
    def is_random(self) -> bool:
        return self.low != self.high


@dataclass(frozen=True, slots=True)
class ClosureTrigger:
    """When an action fires: closing within `seconds` (> 0) or separating for at least -`seconds` (< 0)."""

    seconds: float
    where: str | None  # 'F' only while the vehicle is in front of the ego, 'B' only behind, None either


@dataclass(frozen=True, slots=True)
class Action:
    """One action set of an A event: at the trigger, move to a new lateral position and speed linearly."""

    trigger: ClosureTrigger
    lateral: Relative
    speed: Relative
    duration: float


@dataclass(frozen=True, slots=True)
class ApproachingVehicle:
    """SDL 'A': a traffic vehicle appearing `gap` ahead (behind if negative) with up to 5 actions.

    `initial`, which SDL text cannot give (the vehicle test packs generate it), is a transition that starts at the
    spawn itself (its trigger is not used): a target that brakes from the start of a test."""

    line: int
    distance: float
    speed: Relative
    gap: float
    lateral: Relative
    model: ModelChoice
    actions: tuple[Action, ...]
    initial: Action | None = None
    code: ClassVar[str] = "A"


@dataclass(frozen=True, slots=True)
class Brake:
    """SDL 'BRK': hold the brake pedal at `pedal` until the threshold is reached or the ego stops."""

    line: int
    distance: float
    pedal: float
    threshold: BrakeThreshold
    magnitude: float
    code: ClassVar[str] = "BRK"


@dataclass(frozen=True, slots=True)
class SurfaceAttribute:
    """SDL 'RSA': set the surface value of lanes from this distance on (10*mu or attribute number)."""

    line: int
    distance: float
    settings: tuple[tuple[int, float], ...]
    code: ClassVar[str] = "RSA"


@dataclass(frozen=True, slots=True)
class Road:
    """Roadway layout: lateral positions are metres from the dividing line, positive to the driver's right."""

    line: int
    distance: float
    lane_width: float
    lanes: int
    lanes_right: int
    code: ClassVar[str] = "ROAD"

    @property
    def lanes_left(self) -> int:
        return self.lanes - self.lanes_right

    def has_lane(self, lane: int) -> bool:
        """Whether an event may name this lane (arithmetic: no list of the road's lanes is built)."""
        return 1 <= lane <= self.lanes_right or 1 <= -lane <= self.lanes_left or lane in (RIGHT_SHOULDER,
                                                                                          LEFT_SHOULDER)

    @property
    def valid_lanes(self) -> tuple[int, ...]:
        """Every lane number an event may name: right lanes, left lanes, then both shoulders."""
        right = tuple(range(1, self.lanes_right + 1))
        left = tuple(-k for k in range(1, self.lanes_left + 1))
        return right + left + (RIGHT_SHOULDER, LEFT_SHOULDER)

    @property
    def right_edge(self) -> float:
        return self.lanes_right * self.lane_width

    @property
    def left_edge(self) -> float:
        return -self.lanes_left * self.lane_width

    def lane_center(self, lane: int) -> float:
        """Lateral position of a lane's centre; a shoulder is taken as one lane width beyond the edge."""
        if not self.has_lane(lane):
            raise ValueError(f"lane {lane} is not on this road ({self.lanes_right} right, {self.lanes_left} left and "
                             "the shoulders)")
        if lane == RIGHT_SHOULDER:
            return self.right_edge + self.lane_width / 2
        if lane == LEFT_SHOULDER:
            return self.left_edge - self.lane_width / 2
        side = 1 if lane > 0 else -1
        return side * (abs(lane) - 0.5) * self.lane_width

    def lane_at(self, lateral: float) -> int:
        """Lane number under a lateral position; beyond the outer lanes is the shoulder."""
        # A boundary between two lanes belongs to the outer one; the dividing line itself belongs to lane 1.
        if lateral >= 0:
            k = math.floor(lateral / self.lane_width) + 1
            return k if k <= self.lanes_right else RIGHT_SHOULDER
        k = math.floor(-lateral / self.lane_width) + 1
        return -k if k <= self.lanes_left else LEFT_SHOULDER


@dataclass(frozen=True, slots=True)
class EndOfScenario:
    """SDL 'ES': the scenario ends when the ego reaches this distance."""

    line: int
    distance: float
    code: ClassVar[str] = "ES"


Event = Union[ApproachingVehicle, Brake, SurfaceAttribute, EndOfScenario]


@dataclass(frozen=True, slots=True)
class Parameter:
    """A scenario parameter declared by a comment line `// @param NAME = VALUE [UNIT] [in LOW..HIGH]`
    (docs/scenarios.md, Parameters): its value in this scenario (the declared one unless set), as written in the file's
    units; the declared unit (None: unchecked) and range (None: the fields' own limits only); the line of its
    declaration; `uses`: (line, field) of every field that reads it; `whole`: every such field takes a whole number
    (a model, a lane, a BRK threshold type, ROAD's lane counts)."""

    name: str
    value: float
    default: float
    unit: str | None
    low: float | None
    high: float | None
    line: int
    uses: tuple[tuple[int, str], ...] = ()
    whole: bool = False


@dataclass(frozen=True, slots=True)
class Source:
    """What a Scenario was read from, so that parameters can be set again (sdl/parameters.py): the text, the
    skip_unsupported it was read with, the values set ((name or address, value) in the order given) and the warnings
    of the reading itself (an encoding fallback), which come before the parser's."""

    text: str
    skip_unsupported: bool = False
    values: tuple[tuple[str, float], ...] = ()
    read_warnings: tuple[str, ...] = ()

DEFAULT_ROAD = Road(line=0, distance=0.0, lane_width=to_si(12.0, ENGLISH), lanes=2, lanes_right=1)
"""Without a ROAD event: one 12 ft lane each way, dividing line between them."""


@dataclass(frozen=True, slots=True)
class Scenario:
    """A parsed scenario file: its units, road layout and events in the order they take effect: by distance,
    file order breaking ties (ROAD excluded)."""

    path: str
    units: Units
    road: Road
    events: tuple[Event, ...]
    end_distance: float | None
    warnings: tuple[str, ...] = ()  # what was read but will not act (skipped codes, lanes the road lacks)
    parameters: tuple[Parameter, ...] = ()  # the declared parameters (`// @param`), in the order declared
    source: Source | None = None  # the text it was parsed from (None: made in code, e.g. by a test pack)
