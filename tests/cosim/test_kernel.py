"""The compiled criticality kernel (sdl_fmu/cosim/_kernel.c) against its Python twin (looks.py, measures.py,
geometry.py, traffic.py): every function gives the same bits on generated and edge inputs, and whole runs give the
same records with either. The twin is the reference: its measures are held to closed forms and to CommonRoad-CriMe
by test_criticality*.py; here only the equality of the two is at stake, so every comparison is exact (no
tolerance: the same operations in the same order round the same way)."""

import dataclasses
import math
import struct

import numpy as np
import pytest

from sdl_fmu.cosim import geometry, looks, measures, traffic as traffic_module
from sdl_fmu.cosim.geometry import Footprint
from sdl_fmu.cosim.master import Cosimulation, RunOptions
from sdl_fmu.paths import SCENARIO_DIRECTORY
from sdl_fmu.sdl import default_vehicle_table_path, load_scenario, load_vehicle_table, parse_text
from sdl_fmu.units import FOOT
from sdl_fmu.vehicle import EgoModel, shipped_map_path
from sdl_fmu.vehicle.instance import EgoState

KERNEL = looks.KERNEL
DRAWS = 4000  # per function and seed: each a few hundred operations, so a few million compared in all
LOOKS = 2000  # per seed, looks (each also a course check, a probe, a horizon: the Python twin's slowest)


def test_the_kernel_is_built_by_the_install():
    # setup.py builds it where a C compiler and Python's headers are found (CI's machine has both): without it the
    # runs would take the Python twin, right but slower, and the comparisons below would compare nothing
    assert KERNEL is not None, "sdl_fmu.cosim._kernel is missing: pip install the package where gcc is found"
    assert looks.arithmetic() is KERNEL


def test_the_kernel_s_constants_are_the_python_s():
    assert (KERNEL.RANGE, KERNEL.FLAT) == (looks.RANGE, looks.FLAT)
    assert (KERNEL.COURSE_WINDOW, KERNEL.COURSE_TRIES, KERNEL.COURSE_MARGIN) == \
        (measures.COURSE_WINDOW, measures.COURSE_TRIES, measures.COURSE_MARGIN)
    assert (KERNEL.HEADING_STRETCHES, KERNEL.HEADING_STRETCH) == (measures.HEADING_STRETCHES, measures.HEADING_STRETCH)


def bits(value):
    """A value's bits (any nan the same; -0.0 and 0.0 told apart), through tuples and lists: what the tests compare."""
    if isinstance(value, (tuple, list)):
        return tuple(bits(v) for v in value)
    if value is None or isinstance(value, bool):
        return value
    return "nan" if value != value else struct.pack("<d", value)


def python(function, *args):
    """The Python twin's value, or None where it raises (a division by zero or a square root of a negative
    number: inputs no run reaches; the kernel returns inf or nan there)."""
    try:
        return function(*args)
    except (ZeroDivisionError, ValueError):
        return None


def compare(name, draws):
    """Each draw's arguments through the Python function `name` (in looks, measures or geometry) and the kernel's,
    bit for bit; returns how many the Python computed (the rest raised)."""
    twin = getattr(looks, name, None) or getattr(measures, name, None) or getattr(geometry, name)
    compiled = getattr(KERNEL, name)
    computed = 0
    for args in draws:
        expected = python(twin, *args)
        if expected is None:
            continue
        computed += 1
        assert bits(compiled(*args)) == bits(expected), (name, args)
    return computed


# ---- the inputs: what runs give (metres, m/s, radians), with the cases where a comparison decides an outcome

EDGES = (0.0, -0.0, 1.0, -1.0, 2.1, -2.1, 0.875, 50.0, 1e-12, -1e-12)


def draw(rng, n, low, high, edge_share=0.15):
    """n values uniform in [low, high), a share of them replaced by edge values (zeros of both signs, the
    footprints' half sizes and RANGE: where `>=` and `>` part)."""
    values = rng.uniform(low, high, n)
    edge = rng.random(n) < edge_share
    values[edge] = rng.choice(EDGES, edge.sum())
    return values.tolist()


def footprints(rng, n):
    """Ego footprints: a 4.5 x 1.8 m car or another size, turned by any yaw, yaw 0 and pi/2 a quarter of the time
    (the footprints' edges then parallel: ties between corners)."""
    psi = rng.uniform(-math.pi, math.pi, n)
    psi[rng.random(n) < 0.25] = 0.0
    psi[rng.random(n) < 0.1] = math.pi / 2
    length = np.where(rng.random(n) < 0.7, 4.5, rng.uniform(1.0, 12.0, n))
    width = np.where(rng.random(n) < 0.7, 1.8, rng.uniform(0.5, 3.0, n))
    return [Footprint.of(float(a), float(b), float(p)) for a, b, p in zip(length, width, psi)]


def vehicle_draws(rng, n, scale=20.0):
    """(footprint, dx, dy, vx, vy, length, width) with the vehicle within `scale` m: near, touching, overlapping."""
    return list(zip(footprints(rng, n), draw(rng, n, -scale, scale), draw(rng, n, -scale / 4, scale / 4),
                    draw(rng, n, -40, 40), draw(rng, n, -5, 5), draw(rng, n, 1.0, 12.0), draw(rng, n, 0.5, 3.0)))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_footprint_measures_are_the_python_s_to_the_bit(seed):
    rng = np.random.default_rng(seed)
    near = vehicle_draws(rng, DRAWS, scale=8.0)
    far = vehicle_draws(rng, DRAWS, scale=80.0)
    yaw_rates = draw(rng, 2 * DRAWS, -1.0, 1.0)
    rows = [(e, dx, dy, vx, vy, r, length, width) for (e, dx, dy, vx, vy, length, width), r
            in zip(near + far, yaw_rates)]
    # (the Python raises where a corner touches and the penetration rounds below 0: a division by a zero distance)
    assert compare("distance_and_rates", rows) > 0.98 * len(rows)
    assert compare("penetration", [(e, dx, dy, length, width) for e, dx, dy, _, _, length, width in near + far]) \
        == 2 * DRAWS
    assert compare("ttc", near + far) == 2 * DRAWS
    accelerations = list(zip(draw(rng, 2 * DRAWS, -10, 10), draw(rng, 2 * DRAWS, -10, 10)))
    rates = [(e, dx, dy, vx, vy, ax, ay, r, length, width) for (e, dx, dy, vx, vy, length, width), (ax, ay), r
             in zip(near + far, accelerations, yaw_rates)]
    assert compare("ttc_rate_known", rates) > 0.99 * len(rates)
    speeds = draw(rng, 2 * DRAWS, -2, 40)
    gaps = [(e, dx, dy, v, vx, length, width) for (e, dx, dy, vx, _, length, width), v in zip(near + far, speeds)]
    assert compare("headway", gaps) == 2 * DRAWS
    # defined where the ego moves forward (its station rate > 0, as evaluate calls it)
    known = [(e, abs(dx) / 10, v, vx, a, r) for (e, dx, _, vx, _, _, _), v, (a, _), r
             in zip(near + far, draw(rng, 2 * DRAWS, 0.1, 40, 0.0), accelerations, yaw_rates)]
    assert compare("headway_rate_known", known) > 0.99 * len(known)
    # a collision course's TTC and its rate, then DRAC and its rate, as evaluate combines them
    values = [(abs(t), vx, vy) for t, vx, vy in zip(draw(rng, DRAWS, -20, 20), draw(rng, DRAWS, -40, 40),
                                                     draw(rng, DRAWS, -5, 5))]
    assert compare("drac", values) == DRAWS
    # its rate where DRAC is defined (0 < TTC), as evaluate calls it
    assert compare("drac_rate_known", [(t, r, vx, vy, ax, ay) for t, (_, vx, vy), r, (ax, ay)
                                       in zip(draw(rng, DRAWS, 0.01, 20, 0.0), values, yaw_rates, accelerations)]) \
        > 0.99 * DRAWS


@pytest.mark.parametrize("seed", [4, 5, 6])
def test_the_horizons_are_the_python_s_to_the_bit(seed):
    rng = np.random.default_rng(seed)
    n = DRAWS
    # the bounds (A > 0, R r_max, r_max, sizes and reaches, the horizon's limit >= 0) drawn without the signed edge
    # values: a run passes none below 0
    # reach_time: margins of both signs, rates of both signs, the ego's acceleration bound
    assert compare("reach_time_scalar", list(zip(draw(rng, n, -5, 60), draw(rng, n, -40, 40),
                                                 draw(rng, n, 0.5, 25, 0.0)))) == n
    # approach: distances, frozen rates mostly closing, relative speeds, R r_max, A, r_max
    approach = list(zip(draw(rng, n, 0, 60, 0.0), draw(rng, n, -40, 5), draw(rng, n, 0, 45, 0.0),
                        draw(rng, n, 0, 8, 0.0),
                        draw(rng, n, 0.5, 25, 0.0), draw(rng, n, 0, 2, 0.0)))
    assert compare("approach_horizon", approach) > 0.99 * n
    # heading: far vehicles (the offsets of up to 200 m) closing or not
    heading = list(zip(draw(rng, n, -200, 200), draw(rng, n, -10, 10), draw(rng, n, -45, 45), draw(rng, n, -5, 5),
                       draw(rng, n, 0, 10, 0.0), draw(rng, n, 0, 8, 0.0), draw(rng, n, 0.5, 25, 0.0)))
    assert compare("heading_horizon", heading) > 0.9 * n
    # course: a car beside the ego's path (dy beyond the reach), the reaches of two cars' half sizes
    course = list(zip(draw(rng, n, -60, 60), draw(rng, n, -8, 8), draw(rng, n, -45, 45), draw(rng, n, -3, 3),
                      draw(rng, n, 2, 8, 0.0), draw(rng, n, 0.8, 3, 0.0), draw(rng, n, 0, 3, 0.0),
                      draw(rng, n, 0, 8, 0.0),
                      draw(rng, n, 0.5, 25, 0.0)))
    assert compare("course_horizon", course) > 0.99 * n
    assert compare("off_course", [(dx, dy, vx, vy, hx, hy) for dx, dy, vx, vy, hx, hy, *_ in course]) == n


def ego_states(rng, n):
    """EgoStates as a run makes them: on the road (x along it, y across), any yaw, moving forward mostly."""
    return [EgoState(*args, False) for args in zip(draw(rng, n, 0, 100), draw(rng, n, 0, 200), draw(rng, n, -4, 4),
                                                    draw(rng, n, -0.6, 0.6), draw(rng, n, 0, 400),
                                                    draw(rng, n, 0, 40), draw(rng, n, -2, 40), draw(rng, n, -3, 3),
                                                    draw(rng, n, -9, 4), draw(rng, n, -8, 8), draw(rng, n, -1, 1))]


def motions(rng, states):
    """Traffic rows (t0, station0, lateral0, speed0, lateral1, speed1, duration) about each state: oncoming, the
    ego's way, stopped; within a transition, after it, and holding (duration 0); the state never before t0."""
    n = len(states)
    rows = []
    for state, ahead, lateral0, speed0, lateral1, speed1, duration, since in zip(
            states, draw(rng, n, -30, 120), draw(rng, n, -4, 4), draw(rng, n, -40, 40), draw(rng, n, -4, 4),
            draw(rng, n, -40, 40), draw(rng, n, 0, 6, 0.0), draw(rng, n, 0, 8, 0.0)):
        if rng.random() < 0.2:
            duration = 0.0
        if rng.random() < 0.1:
            speed0 = speed1 = 0.0
        rows.append((state.time - since, state.x + ahead, lateral0, speed0, lateral1, speed1, duration))
    return rows


def record_lists(rng, capacity):
    """The record's 8 lists (value, time) of distance, TTC, DRAC and headway, as Extremes keeps them: nan (nothing
    recorded yet) for a third of the vehicles, values near the ones offered for the rest (the FLAT comparisons)."""
    tables = []
    for k in range(8):
        values = rng.uniform(0, 60, capacity) if k % 2 == 0 else rng.uniform(0, 100, capacity)
        values[rng.random(capacity) < 0.33] = np.nan
        tables.append(values.tolist())
    return tuple(tables)


@pytest.mark.parametrize("seed", [7, 8, 9])
def test_a_look_a_course_check_and_a_probe_are_the_python_s_to_the_bit(seed):
    # looks.evaluate, horizon, look (with its offers), course_check and distance_rate, the record's calls, from the
    # same arguments as Extremes passes them: the ego's half sizes, a row, the vehicle's size, the ego's state
    rng = np.random.default_rng(seed)
    states = ego_states(rng, LOOKS)
    rows = motions(rng, states)
    sizes = list(zip(draw(rng, LOOKS, 1.0, 12.0, 0.0), draw(rng, LOOKS, 0.5, 3.0, 0.0)))
    bounds = list(zip(draw(rng, LOOKS, 0.5, 25, 0.0), draw(rng, LOOKS, 0, 2, 0.0), draw(rng, LOOKS, 1, 4, 0.0)))
    records = draw(rng, LOOKS, 0, 100)
    python_tables = record_lists(rng, 40)
    kernel_tables = tuple(list(table) for table in python_tables)
    evaluated = on_course = offered = 0
    for n, (state, row, size, (acceleration, yaw_rate_bound, radius), recorded) in enumerate(
            zip(states, rows, sizes, bounds, records)):
        ego = (2.25, 0.9)
        motion_args = (state.time, state.x, state.y, state.psi, state.vx, state.vy)
        args = (*ego, row, size, *motion_args, state.ax, state.ay, state.yaw_rate)
        expected = python(looks.evaluate, *args)
        if expected is None:
            continue
        evaluated += 1
        got = KERNEL.evaluate(*args)
        assert bits(got) == bits(expected), args
        on_course += got[1][1] == got[1][1]
        motion, rate = expected[2], expected[1][0]
        horizon = (motion, rate, min(recorded, motion[0]), acceleration, yaw_rate_bound, radius)
        want = python(looks.horizon, *horizon)
        if want is not None:
            assert bits(KERNEL.horizon(*horizon)) == bits(want), horizon
        # a look: evaluated here or given, its offers to the record's lists (the same lists after it), its bounds
        i = n % 40
        for given in (None, expected):
            look = (*args, given, i, python_tables, acceleration, yaw_rate_bound, radius)
            before = bits(python_tables)
            want = python(looks.look, *look)
            if want is None:
                continue
            offered += bits(python_tables) != before
            assert bits(KERNEL.look(*args, given, i, kernel_tables, acceleration, yaw_rate_bound, radius)) == \
                bits(want), look
            assert bits(kernel_tables) == bits(python_tables)
        check = (*ego, row, size, *motion_args, state.yaw_rate, acceleration, yaw_rate_bound, radius)
        want = python(looks.course_check, *check)
        if want is not None:
            assert bits(KERNEL.course_check(*check)) == bits(want), check
        probe = (*ego, row, size, *motion_args, state.yaw_rate)
        assert bits(KERNEL.distance_rate(*probe)) == bits(looks.distance_rate(*probe)), probe
    # the draws reach every branch: nearly all evaluated, at least fifty on a collision course (TTC's rate
    # defined: DRAC and the rates' full path), and the offers changed the record hundreds of times
    assert evaluated > 0.99 * LOOKS and on_course >= 50 and offered >= 100


def test_an_offer_is_the_python_s():
    # every case of the comparison: nothing recorded (nan), better by more than FLAT (value and instant replaced),
    # within FLAT (the value improves, the instant stays), worse, not finite (not offered); the minimum and DRAC's
    # maximum
    for largest in (False, True):
        for recorded in (math.nan, 10.0):
            for value in (10.0 - 2e-9, 10.0 - 5e-10, 10.0, 10.0 + 5e-10, 10.0 + 2e-9, math.inf, -math.inf, math.nan):
                lists = ([1.0, recorded], [0.5, 3.0])
                twin = ([1.0, recorded], [0.5, 3.0])
                KERNEL.offer(*lists, 1, 7.0, value, largest)
                looks.offer(*twin, 1, 7.0, value, largest)
                assert bits((tuple(lists[0]), tuple(lists[1]))) == bits((tuple(twin[0]), tuple(twin[1])))


@pytest.mark.parametrize("seed", [11, 12])
def test_the_follower_s_scans_are_the_python_s(seed):
    # which vehicles are due a look or a check, and the earliest bounds, over the vehicles on the road: the same
    # lists and minima (the per-vehicle instants drawn on a coarse grid, so that ties and equalities occur)
    rng = np.random.default_rng(seed)
    for _ in range(2000):
        size = int(rng.integers(1, 30))
        vehicles = sorted(rng.choice(size, int(rng.integers(0, size + 1)), replace=False).tolist())
        tables = [(rng.integers(-2, 8, size) * 0.5).tolist() for _ in range(4)]
        for table in tables:
            table[int(rng.integers(size))] = -math.inf  # NO_LOOK
        t, ahead = float(rng.integers(0, 6) * 0.5), [None, float(rng.integers(0, 8) * 0.5)][int(rng.integers(2))]
        now = bool(rng.integers(2))
        assert KERNEL.due_looks(vehicles, *tables[:3], t, ahead, now) == \
            looks.due_looks(vehicles, *tables[:3], t, ahead, now)
        assert KERNEL.due_checks(vehicles, *tables[:3], ahead or t, t) == \
            looks.due_checks(vehicles, *tables[:3], ahead or t, t)
        assert bits(KERNEL.earliest(vehicles, tables[0])) == bits(looks.earliest(vehicles, tables[0]))
        assert bits(KERNEL.earliest(vehicles, *tables[:3])) == bits(looks.earliest(vehicles, *tables[:3]))


def test_the_kernel_refuses_wrong_arguments_with_a_type_error():
    # misuse (a bug in the caller) is a Python exception, never a crash
    row = (0.0, 50.0, 0.0, 20.0, 0.0, 20.0, 0.0)
    state = (1.0, 0.0, 0.0, 0.0, 20.0, 0.0)
    with pytest.raises(TypeError):
        KERNEL.evaluate(2.25, 0.9, row, (4.0, 1.8), *state, 0.0, 0.0)  # one argument short
    with pytest.raises(TypeError):
        KERNEL.evaluate(2.25, 0.9, row[:6], (4.0, 1.8), *state, 0.0, 0.0, 0.0)  # a row of 6
    with pytest.raises(TypeError):
        KERNEL.course_check(2.25, 0.9, row, (4.0,), *state, 0.0, 9.0, 0.5, 2.5)  # a size of 1
    with pytest.raises(TypeError):
        KERNEL.look(2.25, 0.9, row, (4.0, 1.8), *state, 0.0, 0.0, 0.0, None, 0, ([1.0],) * 7, 9.0, 0.5, 2.5)
    with pytest.raises(IndexError):  # a vehicle beyond the record's lists
        KERNEL.look(2.25, 0.9, row, (4.0, 1.8), *state, 0.0, 0.0, 0.0, None, 5, ([1.0],) * 8, 9.0, 0.5, 2.5)
    with pytest.raises(TypeError):
        KERNEL.ttc((2.25, 0.9, 1.0), 10.0, 0.0, -20.0, 0.0, 4.0, 1.8)  # a footprint of 3
    with pytest.raises(TypeError):
        KERNEL.reach_time_scalar("1", 2.0, 3.0)
    with pytest.raises(IndexError):
        KERNEL.earliest([3], [1.0, 2.0])


def test_the_ego_and_the_motion_law_are_the_python_s():
    # the kernel computes the ego at a state as looks.ego does (cos and sin the C library's, as Python's math calls
    # them) and a vehicle's motion from its row as traffic.motion_law does (Traffic.motion_of is motion_law)
    rng = np.random.default_rng(10)
    states = ego_states(rng, 2000)
    for state, row in zip(states, motions(rng, states)):
        station, lateral, speed, lateral_rate, _ = traffic_module.motion_law(row, state.time)
        footprint, c, s, ego_vx, ego_vy, _, _ = looks.ego(2.25, 0.9, state.psi, state.vx, state.vy)
        motion = KERNEL.evaluate(2.25, 0.9, row, (4.0, 1.8), state.time, 0.0, 0.0, state.psi, state.vx, state.vy,
                                 0.0, 0.0, 0.0)[2]
        assert bits(motion[10]) == bits(footprint) == bits((2.25, 0.9, math.cos(state.psi), math.sin(state.psi)))
        assert bits(motion[2:6]) == bits((station - 0.0, -lateral - 0.0, -speed - ego_vx, -lateral_rate - ego_vy))


# ---- whole runs: the same records with the kernel and with the twin

TABLE = load_vehicle_table(default_vehicle_table_path())
RUNS = {
    "demo": (lambda: load_scenario(SCENARIO_DIRECTORY / "demo.sdl"), None),
    "head_on": (lambda: load_scenario(SCENARIO_DIRECTORY / "head_on.sdl"), None),
    "lead_vehicle": (lambda: load_scenario(SCENARIO_DIRECTORY / "lead_vehicle.sdl"), None),
    "approaching_vehicle": (lambda: load_scenario(SCENARIO_DIRECTORY / "approaching_vehicle.sdl"), None),
    # 24 cars oncoming in the next lane, one every 100 ft, with the ego braking among them: dense traffic, where
    # the kernel does most of the record's work
    "dense": (lambda: parse_text("\n".join(["English"] + [f"{100 + 100 * k},A,30,800,-6,1" for k in range(24)]
                                           + ["1200,BRK,40,0,30", "3200,ES"]), "dense.sdl"), None),
    # the ego swerving (yaw and yaw rate on) past a car coming into its lane and back
    "swerve": (lambda: parse_text("English\n100,A,20,700,-6,1,3,2,20,2,1,-6,20,2\n1500,ES", "swerve.sdl"),
               2600 * FOOT),
}


def recorded(name, simple_fmu, step):
    scenario, until = RUNS[name]
    model = EgoModel.open(simple_fmu, shipped_map_path("simple"))
    return Cosimulation(scenario(), model, RunOptions(step=step, until_distance=until), TABLE).run()


@pytest.mark.parametrize("step", [0.01, 1.0])
@pytest.mark.parametrize("name", RUNS)
def test_runs_record_the_same_with_the_kernel_and_with_its_twin(name, step, simple_fmu, monkeypatch):
    compiled = recorded(name, simple_fmu, step)
    monkeypatch.setattr(looks, "KERNEL", None)  # every Extremes made from here on takes the Python twin
    assert looks.arithmetic() is looks
    twin = recorded(name, simple_fmu, step)
    assert bits_of(compiled.criticality) == bits_of(twin.criticality)
    assert compiled.events == twin.events
    assert compiled.columns.keys() == twin.columns.keys()
    for key in compiled.columns:
        assert np.array_equal(np.asarray(compiled.columns[key]), np.asarray(twin.columns[key]), equal_nan=True), key
    assert len(compiled.vehicles) == len(twin.vehicles)
    for u, w in zip(compiled.vehicles, twin.vehicles):
        for field in dataclasses.fields(u):
            a, b = getattr(u, field.name), getattr(w, field.name)
            if isinstance(a, (str, int)):
                assert a == b, field.name
            else:
                assert np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True), \
                    field.name
    # the run records something to compare: a minimum distance per vehicle
    assert compiled.criticality["vehicles"] and all(v["min_distance"] is not None
                                                    for v in compiled.criticality["vehicles"])


def bits_of(value):
    """A JSON-like record's floats as bits (nan equal to nan)."""
    if isinstance(value, dict):
        return {k: bits_of(v) for k, v in value.items()}
    if isinstance(value, list):
        return [bits_of(v) for v in value]
    if isinstance(value, float):
        return bits(value)
    return value
