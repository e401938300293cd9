"""The Advanced FMU's first build: CPU time (user + system of the whole process tree, from os.wait4) of
`python build_fmu.py --dynamics advanced --out DIR` with a fresh, empty SDL_FMU_CACHE each time, so that both FMI
versions are built (one code generation, the model code compiled once per platform and linked into both). With
mingw-w64 (the Windows DLLs too) and without it (SDL_FMU_MINGW_CC naming a compiler that does not exist: the Linux
binaries only). With --reference, a reference checkout's build (its own build_fmu.py) alternates with this
checkout's. CPU time is the figure that counts on a shared machine; wall time is recorded but depends on the load.

    python benchmarks/build_cost.py [--repeat N] [--reference CHECKOUT] [--mingw both|with|without] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from provenance import stamp

ROOT = Path(__file__).resolve().parents[1]
NO_MINGW = "sdl-fmu-benchmark-no-mingw-gcc"  # a cross compiler that does not exist: the build skips Windows


def build_once(checkout: Path, mingw: bool) -> dict:
    """One first build from `checkout` into a fresh cache; the process tree's CPU time and the wall time."""
    with tempfile.TemporaryDirectory(prefix="sdl-fmu-build-cost-") as folder:
        environment = {**os.environ, "SDL_FMU_CACHE": str(Path(folder) / "cache")}
        if not mingw:
            environment["SDL_FMU_MINGW_CC"] = NO_MINGW
        command = [sys.executable, "build_fmu.py", "--dynamics", "advanced", "--out", str(Path(folder) / "out")]
        load = os.getloadavg()[0]
        wall = time.perf_counter()
        process = subprocess.Popen(command, cwd=checkout, env=environment, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE, text=True)
        _, status, usage = os.wait4(process.pid, 0)  # the rusage of the child and every descendant it waited for
        wall = time.perf_counter() - wall
        error = process.stderr.read()
        process.stderr.close()
        if status != 0:
            raise SystemExit(f"build from {checkout} failed:\n{error}")
        return {"cpu_s": round(usage.ru_utime + usage.ru_stime, 1), "user_s": round(usage.ru_utime, 1),
                "sys_s": round(usage.ru_stime, 1), "wall_s": round(wall, 1), "load_start": round(load, 1),
                "load_end": round(os.getloadavg()[0], 1)}


def summary(runs: list[dict]) -> dict:
    cpu = [r["cpu_s"] for r in runs]
    return {"runs": runs, "cpu_min_s": min(cpu), "cpu_median_s": round(statistics.median(cpu), 1),
            "wall_median_s": round(statistics.median(r["wall_s"] for r in runs), 1)}


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--repeat", type=int, default=3)
    arguments.add_argument("--reference", help="checkout whose build is measured alternately (e.g. main)")
    arguments.add_argument("--mingw", choices=["both", "with", "without"], default="both")
    arguments.add_argument("--json")
    args = arguments.parse_args()
    checkouts = {"new": ROOT} | ({"reference": Path(args.reference).resolve()} if args.reference else {})
    modes = {"both": (True, False), "with": (True,), "without": (False,)}[args.mingw]
    if True in modes and shutil.which(os.environ.get("SDL_FMU_MINGW_CC", "x86_64-w64-mingw32-gcc")) is None:
        raise SystemExit("mingw-w64 is not installed: run with --mingw without")
    runs = {(name, mingw): [] for name in checkouts for mingw in modes}
    for _ in range(args.repeat):
        for mingw in modes:
            for name, checkout in checkouts.items():
                runs[name, mingw].append(build_once(checkout, mingw))
                print(name, "with" if mingw else "without", "mingw-w64:", runs[name, mingw][-1], flush=True)
    results = {name: {("with mingw-w64" if mingw else "without mingw-w64"): summary(runs[name, mingw])
                      for mingw in modes} for name in checkouts}
    for name, kinds in results.items():
        for kind, result in kinds.items():
            print(f"{name}, {kind}: CPU min {result['cpu_min_s']} s, median {result['cpu_median_s']} s")
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": stamp(), **results}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
