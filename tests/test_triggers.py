"""The trigger prediction's scalar fast path against its array form: the master uses `vehicle_horizon`
(plain floats) when only a few vehicles' bounds are stale and `vehicle_horizons` (NumPy) otherwise, and
the step ends, so the samples, depend on those bounds: the two must agree bit for bit, not to a tolerance."""

import math

import numpy as np

from sdl_fmu.cosim.traffic import Traffic
from sdl_fmu.cosim.triggers import EgoBounds, EgoKinematics, vehicle_horizon, vehicle_horizons


def random_traffic(rng: np.random.Generator, n: int) -> Traffic:
    """n vehicles in every state the horizons branch on: before, during and after a transition; no action,
    positive and negative closure times, F / B / either; in contact or not; gaps from touching to far."""
    traffic = Traffic(capacity=n)
    traffic.size = n
    traffic.t0[:] = rng.uniform(0, 10, n)  # the ego's instants below are later
    traffic.station0[:] = rng.choice([rng.uniform(-5, 5, n), rng.uniform(-200, 200, n)], axis=0)
    traffic.lateral0[:] = rng.uniform(-6, 6, n)
    traffic.lateral1[:] = np.where(rng.random(n) < 0.5, traffic.lateral0, rng.uniform(-6, 6, n))
    traffic.speed0[:] = rng.uniform(-30, 40, n)
    traffic.speed1[:] = np.where(rng.random(n) < 0.5, traffic.speed0, rng.uniform(-30, 40, n))
    traffic.duration[:] = rng.choice([0.0, 2.0, 15.0], n)
    traffic.length[:] = rng.uniform(3, 12, n)
    traffic.width[:] = rng.uniform(1.5, 2.6, n)
    traffic.trigger_seconds[:] = rng.choice([np.nan, 2.0, 10.0, -3.0], n)
    traffic.where[:] = rng.integers(0, 3, n)
    traffic.in_contact[:] = rng.random(n) < 0.3
    traffic.present[:] = True
    traffic.active = np.arange(n)
    return traffic


def test_scalar_vehicle_horizon_equals_the_array_form_bit_for_bit():
    rng = np.random.default_rng(11)
    traffic = random_traffic(rng, 4000)
    bounds = EgoBounds(acceleration=15.2, yaw_rate=1.3, length=4.6, width=1.8, radius=math.hypot(2.3, 0.9),
                       wheel_arm=1.9)
    checked = 0
    for _ in range(8):
        ego = EgoKinematics(time=float(rng.uniform(10, 25)), station=float(rng.uniform(-5, 5)),
                            lateral=float(rng.uniform(-4, 4)), station_rate=float(rng.choice([0.0, 3.0, 27.0, -2.0])),
                            lateral_rate=float(rng.choice([0.0, 0.4, -3.5])), psi=float(rng.choice([0.0, 0.1, -2.9])))
        expected = vehicle_horizons(traffic, traffic.active, ego, bounds)
        got = np.array([vehicle_horizon(traffic, i, ego, bounds) for i in range(traffic.size)])
        assert np.array_equal(got, expected), np.flatnonzero(got != expected)[:10]
        checked += np.isfinite(expected).sum()
    assert checked > 10000  # most cases give a finite bound, not inf on both sides
