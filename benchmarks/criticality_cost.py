"""Per-call CPU cost of the criticality measures (measures.py, extremes.py), in plain floats and in arrays, to budget
their integration in the master (the demo spends about 38 µs per communication step in all, Simple).

    python benchmarks/criticality_cost.py
"""

import math
import time
from typing import NamedTuple

import numpy as np

from sdl_fmu.cosim.extremes import Extremes
from sdl_fmu.cosim.geometry import Footprint
from sdl_fmu.cosim.measures import approach_horizon, distance, distance_rate, distances, headway, ttc, ttc_rate, ttcs
from sdl_fmu.cosim.traffic import Traffic


class State(NamedTuple):
    time: float
    x: float
    y: float
    psi: float
    vx: float
    vy: float
    ax: float
    ay: float
    yaw_rate: float


def per_call(function, repeat: int = 20000) -> float:
    """µs of CPU per call, best of 3."""
    best = math.inf
    for _ in range(3):
        start = time.process_time()
        for _ in range(repeat):
            function()
        best = min(best, (time.process_time() - start) / repeat * 1e6)
    return best


def traffic_of(n: int) -> Traffic:
    rng = np.random.default_rng(1)
    traffic = Traffic(capacity=n)
    traffic.size = n
    traffic.station0[:n] = rng.uniform(20, 200, n)
    traffic.lateral0[:n] = traffic.lateral1[:n] = rng.choice([-3.6, 0.0], n)
    traffic.speed0[:n] = traffic.speed1[:n] = rng.uniform(-20, 25, n)
    traffic.length[:n], traffic.width[:n] = 4.5, 1.8
    traffic.active = np.arange(n)
    return traffic


def main() -> None:
    ego = Footprint.of(4.6, 1.8, 0.02)
    calls = {
        "distance (float)": lambda: distance(ego, 30.0, 3.6, 4.5, 1.8),
        "distance_rate (float)": lambda: distance_rate(ego, 30.0, 3.6, -45.0, 0.1, 0.01, 4.5, 1.8),
        "ttc (float)": lambda: ttc(ego, 30.0, 0.5, -45.0, 0.1, 4.5, 1.8),
        "ttc_rate (float)": lambda: ttc_rate(ego, 30.0, 0.5, -45.0, 0.1, 1.0, 0.0, 0.01, 4.5, 1.8),
        "headway (float)": lambda: headway(ego, 30.0, 0.5, 25.0, 20.0, 4.5, 1.8),
        "approach_horizon (float)": lambda: approach_horizon(30.0, -40.0, 45.0, 2.6, 15.0, 1.3),
    }
    for name, call in calls.items():
        print(f"{name:28} {per_call(call):6.2f} µs")
    state = State(1.0, 25.0, 0.0, 0.02, 25.0, 0.1, 0.5, 0.1, 0.01)
    for n in (1, 4, 16, 64):
        traffic = traffic_of(n)
        extremes = Extremes(4.6, 1.8)
        idx = traffic.active
        cost = per_call(lambda: extremes.observe(traffic, idx, state), 2000)
        print(f"Extremes.observe, {n:2d} vehicles {cost:7.1f} µs")
    traffic = traffic_of(2)
    traffic.station0[:2] = 40.0, 300.0  # within RANGE and beyond
    extremes = Extremes(4.6, 1.8)
    for i, where in enumerate(("within 50 m", "beyond 50 m")):
        cost = per_call(lambda: extremes.look(traffic, i, state, 15.0, 2.5, 2.5), 5000)
        print(f"Extremes.look, {where}  {cost:6.2f} µs")
    print(f"Extremes.rates, 1 vehicle    {per_call(lambda: extremes.rates(traffic, 0, state), 5000):6.2f} µs")
    dx = np.linspace(10, 200, 64)
    cost = per_call(lambda: (distances(ego, dx, 3.6, 4.5, 1.8), ttcs(ego, dx, 3.6, -45.0, 0.0, 4.5, 1.8)), 2000)
    print(f"distances + ttcs, 64 (array) {cost:6.1f} µs")


if __name__ == "__main__":
    main()
