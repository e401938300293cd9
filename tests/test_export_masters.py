"""Cross-master conformance: every shipped scenario, exported (`api.export`, FMI 2.0, step 0.01 s) and run by the real
SSP masters through the recipes of docs/export.md (read from that page, run as written), gives `sdl-fmu run`'s
events in the same order, each within the bound the scenario FMU's documentation states, the same collisions and
the same end; libcosim and ecos agree with each other to rounding. The FMI 3.0 export runs in ecos, and a vehicle
FMU built elsewhere (the test suite's PythonFMU car) runs in libcosim and ecos through its map.

Each master runs in a subprocess of its own (tests/ssp_masters.py)."""

from pathlib import Path

import numpy as np
import pytest

import results_snapshot
from sdl_fmu import api
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
END_REASONS = {"scenario": 1, "until_distance": 2, "until_time": 3, "runout": 4, "time_limit": 5}


# ---- the comparison with `sdl-fmu run` -------------------------------------------------------------------------------


def event_bound(step: float) -> float:
    """The bound the scenario FMU's documentation states on an event's instant in a master against `run`'s."""
    from sdl_fmu.export.scenario_fmu import event_bound as stated

    return stated(step)


def assert_conforms(result: dict[str, np.ndarray], reference: api.Result, step: float, label: str) -> None:
    """The same events in the same order, each within the bound; the same collisions; the same end."""
    time, count = result["time"], result["scenario.events"]
    assert np.all(np.diff(time) > 0) and abs(time[0] - step) < 1e-9, label
    assert np.all(np.diff(count) >= 0), label
    events = list(reference.events)
    assert count[-1] == len(events), (label, count[-1], len(events))
    bound = event_bound(step)
    for i, event in enumerate(events, 1):
        k = int(np.argmax(count >= i))  # the first communication point that shows the i-th event
        assert abs(time[k] - event["time_s"]) <= bound, (label, i, event, time[k])
        if count[k] == i:  # it was the last to fire in its step: the outputs name it
            shown = (result["scenario.last_event_code"][k], result["scenario.last_event_action"][k])
            assert shown == (CODES[event["code"]], ACTIONS[event["action"]]), (label, i, event, shown)
            if "vehicle" in event:
                assert result["scenario.last_event_vehicle"][k] == event["vehicle"], (label, i, event)
            if "line" in event:
                assert result["scenario.last_event_line"][k] == event["line"], (label, i, event)
            assert abs(result["scenario.last_event_time"][k] - event["time_s"]) <= bound, (label, i, event)
    assert result["scenario.collisions"][-1] == reference.collisions, label
    ended = result["scenario.ended"].astype(bool)
    assert ended[-1], label
    end = int(np.argmax(ended))
    assert abs(time[end] - reference.final["time_s"]) <= bound, (label, time[end], reference.final)
    assert result["scenario.end_reason"][end] == END_REASONS[events[-1]["reason"]], label


# libcosim and ecos step the same FMUs from the same values; they differ only in how they form the communication
# points (libcosim: whole nanoseconds, converted; ecos: a running sum of steps), which differ by a few ulps (1e-15
# s relative). The FMUs step from the point they are given, so each step's result moves by ~|dx/dt| 1e-15 s; over
# the runs here (at most 13 000 steps, |dx/dt| <= 40 m/s, the dynamics dissipative: no growth) that adds up to well
# under 1e-9 in any output. An event or a step change of a pedal could only move if a trigger's margin fell within
# that rounding of zero at a communication point.
ROUNDING = 1e-9


def assert_agree_to_rounding(a: dict[str, np.ndarray], b: dict[str, np.ndarray], label: str) -> None:
    for name, kind in SIGNALS.items():
        x, y = a[name], b[name]
        assert x.shape == y.shape, (label, name)
        if kind == "Real":
            scale = np.maximum(1.0, np.abs(x))
            worst = float(np.max(np.abs(x - y) / scale))
            assert worst <= ROUNDING, (label, name, worst)
        else:
            assert np.array_equal(x.astype(int), y.astype(int)), (label, name)


# ---- every shipped scenario in every master ------------------------------------------------------------------------


CASES = list(results_snapshot.cases())  # (name, dynamics, skip_unsupported), under each dynamics its header names


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """Every shipped scenario exported once (FMI 2.0, step 0.01 s), by (name, dynamics)."""
    folder = tmp_path_factory.mktemp("exports")
    return {(name, dynamics): api.export(name, dynamics=dynamics, skip_unsupported=skip, step=STEP,
                                         out=folder / f"{name}-{dynamics}")
            for name, dynamics, skip in CASES}


@pytest.fixture(scope="module")
def master_runs(exported):
    """Each export run by each master, once."""
    return {(key, master): run_master(master, export.ssp, export.stop_time, STEP, SIGNALS)
            for key, export in exported.items() for master in MASTERS}


@pytest.mark.slow
@pytest.mark.parametrize("master", MASTERS)
@pytest.mark.parametrize("name, dynamics", [(n, d) for n, d, _ in CASES], ids=[f"{n}-{d}" for n, d, _ in CASES])
def test_every_shipped_scenario_gives_runs_events_collisions_and_end_in_each_master(exported, master_runs, name,
                                                                                   dynamics, master):
    export = exported[(name, dynamics)]
    assert_conforms(master_runs[((name, dynamics), master)], export.reference, export.step, f"{name} {master}")


@pytest.mark.slow
@pytest.mark.parametrize("name, dynamics", [(n, d) for n, d, _ in CASES], ids=[f"{n}-{d}" for n, d, _ in CASES])
def test_libcosim_and_ecos_agree_to_rounding(master_runs, name, dynamics):
    key = (name, dynamics)
    assert_agree_to_rounding(master_runs[(key, "libcosim")], master_runs[(key, "ecos")], name)


@pytest.mark.slow
def test_the_fmi3_export_runs_in_ecos(tmp_path, simple_fmus):
    export = api.export("demo", fmi_version=3, out=tmp_path / "fmi3")
    for path in export.fmus.values():
        assert b'fmiVersion="3.0"' in _model_description(path)
    assert_conforms(run_master("ecos", export.ssp, export.stop_time, STEP, SIGNALS), export.reference, export.step,
                    "demo fmi3")


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
    assert_conforms(result, export.reference, export.step, f"foreign car {master}")
    # the scenario FMU sees the car in SI and ISO axes: km/h -> m/s, y to the right -> y to the left (an input read
    # after step k: libcosim shows the value step k used, the car's output at k - 1; ecos the car's output at k)
    lag = {"libcosim": 1, "ecos": 0}[master]
    sent = slice(0, len(result["time"]) - lag)
    assert np.allclose(result["scenario.ego_v"][lag:], result["ego.veh_speed"][sent] / 3.6, rtol=1e-12)
    assert np.allclose(result["scenario.ego_y"][lag:], -result["ego.earth_y"][sent], rtol=1e-12)
    assert result["ego.earth_y"][0] == pytest.approx(6 * 0.3048, rel=1e-6)  # lane 1's centre, to the right


def _model_description(fmu: Path) -> bytes:
    import zipfile

    with zipfile.ZipFile(fmu) as archive:
        return archive.read("modelDescription.xml")
