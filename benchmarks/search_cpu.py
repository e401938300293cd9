"""What a search costs beyond its runs: `sdl-fmu search` of 200 TPE trials on 2 workers against `sdl-fmu sweep` of
the same 200 runs on 2 workers, each command's whole CPU time (the command, its Dask scheduler and worker processes:
the children's rusage), side by side, repeated.

The problem is benchmarks/scenarios/pocket.sdl without --on-collision stop: every run drives the scenario's 2500 m, so
a run's cost is set by the ego's speed (the crossing car's timing changes only its path). The search varies speed,
cross_ttc and cross_time and minimises min_distance; the sweep then runs the search's 200 speeds (`--vary
speed=v1,...,v200`, the crossing at its declared values): the same 200 runs as far as their cost goes.

    python benchmarks/search_cpu.py [--trials 200] [--repeat 2] [--json benchmarks/results/search_cpu.json]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from provenance import stamp
from sdl_fmu import api

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "benchmarks" / "scenarios" / "pocket.sdl"


def timed(arguments: list[str]) -> tuple[float, float]:
    """(CPU s of the command and every process it waited for, wall s)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    began = time.perf_counter()
    environment = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-m", "sdl_fmu", *arguments], capture_output=True, text=True,
                          env=environment)
    wall = time.perf_counter() - began
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{arguments[0]} failed ({done.returncode}): {done.stderr[-2000:]}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--trials", type=int, default=200)
    arguments.add_argument("--repeat", type=int, default=2)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    api.ego_fmu("simple")  # built (or found) in the cache before anything is timed
    pairs = []
    with tempfile.TemporaryDirectory() as folder:
        for repeat in range(args.repeat):
            out = Path(folder) / f"search-{repeat}"
            search_cpu, search_wall = timed(["search", str(SCENARIO), "--vary", "speed=10..30", "--vary", "cross_ttc",
                                             "--vary", "cross_time", "--minimize", "min_distance", "--budget",
                                             str(args.trials), "--seed", str(repeat), "--workers", "2", "--out",
                                             str(out)])
            with open(out / "search.csv", newline="") as table:
                speeds = [row["speed_m/s"] for row in csv.DictReader(table)]
            assert len(speeds) == args.trials, len(speeds)
            sweep_cpu, sweep_wall = timed(["sweep", str(SCENARIO), "--vary", "speed=" + ",".join(speeds),
                                           "--workers", "2", "--out", str(Path(folder) / f"sweep-{repeat}")])
            pairs.append({"search_cpu_s": search_cpu, "sweep_cpu_s": sweep_cpu, "ratio": search_cpu / sweep_cpu,
                          "search_wall_s": search_wall, "sweep_wall_s": sweep_wall})
            print(f"repeat {repeat}: search {search_cpu:.1f} s CPU ({search_wall:.0f} s wall), sweep "
                  f"{sweep_cpu:.1f} s CPU ({sweep_wall:.0f} s wall): {search_cpu / sweep_cpu:.3f}x", flush=True)
            report = {"measured": stamp("each command a subprocess; CPU: its own and its children's (Dask "
                                        "scheduler, nannies, workers)"),
                      "trials": args.trials, "workers": 2, "pairs": pairs,
                      "ratio_median": statistics.median(p["ratio"] for p in pairs)}
            if args.json:  # after every pair
                Path(args.json).write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
