"""The orchestrator against hand computations: BRK thresholds, RSA sections per wheel, A closure times,
collisions, seeds, units. Runs the real Simple FMU through fmpy."""

import math

import numpy as np
import pytest

from sdl_fmu.cosim.master import RunOptions, run_scenario
from sdl_fmu.vehicle import EgoModel, shipped_map_path
from sdl_fmu.cosim.traffic import choose_model
from sdl_fmu.sdl import parse_text
from sdl_fmu.units import FOOT

from helpers import NO_RESISTANCES, TABLE, G, as_written

# Triggers are located to 1e-6 s; at 100 ft/s that is 1e-4 ft, and the FMU's own stop is exact to
# round-off. So 1e-3 ft and 1e-5 s bound the numerics.
DISTANCE_TOLERANCE = 1e-3  # ft
TIME_TOLERANCE = 1e-5  # s


def run(text, speed_ft=100.0, parameters=NO_RESISTANCES, seed=1, **options):
    scenario = parse_text(text, "test.sdl")
    speed = speed_ft * (FOOT if scenario.units == "English" else 1.0)
    model = EgoModel.open(options.pop("fmu"), shipped_map_path("simple")).with_parameters(parameters)
    return as_written(run_scenario(scenario, model, RunOptions(speed=speed, seed=seed, **options), TABLE))


def events(result, code, action=None):
    return [e for e in result.events if e["code"] == code and (action is None or e["action"] == action)]


@pytest.fixture
def fmu(simple_fmu):
    return simple_fmu


def deceleration_ft(pedal, mu=0.8, brake_decel_max=9.81):
    """Constant deceleration in ft/s2 on uniform mu with no drag: min(pedal a_max, mu g) (docs/verification.md)."""
    return min(pedal * brake_decel_max, mu * G) / FOOT


def test_brk_time_threshold(fmu):
    # v0 = 100 ft/s, full pedal: a = 0.8 g; after T = 3 s: v = v0 - a T, distance v0 T - a T^2 / 2
    result = run("1000,BRK,100,0,3", fmu=fmu)
    on, = events(result, "BRK", "on")
    off, = events(result, "BRK", "off")
    a = deceleration_ft(1.0)
    assert off["reason"] == "time"
    assert on["distance"] == pytest.approx(1000.0, abs=DISTANCE_TOLERANCE)
    assert off["time_s"] - on["time_s"] == pytest.approx(3.0, abs=TIME_TOLERANCE)
    assert off["distance"] - on["distance"] == pytest.approx(100 * 3 - a * 9 / 2, abs=DISTANCE_TOLERANCE)
    assert off["speed"] == pytest.approx(100 - a * 3, abs=1e-3)


def test_brk_distance_threshold(fmu):
    # 25 % pedal: a = 0.25 * 9.81 m/s2 < mu g; off after 200 ft at v^2 = v0^2 - 2 a d, after (v0 - v) / a
    result = run("2000,BRK,25,1,200", fmu=fmu)
    on, = events(result, "BRK", "on")
    off, = events(result, "BRK", "off")
    a = deceleration_ft(0.25)
    speed = math.sqrt(100**2 - 2 * a * 200)
    assert off["reason"] == "distance"
    assert off["distance"] == pytest.approx(2200.0, abs=DISTANCE_TOLERANCE)
    assert off["speed"] == pytest.approx(speed, abs=1e-3)
    assert off["time_s"] - on["time_s"] == pytest.approx((100 - speed) / a, abs=TIME_TOLERANCE)


def test_brk_velocity_threshold(fmu):
    # 50 % pedal until below 30 ft/s: distance (v0^2 - 30^2) / (2a), time (v0 - 30) / a
    result = run("3000,BRK,50,2,30", fmu=fmu)
    on, = events(result, "BRK", "on")
    off, = events(result, "BRK", "off")
    a = deceleration_ft(0.5)
    assert off["reason"] == "velocity"
    assert off["distance"] - on["distance"] == pytest.approx((100**2 - 30**2) / (2 * a), abs=DISTANCE_TOLERANCE)
    assert off["time_s"] - on["time_s"] == pytest.approx(70 / a, abs=TIME_TOLERANCE)


def test_brk_relative_velocity_threshold(fmu):
    # full pedal until the speed has dropped by 30 ft/s: 100 -> 70
    result = run("4000,BRK,100,3,30", fmu=fmu)
    on, = events(result, "BRK", "on")
    off, = events(result, "BRK", "off")
    a = deceleration_ft(1.0)
    assert off["reason"] == "relative_velocity"
    # the instant is located to 1e-6 s, in which the speed changes by a * 1e-6
    assert off["speed"] == pytest.approx(70.0, abs=a * 1e-6)
    assert off["distance"] - on["distance"] == pytest.approx((100**2 - 70**2) / (2 * a), abs=DISTANCE_TOLERANCE)


def test_brk_released_when_the_vehicle_stops(fmu):
    # threshold 2000 ft is never reached: the stop after v0^2 / (2a) releases the brakes, then the driver
    # accelerates back to the start speed
    result = run("1000,BRK,100,1,2000", fmu=fmu)
    off, = events(result, "BRK", "off")
    a = deceleration_ft(1.0)
    assert off["reason"] == "stopped" and off["speed"] == 0.0
    assert off["distance"] == pytest.approx(1000 + 100**2 / (2 * a), abs=DISTANCE_TOLERANCE)
    assert off["time_s"] == pytest.approx(10.0 + 100 / a, abs=TIME_TOLERANCE)
    assert result.final["speed"] > 90


def test_brk_stop_with_drag_and_rolling_resistance(fmu, defaults_simple):
    # with resistances the onset speed is whatever the driver held; from it the closed form (docs/verification.md):
    # s = ln(1 + K v^2 / A) / (2K), A = a + f_r g, K = rho CdA / (2 m)
    result = run("1000,BRK,100,1,2000", fmu=fmu, parameters={})
    on, = events(result, "BRK", "on")
    off, = events(result, "BRK", "off")
    p = defaults_simple
    k = p["air_density"] * p["drag_area"] / (2 * p["mass"])
    a = min(p["brake_decel_max"], 0.8 * G) + p["rolling_resistance"] * G
    v = on["speed"] * FOOT
    assert off["reason"] == "stopped"
    expected_ft = math.log(1 + k * v**2 / a) / (2 * k) / FOOT
    assert off["distance"] - on["distance"] == pytest.approx(expected_ft, abs=DISTANCE_TOLERANCE)


def test_brk_ends_with_the_scenario(fmu):
    result = run("100,BRK,10,0,100\n200,ES", fmu=fmu)
    off, = events(result, "BRK", "off")
    assert off["reason"] == "end"
    assert off["distance"] == pytest.approx(200.0, abs=DISTANCE_TOLERANCE)


def test_ice_in_another_lane_changes_nothing(fmu):
    plain = run("1000,BRK,100,1,2000", fmu=fmu)
    iced = run("1000,RSA,-1,2\n1000,BRK,100,1,2000", fmu=fmu)
    assert events(iced, "BRK", "off")[0]["distance"] == events(plain, "BRK", "off")[0]["distance"]
    assert (iced.columns["mu_fl"] == 0.8).all()


def test_ice_patch_that_ends_during_a_stop(fmu, defaults_simple):
    # Ice (mu 0.2) on lane 1 from station S1 = 1000 ft to S2 = 1050 ft; full pedal (9.81 m/s2 > mu g on
    # both surfaces) from CG distance 1000 ft. Each wheel carries a quarter of the weight, so the
    # deceleration is g times the mean mu under the four wheels. The Simple FMU's wheels sit half a
    # wheelbase ahead of / behind the CG (a = b = L/2). With the CG at s, the front wheels are on ice for
    # s + a in [S1, S2), the rear for s - b in [S1, S2). Phases of CG travel from s = S1:
    #   [S1, S1 + b)       front on ice, rear dry   mean mu 0.5
    #   [S1 + b, S2 - a)   all on ice               0.2
    #   [S2 - a, S2 + b)   rear on ice, front dry   0.5
    #   then dry                                    0.8
    # v^2 drops by 2 g mu_mean ds in each; the stop is where it reaches 0.
    half = defaults_simple["wheelbase"] / 2
    s1, s2 = 1000 * FOOT, 1050 * FOOT
    v_squared = (100 * FOOT) ** 2
    s = s1
    for end, mu in ((s1 + half, 0.5), (s2 - half, 0.2), (s2 + half, 0.5), (math.inf, 0.8)):
        if v_squared <= 2 * G * mu * (end - s):
            stop = s + v_squared / (2 * G * mu)
            break
        v_squared -= 2 * G * mu * (end - s)
        s = end
    assert stop > s2 + half  # the patch ends during the stop
    result = run("1000,RSA,1,2\n1000,BRK,100,1,2000\n1050,RSA,1,8", fmu=fmu)
    off, = events(result, "BRK", "off")
    assert off["reason"] == "stopped"
    assert off["distance"] == pytest.approx(stop / FOOT, abs=DISTANCE_TOLERANCE)


def a_event_times(result):
    return {(e["action"], e.get("index")): e["time_s"] for e in events(result, "A")}


def test_closure_time_actions_fire_at_hand_computed_instants(fmu):
    # Ego 60 ft/s, vehicle 20 ft/s toward it: closing at 80 ft/s. Spawn when the ego has driven 100 ft
    # (t = 100/60 s) with a gap of 1000 ft. Action 1 (10 s) fires when gap = 10 * 80 = 800 ft, i.e. 200 ft
    # of closing = 2.5 s later; action 2 (5 s) when gap = 400 ft, 7.5 s after the spawn.
    result = run("100,A,20,1000,-6,1,10,*0,20,2,5,-6,20,2", speed_ft=60.0, fmu=fmu)
    times = a_event_times(result)
    spawn = 100 / 60
    assert times[("spawn", None)] == pytest.approx(spawn, abs=TIME_TOLERANCE)
    assert times[("maneuver", 1)] == pytest.approx(spawn + 2.5, abs=TIME_TOLERANCE)
    assert times[("maneuver", 2)] == pytest.approx(spawn + 7.5, abs=TIME_TOLERANCE)
    time = result.columns["time"]
    lateral = result.vehicles[0].dense("lateral", len(time))
    # after action 1 (2 s transition) the vehicle is in the ego's lane: lateral = ego's 6 ft
    during = (time > spawn + 4.6) & (time < spawn + 7.4)
    assert during.sum() > 10 and np.allclose(lateral[during], 6 * FOOT)
    # and back in its own lane 2 s after action 2
    after = (time > spawn + 9.6) & ~np.isnan(lateral)
    assert after.sum() > 10 and np.allclose(lateral[after], -6 * FOOT)


def test_starred_speed_and_lateral_are_relative_to_the_ego(fmu):
    # speed *10 = ego 60 + 10 = 70 ft/s; lateral *-12 = ego 6 - 12 = -6 ft; action speed *-50 = 60 - 50
    # = 10 ft/s taken when the action fires (closing at 130 ft/s: gap 1300 - 130 * 5 after 5 s...).
    # Action 1 (8 s) fires when gap = 8 * 130 = 1040 ft: (1300 - 1040) / 130 = 2 s after the spawn.
    result = run("0,A,*10,1300,*-12,1,8,*3,*-50,0", speed_ft=60.0, fmu=fmu)
    time = result.columns["time"]
    speed, lateral = (result.vehicles[0].dense(name, len(time)) for name in ("speed", "lateral"))
    before = time < 2.0 - 1e-3
    assert np.allclose(speed[before], 70 * FOOT) and np.allclose(lateral[before], -6 * FOOT)
    assert a_event_times(result)[("maneuver", 1)] == pytest.approx(2.0, abs=TIME_TOLERANCE)
    after = (time > 2.0 + 1e-3) & ~np.isnan(speed)
    assert after.sum() > 10 and np.allclose(speed[after], 10 * FOOT) and np.allclose(lateral[after], 9 * FOOT)


def test_behind_only_trigger_fires_for_a_vehicle_closing_from_behind(fmu):
    # A vehicle 300 ft behind (gap -300) with speed -80 ft/s (moving the ego's way at 80 ft/s) closes on
    # the ego (60 ft/s) at 20 ft/s. "5B" fires when |gap| = 5 * 20 = 100 ft: 200 ft / 20 ft/s = 10 s after
    # the spawn. "5F" would need the vehicle in front: it must not fire in the other run.
    behind = run("0,A,-80,-300,-6,1,5B,-6,-80,0", speed_ft=60.0, fmu=fmu, until_time=12.0)
    front = run("0,A,-80,-300,-6,1,5F,-6,-80,0", speed_ft=60.0, fmu=fmu, until_time=12.0)
    assert a_event_times(behind)[("maneuver", 1)] == pytest.approx(10.0, abs=TIME_TOLERANCE)
    assert ("maneuver", 1) not in a_event_times(front)


def test_negative_closure_time_fires_while_separating(fmu):
    # Spawn gap 800 ft, closing at 60 + 20 = 80 ft/s: they pass at t = 10 s. "-3" fires when separated
    # for gap / 80 >= 3 s, i.e. |gap| = 240 ft: 3 s after passing. Then the vehicle stops (speed 0 over
    # 0 s) and stays behind until despawned.
    result = run("0,A,20,800,-6,1,-3,-6,0,0", speed_ft=60.0, fmu=fmu, until_time=20.0)
    assert a_event_times(result)[("maneuver", 1)] == pytest.approx(13.0, abs=TIME_TOLERANCE)


def test_head_on_collision_counted_once(fmu, defaults_simple):
    # Ego at 88 ft/s, vehicle (model 2) at 40 ft/s in the ego's own lane, 800 ft ahead when the ego has
    # driven 200 ft. Footprints touch when the gap between centres is (L_ego + L_vehicle) / 2; closing
    # at 128 ft/s. The vehicles pass through each other: one contact, one collision.
    result = run("200,A,40,800,*0,2\n1600,ES", speed_ft=88.0, fmu=fmu)
    contact_gap = (defaults_simple["length"] + TABLE[2].length) / 2 / FOOT
    expected = 200 / 88 + (800 - contact_gap) / 128
    assert result.collisions == 1
    collision, = events(result, "A", "collision")
    assert collision["time_s"] == pytest.approx(expected, abs=TIME_TOLERANCE)
    assert len(result.collision_points) == 1
    # the relative impact speed: 88 + 40 ft/s head-on (IMPACT_TOLERANCE, below)
    assert collision["relative_speed"] == pytest.approx(128.0, abs=IMPACT_TOLERANCE)


# ft/s: without resistances the lane driver holds its start speed to round-off (its feed-forward is exact), and the
# contact is located to 1e-6 s, over which neither speed changes: the relative impact speed is the closed form's to
# far below this
IMPACT_TOLERANCE = 1e-6


@pytest.mark.parametrize("vehicle_speed, relative", [(0.0, 88.0), (-60.0, 28.0), (30.0, 118.0)])
def test_a_collisions_relative_impact_speed_is_the_speed_difference(fmu, vehicle_speed, relative):
    """A compact car (model 1) 400 ft ahead in the ego's lane: stopped, going the ego's way at 60 ft/s (an A event's
    negative speed), or oncoming at 30 ft/s. The ego holds 88 ft/s and never brakes (the lane driver ignores traffic),
    so it hits the car at 88 ft/s and the relative impact speed is |88 - (-vehicle_speed)|: 88, 28 and 118 ft/s, in
    the scenario's units (summary.json's `relative_speed`); the ego's own `speed` stays 88."""
    result = run(f"0,A,{vehicle_speed:g},400,*0,1\n3000,ES", speed_ft=88.0, fmu=fmu, until_time=30.0)
    collision, = events(result, "A", "collision")
    assert collision["speed"] == pytest.approx(88.0, abs=IMPACT_TOLERANCE)
    assert collision["relative_speed"] == pytest.approx(relative, abs=IMPACT_TOLERANCE)
    assert not any("relative_speed" in event for event in result.events if event["action"] != "collision")
    metric = run(f"Metric\n0,A,{vehicle_speed * FOOT:g},{400 * FOOT!r},*0,1\n1000,ES", speed_ft=88.0 * FOOT,
                 fmu=fmu, until_time=30.0)
    collision, = events(metric, "A", "collision")
    assert collision["relative_speed"] == pytest.approx(relative * FOOT, abs=IMPACT_TOLERANCE)


def test_random_models_reproducible_and_cover_the_range(fmu):
    text = "\n".join(f"{10 * i},A,20,-500,-30,*1~8" for i in range(40))
    first = run(text, fmu=fmu, seed=7, until_time=2.0)
    again = run(text, fmu=fmu, seed=7, until_time=2.0)
    other = run(text, fmu=fmu, seed=8, until_time=2.0)
    models = [e["model"] for e in events(first, "A", "spawn")]
    assert models == [e["model"] for e in events(again, "A", "spawn")]
    assert models != [e["model"] for e in events(other, "A", "spawn")]
    assert set(models) <= set(range(1, 9))
    # the draw is uniform over the inclusive range: over many seeds every model appears
    import random

    event = parse_text("0,A,20,100,-6,*1~8").events[0]
    draws = {choose_model(event, random.Random(seed)) for seed in range(200)}
    assert draws == set(range(1, 9))


def test_metric_scenario(fmu):
    # Metric: distances in m, speeds in m/s. 30 m/s, full pedal at 300 m: stop after 30^2 / (2 * 0.8 g)
    result = run("Metric\n300,BRK,100,1,1000", speed_ft=30.0, fmu=fmu)
    off, = events(result, "BRK", "off")
    assert result.units == "Metric"
    assert off["distance"] == pytest.approx(300 + 30**2 / (2 * 0.8 * G), abs=DISTANCE_TOLERANCE * FOOT)
    assert off["lateral"] == pytest.approx(6 * FOOT, abs=1e-9)  # the default road is 12 ft lanes

