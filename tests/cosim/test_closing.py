"""The end of a run when the ego no longer closes on a vehicle (cosim/closing.py), and a generated vehicle's transition
from its spawn (ApproachingVehicle.initial), against hand computations, whatever the communication step.

Every case brakes the Simple FMU with a BRK pedal of 0.5 and no drag or rolling resistance: a = 0.5 x brake_decel_max
= 4.905 m/s2, below its friction limit 0.8 g, so its speed falls exactly linearly (the FMU's states are then
polynomials its solver integrates to round-off) and it stops at v0 / a, where its stop event makes the speed exactly
0. The instants are located by bisection to TIME_TOLERANCE (1e-6 s)."""

import pytest

from sdl_fmu import api
from sdl_fmu.cosim.locate import TIME_TOLERANCE
from sdl_fmu.sdl.events import (DEFAULT_ROAD, Action, ApproachingVehicle, Brake, ClosureTrigger, ModelChoice,
                                Relative, Scenario)
from sdl_fmu.units import KILOMETRE_PER_HOUR, METRIC

from helpers import NO_RESISTANCES

A = 0.5 * 9.81  # m/s2: the pedal 0.5 of the Simple FMU's brake_decel_max
V0 = 50 * KILOMETRE_PER_HOUR

pytestmark = pytest.mark.usefixtures("simple_fmus")  # every run uses the Simple FMU of the cache


def scenario(target_speed: float, gap: float, brake: bool = True, target_braking: float | None = None) -> Scenario:
    """The ego at V0 in lane 1 behind vehicle 1 (model 1, the compact car, 4.2 m long), `gap` centre to centre,
    moving the ego's way at `target_speed` (m/s; braking from the start at `target_braking` m/s2 to a stop); a BRK of
    pedal 0.5 from the start (held 100 s or to the stop)."""
    lateral = Relative(0.0, relative=True)
    initial = None if target_braking is None else Action(ClosureTrigger(0.0, None), lateral, Relative(0.0, False),
                                                         target_speed / target_braking)
    target = ApproachingVehicle(0, 0.0, Relative(-target_speed, False), gap, lateral, ModelChoice(1, 1), (), initial)
    events = (target, Brake(0, 0.0, 0.5, "time", 100.0)) if brake else (target,)
    return Scenario("generated.sdl", METRIC, DEFAULT_ROAD, events, None)


def run(scene, step):
    return api.run(scene, speed=V0, until_time=20.0, until_not_closing=1, step=step, params=NO_RESISTANCES,
                   plot=False)


def ends(result):
    return [(e["time_s"], e.get("reason")) for e in result.events if e["code"] == "ES"]


@pytest.mark.parametrize("step", [1.0, 0.01])
def test_the_run_ends_where_the_ego_falls_to_the_speed_of_the_vehicle_it_closed_on(step):
    # target at 20 km/h, 33 m ahead centre to centre: the ego closes from the start (50 > 20 km/h) and its speed
    # falls to the target's at t = (V0 - v_t) / A = (13.889 - 5.556) / 4.905 = 1.6989 s; the gap shrinks by
    # (V0 - v_t)^2 / (2 A) = 7.08 m of the 33 - (4.6 + 4.2) / 2 = 28.6 m: no contact
    vt = 20 * KILOMETRE_PER_HOUR
    result = run(scenario(vt, 33.0), step)
    (time, reason), = ends(result)
    assert reason == "not_closing" and result.collisions == 0
    assert time == pytest.approx((V0 - vt) / A, abs=2 * TIME_TOLERANCE)
    assert result.final["speed"] == pytest.approx(vt, abs=A * 2 * TIME_TOLERANCE)


@pytest.mark.parametrize("step", [1.0, 0.01])
def test_a_stop_behind_a_stationary_vehicle_ends_the_run_at_the_stop(step):
    # stationary target 40 m ahead: the ego stops after V0^2 / (2 A) = 19.66 m at t = V0 / A = 2.8316 s, the
    # relative speed reaching 0 exactly there
    result = run(scenario(0.0, 40.0), step)
    (time, reason), = ends(result)
    assert reason == "not_closing" and result.collisions == 0 and result.final["speed"] == 0.0
    assert time == pytest.approx(V0 / A, abs=2 * TIME_TOLERANCE)
    assert result.final["distance"] == pytest.approx(V0**2 / (2 * A), abs=1e-6)


@pytest.mark.parametrize("step", [1.0, 0.01])
def test_a_target_that_brakes_from_its_spawn(step):
    # both at 50 km/h, the target 12 m ahead bumper to bumper (12 + (4.6 + 4.2) / 2 centre to centre), braking at
    # 6 m/s2 from the start, the ego not braking: the gap closes as 3 t^2, contact at t = sqrt(12 / 3) = 2 s, the
    # target then at V0 - 12 m/s. The ego closes on it from t = 0+ (located), so no end before the contact.
    result = run(scenario(V0, 12.0 + 4.4, brake=False, target_braking=6.0), step)
    contact = [e for e in result.events if e["code"] == "A" and e["action"] == "collision"]
    assert len(contact) == 1 and contact[0]["time_s"] == pytest.approx(2.0, abs=2 * TIME_TOLERANCE)
    assert all(time > 2.0 for time, _ in ends(result))
    track = result.raw.vehicles[0]
    k = list(result.time).index(contact[0]["time_s"])
    assert track.speed[k] == pytest.approx(-(V0 - 12.0), abs=1e-9)  # road-frame speed: negative, the ego's way


def test_an_ego_that_never_closed_is_not_ended():
    # the target brakes at 2 m/s2 from 50 km/h, the ego at 4.905: the ego is slower from the start and never closes,
    # so the end (which needs the ego to have closed first) never comes; the run ends at its time limit
    result = run(scenario(V0, 30.0, target_braking=2.0), 1.0)
    assert ends(result) == [(20.0, "until_time")]
