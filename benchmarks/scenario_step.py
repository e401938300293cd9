"""Per-step cost of the scenario FMU against the Simple ego FMU, side by side in one process.

The demo (two miles, 4 vehicles, 4 BRK, 3 surface stretches) is first run as a fixed-step master would run it: the
scenario FMU and the Simple ego FMU stepped together at 10 ms (each given the other's outputs at the step's start),
its 13 000 steps' inputs recorded. Then each FMU replays its own recorded inputs alone, through fmpy's public
FMU2Slave calls as benchmarks/fmu_step.py does: set the inputs, doStep(10 ms), get the outputs the other FMU reads;
CPU time per step (time.process_time), and the doStep call alone (perf_counter_ns around it). Best of 3 rounds, the
two FMUs alternating, so that a busy machine weighs on both alike.

    python benchmarks/scenario_step.py [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import fmpy
from fmpy.fmi2 import FMU2Slave

from provenance import stamp

STEP = 0.01  # s
EGO_OUTPUTS = ("x", "y", "psi", "v", "s", "vx", "vy", "yaw_rate", "ax", "ay")
COMMANDS = ("throttle", "brake", "steer", "mu_fl", "mu_fr", "mu_rl", "mu_rr")


class Slave:
    def __init__(self, path: Path, start: dict):
        description = fmpy.read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in description.modelVariables}
        self.unzipped = fmpy.extract(str(path))
        self.slave = FMU2Slave(guid=description.guid, unzipDirectory=self.unzipped,
                               modelIdentifier=description.coSimulation.modelIdentifier, instanceName="bench")
        self.slave.instantiate()
        self.slave.setupExperiment(startTime=0.0)
        for name, value in start.items():
            self.slave.setReal([self.vr[name]], [value])
        self.slave.enterInitializationMode()

    def started(self):
        self.slave.exitInitializationMode()
        return self

    def close(self):
        self.slave.terminate()
        self.slave.freeInstance()
        shutil.rmtree(self.unzipped, ignore_errors=True)


def record(ego_fmu: Path, scenario_fmu: Path, start: dict) -> tuple[list, list, list]:
    """The demo in a Jacobi master at STEP: each step's ego inputs (the scenario's commands and surfaces) and
    scenario inputs (the ego's outputs and `stopped`)."""
    ego = Slave(ego_fmu, start).started()
    scenario = Slave(scenario_fmu, {})
    ego_out = [ego.vr[n] for n in EGO_OUTPUTS]
    scenario_in = [scenario.vr[f"ego_{n}"] for n in EGO_OUTPUTS]
    scenario.slave.setReal(scenario_in, ego.slave.getReal(ego_out))
    scenario.started()
    commands_out = [scenario.vr[n] for n in COMMANDS]
    ego_in = [ego.vr[n] for n in COMMANDS]
    ego_inputs, scenario_inputs, stopped = [], [], []
    t, k = 0.0, 0
    while not scenario.slave.getBoolean([scenario.vr["ended"]])[0]:
        outputs = ego.slave.getReal(ego_out)
        held = ego.slave.getBoolean([ego.vr["stopped"]])[0]
        commands = scenario.slave.getReal(commands_out)
        scenario.slave.setReal(scenario_in, outputs)
        scenario.slave.setBoolean([scenario.vr["ego_stopped"]], [held])
        ego.slave.setReal(ego_in, commands)
        end = (k + 1) * STEP
        ego.slave.doStep(t, end - t)
        scenario.slave.doStep(t, end - t)
        ego_inputs.append(commands)
        scenario_inputs.append(outputs)
        stopped.append(held)
        t, k = end, k + 1
    ego.close()
    scenario.close()
    return ego_inputs, scenario_inputs, stopped


def replay(path: Path, start: dict, inputs: list, names: tuple, outputs: tuple, booleans: list | None = None):
    """(µs CPU per set + doStep + get, µs wall per doStep alone) of one FMU replaying its recorded inputs."""
    slave = Slave(path, start)
    input_vr = [slave.vr[n] for n in names]
    slave.slave.setReal(input_vr, inputs[0])
    slave.started()
    output_vr = [slave.vr[n] for n in outputs]
    stopped_vr = [slave.vr["ego_stopped"]] if booleans is not None else None
    do_step, set_real, get_real, set_boolean = (slave.slave.doStep, slave.slave.setReal, slave.slave.getReal,
                                                slave.slave.setBoolean)
    in_step = 0
    t = 0.0
    began = time.process_time()
    for k, values in enumerate(inputs):
        set_real(input_vr, values)
        if stopped_vr is not None:
            set_boolean(stopped_vr, [booleans[k]])
        end = (k + 1) * STEP
        before = time.perf_counter_ns()
        do_step(t, end - t)
        in_step += time.perf_counter_ns() - before
        get_real(output_vr)
        t = end
    cpu = (time.process_time() - began) / len(inputs) * 1e6
    slave.close()
    return cpu, in_step / len(inputs) / 1e3


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--rounds", type=int, default=3)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    from sdl_fmu import api
    from sdl_fmu.export.scenario_fmu import write_scenario_fmu

    scenario = api.load("demo")
    model = api.ego_model("simple")
    with tempfile.TemporaryDirectory() as folder:
        scenario_fmu = write_scenario_fmu(scenario, Path(folder) / "demo.fmu", ego=model)
        start = {"v0": scenario_fmu.parameters["speed"], "y0": -scenario.road.lane_center(1)}
        ego_inputs, scenario_inputs, stopped = record(model.fmu_path, scenario_fmu.path, start)
        ego_best, scenario_best = (float("inf"), float("inf")), (float("inf"), float("inf"))
        for _ in range(args.rounds):
            ego = replay(model.fmu_path, start, ego_inputs, COMMANDS, EGO_OUTPUTS)
            ours = replay(scenario_fmu.path, {}, scenario_inputs, tuple(f"ego_{n}" for n in EGO_OUTPUTS), COMMANDS,
                          stopped)
            ego_best = tuple(map(min, ego_best, ego))
            scenario_best = tuple(map(min, scenario_best, ours))
    results = {"steps": len(ego_inputs), "simulated_s": len(ego_inputs) * STEP,
               "ego_simple": {"cpu_us_per_step": ego_best[0], "do_step_us": ego_best[1]},
               "scenario": {"cpu_us_per_step": scenario_best[0], "do_step_us": scenario_best[1]}}
    print(f"{results['steps']} steps of {STEP} s (the demo, {results['simulated_s']:.1f} s)")
    for name in ("ego_simple", "scenario"):
        print(f"{name:<11} {results[name]['cpu_us_per_step']:7.2f} us CPU per step (set + doStep + get), "
              f"{results[name]['do_step_us']:7.2f} us in doStep")
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": stamp(f"best of {args.rounds} rounds"), **results},
                                              indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
