"""The orchestrator with the Advanced FMU: RSA attribute numbers per wheel, BRK ignored, the STISIM
text's examples run, tire attribute files."""

import math

import numpy as np
import pytest

from sdl_fmu.cosim.master import RunOptions, run_scenario
from sdl_fmu.paths import SCENARIO_DIRECTORY
from sdl_fmu.sdl import load_scenario, parse_text
from sdl_fmu.units import FOOT
from sdl_fmu.vehicle import EgoModel, shipped_map_path

from helpers import NO_RESISTANCES, TABLE


def model(fmu, parameters=None):
    """The Advanced FMU through its shipped map, its tire slots filled from the shipped Tire Attribute File."""
    model = EgoModel.open(fmu, shipped_map_path("advanced")).with_tires().with_parameters(parameters)
    assert model.warnings == () and model.known_attributes == {0, 1, 2, 3, 4}
    return model


def test_rsa_example_sets_attribute_numbers_under_each_wheel(advanced_fmu):
    # The STISIM text's advanced RSA example: lane 1 gets attribute 1 from 1000 ft to 1100 ft. The wheels of the
    # Advanced FMU sit cg_to_front_axle ahead of and cg_to_rear_axle behind the CG, so the front-left
    # wheel reads attribute 1 while its station is in [1000, 1100) ft, i.e. while the CG station is in
    # [1000 ft - a, 1100 ft - a); the rear wheels while it is in [1000 ft + b, 1100 ft + b).
    scenario = load_scenario(SCENARIO_DIRECTORY / "road_surface_advanced.sdl")
    result = run_scenario(scenario, model(advanced_fmu), RunOptions(until_distance=1300 * FOOT), TABLE)
    assert result.warnings == []
    sets = [(e["lane"], e["value"]) for e in result.events if e["code"] == "RSA"]
    assert sets == [(1, 1), (-5, 2), (101, 3), (1, 0), (-5, 1)]
    station = result.columns["station"]
    a, b = 1.1, 1.6  # the FMU's default cg_to_front_axle / cg_to_rear_axle
    front_on = (station >= 1000 * FOOT - a) & (station < 1100 * FOOT - a)
    rear_on = (station >= 1000 * FOOT + b) & (station < 1100 * FOOT + b)
    # the sample at a crossing is within 1e-6 s (3e-5 m) of it, where the small yaw angle of the lane
    # keeping moves the contact point by ~1e-5 m: compare away from the boundaries
    boundaries = np.array([1000 * FOOT - a, 1100 * FOOT - a, 1000 * FOOT + b, 1100 * FOOT + b])
    clear = np.abs(station[:, None] - boundaries).min(axis=1) > 1e-3
    assert (result.columns["surface_fl"] == np.where(front_on, 1, 0))[clear].all()
    assert (result.columns["surface_rr"] == np.where(rear_on, 1, 0))[clear].all()
    # and every change happens at a located crossing, not a grid point: a sample sits on each boundary
    assert (np.abs(station[:, None] - boundaries).min(axis=0) < 1e-3).all()


def test_brk_is_ignored_with_a_warning(advanced_fmu):
    result = run_scenario(parse_text("100,BRK,100,0,3", "brk.sdl"), model(advanced_fmu),
                          RunOptions(until_distance=200 * FOOT), TABLE)
    assert not [e for e in result.events if e["code"] == "BRK"]
    assert result.warnings == ["line 1: BRK ignored: brake events act only with simple dynamics"]
    assert (result.columns["brake"] == 0).all()


def test_unknown_attribute_falls_back_with_a_warning(advanced_fmu):
    result = run_scenario(parse_text("10,RSA,1,9", "rsa.sdl"), model(advanced_fmu),
                          RunOptions(until_distance=100 * FOOT), TABLE)
    assert result.warnings == ["line 1: RSA attribute 9 (lane 1) has no entry in the Tire Attribute File: "
                               "attribute 0 (standard tires) is used"]


def test_approaching_vehicle_example_runs_with_advanced_dynamics(advanced_fmu):
    # The STISIM text's A example at 60 ft/s with drag and rolling resistance off: the driver holds the speed, so
    # the hand computation of the simple-dynamics test holds: closing at 80 ft/s, spawn at 100/60 s,
    # action 1 at gap 800 ft (2.5 s later), action 2 at gap 400 ft (7.5 s after the spawn).
    scenario = load_scenario(SCENARIO_DIRECTORY / "approaching_vehicle.sdl")
    result = run_scenario(scenario, model(advanced_fmu, NO_RESISTANCES), RunOptions(speed=60 * FOOT), TABLE)
    times = {(e["action"], e.get("index")): e["time_s"] for e in result.events if e["code"] == "A"}
    spawn = 100 / 60
    assert times[("spawn", None)] == pytest.approx(spawn, abs=1e-5)
    assert times[("maneuver", 1)] == pytest.approx(spawn + 2.5, abs=0.02)
    assert times[("maneuver", 2)] == pytest.approx(spawn + 7.5, abs=0.02)
    assert math.isclose(result.final["speed"], 60.0 * FOOT, abs_tol=0.05 * FOOT)  # the record is SI
