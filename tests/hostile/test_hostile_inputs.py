"""Sizes and values are checked before anything grows: sweep grids and values (sdl_fmu/sweep.py), --workers and
--scheduler, unit strings (sdl_fmu/vehicle/unit_text.py), vehicle map values and nesting (vehicle_map.py).

Every case is the real command line under a 1.5 GB address-space cap (tests/hostile_fmus.py), ends with one line
naming the option, file or FMU and the documented exit code (docs/decisions.md), and writes nothing. Timeouts only
catch hangs (the unit bomb and the dashboard port used to hang for ever)."""

import os
import socket
import subprocess
import sys
import threading
import time

import pytest

from hostile_fmus import HANG_LIMIT, capped, hostile_fmu, hostile_map, library, one_line

SCENARIO = "English\n300,BRK,100,1,50\n600,ES\n"
SLOW = pytest.mark.slow  # the fast loop keeps three sweep refusals and the grammar; the rest runs in CI

# --- sweep sizes and values: refused before a value is generated, a grid built or a cluster started ----------------
SWEEP = [
    (["--vary", "speed=0:1e8:1"], "--vary speed=0:1e8:1: 1e+08 values, more than the 100000 runs"),
    (["--vary", "speed=uniform(0,1,1000000000)"], "--vary speed=uniform(0,1,1000000000): 1e+09 values"),
    (["--vary", "seed=integers(0,1,99999999999999999999)"], "--vary seed=integers(0,1,99999999999999999999): 1e+20 values, more than the 100000 runs"),
    (["--vary", "speed=0:1e5:1", "--vary", "seed=0:1e5:1"], "--vary speed=0:1e5:1: 100001 values"),
    (["--vary", "speed=0:5e4:1", "--vary", "seed=0:5e4:1"], "--vary: 50001 x 50001 = 2500100001 runs, more than"),
    (["--vary", "speed=0:inf:1"], "--vary speed=0:inf:1: expected a,b,c or start:stop:step (finite numbers"),
    (["--vary", "seed=inf"], "--vary seed=inf: every value must be a finite number"),
    (["--vary", "seed=nan"], "--vary seed=nan: every value must be a finite number"),
    (["--vary", "seed=integers(0,inf,2)"], "--vary seed=integers(0,inf,2): expected"),
    (["--vary", "seed=1e300"], "--vary seed=1e300: seeds are whole numbers from 0 to 9223372036854775807"),
    (["--vary", "seed=-1"], "--vary seed=-1: seeds are whole numbers from 0"),
    (["--vary", "speed=1,nan"], "--vary speed=1,nan: every value must be a finite number"),
    (["--vary", "speed=40", "--workers", "100000"], "--workers 100000: must be from 1 to "),
    (["--vary", "speed=40", "--workers", "0"], "--workers 0: must be from 1 to "),
    (["--vary", "speed=40", "--scheduler", ""], "--scheduler '': expected an address such as tcp://host:8786"),
    (["--vary", "speed=40", "--scheduler", "not an address"], "--scheduler 'not an address': expected an address"),
]


@pytest.fixture
def work(tmp_path, simple_fmus):  # the sweeps take the Simple FMU from the cache
    (tmp_path / "work").mkdir()
    (tmp_path / "rsa.sdl").write_text("English\n100,RSA,1,8\n500,ES\n")
    return tmp_path


@pytest.mark.parametrize("arguments, needle", [
    pytest.param(*case, marks=() if index < 3 else SLOW, id=" ".join(case[0])[:60]) for index, case in enumerate(SWEEP)])
def test_a_sweep_too_big_or_with_a_bad_value_is_one_line_before_anything_runs(work, arguments, needle):
    completed = capped("sweep", work / "rsa.sdl", *arguments, "--out", work / "work" / "sweep", cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: {needle}")
    assert completed.stdout == "" and os.listdir(work / "work") == []


class _Server:
    """A TCP server on a free port of 127.0.0.1 that answers every connection its own way (a thread of the test)."""

    def __init__(self, answer):
        self.socket = socket.create_server(("127.0.0.1", 0))
        self.port = self.socket.getsockname()[1]
        self.answer = answer
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self):
        while True:
            try:
                connection, _ = self.socket.accept()
            except OSError:
                return
            with connection:
                self.answer(connection)

    def close(self):
        self.socket.close()


def _http(connection):
    """What an HTTP server (Dask's dashboard, port 8787) does: wait for a request, then answer 400 and close."""
    connection.settimeout(HANG_LIMIT)
    try:
        connection.recv(65536)
        connection.sendall(b"HTTP/1.0 400 Bad request\r\n\r\n")
    except OSError:
        pass


def _garbage(connection):
    connection.sendall(b"\xff" * 64)


@SLOW
@pytest.mark.parametrize("server, needle", [
    (_http, "no Dask scheduler there (it sent nothing in 10 s: a web server? The dashboard is usually on 8787"),
    (_garbage, "not a Dask scheduler (what it sent is not Dask's handshake)"),
    (None, "cannot connect: Connection refused"),
])
def test_a_scheduler_address_that_is_no_dask_scheduler_is_one_line(work, server, needle):
    if server is None:  # a port nobody listens on: bound, then closed
        with socket.create_server(("127.0.0.1", 0)) as probe:
            port = probe.getsockname()[1]
        running = None
    else:
        running = _Server(server)
        port = running.port
    try:
        completed = capped("sweep", work / "rsa.sdl", "--vary", "speed=40", "--scheduler", f"tcp://127.0.0.1:{port}",
                           "--out", work / "work" / "sweep", cwd=work / "work")
    finally:
        if running is not None:
            running.close()
    one_line(completed, 2, f"sdl-fmu: --scheduler tcp://127.0.0.1:{port}: {needle}")
    assert os.listdir(work / "work") == []


# --- unit strings: a grammar, not pint's arithmetic ---------------------------------------------------------------

@pytest.fixture(scope="module")
def car(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hostile")
    library(folder)
    scenario = folder / "brake.sdl"
    scenario.write_text(SCENARIO)
    return folder, scenario


@SLOW
@pytest.mark.parametrize("where", ["fmu", "map"])
def test_a_unit_string_cannot_make_sdl_fmu_compute(car, work, where):
    """`10**10**10*m/s`: pint would compute a number of ten billion digits (sdl-fmu hung resolving the FMU)."""
    folder, scenario = car
    bomb = "10**10**10*m/s"
    fmu = hostile_fmu(work / "fmu", speed_unit=bomb if where == "fmu" else None)
    vehicle = hostile_map(work, speed='variable = "speed"' + (f', unit = "{bomb}"' if where == "map" else ""))
    for command in (["run", scenario, "--out", work / "work" / "out"], ["verify", "--out", work / "work" / "out"],
                    ["sweep", scenario, "--vary", "speed=40,50", "--out", work / "work" / "out"]):
        completed = capped(*command, "--fmu", fmu, "--vehicle", vehicle, cwd=work / "work")
        if where == "fmu":
            one_line(completed, 2, f"{vehicle}: outputs.speed: the FMU declares 'speed' in '{bomb}' (not a unit "
                                   "string sdl-fmu reads: expected a unit name or 1 at '10**10**10'")
        else:
            one_line(completed, 2, f"{vehicle}: outputs.speed.unit: '{bomb}' (not a unit string sdl-fmu reads: "
                                   "expected a unit name or 1 at '10**10**10') is an unknown unit")
        assert os.listdir(work / "work") == []


def test_unit_strings_the_grammar_reads_convert_as_pint_says():
    """Exact conversions from the unit definitions: 1 km/h = 1/3.6 m/s, 1 mph = 0.44704 m/s, 1 ft = 0.3048 m,
    1 deg = pi/180 rad; a product of names with exponents, left to right (a/b/c = a/(b c))."""
    import math

    from sdl_fmu.vehicle.unit_text import conversion, refusal

    assert conversion("km/h", "m/s") == pytest.approx((1 / 3.6, 0.0), rel=1e-15)
    assert conversion("mph", "m/s") == pytest.approx((0.44704, 0.0), rel=1e-15)
    assert conversion("ft/s2", "m/s**2") == pytest.approx((0.3048, 0.0), rel=1e-15)
    assert conversion("ft/s^2", "m/s**2") == conversion("ft/s**2", "m/s**2") == conversion("ft/s/s", "m/s**2")
    assert conversion("deg/s", "rad/s") == pytest.approx((math.pi / 180, 0.0), rel=1e-15)
    assert conversion("1/s", "rad/s") == (1.0, 0.0)
    assert conversion("m", "m/s") is None  # another dimension
    for text, reason in [("10**10**10*m", "expected a unit name or 1 at '10**10**10'"),
                         ("m**99", "exponent of 'm' is not a whole number from -9 to 9"),
                         ("m" * 65, "longer than 64 characters"), ("m*" * 9 + "m", "more than 8 terms"),
                         ("(m)", "expected a unit name or 1 at '(m)'"), ("", "empty"), ("m/", "expected *, . or /")]:
        assert conversion(text, "m") is None and reason in refusal(text), (text, refusal(text))


# --- vehicle map values: ranges, the FMU's declared min/max, nesting ----------------------------------------------

GEOMETRY = "length = 4.5\nwidth = 1.8\nwheelbase = 2.7\ntrack = 1.5\n"
MAP_VALUES = [
    ("mass", GEOMETRY + "mass = 0\n", "vehicle.mass: 0.0 is outside its range: > 0 and <= 1e+06 (SI)"),
    ("negative mass", GEOMETRY + "mass = -1500\n", "vehicle.mass: -1500.0 is outside its range"),
    ("wheel_radius", GEOMETRY + "drive_torque_max = 1800\nwheel_radius = 0\n", "vehicle.wheel_radius: 0.0 is outside"),
    ("torque alone", GEOMETRY + "drive_torque_max = 1800\n", "vehicle.wheel_radius: missing (drive_torque_max is a "
                                                             "wheel torque"),
    ("wheelbase 0", GEOMETRY.replace("2.7", "0"), "vehicle.wheelbase: 0.0 is outside its range: > 0 and <= 50"),
    ("wheelbase negative", GEOMETRY.replace("2.7", "-2.7"), "vehicle.wheelbase: -2.7 is outside its range"),
    ("wheelbase huge", GEOMETRY.replace("2.7", "1e308"), "vehicle.wheelbase: 1e+308 is outside its range"),
    ("length", GEOMETRY.replace("4.5", "-4.6"), "vehicle.length: -4.6 is outside its range"),
    ("bounds 0", GEOMETRY + "max_acceleration = 0\nmax_yaw_rate = 1\n", "vehicle.max_acceleration: 0.0 is outside"),
    ("bounds negative", GEOMETRY + "max_acceleration = 10\nmax_yaw_rate = -1\n", "vehicle.max_yaw_rate: -1.0 is "),
    ("air_density", GEOMETRY + "air_density = -1.2\n", "vehicle.air_density: -1.2 is outside its range: >= 0"),
    ("peak_friction", GEOMETRY + "peak_friction = -1\n", "vehicle.peak_friction: -1.0 is outside its range"),
    ("brake", GEOMETRY + "brake_decel_max = -8\n", "vehicle.brake_decel_max: -8.0 is outside its range: > 0"),
    ("cg", "length = 4.5\nwidth = 1.8\ntrack = 1.5\ncg_to_front_axle = 0\ncg_to_rear_axle = 0\n",
     "vehicle.cg_to_rear_axle: cg_to_front_axle + cg_to_rear_axle must be > 0"),
]


@SLOW
@pytest.mark.parametrize("vehicle, needle", [case[1:] for case in MAP_VALUES], ids=[case[0] for case in MAP_VALUES])
def test_map_values_outside_their_range_are_one_line_naming_the_file_and_key(car, work, vehicle, needle):
    folder, scenario = car
    fmu = hostile_fmu(work / "fmu")
    path = hostile_map(work, vehicle=vehicle)
    commands = [["run", scenario, "--out", work / "work" / "out"]]
    if "mass = 0" in vehicle:  # verify reads the map the same way: once is enough to show it
        commands.append(["verify", "--out", work / "work" / "out"])
    for command in commands:
        completed = capped(*command, "--fmu", fmu, "--vehicle", path, cwd=work / "work")
        one_line(completed, 2, f"sdl-fmu: {path}: {needle}")
    assert os.listdir(work / "work") == []


@SLOW
@pytest.mark.parametrize("extra, needle", [
    ('speed = { variable = "speed", scale = 1e300 }', "outputs.speed.scale: 1e+300 is outside its range: 1e-06 <= "
                                                       "|scale| <= 1e+06"),
    ('speed = { variable = "speed", scale = 0 }', "outputs.speed.scale: 0.0 is outside its range"),
    ('speed = { variable = "speed", offset = -1e300 }', "outputs.speed.offset: -1e+300 is outside its range"),
])
def test_channel_scales_and_offsets_are_range_checked(car, work, extra, needle):
    folder, scenario = car
    path = hostile_map(work, speed=extra.removeprefix("speed = { ").removesuffix(" }"))
    completed = capped("run", scenario, "--fmu", hostile_fmu(work / "fmu"), "--vehicle", path, "--out",
                       work / "work" / "out", cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: {path}: {needle}")


START_ON_V_INIT = '[start]\nspeed = { variable = "v_init" }\n'  # hostile_map's start speed


@SLOW
def test_map_parameters_are_checked_against_the_fmus_declared_range(car, work):
    folder, scenario = car
    fmu = hostile_fmu(work / "fmu", ranges={"v_init": (0.0, 100.0)})
    path = hostile_map(work, extra="", name="fast")
    # v_init as a parameter only: [start] speed on it too would be two values for one variable (refused on its own)
    path.write_text(path.read_text().replace(START_ON_V_INIT, "") + "v_init = 1000.0\n")
    completed = capped("run", scenario, "--fmu", fmu, "--vehicle", path, "--out", work / "work" / "out",
                       cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: {path}: parameters.v_init: 1000.0 is above the FMU's declared maximum 100")


@SLOW
def test_a_huge_start_value_without_a_declared_range_ends_the_run_at_the_fmus_output(car, work):
    """v_init = 1e308 on an FMU that declares no range: the car's first output is 1e308 m/s: one line naming it."""
    folder, scenario = car
    path = hostile_map(work, name="v1e308")
    path.write_text(path.read_text().replace(START_ON_V_INIT, "") + "v_init = 1e308\n")
    completed = capped("run", scenario, "--fmu", hostile_fmu(work / "fmu"), "--vehicle", path, "--out",
                       work / "work" / "out", cwd=work / "work")
    one_line(completed, 2, "sdl-fmu: the FMU HostileCar.fmu failed: its output 'speed' (speed) is 1e+308 at t = "
                           "0.000000 s: beyond 1e+09 in SI units")


@SLOW
@pytest.mark.parametrize("depth", [100_000, 2_000])
def test_a_map_nested_deep_is_one_line(car, work, depth):
    folder, scenario = car
    path = work / "deep.toml"
    path.write_text("name = " + "[" * depth + "]" * depth + "\n")
    completed = capped("run", scenario, "--fmu", hostile_fmu(work / "fmu"), "--vehicle", path, "--out",
                       work / "work" / "out", cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: {path}: not TOML sdl-fmu reads (nested too deeply)")


@SLOW
def test_a_huge_map_is_refused_unread(car, work):
    folder, scenario = car
    path = work / "huge.toml"
    with open(path, "wb") as file:
        file.write(b"# " + b"x" * (2 << 20) + b"\n")
    completed = capped("run", scenario, "--fmu", hostile_fmu(work / "fmu"), "--vehicle", path, "--out",
                       work / "work" / "out", cwd=work / "work")
    one_line(completed, 2, f"sdl-fmu: --vehicle {path}: larger than 1024 KB; a vehicle map is a small text")


@SLOW
@pytest.mark.parametrize("hostile", ["nested", "huge"])
def test_a_hostile_controller_map_is_one_line(work, hostile):
    """A controller map is read as a vehicle map is (one reader): nested deeper than tomllib's recursion (a
    RecursionError traceback before they shared it) or larger than 1 MB, one line, before any FMU is looked at."""
    path = work / f"{hostile}.toml"
    if hostile == "nested":
        path.write_text("name = " + "[" * 100_000 + "]" * 100_000 + "\n")
        expected = f"sdl-fmu: {path}: not TOML sdl-fmu reads (nested too deeply)"
    else:
        with open(path, "wb") as file:
            file.write(b"# " + b"x" * (2 << 20) + b"\n")
        expected = f"sdl-fmu: --controller-map {path}: larger than 1024 KB; a controller map is a small text"
    completed = capped("run", "demo", "--controller-map", path, "--out", work / "work" / "out", cwd=work / "work")
    one_line(completed, 2, expected)


@SLOW
def test_a_param_the_vehicle_cannot_have_is_one_line_naming_the_param(work):
    """--param brake_decel_max=0 is within the Simple FMU's declared range (>= 0), but the driver model divides by
    it: refused before the run, naming --param (it was a ZeroDivisionError traceback at the first braking)."""
    completed = capped("run", "demo", "--param", "brake_decel_max=0", "--out", work / "work" / "out",
                       cwd=work / "work")
    one_line(completed, 2, "sdl-fmu: --param brake_decel_max=0: ", "vehicle.brake_decel_max: the FMU parameter "
                           "'brake_decel_max': 0.0 is outside its range: > 0 and <= 100 (SI)")
