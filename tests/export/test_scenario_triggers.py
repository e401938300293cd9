"""Triggers inside a step: in a master stepping at a fixed h (Jacobi: the scenario FMU and the ego FMU both step
t -> t + h with each other's outputs at t), each event fires inside the step that holds its true instant, located on
the predicted path, so that it takes effect at the first communication point at or after that instant.

The truth is the ego's own trajectory in that master: at every step that fires something, the ego FMU is restored to
its state at the step's start (fmi2SetFMUstate) and stepped, with the same inputs, to the reported instant, and the
scenario FMU is replayed over the step in 200 sub-steps along that trajectory (the prediction over h / 200 is exact to
~1e-12 m, an oracle with the same rules).

The bound, derived (docs/scenario-fmu.md): over a step the scenario FMU predicts the ego's distance s(t + tau) =
s + v tau + s'' tau^2 / 2 with s'' = (vx ax + vy ay) / v from its inputs at t, and its belief starts from where the
previous step's prediction ended, fading that offset linearly to 0. With D_k = max |s''(t) - s''_in| over step k (the
ego's path acceleration against the one its inputs gave; it jumps when the commands change at t), the belief's
distance error is at most e_k = (D_{k-1} + D_k) h^2 / 2 (plus the bisection's 1e-9 s times v). A distance-triggered
event (its SDL distance D) is therefore fired where the ego's true distance is within e_k of D, and in the step that
holds its true instant unless that instant is within e_k / v of the step's end points.
"""

import math
import tempfile
from pathlib import Path

import pytest

from sdl_fmu import api
from sdl_fmu.export.scenario_fmu import tie_tolerance, write_scenario_fmu

from scenario_generator import random_scenario
from scenario_harness import (Ego, ScenarioInstance, path_acceleration, scenario_inputs, wheel_names)

H = 0.01  # s, the master's communication step
SUBSTEPS = 200  # the oracle's sub-steps per step
BISECTION = 1e-9  # s, TRIGGER_TOLERANCE of the runtime
DISTANCE_ACTIONS = {("A", "spawn"), ("BRK", "on"), ("RSA", "set")}

pytestmark = pytest.mark.usefixtures("simple_fmus", "scenario_binaries")  # the FMUs the masters run, from the cache


def scenario_fmu(scenario, dynamics, directory, fmi_version=2, **options):
    ego = api.ego_model(dynamics, fmu=None) if dynamics else None
    fmu = write_scenario_fmu(scenario, directory / f"scenario{fmi_version}.fmu", ego=ego, fmi_version=fmi_version,
                             **options)
    return fmu, ego


def ego_start(scenario, speed):
    return {"v0": speed, "x0": 0.0, "y0": -scenario.road.lane_center(1), "psi0": 0.0}


def connect(scenario_instance, ego, dynamics):
    """The master's transfer at a communication point: the ego's outputs to the scenario, the scenario's commands and
    surfaces to the ego (both read before either is set: Jacobi)."""
    outputs = ego.outputs()
    commands = {name: scenario_instance.get(name) for name in ("throttle", "brake", "steer", *wheel_names(dynamics))}
    assert scenario_instance.set(**scenario_inputs(outputs)) == 0
    ego.set(**commands)
    return outputs


def oracle(scenario_instance, ego, start_states, t, h, before):
    """The events of step (t, t + h] with the scenario FMU stepped in SUBSTEPS sub-steps along the ego's trajectory
    (ego inputs held as in the step); every instance is put back where it was."""
    sc_state, ego_state = start_states
    sc_after, ego_after = scenario_instance.get_state(), ego.save()
    messages = len(scenario_instance.messages)
    assert scenario_instance.set_state(sc_state) == 0
    ego.restore(ego_state, t)
    logged = len(scenario_instance.events())
    delta = h / SUBSTEPS
    for j in range(SUBSTEPS):
        start = t + j * delta
        end = t + h if j == SUBSTEPS - 1 else t + (j + 1) * delta
        if j > 0:
            assert scenario_instance.set(**scenario_inputs(ego.outputs())) == 0
        assert scenario_instance.step(start, end - start)[0] == 0
        ego.step_to(end)
    found = scenario_instance.events()[logged:]
    del scenario_instance.messages[messages:]
    assert scenario_instance.set_state(sc_after) == 0
    ego.restore(ego_after, t + h)
    for state in (sc_after,):
        scenario_instance.free_state(state)
    ego.discard(ego_after)
    return found


def true_state_at(ego, start_state, t, instant, after_time):
    """The ego's outputs at `instant` inside the step from t, on its own trajectory (restored, stepped, put back)."""
    after = ego.save()
    ego.restore(start_state, t)
    ego.step_to(instant)
    outputs = ego.outputs()
    ego.restore(after, after_time)
    ego.discard(after)
    return outputs


def run_master(scenario, dynamics, directory, stop_time, check=True):
    """The Jacobi master over the scenario; checks every fired event (see the module docstring); returns the
    events and what was measured."""
    fmu, model = scenario_fmu(scenario, dynamics, directory, until_time=stop_time)
    instance = ScenarioInstance(fmu.path, directory / "unzipped")
    assert instance.component, instance.messages
    instance.debug_logging(True)
    ego = Ego(model.fmu_path, ego_start(scenario, fmu.parameters["speed"]))
    instance.initialize({}, scenario_inputs(ego.outputs()))
    by_line = {event.line: event for event in scenario.events}
    t, k, previous_deviation = 0.0, 0, 0.0
    measured = {"events": 0, "worst_distance_error": 0.0, "bound_margin": math.inf, "oracle_worst": 0.0,
                "neighbouring": 0}
    while not instance.get("ended"):
        outputs = connect(instance, ego, dynamics)
        s_rate_in = path_acceleration(outputs)
        s_rate_start = path_acceleration(ego.outputs())  # the ego's acceleration with its new inputs (feedthrough)
        states = (instance.get_state(), ego.save())
        before = len(instance.events())
        end = (k + 1) * H
        ego.step_to(end)
        status, _, _, _ = instance.step(t, end - t)
        assert status == 0, instance.messages[-3:]
        end_outputs = ego.outputs()
        deviation = max(abs(s_rate_start - s_rate_in), abs(path_acceleration(end_outputs) - s_rate_in))
        fired = instance.events()[before:]
        if fired and check:
            bound = (previous_deviation + deviation) * H * H / 2 + BISECTION * max(outputs["v"], end_outputs["v"])
            truth = oracle(instance, ego, states, t, end - t, before)
            assert [(e.code, e.action, e.vehicle) for e in fired] == [(e.code, e.action, e.vehicle) for e in truth], \
                (t, fired, truth)
            for event, true_event in zip(fired, truth):
                measured["events"] += 1
                assert t < event.time <= end, (t, event)  # fired inside this step: takes effect at t + h
                measured["oracle_worst"] = max(measured["oracle_worst"], abs(event.time - true_event.time))
                if (event.code, event.action) in DISTANCE_ACTIONS:
                    distance = by_line[event.line].distance
                    at = true_state_at(ego, states[1], t, event.time, end)
                    error = abs(at["s"] - distance)
                    measured["worst_distance_error"] = max(measured["worst_distance_error"], error)
                    measured["bound_margin"] = min(measured["bound_margin"], bound - error)
                    assert error <= bound, (event, error, bound)
                    # the true instant is in this step, or within bound / v of one of its ends
                    inside = outputs["s"] < distance <= end_outputs["s"]
                    near_end = min(abs(outputs["s"] - distance), abs(end_outputs["s"] - distance)) <= bound
                    assert inside or near_end, (event, outputs["s"], end_outputs["s"], distance)
                    measured["neighbouring"] += not inside
        for state in states[:1]:
            instance.free_state(state)
        ego.discard(states[1])
        previous_deviation = deviation
        t, k = end, k + 1
    events = instance.events()
    ego.close()
    instance.free()
    return events, measured


@pytest.mark.parametrize("name, stop", [("demo", 52.0), ("head_on", None), ("road_surface_simple", None)])
def test_fixed_step_master_fires_each_event_in_the_step_of_its_instant(name, stop, tmp_path):
    """demo to 52 s: spawns, actions, departures, RSA and a BRK on and off; head_on: a collision; road_surface_simple:
    a BRK ended by distance on a surface change."""
    scenario = api.load(name)
    events, measured = run_master(scenario, "simple", tmp_path, stop)
    assert measured["events"] == len(events) > 0  # every event fired inside a step and was checked
    # the same events in the same order as sdl-fmu run (their instants drift: see test_early_return_...)
    run = api.run(scenario, dynamics="simple", until_time=stop)
    assert [(e.code, e.action, e.vehicle) for e in events] == \
           [(e["code"], e["action"], e.get("vehicle")) for e in run.events]


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_fixed_step_master_on_generated_scenarios(seed, tmp_path):
    """Random scenarios (collisions, actions with F and B, every BRK threshold, RSA on shoulders)."""
    path = tmp_path / f"generated{seed}.sdl"
    path.write_text(random_scenario(seed))
    scenario = api.load(path, dynamics="simple")
    events, measured = run_master(scenario, "simple", tmp_path, 60.0)
    assert measured["events"] > 0


def early_master(scenario, directory, early: bool):
    """An FMI 3.0 master at the fixed step H that honours early return: when the scenario FMU returns at an event's
    instant, the ego is stepped to that instant too, and the master goes on from there to the next grid point."""
    fmu, model = scenario_fmu(scenario, "simple", directory, fmi_version=3)
    instance = ScenarioInstance(fmu.path, directory / "unzipped", early_return=early)
    assert instance.component, instance.messages
    instance.debug_logging(True)
    from sdl_fmu.fmu.cache import cached_fmu

    ego = Ego(cached_fmu("simple", 3), ego_start(scenario, fmu.parameters["speed"]))
    instance.initialize({}, scenario_inputs(ego.outputs()))
    t, k, returns = 0.0, 0, 0
    while not instance.get("ended"):
        connect(instance, ego, "simple")
        status, returned, reached, terminate = instance.step(t, (k + 1) * H - t)
        assert status == 0 and terminate == bool(instance.get("ended"))
        assert returned == (reached < (k + 1) * H)
        ego.step_to(reached)
        returns += returned
        k += not returned
        t = reached
    events = instance.events()
    ego.close()
    instance.free()
    return events, returns


@pytest.mark.parametrize("name", ["demo", "brake_examples"])
def test_early_return_makes_a_fixed_step_master_exact(name, tmp_path):
    """With early return, every event's commands reach the ego at the event's instant, so the fixed-step system
    follows `sdl-fmu run` (which applies everything at the exact instant): every event within 5e-6 s of the run's
    (the run locates to 1e-6 s, the prediction to far better, and the driver's samples are on the grid in both).
    Without it, each BRK takes effect up to h late and the events after it drift by up to tens of ms (demo: 0.033 s
    at 130 s, measured): the fixed-step bound."""
    scenario = api.load(name)
    run = list(api.run(scenario, dynamics="simple").events)
    exact, returns = early_master(scenario, tmp_path, early=True)
    assert returns > 0
    assert [(e.code, e.action, e.vehicle) for e in exact] == [(e["code"], e["action"], e.get("vehicle")) for e in run]
    assert max(abs(ours.time - theirs["time_s"]) for ours, theirs in zip(exact, run)) < 5e-6
    fixed, returns = early_master(scenario, tmp_path / "fixed", early=False)
    assert returns == 0
    assert [(e.code, e.action, e.vehicle) for e in fixed] == [(e["code"], e["action"], e.get("vehicle")) for e in run]
    assert max(abs(ours.time - theirs["time_s"]) for ours, theirs in zip(fixed, run)) > 1e-3


# ---- ties at communication points and the belief's fading offset --------------------------------------------------

FOOT = 0.3048


def one_event_fmu(text: str, directory: Path):
    path = directory / "scenario.sdl"
    path.write_text(text)
    return write_scenario_fmu(api.load(path), directory / "scenario.fmu", ego=api.ego_model("simple"))


def test_the_tie_tolerance_is_the_runtimes():
    # scenario_fmu.TIE_TOLERANCE (what the cross-master tests hold the located instants to) is runtime/scenario.h's
    import re

    from sdl_fmu.export.binary import RUNTIME_DIRECTORY
    from sdl_fmu.export.scenario_fmu import TIE_TOLERANCE

    header = (RUNTIME_DIRECTORY / "scenario.h").read_text()
    assert float(re.search(r"#define TIE_TOLERANCE (\S+)", header)[1]) == TIE_TOLERANCE
    assert tie_tolerance(0.5) == TIE_TOLERANCE and tie_tolerance(-12.5) == 12.5 * TIE_TOLERANCE


@pytest.mark.parametrize("clock", ["nanoseconds", "running sum"])
def test_an_event_within_rounding_after_a_communication_point_shows_there(clock, tmp_path):
    """A tie: ES at 1100 ft at a constant 88 ft/s is 12.5 s, a communication point at h = 10 ms (approaching_vehicle's
    end). Masters form their communication points with different rounding (libcosim: whole nanoseconds, converted;
    ecos: a running sum of steps, a few ulps off), and the ego's distance carries its own, so the located instant
    falls a hair before 12.5 s in one master and a hair after it in another. An instant within tie_tolerance(t) after
    the communication point t (1e-9 relative: 1.25e-8 s here) belongs to the step that ends at t: the end shows at
    12.5 s with the ego's distance 1e-12 m (18 ulps; its instant 3.7e-14 s) short of 1100 ft, on it, or past it, with
    either clock, located on the belief to the bisection's 1e-9 s."""
    fmu = one_event_fmu("English\n1100,ES\n", tmp_path)
    v = 88 * FOOT
    shown = set()
    for shift in (-1e-12, 0.0, 1e-12):
        instance = ScenarioInstance(fmu.path, tmp_path / f"shift{shift}")
        instance.initialize({}, {"ego_v": v, "ego_vx": v, "ego_y": -6 * FOOT})
        t, k = 0.0, 0
        while not instance.get("ended"):
            assert instance.set(ego_x=v * t + shift, ego_s=v * t + shift) == 0
            assert instance.step(t, H)[0] == 0, instance.messages[-2:]
            k += 1
            t = k * 10_000_000 / 1e9 if clock == "nanoseconds" else t + H
            assert k < 1300
        located = instance.get("last_event_time")
        assert (instance.get("end_reason"), instance.get("events")) == (1, 1)  # ES
        assert abs(t - 12.5) < 1e-12 and located - t <= tie_tolerance(t), (shift, t, located)
        assert abs(located - (12.5 - shift / v)) <= BISECTION + 1e-12, (shift, located)
        shown.add(k)
        instance.free()
    assert shown == {1250}


@pytest.mark.parametrize("speed", [26.8224, 0.3])
def test_the_trigger_bounds_follow_the_beliefs_fading_offset(speed, tmp_path):
    """The worst case of docs/scenario-fmu.md (Stepping, the bound's proof). Over step 1 the ego's inputs say it
    brakes at the acceleration bound a (ax = -a), while it accelerates at +a (a command change: its path acceleration
    strays by 2a, the most the bound allows); at t = h its inputs hold where it is (s1 = V h + a h^2 / 2, v1 = V + a h,
    ax = +a). The belief ended step 1 at V h - a h^2 / 2, a h^2 behind: over step 2 it is
        s_b(tau) = s1 + v1 tau + a tau^2 / 2 - a h^2 (1 - tau / h),
    which moves at v1 + a h, faster than the speed v1 the inputs give, by the fading offset's rate a h. ES is put
    where the belief arrives at tau* = 0.9 h. A lower bound on the arrival that took the speed v1 as the distance's rate
    would say tau* + a h tau* / (v1 + a tau*): the end located 2.7e-5 s late at 88 ft/s, and at 0.3 m/s after the
    step's end (1.6e-3 s late), so that it shows one step late. With the offset's rate in the bound the end is located
    at h + tau* (to the bisection's 1e-9 s) and shows at 2 h."""
    a, h = 8.0, H
    s1, v1 = speed * h + a * h * h / 2, speed + a * h
    tau = 0.9 * h
    distance = s1 + v1 * tau + a * tau * tau / 2 - a * h * h * (1 - tau / h)
    fmu = one_event_fmu(f"Metric\n{distance!r},ES\n", tmp_path)
    instance = ScenarioInstance(fmu.path, tmp_path / "unzipped")
    lane = -6 * FOOT
    instance.initialize({"ego_max_acceleration": a}, {"ego_v": speed, "ego_vx": speed, "ego_ax": -a, "ego_y": lane})
    assert instance.step(0.0, h)[0] == 0 and not instance.get("ended")
    assert instance.set(ego_x=s1, ego_s=s1, ego_v=v1, ego_vx=v1, ego_ax=a) == 0
    assert instance.step(h, h)[0] == 0
    assert instance.get("ended"), "the end shows one step late"
    located = instance.get("last_event_time")
    assert abs(located - (h + tau)) <= BISECTION + 1e-12, (located, h + tau)
    assert not any(category == "logStatusWarning" for _, category, _ in instance.messages)  # within the bounds
    instance.free()
