"""The worst-case search benchmark (as ARCH-COMP's falsification problems are run): two problems, each with a fixed
budget, searched by random search, TPE and CMA-ES over 5 seeds on one Dask cluster of 2 worker processes.

- ccr: the car-to-car rear encounter (benchmarks/scenarios/ccr_rear.sdl) with the example AEB in the loop, 4
  parameters (the ego's speed 30..80 km/h, the target's speed, the closure time at which it brakes, its braking
  time), maximise the relative impact speed;
- pocket: benchmarks/scenarios/pocket.sdl, a car crossing the road ahead of the lane driver, 3 parameters, a small
  collision pocket; minimise the robustness of `always (abs(A1_gap_m) > 4.5 or abs(A1_lateral_m - lateral_m) > 1.8)`.

Per search: the best objective, the runs to the first collision (the trial number of the first with collisions >= 1,
plus one; none when no trial collided). Each search goes through sdl_fmu.search.search, as `sdl-fmu search` runs it,
with report=False (its table and journal only: no worst-case run, plot or report, which cost the same whatever the
method).

    python benchmarks/search_benchmark.py [--seeds 5] [--problems ccr,pocket] --json benchmarks/results/search_benchmark.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

from provenance import stamp
from sdl_fmu import api
from sdl_fmu import search as searching
from sdl_fmu.shipping import client as cluster_client

HERE = Path(__file__).resolve().parent / "scenarios"
KMH = 3.6
PROBLEMS = {
    "ccr": {"scenario": HERE / "ccr_rear.sdl", "budget": 40,
            "vary": ["speed=8.333333..22.222222", "target_velocity", "brake_ttc", "brake_time"],
            "objective": (None, "relative_impact_speed", None),
            "fixed": {"controller": "example-aeb", "on_collision": "stop", "until_time": 10.0}},
    "pocket": {"scenario": HERE / "pocket.sdl", "budget": 40,
               "vary": ["speed=10..30", "cross_ttc", "cross_time"],
               "objective": (None, None, "always (abs(A1_gap_m) > 4.5 or abs(A1_lateral_m - lateral_m) > 1.8)"),
               "fixed": {"until_distance": 700.0}},  # through the contact: the robustness measures the overlap
}
METHODS = ("random", "tpe", "cmaes")


def one(problem: str, method: str, seed: int, client, folder: Path) -> dict:
    spec = PROBLEMS[problem]
    objective = searching.objective_of(*spec["objective"])
    began, cpu = time.perf_counter(), time.process_time()
    found = searching.search(str(spec["scenario"]), searching.parse_ranges(spec["vary"]),
                             folder / f"{problem}-{method}-{seed}", objective=objective, budget=spec["budget"],
                             method=method, seed=seed, client=client, progress=False, report=False,
                             **spec["fixed"])
    rows = found.rows
    first = next((row["trial"] + 1 for row in rows if (row.get("collisions") or 0) >= 1), None)
    return {"problem": problem, "method": method, "seed": seed, "trials": len(rows),
            "failed": sum(row["status"] != "ok" for row in rows),
            "best": None if found.worst is None else found.worst["objective"],
            "runs_to_first_collision": first,
            "collisions": sum((row.get("collisions") or 0) >= 1 for row in rows),
            "wall_s": time.perf_counter() - began, "main_cpu_s": time.process_time() - cpu}


def summarise(results: list[dict]) -> dict:
    table = {}
    for problem in PROBLEMS:
        table[problem] = {}
        for method in METHODS:
            mine = [r for r in results if r["problem"] == problem and r["method"] == method]
            best = [r["best"] for r in mine if r["best"] is not None]
            firsts = [r["runs_to_first_collision"] for r in mine if r["runs_to_first_collision"] is not None]
            table[problem][method] = {
                "best_median": statistics.median(best) if best else None, "best_min": min(best, default=None),
                "best_max": max(best, default=None), "found_collision": len(firsts), "searches": len(mine),
                "runs_to_first_collision_median": statistics.median(firsts) if firsts else None,
                "runs_to_first_collision": [r["runs_to_first_collision"] for r in mine]}
    return table


def write(path: Path, results: list[dict]) -> dict:
    report = {"measured": stamp("2 Dask worker processes (LocalCluster), one shared by every search of a problem"),
              "problems": {name: {"budget": spec["budget"], "vary": spec["vary"],
                                  "objective": [x for x in spec["objective"] if x][0],
                                  "direction": searching.objective_of(*spec["objective"]).direction}
                           for name, spec in PROBLEMS.items()},
              "summary": summarise(results), "searches": results}
    path.write_text(json.dumps(report, indent=2) + "\n")
    return report


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--seeds", type=int, default=5)
    arguments.add_argument("--problems", default=",".join(PROBLEMS))
    arguments.add_argument("--json", required=True, help="written after every search; the searches it holds are "
                                                          "kept and not run again")
    arguments.add_argument("--merge", nargs="*", default=[], help="only merge these results files into --json")
    args = arguments.parse_args()
    path = Path(args.json)
    results = json.loads(path.read_text())["searches"] if path.exists() else []
    if args.merge:
        for part in args.merge:
            results += json.loads(Path(part).read_text())["searches"]
        write(path, results)
        return 0
    done = {(r["problem"], r["method"], r["seed"]) for r in results}
    api.ego_fmu("simple")  # the FMUs built (or found) in the cache before anything is timed
    api.example_controller()
    client, owned = cluster_client(2, None)
    try:
        with tempfile.TemporaryDirectory() as folder:
            for problem in args.problems.split(","):
                for method in METHODS:
                    for seed in range(args.seeds):
                        if (problem, method, seed) in done:
                            continue
                        results.append(one(problem, method, seed, client, Path(folder)))
                        r = results[-1]
                        print(f"{problem} {method} seed {seed}: best {r['best']}, first collision at run "
                              f"{r['runs_to_first_collision']}, {r['wall_s']:.0f} s", flush=True)
                        write(path, results)
    finally:
        for thing in owned:
            thing.close()
    print(json.dumps(summarise(results), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
