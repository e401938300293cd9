"""The AEB car-to-car pack's cost: the whole CCR grid (CCRs, CCRm, CCRb: 120 tests) on the Simple vehicle with the
shipped example AEB in the loop, every test run in this process one after the other (`api.verify(...,
workers=0)`: one core, no Dask), by CPU time (`time.process_time`) and wall time, results folder written.

    python benchmarks/aeb_ccr.py [--repeat N] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

from provenance import stamp
from sdl_fmu import api
from sdl_fmu.verify.aeb import totals


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--repeat", type=int, default=3)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    api.ego_fmu("simple")  # built (or found) in the cache before anything is timed
    api.example_controller()
    cpu, wall = [], []
    for _ in range(args.repeat):
        with tempfile.TemporaryDirectory() as folder:
            w, c = time.perf_counter(), time.process_time()
            result = api.verify(dynamics="simple", pack="aeb-ccr", controller="example-aeb", workers=0,
                                out=Path(folder) / "aeb")
            wall.append(time.perf_counter() - w)
            cpu.append(time.process_time() - c)
    outcomes = result.outcomes
    per_test = statistics.median(o.wall_s for o in outcomes)
    report = {"tests": len(outcomes), "cpu_s": [round(x, 2) for x in cpu], "wall_s": [round(x, 2) for x in wall],
              "best_cpu_s": round(min(cpu), 2), "median_test_wall_s": round(per_test, 3),
              "errors": sum(o.error is not None for o in outcomes),
              "points": {group: total["points"] for group, total in totals(outcomes).items()}}
    print(f"{len(outcomes)} tests: CPU {', '.join(f'{x:.1f}' for x in cpu)} s, "
          f"wall {', '.join(f'{x:.1f}' for x in wall)} s; median test {per_test * 1000:.0f} ms wall")
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": stamp("one process, tests one after the other"),
                                               **report}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
