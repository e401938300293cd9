"""Scaling of the simulation phase (time and peak memory) in the number of A vehicles and in scenario
length, each run in a fresh process, plus plots.

Vehicles: N oncoming vehicles (50 ft/s, the opposite lane, 2000 ft ahead when they appear), one every
10 ft of the ego's travel, so N vehicles take N x 10 ft (about N / 8.8 s at 88 ft/s) and about 150 are
on the road at any time; every one is spawned, passed and despawned.
Length: blocks of 10 lines at one distance every 15 ft: an oncoming vehicle, an RSA under the ego's
wheels (mu 0.7 and 0.8 alternately: a surface change under each wheel per block), three RSA in lanes
the ego never touches, a 5 % brake for 0.1 s, and four comment lines; 200 000 lines are 300 000 ft
(about 3400 s at 88 ft/s, within the 3600 s a run may last).

    python benchmarks/scaling.py [--vehicles 250 500 1000 2000 5000 10000] [--lines ...] [--out DIR]
    python benchmarks/scaling.py --only lines   # one part; the other's rows are kept from DIR/scaling.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from provenance import stamp

CHILD = r"""
import json, resource, sys, time
from pathlib import Path
from sdl_fmu.cosim.master import RunOptions, run_scenario
from sdl_fmu.results import write_results
from sdl_fmu.sdl import default_vehicle_table_path, load_scenario, load_vehicle_table
scenario = load_scenario(sys.argv[1])
table = load_vehicle_table(default_vehicle_table_path())
cpu = time.process_time()
result = run_scenario(scenario, Path(sys.argv[2]), RunOptions(), table)
cpu = time.process_time() - cpu
peak_simulation = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
began = time.perf_counter()
write_results(result, Path(sys.argv[3]), plot=sys.argv[4] == "plot")
write = time.perf_counter() - began
print(json.dumps({**result.timing, "cpu_s": cpu, "simulated_s": result.final["time_s"], "write_s": write,
                  "events": len(result.events), "vehicles": len(result.vehicles), "collisions": result.collisions,
                  "peak_rss_simulation_mb": peak_simulation,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def vehicles_scenario(n: int) -> str:
    return "English\n" + "".join(f"{10 * (k + 1)},A,50,2000,-6,{1 + k % 8}\n" for k in range(n))


def length_scenario(lines: int) -> str:
    out = ["English"]
    for block in range(lines // 10):
        d = 15 * (block + 1)
        out += [f"{d},A,50,2000,-6,{1 + block % 8}", f"{d},RSA,1,{7 if block % 2 == 0 else 8}",
                f"{d},RSA,-1,{5 + block % 3}", f"{d},RSA,101,3", f"{d},RSA,-101,2", f"{d},BRK,5,0,0.1",
                f"// block {block}", "//", "//", "//"]
    return "\n".join(out) + "\n"


def run(path: Path, fmu: Path, out: Path, plot: bool) -> dict:
    done = subprocess.run([sys.executable, "-c", CHILD, str(path), str(fmu), str(out), "plot" if plot else "no"],
                          capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"{path.name}: {done.stderr.strip()}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def plot(series: dict, out: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(11, 4.2), dpi=110, layout="constrained")
    FigureCanvasAgg(figure)
    for column, (key, label) in enumerate((("vehicles", "A vehicles"), ("lines", "scenario lines"))):
        rows = series.get(key, [])
        if not rows:
            continue
        ax = figure.add_subplot(1, 2, column + 1)
        x = [row["size"] for row in rows]
        ax.plot(x, [row["wall_s"] for row in rows], "o-", label="simulation wall time [s]")
        ax.plot(x, [row["cpu_s"] for row in rows], "d-", label="simulation CPU time [s]")
        ax.plot(x, [row["write_s"] for row in rows], "s--", label="writing results [s]")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.grid(True, which="both", alpha=0.3)
        memory = ax.twinx()
        memory.plot(x, [row["peak_rss_simulation_mb"] for row in rows], "^:", color="tab:red",
                    label="peak RSS simulating [MB]")
        memory.plot(x, [row["peak_rss_mb"] for row in rows], "v:", color="tab:pink", label="peak RSS with writing [MB]")
        memory.set_ylabel("peak RSS [MB]", color="tab:red")
        memory.set_ylim(bottom=0)
        memory.legend(loc="lower right", fontsize=8)
        ax.legend(loc="upper left", fontsize=8)
        ax.set_title(f"scaling in {label} (one core)", fontsize=10, loc="left")
    figure.savefig(out)


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--vehicles", type=int, nargs="*", default=[1000, 2500, 10000])
    arguments.add_argument("--lines", type=int, nargs="*", default=[12500, 50000, 200000])
    arguments.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    arguments.add_argument("--only", choices=("vehicles", "lines"),
                           help="run only this part; the other part's rows are kept from OUT/scaling.json")
    arguments.add_argument("--plot-runs", action="store_true", help="also write plot.png of each run")
    args = arguments.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from sdl_fmu.fmu.package import build_fmu

    series = {"measured": {}, "vehicles": [], "lines": []}
    if args.only is not None:
        earlier = out / "scaling.json"
        if earlier.exists():
            series.update(json.loads(earlier.read_text()))
        series[args.only] = []
        if args.only == "lines":
            args.vehicles = []
        else:
            args.lines = []
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        fmu = build_fmu("simple", folder / "dist")
        for key, sizes, make in (("vehicles", args.vehicles, vehicles_scenario),
                                 ("lines", args.lines, length_scenario)):
            for size in sizes:
                path = folder / f"{key}_{size}.sdl"
                path.write_text(make(size))
                row = {"size": size, **run(path, fmu, folder / f"run_{key}_{size}", args.plot_runs)}
                series[key].append(row)
                print(f"{key} {size:>7}: {row['simulated_s']:8.1f} s simulated, {row['wall_s']:7.2f} s wall "
                      f"({row['real_time_factor']:.0f}x), {row['cpu_s']:7.2f} s CPU, {row['steps']} steps, write {row['write_s']:.2f} s, "
                      f"peak RSS {row['peak_rss_simulation_mb']:.0f} MB simulating, {row['peak_rss_mb']:.0f} MB with writing, "
                      f"{row['events']} events", flush=True)
    series["measured"].update({part: stamp() for part in ("vehicles", "lines") if args.only in (None, part)})
    (out / "scaling.json").write_text(json.dumps(series, indent=2) + "\n")
    plot(series, out / "scaling.png")
    print(f"wrote {out / 'scaling.json'} and {out / 'scaling.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
