"""What running an FMU in a host process costs (sdl_fmu/vehicle/isolated.py), side by side in one process with the
same FMU in sdl-fmu's own process: the shipped Simple and Advanced FMUs (FMI 2.0 and 3.0), wall clock (the work is
split over two processes, so this process's CPU time alone would hide the host's).

- start: a first instance (the host's start: an interpreter, fmpy, the FMU loaded) and a later one (the host kept);
- step: one communication step of 50 ms (the driver's period) with the controls set and the outputs read, the
  master's per-step calls, N steps;
- run: `api.run` of the demo (Simple: demo, Advanced: demo_advanced), no plot, whole call and the loop alone
  (summary.json's timing.wall_s).

And a controller FMU (--part controller): the shipped example AEB in sdl-fmu's process against a foreign copy of it
(the same FMU, other bytes: its archive with a zip comment, which sdl-fmu runs in a host), the ego in process both
ways:

- start: as above;
- sample: one sample of 10 ms (the AEB's period) with its two inputs set, a step and its three outputs read, N samples;
- run: `api.run` of a CCRs test (50 km/h toward a stationary car 60 m ahead, 8 s), no plot: wall clock, CPU seconds
  of this process and of the host (reaped after the run), the loop's extra time per sample of the controller (801
  samples) and per step of the master;
- pack: the whole AEB car-to-car grid (`api.verify(pack="aeb-ccr", workers=0)`: 120 tests one after the other in this
  process; one host for all of them), wall clock and CPU seconds of this process and of its hosts (reaped at the end).

Each figure is the median of --repeat measurements (the pack: --pack-repeat), the two ways interleaved. With --part controller the vehicles'
figures in --json are kept (the controller's carry their own `measured`), and the other way round.

    python benchmarks/isolation.py [--part all|vehicles|controller] [--steps N] [--repeat R] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import tempfile
import time
import zipfile
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


CCRS = "Metric\n0, A, 0, 60, *0, 1\n200, ES\n"  # a stationary compact car 60 m ahead (centre to centre)
CCRS_SPEED = 50 / 3.6  # m/s
CCRS_TIME = 8.0  # s
SIGNALS = {"lead_ttc": 3.0, "lead_relative_speed": -5.0}  # the example AEB's inputs: no stage on (TTC above 2.6 s)


def _foreign_copy(fmu: Path, folder: Path) -> Path:
    """The example AEB as a user would bring it: the same FMU, other bytes (a zip comment), so it runs in a host."""
    copy = folder / fmu.name
    shutil.copyfile(fmu, copy)
    with zipfile.ZipFile(copy, "a") as archive:
        archive.comment = b"a foreign copy of the example AEB"
    return copy


def _controller_instances(model, samples: int) -> dict:
    from sdl_fmu.vehicle.isolated import _end_hosts

    _end_hosts()
    began = time.perf_counter()
    first = model.instantiate("bench")
    first_s = time.perf_counter() - began
    first.close()
    began = time.perf_counter()
    controller = model.instantiate("bench")
    later_s = time.perf_counter() - began
    began = time.perf_counter()
    for k in range(samples):
        controller.sample(k, SIGNALS)
    sample_s = (time.perf_counter() - began) / samples
    controller.close()
    return {"kind": type(controller).__name__, "first_instance_s": first_s, "later_instance_s": later_s,
            "sample_us": sample_s * 1e6}


def _controller_run(scenario: Path, fmu: Path, cmap: Path) -> dict:
    from sdl_fmu import api
    from sdl_fmu.vehicle.isolated import _end_hosts

    _end_hosts()
    children = _children_cpu()
    began, cpu = time.perf_counter(), time.process_time()
    result = api.run(scenario, dynamics="simple", speed=CCRS_SPEED, until_time=CCRS_TIME, controller=fmu,
                     controller_map=cmap, plot=False)
    run_s, cpu = time.perf_counter() - began, time.process_time() - cpu
    _end_hosts()  # the host reaped: its CPU time is counted in RUSAGE_CHILDREN
    return {"run_s": run_s, "run_cpu_s": cpu + _children_cpu() - children, "loop_s": result.raw.timing["wall_s"],
            "steps": result.raw.timing["steps"], "samples": int(round(CCRS_TIME / 0.01)) + 1}


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _controller_pack(fmu: Path, cmap: Path) -> dict:
    from sdl_fmu import api
    from sdl_fmu.vehicle.isolated import _end_hosts

    _end_hosts()
    with tempfile.TemporaryDirectory() as folder:
        children = _children_cpu()
        wall, cpu = time.perf_counter(), time.process_time()
        result = api.verify(dynamics="simple", pack="aeb-ccr", controller=fmu, controller_map=cmap, workers=0,
                            out=Path(folder) / "aeb")
        cpu = time.process_time() - cpu
        _end_hosts()  # the host reaped: its CPU time is counted in RUSAGE_CHILDREN
        wall = time.perf_counter() - wall
    errors = sum(o.error is not None for o in result.outcomes)
    assert errors == 0, [o.error for o in result.outcomes if o.error][:3]
    return {"pack_wall_s": wall, "pack_cpu_s": cpu, "pack_host_cpu_s": _children_cpu() - children,
            "pack_tests": len(result.outcomes)}


def _controller(args) -> dict:
    from sdl_fmu import api
    from sdl_fmu.vehicle.controller import ControllerModel

    api.ego_fmu("simple")
    example, cmap = api.example_controller()
    entry = {}
    with tempfile.TemporaryDirectory() as folder:
        foreign = _foreign_copy(example, Path(folder))
        scenario = Path(folder) / "ccrs.sdl"
        scenario.write_text(CCRS)
        ways = {"in_process": example, "isolated": foreign}
        models = {way: ControllerModel.open(fmu, cmap) for way, fmu in ways.items()}
        samples = {way: [] for way in ways}
        packs = {way: [] for way in ways}
        for repetition in range(args.repeat):  # the two ways interleaved: both see the same load
            for way, fmu in ways.items():
                samples[way].append({**_controller_instances(models[way], args.steps),
                                     **_controller_run(scenario, fmu, cmap)})
                if repetition < args.pack_repeat:
                    packs[way].append(_controller_pack(fmu, cmap))
        for way in ways:
            kinds = {sample.pop("kind") for sample in samples[way]}
            entry[way] = {"instance": kinds.pop(), **{k: round(v, 4) for k, v in _median(samples[way]).items()},
                          **{k: round(v, 3) for k, v in _median(packs[way]).items()}}
    a, b = entry["in_process"], entry["isolated"]
    assert (a["instance"], b["instance"]) == ("ControllerInstance", "IsolatedController"), (a, b)
    entry["extra"] = {"first_instance_s": round(b["first_instance_s"] - a["first_instance_s"], 3),
                      "sample_us": round(b["sample_us"] - a["sample_us"], 1),
                      "run_s": round(b["run_s"] - a["run_s"], 3),
                      "run_cpu_s": round(b["run_cpu_s"] - a["run_cpu_s"], 3),
                      "loop_per_sample_us": round((b["loop_s"] - a["loop_s"]) / a["samples"] * 1e6, 1),
                      "loop_per_step_us": round((b["loop_s"] - a["loop_s"]) / a["steps"] * 1e6, 1),
                      "pack_wall_s": round(b["pack_wall_s"] - a["pack_wall_s"], 2),
                      "pack_cpu_s": round(b["pack_cpu_s"] + b["pack_host_cpu_s"] - a["pack_cpu_s"]
                                          - a["pack_host_cpu_s"], 2)}
    entry["measured"] = stamp(f"{args.repeat} repetitions, medians; {args.steps} samples of 0.01 s; the pack "
                              f"{args.pack_repeat} times, medians")
    print(f"example AEB: in process {a}\n    isolated {b}\n    extra {entry['extra']}")
    return entry


def _median(samples: list[dict]) -> dict:
    return {key: statistics.median(sample[key] for sample in samples) for key in samples[0]}


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--part", choices=("all", "vehicles", "controller"), default="all")
    arguments.add_argument("--steps", type=int, default=2000)
    arguments.add_argument("--repeat", type=int, default=5)
    arguments.add_argument("--pack-repeat", type=int, default=3)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    from sdl_fmu.fmu.cache import cached_fmu
    from sdl_fmu.vehicle import shipped_map_path
    from sdl_fmu.vehicle.model import EgoModel

    report = {}
    if args.json and Path(args.json).exists():  # what this run does not measure is kept
        report = json.loads(Path(args.json).read_text())
    if args.part in ("all", "controller"):
        report["controller"] = _controller(args)
    for dynamics in ("simple", "advanced") if args.part in ("all", "vehicles") else ():
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
    if args.part in ("all", "vehicles"):
        report["measured"] = stamp(f"{args.repeat} repetitions, medians; {args.steps} steps of {STEP:g} s")
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": report.pop("measured"), **report}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
