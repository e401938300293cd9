"""Cross-master conformance: every shipped scenario, exported (`api.export`, FMI 2.0, step 0.01 s) and run by the real
SSP masters through the recipes of docs/export.md (read from that page, run as written), gives `sdl-fmu run`'s
events in the same order, each within the bound the scenario FMU's documentation states, the same collisions and
the same end; libcosim and ecos agree with each other to rounding. The FMI 3.0 export runs in ecos, and a vehicle
FMU built elsewhere (the test suite's PythonFMU car) runs in libcosim and ecos through its map.

Each master runs in a subprocess of its own (tests/ssp_masters.py)."""

import ctypes
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import results_snapshot
from sdl_fmu import api
from sdl_fmu.cosim.locate import TIME_TOLERANCE
from sdl_fmu.export.scenario_fmu import tie_tolerance
from sdl_fmu.units import to_si
from helpers import FOREIGN_AEB_MAP, build_foreign_controller
from ssp_masters import MASTERS, run_master

STEP = 0.01  # s, the exported systems' step (export's default)

# what the tests record: outputs only (a master shows an input's value either before or after the transfer at a
# communication point: libcosim the value the last step used, ecos and fmpy the one the next step will use)
SCENARIO_SIGNALS = {"scenario.events": "Integer", "scenario.collisions": "Integer", "scenario.ended": "Boolean",
                    "scenario.end_reason": "Integer", "scenario.last_event_code": "Integer",
                    "scenario.last_event_action": "Integer", "scenario.last_event_vehicle": "Integer",
                    "scenario.last_event_line": "Integer", "scenario.last_event_time": "Real",
                    "scenario.throttle": "Real", "scenario.brake": "Real", "scenario.steer": "Real"}
SIGNALS = {**SCENARIO_SIGNALS, "ego.x": "Real", "ego.y": "Real", "ego.s": "Real", "ego.v": "Real"}  # shipped egos
CODES = {"A": 1, "BRK": 2, "RSA": 3, "ES": 4}
ACTIONS = {"spawn": 1, "maneuver": 2, "collision": 3, "despawn": 4, "on": 5, "off": 6, "set": 7, "end": 8}
END_REASONS = {"scenario": 1, "until_distance": 2, "until_time": 3, "runout": 4, "time_limit": 5, "collision": 6}


# ---- the comparison with `sdl-fmu run` -------------------------------------------------------------------------------

# Events the ego's distance travelled triggers (an A appears, an RSA is met, a BRK begins, the end by distance)
DISTANCE_EVENTS = {("A", "spawn"), ("RSA", "set"), ("BRK", "on")}
DISTANCE_ENDS = {"scenario", "until_distance", "runout"}
# s: how exactly `sdl-fmu run` locates its instants (its bisection; more for an ego that cannot roll back: the
# event's own time_uncertainty_s is added)
LOCATED = TIME_TOLERANCE
# The scenario FMU's bound (docs/scenario-fmu.md, Stepping): over step k its belief of the ego's distance is within
# e_k = (D_{k-1} + D_k) h^2 / 2 of the ego's, D the stray of the path acceleration from the one the inputs gave,
# at most 2 a_max: e_k <= 2 a_max h^2. Reading the master's distance linearly between communication points adds
# a_max h^2 / 8. In time, divided by the speed there.
DISTANCE_BOUND = 2.0 + 1.0 / 8.0  # x a_max h^2


def ego_lag(master_time, master_s, master_v, reference: api.Result, a_max: float) -> float:
    """How far the master's ego runs behind run's (s): at each communication point up to run's end where it moves
    (> 1 m/s), the time the master's ego takes to reach the distance run's ego had then; run's distance between its
    samples is read linearly, within a_max dt^2 / 8 (dt its sample spacing), which is added."""
    run_time = np.asarray(reference.raw.columns["time"], float)
    run_s = np.asarray(reference.raw.columns["s"], float)
    t = np.concatenate([[0.0], master_time])
    s = np.concatenate([[0.0], master_s])
    use = (master_v > 1.0) & (master_time <= run_time[-1])
    if not use.any():
        return 0.0
    times = master_time[use]
    reached = np.interp(np.interp(times, run_time, run_s), s, t)
    spacing = np.diff(run_time)[np.clip(np.searchsorted(run_time, times) - 1, 0, len(run_time) - 2)]
    return float(np.max(np.abs(reached - times) + a_max * spacing**2 / (8 * master_v[use])))


def assert_conforms(result: dict[str, np.ndarray], reference: api.Result, step: float, label: str, *, distance,
                    speed, a_max: float) -> None:
    """The same events in the same order, each shown at the first communication point at or after its located instant
    (the scenario FMU's bound), and at run's instant moved by the master's ego lag: exactly (to how the instant is
    located) for an event the ego's distance triggers, within that lag and a step for the others; the same
    collisions; the same end. distance and speed: the master's ego's, at its communication points (m, m/s); a_max:
    a bound on its acceleration (m/s2)."""
    time, count = result["time"], result["scenario.events"]
    assert np.all(np.diff(time) > 0) and abs(time[0] - step) < 1e-9, label
    assert np.all(np.diff(count) >= 0), label
    events = list(reference.events)
    assert count[-1] == len(events), (label, count[-1], len(events))
    lag = ego_lag(time, distance, speed, reference, a_max)
    t = np.concatenate([[0.0], time])
    s = np.concatenate([[0.0], distance])
    for i, event in enumerate(events, 1):
        k = int(np.argmax(count >= i))  # the first communication point that shows the i-th event
        assert abs(time[k] - event["time_s"]) <= step + lag, (label, i, event, time[k], lag)
        if count[k] != i:  # another event fired after it in the same step: the outputs name that one
            continue
        shown = (result["scenario.last_event_code"][k], result["scenario.last_event_action"][k])
        assert shown == (CODES[event["code"]], ACTIONS[event["action"]]), (label, i, event, shown)
        if "vehicle" in event:
            assert result["scenario.last_event_vehicle"][k] == event["vehicle"], (label, i, event)
        if "line" in event:
            assert result["scenario.last_event_line"][k] == event["line"], (label, i, event)
        located = result["scenario.last_event_time"][k]
        assert time[k] - step - 1e-9 <= located <= time[k] + tie_tolerance(time[k]), \
            (label, i, event, located, time[k])
        if (event["code"], event["action"]) in DISTANCE_EVENTS or event.get("reason") in DISTANCE_ENDS:
            # where the master's ego reaches run's ego's distance at the event
            where = to_si(event["distance"], reference.scenario.units)
            reached = float(np.interp(where, s, t))
            v = float(np.interp(reached, t[1:], speed))
            bound = LOCATED + event.get("time_uncertainty_s", 0.0) + DISTANCE_BOUND * a_max * step**2 / v
            assert abs(located - reached) <= bound, (label, i, event, located, reached)
    assert result["scenario.collisions"][-1] == reference.collisions, label
    ended = result["scenario.ended"].astype(bool)
    assert ended[-1], label
    end = int(np.argmax(ended))
    assert abs(time[end] - reference.final["time_s"]) <= step + lag, (label, time[end], reference.final)
    assert result["scenario.end_reason"][end] == END_REASONS[events[-1]["reason"]], label


def check(result: dict[str, np.ndarray], export: api.Export, label: str) -> None:
    """assert_conforms for an export of a shipped ego (its distance and speed are the outputs s and v)."""
    assert_conforms(result, export.reference, export.step, label, distance=result["ego.s"], speed=result["ego.v"],
                    a_max=export.parameters["scenario"]["ego_max_acceleration"])


# libcosim and ecos step the same FMUs from the same values; they differ only in how they form the communication
# points (libcosim: whole nanoseconds, converted; ecos: a running sum of steps), which differ by a few ulps (1e-15
# s relative). The FMUs step from the point they are given, so each step's result moves by ~|dx/dt| 1e-15 s; over
# the runs here (at most 13 000 steps, |dx/dt| <= 40 m/s, the dynamics dissipative: no growth) that adds up to well
# under 1e-9 in any output. Measured: 2e-16 relative in the ego's distance after the demo's 130 s.
ROUNDING = 1e-9
# An event whose instant falls within that rounding of a communication point (a tie, which round SDL numbers make
# common: approaching_vehicle's ES at 1100 ft at a constant 88 ft/s is 12.5 s, exactly a communication point) shows
# at that point in both: the scenario FMU counts an instant up to tie_tolerance(t) after a communication point t as
# the step's (docs/scenario-fmu.md, Stepping, ties), far more than the masters' clocks differ. So every event, count
# and code is the same in both, at every communication point.


def assert_agree_to_rounding(a: dict[str, np.ndarray], b: dict[str, np.ndarray], label: str) -> None:
    time = a["time"]
    assert np.array_equal(time, b["time"]), label
    for name, kind in SIGNALS.items():
        x, y = a[name], b[name]
        assert x.shape == y.shape, (label, name)
        if kind == "Real":
            worst = float(np.max(np.abs(x - y) / np.maximum(1.0, np.abs(x))))
            assert worst <= ROUNDING, (label, name, worst)
        else:
            assert np.array_equal(x.astype(int), y.astype(int)), (label, name)


# ---- every shipped scenario in every master ------------------------------------------------------------------------


# (name, dynamics, skip_unsupported, driver), under each dynamics its header names, with the options it names
CASES = list(results_snapshot.cases())


@pytest.fixture(scope="module")
def foreign_controller_and_ccrs(tmp_path_factory):
    """The foreign AEB controller (tests/controllers, PythonFMU, FMI 2.0) and a CCRs-like scenario."""
    folder = tmp_path_factory.mktemp("aeb")
    (folder / "ccrs.sdl").write_text("Metric\n// a stationary compact car 60 m ahead in the ego's lane\n"
                                     "0, A, 0, 60, *0, 1\n200, ES\n")
    return build_foreign_controller(folder, 2), folder / "ccrs.sdl"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """Every shipped scenario exported once (FMI 2.0, step 0.01 s), by (name, dynamics)."""
    folder = tmp_path_factory.mktemp("exports")
    return {(name, dynamics): api.export(name, dynamics=dynamics, skip_unsupported=skip, step=STEP, driver=driver,
                                         out=folder / f"{name}-{dynamics}")
            for name, dynamics, skip, driver in CASES}


@pytest.fixture(scope="module")
def master_runs(exported):
    """Each export run by each master, once."""
    return {(key, master): run_master(master, export.ssp, export.stop_time, STEP, SIGNALS)
            for key, export in exported.items() for master in MASTERS}


@pytest.mark.slow
@pytest.mark.xdist_group("master-runs")  # one worker computes master_runs (pytest -n: a module fixture per worker)
@pytest.mark.parametrize("master", MASTERS)
@pytest.mark.parametrize("name, dynamics", [(n, d) for n, d, _, _ in CASES],
                         ids=[f"{n}-{d}" for n, d, _, _ in CASES])
def test_every_shipped_scenario_gives_runs_events_collisions_and_end_in_each_master(exported, master_runs, name,
                                                                                   dynamics, master):
    check(master_runs[((name, dynamics), master)], exported[(name, dynamics)], f"{name} {master}")


@pytest.mark.slow
@pytest.mark.xdist_group("master-runs")
@pytest.mark.parametrize("name, dynamics", [(n, d) for n, d, _, _ in CASES],
                         ids=[f"{n}-{d}" for n, d, _, _ in CASES])
def test_libcosim_and_ecos_agree_to_rounding(master_runs, name, dynamics):
    key = (name, dynamics)
    assert_agree_to_rounding(master_runs[(key, "libcosim")], master_runs[(key, "ecos")], name)


@pytest.mark.slow
def test_the_fmi3_export_runs_in_ecos(tmp_path, simple_fmus, scenario_binaries):
    export = api.export("demo", fmi_version=3, out=tmp_path / "fmi3")
    for path in export.fmus.values():
        assert b'fmiVersion="3.0"' in _model_description(path)
    check(run_master("ecos", export.ssp, export.stop_time, STEP, SIGNALS), export, "demo fmi3")


@pytest.mark.slow
@pytest.mark.parametrize("master", ["libcosim", "ecos"])
def test_a_foreign_vehicle_fmu_exports_and_runs_through_its_map(tmp_path, foreign_vehicle, master):
    # the PythonFMU car (tests/vehicles): its own names, %, bar, degrees, km/h, SAE axes, no distance output; every
    # connection but x and the friction scales or converts. head_on: a spawn, a contact, a despawn and the end
    fmu, vehicle_map = foreign_vehicle(2)
    export = api.export("head_on", fmu=fmu, vehicle=vehicle_map, out=tmp_path / "foreign")
    signals = {**SCENARIO_SIGNALS, "ego.veh_speed": "Real", "ego.earth_y": "Real", "scenario.ego_v": "Real",
               "scenario.ego_y": "Real"}
    result = run_master(master, export.ssp, export.stop_time, STEP, signals)
    # the car has no distance output: the scenario FMU takes the trapezoid rule on its speed, as run does
    speed = result["ego.veh_speed"] / 3.6
    before = np.concatenate([[export.reference.raw.columns["v"][0]], speed[:-1]])  # the start speed at t = 0
    distance = np.cumsum(STEP * (before + speed) / 2)
    assert_conforms(result, export.reference, export.step, f"foreign car {master}", distance=distance, speed=speed,
                    a_max=export.parameters["scenario"]["ego_max_acceleration"])
    # the scenario FMU sees the car in SI and ISO axes: km/h -> m/s, y to the right -> y to the left (an input read
    # after step k: libcosim shows the value step k used, the car's output at k - 1; ecos the car's output at k)
    lag = {"libcosim": 1, "ecos": 0}[master]
    sent = slice(0, len(result["time"]) - lag)
    assert np.allclose(result["scenario.ego_v"][lag:], result["ego.veh_speed"][sent] / 3.6, rtol=1e-12)
    assert np.allclose(result["scenario.ego_y"][lag:], -result["ego.earth_y"][sent], rtol=1e-12)
    assert result["ego.earth_y"][0] == pytest.approx(6 * 0.3048, rel=1e-6)  # lane 1's centre, to the right


@pytest.mark.slow
def test_a_vehicle_that_fills_its_outputs_only_on_leaving_initialization_is_started_right_in_ecos(tmp_path,
                                                                                                  foreign_vehicle):
    # the FMI 3.0 foreign car (pythonfmu3) computes its outputs in exit_initialization_mode: ecos passes them on in
    # initialization mode (zeros: an ego at rest on the dividing line, which asks for full throttle and a steer to the
    # right) and again after every FMU left it (its start). The scenario FMU takes the start again at its first step:
    # its commands from then on to the driver's next sample (0.05 s) are those it gives the FMI 2.0 car, whose outputs
    # are right in initialization mode, bit for bit. What it cannot change is the car's first step, which ecos feeds
    # with the commands read before it (docs/export.md, the start).
    results = {}
    for version in (3, 2):
        fmu, vehicle_map = foreign_vehicle(version)
        export = api.export("head_on", fmu=fmu, vehicle=vehicle_map, fmi_version=3, out=tmp_path / f"car{version}")
        signals = {"scenario.throttle": "Real", "scenario.brake": "Real", "scenario.steer": "Real",
                   "scenario.ego_v": "Real", "scenario.ego_y": "Real"}
        results[version] = run_master("ecos", export.ssp, 0.1, STEP, signals)
    before_the_next_sample = slice(0, 4)  # t = 0.01 ... 0.04
    for name in ("scenario.throttle", "scenario.brake", "scenario.steer"):
        assert np.array_equal(results[3][name][before_the_next_sample], results[2][name][before_the_next_sample]), \
            (name, results[3][name][:5], results[2][name][:5])
    assert results[3]["scenario.throttle"][0] < 0.2 and results[3]["scenario.steer"][0] == 0.0  # not 1.0, -0.355


@pytest.mark.slow
def test_ecos_asks_every_fmi3_fmu_for_its_version_before_loading_its_binary(tmp_path, foreign_vehicle):
    # ecos (ecospy 0.7.2) prints 'Function "fmi3GetVersion" is not provided by this FMU.' for each FMI 3.0 FMU: its
    # model-description reader calls fmi4c's fmi3_getVersion, and fmi4c loads an FMI 3.0 binary's functions only when
    # an instance is made, so the call reaches fmi4c's placeholder (docs/export.md, ecos). Not ours: the same line for
    # the car pythonfmu3 built, once per FMI 3.0 FMU; our binaries export fmi3GetVersion, which answers "3.0".
    fmu, vehicle_map = foreign_vehicle(3)
    export = api.export("head_on", fmu=fmu, vehicle=vehicle_map, fmi_version=3, out=tmp_path / "fmi3")
    code = ("import sys\nfrom ecospy import EcosSimulation\n"
            "with EcosSimulation(ssp_path=sys.argv[1], step_size=0.01) as simulation:\n"
            "    simulation.init(parameter_set='start')\n    simulation.step()\n    simulation.terminate()\n")
    completed = subprocess.run([sys.executable, "-c", code, str(export.ssp)], capture_output=True, text=True,
                               timeout=300)
    assert completed.returncode == 0, completed.stderr[-2000:]
    said = completed.stdout + completed.stderr
    assert said.count('Function "fmi3GetVersion" is not provided by this FMU.') == 2, said[-2000:]
    with zipfile.ZipFile(export.fmus["scenario"]) as archive:
        archive.extractall(tmp_path / "scenario")
    library = ctypes.CDLL(str(tmp_path / "scenario" / "binaries" / "x86_64-linux" / "SdlScenario.so"))
    library.fmi3GetVersion.restype = ctypes.c_char_p
    assert library.fmi3GetVersion() == b"3.0"


def _model_description(fmu: Path) -> bytes:
    with zipfile.ZipFile(fmu) as archive:
        return archive.read("modelDescription.xml")


@pytest.mark.slow
@pytest.mark.parametrize("master", ["libcosim", "ecos"])
def test_a_controller_brakes_the_ego_two_steps_after_its_sample(tmp_path, foreign_controller_and_ccrs, master):
    # CCRs-like at 50 km/h toward a stationary car; the foreign AEB (PythonFMU, its own units: km/h, ms, %) latches a
    # full brake at the first sample with TTC <= 1.5 s, as in run (tests/vehicle/test_controller_runs.py). Run applies
    # the request from that sample; in the SSP the request is the controller's output one step later and the scenario
    # FMU's arbitrated command one step after that, so the ego brakes 2 h later, from the same constant speed V0, and
    # then as in run: it stops 2 h V0 further (0.278 m), with the same events
    fmu, ccrs = foreign_controller_and_ccrs
    v0 = 50 / 3.6
    export = api.export(ccrs, speed=v0, until_time=8.0, controller=fmu, controller_map=FOREIGN_AEB_MAP,
                        out=tmp_path / "aeb")
    result = run_master(master, export.ssp, export.stop_time, STEP, {**SIGNALS, "controller.aeb_active": "Boolean"})
    check(result, export, f"aeb {master}")
    assert export.reference.collisions == 0 and export.reference.final["speed"] == 0.0
    stop = export.reference.final["distance"]  # m (Metric)
    assert result["ego.v"][-1] == 0.0
    assert abs(result["ego.s"][-1] - (stop + 2 * STEP * v0)) < 1e-9, (result["ego.s"][-1], stop)


@pytest.mark.slow
def test_the_end_at_the_first_contact_and_the_follow_driver_in_a_master(tmp_path, simple_fmus):
    # head_on with --on-collision stop: the scenario ends at the contact (end reason collision); and with the follow
    # driver (Gipps' law), whose decisions every 2/3 s the scenario FMU takes on its predicted ego
    for options in ({"on_collision": "stop"}, {"driver": "follow"}):
        export = api.export("head_on", out=tmp_path / "-".join(options.values()), **options)
        check(run_master("libcosim", export.ssp, export.stop_time, STEP, SIGNALS), export, f"head_on {options}")
