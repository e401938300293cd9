"""An estimate, before the master calls the measures, of what they will add to the demo's simulation time:
the demo (Simple, default settings) run plain and with the criticality record riding on every recorded
sample, side by side in one process, alternating, best of N, by CPU time.

At every communication point, for each vehicle on the road whose horizon has come (at every point within
50 m, beyond it as the distance horizons allow), Extremes.look offers its values and returns its rates and
its next horizon. What this leaves
out, and the master will add: the bisections at the rates' sign changes (counted here; each costs about
as much as a trigger's bisection, some 20 probes with an FMU state restore and step).

    python benchmarks/criticality_overhead.py [--repeat N]
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from sdl_fmu.cosim.criticality import Extremes
from sdl_fmu.cosim.master import Cosimulation, RunOptions
from sdl_fmu.fmu.package import build_fmu
from sdl_fmu.interface import SCENARIO_DIRECTORY
from sdl_fmu.sdl import default_vehicle_table_path, load_scenario, load_vehicle_table


class WithCriticality(Cosimulation):
    """The record riding on the master as it would be wired: per vehicle a next-look instant, their minimum
    cached (one comparison per step while no look is due), every bound dropped when something fires (an
    action changes a vehicle's motion), as the master does with its traffic bounds."""

    def __init__(self, *args):
        super().__init__(*args)
        self.extremes = Extremes(*self.ego_size)
        self.next_look = np.zeros(16)
        self.earliest_look = -math.inf
        self.previous_rates: dict[int, tuple] = {}
        self.looks = self.sign_changes = 0

    def fire_due(self, state) -> None:
        super().fire_due(state)
        self.earliest_look = -math.inf
        self.next_look[:] = -math.inf

    def record(self, state) -> None:
        super().record(state)
        t = state.time
        if t < self.earliest_look:
            return
        traffic, bounds = self.traffic, self.bounds
        active = traffic.active.tolist()
        if len(self.next_look) < traffic.size:
            self.next_look = np.concatenate([self.next_look, np.full(traffic.size, -math.inf)])
        earliest = math.inf
        for i in active:
            look = float(self.next_look[i])
            if look <= t:
                self.looks += 1
                rates, horizon = self.extremes.look(traffic, i, state, bounds.acceleration, bounds.yaw_rate,
                                                    bounds.radius)
                previous = self.previous_rates.get(i)
                if previous is not None:
                    self.sign_changes += sum(1 for a, b in zip(previous, rates) if a < 0 <= b)
                self.previous_rates[i] = rates
                look = self.next_look[i] = t + horizon
            earliest = min(earliest, look)
        self.earliest_look = earliest


def main() -> None:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--repeat", type=int, default=5)
    args = arguments.parse_args()
    scenario = load_scenario(SCENARIO_DIRECTORY / "demo.sdl")
    table = load_vehicle_table(default_vehicle_table_path())
    with tempfile.TemporaryDirectory() as folder:
        fmu = build_fmu("simple", Path(folder))
        plain, riding = [], []
        for _ in range(args.repeat):
            for kind, times in ((Cosimulation, plain), (WithCriticality, riding)):
                began = time.process_time()
                run = kind(scenario, fmu, RunOptions(), table)
                run.run()
                times.append(time.process_time() - began)
        summary = run.extremes.summary(np.array(run.vehicle_ids), lambda value: value / 0.3048)
    print(f"plain {min(plain):.3f} s CPU, with the record {min(riding):.3f} s CPU: "
          f"+{(min(riding) / min(plain) - 1) * 100:.1f} % ({run.steps} steps, {run.looks} looks, "
          f"{run.sign_changes} sign changes to bisect)")
    print({k: v for k, v in summary.items() if k != "vehicles"})
    for vehicle in summary["vehicles"]:
        print(vehicle)


if __name__ == "__main__":
    main()
