"""The lead-vehicle signals (sdl_fmu/cosim/signals.py) against hand computations."""

import math

import pytest

from sdl_fmu.cosim.signals import NO_GAP, NO_LEAD, NO_TTC, extents, lead_vehicle

EGO_LENGTH, EGO_WIDTH = 4.5, 1.8
EGO_Y = -1.8288  # the centre of lane 1 of the default road (6 ft right of the dividing line)


def lead(stations, laterals, speeds, psi=0.0, vx=20.0, vy=0.0, lengths=None, widths=None):
    n = len(stations)
    return lead_vehicle(0.0, EGO_Y, psi, vx, vy, EGO_LENGTH, EGO_WIDTH, stations, laterals, speeds,
                        lengths or [4.0] * n, widths or [1.8] * n, list(range(n)))


def test_a_slower_car_ahead_in_the_lane_is_the_lead_vehicle():
    # vehicle 0 in the ego's lane 30 m ahead moving the ego's way at 10 m/s (speed -10: toward increasing
    # station); vehicle 1 closer but a lane to the left (its centre 3.6576 m left: |dy| = 3.6576 >= 0.9 + 0.9);
    # vehicle 2 behind the ego
    signals = lead([30.0, 10.0, -20.0], [1.8288, -1.8288, 1.8288], [-10.0, 15.0, -10.0])
    # gap = 30 - 4.5/2 - 4/2 = 25.75 m; relative speed 10 - 20 = -10 m/s; TTC 25.75 / 10 s
    assert signals.present and signals.index == 0 and signals.vehicle_id == 1
    assert signals.gap == pytest.approx(25.75, abs=1e-12)
    assert signals.speed == 10.0 and signals.relative_speed == -10.0
    assert signals.ttc == pytest.approx(2.575, abs=1e-12)
    assert signals.lateral_offset == pytest.approx(0.0, abs=1e-15)


def test_the_nearest_vehicle_in_the_path_wins_and_an_oncoming_one_counts():
    # an oncoming car (speed +15 toward decreasing station) 50 m ahead half a lane to the left, and a stopped
    # car 80 m ahead: the oncoming one is nearer; |dy| = 1.2 < 0.9 + 0.9 (in the path)
    signals = lead([80.0, 50.0], [1.8288, 1.8288 - 1.2], [0.0, 15.0])
    assert signals.index == 1
    assert signals.speed == -15.0 and signals.relative_speed == -35.0
    assert signals.gap == pytest.approx(50 - 2.25 - 2.0, abs=1e-12)
    assert signals.lateral_offset == pytest.approx(1.2, abs=1e-12)  # y left of the ego's centre


def test_a_yawed_ego_reaches_further_across_and_less_far_ahead():
    psi = 0.3
    along, across = extents(EGO_LENGTH, EGO_WIDTH, psi)
    assert along == pytest.approx(2.25 * math.cos(psi) + 0.9 * math.sin(psi))
    assert across == pytest.approx(2.25 * math.sin(psi) + 0.9 * math.cos(psi))
    # a car 1.9 m to the side is out of the path when the ego is straight (0.9 + 0.9 < 1.9) and in it yawed
    assert not lead([20.0], [1.8288 - 1.9], [0.0]).present
    signals = lead([20.0], [1.8288 - 1.9], [0.0], psi=psi, vx=10.0, vy=1.0)
    assert signals.present and signals.gap == pytest.approx(20 - along - 2.0)
    # the ego's velocity along the road: vx cos psi - vy sin psi
    assert signals.relative_speed == pytest.approx(-(10 * math.cos(psi) - math.sin(psi)))


def test_without_a_closing_lead_the_sentinels_hold():
    assert lead([], [], []) == NO_LEAD
    assert NO_LEAD.gap == NO_GAP and NO_LEAD.ttc == NO_TTC and NO_LEAD.vehicle_id == 0
    opening = lead([30.0], [1.8288], [-25.0])  # it pulls away at 25 m/s against the ego's 20
    assert opening.present and opening.relative_speed == 5.0 and opening.ttc == NO_TTC


def test_overlapping_road_extents_give_a_zero_gap_and_ttc():
    signals = lead([4.0], [1.8288], [0.0])  # centres 4 m apart, 2.25 + 2.0 > 4: in contact along the road
    assert signals.gap == 0.0 and signals.ttc == 0.0
