"""The foreign car (tests/vehicles, built at test time by pythonfmu3 / PythonFMU) driven through the shipped
scenarios `brake_examples`, `demo` and `head_on` by its vehicle map. Its BRK onsets and releases and its head-on
contact are checked against closed forms of the car's OWN equations (foreign_car_dynamics.py's docstring),
from the state each event reports.

Tolerances. The car cannot get or set its state, so the master cannot roll back: near a possible trigger it steps
at most 1 ms, fires what has become true at the end of that step, and reports the step as the event's
`time_uncertainty_s` (u): the true instant lies in (t - u, t] before the reported t, so a quantity changing at rate
r has passed its threshold by at most r u when it is reported (one-sided). The event acts from the reported instant
on (the pedals change there), so a BRK hold's own dynamics start exactly at its reported onset state. What the
car itself adds is Runge-Kutta 4 rounding (below 1e-9, test_foreign_vehicle.py). The distance sdl-fmu reports is
not the car's (it has none): sdl-fmu integrates the car's speed between communication points by the trapezoid
rule, whose error per step h is h^3 |v''| / 12, so over T seconds of braking at most T h_max^2 max|v''| / 12 with
h_max the driver's sampling period (the longest step while the driver or a BRK holds the pedals).
"""

import math
import tomllib

import pytest

from sdl_fmu import api
from sdl_fmu.units import FOOT, STANDARD_GRAVITY as G
from sdl_fmu.vehicle import STOPPED_SPEED

from helpers import foreign_parameters, local_cluster, sdl_fmu

pytestmark = pytest.mark.slow  # builds the FMUs with PythonFMU / pythonfmu3 and runs whole scenarios

NUMERIC = 1e-9  # the car's own integration error (test_foreign_vehicle.py), m or m/s
DRIVER_PERIOD = 0.05  # s, sdl-fmu's default driver sampling period: the longest step while braking


class Braking:
    """The car braking straight without throttle from v0, from its equations (see test_foreign_vehicle.py):
        v' = -(A + K v^2),  A = min(brake_gain p, mu m G) / m + roll_coeff G,  K = air_rho cd_a / (2 m)
        v(t) = sqrt(A/K) tan(theta0 - sqrt(A K) t),  theta0 = atan(v0 sqrt(K/A))
        t(v) = (theta0 - atan(v sqrt(K/A))) / sqrt(A K)
        s(v) = ln((A + K v0^2) / (A + K v^2)) / (2 K)  =>  v(s) = sqrt(((A + K v0^2) exp(-2 K s) - A) / K)
    and |v''| = |2 K v v'| <= 2 K v0 (A + K v0^2) for the distance bound."""

    def __init__(self, parameters, pressure, mu, v0):
        m = parameters["vehicle_mass"]
        self.A = min(parameters["brake_gain"] * pressure, mu * m * G) / m + parameters["roll_coeff"] * G
        self.K = parameters["air_rho"] * parameters["cd_a"] / (2 * m)
        self.v0 = v0
        self.theta0 = math.atan(v0 * math.sqrt(self.K / self.A))
        self.rate = math.sqrt(self.A * self.K)
        self.jerk_max = 2 * self.K * v0 * (self.A + self.K * v0**2)

    def speed(self, t):
        return math.sqrt(self.A / self.K) * math.tan(self.theta0 - self.rate * t)

    def time_to(self, v):
        return (self.theta0 - math.atan(v * math.sqrt(self.K / self.A))) / self.rate

    def distance_to(self, v):
        return math.log((self.A + self.K * self.v0**2) / (self.A + self.K * v * v)) / (2 * self.K)

    def speed_after(self, s):
        return math.sqrt(((self.A + self.K * self.v0**2) * math.exp(-2 * self.K * s) - self.A) / self.K)

    def release(self, threshold, magnitude):
        """(time after onset, speed) at which a BRK threshold (SI magnitude) is reached."""
        if threshold == "time":
            return magnitude, self.speed(magnitude)
        if threshold == "distance":
            v = self.speed_after(magnitude)
        elif threshold == "velocity":
            v = magnitude
        else:  # relative_velocity
            v = self.v0 - magnitude
        return self.time_to(v), v


@pytest.fixture(scope="module")
def runs(foreign_vehicle):
    """run(scenario, fmi_version, **options): the foreign car through a scenario, each combination run once."""
    cache = {}

    def run(scenario, fmi_version=3, **options):
        key = (scenario, fmi_version, tuple(sorted(options.items())))
        if key not in cache:
            fmu, vehicle = foreign_vehicle(fmi_version)
            cache[key] = api.run(scenario, fmu=fmu, vehicle=vehicle, progress=False, **options)
        return cache[key]

    return run


def brake_holds(events):
    """(on, off) pairs of BRK events, in order."""
    pairs, on = [], None
    for event in events:
        if event["code"] == "BRK" and event["action"] == "on":
            on = event
        elif event["code"] == "BRK" and event["action"] == "off":
            pairs.append((on, event))
    return pairs


def friction_at(events, distance_ft):
    """mu in lane 1 at a distance: the last RSA setting of lane 1 before it (value / 10), 0.8 without one."""
    value = 8.0
    for event in events:
        if event["code"] == "RSA" and event["lane"] == 1 and event["distance"] <= distance_ft:
            value = event["value"]
    return value / 10


def check_distance_triggers(result, scenario):
    """Every event the driven distance triggers (A spawn, BRK on, RSA set) fires at the first communication point
    at or past its distance D; the step before ended short of it, so 0 <= s - D <= (v + a u) u, with a the
    acceleration bound the run used (summary.json's vehicle bounds) and v the speed at the reported instant."""
    distances = {event.line: event.distance for event in api.load(scenario).events}
    acceleration = result.summary["vehicle"]["bounds"]["acceleration_m/s2"]
    checked = 0
    for event in result.events:
        if event.get("line") is not None and event["action"] in ("spawn", "on", "set"):
            u = event["time_uncertainty_s"]
            past = event["distance"] * FOOT - distances[event["line"]]
            assert -NUMERIC <= past <= (event["speed"] * FOOT + acceleration * u) * u + NUMERIC
            checked += 1
    return checked


def check_brake_hold(on, off, parameters, brake_scale, mu, reason=None):
    """One BRK hold against the car's closed forms, from the state its onset reports; reason: why it ends (its
    threshold unless given; "stopped": when the speed falls below sdl-fmu's STOPPED_SPEED, the car having no
    `stopped` output)."""
    # the brakes act from the reported onset on: pressure = the map's scale x pedal
    braking = Braking(parameters, brake_scale * on["pedal"] / 100, mu, on["speed"] * FOOT)
    if reason == "stopped":
        t_release = braking.time_to(STOPPED_SPEED)
    else:
        magnitude = on["magnitude"] * (1.0 if on["threshold"] == "time" else FOOT)
        t_release, _ = braking.release(on["threshold"], magnitude)
    t_off, u_off = off["time_s"] - on["time_s"], off["time_uncertainty_s"]
    assert off["reason"] == (reason or on["threshold"])
    # the release instant: at or after the closed form's, by at most its uncertainty (0 for the time threshold,
    # which the master steps to); the speed reported then on the closed-form curve
    assert -NUMERIC <= t_off - t_release <= u_off + NUMERIC
    assert off["speed"] * FOOT == pytest.approx(braking.speed(t_off), abs=NUMERIC)
    # the distance braked: sdl-fmu's trapezoid over the car's speed (bound in the module docstring)
    trapezoid = t_off * DRIVER_PERIOD**2 * braking.jerk_max / 12
    assert (off["distance"] - on["distance"]) * FOOT == pytest.approx(
        braking.distance_to(braking.speed(t_off)), abs=trapezoid + 2 * NUMERIC)


def brake_scale(map_path):
    with open(map_path, "rb") as file:
        return tomllib.load(file)["inputs"]["brake"]["scale"]


def brk_lines(scenario: str) -> list[int]:
    """The lines of the scenario's BRK events, in the order they take effect (read from the shipped file)."""
    return [event.line for event in api.load(scenario).events if event.code == "BRK"]


@pytest.mark.parametrize("fmi_version", [3, 2])
def test_foreign_car_brake_examples_match_its_closed_forms(runs, foreign_vehicle, fmi_version):
    """The four BRK examples of the STISIM text at 100 ft/s: full braking 3 s, 25 % for 200 ft, 50 % until below
    30 ft/s, full until 30 ft/s slower. Full braking asks 120 bar = 12 000 N, more than the grip 0.8 m G = 11 376 N:
    grip-limited; 25 % and 50 % are pressure-limited (3000 N, 6000 N)."""
    fmu, map_path = foreign_vehicle(fmi_version)
    result = runs("brake_examples", fmi_version, speed=100.0)
    parameters = foreign_parameters(fmu)
    holds = brake_holds(result.events)
    assert [on["line"] for on, _ in holds] == brk_lines("brake_examples")  # the four BRK examples, in order
    assert check_distance_triggers(result, "brake_examples") == 4
    for on, off in holds:
        check_brake_hold(on, off, parameters, brake_scale(map_path), 0.8)
    assert result.collisions == 0


@pytest.mark.parametrize("fmi_version", [3, 2])
def test_foreign_car_demo_brakes_match_its_closed_forms_without_collision(runs, foreign_vehicle, fmi_version):
    """demo: BRK at 4200 ft on ice (mu 0.2, grip-limited), 6000 ft and 7500 ft on mu 0.8, 9200 ft on mu 0.5 (60 %
    = 72 bar = 7200 N > 0.5 m G = 7110 N: grip-limited). Each hold ends well inside its surface patch.

    No collision, by hand: the oncoming cars (lines 7, 8) keep to lateral -6 ft, 12 ft = 3.66 m from the ego's lane
    centre at +6 ft, more than half the sum of widths (at most (1.8 + 2.55) / 2 = 2.18 m, the widest model). The
    truck (model 7, 2.5 m wide) drifts to -2 ft, 8 ft = 2.44 m from the ego's lane centre; contact would need the
    ego 2.44 - (1.8 + 2.5) / 2 = 0.29 m off its lane centre towards it. The swerving car (line 11) comes into the
    ego's lane at closure time 10 s and leaves it at closure time 5 s, 12 ft in 2 s: its lateral offset from the ego
    exceeds half the sum of widths (<= 2.18 m) after at most 2.18 / 3.6576 x 2 s = 1.19 s, at a closure time of at
    least 3.8 s; the gap is then >= 3.8 s x 108 ft/s = 125 m, far more than half the sum of lengths (<= 8.3 m)."""
    fmu, map_path = foreign_vehicle(fmi_version)
    result = runs("demo", fmi_version)
    parameters = foreign_parameters(fmu)
    holds = brake_holds(result.events)
    assert [on["line"] for on, _ in holds] == brk_lines("demo")  # each of the demo's four BRK lines, in order
    assert check_distance_triggers(result, "demo") == 4 + 4 + 8  # BRK on, A spawn, RSA set (4 lines, 2 lanes each)
    mus = [friction_at(result.events, on["distance"]) for on, _ in holds]
    assert mus == [0.2, 0.8, 0.8, 0.5]
    for (on, off), mu in zip(holds, mus):
        check_brake_hold(on, off, parameters, brake_scale(map_path), mu)
        # the hold (plus the car's length) stays on one surface
        changes = [e["distance"] for e in result.events if e["code"] == "RSA"]
        assert not any(on["distance"] - 4.6 / FOOT < d < off["distance"] + 4.6 / FOOT for d in changes)
    lateral = result.arrays["lateral_ft"]
    assert abs(lateral - 6.0).max() * FOOT < 0.29
    assert result.collisions == 0
    assert check_closure_actions(result, "demo") == 4  # the swerving car (line 11) and the truck (line 22), 2 each


def check_closure_actions(result, scenario):
    """Each closure-time action fires at the first communication point where the closure time (longitudinal gap
    between the centres / closing speed) is <= T. A vehicle of line L spawns `gap` ahead of the ego's distance d_s
    at t_s and comes at its speed w (held through these actions: each asks for the same speed), so at the reported
    instant t, with the ego at distance d and speed v:  closure = (d_s + gap - w (t - t_s) - d) / (v + w).
    It falls at the rate |d closure / dt| = |-1 - closure v' / (v + w)| <= 1 + T a / (v + w) (a: the acceleration
    bound), so at the reported instant T - (1 + T a / (v + w)) u <= closure <= T."""
    scenario_events = {event.line: event for event in api.load(scenario).events}
    acceleration = result.summary["vehicle"]["bounds"]["acceleration_m/s2"]
    spawns = {e["vehicle"]: e for e in result.events if e["code"] == "A" and e["action"] == "spawn"}
    checked = 0
    for event in result.events:
        if event["code"] != "A" or event["action"] != "maneuver":
            continue
        spawn = spawns[event["vehicle"]]
        line = scenario_events[spawn["line"]]
        w = line.speed.value
        assert all(action.speed.value == w and not action.speed.relative for action in line.actions)
        T = line.actions[event["index"] - 1].trigger.seconds
        v, u = event["speed"] * FOOT, event["time_uncertainty_s"]
        gap = spawn["distance"] * FOOT + line.gap - w * (event["time_s"] - spawn["time_s"]) - event["distance"] * FOOT
        closure = gap / (v + w)
        if event["time_s"] == spawn["time_s"]:  # already within T when the vehicle appeared
            assert closure <= T + NUMERIC
        else:
            assert T - (1 + T * acceleration / (v + w)) * u - NUMERIC <= closure <= T + NUMERIC
        checked += 1
    return checked


@pytest.mark.parametrize("fmi_version", [3, 2])
def test_foreign_car_head_on_contact_at_half_the_sum_of_lengths(runs, foreign_vehicle, fmi_version):
    """head_on: a sedan (model 2, 4.85 m) spawns 800 ft ahead of the ego's centre in its lane and comes at 40 ft/s;
    the footprints touch when the centre gap is (L_ego + L_sedan) / 2 = (4.6 + 4.85) / 2 m. At the reported
    contact instant t_c the sedan's centre is at d_spawn + 800 ft - 40 ft/s (t_c - t_spawn), the ego's at its
    driven distance d_c (a straight lane: distance = station); the gap closes at v_ego + 40 ft/s, so within u_c
    of the true instant it is half the sum of lengths within (v_ego + 40 ft/s) u_c. One contact, one collision."""
    result = runs("head_on", fmi_version)
    assert result.collisions == 1
    spawn, = [e for e in result.events if e["code"] == "A" and e["action"] == "spawn"]
    contact, = [e for e in result.events if e["code"] == "A" and e["action"] == "collision"]
    assert spawn["model"] == 2
    gap_ft = spawn["distance"] + 800.0 - 40.0 * (contact["time_s"] - spawn["time_s"]) - contact["distance"]
    closing_ft_s = contact["speed"] + 40.0
    overlap = (4.6 + 4.85) / 2 - gap_ft * FOOT
    assert -NUMERIC <= overlap <= closing_ft_s * FOOT * contact["time_uncertainty_s"] + NUMERIC
    # from scratch: the driver model's feed-forward is the car's own resistance law (its map's [vehicle]), so the
    # ego holds 88 ft/s exactly; it reaches 200 ft at 200/88 s and the contact comes (800 ft - 4.725 m) / 128 ft/s
    # later; each instant is reported up to its uncertainty after the true one, the spawn's delay carrying over
    # (the sedan is placed 800 ft ahead of where the ego is when the spawn is reported)
    assert result.arrays["speed_ft/s"] == pytest.approx(88.0, abs=1e-12)
    spawn_true = 200.0 / 88.0
    assert 0.0 <= spawn["time_s"] - spawn_true <= spawn["time_uncertainty_s"] + NUMERIC
    contact_true = spawn_true + (800.0 - (4.6 + 4.85) / 2 / FOOT) / 128.0
    assert -NUMERIC <= contact["time_s"] - contact_true <= spawn["time_uncertainty_s"] + contact[
        "time_uncertainty_s"] + NUMERIC


@pytest.mark.parametrize("fmi_version, replace, key, words", [
    # a variable the FMU lacks
    (3, ('"brake_pressure"', '"brake_line_pressure"'), "inputs.brake", "brake_line_pressure"),
    # an output of the FMU mapped as an input
    (2, ('throttle = { variable = "accel_pedal"', 'throttle = { variable = "veh_speed"'), "inputs.throttle",
     "veh_speed"),
    # a unit that disagrees with the one the FMI 3.0 build declares (km/h)
    (3, ('variable = "veh_speed", unit = "km/h"', 'variable = "veh_speed", unit = "m/s"'), "outputs.speed.unit",
     "km/h"),
], ids=["missing-variable", "output-as-input", "disagreeing-unit"])
def test_bad_foreign_car_map_is_one_line_naming_file_and_key(foreign_vehicle, tmp_path, fmi_version, replace, key,
                                                             words):
    fmu, good = foreign_vehicle(fmi_version)
    text = good.read_text()
    assert replace[0] in text
    bad = tmp_path / "bad_map.toml"
    bad.write_text(text.replace(replace[0], replace[1]))
    out = tmp_path / "results"
    completed = sdl_fmu("run", "head_on", "--fmu", fmu, "--vehicle", bad, "--out", out, cwd=tmp_path)
    assert completed.returncode == 2 and "Traceback" not in completed.stderr
    line, = completed.stderr.strip().splitlines()
    assert str(bad) in line and key in line and words in line
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad_map.toml"]


def test_foreign_car_sweeps_on_dask(foreign_vehicle, tmp_path):
    """A sweep drives the foreign car (its Python inside the FMU, one instance per Dask worker thread at once).
    head_on at v = 70, 80, 90 ft/s: the driver holds v exactly (see the head-on test), so the run ends at ES, 1600 ft,
    at the first communication point at or past 1600 / v seconds, at most MIN_LOOKAHEAD later; one collision each."""
    distributed = pytest.importorskip("distributed")
    from sdl_fmu import sweep as sweeping
    from sdl_fmu.cosim.master import MIN_LOOKAHEAD

    fmu, map_path = foreign_vehicle(3)
    cluster = local_cluster(2)
    try:
        with distributed.Client(cluster) as client:
            rows = sweeping.sweep("head_on", {"speed": [70.0, 80.0, 90.0]}, tmp_path / "sweep", client=client,
                                  progress=False, fmu=fmu, vehicle=map_path)
    finally:
        cluster.close()
    assert [(row["speed_ft/s"], row["status"], row["collisions"]) for row in rows] == [
        (70.0, "ok", 1), (80.0, "ok", 1), (90.0, "ok", 1)]
    for row in rows:
        assert row["final_speed_ft/s"] == pytest.approx(row["speed_ft/s"], abs=1e-9)
        assert -NUMERIC <= row["final_time_s"] - 1600.0 / row["speed_ft/s"] <= MIN_LOOKAHEAD + NUMERIC


@pytest.mark.parametrize("scenario, options", [("brake_examples", {"speed": 100.0}), ("demo", {}), ("head_on", {})])
def test_foreign_car_fmi2_and_fmi3_builds_agree(runs, scenario, options):
    """The same Python equations packaged twice: the FMI 3.0 build converts through its UnitDefinitions, the FMI 2.0
    build (no units) through the map's units and pint. The two conversions agree to the last bits (km/h: 1/3.6
    written to 16 digits or computed), so both runs fire the same events at the same communication points, their
    numbers equal to rounding (1e-12 relative)."""
    fmi3, fmi2 = runs(scenario, 3, **options), runs(scenario, 2, **options)
    assert len(fmi3.events) == len(fmi2.events) and fmi3.collisions == fmi2.collisions
    for a, b in zip(fmi3.events, fmi2.events):
        assert a.keys() == b.keys()
        for key in a:
            if isinstance(a[key], float):
                assert a[key] == pytest.approx(b[key], rel=1e-12, abs=1e-12)
            else:
                assert a[key] == b[key]


def test_foreign_car_brake_hold_ends_when_it_stops(runs, foreign_vehicle, tmp_path):
    """Full braking for 30 s from 88 ft/s: the car stops long before (t_stop = theta0 / sqrt(A K) = 3.34 s), so the
    hold ends as `stopped`. The car has no `stopped` output: sdl-fmu takes it as stopped below STOPPED_SPEED, which
    the closed form reaches at t(STOPPED_SPEED); the release comes at most its uncertainty later. Then the driver
    model drives off again (the car does not creep backwards meanwhile: its speed never goes below 0)."""
    scenario = tmp_path / "stop.sdl"
    scenario.write_text("English\n500,BRK,100,0,30\n1000,ES\n")
    fmu, map_path = foreign_vehicle(3)
    result = runs(str(scenario), 3)
    (on, off), = brake_holds(result.events)
    check_brake_hold(on, off, foreign_parameters(fmu), brake_scale(map_path), 0.8, reason="stopped")
    assert off["time_s"] - on["time_s"] < 30.0 and off["speed"] * FOOT < STOPPED_SPEED
    assert result.arrays["speed_ft/s"].min() >= 0.0 and result.final["distance"] >= 1000.0
