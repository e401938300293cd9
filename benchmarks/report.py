"""BENCHMARKS.md, generated from benchmarks/results/*.json: every measured number is typed once, by the benchmark
that measured it. The method of each benchmark and its target are written here; the numbers come from the JSON.

    python benchmarks/report.py            # rewrites BENCHMARKS.md
    python benchmarks/report.py --check    # exit 1 if BENCHMARKS.md is not what the results give
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
OUT = ROOT / "BENCHMARKS.md"

# the targets the benchmarks are held to (requirements, not measurements)
DEMO_RTF = {"simple": 1000.0, "advanced": 200.0}
DEMO_EVENT_S, DEMO_DISTANCE_FT = 1e-3, 0.01
VEHICLES_TIME_RATIO = 12.0  # 10 000 vehicles take at most 12x the time of 1 000
SWEEP_SPEEDUP = 1.8  # 2 workers against 1
CRITICALITY_OVERHEAD = 0.15  # on the demo
CRITICALITY_DENSE_OVERHEAD = 0.40  # with 32 cars oncoming in the next lane
VERIFY_CPU_S = {"simple": 30.0, "advanced": 120.0}
AEB_CCR_CPU_S = 60.0  # the whole CCR grid, Simple vehicle, example AEB, one core
EXPORT_LIBCOSIM_RTF = 100.0  # the exported demo (Simple ego, step 10 ms) in libcosim
SEARCH_CPU_RATIO = 1.2  # a search of 200 trials on 2 workers against a sweep of the same 200 runs
BUILD_CPU_S = 120.0  # the Advanced FMU's first build, both FMI versions, Linux and Windows binaries


def _load(name: str, results: Path) -> dict:
    return json.loads((results / f"{name}.json").read_text())


def _measured(block: dict) -> str:
    load = block.get("load_average_1min")
    when = f"{block['utc']}, {block['machine']}, Python {block['python']}, " + ", ".join(
        f"{name} {version}" for name, version in block["versions"].items())
    parts = [when] + ([f"load average {load} (1 min) at the end"] if load is not None else [])
    parts += [block["conditions"]] if block.get("conditions") else []
    return "Measured " + "; ".join(parts) + "."


def _met(ok: bool) -> str:
    return "**met**" if ok else "**not met**"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] + ["| " + " | ".join(r) + " |" for r in rows]


def _pct(x: float) -> str:
    return f"{x * 100:+.1f} %"


def fmu_step(results: Path) -> list[str]:
    data = _load("fmu_step", results)
    native = data["native simple (fmpy, FMI 2 CS)"]
    how = {
        "native simple (fmpy, FMI 2 CS)": "sdl-fmu: CasADi C code + own runtime, RODAS4 with error-controlled steps (default)",
        "native advanced (fmpy, FMI 2 CS)": "the same, the Advanced model (Magic Formula tires)",
        "native simple, fixed 1 ms steps": "the Simple FMU with `solver_tolerance` 0, `solver_step` 1 ms",
        "native advanced, fixed 1 ms steps": "likewise, Advanced",
        "PythonFMU simple (fmpy, FMI 2 CS)": "`benchmarks/simple_pythonfmu.py`: the model's CasADi derivatives "
                                             "function called from Python, RK4 at 1 ms",
        "CasADi export simple (fmpy CVode, FMI 3 ME)": "`DaeBuilder.export_fmu` + `compile_fmu` + `pack_fmu` (FMI 3.0 "
                                                       "model exchange), simulated by `fmpy.simulate_fmu` (CVode)",
    }
    rows = []
    for name, cost in data.items():
        if name == "measured":
            continue
        if isinstance(cost, (int, float)):
            figure = f"{cost:,.0f}".replace(",", " ") + ("" if name.startswith("native simple (") else
                                                         f" ({cost / native:.1f}× the native Simple)")
        else:
            figure = str(cost)
        rows.append([name, how.get(name, ""), figure])
    return [
        "## 1. Per-step cost of the ego FMU through fmpy", "", "Script: `benchmarks/fmu_step.py`.", "",
        "Set the inputs, advance 10 ms, get the outputs, through fmpy's public calls; CPU time per 10 ms step "
        "(2000 steps for the native Simple FMU and the CasADi export, 500 for the others; the CasADi export's figure "
        "is `fmpy.simulate_fmu`'s whole CPU time over 2000 output intervals, its set-up included). All integrate the "
        "same Simple equations (`sdl_fmu.dynamics.simple.equations()`): the native build compiles them, the "
        "PythonFMU slave evaluates the model's CasADi `derivatives` Function in Python (what a PythonFMU user with "
        "this model would write), and the CasADi export is built generically from the model's interface.", "",
        *_table(["FMU", "how it is made", "µs CPU per 10 ms step"], rows), "",
        _measured(data["measured"]), "",
        "- The PythonFMU slave's cost is CasADi's numeric call from Python (argument conversion and the SX virtual "
        "machine), 40 calls per 10 ms step with RK4 at 1 ms. Hand-written Python arithmetic would be cheaper per "
        "call but would be a second copy of the equations.",
        "- CasADi's `DaeBuilder.export_fmu` generates FMI 3.0 model-exchange sources only (no FMI 2.0, no "
        "co-simulation). fmpy's fixed-step `Euler` solver cannot run the export: it answers "
        "`fmi3GetEventIndicators` with status fatal when it has no event indicators. The export has no events: "
        "the Simple model's discrete states (`stopped`, each wheel's direction) stay at their start values, so it "
        "cannot come to a standstill; the benchmark drives forward and never stops, so its trajectory is unaffected.",
        ""]


def demo_speed(results: Path) -> list[str]:
    data = _load("demo_speed", results)
    rows, verdicts = [], []
    for dynamics in ("simple", "advanced"):
        r = data[dynamics]
        fixed = r["fixed_1ms_internal_steps"]
        against = fixed["default_against_it"]
        master = data.get(f"{dynamics}_master", {})
        rows.append([dynamics.capitalize(), f"{r['simulated_s']:.1f}", f"{r['wall_s']:.3f}",
                     f"**{r['real_time_factor']:.0f}×** (CPU: {r['cpu_real_time_factor']:.0f}×)", str(r["steps"]),
                     f"{r['reference_wall_s']:.3f} s, {r['reference_steps']} steps; "
                     f"{'same' if r['same_events'] else 'different'} events, worst time difference "
                     f"{r['worst_event_time_difference_s']:.1e} s, final distance {r['final_distance_difference_ft']:.1e} ft",
                     f"{fixed['wall_s']:.3f} s = {fixed['real_time_factor']:.0f}×; "
                     f"{'same' if against['same_events'] else 'different'} events, "
                     f"{against['worst_event_time_difference_s']:.1e} s, {against['final_distance_difference_ft']:.1e} ft",
                     f"{master['master_us_per_step']:.0f}" if master else "–"])
        ok = (r["real_time_factor"] >= DEMO_RTF[dynamics] and r["same_events"]
              and r["worst_event_time_difference_s"] <= DEMO_EVENT_S
              and r["final_distance_difference_ft"] <= DEMO_DISTANCE_FT)
        verdicts.append(f"{dynamics.capitalize()} ≥ {DEMO_RTF[dynamics]:.0f}× real time with the 10 ms reference's "
                        f"events within {DEMO_EVENT_S:g} s and final distance within {DEMO_DISTANCE_FT:g} ft: {_met(ok)}")
    return [
        "## 2. The demo's real-time factors", "", "Script: `benchmarks/demo_speed.py`.", "",
        "`scenarios/demo.sdl` (two miles, 4 vehicles, 4 BRK events, 3 surface stretches) at the default settings "
        "(`--step 1`, driver sampled every 0.05 s, the FMUs' error-controlled internal step), best of 3, by wall "
        "time of the co-simulation loop (`timing.wall_s`), against the 10 ms reference run (`--step 0.01`, same "
        "driver) and against the same run with the FMUs' fixed 1 ms internal steps (`solver_tolerance` 0). The "
        "master's own work is the loop's time minus the time inside fmi2DoStep, per communication step.", "",
        *_table(["dynamics", "simulated s", "wall s", "real-time factor", "steps", "vs the 10 ms reference",
                 "vs fixed 1 ms internal steps", "master µs / step"], rows), "",
        _measured(data["measured"]), "",
        *[f"- {v}" for v in verdicts], ""]


def scaling(results: Path) -> list[str]:
    data = _load("scaling", results)
    rows = []
    for part, label in (("vehicles", "A vehicles"), ("lines", "lines")):
        for r in data[part]:
            rows.append([f"{r['size']:,} {label}".replace(",", " "), f"{r['simulated_s']:,.0f}".replace(",", " "),
                         f"{r['steps']:,}".replace(",", " "), f"{r['wall_s']:.2f}", f"{r['cpu_s']:.2f}",
                         f"{r['peak_rss_simulation_mb']:.0f} MB", f"{r['write_s']:.1f}", f"{r['peak_rss_mb']:.0f} MB"])
    vehicles = {r["size"]: r for r in data["vehicles"]}
    lines = sorted(data["lines"], key=lambda r: r["size"])
    out = []
    if 1000 in vehicles and 10000 in vehicles:
        small, large = vehicles[1000], vehicles[10000]
        ratio = large["cpu_s"] / small["cpu_s"]
        out.append(f"- Vehicles: 10 000 take {ratio:.1f}× the CPU time of 1 000 "
                   f"({large['wall_s'] / small['wall_s']:.1f}× the wall time) for "
                   f"{large['simulated_s'] / small['simulated_s']:.1f}× the simulated time; peak RSS "
                   f"{small['peak_rss_simulation_mb']:.0f} → {large['peak_rss_simulation_mb']:.0f} MB simulating. "
                   f"Target ≤ {VEHICLES_TIME_RATIO:g}×: {_met(ratio <= VEHICLES_TIME_RATIO)}.")
    if len(lines) >= 2:
        a, b = lines[-2], lines[-1]
        per_line = (b["peak_rss_mb"] - a["peak_rss_mb"]) * 2**20 / (b["size"] - a["size"])
        out.append(f"- Length: {b['cpu_s'] / a['cpu_s']:.2f}× the CPU time for {b['size'] / a['size']:.0f}× the lines "
                   f"({a['size']:,} → {b['size']:,}); peak RSS with writing ".replace(",", " ")
                   + " / ".join(f"{r['peak_rss_mb']:.0f}" for r in lines)
                   + f" MB, i.e. {per_line:.0f} B per added line (the parsed scenario, which must be read whole: "
                   "every problem of a file is reported before a run).")
    return [
        "## 3. Scaling", "", "Script: `benchmarks/scaling.py`.", "",
        "Each size in a fresh process; simulation = the co-simulation loop (`timing.wall_s`), CPU = process time "
        "of `run_scenario`; writing the results (timeseries.csv, traffic.csv, summary.json; no plot) is shown "
        "separately; peak RSS covers the whole process. Scenarios (generated by the script): *vehicles*, N oncoming "
        "vehicles (50 ft/s, opposite lane, 2000 ft ahead when they appear), one every 10 ft of the ego's travel, "
        "each spawned, passed and despawned; *lines*, blocks of 10 lines at one distance every 15 ft (an oncoming "
        "vehicle, an RSA under the ego's wheels alternating mu 0.7 / 0.8, three RSA in lanes it never touches, a "
        "5 % brake for 0.1 s, four comment lines).", "",
        *_table(["scenario", "simulated s", "steps", "simulation wall s", "CPU s", "peak RSS simulating",
                 "writing s", "peak RSS with writing"], rows), "",
        *[_measured(data["measured"][part]).replace("Measured ", f"The {part} rows: measured ", 1)
          for part in ("vehicles", "lines") if part in data.get("measured", {})], "",
        "![scaling](benchmarks/results/scaling.png)", "",
        *out, ""]


def sweep_workers(results: Path) -> list[str]:
    data = _load("sweep_workers", results)
    rows = [[workers, str(r["runs"]), f"{r['wall_s']:.2f}", f"{r['sum_of_run_wall_s']:.2f}",
             f"{r['load_average_1min_after']:.1f}"] for workers, r in data.items() if workers in ("1", "2")]
    return [
        "## 4. Sweeps: 2 workers against 1", "", "Script: `benchmarks/sweep_workers.py`.", "",
        "Runs of the demo at different speeds on a LocalCluster of 1 and of 2 worker processes (one thread each), "
        "timed from submission to the written table (cluster start-up excluded; the ego FMU is built or found in "
        "the cache before anything is timed). Two worker processes get two cores only on an idle machine.", "",
        *_table(["workers", "runs", "sweep wall s", "sum of the runs' own wall s", "load average (1 min, after)"],
                rows), "",
        _measured(data["measured"]), "",
        f"- 2 workers against 1: {data['speedup']:.2f}×. Target ≥ {SWEEP_SPEEDUP:g}×: "
        f"{_met(data['speedup'] >= SWEEP_SPEEDUP)}.", ""]


def criticality_overhead(results: Path) -> list[str]:
    data = _load("criticality_overhead", results)
    rows = []
    for c in data["cases"]:
        detail = ", ".join(f"{c[k]} {label}" for k, label in (("steps", "steps"), ("located", "located instants"))
                           if c.get(k) is not None)
        rows.append([c["name"] + (f" ({detail})" if detail else ""), f"{c['plain_s']:.3f}", f"{c['measured_s']:.3f}",
                     _pct(c["overhead_best"]), f"**{_pct(c['overhead_median'])}** "
                     f"({_pct(c['overhead_min'])} … {_pct(c['overhead_max'])})",
                     "" if c.get("added_per_vehicle_s") is None else f"{c['added_per_vehicle_s'] * 1e3:.2f}",
                     "" if c.get("overhead_instructions") is None else f"**{_pct(c['overhead_instructions'])}** "
                     f"({c['instructions_plain'] / 1e6:.0f} M → {c['instructions_measured'] / 1e6:.0f} M)"])
    verdict = []
    for name, target in (("demo", CRITICALITY_OVERHEAD), ("32 oncoming", CRITICALITY_DENSE_OVERHEAD)):
        case = next((c for c in data["cases"] if c["name"] == name), None)
        if case:
            ok = case["overhead_best"] <= target and case["overhead_median"] <= target
            line = (f"- {name}: at most {target * 100:.0f} % added, by both the best-of ratio and the pairwise median: "
                    f"{_met(ok)}")
            if case.get("overhead_instructions") is not None:
                line += (f"; by the instructions (load-independent): "
                         f"{_met(case['overhead_instructions'] <= target)}")
            verdict.append(line + ".")
    return [
        "## 5. Criticality measures: what they add to a run", "", "Script: `benchmarks/criticality_overhead.py`.", "",
        "The master measures them on every run; the benchmark runs it side by side with the same master whose "
        "criticality follower measures nothing (no looks, no FMU snapshots, no located instants), in one "
        f"process, alternating, {data['repeat']} pairs on the demo, by CPU time (`time.process_time`), Simple FMU, "
        "default settings: the best of each kind, and the median and spread of the pairwise ratios; and (`--instructions`) "
        "the instructions each kind executes, counted by valgrind with OpenBLAS on one thread (its idle worker "
        "threads spin for a scheduling-dependent time, which valgrind would count), which do not depend on the "
        "machine's load. The "
        "scenarios: the demo, and a straight road with N cars oncoming in the next lane, one spawned every 100 ft.", "",
        *_table(["scenario", "plain CPU s (best)", "with the measures (best)", "best-of ratio",
                 "pairwise median (spread)", "added CPU per vehicle, ms (median)", "instructions added"], rows), "",
        _measured(data["measured"]), "",
        *verdict,
        "- Linear in the vehicles: the added CPU per passing vehicle should stay about constant as N grows.", ""]


def vehicle_path_speed(results: Path) -> list[str]:
    data = _load("vehicle_path_speed", results)
    ratio = data["ratio_new_over_reference"]
    rows = [[name, f"{data[name]['loop_wall_s']:.3f}", f"{data[name]['call_wall_s']:.3f}", f"{data[name]['cpu_s']:.3f}"]
            for name in ("vehicle_map", "reference")]
    rows.append(["ratio", f"**{ratio['loop_wall_s']:.3f}**", f"{ratio['call_wall_s']:.3f}", f"{ratio['cpu_s']:.3f}"])
    return [
        "## 6. The vehicle-map path against a reference checkout", "", "Script: `benchmarks/vehicle_path_speed.py`.", "",
        "The demo with the Simple FMU through this checkout's code (the FMU driven through its vehicle map, one "
        "`EgoModel` per run) and through a reference checkout's code (`--reference`, imported in the same process "
        f"as the package `sdl_fmu_reference`), on one FMU file, alternating, best of {data['repeat']} each. The ego "
        f"columns of the two runs are {'identical' if data['identical_ego_columns'] else 'NOT identical'} "
        "(`numpy.array_equal`).", "",
        *_table(["code", "loop wall s", "whole call wall s", "CPU s"], rows), "",
        _measured(data["measured"]), ""]


def verify_pack(results: Path) -> list[str]:
    data = _load("verify_pack", results)
    rows, verdicts = [], []
    for model in ("simple", "advanced"):
        if model not in data:
            continue
        r = data[model]
        rows.append([model.capitalize(), f"**{r['cpu_s']:.1f}**", f"{r['wall_s']:.1f}",
                     ", ".join(f"{name} {s:g}" for name, s in r["manoeuvres_wall_s"].items())])
        if "reference" in r:
            ref = r["reference"]
            rows.append([f"{model.capitalize()}, reference checkout", f"{ref['cpu_s']:.1f} (new / reference "
                         f"{r['cpu_ratio_new_over_reference']:.2f})", f"{ref['wall_s']:.1f}",
                         ", ".join(f"{name} {s:g}" for name, s in ref["manoeuvres_wall_s"].items())])
        verdicts.append(f"{model.capitalize()} < {VERIFY_CPU_S[model]:g} s CPU on one core: "
                        f"{_met(r['cpu_s'] < VERIFY_CPU_S[model])}")
    return [
        "## 7. The vehicle test pack", "", "Script: `benchmarks/verify_pack.py`.", "",
        "`api.verify` of the whole pack (six manoeuvres, results folder with report.html written) per shipped "
        "model, in one process on one core, the manoeuvres one after the other; the Simple pack includes the 60 "
        "closed-form stops. CPU time (`time.process_time`) is the figure that counts on a shared machine. A "
        "reference checkout's pack (`--reference`), where measured, ran side by side in the same process.", "",
        *_table(["model", "pack CPU s", "pack wall s", "per manoeuvre, wall s"], rows), "",
        _measured(data["measured"]), "",
        *[f"- {v}" for v in verdicts], ""]


def aeb_ccr(results: Path) -> list[str]:
    data = _load("aeb_ccr", results)
    best = data["best_cpu_s"]
    points = ", ".join(f"{group} {value:g}" for group, value in data["points"].items())
    return [
        "## 8. The AEB car-to-car pack", "", "Script: `benchmarks/aeb_ccr.py`.", "",
        f"`api.verify(pack=\"aeb-ccr\", controller=\"example-aeb\", workers=0)`: the whole grid ({data['tests']} "
        "tests: CCRs, CCRm, CCRb at every overlap) on the Simple vehicle with the shipped example AEB in the loop, the "
        "tests one after the other in one process (one core, no Dask), results folder with report.html written; "
        "best of the repeats by CPU time (`time.process_time`).", "",
        *_table(["tests", "CPU s (best)", "CPU s (each)", "wall s (each)", "median test, wall ms", "runs failed",
                 "points"],
                [[str(data["tests"]), f"**{best:.1f}**", ", ".join(f"{x:.1f}" for x in data["cpu_s"]),
                  ", ".join(f"{x:.1f}" for x in data["wall_s"]), f"{data['median_test_wall_s'] * 1000:.0f}",
                  str(data["errors"]), points]]), "",
        _measured(data["measured"]), "",
        f"- The whole CCR grid in < {AEB_CCR_CPU_S:g} s of CPU on one core: {_met(best < AEB_CCR_CPU_S)}", ""]


def scenario_step(results: Path) -> list[str]:
    data = _load("scenario_step", results)
    ego, scenario = data["ego_simple"], data["scenario"]
    rows = [["Simple ego FMU", f"{ego['cpu_us_per_step']:.2f}", f"**{ego['do_step_us']:.2f}**"],
            ["scenario FMU (demo)", f"{scenario['cpu_us_per_step']:.2f}", f"**{scenario['do_step_us']:.2f}**"]]
    ratio = scenario["do_step_us"] / ego["do_step_us"]
    return [
        "## 9. The scenario FMU's step", "", "Script: `benchmarks/scenario_step.py`.", "",
        f"The demo run as a fixed-step master runs it (the scenario FMU and the Simple ego FMU stepped together at "
        f"10 ms, each given the other's outputs at the step's start; {data['steps']} steps, "
        f"{data['simulated_s']:.1f} s), each FMU's inputs recorded; then each FMU replays its own inputs alone "
        "through fmpy's FMU2Slave calls: set its inputs, doStep(10 ms), get the outputs the other FMU reads (from "
        "the ego its 10 pose and motion outputs, from the scenario its 7 commands and surfaces). CPU time per step, "
        "and the time inside doStep alone. Best of the rounds, the two FMUs alternating.", "",
        *_table(["FMU", "µs CPU per step (set + doStep + get)", "µs in doStep"], rows), "",
        _measured(data["measured"]), "",
        f"- The scenario FMU's doStep costs at most the Simple ego FMU's per 10 ms step: {ratio:.2f}× "
        f"{_met(ratio <= 1.0)}", ""]


def export_speed(results: Path) -> list[str]:
    data = _load("export_speed", results)
    names = {"libcosim": "libcosim (libcosimpy), `simulate_until`", "ecos": "ecos (ecospy), `step`",
             "fmpy": "fmpy, `simulate_ssp`"}
    rows = [[names[master], f"**{r['real_time_factor']:.0f}×**", f"{r['wall_s']:.3f}", f"{r['cpu_s']:.3f}",
             f"{r['us_per_step']:g}", f"{r['load_s']:.3f}" if master != "fmpy" else "in the run"]
            for master, r in data["masters"].items()]
    libcosim = data["masters"]["libcosim"]["real_time_factor"]
    return [
        "## 10. The exported demo in SSP masters", "", "Script: `benchmarks/export_speed.py`.", "",
        f"`api.export(\"demo\")` (the Simple ego, FMI 2.0, step {data['step_s'] * 1000:g} ms: "
        f"{data['steps']} steps to the stop time {data['stop_time_s']:g} s), the SSP run whole by each master in a "
        f"fresh process of its own, best of {data['repeat']} by wall time of the simulation alone (loading the SSP, "
        "unzipping and instantiating the FMUs are apart; fmpy's `simulate_ssp` does all in one call). The scenario "
        "FMU and the ego FMU are stepped by the master on its "
        "fixed grid ([docs/export.md](docs/export.md)).", "",
        *_table(["master", "real-time factor", "wall s", "CPU s", "µs / step", "load s"], rows), "",
        _measured(data["measured"]), "",
        f"- libcosim ≥ {EXPORT_LIBCOSIM_RTF:g}× real time at 10 ms: {_met(libcosim >= EXPORT_LIBCOSIM_RTF)}", ""]


def isolation(results: Path) -> list[str]:
    data = _load("isolation", results)
    rows = []
    for key in ("simple_fmi2", "simple_fmi3", "advanced_fmi2", "advanced_fmi3"):
        if key not in data:
            continue
        a, b, extra = data[key]["in_process"], data[key]["isolated"], data[key]["extra"]
        model, version = key.split("_")
        rows.append([f"{model.capitalize()} FMI {version[-1]}.0", f"{b['first_instance_s']:.2f}",
                     f"{a['step_us']:.0f} / **{b['step_us']:.0f}**",
                     f"{a['run_s']:.2f} / **{b['run_s']:.2f}**", f"{extra['loop_per_step_us']:.0f}"])
    return [
        "## 11. A foreign FMU in its host process", "", "Script: `benchmarks/isolation.py`.", "",
        "An FMU sdl-fmu did not build runs in a host process (`sdl_fmu/vehicle/isolated.py`; the decision: "
        "[docs/decisions.md](docs/decisions.md)). Measured on the shipped FMUs, in process and in a host "
        "(`SDL_FMU_ISOLATION=always`), side by side in one process, wall clock (the work is split over two "
        "processes), medians: the host's start (once per FMU and process; a later instance reuses it), one "
        "50 ms communication step with the controls set and the outputs read, the demo through `api.run` "
        "(Simple: demo, Advanced: demo_advanced; no plot), and the master loop's extra time per step.", "",
        *_table(["FMU", "host start s", "step µs (in process / host)", "demo run s (in process / host)",
                 "loop, extra µs per step"], rows), "",
        _measured(data["measured"]), "", *_controller_isolation(data.get("controller"))]


def _controller_isolation(entry: dict | None) -> list[str]:
    """Section 11's controller part: the example AEB in process against a foreign copy of it in a host."""
    if entry is None:
        return []
    a, b, extra = entry["in_process"], entry["isolated"], entry["extra"]
    row = [f"{b['first_instance_s']:.2f}", f"{a['sample_us']:.0f} / **{b['sample_us']:.0f}**",
           f"{a['run_s']:.2f} / **{b['run_s']:.2f}**", f"{a['run_cpu_s']:.2f} / **{b['run_cpu_s']:.2f}**",
           f"{extra['loop_per_sample_us']:.0f}",
           f"{a['pack_wall_s']:.1f} / **{b['pack_wall_s']:.1f}**",
           f"{a['pack_cpu_s'] + a['pack_host_cpu_s']:.1f} / **{b['pack_cpu_s'] + b['pack_host_cpu_s']:.1f}**"]
    return [
        "A controller FMU sdl-fmu did not build runs in a host too (`IsolatedController`, "
        "`sdl_fmu/vehicle/controller.py`; [docs/controllers.md](docs/controllers.md)). Measured with the shipped "
        "example AEB in sdl-fmu's process against a foreign copy of it (the same FMU, other bytes: its archive with a "
        "zip comment), the Simple ego in process both ways, interleaved, medians: the host's start, one 10 ms sample "
        "(two inputs set, a step, three outputs read), a CCRs test through `api.run` (50 km/h toward a stationary "
        f"car, 8 s, {a['samples']} samples, {a['steps']} steps; CPU: this process and the host, whose start is in "
        "it), the master loop's extra time per sample, and the whole AEB car-to-car grid "
        f"(`verify --pack aeb-ccr --workers 0`: {a['pack_tests']} tests one after the other, one host for all; CPU: "
        "this process and the host).", "",
        *_table(["controller", "host start s", "sample µs (in process / host)", "CCRs run s (in process / host)",
                 "CCRs run CPU s", "loop, extra µs per sample", "CCR grid s", "CCR grid CPU s"],
                [["example AEB", *row]]), "",
        _measured(entry["measured"]), ""]


def hosted_controller(results: Path) -> list[str]:
    """Section 11's last part: a hosted controller's per-sample cost before and after the host's protocol was
    slimmed (benchmarks/hosted_controller.py)."""
    data = _load("hosted_controller", results)
    before, after = data["reference"]["hosted"], data["new"]["hosted"]
    after_in = data["new"]["in_process"]["sample_cpu_us"]
    after_ratio = data["new"]["hosted_over_in_process"]["sample_cpu"]
    rows = []
    for code, label in (("reference", "before (main)"), ("new", "after")):
        a, b, ratio = data[code]["in_process"], data[code]["hosted"], data[code]["hosted_over_in_process"]
        rows.append([label, f"{a['sample_us']:.0f} / **{b['sample_us']:.0f}**",
                     f"{a['sample_cpu_us']:.0f} / **{b['sample_cpu_us']:.0f}** + {b['sample_host_cpu_us']:.0f}",
                     f"{ratio['sample_cpu']:.2f}", f"{a['loop_us_per_step']:.0f} / **{b['loop_us_per_step']:.0f}**",
                     f"{a['run_cpu_us_per_step']:.0f} / **{b['run_cpu_us_per_step']:.0f}** + "
                     f"{b['run_host_cpu_us_per_step']:.0f}", f"{ratio['run_cpu']:.2f}"])
    return [
        "A hosted controller's cost per sample, before and after its host's protocol was slimmed (an answer's length "
        "and body taken in one read on either side, the messages' text formatted only for a message), side by side "
        "in one process (script: `benchmarks/hosted_controller.py`): the example AEB in process and a foreign copy "
        "of it in a host, each through this checkout's sdl-fmu and through main's (its own host process), the four "
        "interleaved, medians. A sample in a loop (wall µs; CPU µs of this process, + the host's), and a CCRs test "
        "through `api.run` (the master loop's wall µs per step; CPU µs per step of this process, + the host's). The "
        "controller is in a closed loop: sample k + 1's inputs depend on the ego's answer to sample k's request, so "
        "one request per sample is the least there can be (batching samples would need the controller rolled back, "
        "which sdl-fmu never does: [docs/controllers.md](docs/controllers.md)); what a request costs beyond the "
        "in-process sample is the pipe's two wake-ups, which a loaded machine makes long.", "",
        *_table(["protocol", "sample µs (in process / host)", "sample CPU µs (in process / host + host process)",
                 "sample CPU, host / in process", "CCRs loop µs per step (in process / host)",
                 "CCRs CPU µs per step (in process / host + host process)", "CCRs CPU, host / in process"], rows), "",
        _measured(data["measured"]), "",
        f"- A hosted sample's CPU (both processes), after against before: {_both(after):.0f} µs against "
        f"{_both(before):.0f} "
        f"µs ({_pct(_both(after) / _both(before) - 1)}), the in-process sample {after_in:.0f} µs: the host's "
        f"per-sample cost is **not** brought near the in-process one (x {after_ratio:.2f}); a whole CCRs test costs "
        f"x {data['new']['hosted_over_in_process']['run_cpu']:.2f} the CPU of the in-process one.", ""]


def _both(hosted: dict) -> float:
    """A hosted sample's CPU µs, this process's and the host's."""
    return hosted["sample_cpu_us"] + hosted["sample_host_cpu_us"]


def run_process(results: Path) -> list[str]:
    data = _load("run_process", results)
    pairs = data["pairs"]

    def median(key: str) -> float:
        return statistics.median(row[key] for row in pairs)

    rows = [["`python -c \"import sdl_fmu.api\"`", f"{median('import_api_s'):.2f}", "1×"],
            ["`sdl-fmu run demo`", f"{median('run_s'):.2f}", f"**{data['ratio_run']:.1f}×**"],
            ["`sdl-fmu run demo --no-plot`", f"{median('run_no_plot_s'):.2f}", f"{data['ratio_run_no_plot']:.1f}×"]]
    if "reference_run_s" in pairs[0]:
        rows.append([f"`sdl-fmu run demo` of the reference ({data['reference'].split()[0]})",
                     f"{median('reference_run_s'):.2f}",
                     f"{data['ratio_reference_run']:.1f}× (its own import)"])
    names = {"import_api_s": "import sdl_fmu.api", "simulation_s": "the simulation (api.run, no plot)",
             "files_s": "timeseries.csv, summary.json", "import_matplotlib_s": "import the plot module (matplotlib)",
             "plot_s": "plot.png"}
    parts = data["parts"]
    part_rows = [[names[key]] + [f"{parts[name][key]:.2f}" for name in parts] for key in names]
    lines = [
        "## 12. `sdl-fmu run demo` as a whole process", "", "Script: `benchmarks/run_process.py`.", "",
        "CPU time (user + system) of whole processes, pairwise: each repetition runs the API's import, the run with "
        f"its plot and the run with `--no-plot` one after the other ({data['repeat']} repetitions, interleaved; "
        "medians, ratios the median of each repetition's ratio). The FMU is in the cache. The reference is "
        f"`{data.get('reference', '')}`, before the plot's fixed layout, run beside in each repetition with its own "
        "import.", "",
        *_table(["process", "CPU s", "against the import"], rows), "",
        "One run split into its parts (process time in one child, medians):", "",
        *_table(["part"] + [f"{name} s" for name in parts], part_rows), "",
        _measured(data["measured"]), "",
        f"- `sdl-fmu run demo`, plot included, at most {data['target_ratio']:g}× the API's import: "
        f"{data['ratio_run']:.1f}×, {_met(data['ratio_run'] <= data['target_ratio'])}"]
    if "run_against_reference" in data:
        lines.append(f"- against the reference: the whole run takes {data['run_against_reference']:.2f}× its CPU time")
    return lines + [""]


def search_benchmark(results: Path) -> list[str]:
    data = _load("search_benchmark", results)
    summary, problems = data["summary"], data["problems"]
    names = {"random": "random", "tpe": "TPE", "cmaes": "CMA-ES"}

    def shown(problem: str, value) -> str:
        if value is None:
            return "-"
        return f"{value * 3.6:.2f} km/h" if problem == "ccr" else f"{value:.3f} m"

    rows = []
    for problem, methods in summary.items():
        for method, entry in methods.items():
            firsts = ", ".join("-" if x is None else str(x) for x in entry["runs_to_first_collision"])
            rows.append([problem, names[method], shown(problem, entry["best_median"]),
                         shown(problem, entry["best_min"]), shown(problem, entry["best_max"]),
                         f"{entry['found_collision']} of {entry['searches']}",
                         "-" if entry["runs_to_first_collision_median"] is None else
                         f"{entry['runs_to_first_collision_median']:g}", firsts])
    better = {problem: (lambda tpe, rnd: tpe is not None and rnd is not None and (
        tpe > rnd if problems[problem]["direction"] == "maximize" else tpe < rnd))(
        methods["tpe"]["best_median"], methods["random"]["best_median"]) for problem, methods in summary.items()}
    pocket = summary["pocket"]["tpe"]
    return [
        "## 13. Worst-case search: random, TPE, CMA-ES", "", "Script: `benchmarks/search_benchmark.py`.", "",
        "Two problems, as ARCH-COMP's falsification benchmarks are run: each a fixed budget of runs, searched by "
        "random search (optuna's random sampler), TPE (optuna, multivariate, constant liar) and CMA-ES (the `cma` "
        "package) over 5 seeds (0 … 4), through `sdl_fmu.search.search` (with `report=False`: no worst-case run, plot "
        "or report, the same whatever the method) on one local Dask cluster of 2 worker processes per problem, two trials "
        "in flight per worker thread (one proposed as each run comes back), so the proposals depend on the order "
        "runs come back in. **ccr** (`benchmarks/scenarios/ccr_rear.sdl`): the car-to-car rear encounter "
        "with the example AEB in the loop, 4 parameters (the ego's speed 30 … 80 km/h, the target's speed 0 … 43 "
        "km/h, the closure time at which the target brakes 0.5 … 6 s, its braking time to a stop 0.3 … 4 s), "
        f"budget {problems['ccr']['budget']}, maximise the relative impact speed (shown in km/h). **pocket** "
        "(`benchmarks/scenarios/pocket.sdl`): a car crossing the road ahead of the lane driver, 3 parameters (the "
        "ego's speed 10 … 30 m/s, the closure time at which the car starts 0.2 … 30 s, its crossing time 0.3 … 3 s), a "
        "collision pocket of a few per cent of the box (4 of 60 random draws collided when it was made), budget "
        f"{problems['pocket']['budget']}, minimise the robustness of `{problems['pocket']['objective']}` "
        "(negative: an overlap; shown in m). Best objective per method over the seeds (median, min, max); the runs "
        "to the first collision per seed (`-`: none in the budget).", "",
        *_table(["problem", "method", "best (median)", "best (min)", "best (max)", "found a collision",
                 "runs to the first collision (median)", "per seed"], rows), "",
        _measured(data["measured"]), "",
        f"- At the same budget, TPE's median best objective is better than random search's on ccr: "
        f"{_met(better['ccr'])}; on pocket: {_met(better['pocket'])}",
        f"- A TPE search of {problems['pocket']['budget']} runs finds the pocket in at least 4 of 5 seeds: "
        f"{pocket['found_collision']} of {pocket['searches']}, {_met(pocket['found_collision'] >= 4)}", ""]


def search_cpu(results: Path) -> list[str]:
    data = _load("search_cpu", results)
    rows = [[str(k), f"{p['search_cpu_s']:.1f}", f"{p['sweep_cpu_s']:.1f}", f"{p['ratio']:.3f}",
             f"{p['search_wall_s']:.0f}", f"{p['sweep_wall_s']:.0f}"] for k, p in enumerate(data["pairs"])]
    return [
        "## 14. What a search costs beyond its runs", "", "Script: `benchmarks/search_cpu.py`.", "",
        f"`sdl-fmu search` of {data['trials']} TPE trials on {data['workers']} workers (`benchmarks/scenarios/"
        "pocket.sdl`, 3 parameters, minimise min_distance; its table, worst.sdl, the worst case run again with its "
        "plot, search.png and report.html included) against `sdl-fmu sweep` of the same runs on 2 workers (the "
        "search's 200 speeds, which set each run's cost: every run drives the whole 2500 m), each command's whole "
        "CPU time (its own and its Dask scheduler's, nannies' and workers', the children's rusage), side by side.", "",
        *_table(["repeat", "search CPU s", "sweep CPU s", "search / sweep", "search wall s", "sweep wall s"], rows), "",
        _measured(data["measured"]), "",
        f"- A search of {data['trials']} trials costs at most {SEARCH_CPU_RATIO:g}× the CPU of a sweep of the same runs: "
        f"median {data['ratio_median']:.3f}×, {_met(data['ratio_median'] <= SEARCH_CPU_RATIO)}", ""]


def build_cost(results: Path) -> list[str]:
    data = _load("build_cost", results)
    kinds = ("with mingw-w64", "without mingw-w64")
    rows = []
    labels = {"new": "this checkout", "reference": "reference checkout"}  # other keys: a variant, by its name
    for name in [key for key in data if key != "measured"]:
        label = labels.get(name, name)
        for kind in kinds:
            r = data[name].get(kind)
            if r is not None:
                rows.append([label, kind, str(len(r["runs"])), f"**{r['cpu_min_s']:.1f}**", f"{r['cpu_median_s']:.1f}",
                             f"{r['wall_median_s']:.0f}",
                             ", ".join(f"{run['load_start']:g}–{run['load_end']:g}" for run in r["runs"])])
    new = data["new"].get("with mingw-w64")
    verdict = (f"The first build with both binaries < {BUILD_CPU_S:g} s CPU: {_met(new['cpu_median_s'] < BUILD_CPU_S)}"
               if new else "")
    return [
        "## 15. The Advanced FMU's first build", "", "Script: `benchmarks/build_cost.py`.", "",
        "CPU time (user + system of the whole process tree, `os.wait4`) of `python build_fmu.py --dynamics advanced "
        "--out DIR` with a fresh empty `SDL_FMU_CACHE` each run: one code generation, the model code compiled once per "
        "platform and linked into both FMI versions' binaries; with mingw-w64 (the Windows DLLs too) and without it "
        "(`SDL_FMU_MINGW_CC` naming no compiler). A reference checkout's build (`--reference`) or a variant, where "
        "measured, ran alongside. CPU time also grows with the machine's load (shared caches), so compare rows measured together; "
        "wall time depends on the load far more.", "",
        *_table(["checkout", "kind", "runs", "CPU s, min", "CPU s, median", "wall s, median", "load average"],
                rows), "",
        _measured(data["measured"]), "",
        *([f"- {verdict}"] if verdict else []), ""]


SECTIONS = (fmu_step, demo_speed, scaling, sweep_workers, criticality_overhead, vehicle_path_speed, verify_pack,
            aeb_ccr, scenario_step, export_speed, isolation, hosted_controller, run_process, search_benchmark,
            search_cpu, build_cost)


def render(results: Path = RESULTS) -> str:
    head = [
        "# sdl-fmu benchmarks", "",
        "<!-- Generated by `python benchmarks/report.py` from benchmarks/results/*.json: edit those (by re-running "
        "a benchmark) or the script, not this file. -->", "",
        "What the co-simulation costs, against the alternatives, and how it scales. Speed targets live here, never "
        "in the timed tests. Each benchmark writes its results, with when and where it measured them, to "
        "`benchmarks/results/<name>.json`; this page is generated from those files. Ratios are measured side by "
        "side in one process; absolute times depend on the machine and its load.", "",
        "## How to reproduce", "",
        "From the repository, in its venv:", "",
        "```",
        "pip install -e '.[bench]'                     # adds pythonfmu",
        "python benchmarks/fmu_step.py --json benchmarks/results/fmu_step.json",
        "python benchmarks/demo_speed.py --json benchmarks/results/demo_speed.json",
        "python benchmarks/scaling.py                  # writes benchmarks/results/scaling.json and scaling.png",
        "python benchmarks/sweep_workers.py --runs 24 --json benchmarks/results/sweep_workers.json",
        "python benchmarks/criticality_overhead.py --vehicle-repeat 21 --instructions",
        "python benchmarks/vehicle_path_speed.py --reference CHECKOUT --json benchmarks/results/vehicle_path_speed.json",
        "python benchmarks/verify_pack.py --reference CHECKOUT --json benchmarks/results/verify_pack.json",
        "python benchmarks/aeb_ccr.py --json benchmarks/results/aeb_ccr.json",
        "python benchmarks/scenario_step.py --json benchmarks/results/scenario_step.json",
        "python benchmarks/export_speed.py --json benchmarks/results/export_speed.json",
        "python benchmarks/isolation.py --repeat 7 --json benchmarks/results/isolation.json  # --part vehicles|controller",
        "python benchmarks/hosted_controller.py --reference CHECKOUT --json benchmarks/results/hosted_controller.json",
        "python benchmarks/run_process.py --repeat 7 --reference CHECKOUT --json benchmarks/results/run_process.json",
        "python benchmarks/search_benchmark.py --json benchmarks/results/search_benchmark.json",
        "python benchmarks/search_cpu.py --json benchmarks/results/search_cpu.json",
        "python benchmarks/build_cost.py --reference CHECKOUT --json benchmarks/results/build_cost.json",
        "python benchmarks/report.py                   # regenerates this page",
        "```", "",
        "`summary.json` of every run records `timing`: `wall_s` (the co-simulation loop, from the first step to the "
        "last sample; loading the FMU and writing the results are not in it), `real_time_factor` (simulated s per "
        "wall s), `steps`, `samples`.", ""]
    body = [line for section in SECTIONS for line in section(results)]
    return "\n".join(head + body).rstrip() + "\n"


def main() -> int:
    arguments = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    arguments.add_argument("--check", action="store_true", help="only compare; exit 1 if BENCHMARKS.md differs")
    args = arguments.parse_args()
    text = render()
    if args.check:
        same = OUT.exists() and OUT.read_text() == text
        print("BENCHMARKS.md is up to date" if same else "BENCHMARKS.md differs: run python benchmarks/report.py")
        return 0 if same else 1
    OUT.write_text(text)
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
