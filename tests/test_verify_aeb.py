"""`sdl-fmu verify --pack aeb-ccr`: the Euro NCAP AEB car-to-car rear grid (docs/verification.md, The AEB
car-to-car pack).

The protocol's tables are written out here, from Euro NCAP Test Protocol - AEB Car-to-Car systems v3.0.2 (July 2019)
and Assessment Protocol - Safety Assist v9.1 (November 2021), as BeamNG's implementation of them encodes them
(BeamNG_NCAP_Tests, src/beamng_ncap/scenarios.py: CCRS, CCRM, CCRB and their colour schemes), and the pack's grid
and scoring are held to them."""

import itertools

import pytest

from sdl_fmu.sdl import default_vehicle_table_path, load_vehicle_table
from sdl_fmu.sdl.events import Brake
from sdl_fmu.verify.aeb import protocol
from sdl_fmu.verify.aeb.protocol import grid, lateral_offset, score
from sdl_fmu.verify.aeb.scenario import start_gap, scenario_of

KMH = 1 / 3.6

# --- the protocol's tables --------------------------------------------------------------------------------------
OVERLAPS = [-75, -50, 50, 75, 100]  # % of the VUT's width overlapping the target
CCRS = [10, 15, 20, 25, 30, 35, 40, 45, 50]  # VUT km/h, target stationary
CCRM = [30, 35, 40, 45, 50, 55, 60, 65, 70, 75, 80]  # VUT km/h, target 20 km/h
CCRB = [(-2, 12), (-2, 40), (-6, 12), (-6, 40)]  # target m/s2, headway m; both at 50 km/h
# the colour bands, per VUT speed: (thresholds of the relative impact speed in km/h, points), as BeamNG lists them:
# a test scores the points of the last threshold its relative impact speed is below, else 0
CCRS_BANDS = {50: ([40, 30, 15, 5], [0.25, 0.5, 0.75, 1]), 45: ([35, 25, 15, 5], [0.25, 0.5, 0.75, 1]),
              40: ([35, 25, 15, 5], [0.25, 0.5, 0.75, 1]), 35: ([25, 15, 5], [0.5, 0.75, 1]),
              30: ([25, 15, 5], [0.5, 0.75, 1]), 25: ([15, 5], [0.5, 1]), 20: ([1], [1]), 15: ([1], [1]),
              10: ([1], [1])}
CCRM_BANDS = {80: ([50, 35, 20, 5], [0.25, 0.5, 0.75, 1]), 75: ([45, 30, 15, 5], [0.25, 0.5, 0.75, 1]),
              70: ([40, 30, 15, 5], [0.25, 0.5, 0.75, 1]), 65: ([35, 25, 15, 5], [0.25, 0.5, 0.75, 1]),
              60: ([35, 25, 15, 5], [0.25, 0.5, 0.75, 1]), 55: ([25, 15, 5], [0.5, 0.75, 1]),
              50: ([25, 15, 5], [0.5, 0.75, 1]), 45: ([15, 5], [0.5, 1]), 40: ([15, 5], [0.5, 1]), 35: ([5], [1]),
              30: ([5], [1])}
CCRB_BANDS = ([1], [1])


def protocol_points(thresholds, points, relative_impact_speed):
    result = 0
    for threshold, value in zip(thresholds, points):
        if relative_impact_speed < threshold:
            result = value
    return result


def test_the_grid_is_the_protocols():
    expected = ([("CCRs", v, 0, o, None, None) for v, o in itertools.product(CCRS, OVERLAPS)]
                + [("CCRm", v, 20, o, None, None) for v, o in itertools.product(CCRM, OVERLAPS)]
                + [("CCRb", 50, 50, o, -a, h) for (a, h), o in itertools.product(CCRB, OVERLAPS)])
    got = [(t.group, t.ego_speed_kmh, t.target_speed_kmh, t.overlap_pct, t.target_decel_mps2, t.headway_m)
           for t in grid()]
    assert got == expected and len(got) == 45 + 55 + 20
    assert [t.group for t in grid(["CCRb"])] == ["CCRb"] * 20


@pytest.mark.parametrize("group, bands", [("CCRs", CCRS_BANDS), ("CCRm", CCRM_BANDS)])
def test_the_scoring_is_the_protocols(group, bands):
    for speed, (thresholds, points) in bands.items():
        test = protocol.Test(group, speed, 0 if group == "CCRs" else 20, 100)
        for relative in [0.0, 0.5, 0.999, 1.0, 4.99, 5.0, 14.9, 15.0, 19.9, 20.0, 24.9, 25.0, 29.9, 30.0, 34.9, 35.0,
                         39.9, 40.0, 44.9, 45.0, 49.9, 50.0, 80.0]:
            assert score(test, relative) == protocol_points(thresholds, points, relative), (speed, relative)
    assert set(bands) == set(CCRS if group == "CCRs" else CCRM)


def test_the_ccrb_scoring_and_the_colours():
    test = protocol.Test("CCRb", 50, 50, 100, 6.0, 12.0)
    for relative in (0.0, 0.99, 1.0, 10.0):
        assert score(test, relative) == protocol_points(*CCRB_BANDS, relative)
    assert protocol.COLOURS == {1.0: "green", 0.75: "yellow", 0.5: "orange", 0.25: "brown", 0.0: "red"}


def test_the_overlaps_place_the_target():
    # ego 1.8 m wide, target 1.72 m: x % of the ego's width behind the target puts the ego's centre line
    # (x - 50) % of its width inside the target's edge; negative: the ego to the left of the target, whose centre is
    # then to the ego's right (+ lateral, the roadway frame)
    ego, target = 1.8, protocol.TARGET_WIDTH_M
    assert lateral_offset(100, ego) == 0.0
    assert lateral_offset(50, ego) == pytest.approx(-target / 2)
    assert lateral_offset(-50, ego) == pytest.approx(target / 2)
    assert lateral_offset(75, ego) == pytest.approx(-(target / 2 - 0.25 * ego))
    for overlap in (50, 75, -50, -75):  # the overlapping width is the share of the ego's
        offset = abs(lateral_offset(overlap, ego))
        assert (ego + target) / 2 - offset == pytest.approx(abs(overlap) / 100 * ego)


def test_a_test_as_a_scenario():
    # the target: the vehicle table's Euro NCAP target, its rear bumper the start gap ahead of the ego's front one:
    # 4 s x the closing speed, or the CCRb headway
    table = load_vehicle_table(default_vehicle_table_path())
    target = table[protocol.TARGET_MODEL]
    assert (target.length, target.width) == (3.95, 1.72)
    assert start_gap(protocol.Test("CCRs", 50, 0, 100)) == pytest.approx(4 * 50 * KMH)
    assert start_gap(protocol.Test("CCRm", 80, 20, 100)) == pytest.approx(4 * 60 * KMH)
    ccrb = protocol.Test("CCRb", 50, 50, -75, 6.0, 40.0)
    assert start_gap(ccrb) == 40.0
    scene = scenario_of(ccrb, 4.6, 1.8)
    (event,) = scene.events
    assert scene.units == "Metric" and not any(isinstance(e, Brake) for e in scene.events)
    assert event.gap == pytest.approx(40.0 + (4.6 + 3.95) / 2)
    assert event.speed.value == pytest.approx(-50 * KMH) and not event.speed.relative
    assert event.lateral.relative and event.lateral.value == pytest.approx(lateral_offset(-75, 1.8))
    # braking from the start at 6 m/s2 to a stop: the transition's duration is v / a, its lateral unchanged
    assert event.initial.speed.value == 0.0 and event.initial.duration == pytest.approx(50 * KMH / 6.0)
    assert event.initial.lateral == event.lateral
    assert scenario_of(protocol.Test("CCRm", 50, 20, 100), 4.6, 1.8).events[0].initial is None
