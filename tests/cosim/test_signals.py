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


@pytest.mark.parametrize("name", ["lead_vehicle", "demo"])
def test_the_lead_track_of_a_run_is_lead_vehicle_at_every_sample_bit_for_bit(simple_fmu, name):
    # signals.lead_track (the plot's lead series, vectorised over the samples) against lead_vehicle (plain floats)
    # at every sample, over the vehicles on the road there: the same operations in the same order, the same bits
    import numpy as np

    from sdl_fmu import api
    from sdl_fmu.cosim.signals import lead_track
    from sdl_fmu.vehicle import EgoModel, shipped_map_path

    result = api.run(name, fmu=simple_fmu)
    raw = result.raw
    columns, tracks = raw.columns, list(raw.vehicles)
    model = EgoModel.open(simple_fmu, shipped_map_path("simple"))
    length, width = model.length, model.width
    series = lead_track(columns["x"], columns["y"], columns["psi"], columns["vx"], columns["vy"], length, width,
                        [(track.vehicle - 1, track.first, track.station, track.lateral, track.speed, track.length,
                          track.width) for track in tracks])
    assert series["present"].sum() > 100
    for k in range(len(columns["time"])):
        present = [track for track in tracks if track.first <= k < track.first + len(track.station)]
        lead = lead_vehicle(float(columns["x"][k]), float(columns["y"][k]), float(columns["psi"][k]),
                            float(columns["vx"][k]), float(columns["vy"][k]), length, width,
                            [t.station[k - t.first] for t in present], [t.lateral[k - t.first] for t in present],
                            [t.speed[k - t.first] for t in present], [t.length for t in present],
                            [t.width for t in present], [t.vehicle - 1 for t in present])
        got = (bool(series["present"][k]), int(series["index"][k]), *(float(series[key][k]) for key in (
            "gap", "speed", "relative_speed", "ttc", "lateral_offset")))
        assert got == (lead.present, lead.index, lead.gap, lead.speed, lead.relative_speed, lead.ttc,
                       lead.lateral_offset), k
    # and the record's own series (made by the run stage from the vehicles' closed-form motions) is this one
    recorded = raw.lead_series()
    assert all(np.array_equal(recorded[key], series[key]) for key in series)


def test_bumper_gaps_ahead_behind_and_overlapping_by_hand():
    # ego 4.5 x 1.8 m at yaw 0 (reaching 2.25 m ahead and behind its centre), cars 4.0 m long: a centre 30 m ahead
    # is 30 - 2.25 - 2.0 = 25.75 m from bumper to bumper; one 30 m behind -25.75 m; centres 3 m apart (ahead or
    # behind) overlap along the road: 0
    import numpy as np

    from sdl_fmu.cosim.signals import bumper_gaps

    along = extents(EGO_LENGTH, EGO_WIDTH, 0.0)[0]
    assert along == 2.25
    gaps = bumper_gaps(np.array([30.0, -30.0, 3.0, -3.0]), along, np.full(4, 4.0))
    assert list(gaps) == [25.75, -25.75, 0.0, 0.0]
    # and ahead it is lead_vehicle's gap
    assert lead([30.0], [-EGO_Y], [0.0]).gap == gaps[0]
