"""Per-step cost of one ego FMU through fmpy: set the inputs, fmi2DoStep / integrate 10 ms, get the outputs.
CPU time of this process (robust on a shared machine). Side by side in one process:
  - the native Simple and Advanced FMUs (sdl-fmu build), FMI 2.0 co-simulation, RODAS4 inside: its default
    error-controlled step, and fixed 1 ms steps (solver_tolerance 0, as before the error control);
  - the same Simple dynamics packaged with PythonFMU (benchmarks/simple_pythonfmu.py: the model's CasADi
    derivatives function evaluated in Python, RK4 at 1 ms);
  - the same Simple equations exported by CasADi's own DaeBuilder.export_fmu (FMI 3.0 model exchange, no events),
    simulated by fmpy.simulate_fmu (its default CVode solver; its Euler solver cannot run this FMU, see
    BENCHMARKS.md), cost per 10 ms output interval.

    python benchmarks/fmu_step.py [--steps N] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import fmpy
from fmpy.fmi2 import FMU2Slave

from provenance import stamp

HERE = Path(__file__).resolve().parent
STEP = 0.01  # s, the communication step measured
FIXED_STEPS = {"solver_tolerance": 0.0, "solver_step": 1e-3}  # the FMUs' solver before its error control


def native_fmus(out: Path) -> dict[str, Path]:
    from sdl_fmu.fmu.package import build_fmu

    return {name: build_fmu(name, out) for name in ("simple", "advanced")}


def pythonfmu_fmu(out: Path) -> Path:
    subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(HERE / "simple_pythonfmu.py"), "-d",
                    str(out)], check=True, capture_output=True)
    return out / "SimplePythonFmu.fmu"


def casadi_fmu(out: Path, start: dict[str, float]) -> Path:
    """The current Simple model's equations (sdl_fmu.dynamics.simple.equations(), the same CasADi
    expressions sdl-fmu compiles) through DaeBuilder.export_fmu / compile_fmu / pack_fmu.

    Built generically from the interface: inputs and parameters by name with their start values (`start`
    overrides), the continuous states starting where the model's initial_state function puts them, and
    dx/dt from calling the model's derivatives Function on the DaeBuilder symbols; the output v likewise.
    The discrete states are held at their initial values (stopped = 0, every wheel rolling forward):
    this export has no event indicators, so it cannot stop or reverse a wheel's direction. The benchmark
    drives forward and never stops, so that does not change the trajectory measured.
    """
    import os

    import casadi as ca

    from sdl_fmu.dynamics.simple import equations
    from sdl_fmu.interface import DISCRETE, INPUT, OUTPUT, PARAMETER, STATE

    model = equations()
    interface, functions = model.interface, model.functions()
    u_start = [start.get(v.name, v.start) for v in interface.of_role(INPUT)]
    p_start = [start.get(v.name, v.start) for v in interface.of_role(PARAMETER)]
    x_start, d_held = functions["initial_state"](ca.DM.zeros(model.symbols.x.numel()),
                                                 ca.DM.zeros(model.symbols.d.numel()), u_start, p_start)
    dae = ca.DaeBuilder("SimpleCasadi")
    u = ca.vertcat(*[dae.add(v.name, "input", {"start": value})
                     for v, value in zip(interface.of_role(INPUT), u_start)])
    p = ca.vertcat(*[dae.add(v.name, "parameter", "tunable", {"start": value})
                     for v, value in zip(interface.of_role(PARAMETER), p_start)])
    states = [dae.add(name, {"start": float(x_start[i])}) for i, name in enumerate(interface.names(STATE))]
    x = ca.vertcat(*states)
    derivatives = functions["derivatives"](x, d_held, u, p)
    for i, state in enumerate(states):
        dae.eq(dae.der(state), derivatives[i])
    outputs = functions["outputs"](x, d_held, u, p)
    speed = dae.add("v", "output")
    dae.eq(speed, outputs[interface.names(OUTPUT).index("v")])
    here = Path.cwd()
    try:
        os.chdir(out)  # export_fmu / compile_fmu write into the current directory
        files = dae.export_fmu({"no_warning": True})
        files = dae.compile_fmu(files, {"include_dirs": [str(Path(fmpy.__file__).parent / "c-code")]})
        return out / dae.pack_fmu(files, {})
    finally:
        os.chdir(here)


def cost_cosimulation(path: Path, steps: int, start: dict[str, float] | None = None) -> float:
    """Microseconds per set inputs + doStep(10 ms) + get outputs, through fmpy's public FMU2Slave calls."""
    description = fmpy.read_model_description(str(path))
    variables = {v.name: v for v in description.modelVariables}
    unzipped = fmpy.extract(str(path))
    slave = FMU2Slave(guid=description.guid, unzipDirectory=unzipped,
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName="bench")
    try:
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        for name, value in (start or {}).items():
            if variables[name].type == "Real":
                slave.setReal([variables[name].valueReference], [value])
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        inputs = [variables[n].valueReference for n in ("throttle", "brake", "steer")]
        outputs = [variables[n].valueReference for n in ("x", "y", "psi", "s", "v")]
        t = 0.0
        began = time.process_time()
        for k in range(steps):
            slave.setReal(inputs, [0.3, 0.0, 0.001 * (k % 2)])
            slave.doStep(currentCommunicationPoint=t, communicationStepSize=STEP)
            slave.getReal(outputs)
            t += STEP
        return (time.process_time() - began) / steps * 1e6
    finally:
        slave.terminate()
        slave.freeInstance()
        shutil.rmtree(unzipped, ignore_errors=True)


def cost_model_exchange(path: Path, steps: int) -> float:
    """Microseconds per 10 ms output interval of fmpy.simulate_fmu (CVode) on a model-exchange FMU."""
    began = time.process_time()
    fmpy.simulate_fmu(str(path), stop_time=steps * STEP, output_interval=STEP, start_values={"throttle": 0.3},
                      output=["x", "y", "psi", "s", "v"])
    return (time.process_time() - began) / steps * 1e6


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--steps", type=int, default=2000)
    arguments.add_argument("--json")
    args = arguments.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        fmus = native_fmus(out)
        from sdl_fmu.dynamics.tires import default_attribute_file, slot_parameters

        tires, _, _ = slot_parameters(default_attribute_file())
        results = {
            "native simple (fmpy, FMI 2 CS)": cost_cosimulation(fmus["simple"], args.steps, {"v0": 26.8224}),
            "native advanced (fmpy, FMI 2 CS)": cost_cosimulation(fmus["advanced"], args.steps // 4,
                                                                  {"v0": 26.8224, **tires}),
            "native simple, fixed 1 ms steps": cost_cosimulation(fmus["simple"], args.steps // 4,
                                                                 {"v0": 26.8224, **FIXED_STEPS}),
            "native advanced, fixed 1 ms steps": cost_cosimulation(fmus["advanced"], args.steps // 4,
                                                                   {"v0": 26.8224, **tires, **FIXED_STEPS}),
            "PythonFMU simple (fmpy, FMI 2 CS)": cost_cosimulation(pythonfmu_fmu(out), args.steps // 4,
                                                                   {"v0": 26.8224}),
        }
        try:
            results["CasADi export simple (fmpy CVode, FMI 3 ME)"] = cost_model_exchange(
                casadi_fmu(out, {"v0": 26.8224}), args.steps)
        except Exception as error:  # reported, not hidden: the note says why
            results["CasADi export simple (fmpy CVode, FMI 3 ME)"] = f"failed: {error}"
    width = max(map(len, results))
    for name, cost in results.items():
        print(f"{name:<{width}}  " + (f"{cost:9.1f} us CPU per 10 ms step" if isinstance(cost, float) else cost))
    if args.json:
        Path(args.json).write_text(json.dumps({"measured": stamp(), **results}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
