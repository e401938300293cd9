"""The demo with the shipped Simple FMU through the vehicle-map path (EgoModel + its shipped map) against a
reference checkout's code (e.g. main before the vehicle map), side by side in one process on one FMU file:
alternating runs, best of N each, wall (loop and whole call) and CPU. The reference's `sdl_fmu` is copied
into a temporary folder and imported as the package `sdl_fmu_reference` (its relative imports keep it whole).

    python benchmarks/vehicle_path_speed.py --reference /path/to/other/checkout [--repeat N] [--json OUT]
"""

from __future__ import annotations

import argparse
import importlib
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from provenance import stamp


def load_package(name: str, source: Path, folder: Path):
    shutil.copytree(source / "sdl_fmu", folder / name, ignore=shutil.ignore_patterns("__pycache__"))
    for data in ("scenarios", "modelDescription"):  # a checkout of the top-level layout: its data, as a wheel has it
        if (source / data).is_dir():
            shutil.copytree(source / data, folder / name / data, ignore=shutil.ignore_patterns("__pycache__"))
    sys.path.insert(0, str(folder))
    return importlib.import_module(name)


def runner(package_name: str, fmu: Path):
    """A function running the demo once through this package's master; returns (result, whole-call wall, CPU)."""
    master = importlib.import_module(f"{package_name}.cosim.master")
    sdl = importlib.import_module(f"{package_name}.sdl")
    from sdl_fmu.paths import SCENARIO_DIRECTORY

    scenario = sdl.load_scenario(SCENARIO_DIRECTORY / "demo.sdl")  # the same file for both
    table = sdl.load_vehicle_table(sdl.default_vehicle_table_path())

    def run():
        wall, cpu = time.perf_counter(), time.process_time()
        result = master.run_scenario(scenario, fmu, master.RunOptions(), table)
        return result, time.perf_counter() - wall, time.process_time() - cpu

    return run


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--reference", required=True, help="checkout whose sdl_fmu is the reference")
    arguments.add_argument("--repeat", type=int, default=7)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    from sdl_fmu.fmu.cache import cached_fmu

    fmu = cached_fmu("simple")
    with tempfile.TemporaryDirectory() as folder:
        load_package("sdl_fmu_reference", Path(args.reference), Path(folder))
        runs = {"vehicle_map": runner("sdl_fmu", fmu), "reference": runner("sdl_fmu_reference", fmu)}
        best: dict[str, dict] = {}
        results = {}
        for _ in range(args.repeat):
            for name, run in runs.items():  # alternating: a busy spell of the machine hits both
                result, wall, cpu = run()
                results[name] = result
                entry = best.setdefault(name, {"loop_wall_s": np.inf, "call_wall_s": np.inf, "cpu_s": np.inf})
                entry["loop_wall_s"] = min(entry["loop_wall_s"], result.timing["wall_s"])
                entry["call_wall_s"] = min(entry["call_wall_s"], wall)
                entry["cpu_s"] = min(entry["cpu_s"], cpu)
        same = all(np.array_equal(np.asarray(results["vehicle_map"].columns[k]),
                                  np.asarray(results["reference"].columns[k]), equal_nan=True)
                   for k in results["reference"].columns)
    report = {name: best[name] for name in runs}
    report["ratio_new_over_reference"] = {key: best["vehicle_map"][key] / best["reference"][key]
                                          for key in best["reference"]}
    report["identical_ego_columns"] = same
    report["repeat"] = args.repeat
    for name in runs:
        b = best[name]
        print(f"{name:12}: loop {b['loop_wall_s']:.3f} s, whole call {b['call_wall_s']:.3f} s, CPU {b['cpu_s']:.3f} s")
    r = report["ratio_new_over_reference"]
    print(f"new / reference: loop {r['loop_wall_s']:.3f}, call {r['call_wall_s']:.3f}, CPU {r['cpu_s']:.3f}; "
          f"ego columns identical: {same}")
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": stamp(), **report}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
