"""`sdl-fmu run demo` as a whole process, plot included, against `python -c "import sdl_fmu.api"`: CPU time (user +
system, of the child process: robust on a shared machine), measured pairwise (one import, then one run of each
kind, repeated and interleaved), so that the machine's load moves both sides of each ratio alike. Kinds: the run
with its plot, the run with `--no-plot`, and (with --reference) the same run from another checkout, e.g. the
commit before the plot was made cheaper. A child process also splits one run into its parts (the API's import, the
simulation, writing the CSV and JSON files, matplotlib's import, the plot) by process time.

    python benchmarks/run_process.py [--repeat 7] [--reference CHECKOUT] [--json benchmarks/results/run_process.json]
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from provenance import stamp

ROOT = Path(__file__).resolve().parents[1]
TARGET = 4.0  # the whole run, plot included, at most 4x the API's import

PARTS = r"""
import json, sys, time
clock = time.process_time
began = clock()
from sdl_fmu import api
imported = clock()
result = api.run("demo", plot=False)
simulated = clock()
result.write(sys.argv[1], plot=False)
written = clock()
import sdl_fmu.results.plots
plotting = clock()
result.plot(sys.argv[2])
plotted = clock()
print(json.dumps({"import_api_s": imported - began, "simulation_s": simulated - imported,
                  "files_s": written - simulated, "import_matplotlib_s": plotting - written,
                  "plot_s": plotted - plotting}))
"""


def cpu(command: list[str], cwd: Path) -> float:
    """CPU seconds (user + system) of one child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(command, check=True, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--repeat", type=int, default=7)
    arguments.add_argument("--reference", type=Path, help="another checkout (its own sdl_fmu) to run beside")
    arguments.add_argument("--json", type=Path)
    args = arguments.parse_args()
    checkouts = {"this": ROOT, **({"reference": args.reference.resolve()} if args.reference else {})}
    work = Path(tempfile.mkdtemp(prefix="run-process-"))
    try:
        def run(checkout: Path, *extra: str) -> float:
            out = work / "out"
            shutil.rmtree(out, ignore_errors=True)
            return cpu([sys.executable, "-m", "sdl_fmu", "run", "demo", "--out", str(out), *extra], checkout)

        run(ROOT)  # the FMU into the cache, the files into the page cache: not measured
        pairs = []
        for k in range(args.repeat):
            row = {"import_api_s": cpu([sys.executable, "-c", "import sdl_fmu.api"], ROOT),
                   "run_s": run(ROOT), "run_no_plot_s": run(ROOT, "--no-plot")}
            if args.reference:
                row["reference_import_api_s"] = cpu([sys.executable, "-c", "import sdl_fmu.api"], args.reference)
                row["reference_run_s"] = run(args.reference)
            pairs.append(row)
            print(json.dumps(row), flush=True)
        parts = {}
        for name, checkout in checkouts.items():
            samples = []
            for _ in range(max(3, args.repeat // 2)):
                done = subprocess.run([sys.executable, "-c", PARTS, str(work / "parts"), str(work / "plot.png")],
                                      cwd=checkout, check=True, capture_output=True, text=True)
                shutil.rmtree(work / "parts", ignore_errors=True)
                samples.append(json.loads(done.stdout.splitlines()[-1]))
            parts[name] = {key: statistics.median(s[key] for s in samples) for key in samples[0]}
    finally:
        shutil.rmtree(work, ignore_errors=True)

    def median_ratio(numerator: str, denominator: str) -> float:
        return statistics.median(row[numerator] / row[denominator] for row in pairs)

    data = {"repeat": args.repeat, "pairs": pairs, "parts": parts, "target_ratio": TARGET,
            "ratio_run": median_ratio("run_s", "import_api_s"),
            "ratio_run_no_plot": median_ratio("run_no_plot_s", "import_api_s"),
            "measured": stamp("a shared machine: 2 cores, other test runs beside")}
    if args.reference:
        data["ratio_reference_run"] = median_ratio("reference_run_s", "reference_import_api_s")
        data["run_against_reference"] = median_ratio("run_s", "reference_run_s")
        data["reference"] = subprocess.run(["git", "-C", str(args.reference), "log", "-1", "--format=%h %s"],
                                           capture_output=True, text=True).stdout.strip()[:100] or str(args.reference)
    print(json.dumps({k: v for k, v in data.items() if k != "pairs"}, indent=2))
    if args.json:
        args.json.write_text(json.dumps(data, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
