"""Criticality measures located by the master on runs of the real Simple FMU, against hand computations written
here, and the same values whatever --step (0.001 ... 10 s)."""

import math

import numpy as np
import pytest

from sdl_fmu.cosim.extremes import RANGE
from sdl_fmu.cosim.geometry import Footprint
from sdl_fmu.cosim.measures import distances, drac
from sdl_fmu.cosim.master import CRITICALITY_TOLERANCE, Cosimulation, RunOptions
from sdl_fmu.paths import SCENARIO_DIRECTORY
from sdl_fmu.sdl import default_vehicle_table_path, load_scenario, load_vehicle_table, parse_text
from sdl_fmu.units import FOOT
from sdl_fmu.vehicle import EgoModel, shipped_map_path

from helpers import as_written

TABLE = load_vehicle_table(default_vehicle_table_path())
STEPS = (0.001, 0.01, 1.0, 10.0)
V0 = 88 * FOOT  # m/s, the driver's default speed, which it holds on a straight road

SCENARIOS = {
    # model 1 (4.2 x 1.75 m) oncoming at 20 ft/s in the other lane (centre 6 ft left of the dividing line)
    "adjacent": lambda: parse_text("English\n100,A,20,1000,-6,1\n1500,ES", "adjacent.sdl"),
    # model 1 moving the ego's way at 40 ft/s in its lane, 300 ft ahead; full brake at 200 ft until 20 ft/s
    "braking": lambda: parse_text("English\n100,A,-40,300,*0,1\n200,BRK,100,2,20\n380,ES", "braking.sdl"),
    # model 1 oncoming at 20 ft/s in the other lane, 500 ft ahead; within 4 s it moves toward the ego's lane
    # (to -3 ft, its footprint still outside it) over 1 s, within 1.5 s back out to -8 ft over 2 s; the ego
    # brakes at half pedal from 300 ft (BRK_ONCOMING: drag and rolling resistance 0, a constant deceleration)
    "braking_oncoming": lambda: parse_text("English\n100,A,20,500,-6,1,4,-3,20,1,1.5,-8,20,2\n"
                                           "300,BRK,50,0,20\n700,ES", "braking_oncoming.sdl"),
    # model 1 oncoming at 20 ft/s in the other lane; within 1 s it starts moving over to the ego's lane centre
    # (6 ft) over 8 s, entering the ego's lane behind the ego (the ego passes first); the second action, armed
    # (it fires 30 s apart), keeps it on the road (a vehicle leaves only with no action left that could fire)
    "ego_first": lambda: parse_text("English\n100,A,20,1000,-6,1,1,6,20,8,-30,-6,20,2\n1500,ES", "ego_first.sdl"),
    "head_on": lambda: load_scenario(SCENARIO_DIRECTORY / "head_on.sdl"),
    # model 1 (4.2 x 1.75 m) in the ego's lane 200 ft ahead, going the ego's way at 60 ft/s; within 4 s of each
    # other it moves to the other lane (-6 ft) over 3 s at the same speed: the headway applies (within RANGE)
    # until its footprint leaves the ego's path
    "lead_leaves": lambda: parse_text("English\n100,A,-60,200,*0,1,4,-6,-60,3\n1500,ES", "lead_leaves.sdl"),
    "seed_a": lambda: load_scenario(SCENARIO_DIRECTORY / "approaching_vehicle.sdl"),
    # the demo to 4700 ft (54 s): three cars pass, one swerving into the ego's lane and back (PET, transitions
    # ending within range), a BRK on ice
    "demo": lambda: load_scenario(SCENARIO_DIRECTORY / "demo.sdl"),
}
UNTIL = {"demo": 4700 * FOOT}
BRK_ONCOMING = {"drag_area": 0.0, "rolling_resistance": 0.0}
PARAMETERS = {"braking_oncoming": BRK_ONCOMING}
_runs: dict = {}


@pytest.fixture
def run(simple_fmu):
    """(result, the master) of a scenario at a step, each run once per session."""
    def at(name: str, step: float = 0.01):
        if (name, step) not in _runs:
            model = EgoModel.open(simple_fmu, shipped_map_path("simple")).with_parameters(PARAMETERS.get(name))
            cosim = Cosimulation(SCENARIOS[name](), model, RunOptions(step=step, until_distance=UNTIL.get(name)), TABLE)
            _runs[(name, step)] = as_written(cosim.run()), cosim
        return _runs[(name, step)]
    return at


def event(result, action: str, **match) -> dict:
    return next(e for e in result.events if e["action"] == action and all(e.get(k) == v for k, v in match.items()))


def column(result, name: str) -> np.ndarray:
    return np.asarray(result.columns[name], dtype=float)


def test_oncoming_vehicle_in_the_adjacent_lane_minimum_distance_is_the_lateral_clearance(run):
    # The ego holds lane 1's centre (lateral 6 ft, yaw 0) at 88 ft/s; the car's centre is at lateral -6 ft.
    # Their footprints (ego width W, car 1.75 m) face each other across 12 ft - (W + 1.75 m) / 2 whenever they
    # overlap lengthwise, i.e. while |station_car - x| <= (L + 4.2 m) / 2 = h. The car spawns at t_s
    # (ego at 100 ft) 1000 ft ahead at 20 ft/s: station_car - x = 1000 ft - (88 + 20) ft/s (t - t_s), so the
    # overlap (and the minimum, first reached) starts at t* = t_s + (1000 ft - h) / 108 ft/s.
    result, cosim = run("adjacent")
    ego_length, ego_width = cosim.bounds.length, cosim.bounds.width
    lateral = column(result, "lateral")
    assert np.abs(column(result, "v") - V0).max() < 1e-9 and np.abs(lateral - 6 * FOOT).max() < 1e-12
    assert np.abs(column(result, "psi")).max() < 1e-12
    clearance = 12 * FOOT - (ego_width + 1.75) / 2
    half_sum = (ego_length + 4.2) / 2
    spawn = event(result, "spawn")["time_s"]
    start = spawn + (1000 * FOOT - half_sum) / (108 * FOOT)
    vehicle = result.criticality["vehicles"][0]
    assert vehicle["min_distance"] == pytest.approx(clearance / FOOT, abs=1e-9)
    # located by bisection to CRITICALITY_TOLERANCE after the instant (speed held to 1e-9 m/s: < 1e-9 s)
    assert 0 <= vehicle["min_distance_time_s"] - start <= CRITICALITY_TOLERANCE + 1e-9
    # the distance holds over the whole overlap: at every sample inside it, the same clearance
    track = result.vehicles[0]
    rows = slice(track.first, track.first + len(track.station))
    dx = np.asarray(track.station) - column(result, "x")[rows]
    inside = np.abs(dx) < half_sum
    assert inside.sum() >= 3
    d = distances(Footprint.of(ego_length, ego_width, 0.0), dx[inside],
                  -np.asarray(track.lateral)[inside] - column(result, "y")[rows][inside], 4.2, 1.75)
    assert np.abs(d - clearance).max() < 1e-12
    assert vehicle["min_ttc_s"] is None and vehicle["max_drac"] is None and vehicle["min_pet_s"] is None


def test_head_on_ttc_is_gap_over_closing_speed_and_drac_closing_squared_over_twice_the_gap(run):
    # head_on.sdl: model 2 (4.85 x 1.85 m) spawns 800 ft ahead in the ego's lane at 40 ft/s oncoming. With the
    # ego on the lane centre at yaw 0 the footprints overlap sideways, so under constant velocities they touch
    # after gap / closing: TTC = (station_car - x - (L + 4.85) / 2) / (v + 40 ft/s) at each instant, and
    # DRAC = closing^2 / (2 gap) (= |v_rel| / (2 TTC), v_rel along the road). Both within RANGE (50 m) only.
    result, cosim = run("head_on")
    track = result.vehicles[0]
    rows = slice(track.first, track.first + len(track.station))
    assert np.abs(column(result, "psi")[rows]).max() < 1e-12
    gap = np.asarray(track.station) - column(result, "x")[rows] - (cosim.bounds.length + 4.85) / 2
    closing = column(result, "v")[rows] + 40 * FOOT
    ttc = result.ttc_series()[rows]
    near = (gap > 0) & (gap <= RANGE)
    assert near.sum() > 20 and np.isnan(ttc[gap > RANGE]).all()
    assert ttc[near] == pytest.approx(gap[near] / closing[near], rel=1e-9)
    assert [drac(t, c, 0.0) for t, c in zip(ttc[near], closing[near])] == \
        pytest.approx(closing[near] ** 2 / (2 * gap[near]), rel=1e-9)
    # in contact TTC is 0: the smallest TTC, at the contact's start (the collision event, located to 1e-6 s)
    collision = event(result, "collision")["time_s"]
    summary = result.criticality
    assert summary["min_ttc_s"] == 0.0 and summary["min_distance"] == 0.0
    assert abs(summary["min_ttc_time_s"] - collision) <= 1e-6 + CRITICALITY_TOLERANCE
    # the ego touched it: no DRAC (it grows without bound toward the contact: any finite value would only say how
    # close to it the last look was, 286 788 ft/s2 at the default step before), the contact flagged instead
    vehicle = summary["vehicles"][0]
    assert vehicle["contact"] and summary["contact"]
    assert vehicle["max_drac"] is None and vehicle["max_drac_time_s"] is None and summary["max_drac"] is None


def test_the_headway_applies_until_the_vehicle_ahead_leaves_the_path_and_its_minimum_there_is_located(run):
    # lead_leaves: the ego holds V0 = 88 ft/s at yaw 0 on lane 1's centre (y = -6 ft); the car (4.2 x 1.75 m)
    # spawns at t_s 200 ft ahead (centres) in the ego's lane going its way at 60 ft/s, closing at 28 ft/s; action 1
    # at t_a (the gap 4 s x 28 ft/s = 112 ft) moves it from lateral 6 ft to -6 ft over 3 s: dy = 4 ft/s (t - t_a).
    # The headway applies while the footprints overlap across the road, |dy| < (W + 1.75 m) / 2, i.e. until
    # t_end = t_a + (W + 1.75 m) / 2 / (4 ft/s); it falls all along (the gap closes), so its minimum is at that
    # end of its domain: (200 ft - 28 ft/s (t_end - t_s) - (L + 4.2 m) / 2) / V0 (about 21 m from bumper to
    # bumper: within RANGE). Not a communication point: the instant is located (it was the last sample before it,
    # whatever the step)
    result, cosim = run("lead_leaves")
    length, width = cosim.bounds.length, cosim.bounds.width
    assert np.abs(column(result, "v") - V0).max() < 1e-9 and np.abs(column(result, "psi")).max() < 1e-12
    t_s, t_a = event(result, "spawn")["time_s"], event(result, "maneuver", index=1)["time_s"]
    assert t_a - t_s == pytest.approx(88 / 28, abs=1e-5)
    t_end = t_a + (width + 1.75) / 2 / (4 * FOOT)
    headway = (200 * FOOT - 28 * FOOT * (t_end - t_s) - (length + 4.2) / 2) / V0
    vehicle = result.criticality["vehicles"][0]
    assert vehicle["min_headway_time_s"] == pytest.approx(t_end, abs=1e-6)
    assert vehicle["min_headway_s"] == pytest.approx(headway, abs=1e-6)
    assert not vehicle["contact"] and result.collisions == 0


def test_seed_a_post_encroachment_time(run):
    # approaching_vehicle.sdl (the STISIM A example): the car (model m) spawns at t_s 1000 ft ahead at lateral
    # -6 ft, oncoming at 20 ft/s; action 1 at once moves it to the ego's lateral L1 = 6 ft over 2 s; action 2
    # at t2 moves it back to -6 ft over 2 s. Its footprint (width w) leaves the ego's lane (lateral 0 .. 12 ft)
    # when its centre passes -w / 2: t_leave = t2 + 2 s (L1 + w / 2) / (L1 + 6 ft), standing then at
    # station x_s + 1000 ft - 20 ft/s (t_leave - t_s) (x_s: the ego at t_s). The conflict area's near end is
    # its rear, station - l / 2; the ego's front (x + L / 2, x = x_s + 88 ft/s (t - t_s)) reaches it at
    # t_reach = t_s + (station - l / 2 - L / 2 - x_s) / 88 ft/s. PET = t_reach - t_leave.
    result, cosim = run("seed_a")
    spawn = event(result, "spawn")
    model = TABLE[spawn["model"]]
    t_s, x_s = spawn["time_s"], spawn["distance"] * FOOT
    t2 = event(result, "maneuver", index=2)["time_s"]
    lateral1 = spawn["lateral"] * FOOT
    assert t2 > t_s + 2 and lateral1 == pytest.approx(6 * FOOT, abs=1e-12)
    t_leave = t2 + 2 * (lateral1 + model.width / 2) / (lateral1 + 6 * FOOT)
    station = x_s + 1000 * FOOT - 20 * FOOT * (t_leave - t_s)
    t_reach = t_s + (station - model.length / 2 - cosim.bounds.length / 2 - x_s) / V0
    assert np.abs(column(result, "v") - V0).max() < 1e-9
    # t_leave is stepped to exactly; the reach bisected to CRITICALITY_TOLERANCE; the ego's speed within 1e-9
    # m/s of 88 ft/s moves its front by < 1e-8 m over the 10 s: < 1e-9 s
    pet = result.criticality["min_pet_s"]
    assert 0 <= pet - (t_reach - t_leave) <= CRITICALITY_TOLERANCE + 1e-9
    assert result.criticality["vehicles"][0]["min_pet_s"] == pet


def test_post_encroachment_time_when_the_ego_passes_first(run):
    # ego_first: PET = t_entry(second, area) - t_exit(first, area) (CommonRoad-CriMe pet.py, case 1: the ego
    # first; SUMO's "departure of the first from the conflict area to the arrival of the second"). The ego
    # (L x W, yaw 0) holds 88 ft/s from x_s at t_s (the spawn); the car (model 1, l x w) spawns at
    # c = x_s + 1000 ft, oncoming at 20 ft/s: c(t) = x_s + 1000 ft - 20 ft/s (t - t_s). Action 1 fires when the
    # closure time gap / 108 ft/s falls to 1 s: t_a = t_s + (1000 - 108) ft / 108 ft/s. From t_a its centre moves
    # from -6 ft to 6 ft over 8 s (1.5 ft/s); its footprint enters the ego's lane (lateral 0 ... 12 ft) when the
    # centre passes -w / 2: t_enter = t_a + (6 ft - w / 2) / 1.5 ft/s, covering stations c(t_enter) -+ l / 2. The
    # ego left that area when its rear x - L / 2 passed the far end c(t_enter) + l / 2:
    # t_exit = t_s + (c(t_enter) + l / 2 + L / 2 - x_s) / 88 ft/s. PET = t_enter - t_exit.
    from sdl_fmu.cosim.master import TIME_TOLERANCE

    result, cosim = run("ego_first")
    L = cosim.bounds.length
    model = TABLE[1]
    spawn = event(result, "spawn")
    t_s, x_s = spawn["time_s"], spawn["distance"] * FOOT
    t_a = event(result, "maneuver", index=1)["time_s"]
    assert 0 <= t_s - 100 / 88 <= TIME_TOLERANCE and 0 <= t_a - (t_s + (1000 - 108) / 108) <= TIME_TOLERANCE + 1e-9
    t_enter = t_a + (6 * FOOT - model.width / 2) / (1.5 * FOOT)
    far_end = x_s + 1000 * FOOT - 20 * FOOT * (t_enter - t_s) + model.length / 2
    t_exit = t_s + (far_end + L / 2 - x_s) / V0
    expected = t_enter - t_exit
    assert 0.5 < expected < t_enter - t_a  # the ego left the area after the move began, and before the entry
    # the ego's distance from its closed form (speed held by the driver), e_x, moves its rear's passage by e_x / v0
    time, x = column(result, "time"), column(result, "x")
    e_x = np.abs(x - (x_s + V0 * (time - t_s)))[time >= t_s].max()
    assert np.abs(column(result, "psi")).max() < 1e-12
    # the rear's passage bisected to CRITICALITY_TOLERANCE (at or after it); t_enter closed form as the master's
    pet = result.criticality["vehicles"][0]["min_pet_s"]
    assert -CRITICALITY_TOLERANCE - e_x / V0 - 1e-12 <= pet - expected <= e_x / V0 + 1e-12
    assert result.criticality["min_pet_s"] == pet and result.collisions == 0
    print(f"PET {expected:.9f} s, located {pet - expected:+.2e} s (e_x {e_x:.1e} m)")


def test_braking_ego_minimum_distance_at_the_root_of_its_derivative(run):
    # The car moves the ego's way at u = 40 ft/s in its lane; the ego brakes (BRK, full pedal, from 200 ft)
    # from 88 ft/s. The distance between the footprints is the bumper gap g = station_car - x - h (yaw 0,
    # same lateral), g' = u - v: the minimum is the root of g', where the ego's speed falls through u. By hand
    # from the samples: the sample interval where v crosses u, the instant by linear interpolation of v
    # (error <= |v''| dt^2 / 8 / |v'|, bounded below with the samples' second differences), g there by cubic
    # Hermite interpolation of x with its derivative vx (error <= |x''''| dt^4 / 384, i.e. the jerk's change).
    result, cosim = run("braking")
    u = 40 * FOOT
    time, x, v, vx = (column(result, name) for name in ("time", "x", "v", "vx"))
    assert np.abs(column(result, "psi")).max() < 1e-12
    k = int(np.flatnonzero((v[:-1] > u) & (v[1:] <= u))[0])
    dt = time[k + 1] - time[k]
    fraction = (v[k] - u) / (v[k] - v[k + 1])
    root = time[k] + fraction * dt
    curvature = abs(v[k + 1] - 2 * v[k] + v[k - 1]) / (time[k] - time[k - 1]) ** 2
    slope = abs(v[k + 1] - v[k]) / dt
    time_bound = curvature * dt**2 / 8 / slope
    h00, h10, h01, h11 = (2 * fraction**3 - 3 * fraction**2 + 1, fraction**3 - 2 * fraction**2 + fraction,
                          -2 * fraction**3 + 3 * fraction**2, fraction**3 - fraction**2)
    x_root = h00 * x[k] + h10 * dt * vx[k] + h01 * x[k + 1] + h11 * dt * vx[k + 1]
    track = result.vehicles[0]
    car = np.interp(root, time[track.first:track.first + len(track.station)], np.asarray(track.station))
    gap = car - x_root - (cosim.bounds.length + 4.2) / 2
    vehicle = result.criticality["vehicles"][0]
    assert abs(vehicle["min_distance_time_s"] - root) <= time_bound + CRITICALITY_TOLERANCE
    # the car's station is linear in time (exact interpolation); x by Hermite: within 1e-6 ft of the located
    # value (the rate is 0 there: the instant's uncertainty changes the distance by |v'| dt_err^2 / 2 only)
    assert vehicle["min_distance"] == pytest.approx(gap / FOOT, abs=1e-6)
    assert vehicle["min_distance_time_s"] > event(result, "on")["time_s"]


def bisect_root(f, low: float, high: float) -> float:
    """The root of f in [low, high] (f(low) < 0 <= f(high)) to the last bits of a double."""
    assert f(low) < 0 <= f(high)
    while True:
        middle = 0.5 * (low + high)
        if not low < middle < high:
            return high
        low, high = (low, middle) if f(middle) >= 0 else (middle, high)


def test_braking_ego_and_an_oncoming_vehicle_minimum_distance_at_the_root_of_its_derivative(run, simple_fmu):
    # braking_oncoming: everything in metres and seconds. The ego drives lane 1's centre (lateral Y = 6 ft,
    # yaw 0) at v0 = 88 ft/s from x = 0. BRK (half pedal, from 300 ft) with drag and rolling resistance 0 and
    # mu = 0.8: the demand 0.5 brake_decel_max < mu g, so (straight-line braking's closed form) a constant deceleration
    # a = 0.5 brake_decel_max from the onset t_b (x_b, v_b the logged onset): x(t) = x_b + v_b tau - a tau^2 / 2,
    # v = v_b - a tau, tau = t - t_b. The car (model 1, l x w = 4.2 x 1.75 m) spawns at t_s, 500 ft ahead of
    # the ego's x_s, oncoming at u = 20 ft/s: c(t) = x_s + 500 ft - u (t - t_s). Its lateral position: -6 ft;
    # from action 1 (t1) linearly to -3 ft over 1 s; from action 2 (t2) linearly to -8 ft over 2 s.
    # Action k fires when the closure time (c - x) / (u + v) falls to 4 s and 1.5 s: before BRK (both speeds
    # constant) t1 = t_s + (500 ft - 4 s x 108 ft/s) / 108 ft/s; t2 by bisection on the closed forms.
    # While the car is ahead of the ego (gx > 0) and off its lane side (gy > 0) the closest points are the
    # ego's front left corner and the car's front corner on the ego's side:
    #   gx = c - l / 2 - (x + L / 2),  gy = (Y - W / 2) - (lat + w / 2),  d = sqrt(gx^2 + gy^2),
    #   d' = (gx gx' + gy gy') / d, gx' = -(u + v), gy' = -lat'.
    # While the car pulls back out (lat' = -2.5 ft/s, gy' > 0) and closes (gx' < 0), d' rises from < 0 to > 0:
    # the minimum is the interior root of f = gx gx' + gy gy', found here by bisection on the closed forms.
    # The logged instants (spawn, actions, BRK) are the master's triggers, each located within TIME_TOLERANCE
    # after its hand instant and then the true start of the motions; the closed forms take them as such.
    from fmpy import read_model_description

    from sdl_fmu.cosim.ego import parameter_defaults
    from sdl_fmu.cosim.master import TIME_TOLERANCE

    result, cosim = run("braking_oncoming")
    L, W = cosim.bounds.length, cosim.bounds.width
    model = TABLE[1]
    l, w = model.length, model.width
    v0, u, Y = V0, 20 * FOOT, 6 * FOOT
    a = 0.5 * parameter_defaults(read_model_description(str(simple_fmu)))["brake_decel_max"]
    assert 0.5 * 9.81 < 0.8 * 9.80665  # the demand is below the friction limit: rolling, a = demand
    time, x, vx = column(result, "time"), column(result, "x"), column(result, "vx")
    assert np.abs(column(result, "psi")).max() < 1e-12 and np.abs(column(result, "lateral") - Y).max() < 1e-12
    spawn, brk = event(result, "spawn"), event(result, "on")
    t_s, x_s = spawn["time_s"], spawn["distance"] * FOOT
    t_b, x_b, v_b = brk["time_s"], brk["distance"] * FOOT, brk["speed"] * FOOT
    t1, t2 = (event(result, "maneuver", index=k)["time_s"] for k in (1, 2))
    assert 0 <= t_s - 100 / 88 <= TIME_TOLERANCE and 0 <= t_b - 300 / 88 <= TIME_TOLERANCE
    assert 0 <= t1 - (t_s + (500 - 4 * 108) / 108) <= TIME_TOLERANCE + 1e-9
    assert t1 + 1 < t_b < t2

    def ego_x(t):
        return x_b + v_b * (t - t_b) - a * (t - t_b) ** 2 / 2

    def ego_v(t):
        return v_b - a * (t - t_b)

    def car(t):
        return x_s + 500 * FOOT - u * (t - t_s)

    assert 0 <= t2 - bisect_root(lambda t: 1.5 - (car(t) - ego_x(t)) / (u + ego_v(t)), t_b, t_b + 3) \
        <= TIME_TOLERANCE + 1e-9

    def gaps(t):
        lateral = (-3 - 2.5 * min(t - t2, 2.0)) * FOOT if t >= t2 else -3 * FOOT
        lateral_rate = -2.5 * FOOT if t2 <= t < t2 + 2 else 0.0
        return car(t) - l / 2 - ego_x(t) - L / 2, Y - W / 2 - lateral - w / 2, -(u + ego_v(t)), -lateral_rate

    def f(t):
        gx, gy, gx_rate, gy_rate = gaps(t)
        return gx * gx_rate + gy * gy_rate

    root = bisect_root(f, t2, t2 + 2)
    gx, gy, gx_rate, gy_rate = gaps(root)
    assert gx > 0 and gy > 0 and ego_v(root) > 0  # an interior root: corner to corner, the ego still moving
    expected = math.sqrt(gx * gx + gy * gy)
    # how far the FMU's ego is from the closed form (its fixed-step solver; the samples after the onset up to
    # past the root), in position e_x and speed e_v; the root of f moves by at most
    # (e_x |gx'| + e_v gx) / f'(root), f' = gx'^2 + gx gx'' + gy'^2 (gx'' = a, gy'' = 0)
    braking = (time > t_b) & (time < root + 1)
    e_x = np.abs(x[braking] - ego_x(time[braking])).max()
    e_v = np.abs(vx[braking] - ego_v(time[braking])).max()
    slope = gx_rate**2 + gx * a + gy_rate**2
    vehicle = result.criticality["vehicles"][0]
    located = vehicle["min_distance_time_s"]
    # located: a bracket of CRITICALITY_TOLERANCE about the FMU's own root, the first instant within FLAT kept
    assert abs(located - root) <= CRITICALITY_TOLERANCE + (e_x * abs(gx_rate) + e_v * gx) / slope + 1e-12
    # the value: at a root the distance is flat (d'' dt^2 / 2 < 1e-12 m for dt < 1e-6 s); off by the FMU's e_x
    assert vehicle["min_distance"] * FOOT == pytest.approx(expected, abs=e_x + 1e-12)
    assert result.criticality["min_distance"] == vehicle["min_distance"]
    assert vehicle["min_ttc_s"] is None and vehicle["min_pet_s"] is None  # never on a course, never in the lane
    print(f"root {root:.9f} s, located {located - root:+.2e} s; distance {expected:.9f} m, "
          f"located {vehicle['min_distance'] * FOOT - expected:+.2e} m; e_x {e_x:.1e} m, e_v {e_v:.1e} m/s")


CRITICALITY_TIMES = ("min_distance_time_s", "min_ttc_time_s", "max_drac_time_s", "min_headway_time_s")
CRITICALITY_LENGTHS = ("min_distance", "max_drac")


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_criticality_is_the_same_whatever_the_step(run, name):
    # Every instant is located (bisected to CRITICALITY_TOLERANCE from whichever side the step brackets it,
    # after the master's triggers, themselves within 1e-6 s): two runs agree within 1e-6 s, and the values,
    # taken at roots of their rates (flat there) or at located instants, within 1e-6 ft, except where the
    # trajectories themselves differ between the runs: under BRK the FMU's fixed-step solver, whose steps end
    # at the communication points, puts the ego some 1e-5 ft elsewhere at --step 0.001 than at the driver's
    # 0.05 s samples; and a car spawned 1e-6 s later (the spawn trigger's own tolerance) starts (v - u) 1e-6 s
    # further on, which cancels against the ego for an oncoming car but not for one moving the ego's way
    # (48 ft/s x 1e-6 s here). Both measured below on the common samples; the distance may differ by as much.
    # A vehicle the ego touched has no DRAC (null, the contact flagged): head-on too, every key agrees.
    reference, _ = run(name, 0.01)
    ref_time, ref_s = column(reference, "time"), column(reference, "s")
    for step in STEPS:
        result, _ = run(name, step)
        time, s = column(result, "time"), column(result, "s")
        common = np.intersect1d(np.round(time, 9), np.round(ref_time, 9))
        drift = np.abs(np.interp(common, time, s) - np.interp(common, ref_time, ref_s)).max() / FOOT
        for track, ref_track in zip(result.vehicles, reference.vehicles):  # the cars: spawned 1e-6 s apart
            own, ref_own = (time[track.first:track.first + len(track.station)],
                            ref_time[ref_track.first:ref_track.first + len(ref_track.station)])
            both = common[(common >= max(own[0], ref_own[0])) & (common <= min(own[-1], ref_own[-1]))]
            drift += np.abs(np.interp(both, own, np.asarray(track.station))
                            - np.interp(both, ref_own, np.asarray(ref_track.station))).max() / FOOT
        for entry, expected in zip([result.criticality, *result.criticality["vehicles"]],
                                   [reference.criticality, *reference.criticality["vehicles"]]):
            assert entry.keys() == expected.keys()
            for key, value in entry.items():
                if key == "vehicles":
                    continue
                if value is None or expected[key] is None:
                    assert value is None and expected[key] is None, (step, key)
                elif key in CRITICALITY_TIMES or key.endswith("_s"):
                    assert value == pytest.approx(expected[key], abs=1e-6), (step, key)
                else:
                    # the oncoming cases: the clearance and 0 in contact do not depend on where either is
                    slack = drift if name in ("braking", "braking_oncoming", "demo") else 0.0
                    assert value == pytest.approx(expected[key], abs=1e-6 + slack), (step, key, drift)
        if name in ("braking", "braking_oncoming", "demo"):
            assert drift < 1e-3, step  # (a few 1e-5 ft: the slack is the runs' own difference, not a fudge)


SPEC_KEYS = {"min_distance", "min_distance_time_s", "min_ttc_s", "min_ttc_time_s", "max_drac", "min_pet_s"}


def test_summary_json_api_and_plot_carry_the_criticality(simple_fmu, tmp_path):
    # summary.json's `criticality` holds docs/results.md's keys run-wide and per vehicle id (null where never applied,
    # distances in the scenario's units), api.Result exposes the same, and the plot is drawn with them.
    import json

    from sdl_fmu import api

    result = api.run(str(SCENARIO_DIRECTORY / "head_on.sdl"), fmu=str(simple_fmu))
    folder = result.write(tmp_path / "out")
    written = json.loads((folder / "summary.json").read_text())["criticality"]
    assert written == result.summary["criticality"]  # as written (numbers rounded as in every summary)
    assert written["vehicles"][0]["min_ttc_time_s"] == pytest.approx(result.criticality["min_ttc_time_s"], abs=1e-6)
    assert SPEC_KEYS <= written.keys() and [v["vehicle"] for v in written["vehicles"]] == [1]
    assert SPEC_KEYS <= written["vehicles"][0].keys()
    assert written["min_pet_s"] is None and written["min_distance"] == 0.0  # no lateral move; a collision
    assert (folder / "plot.png").read_bytes()[:4] == b"\x89PNG"


def test_an_fmu_that_cannot_roll_back_gives_the_extremes_within_a_step(simple_fmu, tmp_path):
    # The Simple FMU rewritten to say it cannot get and set its state: no bisection; an extreme is taken at the
    # communication point after it, and summary's criticality says how exactly (time_uncertainty_s, the
    # longest step in which one was found, at most the driver's 0.05 s period). The adjacent-lane car of the
    # first test: the clearance is flat over the overlap, so the value is exact and the instant is the first
    # communication point in the overlap, within time_uncertainty_s after its start t*.
    import re

    from helpers import rewritten_fmu

    no_state = rewritten_fmu(simple_fmu, tmp_path / "NoState.fmu", lambda text: re.sub(
        r'canGetAndSetFMUstate="true"', 'canGetAndSetFMUstate="false"', text, flags=re.I))
    cosim = Cosimulation(SCENARIOS["adjacent"](), no_state, RunOptions(), TABLE)
    result = as_written(cosim.run())
    assert not cosim.exact
    summary = result.criticality
    uncertainty = summary["time_uncertainty_s"]
    assert 0 < uncertainty <= 0.05 + 1e-12
    clearance = 12 * FOOT - (cosim.bounds.width + 1.75) / 2
    start = event(result, "spawn")["time_s"] + (1000 * FOOT - (cosim.bounds.length + 4.2) / 2) / (108 * FOOT)
    assert summary["min_distance"] == pytest.approx(clearance / FOOT, abs=1e-9)
    assert 0 <= summary["min_distance_time_s"] - start <= uncertainty


def crowd(n: int):
    """n cars on the road at once: all spawned at 1 ft, 1000 + 60 k ft ahead, oncoming in the other lane; each
    passes the ego and leaves the road; the run ends after the last has passed."""
    lines = ["English"] + [f"1,A,20,{1000 + 60 * k},-6,1" for k in range(n)]
    return parse_text("\n".join(lines + [f"{int(300 + 0.82 * (1000 + 60 * n))},ES"]), f"crowd{n}.sdl")


def counted_run(scenario, fmu) -> tuple[dict, object]:
    """A run of the real master and FMU with its criticality looks (Extremes.look calls) counted by what made
    them: `fire` (a spawn, an action, a contact's start or end, a departure: look(only=...) and
    look_before_change), `due` (a vehicle's own next-look instant came), `ahead` (a bound ending in the
    coming step looked at its start to spare a snapshot), `located` (an instant located inside a step)."""
    cosim = Cosimulation(scenario, fmu, RunOptions(), TABLE)
    counts = dict.fromkeys(("fire", "due", "ahead", "located", "end"), 0)
    source = ["located"]

    def counting(method, name_of):
        def wrapped(*args, **kwargs):
            previous, source[0] = source[0], name_of(*args, **kwargs)
            try:
                return method(*args, **kwargs)
            finally:
                source[0] = previous
        return wrapped

    follower = cosim.follower  # the looks happen there (the master's loop asks and notifies it)
    look = follower.extremes.look

    def count(*args, **kwargs):
        counts[source[0]] += 1
        return look(*args, **kwargs)

    follower.extremes.look = count
    # a look at every vehicle is the run's end (or start) one, else a fire's
    follower.look = counting(follower.look, lambda state, everyone=False, ahead=None, only=None:
                          ("end" if cosim.finished or state.time == 0.0 else "fire") if everyone
                          else "fire" if only is not None else "ahead" if ahead is not None else "due")
    follower.look_before_change = counting(follower.look_before_change, lambda *_: "fire")
    return counts, cosim.run()


def test_a_fire_looks_only_at_the_vehicles_it_concerns_so_looks_grow_linearly(simple_fmu):
    # With n cars on the road at once, each of the n departures (and the spawn) used to look at every vehicle on
    # the road: about n^2 looks at fires. A fire now looks only at the vehicles it concerns: the spawned one,
    # one whose action starts (before and after), one whose contact begins or ends, one leaving (before, unless
    # looked at at this instant already). So the fire looks are at most 2 per such vehicle event, whatever n;
    # the looks at a vehicle's own next-look instants and at located instants follow that vehicle's motion, so
    # per vehicle they do not grow with n either (counted, not timed: the counts are deterministic).
    per_vehicle = {}
    for n in (4, 8, 16):
        counts, result = counted_run(crowd(n), simple_fmu)
        vehicle_events = sum(e["action"] in ("spawn", "maneuver", "collision", "despawn") for e in result.events)
        assert sum(e["action"] == "despawn" for e in result.events) == n  # every car passed and left
        assert counts["fire"] <= 2 * vehicle_events == 4 * n, (n, counts)
        per_vehicle[n] = (counts["fire"] + counts["due"] + counts["located"]) / n
        print(n, counts, f"{per_vehicle[n]:.2f} per vehicle")
    assert per_vehicle[16] <= per_vehicle[8] <= per_vehicle[4], per_vehicle
