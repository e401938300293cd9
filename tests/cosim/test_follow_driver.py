"""`--driver follow`: the built-in driver also follows the vehicle ahead with Gipps' (1981) car-following law and its
reaction time; it brakes to a stop behind a stopped car at the distance the law gives, stays stopped, never overrides
BRK, and without a vehicle ahead drives as the lane driver (docs/controllers.md). The default lane driver ignores
traffic and drives into the stopped car."""

import math

import numpy as np
import pytest

from sdl_fmu import api

V0 = 50 / 3.6  # m/s
SPAWN = 100.0  # m: the stopped car's centre ahead of the ego's centre at t = 0
EGO_LENGTH, TARGET_LENGTH = 4.6, 4.2  # m: the Simple FMU's default; vehicle table model 1
GAP0 = SPAWN - (EGO_LENGTH + TARGET_LENGTH) / 2  # the bumper gap at t = 0

# Gipps (1981), the means of his simulation's distributions: reaction time tau = 2/3 s, the driver's braking
# b = -2 a = -3.4 m/s2 (a = 1.7 m/s2), the leader's braking the driver expects b^ = min(-3.0, (b - 3.0)/2) = -3.2 m/s2;
# sdl-fmu's margin at rest (bumper gap) 2.0 m
TAU, B, B_HAT, MARGIN = 2 / 3, -3.4, -3.2, 2.0


def gipps(v: float, gap: float, v_lead: float) -> float:
    """Gipps' braking term, written here from the paper: the speed tau from now."""
    argument = B * B * TAU * TAU - B * (2 * (gap - MARGIN) - v * TAU - v_lead * v_lead / B_HAT)
    return max(B * TAU + math.sqrt(argument), 0.0) if argument > 0 else 0.0


@pytest.fixture(scope="module")
def stopped_car(tmp_path_factory):
    path = tmp_path_factory.mktemp("scenario") / "stopped_car.sdl"
    path.write_text(f"Metric\n0, A, 0, {SPAWN:g}, *0, 1\n300, ES\n")
    return path


def hand_rest_gap(v0: float, gap0: float, defaults: dict) -> tuple[int, float, list]:
    """Gipps' model by hand: at each decision t_k = k tau the driver takes min(its speed, the law's speed) as its
    speed at t_(k+1), reached at a constant acceleration (the lane driver holds V0, so the law alone slows it); the
    bumper gap closes by the mean speed x tau. At rest the law's speed is 0 exactly when gap = margin (sqrt(b^2 tau^2)
    + b tau), and near it the linearised recursion (e, v) -> (e/2 - v tau/4, e/tau - v/2), e = gap - margin, is
    nilpotent (its matrix squares to 0): the approach to the margin settles within a few decisions but is
    asymptotic. The driver ends it at the first instant it looks (a driver sample, every 0.05 s, or a decision) with
    its speed below 0.01 m/s while the law allows less than 0.1 m/s: it holds the brake at pedal 0.3 and stops within
    v^2 / (2 (0.3 brake_decel_max + f_r g)) < 2e-5 m. Returns (the first braking decision, the rest gap, the
    decisions' (speed, gap))."""
    v, g, braking, decisions = v0, gap0, None, []
    for k in range(40):
        following = min(v, gipps(v, g, 0.0))
        decisions.append((v, g))
        if braking is None and following < v:
            braking = k
        looks = sorted({k * TAU, *(n * 0.05 for n in range(math.ceil(k * TAU / 0.05), int((k + 1) * TAU / 0.05) + 1)
                                   if n * 0.05 < (k + 1) * TAU)})
        for t in looks:
            h = t - k * TAU
            speed = v + (following - v) * h / TAU
            if speed < 0.01 and following < 0.1:
                rest = g - (v * h + (following - v) * h * h / (2 * TAU))
                hold = 0.3 * defaults["brake_decel_max"] + defaults["rolling_resistance"] * 9.80665
                return braking, rest - speed * speed / (2 * hold), decisions
        g -= (v + following) / 2 * TAU
        v = following
    raise AssertionError("the hand recursion does not come to rest")


def test_the_follow_driver_stops_behind_a_stopped_car_where_the_law_says(stopped_car, defaults_simple):
    """The run against the hand recursion (hand_rest_gap): it starts braking at the decision k = 6 (t = 4.0 s), its
    speed and gap at every decision and the gap it comes to rest at (0.57 mm beyond the margin: the hold at 10.6 s).

    Tolerances from the numerics: the driver meets the law's acceleration through pedals computed every 0.05 s with
    the drag feed-forward of the sample's speed, which then falls by <= 3.4 x 0.05 m/s: the drag it feeds forward is
    off by <= 2 K v dv = 2 x 2.86e-4 x 13.9 x 0.17 = 1.4e-3 m/s2, so each decision interval ends <= 1.4e-3 x tau =
    9e-4 m/s and 1.4e-3 tau^2 / 2 = 3e-4 m off the hand recursion, errors the next decision takes from the actual state
    (the law re-decides from where the car is) rather than adds up: 2e-3 m/s and m bound them. Near rest the drag
    error vanishes (K v^2, v < 1 m/s over the last two decisions: 1e-4 m/s2, 2e-5 m per decision): the rest gap
    within 1e-4 m."""
    result = api.run(stopped_car, speed=V0, driver="follow", until_time=40.0)
    arrays = result.arrays
    time, speed = arrays["time_s"], arrays["speed_m/s"]
    gap = arrays["A1_gap_m"] - (EGO_LENGTH + TARGET_LENGTH) / 2  # centre to centre less the half lengths
    assert result.collisions == 0
    braking, rest_gap, decisions = hand_rest_gap(V0, GAP0, defaults_simple)
    assert braking == 6 and rest_gap - MARGIN == pytest.approx(5.7e-4, abs=5e-5)  # the worked numbers
    for k, (v, g) in enumerate(decisions):
        i = np.flatnonzero(np.abs(time - k * TAU) < 1e-9)
        assert len(i) == 1, f"no sample at the decision instant {k} tau"
        assert speed[i[0]] == pytest.approx(v, abs=2e-3) and gap[i[0]] == pytest.approx(g, abs=2e-3)
    rest = np.flatnonzero(arrays["stopped"] > 0)
    assert len(rest) and np.all(arrays["stopped"][rest[0]:] > 0)  # stays stopped to the end of the run (40 s)
    assert gap[-1] == pytest.approx(rest_gap, abs=1e-4)
    assert arrays["brake_1"][-1] == 0.3  # held on the brake
    assert result.summary["driver"]["law"] == "Gipps (1981)"


def test_the_lane_driver_ignores_traffic(stopped_car):
    result = api.run(stopped_car, speed=V0, until_time=20.0)
    assert result.collisions == 1 and "driver" not in result.summary


def test_the_follow_driver_never_overrides_brk(tmp_path):
    """A BRK of 10 % for 1 s fires at 30 m, while the law asks for more (it brakes from 4.67 s on, and harder): the
    pedals are BRK's while it holds them; then the follow driver takes over again."""
    path = tmp_path / "brk.sdl"
    path.write_text(f"Metric\n0, A, 0, {SPAWN:g}, *0, 1\n70, BRK, 10, 0, 1\n300, ES\n")
    result = api.run(path, speed=V0, driver="follow", until_time=30.0)
    arrays = result.arrays
    on = next(e for e in result.events if e["code"] == "BRK" and e["action"] == "on")
    off = next(e for e in result.events if e["code"] == "BRK" and e["action"] == "off")
    held = (arrays["time_s"] >= on["time_s"]) & (arrays["time_s"] < off["time_s"])
    assert held.sum() > 10 and off["reason"] == "time"
    assert np.all(arrays["brake_1"][held] == 0.1) and np.all(arrays["throttle_1"][held] == 0.0)
    after = arrays["time_s"] > off["time_s"]
    assert np.any(arrays["brake_1"][after] > 0.3)  # the law brakes harder once BRK lets go
    assert result.collisions == 0 and arrays["stopped"][-1] == 1


def test_without_a_vehicle_ahead_the_follow_driver_drives_as_the_lane_driver():
    """brake_examples has no traffic: the same events; the follow driver's decision instants only add samples."""
    lane = api.run("brake_examples")
    follow = api.run("brake_examples", driver="follow")
    assert [(e["code"], e["action"]) for e in lane.events] == [(e["code"], e["action"]) for e in follow.events]
    for a, b in zip(lane.events, follow.events):
        assert a["time_s"] == pytest.approx(b["time_s"], abs=1e-6)
    assert follow.final["distance"] == pytest.approx(lane.final["distance"], abs=1e-6)


def test_the_driver_and_on_collision_options_are_checked():
    with pytest.raises(api.InputError, match=r"^driver fast: must be one of lane, follow$"):
        api.run("demo", driver="fast")
    with pytest.raises(api.InputError, match=r"^on_collision halt: must be one of continue, stop$") as caught:
        api.run("demo", on_collision="halt")
    assert caught.value.command_line().startswith("--on-collision halt")
