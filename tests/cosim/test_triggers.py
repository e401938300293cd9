"""The trigger prediction's scalar fast paths against their array forms: the master uses `vehicle_horizon`
and `vehicle_condition` (plain floats) when only a few vehicles are concerned and `vehicle_horizons` and
`vehicle_conditions` (NumPy) otherwise, and the step ends, so the samples, and the firing decisions depend
on them: the two forms must agree bit for bit, not to a tolerance."""

import math

import numpy as np

from sdl_fmu.cosim.geometry import reach_time, reach_time_scalar
from sdl_fmu.cosim.traffic import Traffic
from sdl_fmu.cosim.triggers import (EgoBounds, EgoKinematics, vehicle_condition, vehicle_conditions, vehicle_horizon,
                                   vehicle_horizons)


TIES = (-1.0, 0.0, 2.0)  # stations shared by vehicles and the ego


def random_traffic(rng: np.random.Generator, n: int) -> Traffic:
    """n vehicles in every state the horizons branch on: before, during and after a transition; no action,
    positive and negative closure times, F / B / either; in contact or not; gaps from touching to far."""
    traffic = Traffic(capacity=n)
    traffic.size = n
    traffic.t0[:] = rng.uniform(0, 10, n)  # the ego's instants below are later
    # exact ties too: a vehicle standing at the ego's station (gap 0, gap rate 0 with a standing ego)
    traffic.station0[:] = rng.choice([rng.uniform(-5, 5, n), rng.uniform(-200, 200, n), rng.choice(TIES, n)], axis=0)
    traffic.lateral0[:] = rng.uniform(-6, 6, n)
    traffic.lateral1[:] = np.where(rng.random(n) < 0.5, traffic.lateral0, rng.uniform(-6, 6, n))
    traffic.speed0[:] = np.where(rng.random(n) < 0.2, 0.0, rng.uniform(-30, 40, n))
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


BOUNDS = EgoBounds(acceleration=15.2, yaw_rate=1.3, length=4.6, width=1.8, radius=math.hypot(2.3, 0.9),
                   wheel_arm=1.9)


def random_egos(rng: np.random.Generator, count: int):
    for _ in range(count):
        yield EgoKinematics(time=float(rng.uniform(10, 25)), station=float(rng.choice(TIES)),
                            lateral=float(rng.uniform(-4, 4)), station_rate=float(rng.choice([0.0, 3.0, 27.0, -2.0])),
                            lateral_rate=float(rng.choice([0.0, 0.4, -3.5])), psi=float(rng.choice([0.0, 0.1, -2.9])))


def test_scalar_vehicle_horizon_equals_the_array_form_bit_for_bit():
    rng = np.random.default_rng(11)
    traffic = random_traffic(rng, 4000)
    checked = 0
    with np.errstate(invalid="ignore"):  # the array form computes every branch, NaN ones included
        for ego in random_egos(rng, 12):
            expected = vehicle_horizons(traffic, traffic.active, ego, BOUNDS)
            got = np.array([vehicle_horizon(traffic, i, ego, BOUNDS) for i in range(traffic.size)])
            assert np.array_equal(got, expected), np.flatnonzero(got != expected)[:10]
            checked += np.isfinite(expected).sum()
    assert checked > 10000  # most cases give a finite bound, not inf on both sides


def test_scalar_vehicle_condition_equals_the_array_form():
    rng = np.random.default_rng(12)
    traffic = random_traffic(rng, 4000)
    counts = np.zeros(3, dtype=int)
    for ego in random_egos(rng, 12):
        expected = np.column_stack(vehicle_conditions(traffic, traffic.active, ego, BOUNDS))
        got = np.array([vehicle_condition(traffic, i, ego, BOUNDS) for i in range(traffic.size)])
        assert np.array_equal(got, expected), np.flatnonzero((got != expected).any(axis=1))[:10]
        counts += expected.sum(axis=0)
    assert (counts > 100).all()  # each condition both true and (overwhelmingly) false among the cases


def test_reach_time_of_a_margin_already_used_up_is_zero_whatever_the_rate():
    # A margin at or below 0 (e.g. footprints already overlapping lengthwise while the lateral gap closes)
    # may make its condition true now: its bound must be 0. The root form alone, (root - rate) / A with
    # root = |rate| at distance 0, gives the later root 2 |rate| / A for a rate < 0 (1.33 s for rate -10,
    # A 15), and a collision inside that time went unnoticed.
    assert reach_time_scalar(0.0, -10.0, 15.0) == 0.0
    assert float(reach_time(0.0, -10.0, 15.0)) == 0.0
    rng = np.random.default_rng(7)
    distance = np.concatenate([rng.uniform(-5, 5, 2000), np.zeros(50)])
    rate = np.concatenate([rng.uniform(-20, 20, 2000), rng.uniform(-20, 20, 50)])
    acceleration = rng.uniform(0.5, 30, distance.size)
    array_form = reach_time(distance, rate, acceleration)
    assert np.all(array_form[distance <= 0] == 0.0)
    # elsewhere the smallest root of rate tau + A tau^2 / 2 = distance, checked by substitution
    tau = array_form[distance > 0]
    d, r, a = distance[distance > 0], rate[distance > 0], acceleration[distance > 0]
    assert np.all(tau > 0) and np.allclose(r * tau + a * tau**2 / 2, d, rtol=1e-12, atol=1e-12)
    scalar_form = [reach_time_scalar(float(x), float(y), float(z)) for x, y, z in zip(distance, rate, acceleration)]
    assert np.array_equal(array_form, scalar_form)  # the same operations: the same bits
