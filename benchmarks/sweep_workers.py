"""Sweep throughput with 1 and 2 Dask worker processes (LocalCluster, one thread each): the same 8 runs of
the demo (speed 70..105 ft/s), timed from submission to the last row, cluster start-up excluded.

    python benchmarks/sweep_workers.py [--runs 8] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

from distributed import Client, LocalCluster

from provenance import stamp
from sdl_fmu import api
from sdl_fmu import sweep as sweeping


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--runs", type=int, default=8)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    speeds = [70.0 + 5.0 * k for k in range(args.runs)]
    report = {}
    api.ego_fmu("simple")  # the FMU built (or found) in the cache before anything is timed
    for workers in (1, 2):
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client, tempfile.TemporaryDirectory() as folder:
            client.run(lambda: __import__("sdl_fmu.cosim.master"))  # imports warm on every worker
            began = time.perf_counter()
            rows = sweeping.sweep("demo", {"speed": speeds}, Path(folder) / "sweep", client=client, progress=False)
            wall = time.perf_counter() - began
            assert all(row["status"] == "ok" for row in rows), rows
            load = os.getloadavg()[0]
            report[workers] = {"runs": len(rows), "wall_s": wall, "load_average_1min_after": load,
                               "sum_of_run_wall_s": sum(row["run_wall_s"] for row in rows)}
            print(f"{workers} worker(s): {len(rows)} demo runs in {wall:.2f} s (load average {load:.1f} after)")
    report["speedup"] = report[1]["wall_s"] / report[2]["wall_s"]
    print(f"2 workers vs 1: {report['speedup']:.2f}x")
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": stamp(), **report}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
