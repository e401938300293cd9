"""BRK releases at a complete stop whatever its threshold type: the STISIM text says "in any braking case, if the
brakes are applied long enough so that the vehicle comes to a complete stop, then the brakes will automatically be
released". Each threshold type gets a threshold the car cannot reach before it stops; the release instant is
compared with the stop instant of the closed-form braking distances, and the events after it must still fire."""

import math

import pytest

from sdl_fmu import api
from sdl_fmu.cosim.master import TIME_TOLERANCE
from sdl_fmu.units import FOOT, STANDARD_GRAVITY

SPEED_FT = 88.0  # ft/s, the driver's default start speed (60 mph)
MU = 0.8  # nominal friction (RSA 8) under every wheel
LATER_FT = 400.0  # an A event and an RSA after the stop (the car stops within ~150 ft)
END_FT = 600.0

# The master locates a trigger by bisection: it reports the first probe at which the condition holds, so the
# reported instant t satisfies t_true <= t <= t_true + TIME_TOLERANCE. The FMU locates the stop (vx = 0) within
# 1e-12 s inside its step (EVENT_TIME_TOLERANCE), and with constant deceleration v(t) is linear, which RODAS4
# integrates exactly up to rounding (~1e-15 s here). So: -1e-9 <= t - t_hand <= TIME_TOLERANCE + 1e-9.
EARLY, LATE = -1e-9, TIME_TOLERANCE + 1e-9


def scenario(tmp_path, threshold: int, magnitude: str):
    path = tmp_path / f"brk{threshold}.sdl"
    path.write_text(f"English\n0,BRK,100,{threshold},{magnitude}\n{LATER_FT:g},A,20,500,-6,1\n{LATER_FT:g},RSA,1,8\n"
                    f"{END_FT:g},ES\n")
    return path


def run(tmp_path, simple_fmu, threshold, magnitude, params):
    result = api.run(scenario(tmp_path, threshold, magnitude), fmu=simple_fmu, params=params, plot=False)
    return list(result.events)


def frictionless_stop(v0: float) -> tuple[float, float]:
    # Drag and rolling resistance 0: the closed form a = min(brake * brake_decel_max, mu * g) with full pedal,
    # brake_decel_max 9.81 > mu g = 7.845 m/s2, so a = mu g, constant from the BRK's onset at t = 0 (distance 0
    # fires at the start). Then v(t) = v0 - a t: the stop is t = v0 / a, at s = v0^2 / (2 a).
    a = MU * STANDARD_GRAVITY
    return v0 / a, v0**2 / (2 * a)


def check_release(events, t_stop: float, s_stop_ft: float, reasons=("stopped",)):
    brk = [e for e in events if e["code"] == "BRK"]
    assert [e["action"] for e in brk] == ["on", "off"]
    on, off = brk
    assert on["time_s"] == 0.0
    print(f"stop: hand {t_stop:.9f} s, simulated {off['time_s']:.9f} s ({off['time_s'] - t_stop:+.2e} s); "
          f"distance hand {s_stop_ft:.6f} ft, simulated {off['distance']:.6f} ft; reason {off['reason']}")
    assert off["reason"] in reasons
    assert EARLY <= off["time_s"] - t_stop <= LATE
    # At the stop v = 0, so the distance is that of the true stop up to a t^2 / 2 over the time error: < 1e-9 ft
    assert off["distance"] == pytest.approx(s_stop_ft, abs=1e-6)
    assert off["speed"] == 0.0
    # control returned to the driver: the events after the stop fire at their distances, and ES ends the run
    later = [e for e in events if e["code"] in ("A", "RSA") and e["action"] in ("spawn", "set")]
    assert [e["code"] for e in later] == ["A", "RSA"]
    # a distance trigger is located within TIME_TOLERANCE at under 88 ft/s: 1e-4 ft
    assert all(abs(e["distance"] - LATER_FT) <= SPEED_FT * TIME_TOLERANCE for e in later)
    end = events[-1]
    assert (end["code"], end["action"], end["reason"]) == ("ES", "end", "scenario")
    assert abs(end["distance"] - END_FT) <= SPEED_FT * TIME_TOLERANCE


FRICTIONLESS = {"drag_area": 0.0, "rolling_resistance": 0.0}


@pytest.mark.parametrize("threshold, magnitude", [
    (0, "100"),  # 100 s of braking: the car stops after 3.4 s
    (1, "10000"),  # 10000 ft of braking: it stops within 151 ft
    (3, "200"),  # a drop of 200 ft/s from 88 ft/s: the speed would have to go below 0 (it once held the run)
], ids=["time", "distance", "relative_velocity"])
def test_brk_releases_at_the_stop_when_its_threshold_lies_beyond(tmp_path, simple_fmu, threshold, magnitude):
    t_stop, s_stop = frictionless_stop(SPEED_FT * FOOT)
    check_release(run(tmp_path, simple_fmu, threshold, magnitude, FRICTIONLESS), t_stop, s_stop / FOOT)


def test_brk_velocity_threshold_is_reached_at_the_stop_at_the_latest(tmp_path, simple_fmu):
    # A velocity threshold m > 0 ("speed below m") is always reached by the stop; the closest a threshold can
    # come to lying beyond it is m -> 0, where the threshold instant (v0 - m) / a and the stop v0 / a differ by
    # m / a = 4e-11 s for m = 1e-9 ft/s: less than the bisection's TIME_TOLERANCE, so either reason is correct.
    t_stop, s_stop = frictionless_stop(SPEED_FT * FOOT)
    check_release(run(tmp_path, simple_fmu, 2, "1e-9", FRICTIONLESS), t_stop, s_stop / FOOT,
                  reasons=("velocity", "stopped"))


def test_brk_relative_velocity_releases_at_the_stop_with_drag_and_rolling_resistance(tmp_path, simple_fmu,
                                                                                    defaults_simple):
    # The closed form with drag and rolling resistance: dv/dt = -(A + K v^2), A = mu g + f_r g, K = rho CdA / (2 m).
    # Separating variables, t = integral_0^v0 dv / (A + K v^2) = arctan(v0 sqrt(K / A)) / sqrt(A K), and the
    # distance is ln(1 + K v0^2 / A) / (2 K). The drag changes with v, so v(t) is no longer linear: RODAS4's
    # error under the default solver tolerance is what remains, far below TIME_TOLERANCE (test_solver.py).
    p = defaults_simple
    A = MU * STANDARD_GRAVITY + p["rolling_resistance"] * STANDARD_GRAVITY
    K = p["air_density"] * p["drag_area"] / (2 * p["mass"])
    v0 = SPEED_FT * FOOT
    t_stop = math.atan(v0 * math.sqrt(K / A)) / math.sqrt(A * K)
    s_stop = math.log(1 + K * v0**2 / A) / (2 * K)
    assert t_stop < frictionless_stop(v0)[0]  # the drag is there: a shorter stop than without it
    check_release(run(tmp_path, simple_fmu, 3, "200", {}), t_stop, s_stop / FOOT)


def test_brake_examples_at_25_ft_s_release_every_brk_and_end_by_runout(simple_fmu):
    # At 25 ft/s the fourth example (drop by 30 ft/s) cannot be met; the car stops and
    # must be released there, not held until the 3600 s limit.
    result = api.run("brake_examples", fmu=simple_fmu, speed=25.0, plot=False)
    offs = [e for e in result.events if e["code"] == "BRK" and e["action"] == "off"]
    assert [e["reason"] for e in offs] == ["stopped", "stopped", "velocity", "stopped"]
    assert result.events[-1]["reason"] == "runout"
    assert result.final["time_s"] < 300
