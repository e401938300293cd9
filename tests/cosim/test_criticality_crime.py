"""TTC and time headway against CommonRoad-CriMe (`commonroad-crime`, TUM) on the same trajectories: a straight
lane along x, the ego and a leading car at constant speeds, sampled every dt for CriMe.

CriMe rounds TTC to 0.01 s (utils_gen.int_round(value, 2)), so the two agree within 0.005 s (+ round-off).
CriMe's THW is the first time step at which the ego's front has passed the point where the leader's rear was
(measure/time/thw.py: a strict `>` on sampled positions), so it lies in (THW, THW + dt].
CriMe's TTC takes both speeds along the lanelet's direction whatever the vehicles' headings
(measure/time/ttc.py: |v| cos(lanelet orientation)), so a head-on approach is not comparable there; it is
checked against its hand computation in test_criticality.py.

commonroad-crime is part of the `test` extra (`pip install -e '.[test]'`), so this runs wherever the tests do: a
missing package fails here, it is not skipped.

CriMe imports commonroad-reach, which compiles a Cython module with pyximport on its first import, into ~/.pyxbld
(shared by every process of the user). Two processes compiling it at once (pytest -n 2 collecting this file on a fresh
machine) write the same .c file together and one of them fails to compile it. So CriMe is imported in a fixture, not at
collection, by one process at a time (an flock), and the tests of this file run on one xdist worker."""

import contextlib
import fcntl
import importlib
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from commonroad.geometry.shape import Rectangle
from commonroad.prediction.prediction import TrajectoryPrediction
from commonroad.scenario.lanelet import Lanelet
from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
from commonroad.scenario.scenario import Scenario
from commonroad.scenario.state import CustomState, InitialState
from commonroad.scenario.trajectory import Trajectory

from sdl_fmu.cosim.geometry import Footprint
from sdl_fmu.cosim.measures import headway, ttc

DT = 0.1  # s, CriMe's time step
STEPS = 200
EGO = (4.6, 1.8)  # m
EGO_SPEED = 25.0  # m/s
LEADERS = {  # id: (start x of the centre, speed m/s, length, width); all in the ego's lane, same way
    11: (50.0, 20.0, 4.5, 1.8),
    12: (80.3, 10.0, 12.0, 2.5),
    13: (33.7, 24.0, 4.0, 1.7),
}


def obstacle(vehicle_id: int, x0: float, speed: float, length: float, width: float) -> DynamicObstacle:
    states = [CustomState(time_step=k, position=np.array([x0 + speed * k * DT, 0.0]), orientation=0.0,
                          velocity=speed, acceleration=0.0, yaw_rate=0.0, slip_angle=0.0) for k in range(STEPS)]
    shape = Rectangle(length, width)
    initial = InitialState(time_step=0, position=states[0].position, orientation=0.0, velocity=speed,
                           acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    return DynamicObstacle(vehicle_id, ObstacleType.CAR, shape, initial,
                           TrajectoryPrediction(Trajectory(1, states[1:]), shape))


pytestmark = pytest.mark.xdist_group("commonroad-crime")  # one worker imports CriMe (see the module's docstring)


@contextlib.contextmanager
def pyximport_lock():
    """Held while CriMe is first imported: pyximport's build folder, ~/.pyxbld, is shared by every process."""
    folder = Path.home() / ".pyxbld"
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".sdl-fmu-tests.lock", "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield


@pytest.fixture(scope="module")
def crime():
    """CriMe's configuration class and its TTC and THW measures."""
    with pyximport_lock():
        configuration = importlib.import_module("commonroad_crime.data_structure.configuration")
        time_measures = importlib.import_module("commonroad_crime.measure.time.ttc"), \
            importlib.import_module("commonroad_crime.measure.time.thw")
    return configuration.CriMeConfiguration, time_measures[0].TTC, time_measures[1].THW


@pytest.fixture(scope="module")
def configuration(crime):
    CriMeConfiguration = crime[0]
    logging.getLogger("commonroad_crime").setLevel(logging.ERROR)
    x = np.linspace(-200, 3000, 33)
    lane = Lanelet(np.column_stack([x, np.full_like(x, 1.8)]), np.column_stack([x, np.zeros_like(x)]),
                   np.column_stack([x, np.full_like(x, -1.8)]), 1)
    scenario = Scenario(DT)
    scenario.add_objects(lane)
    scenario.add_objects(obstacle(10, 0.0, EGO_SPEED, *EGO))
    for vehicle_id, (x0, speed, length, width) in LEADERS.items():
        scenario.add_objects(obstacle(vehicle_id, x0, speed, length, width))
    scenario.assign_obstacles_to_lanelets()
    config = CriMeConfiguration()
    config.update(ego_id=10, sce=scenario)
    return config


@pytest.mark.parametrize("vehicle_id", sorted(LEADERS))
def test_ttc_and_headway_agree_with_commonroad_crime(crime, configuration, vehicle_id):
    _, TTC, THW = crime
    x0, speed, length, width = LEADERS[vehicle_id]
    ego = Footprint.of(*EGO, 0.0)
    ttc_measure, thw_measure = TTC(configuration), THW(configuration)
    compared = 0
    for step in (0, 5, 17, 40):
        t = step * DT
        dx = x0 + speed * t - EGO_SPEED * t
        ours = ttc(ego, dx, 0.0, speed - EGO_SPEED, 0.0, length, width)
        theirs = ttc_measure.compute(vehicle_id, step, verbose=False)
        if math.isinf(theirs) and math.isinf(ours):
            continue
        assert abs(ours - theirs) <= 0.005 + 1e-9, (step, ours, theirs)
        ours_thw = headway(ego, dx, 0.0, EGO_SPEED, speed, length, width)
        theirs_thw = thw_measure.compute(vehicle_id, step, verbose=False)
        assert ours_thw < theirs_thw <= ours_thw + DT + 1e-9, (step, ours_thw, theirs_thw)
        compared += 1
    assert compared >= 2
