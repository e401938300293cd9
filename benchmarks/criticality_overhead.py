"""What the criticality measures add to a run's simulation time: the master as shipped (it measures them)
against the same master with the measures switched off (a follower that measures nothing), side by
side in one process, alternating, by CPU time (time.process_time: the machine is shared), on the demo and on
roads with 1 ... N oncoming vehicles (linear in the number of vehicles?).

    python benchmarks/criticality_overhead.py [--repeat N] [--vehicle-repeat M] [--vehicles 1,8,32] [--json OUT]

OUT (default benchmarks/results/criticality_overhead.json) holds `measured` (when and where), `repeat`, and
`cases`: per scenario its `name`, `pairs`, `steps`, `located` (instants the measures located), the best CPU times
`plain_s` and `measured_s`, `overhead_best` (their ratio - 1) and the median, quartiles, least and largest of the
pairwise ratios - 1 (`overhead_median`, `overhead_q1`, `overhead_q3`, `overhead_min`, `overhead_max`), and
`added_per_vehicle_s` (the median pairwise CPU added over the number of vehicles spawned: constant if linear).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from provenance import stamp

from sdl_fmu.cosim.follower import CriticalityFollower
from sdl_fmu.cosim.master import Cosimulation, RunOptions
from sdl_fmu.fmu.cache import cached_fmus
from sdl_fmu.paths import SCENARIO_DIRECTORY
from sdl_fmu.sdl import default_vehicle_table_path, load_scenario, load_vehicle_table, parse_text

RESULT = Path(__file__).parent / "results" / "criticality_overhead.json"


class Blind(CriticalityFollower):
    """A criticality follower that measures nothing: no looks, no snapshots, no located instants."""

    def start(self, state):
        self.touched.clear()

    def wants_snapshot(self, state, limit):
        return False

    def stepped(self, base, t0, state, fired):
        pass

    def changing(self, i, state):
        pass

    def lane_leave_instant(self, i, state):
        pass

    fired = finish = start


class WithoutCriticality(Cosimulation):
    """The master with a follower that measures nothing (the TTC series for the plot is computed only when asked
    for, not in a run)."""

    def __init__(self, *args):
        super().__init__(*args)
        follower = self.follower
        self.follower = Blind(self.ego, self.traffic, self.bounds, self.road, follower.exact)


def traffic_scenario(vehicles: int):
    """A straight run with `vehicles` cars oncoming in the other lane, one spawned every 100 ft (at 20 ft/s,
    1000 ft ahead): each passes the ego within the run."""
    lines = ["English"] + [f"{100 + 100 * k},A,20,1000,-6,1" for k in range(vehicles)]
    return parse_text("\n".join(lines + [f"{100 * vehicles + 1500},ES"]), f"traffic{vehicles}.sdl")


def compare(scenario, fmu, table, repeat: int) -> dict:
    plain, measured = [], []
    for _ in range(repeat):
        for kind, times in ((WithoutCriticality, plain), (Cosimulation, measured)):
            began = time.process_time()
            run = kind(scenario, fmu, RunOptions(), table)
            run.run()
            times.append(time.process_time() - began)
    ratios = [b / a - 1 for a, b in zip(plain, measured)]
    q1, _, q3 = statistics.quantiles(ratios, n=4)
    return {"pairs": repeat, "plain_s": min(plain), "measured_s": min(measured),
            "overhead_best": min(measured) / min(plain) - 1, "overhead_median": statistics.median(ratios),
            "overhead_q1": q1, "overhead_q3": q3, "overhead_min": min(ratios), "overhead_max": max(ratios),
            "added_per_vehicle_s": statistics.median([b - a for a, b in zip(plain, measured)])
            / len(run.recorder.vehicle_ids),
            "located": run.follower.located, "steps": run.steps}


def main() -> None:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--repeat", type=int, default=41, help="pairs on the demo")
    arguments.add_argument("--vehicle-repeat", type=int, default=11, help="pairs on each N-vehicle road")
    arguments.add_argument("--vehicles", default="1,8,32")
    arguments.add_argument("--json", default=str(RESULT))
    args = arguments.parse_args()
    table = load_vehicle_table(default_vehicle_table_path())
    fmu = cached_fmus("simple", (2,))[0]
    cases = [("demo", load_scenario(SCENARIO_DIRECTORY / "demo.sdl"), args.repeat)]
    cases += [(f"{n} oncoming", traffic_scenario(n), args.vehicle_repeat) for n in map(int, args.vehicles.split(","))]
    report = {"repeat": args.repeat, "cases": []}
    for name, scenario, repeat in cases:
        r = compare(scenario, fmu, table, repeat)
        report["cases"].append({"name": name, **r})
        print(f"{name:12s} plain {r['plain_s']:.3f} s CPU, measured {r['measured_s']:.3f} s: best-of "
              f"{r['overhead_best'] * 100:+.1f} %, pairwise median {r['overhead_median'] * 100:+.1f} % "
              f"(quartiles {r['overhead_q1'] * 100:+.1f} … {r['overhead_q3'] * 100:+.1f} %, spread "
              f"{r['overhead_min'] * 100:+.1f} … {r['overhead_max'] * 100:+.1f} %, {repeat} pairs), "
              f"{r['added_per_vehicle_s'] * 1e3:.2f} ms per vehicle, {r['located']} located instants, "
              f"{r['steps']} steps", flush=True)
    measured = stamp("shared machine; CPU time (time.process_time), pairs alternating in one process")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps({"measured": measured, **report}, indent=2) + "\n")


if __name__ == "__main__":
    main()
