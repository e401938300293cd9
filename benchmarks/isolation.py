"""What running an FMU in a host process costs (sdl_fmu/vehicle/isolated.py), side by side in one process with the
same FMU in sdl-fmu's own process: the shipped Simple and Advanced FMUs (FMI 2.0 and 3.0), wall clock (the work is
split over two processes, so this process's CPU time alone would hide the host's).

- start: a first instance (the host's start: an interpreter, fmpy, the FMU loaded) and a later one (the host kept);
- step: one communication step of 50 ms (the driver's period) with the controls set and the outputs read, the
  master's per-step calls, N steps;
- run: `api.run` of the demo (Simple: demo, Advanced: demo_advanced), no plot, whole call and the loop alone
  (summary.json's timing.wall_s).

Each figure is the median of --repeat measurements.

    python benchmarks/isolation.py [--steps N] [--repeat R] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

from provenance import stamp

STEP = 0.05  # s


def _instances(model, isolated: bool, steps: int) -> dict:
    from sdl_fmu.vehicle.instance import EgoInstance
    from sdl_fmu.vehicle.isolated import IsolatedInstance, _end_hosts

    kind = IsolatedInstance if isolated else EgoInstance
    start = {"speed": 20.0, "x": 0.0, "y": 0.0, "yaw": 0.0}
    _end_hosts()  # no host kept from before: the first instance starts one
    began = time.perf_counter()
    first = kind(model, start, {}, "bench")
    first_s = time.perf_counter() - began
    first.close()
    began = time.perf_counter()
    ego = kind(model, start, {}, "bench")
    later_s = time.perf_counter() - began
    began = time.perf_counter()
    t = 0.0
    for k in range(steps):
        ego.set_controls(0.2, 0.0, 0.01)
        t = (k + 1) * STEP
        ego.step_to(t)
        ego.read()
    step_s = (time.perf_counter() - began) / steps
    ego.close()
    return {"first_instance_s": first_s, "later_instance_s": later_s, "step_us": step_s * 1e6}


def _run(dynamics: str, fmi_version: int, isolated: bool) -> dict:
    from sdl_fmu import api
    from sdl_fmu.fmu.cache import cached_fmu
    from sdl_fmu.vehicle.isolated import ISOLATION_VARIABLE, _end_hosts

    _end_hosts()
    os.environ[ISOLATION_VARIABLE] = "always" if isolated else "auto"
    try:
        began = time.perf_counter()
        result = api.run("demo" if dynamics == "simple" else "demo_advanced", dynamics=dynamics,
                         fmu=cached_fmu(dynamics, fmi_version), plot=False)
        return {"run_s": time.perf_counter() - began, "loop_s": result.raw.timing["wall_s"],
                "steps": result.raw.timing["steps"]}
    finally:
        os.environ.pop(ISOLATION_VARIABLE, None)


def _median(samples: list[dict]) -> dict:
    return {key: statistics.median(sample[key] for sample in samples) for key in samples[0]}


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--steps", type=int, default=2000)
    arguments.add_argument("--repeat", type=int, default=5)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    from sdl_fmu.fmu.cache import cached_fmu
    from sdl_fmu.vehicle import shipped_map_path
    from sdl_fmu.vehicle.model import EgoModel

    report = {}
    for dynamics in ("simple", "advanced"):
        for version in (2, 3):
            model = EgoModel.open(cached_fmu(dynamics, version), shipped_map_path(dynamics))
            entry = {}
            for isolated in (False, True):
                way = "isolated" if isolated else "in_process"
                samples = [{**_instances(model, isolated, args.steps), **_run(dynamics, version, isolated)}
                           for _ in range(args.repeat)]
                entry[way] = {key: round(value, 4) for key, value in _median(samples).items()}
            a, b = entry["in_process"], entry["isolated"]
            entry["extra"] = {"first_instance_s": round(b["first_instance_s"] - a["first_instance_s"], 3),
                              "later_instance_s": round(b["later_instance_s"] - a["later_instance_s"], 4),
                              "step_us": round(b["step_us"] - a["step_us"], 1),
                              "run_s": round(b["run_s"] - a["run_s"], 3),
                              "loop_per_step_us": round((b["loop_s"] - a["loop_s"]) / a["steps"] * 1e6, 1)}
            report[f"{dynamics}_fmi{version}"] = entry
            print(f"{dynamics} FMI {version}.0: in process {a}\n    isolated {b}\n    extra {entry['extra']}")
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": stamp(f"{args.repeat} repetitions, medians; "
                                                                 f"{args.steps} steps of {STEP:g} s"), **report},
                                              indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
