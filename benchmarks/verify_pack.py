"""The vehicle test pack's duration per shipped model: wall and CPU time (`time.process_time`) of `api.verify`
for the whole pack, and of each manoeuvre, in one process (one core). With --reference, a reference checkout's pack
(its `sdl_fmu` imported as `sdl_fmu_reference`, as benchmarks/vehicle_path_speed.py does; its FMUs from the same
cache) runs side by side, alternating with this checkout's, best of --repeat each.

    python benchmarks/verify_pack.py [--dynamics simple advanced] [--reference CHECKOUT] [--repeat N] [--json OUT]
"""

from __future__ import annotations

import argparse
import importlib
import json
import tempfile
import time
from pathlib import Path

from provenance import stamp


def measure(api, dynamics: str) -> dict:
    api.ego_fmu(dynamics)  # built (or found) in the cache before anything is timed
    with tempfile.TemporaryDirectory() as folder:
        wall, cpu = time.perf_counter(), time.process_time()
        result = api.verify(dynamics=dynamics, out=Path(folder) / "verify")
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
            "manoeuvres_wall_s": {o.name: round(o.seconds, 2) for o in result.outcomes}}


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--dynamics", nargs="+", default=["simple", "advanced"])
    arguments.add_argument("--reference", help="checkout whose pack is measured side by side (e.g. main)")
    arguments.add_argument("--repeat", type=int, default=1)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    from sdl_fmu import api

    packages = {"new": api}
    with tempfile.TemporaryDirectory() as folder:
        if args.reference:
            from vehicle_path_speed import load_package

            load_package("sdl_fmu_reference", Path(args.reference), Path(folder))
            packages["reference"] = importlib.import_module("sdl_fmu_reference.api")
        report = {}
        for dynamics in args.dynamics:
            best = {}
            for _ in range(args.repeat):
                for name, package in reversed(packages.items()):  # alternating: a busy spell hits both
                    entry = measure(package, dynamics)
                    if name not in best or entry["cpu_s"] < best[name]["cpu_s"]:
                        best[name] = entry
            report[dynamics] = best["new"]
            if "reference" in best:
                report[dynamics]["reference"] = best["reference"]
                report[dynamics]["cpu_ratio_new_over_reference"] = round(best["new"]["cpu_s"] /
                                                                         best["reference"]["cpu_s"], 2)
            for name, entry in best.items():
                print(f"{dynamics} ({name}): pack {entry['wall_s']:.1f} s wall, {entry['cpu_s']:.1f} s CPU; "
                      + ", ".join(f"{k} {s:.1f} s" for k, s in entry["manoeuvres_wall_s"].items()))
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": stamp(), **report}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
