"""The Euro NCAP AEB car-to-car rear tests as data: the grid of tests, the target, the start and end of a test, the
scoring. Every number here comes from the sources below; docs/verification.md (The AEB car-to-car pack) says how
each was taken and where the simulation departs from the track.

Sources:
- [TP] Euro NCAP, Test Protocol - AEB Car-to-Car systems, Version 3.0.2, July 2019 (cdn.euroncap.com/media/56143):
  the scenarios CCRs, CCRm, CCRb (section 2), the test speeds, overlaps, target decelerations and headways, the
  start of a test at 4 s TTC, the end of a test (8.4.3: "V_VUT = 0 km/h, V_VUT < V_GVT, or contact").
- [SA] Euro NCAP, Assessment Protocol - Safety Assist, Version 9.1, November 2021 (cdn.euroncap.com/media/67254):
  the scoring of each test on its relative impact speed, in colour bands that depend on the test speed.
- [BNG] BeamNG GmbH, BeamNG_NCAP_Tests, src/beamng_ncap/scenarios.py (github.com/BeamNG/BeamNG_NCAP_Tests), an
  implementation of [TP] and [SA]: the protocol's own text could not be read here, so the grid and the colour bands
  are taken as [BNG] encodes them (its clause numbers: [TP] 8.4.2, 8.4.3 and 6.1.3), and the overlap's sign as
  [BNG] places the vehicle under test: a negative overlap puts it to the left of the target.
- [GVT] the target is the Global Vehicle Target (ISO 19206-3; Euro NCAP, NHTSA and IIHS adopted the DRI Soft Car
  360 Fiesta as it): its footprint is taken as that of the Ford Fiesta (7th generation) it replicates, 3.95 m x
  1.72 m (the maker's length and width, mirrors excluded).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Group = Literal["CCRs", "CCRm", "CCRb"]
GROUPS: tuple[Group, ...] = ("CCRs", "CCRm", "CCRb")
DESCRIPTION = {  # [TP] section 2
    "CCRs": "Car-to-Car Rear stationary: the ego drives towards a stationary target",
    "CCRm": "Car-to-Car Rear moving: the ego drives towards a target moving slower at a constant speed",
    "CCRb": "Car-to-Car Rear braking: ego and target at the same speed, the target brakes",
}
PROTOCOL = ("Euro NCAP Test Protocol - AEB Car-to-Car systems v3.0.2 (July 2019); scoring: Euro NCAP Assessment "
            "Protocol - Safety Assist v9.1 (November 2021)")

OVERLAPS_PCT = (-75, -50, 50, 75, 100)  # [TP]/[BNG]: the share of the ego's width behind the target
CCRS_SPEEDS_KMH = tuple(range(10, 55, 5))  # ego, stationary target
CCRM_SPEEDS_KMH = tuple(range(30, 85, 5))  # ego, target at CCRM_TARGET_KMH
CCRM_TARGET_KMH = 20
CCRB_SPEED_KMH = 50  # ego and target
CCRB_DECELERATIONS_MPS2 = (2.0, 6.0)  # the target's (written -2 and -6 m/s2 in [TP])
CCRB_HEADWAYS_M = (12.0, 40.0)  # bumper to bumper when the target starts braking
START_TTC_S = 4.0  # CCRs and CCRm start at this time to collision
TARGET_LENGTH_M, TARGET_WIDTH_M = 3.95, 1.72  # [GVT]
TARGET_MODEL = 11  # the target's number in the vehicle table (scenarios/vehicles.csv)

# [SA] via [BNG]: per group and ego speed (km/h), the colour bands as (relative impact speed below which, km/h,
# points): the test scores the points of the lowest band its relative impact speed is below, else 0 (an avoided
# collision is a relative impact speed of 0).
_BANDS_4 = ((5, 1.0), (15, 0.75), (30, 0.5), (40, 0.25))
BANDS: dict[Group, dict[int, tuple[tuple[float, float], ...]]] = {
    "CCRs": {10: ((1, 1.0),), 15: ((1, 1.0),), 20: ((1, 1.0),), 25: ((5, 1.0), (15, 0.5)),
             30: ((5, 1.0), (15, 0.75), (25, 0.5)), 35: ((5, 1.0), (15, 0.75), (25, 0.5)),
             40: ((5, 1.0), (15, 0.75), (25, 0.5), (35, 0.25)), 45: ((5, 1.0), (15, 0.75), (25, 0.5), (35, 0.25)),
             50: _BANDS_4},
    "CCRm": {30: ((5, 1.0),), 35: ((5, 1.0),), 40: ((5, 1.0), (15, 0.5)), 45: ((5, 1.0), (15, 0.5)),
             50: ((5, 1.0), (15, 0.75), (25, 0.5)), 55: ((5, 1.0), (15, 0.75), (25, 0.5)),
             60: ((5, 1.0), (15, 0.75), (25, 0.5), (35, 0.25)), 65: ((5, 1.0), (15, 0.75), (25, 0.5), (35, 0.25)),
             70: _BANDS_4, 75: ((5, 1.0), (15, 0.75), (30, 0.5), (45, 0.25)),
             80: ((5, 1.0), (20, 0.75), (35, 0.5), (50, 0.25))},
    "CCRb": {CCRB_SPEED_KMH: ((1, 1.0),)},
}
COLOURS = {1.0: "green", 0.75: "yellow", 0.5: "orange", 0.25: "brown", 0.0: "red"}  # [SA]'s colour of the points


@dataclass(frozen=True)
class Test:
    """One test of the grid (the protocol's units: km/h, %, m/s2, m)."""

    group: Group
    ego_speed_kmh: float
    target_speed_kmh: float
    overlap_pct: int
    target_decel_mps2: float | None = None  # CCRb
    headway_m: float | None = None  # CCRb

    @property
    def name(self) -> str:
        if self.group == "CCRb":
            return f"CCRb {self.target_decel_mps2:g} m/s2 {self.headway_m:g} m {self.overlap_pct:+d} %"
        return f"{self.group} {self.ego_speed_kmh:g} km/h {self.overlap_pct:+d} %"

    def parameters(self) -> dict:
        """verify.json's keys of the test (docs/verification.md)."""
        keys = {"group": self.group, "ego_speed_kmh": self.ego_speed_kmh, "target_speed_kmh": self.target_speed_kmh,
                "overlap_pct": self.overlap_pct}
        if self.group == "CCRb":
            keys.update(target_decel_mps2=self.target_decel_mps2, headway_m=self.headway_m)
        return keys


def grid(groups: tuple[Group, ...] | list[Group] = GROUPS) -> list[Test]:
    """The protocol's tests of these groups, in the protocol's order: group, speed (CCRb: deceleration, headway),
    overlap."""
    tests = []
    for group in GROUPS:
        if group not in groups:
            continue
        if group == "CCRs":
            tests += [Test("CCRs", v, 0, o) for v in CCRS_SPEEDS_KMH for o in OVERLAPS_PCT]
        elif group == "CCRm":
            tests += [Test("CCRm", v, CCRM_TARGET_KMH, o) for v in CCRM_SPEEDS_KMH for o in OVERLAPS_PCT]
        else:
            tests += [Test("CCRb", CCRB_SPEED_KMH, CCRB_SPEED_KMH, o, a, h)
                      for a in CCRB_DECELERATIONS_MPS2 for h in CCRB_HEADWAYS_M for o in OVERLAPS_PCT]
    return tests


def score(test: Test, relative_impact_speed_kmh: float) -> float:
    """[SA]'s points of a test from its relative impact speed (0 when the collision was avoided)."""
    for below, points in BANDS[test.group][int(test.ego_speed_kmh)]:
        if relative_impact_speed_kmh < below:
            return points
    return 0.0


def lateral_offset(overlap_pct: float, ego_width: float, target_width: float = TARGET_WIDTH_M) -> float:
    """The target's centre relative to the ego's, across the road (m, positive to the ego's right, the roadway
    frame's lateral): `overlap_pct` % of the ego's width is behind the target, so with the ego's centre line
    (|overlap| - 50 %) x its width inside the target's edge (at the edge for 50 %; centred for 100 %). A negative
    overlap puts the ego to the left of the target ([BNG]), i.e. the target to the ego's right."""
    share = abs(overlap_pct) / 100
    offset = 0.0 if share >= 1 else target_width / 2 - (share - 0.5) * ego_width
    return offset if overlap_pct < 0 else -offset
