"""A hosted controller's per-sample cost, before and after the host's protocol was slimmed, side by side in one
process: the shipped example AEB in sdl-fmu's process (`in_process`) against a foreign copy of it (the same FMU, other
bytes: its archive with a zip comment), which runs in a host process (`hosted`), each through this checkout's
sdl_fmu (`new`) and through a reference checkout's (`reference`, e.g. main: its package imported as
`sdl_fmu_reference`, its host process its own), the four interleaved so that all see the same load.

- sample: N samples of 10 ms (the AEB's period: two inputs set, a step, three outputs read) in a loop: wall µs,
  CPU µs of this process and of the host (/proc/<pid>/stat), per sample;
- run: a CCRs test through `api.run` (50 km/h toward a stationary car 60 m ahead, 8 s, 801 samples), no plot: the
  master loop's wall µs per step (summary.json's timing) and the CPU µs of this process and of the host per step.

Each figure is the median of --repeat measurements.

    python benchmarks/hosted_controller.py --reference CHECKOUT [--samples N] [--repeat R] [--json OUT]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from isolation import CCRS, CCRS_SPEED, CCRS_TIME, SIGNALS, _foreign_copy
from provenance import stamp
from vehicle_path_speed import load_package

TICK = os.sysconf("SC_CLK_TCK")


def _host_cpu(instance) -> float:
    """CPU seconds of the host process serving `instance` (0 for an instance in this process)."""
    host = getattr(instance, "_host", None)
    if host is None:
        return 0.0
    fields = Path(f"/proc/{host.process.pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK  # utime, stime


def _samples(package: str, fmu: Path, cmap: Path, count: int) -> dict:
    controller = importlib.import_module(f"{package}.vehicle.controller")
    isolated = importlib.import_module(f"{package}.vehicle.isolated")
    model = controller.ControllerModel.open(fmu, cmap)
    instance = model.instantiate("bench")
    instance.sample(0, SIGNALS)  # the host warm
    host = _host_cpu(instance)
    wall, cpu = time.perf_counter(), time.process_time()
    for k in range(1, count + 1):
        instance.sample(k, SIGNALS)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    host = _host_cpu(instance) - host
    kind = type(instance).__name__
    instance.close()
    isolated._end_hosts()
    return {"kind": kind, "sample_us": wall / count * 1e6, "sample_cpu_us": cpu / count * 1e6,
            "sample_host_cpu_us": host / count * 1e6}


def _run(package: str, scenario: Path, fmu: Path, cmap: Path) -> dict:
    api = importlib.import_module(f"{package}.api")
    isolated = importlib.import_module(f"{package}.vehicle.isolated")
    api.run(scenario, dynamics="simple", speed=CCRS_SPEED, until_time=0.1, controller=fmu, controller_map=cmap,
            plot=False)  # the host started (and kept) before the measured run
    host = isolated._idle and next(iter(isolated._idle.values()))
    pid = host[0].process.pid if host else None
    before = _pid_cpu(pid)
    cpu = time.process_time()
    result = api.run(scenario, dynamics="simple", speed=CCRS_SPEED, until_time=CCRS_TIME, controller=fmu,
                     controller_map=cmap, plot=False)
    cpu = time.process_time() - cpu
    host_cpu = _pid_cpu(pid) - before
    isolated._end_hosts()
    steps = result.raw.timing["steps"]
    return {"loop_us_per_step": result.raw.timing["wall_s"] / steps * 1e6, "run_cpu_us_per_step": cpu / steps * 1e6,
            "run_host_cpu_us_per_step": host_cpu / steps * 1e6, "steps": steps}


def _pid_cpu(pid: int | None) -> float:
    if pid is None:
        return 0.0
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--reference", required=True, help="checkout whose host protocol is the reference")
    arguments.add_argument("--samples", type=int, default=20000)
    arguments.add_argument("--repeat", type=int, default=5)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    import sdl_fmu  # noqa: F401 - this checkout's package first: the reference's copy below never shadows it
    from sdl_fmu import api

    api.ego_fmu("simple")
    example, cmap = api.example_controller()
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        load_package("sdl_fmu_reference", Path(args.reference), folder)
        # the reference's host process imports `sdl_fmu` from the folder holding its package: its own code
        (folder / "sdl_fmu").symlink_to(folder / "sdl_fmu_reference")
        foreign = _foreign_copy(example, folder)
        scenario = folder / "ccrs.sdl"
        scenario.write_text(CCRS)
        ways = {(code, where): (package, fmu) for code, package in (("reference", "sdl_fmu_reference"),
                                                                     ("new", "sdl_fmu"))
                for where, fmu in (("in_process", example), ("hosted", foreign))}
        measured = {way: [] for way in ways}
        for _ in range(args.repeat):
            for way, (package, fmu) in ways.items():
                measured[way].append({**_samples(package, fmu, cmap, args.samples),
                                      **_run(package, scenario, fmu, cmap)})
    report = {"measured": stamp(f"{args.repeat} repetitions, medians; {args.samples} samples of 0.01 s; the "
                                f"reference: {Path(args.reference).resolve()}")}
    for (code, where), samples in measured.items():
        kinds = {sample.pop("kind") for sample in samples}
        assert kinds == {"ControllerInstance" if where == "in_process" else "IsolatedController"}, kinds
        report.setdefault(code, {})[where] = {key: round(statistics.median(s[key] for s in samples), 2)
                                              for key in samples[0]}
    for code in ("reference", "new"):
        a, b = report[code]["in_process"], report[code]["hosted"]
        report[code]["hosted_over_in_process"] = {
            "sample_wall": round(b["sample_us"] / a["sample_us"], 2),
            "sample_cpu": round((b["sample_cpu_us"] + b["sample_host_cpu_us"]) / a["sample_cpu_us"], 2),
            "loop_wall": round(b["loop_us_per_step"] / a["loop_us_per_step"], 2),
            "run_cpu": round((b["run_cpu_us_per_step"] + b["run_host_cpu_us_per_step"]) / a["run_cpu_us_per_step"],
                             2)}
        print(code, json.dumps(report[code]))
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
