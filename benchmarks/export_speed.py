"""The exported demo in the SSP masters: `api.export("demo")` (the Simple ego, FMI 2.0, step 10 ms), then the whole
system run to its stop time by libcosim (`simulate_until`), ecos (`step` to the stop time) and fmpy's `simulate_ssp`,
each in a fresh process of its own (libcosim prints the FMI Library's lines on standard output; the timing is read
from a marked line), best of `--repeat`. Wall and CPU time of the simulation only (loading the SSP, unzipping the
FMUs and instantiating them are reported apart).

    python benchmarks/export_speed.py [--repeat 3] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

from provenance import stamp
from sdl_fmu import api

MARKER = "TIMING "
SCRIPTS = {
    "libcosim": """
        from libcosimpy.CosimExecution import CosimExecution
        load = time.perf_counter()
        execution = CosimExecution.from_ssp_file(ssp)
        load = time.perf_counter() - load
        wall, cpu = time.perf_counter(), time.process_time()
        assert execution.simulate_until(round(stop_time * 1e9))
    """,
    "ecos": """
        from ecospy import EcosSimulation
        load = time.perf_counter()
        simulation = EcosSimulation(ssp_path=ssp, step_size=step)
        simulation.init(parameter_set="start")
        load = time.perf_counter() - load
        wall, cpu = time.perf_counter(), time.process_time()
        simulation.step(round(stop_time / step))
    """,
    "fmpy": """
        from fmpy.ssp.simulation import simulate_ssp
        from fmpy.ssp.ssd import ParameterSet, read_ssd
        parameters = ParameterSet(name="start")
        for component in read_ssd(ssp).system.elements:
            for binding in component.parameterBindings:
                for values in binding.parameterValues:
                    for parameter in values.parameters:
                        parameter.name = f"{component.name}.{parameter.name}"
                        parameter.value = {"true": 1.0, "false": 0.0}.get(parameter.value, parameter.value)
                        parameters.parameters.append(parameter)
        load = 0.0  # simulate_ssp loads and runs in one call: its loading is in the figure
        wall, cpu = time.perf_counter(), time.process_time()
        simulate_ssp(ssp, stop_time=stop_time - step / 2, step_size=step, parameter_set=parameters)
    """,
}
HEAD = "import json, sys, time\nssp, stop_time, step = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])\n"
TAIL = ("wall, cpu = time.perf_counter() - wall, time.process_time() - cpu\n"
        f"print({MARKER!r} + json.dumps([load, wall, cpu]), flush=True)\n")


def timed(master: str, ssp: Path, stop_time: float, step: float) -> tuple[float, float, float]:
    code = HEAD + textwrap.dedent(SCRIPTS[master]) + TAIL
    completed = subprocess.run([sys.executable, "-c", code, str(ssp), repr(stop_time), repr(step)],
                               capture_output=True, text=True, check=True)
    line = next(line for line in completed.stdout.splitlines() if line.startswith(MARKER))
    load, wall, cpu = json.loads(line[len(MARKER):])
    return load, wall, cpu


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--repeat", type=int, default=3)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    report = {}
    with tempfile.TemporaryDirectory() as folder:
        export = api.export("demo", out=Path(folder) / "demo", step=0.01)
        steps = round(export.stop_time / export.step)
        report.update({"repeat": args.repeat, "scenario": "demo", "dynamics": "simple", "fmi_version": 2,
                       "step_s": export.step,
                       "stop_time_s": export.stop_time, "steps": steps, "masters": {}})
        for master in SCRIPTS:
            runs = [timed(master, export.ssp, export.stop_time, export.step) for _ in range(args.repeat)]
            load, wall, cpu = min(runs, key=lambda r: r[1])
            report["masters"][master] = {"load_s": round(load, 4), "wall_s": round(wall, 4), "cpu_s": round(cpu, 4),
                                         "real_time_factor": round(export.stop_time / wall, 1),
                                         "us_per_step": round(wall / steps * 1e6, 1)}
            print(f"{master}: {wall:.3f} s wall, {cpu:.3f} s CPU for {export.stop_time:g} s simulated "
                  f"({export.stop_time / wall:.0f}x real time, {wall / steps * 1e6:.0f} us per step); "
                  f"load {load:.3f} s")
    if args.json:
        from importlib import metadata

        masters = ", ".join(f"{name} {metadata.version(name)}" for name in ("libcosimpy", "ecospy"))
        Path(args.json).write_text(json.dumps({"measured": stamp(masters), **report}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
