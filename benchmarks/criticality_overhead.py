"""What the criticality measures add to a run's simulation time: the master as shipped (it measures them)
against the same master with the measures switched off (a follower that measures nothing), side by
side in one process, alternating, by CPU time (time.process_time: the machine is shared), on the demo and on
roads with 1 ... N oncoming vehicles (linear in the number of vehicles?).

    python benchmarks/criticality_overhead.py [--repeat N] [--vehicle-repeat M] [--vehicles 1,8,32] [--json OUT]
                                              [--instructions]

OUT (default benchmarks/results/criticality_overhead.json) holds `measured` (when and where), `repeat`, and
`cases`: per scenario its `name`, `pairs`, `steps`, `located` (instants the measures located), the best CPU times
`plain_s` and `measured_s`, `overhead_best` (their ratio - 1) and the median, quartiles, least and largest of the
pairwise ratios - 1 (`overhead_median`, `overhead_q1`, `overhead_q3`, `overhead_min`, `overhead_max`), and
`added_per_vehicle_s` (the median pairwise CPU added over the number of vehicles spawned: constant if linear).
With --instructions, also the instructions each kind of run executes (`instructions_plain`, `instructions_measured`,
their ratio - 1 `overhead_instructions`), counted by valgrind's cachegrind: unlike CPU time they do not depend on
the machine's load (each kind runs INSTRUCTION_RUNS times in a process of its own after a warm-up run of both, less
the same process running neither), with OpenBLAS on one thread (`COUNTED_ENVIRONMENT`: its idle worker threads spin
for a time that depends on the scheduling, which valgrind counts: 1 oncoming measured +34 % with them, +12.6 %
twice in a row without). Runs use a private FMU cache holding only the Simple FMU's build (`private_cache`).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from provenance import stamp

from sdl_fmu.cosim.follower import CriticalityFollower
from sdl_fmu.cosim.master import Cosimulation, RunOptions
from sdl_fmu.fmu.cache import cached_fmus
from sdl_fmu.paths import CACHE_VARIABLE, SCENARIO_DIRECTORY
from sdl_fmu.sdl import default_vehicle_table_path, load_scenario, load_vehicle_table, parse_text

RESULT = Path(__file__).parent / "results" / "criticality_overhead.json"
INSTRUCTION_RUNS = 3
# the counted processes' environment: OpenBLAS's worker threads (NumPy's BLAS) spin while idle, and valgrind counts
# their instructions (blas_thread_server: tens of millions per process, varying from process to process)
COUNTED_ENVIRONMENT = {"OPENBLAS_NUM_THREADS": "1"}


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


def instructions(case: str) -> dict:
    """Instructions per run of each kind (valgrind's cachegrind), from processes that differ only in the runs."""
    counts = {}
    for kind in ("none", "plain", "measured"):
        completed = subprocess.run(["valgrind", "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null",
                                    sys.executable, __file__, "--one", kind, case], capture_output=True, text=True,
                                   check=True, env={**os.environ, **COUNTED_ENVIRONMENT})
        counts[kind] = int(re.search(r"I\s+refs:\s+([\d,]+)", completed.stderr)[1].replace(",", ""))
    plain = (counts["plain"] - counts["none"]) / INSTRUCTION_RUNS
    measured = (counts["measured"] - counts["none"]) / INSTRUCTION_RUNS
    return {"instructions_plain": plain, "instructions_measured": measured,
            "overhead_instructions": measured / plain - 1}


def private_cache(fmu: Path, folder: str) -> Path:
    """The FMU's build copied into an FMU cache of its own (`folder`), which this process and the processes it
    starts use from now on: an instance is made in process after the FMU's bytes are found among the cache's
    builds (each new build's digest taken once per process), and in a shared cache builds arriving during the
    measurement would be hashed inside one of the runs measured."""
    shutil.copytree(fmu.parents[1], Path(folder) / fmu.parents[1].name)
    os.environ[CACHE_VARIABLE] = folder
    return cached_fmus("simple", (2,))[0]


def one(kind: str, case: str) -> None:
    """The process `instructions` counts: a warm-up run of each kind, then INSTRUCTION_RUNS runs of `kind`."""
    table = load_vehicle_table(default_vehicle_table_path())
    fmu = cached_fmus("simple", (2,))[0]
    scenario = load_scenario(SCENARIO_DIRECTORY / "demo.sdl") if case == "demo" else traffic_scenario(int(case))
    for master in (WithoutCriticality, Cosimulation):
        master(scenario, fmu, RunOptions(), table).run()
    master = {"none": None, "plain": WithoutCriticality, "measured": Cosimulation}[kind]
    for _ in range(INSTRUCTION_RUNS if master else 0):
        master(scenario, fmu, RunOptions(), table).run()


def main() -> None:
    if sys.argv[1:2] == ["--one"]:
        one(*sys.argv[2:4])
        return
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--repeat", type=int, default=41, help="pairs on the demo")
    arguments.add_argument("--vehicle-repeat", type=int, default=11, help="pairs on each N-vehicle road")
    arguments.add_argument("--vehicles", default="1,8,32")
    arguments.add_argument("--json", default=str(RESULT))
    arguments.add_argument("--instructions", action="store_true", help="also count instructions (valgrind)")
    args = arguments.parse_args()
    table = load_vehicle_table(default_vehicle_table_path())
    private = tempfile.TemporaryDirectory(prefix="criticality-overhead-")
    fmu = private_cache(cached_fmus("simple", (2,))[0], private.name)
    cases = [("demo", load_scenario(SCENARIO_DIRECTORY / "demo.sdl"), args.repeat)]
    cases += [(f"{n} oncoming", traffic_scenario(n), args.vehicle_repeat) for n in map(int, args.vehicles.split(","))]
    report = {"repeat": args.repeat, "cases": []}
    for name, scenario, repeat in cases:
        r = compare(scenario, fmu, table, repeat)
        if args.instructions:
            r.update(instructions("demo" if name == "demo" else name.split()[0]))
            print(f"{name:12s} instructions: plain {r['instructions_plain'] / 1e6:.1f} M, measured "
                  f"{r['instructions_measured'] / 1e6:.1f} M: {r['overhead_instructions'] * 100:+.1f} %", flush=True)
        report["cases"].append({"name": name, **r})
        print(f"{name:12s} plain {r['plain_s']:.3f} s CPU, measured {r['measured_s']:.3f} s: best-of "
              f"{r['overhead_best'] * 100:+.1f} %, pairwise median {r['overhead_median'] * 100:+.1f} % "
              f"(quartiles {r['overhead_q1'] * 100:+.1f} … {r['overhead_q3'] * 100:+.1f} %, spread "
              f"{r['overhead_min'] * 100:+.1f} … {r['overhead_max'] * 100:+.1f} %, {repeat} pairs), "
              f"{r['added_per_vehicle_s'] * 1e3:.2f} ms per vehicle, {r['located']} located instants, "
              f"{r['steps']} steps", flush=True)
    measured = stamp("shared machine; CPU time (time.process_time), pairs alternating in one process"
                     + ("; instructions by valgrind's cachegrind" if args.instructions else ""))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps({"measured": measured, **report}, indent=2) + "\n")


if __name__ == "__main__":
    main()
