"""Vehicle maps (docs/vehicle-maps.md): any FMI 2.0/3.0 co-simulation FMU driven through a map. The FMUs here are
the shipped builds seen through maps unlike their shipped ones (signs flipped, outputs left out, state get/set
switched off in the model description), so every expectation is either a closed form or the shipped run itself."""

import json
import math
import re

import numpy as np
import pytest

from sdl_fmu import api
from sdl_fmu.vehicle import STOPPED_SPEED, EgoModel, VehicleMapError, shipped_map_path

from helpers import G, local_cluster, rewritten_fmu, sdl_fmu

# The Simple FMU described as a foreign vehicle would be: numbers in [vehicle], only the required outputs
BARE_MAP = """
[inputs]
throttle = { variable = "throttle" }
brake    = { variable = "brake" }
steer    = { variable = "steer" }
friction = { variables = ["mu_fl", "mu_fr", "mu_rl", "mu_rr"], meaning = "mu" }
[outputs]
x     = { variable = "x" }
y     = { variable = "y" }
yaw   = { variable = "psi" }
speed = { variable = "v" }
[start]
speed = { variable = "v0" }
y     = { variable = "y0" }
[vehicle]
length = 4.5
width = 1.8
wheelbase = 2.7
track = 1.6
"""


def write(tmp_path, text: str, name: str = "car.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def no_state_fmu(fmu, tmp_path):
    """The FMU whose model description says it cannot get and set its state (FMI 2.0: ...FMUstate, 3.0: ...FMUState)."""
    return rewritten_fmu(fmu, tmp_path / "NoState.fmu", lambda text: re.sub(
        r'canGetAndSetFMUstate="true"', 'canGetAndSetFMUstate="false"', text, flags=re.I))


# ---- errors: one line naming the map file and the key, before anything runs, nothing written ----------------

MAP_MISTAKES = [
    ("the FMU lacks a variable", ('variable = "steer"', 'variable = "steering_angle"'),
     r"car\.toml: inputs\.steer: the FMU \S+ has no variable 'steering_angle'"),
    ("an output mapped as an input", ('throttle = { variable = "throttle" }', 'throttle = { variable = "x" }'),
     r"car\.toml: inputs\.throttle: 'x' is an output of the FMU"),
    ("an input mapped as an output", ('x     = { variable = "x" }', 'x     = { variable = "brake" }'),
     r"car\.toml: outputs\.x: 'brake' is an input of the FMU"),
    ("a missing required output", ('speed = { variable = "v" }\n', ''), r"car\.toml: outputs\.speed: missing"),
    ("an unknown unit", ('speed = { variable = "v" }', 'speed = { variable = "v", unit = "furlongz/h" }'),
     r"car\.toml: outputs\.speed\.unit: 'furlongz/h' is an unknown unit"),
    ("a unit of another kind", ('x     = { variable = "x" }', 'x     = { variable = "x", unit = "s" }'),
     r"car\.toml: outputs\.x\.unit: 's' is an unknown unit or not a unit of m"),
    ("units that disagree", ('speed = { variable = "v" }', 'speed = { variable = "v", unit = "km/h" }'),
     r"car\.toml: outputs\.speed\.unit: 'km/h' disagrees with the FMU's unit 'm/s' of 'v'"),
    ("not TOML", ("[vehicle]", "[vehicle"), r"car\.toml: not TOML: "),
    ("a friction meaning sdl-fmu does not know", ('meaning = "mu"', 'meaning = "grip"'),
     r"car\.toml: inputs\.friction\.meaning: 'grip'"),
    ("a misspelt key", ("[start]", "[starts]"), r"car\.toml: starts: unknown key"),
    # many-to-one wiring: two values written to one FMU variable, one line naming both keys
    ("two inputs on one variable", ('brake    = { variable = "brake" }', 'brake    = { variable = "throttle" }'),
     r"car\.toml: inputs\.brake: 'throttle' is also inputs\.throttle's variable: one FMU variable cannot take two "
     r"values \(map each to a variable of its own\)$"),
    ("two wheels on one friction variable", ('"mu_fl", "mu_fr"', '"mu_fl", "mu_fl"'),
     r"car\.toml: inputs\.friction\.variables\[1\]: 'mu_fl' is also inputs\.friction\.variables\[0\]'s variable"),
    ("a start value on an input", ('y     = { variable = "y0" }', 'y     = { variable = "steer" }'),
     r"car\.toml: start\.y: 'steer' is also inputs\.steer's variable"),
    ("a parameter on a start value", ("track = 1.6\n", "track = 1.6\n[parameters]\nv0 = 20.0\n"),
     r"car\.toml: parameters\.v0: 'v0' is also start\.speed's variable"),
]


@pytest.mark.parametrize("edit, pattern", [m[1:] for m in MAP_MISTAKES], ids=[m[0] for m in MAP_MISTAKES])
def test_map_mistakes_are_one_line_naming_file_and_key(simple_fmu, tmp_path, edit, pattern):
    assert edit[0] in BARE_MAP
    vehicle = write(tmp_path, BARE_MAP.replace(*edit))
    with pytest.raises(api.InputError) as caught:
        api.run("head_on", fmu=simple_fmu, vehicle=vehicle, out=tmp_path / "out")
    message = str(caught.value)
    assert re.search(pattern, message) and "\n" not in message and caught.value.option == "vehicle"
    assert not (tmp_path / "out").exists()


def test_two_keys_on_one_variable_through_an_fmi2_alias_are_one_line(simple_fmu, tmp_path):
    """FMI 2.0 aliases: `gas`, a second name for the Simple FMU's throttle (its value reference, appended to its
    variables), is the throttle itself, so a map sending the brake to `gas` writes two pedals to one variable: one line
    naming both keys, before anything runs; `gas` alone as the throttle is the throttle's value reference."""
    def alias(text: str) -> str:
        reference = re.search(r'name="throttle" valueReference="(\d+)"', text)[1]
        return text.replace("</ModelVariables>", f'<ScalarVariable name="gas" valueReference="{reference}" '
                            'causality="input" variability="continuous"><Real start="0"/></ScalarVariable>\n'
                            "</ModelVariables>")

    fmu = rewritten_fmu(simple_fmu, tmp_path / "Alias.fmu", alias)
    both = write(tmp_path, BARE_MAP.replace('brake    = { variable = "brake" }', 'brake    = { variable = "gas" }'))
    with pytest.raises(api.InputError) as caught:
        api.run("head_on", fmu=fmu, vehicle=both, out=tmp_path / "out")
    assert str(caught.value) == (f"{both}: inputs.brake: 'gas' is an alias of 'throttle', inputs.throttle's variable "
                                 "(value reference 1): one FMU variable cannot take two values (map each to a "
                                 "variable of its own)")
    assert caught.value.option == "vehicle" and not (tmp_path / "out").exists()
    alone = write(tmp_path, BARE_MAP.replace('throttle = { variable = "throttle" }', 'throttle = { variable = "gas" }'),
                  "alone.toml")
    throttle = EgoModel.open(fmu, alone).inputs["throttle"]
    assert (throttle.variable, throttle.reference) == ("gas", 1)


FMU_MISTAKES = [
    ("no co-simulation", dict(edit_description=lambda text: re.sub(r"<CoSimulation.*?</CoSimulation>", "", text,
                                                                   flags=re.S)),
     r"^fmu \S+NoCs\.fmu: has no co-simulation interface"),
    ("no binary for this platform", dict(drop=lambda name: name.startswith("binaries/linux64/")),
     r"^fmu \S+NoCs\.fmu: has no binary for this platform \(binaries/linux64/EgoVehicleSimple\.so\)"),
]


@pytest.mark.parametrize("change, pattern", [m[1:] for m in FMU_MISTAKES], ids=[m[0] for m in FMU_MISTAKES])
def test_fmu_mistakes_are_one_line_naming_the_fmu(simple_fmu, tmp_path, change, pattern):
    fmu = rewritten_fmu(simple_fmu, tmp_path / "NoCs.fmu", **change)
    vehicle = write(tmp_path, BARE_MAP)
    for options in ({"vehicle": vehicle}, {}):  # through a map, and through the shipped map
        with pytest.raises(api.InputError) as caught:
            api.run("head_on", fmu=fmu, out=tmp_path / "out", **options)
        assert re.search(pattern, str(caught.value)) and "\n" not in str(caught.value)
        assert caught.value.option == "fmu" and not (tmp_path / "out").exists()


def test_a_mapped_array_variable_is_one_line(simple_fmus, tmp_path):
    """An FMI 3.0 array (a Dimension element) named by a map entry: its one value reference stands for several
    values, which the run would set or read as one. Refused before anything runs, naming the file and the key."""
    fmu = rewritten_fmu(simple_fmus[3], tmp_path / "Array.fmu", lambda text: re.sub(
        r'(<Float64 name="steer"[^>]*?)\s*/>', r'\1><Dimension start="2"/></Float64>', text))
    vehicle = write(tmp_path, BARE_MAP)
    with pytest.raises(api.InputError) as caught:
        api.run("head_on", fmu=fmu, vehicle=vehicle, out=tmp_path / "out")
    message = str(caught.value)
    assert re.search(r"car\.toml: inputs\.steer: 'steer' is an array; this entry needs a scalar variable$", message)
    assert "\n" not in message and caught.value.option == "vehicle" and not (tmp_path / "out").exists()


def test_command_line_reports_a_map_mistake_in_one_line(simple_fmu, tmp_path):
    vehicle = write(tmp_path, BARE_MAP.replace('variable = "steer"', 'variable = "steering_angle"'))
    completed = sdl_fmu("run", "head_on", "--fmu", simple_fmu, "--vehicle", vehicle, "--out", tmp_path / "out",
                        timeout=120, cwd=tmp_path)
    assert completed.returncode == 2 and completed.stdout == ""
    assert completed.stderr.count("\n") == 1 and "car.toml: inputs.steer" in completed.stderr
    assert not (tmp_path / "out").exists()


def test_dynamics_and_vehicle_together_are_refused(simple_fmu, tmp_path):
    with pytest.raises(api.InputError, match="^dynamics simple: give either a shipped model .* or a vehicle map"):
        api.run("head_on", dynamics="simple", fmu=simple_fmu, vehicle=write(tmp_path, BARE_MAP))


# ---- units and conversions -------------------------------------------------------------------------------------

def test_units_come_from_the_fmu_else_from_the_map_through_pint(simple_fmu, tmp_path):
    """v declares no unit in this copy: the map's km/h applies (1 km/h = 1/3.6 m/s); steer declares none: the
    road-wheel angle x 16 is sent in degrees (FMU value = 16 * 180/pi * rad); psi keeps the FMU's rad (factor 1,
    the map's "deg" would disagree with it)."""
    fmu = rewritten_fmu(simple_fmu, tmp_path / "Bare.fmu", lambda text: re.sub(
        r'(name="(v|steer)"[^\n]*\n\s*<Real[^>]*?) unit="[^"]*"', r"\1", text))
    text = BARE_MAP.replace('speed = { variable = "v" }', 'speed = { variable = "v", unit = "km/h" }').replace(
        'steer    = { variable = "steer" }', 'steer    = { variable = "steer", scale = 16.0, unit = "deg" }')
    model = EgoModel.open(fmu, write(tmp_path, text))
    assert model.outputs["speed"].factor == pytest.approx(1 / 3.6, rel=1e-15) and model.outputs["speed"].offset == 0
    assert model.inputs["steer"].factor == pytest.approx(16 * 180 / math.pi, rel=1e-15)
    assert model.outputs["yaw"].factor == 1.0
    with pytest.raises(VehicleMapError, match=r"outputs\.yaw\.unit: 'deg' disagrees with the FMU's unit 'rad'"):
        EgoModel.open(fmu, write(tmp_path, text.replace('yaw   = { variable = "psi" }',
                                                        'yaw   = { variable = "psi", unit = "deg" }')))


def test_a_mirrored_map_reproduces_the_shipped_run(simple_fmu, tmp_path):
    """scale = -1 flips a sign convention. Here the map flips the lateral axis both ways (steer in, y, yaw, vy, yaw
    rate, ay out, the start y, and left/right friction inputs swapped): the FMU drives the mirror image of the
    shipped run, which is the shipped run seen in a mirror. Round-to-nearest is symmetric in sign, so every
    operation of the mirrored model gives the negated result: the two runs agree to rounding (1e-9)."""
    text = shipped_map_path("simple").read_text()
    for name in ("y", "yaw", "vy", "yaw_rate", "ay"):
        text = re.sub(rf"^({name}\s*= {{ variable = \"\w+\")", r"\1, scale = -1.0", text, count=2, flags=re.M)
    text = text.replace('steer    = { variable = "steer" }', 'steer    = { variable = "steer", scale = -1.0 }')
    text = text.replace('["mu_fl", "mu_fr", "mu_rl", "mu_rr"]', '["mu_fr", "mu_fl", "mu_rr", "mu_rl"]')
    assert text.count("scale = -1.0") == 8  # 5 outputs, steer, start y and yaw
    vehicle = write(tmp_path, text.replace('name = "simple"', 'name = "mirrored"'))
    for scenario in ("head_on", "spin"):
        shipped = api.run(scenario, fmu=simple_fmu)
        mirrored = api.run(scenario, fmu=simple_fmu, vehicle=vehicle)
        assert mirrored.raw.dynamics == "mirrored"
        for name, values in shipped.arrays.items():
            assert np.allclose(mirrored.arrays[name], values, rtol=0, atol=1e-9, equal_nan=True), name
        assert [e["action"] for e in mirrored.events] == [e["action"] for e in shipped.events]


# ---- derived outputs ----------------------------------------------------------------------------------------

def test_missing_outputs_are_derived(simple_fmu, tmp_path):
    """Straight braking, drag and rolling resistance off, with only x, y, yaw and speed mapped. The deceleration
    a = min(brake * brake_decel_max, mu g) is constant until the stop, so v falls linearly and the trapezoid rule
    integrates it exactly: distance = v0 t - a t^2 / 2; ax by backward difference is -a; yaw rate, vy and ay are 0
    driving straight; stopped once v < STOPPED_SPEED, i.e. within STOPPED_SPEED / a of t = v0 / a. The FMU's own
    solver (tolerance 1e-10) keeps v linear to 1e-8 m/s, hence the tolerances."""
    model = EgoModel.open(simple_fmu, write(tmp_path, BARE_MAP))
    v0, brake, mu = 20.0, 0.6, 0.8
    a = min(brake * model.parameters["brake_decel_max"], mu * G)
    with model.instantiate(start={"speed": v0, "y": 0.0},
                           parameters={"drag_area": 0.0, "rolling_resistance": 0.0}) as ego:
        ego.set_controls(0.0, brake, 0.0)
        ego.set_friction((mu,) * 4)
        ego.step_to(0.1)
        while True:
            state = ego.read()
            if state.stopped or state.time > 10:
                break
            t = state.time
            assert state.s == pytest.approx(v0 * t - a * t * t / 2, abs=1e-6)
            assert state.ax == pytest.approx(-a, abs=1e-6)
            assert state.yaw_rate == state.vy == state.ay == 0.0 and state.vx == state.v
            ego.step_to(round(t + 0.1, 10))
        assert state.stopped and 0 <= state.time - (v0 - STOPPED_SPEED) / a <= 0.1 + 1e-9


def test_an_unmapped_start_position_moves_the_fmu_onto_sdl_fmus_start(simple_fmu, tmp_path):
    """Without [start] x and y the FMU starts where it starts (x0 = y0 = 0); its outputs are shifted so the run
    starts where sdl-fmu's start is, and keep moving as the FMU's do."""
    model = EgoModel.open(simple_fmu, write(tmp_path, BARE_MAP.replace('y     = { variable = "y0" }\n', "")))
    with model.instantiate(start={"speed": 10.0, "x": 5.0, "y": -1.8, "yaw": 0.0}) as ego:
        assert (ego.read().x, ego.read().y) == (5.0, -1.8)
        ego.step_to(1.0)
        state = ego.read()
        assert state.y == pytest.approx(-1.8, abs=1e-12) and state.x > 5.0 + 9.0


def test_a_map_without_start_speed_starts_at_the_fmus_own_speed_with_one_warning(simple_fmu, tmp_path):
    model = EgoModel.open(simple_fmu, write(tmp_path, BARE_MAP.replace('speed = { variable = "v0" }\n', "")))
    own = model.parameters["v0"]
    with model.instantiate(start={"speed": own + 5.0, "y": 0.0}) as ego:
        assert ego.read().v == pytest.approx(own, abs=1e-9)
        assert len(ego.warnings) == 1 and "no [start] speed" in ego.warnings[0]


# ---- friction ----------------------------------------------------------------------------------------------------

def test_friction_per_axle_and_for_the_car(simple_fmu, tmp_path):
    """Per axle the mean of its wheels' mu, for the car the mean of all four, scaled and offset as mapped."""
    for variables, scale, expected in (('["mu_fl", "mu_rl"]', 1.0, {"mu_fl": 0.5, "mu_rl": 0.25}),
                                       ('["mu_rr"]', 2.0, {"mu_rr": 2.0 * 0.375})):
        text = BARE_MAP.replace('variables = ["mu_fl", "mu_fr", "mu_rl", "mu_rr"], meaning = "mu"',
                                f'variables = {variables}, meaning = "mu", scale = {scale}')
        model = EgoModel.open(simple_fmu, write(tmp_path, text))
        with model.instantiate(start={"speed": 10.0}) as ego:
            ego.set_friction((0.6, 0.4, 0.3, 0.2))
            read = {name: ego.slave.getReal([model.variables[name].valueReference])[0] for name in expected}
        assert read == pytest.approx(expected, rel=1e-15)


def test_a_vehicle_without_friction_input_warns_once_per_rsa_line(simple_fmu, tmp_path):
    text = BARE_MAP.replace('friction = { variables = ["mu_fl", "mu_fr", "mu_rl", "mu_rr"], meaning = "mu" }\n', "")
    result = api.run("road_surface_simple", fmu=simple_fmu, vehicle=write(tmp_path, text), until_time=5.0)
    rsa_lines = [e.line for e in result.scenario.events if type(e).__name__ == "SurfaceAttribute"]
    warned = [w for w in result.warnings if "RSA has no effect" in w]
    assert len(rsa_lines) > 1 and len(warned) == len(rsa_lines)
    assert [int(w.split(":")[0].split()[1]) for w in warned] == rsa_lines
    assert not any(name.startswith("mu_") for name in result.raw.columns)


# ---- exactness follows capability -------------------------------------------------------------------------------

@pytest.mark.parametrize("fmi_version", [2, 3])
def test_an_fmu_without_state_get_set_locates_triggers_within_its_uncertainty(simple_fmus, fmi_version, tmp_path):
    """BRK on at 100 m, off when the speed falls below 10 m/s. The exact run bisects both instants to 1e-6 s. The
    FMU that cannot roll back is stepped at most MIN_LOOKAHEAD near each possible trigger, so each instant is
    found at the end of the step in which it happened: the onset at most u_on late. Before the onset the ego
    cruises at constant speed, so a late onset shifts the whole braking in time: the release is late by the
    onset's delay plus its own location error, at most u_on + u_off (+ the exact run's 1e-6 s)."""
    scenario = write(tmp_path, "Metric\n100,BRK,80,2,10\n300,ES\n", "brk.sdl")
    vehicle = write(tmp_path, shipped_map_path("simple").read_text())
    simple_fmu = simple_fmus[fmi_version]
    exact = api.run(scenario, fmu=simple_fmu, vehicle=vehicle, step=0.5)
    stepped = api.run(scenario, fmu=no_state_fmu(simple_fmu, tmp_path), vehicle=vehicle, step=0.5)
    assert all("time_uncertainty_s" not in e for e in exact.events)
    assert sum("cannot get and set its state" in w for w in stepped.warnings) == 1
    (on, off), (on_exact, off_exact) = ([e for e in run.events if e["code"] == "BRK"] for run in (stepped, exact))
    assert on["action"] == "on" and off["action"] == "off" and off["reason"] == "velocity"
    # at most MIN_LOOKAHEAD = 1e-3 s, plus the rounding of t + 1e-3 (an ulp of t < 100 s: 1.4e-14 s)
    assert 0 < on["time_uncertainty_s"] <= 1e-3 + 1e-13 and 0 < off["time_uncertainty_s"] <= 1e-3 + 1e-13
    assert -1e-6 <= on["time_s"] - on_exact["time_s"] <= on["time_uncertainty_s"] + 1e-6
    assert -1e-6 <= off["time_s"] - off_exact["time_s"] <= on["time_uncertainty_s"] + off["time_uncertainty_s"] + 1e-6
    assert stepped.summary["vehicle"]["can_roll_back"] is False
    assert stepped.summary["vehicle"]["fmi_version"] == f"{fmi_version}.0"


def test_bounds_used_are_in_the_summary(simple_fmu, tmp_path):
    given = write(tmp_path, BARE_MAP + "max_acceleration = 30.0\nmax_yaw_rate = 3.0\n")
    derived = write(tmp_path, BARE_MAP, "derived.toml")
    summaries = [api.run("head_on", fmu=simple_fmu, vehicle=v, until_time=2.0).summary for v in (given, derived)]
    assert summaries[0]["vehicle"]["bounds"] == {"acceleration_m/s2": 30.0, "yaw_rate_rad/s": 3.0,
                                                 "source": "vehicle map", "defaults": []}
    bounds = summaries[1]["vehicle"]["bounds"]
    assert bounds["source"] == "vehicle properties" and "mass" in bounds["defaults"]
    json.dumps(summaries)


# ---- sweep and verify take the map too ----------------------------------------------------------------------------

def test_a_sweep_drives_a_vehicle_map(simple_fmu, tmp_path):
    """Each run of the sweep is api.run with the map: the same final state as the run made directly."""
    distributed = pytest.importorskip("distributed")
    from sdl_fmu import sweep as sweeping

    vehicle = write(tmp_path, BARE_MAP.replace("[inputs]", 'name = "bare"\n[inputs]'))
    scenario = write(tmp_path, "English\n100,A,50,600,-6,1\n", "pass.sdl")
    cluster = local_cluster(1)
    with distributed.Client(cluster) as client:
        rows = sweeping.sweep(str(scenario), {"speed": [60.0, 80.0]}, tmp_path / "sweep", client=client, timeout=120,
                              until_distance=400.0, progress=False, fmu=str(simple_fmu), vehicle=str(vehicle))
    cluster.close()
    assert [row["status"] for row in rows] == ["ok", "ok"]
    for row in rows:
        direct = api.run(scenario, fmu=simple_fmu, vehicle=vehicle, speed=row["speed_ft/s"], until_distance=400.0)
        assert row["final_time_s"] == direct.final["time_s"]


def test_verify_takes_the_vehicle_option(simple_fmu, tmp_path):
    vehicle = write(tmp_path, BARE_MAP.replace('variable = "steer"', 'variable = "steering_angle"'))
    completed = sdl_fmu("verify", "--fmu", simple_fmu, "--vehicle", vehicle, timeout=120, cwd=tmp_path)
    assert completed.returncode == 2 and "car.toml: inputs.steer" in completed.stderr
    assert completed.stderr.count("\n") == 1
