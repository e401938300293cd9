"""A controller in the loop, run: the foreign AEB controller (tests/controllers, built by PythonFMU for FMI 2.0 and
pythonfmu3 for FMI 3.0, with its own names and units: km/h, ms, %, g) brakes the Simple ego in a CCRs-like run whose
impact speed is computed by hand; its samples are instants the master steps to, so a controller that cannot get and
set its state keeps every instant exact; its requests and the arbitrated commands are in the time series and its
identity in summary.json; --on-collision stop; the command line and the sweep (docs/controllers.md)."""

import json
import math
import re

import numpy as np
import pytest

from helpers import FOREIGN_AEB_MAP, build_foreign_controller, local_cluster, sdl_fmu
from sdl_fmu import api
from sdl_fmu.units import STANDARD_GRAVITY as G

V0 = 50 / 3.6  # m/s, the ego's speed (CCRs at 50 km/h)
SPAWN = 60.0  # m, the stationary target's centre ahead of the ego's centre at t = 0
EGO_LENGTH, TARGET_LENGTH = 4.6, 4.2  # m: the Simple FMU's default length; vehicle table model 1 (compact car)
CCRS = f"""Metric
// CCRs-like: a stationary compact car in the ego's lane, {SPAWN:g} m ahead (centre to centre)
0, A, 0, {SPAWN:g}, *0, 1
200, ES
"""


@pytest.fixture(scope="module")
def controllers(tmp_path_factory):
    """{(fmi_version, can get and set its state): the foreign AEB controller's FMU}."""
    folder = tmp_path_factory.mktemp("controllers")
    return {(version, state): build_foreign_controller(folder, version, state)
            for version in (2, 3) for state in (False, True)}


@pytest.fixture(scope="module")
def ccrs(tmp_path_factory):
    path = tmp_path_factory.mktemp("scenario") / "ccrs.sdl"
    path.write_text(CCRS)
    return path


def aeb_map(tmp_path, trigger: float, extra: str = "", replace: tuple[str, str] | None = None):
    """The foreign AEB's map with its TTC trigger (s) set."""
    text = FOREIGN_AEB_MAP.read_text().replace("ttc_trigger = 1.5", f"ttc_trigger = {trigger!r}") + extra
    if replace is not None:
        text = text.replace(*replace)
    path = tmp_path / f"aeb-{trigger:g}.toml"
    path.write_text(text)
    return path


def impact_speed(trigger: float, period: float, ego: dict) -> tuple[int, float, float]:
    """By hand: the sample k at which the controller latches, the gap d there, and the impact speed.

    Until the latch the lane driver holds V0 exactly (its feed-forward cancels the Simple model's rolling resistance
    and drag), so the bumper gap at t is g0 - V0 t, g0 = SPAWN - (EGO_LENGTH + TARGET_LENGTH) / 2, and the lead TTC
    is gap / V0. The controller is sampled at t_k = k x period and reads the signals there: it latches at the first k
    with gap(t_k) / V0 <= trigger, and its full brake request acts from t_k (the request a sample computes holds from
    that sample). Full pedal asks brake_decel_max = 9.81 m/s2 > mu g (mu 0.8, the default surface), so the Simple
    model's wheels lock and each slides with (mu + f_r) Fz: with drag, m dv/dt = -m (mu + f_r) g - (rho CdA / 2) v^2,
    i.e. dv/dt = -(A + K v^2) with A = (mu + f_r) g and K = rho CdA / (2 m). Along the path, v dv/dx = -(A + K v^2):
    d(v^2)/dx = -2 (A + K v^2), so v^2 + A/K = (V0^2 + A/K) e^(-2 K x); at the contact, x = d:
        v_impact^2 = (V0^2 + A/K) e^(-2 K d) - A/K."""
    g0 = SPAWN - (EGO_LENGTH + TARGET_LENGTH) / 2
    k = next(k for k in range(100_000) if (g0 - V0 * k * period) / V0 <= trigger)
    margin = trigger - (g0 - V0 * k * period) / V0  # how far inside the trigger: far beyond rounding
    assert 1e-6 < margin < period
    d = g0 - V0 * k * period
    a = (0.8 + ego["rolling_resistance"]) * G
    drag = ego["air_density"] * ego["drag_area"] / (2 * ego["mass"])
    return k, d, math.sqrt((V0**2 + a / drag) * math.exp(-2 * drag * d) - a / drag)


@pytest.mark.parametrize("version", [2, 3])
def test_a_ttc_latched_brake_hits_at_the_hand_computed_speed(tmp_path, ccrs, controllers, defaults_simple, version):
    trigger = 0.8  # s: the latch at ~11.0 m, inside the ~12.1 m full stop from 50 km/h: an impact at ~4.1 m/s
    k, d, expected = impact_speed(trigger, 0.01, defaults_simple)
    result = api.run(ccrs, speed=V0, controller=controllers[(version, False)],
                     controller_map=aeb_map(tmp_path, trigger), until_time=20.0)
    arrays = result.arrays
    latched = np.flatnonzero(arrays["request_active"] > 0)
    assert arrays["time_s"][latched[0]] == pytest.approx(k * 0.01, abs=1e-12)
    # the full brake acts from the latch on, and a brake request above 0 cuts the driver's throttle
    assert np.all(arrays["brake_1"][latched] == 1.0) and np.all(arrays["throttle_1"][latched] == 0.0)
    before = slice(1, latched[0])
    assert np.all(arrays["throttle_1"][before] > 0) and np.all(arrays["request_brake_1"][before] == 0.0)
    assert np.all(arrays["driver_throttle_1"][latched[:5]] > 0)  # the driver still asks for throttle
    collision = next(e for e in result.events if e["action"] == "collision")
    # the contact is bisected to 1e-6 s and logged at its bracket's high end: at most A x 1e-6 = 8e-6 m/s slower;
    # the Simple model integrates the locked slide to ~1e-9 relative (docs/verification.md)
    assert collision["speed"] == pytest.approx(expected, abs=1e-5)
    assert expected == pytest.approx(4.0976, abs=1e-4)  # the worked number: 14.75 km/h
    # the target stands still and the ego brakes straight: the relative impact speed is the ego's
    assert collision["relative_speed"] == pytest.approx(expected, abs=1e-5)
    assert collision["distance"] == pytest.approx(SPAWN - (EGO_LENGTH + TARGET_LENGTH) / 2, abs=1e-6)
    assert "time_uncertainty_s" not in collision
    summary = result.summary
    assert summary["controller"]["fmi_version"] == f"{version}.0" and summary["controller"]["period_s"] == 0.01
    assert summary["controller"]["can_roll_back"] is False
    assert summary["controller"]["outputs"] == ["active", "brake"]


def test_a_request_that_overflows_in_si_is_the_runs_one_line(tmp_path, ccrs, controllers):
    """A controller output of 1e308 once ran to exit 0 with numpy's RuntimeWarning and the column empty. Here the
    foreign AEB requests decel_g = 1e308 g once it latches (at the sample k of the 1.5 s trigger, by hand as above): a
    finite output whose SI value (x 9.80665) overflows a double. The run ends at that sample in one line naming the
    output, exit 2, no warning and nothing written; the API raises the same line."""
    g0 = SPAWN - (EGO_LENGTH + TARGET_LENGTH) / 2  # the bumper gap at t = 0; the lane driver holds V0 until the latch
    k = next(k for k in range(100_000) if (g0 - V0 * k * 0.01) / V0 <= 1.5)  # k = 251: t = 2.51 s
    cmap = aeb_map(tmp_path, 1.5, replace=('brake  = { variable = "brake_cmd_pct", scale = 0.01 }',
                                           'deceleration = { variable = "decel_cmd", unit = "standard_gravity" }'))
    cmap.write_text(cmap.read_text().replace("cycle_time = 0.01", "cycle_time = 0.01\ndecel_g = 1e308"))
    output = f"its output 'decel_cmd' (deceleration) is 1e+308 at t = {k * 0.01:.6f} s: beyond 1e+09 in SI units"
    line = f"the controller ForeignAeb.fmu failed: {output}"
    failed = sdl_fmu("run", ccrs, "--speed", V0, "--controller", controllers[(3, False)], "--controller-map", cmap,
                     "--out", tmp_path / "never")
    assert (failed.returncode, failed.stdout, failed.stderr) == (2, "", f"sdl-fmu: {line}\n")
    assert not (tmp_path / "never").exists()
    with pytest.raises(api.InputError, match=re.escape(output)):  # the FMI 2.0 build (PythonFMU) alike
        api.run(ccrs, speed=V0, controller=controllers[(2, False)], controller_map=cmap, until_time=10.0)


def test_a_controller_that_cannot_roll_back_keeps_every_instant_exact(tmp_path, ccrs, controllers):
    """The controller is stepped only at its samples, instants the master steps to, never inside a located step: a
    controller without FMU state get/set gives the very same run as one with it, every event exact (no
    time_uncertainty_s), whatever --step. The controller itself fails any step that does not start where the last
    one ended (tests/controllers/foreign_aeb_logic.py), so these runs also show it was never stepped again."""
    cmap = aeb_map(tmp_path, 0.8)
    runs = {(state, step): api.run(ccrs, speed=V0, controller=controllers[(2, state)], controller_map=cmap,
                                   until_time=8.0, step=step)
            for state in (False, True) for step in (1.0, 0.01)}
    reference = runs[(True, 1.0)]
    for (state, step), result in runs.items():
        events = list(result.events)
        assert not any("time_uncertainty_s" in event for event in events)
        assert not any("cannot get and set" in warning for warning in result.warnings)
        assert [(e["code"], e["action"]) for e in events] == [(e["code"], e["action"]) for e in reference.events]
        for event, other in zip(events, reference.events):
            assert event["time_s"] == pytest.approx(other["time_s"], abs=1e-6)  # bisected to 1e-6 s at any step
        # the criticality extremes, located inside steps from FMU snapshots of the ego alone, are the same instants
        for key in ("min_distance_time_s", "min_ttc_time_s", "max_drac_time_s"):
            if reference.criticality.get(key) is not None:
                assert result.criticality[key] == pytest.approx(reference.criticality[key], abs=1e-6), key
        if step == 1.0:
            for name, values in reference.arrays.items():
                assert np.array_equal(result.arrays[name], values, equal_nan=True), name
            assert result.criticality == reference.criticality


def test_a_deceleration_request_is_turned_into_pedal_by_the_vehicle(tmp_path, ccrs, controllers, defaults_simple):
    """decel_cmd in g (the map's unit, through pint): 0.4 g requested -> brake = 0.4 x 9.80665 / brake_decel_max."""
    cmap = aeb_map(tmp_path, 1.5, replace=('brake  = { variable = "brake_cmd_pct", scale = 0.01 }',
                                           'deceleration = { variable = "decel_cmd", unit = "standard_gravity" }'))
    cmap.write_text(cmap.read_text().replace("cycle_time = 0.01", "cycle_time = 0.01\ndecel_g = 0.4"))
    result = api.run(ccrs, speed=V0, controller=controllers[(3, False)], controller_map=cmap, until_time=10.0)
    arrays = result.arrays
    latched = np.flatnonzero(arrays["request_active"] > 0)
    assert np.allclose(arrays["request_deceleration_m/s2"][latched], 0.4 * G, rtol=1e-12)
    pedal = 0.4 * G / defaults_simple["brake_decel_max"]
    assert np.allclose(arrays["brake_1"][latched], pedal, rtol=1e-12)
    assert np.all(arrays["throttle_1"][latched] == 0.0)
    assert "request_brake_1" not in arrays


def test_on_collision_stop_ends_the_run_at_the_first_contact(tmp_path, ccrs, controllers):
    cmap = aeb_map(tmp_path, 0.8)
    go_on = api.run(ccrs, speed=V0, controller=controllers[(2, False)], controller_map=cmap, until_time=8.0)
    stop = api.run(ccrs, speed=V0, controller=controllers[(2, False)], controller_map=cmap, until_time=8.0,
                   on_collision="stop")
    contact = next(e for e in go_on.events if e["action"] == "collision")
    end = list(stop.events)[-1]
    assert end["code"] == "ES" and end["reason"] == "collision" and end["time_s"] == contact["time_s"]
    assert stop.final["time_s"] == contact["time_s"] and stop.collisions == 1
    assert list(go_on.events)[-1]["reason"] == "until_time"


def test_a_controller_that_fails_is_one_line_naming_it(tmp_path, ccrs, controllers):
    """The foreign AEB fails a step of another length than its cycle_time: a map period of 0.02 s."""
    cmap = aeb_map(tmp_path, 0.8, replace=("period = 0.01", "period = 0.02"))
    with pytest.raises(api.InputError) as caught:
        api.run(ccrs, speed=V0, controller=controllers[(2, False)], controller_map=cmap, until_time=2.0)
    assert caught.value.option == "controller" and "\n" not in str(caught.value)
    assert "the controller ForeignAebFmi2.fmu failed at t = 0.000000 s" in str(caught.value)


def test_the_command_line_puts_a_controller_in_the_loop(tmp_path, ccrs, controllers):
    cmap = aeb_map(tmp_path, 0.8)
    out = tmp_path / "run"
    done = sdl_fmu("run", ccrs, "--speed", V0, "--controller", controllers[(3, False)], "--controller-map", cmap,
                   "--on-collision", "stop", "--until-time", 10, "--out", out)
    assert done.returncode == 0, done.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["controller"]["name"] == "ForeignAeb" and summary["events"][-1]["reason"] == "collision"
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert {"driver_throttle_1", "driver_brake_1", "driver_steer_rad", "request_active",
            "request_brake_1"} <= set(header)
    bad = tmp_path / "bad.toml"
    bad.write_text(cmap.read_text().replace('brake = "max"', 'brake = "most"'))
    failed = sdl_fmu("run", ccrs, "--controller", controllers[(3, False)], "--controller-map", bad,
                     "--out", tmp_path / "never")
    assert failed.returncode == 2 and failed.stdout == ""
    assert failed.stderr == (f"sdl-fmu: {bad}: arbitration.brake: 'most' must be one of 'driver', 'override', "
                             "'max'\n")
    assert not (tmp_path / "never").exists()
    alone = sdl_fmu("run", ccrs, "--controller", controllers[(3, False)], "--out", tmp_path / "never")
    assert alone.returncode == 2 and alone.stderr.startswith("sdl-fmu: --controller ")
    assert "needs a controller map" in alone.stderr


def test_a_sweep_runs_the_controller_in_every_run(tmp_path, ccrs, controllers):
    """The controller and its map travel to the workers as files; --vary is unaffected: at 30 km/h the latch at
    TTC 0.8 s (6.7 m) leaves room to stop (4.4 m), at 50 km/h it does not (above)."""
    import distributed

    from sdl_fmu import sweep

    cmap = aeb_map(tmp_path, 0.8)
    with local_cluster(1) as cluster, distributed.Client(cluster) as client:
        rows = sweep.sweep(str(ccrs), {"speed": [30 / 3.6, V0]}, tmp_path / "sweep", client=client,
                           controller=str(controllers[(2, False)]), controller_map=str(cmap), until_time=8.0,
                           on_collision="stop", progress=False)
    assert [row["status"] for row in rows] == ["ok", "ok"], rows
    assert [row["collisions"] for row in rows] == [0, 1]
