"""BRK's use case in the STISIM text as a scenario (scenarios/spin.sdl): BRK on split friction (RSA) makes the
Simple-dynamics car begin to spin; the driver model counter-steers and brings it back to its lane."""

import csv

import numpy as np
import pytest

from sdl_fmu.cosim import driver
from sdl_fmu.cosim.master import RunOptions, run_scenario
from sdl_fmu.paths import SCENARIO_DIRECTORY
from sdl_fmu.results import write_results
from sdl_fmu.sdl import load_scenario
from sdl_fmu.units import FOOT

from helpers import TABLE, as_written

SCENARIO = SCENARIO_DIRECTORY / "spin.sdl"


def run(fmu):
    return as_written(run_scenario(load_scenario(SCENARIO), fmu, RunOptions(), TABLE))


@pytest.fixture(scope="module")
def spin(simple_fmu):
    return run(simple_fmu)


def test_split_friction_brake_makes_the_car_begin_to_spin(spin, defaults_simple):
    c = spin.columns
    on, = [e for e in spin.events if e["code"] == "BRK" and e["action"] == "on"]
    off, = [e for e in spin.events if e["code"] == "BRK" and e["action"] == "off"]
    assert off["reason"] == "time" and off["time_s"] - on["time_s"] == pytest.approx(0.8, abs=1e-5)
    # at the onset the left wheels are on ice (mu 0.1), the right on 0.8, all locked by the full pedal:
    # dr/dt = t m g (mu_left - mu_right) / (4 I_z) < 0, toward the high-friction (right) side
    onset = int(np.searchsorted(c["time"], on["time_s"]))
    assert [c[f"mu_{w}"][onset] for w in ("fl", "fr", "rl", "rr")] == [0.1, 0.8, 0.1, 0.8]
    p = defaults_simple
    yaw_acceleration = p["track"] * p["mass"] * 9.80665 * (0.1 - 0.8) / 4 / p["yaw_inertia"]
    braking = (c["time"] > on["time_s"]) & (c["time"] <= off["time_s"])
    assert yaw_acceleration < 0 and np.all(c["yaw_rate"][braking] < 0)
    # with every wheel sliding nothing opposes the rotation: it begins to spin
    sideslip = np.degrees(np.arctan2(c["vy"], c["vx"]))
    print(f"min heading {np.degrees(c['psi']).min():.1f} deg, max side slip {sideslip.max():.1f} deg, "
          f"min yaw rate {np.degrees(c['yaw_rate']).min():.1f} deg/s")
    assert np.degrees(c["psi"]).min() < -15 and sideslip.max() > 15


def test_driver_counter_steers_within_its_limits_and_recovers(spin):
    c = spin.columns
    off, = [e for e in spin.events if e["code"] == "BRK" and e["action"] == "off"]
    # counter-steer: while the car yaws right (r < -0.2 rad/s) the driver steers left, up to MAX_STEER
    skidding = c["yaw_rate"] < -0.2
    assert skidding.any() and np.all(c["steer"][skidding] > 0)
    assert c["steer"].max() > 0.3 and np.abs(c["steer"]).max() <= driver.MAX_STEER
    # recovered: heading straight, back in the centre of lane 1 (2.5 ft), at the driver's speed again
    last = c["time"] > c["time"][-1] - 3.0
    lane_centre = spin.road.lane_center(1)
    assert np.abs(np.degrees(c["psi"][last])).max() < 0.5
    assert np.abs(c["lateral"][last] - lane_centre).max() < 0.5 * FOOT
    # and it stayed on the road (+ right: at most the right edge)
    assert c["lateral"].max() < spin.road.right_edge
    assert spin.final["speed"] > 80 and spin.collisions == 0


def test_without_counter_steer_the_car_spins_round(simple_fmu, monkeypatch):
    # the same run with the yaw-rate feedback switched off (pure pursuit only): a full spin
    monkeypatch.setattr(driver, "YAW_RATE_GAIN", 0.0)
    heading = np.degrees(run(simple_fmu).columns["psi"])
    print(f"without counter-steer: heading down to {heading.min():.0f} deg")
    assert np.abs(heading).max() > 180


def test_heading_yaw_rate_and_steering_in_the_results(spin, tmp_path):
    out = write_results(spin, tmp_path / "spin")
    with open(out / "timeseries.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert {"psi_rad", "yaw_rate_rad/s", "steer_rad", "vy_ft/s"} <= set(rows[0])
    psi = np.array([float(row["psi_rad"]) for row in rows])
    assert psi.min() == pytest.approx(spin.columns["psi"].min(), abs=1e-6)  # written with 6 decimals
    assert (out / "plot.png").stat().st_size > 50_000
