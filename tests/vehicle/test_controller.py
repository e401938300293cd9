"""The controller in the loop, without running a scenario: the controller map's shape and its one-line errors (each
key), the map resolved against real FMUs (the foreign AEB controller built by PythonFMU and pythonfmu3, units through
pint and UnitDefinitions), the arbitration rules, the sample clocks and the follow driver's law at hand-computed
points (docs/controllers.md)."""

import math

import pytest

from helpers import FOREIGN_AEB_MAP, build_foreign_controller
from sdl_fmu import api
from sdl_fmu.cosim.arbitration import arbitrate, requested_brake
from sdl_fmu.cosim.clocks import SampleClocks
from sdl_fmu.cosim.driver import MAX_STEER
from sdl_fmu.cosim.follow import safe_speed
from sdl_fmu.vehicle.controller import ControllerModel, Request
from sdl_fmu.vehicle.controller_map import ControllerMapError, load_controller_map


@pytest.fixture(scope="module")
def controllers(tmp_path_factory):
    """{2: the FMI 2.0 foreign AEB (PythonFMU), 3: the FMI 3.0 one (pythonfmu3)}, no state get/set."""
    folder = tmp_path_factory.mktemp("controllers")
    return {version: build_foreign_controller(folder, version) for version in (2, 3)}


GOOD = FOREIGN_AEB_MAP.read_text()


def write_map(tmp_path, text: str):
    path = tmp_path / "aeb.toml"
    path.write_text(text)
    return path


# ---- the map's shape: one line naming the file and the key ------------------------------------------------------

SHAPE_MISTAKES = [
    # (edit of the good map, the key the message names, a part of the reason)
    (lambda t: "speed = 3\n" + t, "speed", "unknown key"),
    (lambda t: t.replace("period = 0.01", "period = nan"), "period", "finite number"),
    (lambda t: t.replace("period = 0.01", "period = 0.0001"), "period", ">= 0.001"),
    (lambda t: t.replace("period = 0.01", "period = 2.0"), "period", "<= 1"),
    (lambda t: t.replace("period = 0.01", "# no period"), "period", "missing"),
    (lambda t: t.replace("[inputs]", "[inputs]\nlead_distance = { variable = \"x\" }"), "inputs.lead_distance",
     "unknown signal"),
    (lambda t: t.replace('ego_v               = { variable = "v_host", unit = "km/h" }', 'ego_v = "v_host"'),
     "inputs.ego_v", "must be a table"),
    (lambda t: t.replace('{ variable = "v_host", unit = "km/h" }', '{ unit = "km/h" }'), "inputs.ego_v.variable",
     "missing"),
    (lambda t: t.replace('{ variable = "v_host", unit = "km/h" }', '{ variable = "v_host", units = "km/h" }'),
     "inputs.ego_v.units", "unknown key"),
    (lambda t: t.replace('{ variable = "obj_valid" }', '{ variable = "obj_valid", scale = 2.0 }'),
     "inputs.lead_present.scale", "boolean: only variable"),
    (lambda t: t.replace('{ variable = "v_host", unit = "km/h" }', '{ variable = "v_host", scale = "fast" }'),
     "inputs.ego_v.scale", "finite number"),
    (lambda t: t.replace('{ variable = "brake_cmd_pct", scale = 0.01 }', '{ variable = "brake_cmd_pct", unit = "%" }'),
     "outputs.brake.unit", "a pedal is a number"),
    (lambda t: t.replace("[outputs]", "[outputs]\nhorn = { variable = \"h\" }"), "outputs.horn", "unknown request"),
    (lambda t: t.replace('brake  = { variable = "brake_cmd_pct", scale = 0.01 }  # 0..100 % -> pedal 0..1', "")
     .replace('brake = "max"', ""), "[outputs]", "requests nothing"),
    (lambda t: t.split("[outputs]")[0], "[outputs]", "missing"),
    (lambda t: t.replace('steer = "driver"', 'horn = "driver"'), "arbitration.horn", "unknown channel"),
    (lambda t: t.replace('brake = "max"', 'brake = "min"'), "arbitration.brake", "must be one of"),
    (lambda t: t.replace('steer = "driver"', 'steer = "max"'), "arbitration.steer", "not defined for a steering"),
    (lambda t: t.replace('throttle = "driver"', 'throttle = "override"'), "arbitration.throttle",
     "has no throttle"),
    (lambda t: t.replace("cycle_time = 0.01", 'cycle_time = "fast"'), "parameters.cycle_time", "finite number"),
    # the vehicle map's ranges (an output offset of 1e308 once ran, its column empty, numpy's RuntimeWarning)
    (lambda t: t.replace('{ variable = "brake_cmd_pct", scale = 0.01 }',
                         '{ variable = "brake_cmd_pct", offset = 1e308 }'),
     "outputs.brake.offset", "1e+308 is outside its range: |offset| <= 1e+06"),
    (lambda t: t.replace('{ variable = "v_host", unit = "km/h" }', '{ variable = "v_host", scale = 1e308 }'),
     "inputs.ego_v.scale", "1e+308 is outside its range: 1e-06 <= |scale| <= 1e+06"),
    (lambda t: t.replace('{ variable = "v_host", unit = "km/h" }', '{ variable = "v_host", scale = 0.0 }'),
     "inputs.ego_v.scale", "0.0 is outside its range"),
    (lambda t: "arbitration = 3\n" + t.split("[arbitration]")[0], "arbitration", "must be a table"),
    # many-to-one: two signals (or a signal and a start value) on one controller variable; the key read second is named
    # with the first (lead_ttc and lead_relative_speed both on ttc once left the AEB blind, exit 0)
    (lambda t: t.replace('{ variable = "v_rel", unit = "km/h" }', '{ variable = "ttc_ms" }'),
     "inputs.lead_ttc", "'ttc_ms' is also inputs.lead_relative_speed's variable: one controller variable cannot take "
                        "two values"),
    (lambda t: t.replace("cycle_time = 0.01", "v_host = 3.0"), "parameters.v_host",
     "'v_host' is also inputs.ego_v's variable"),
]


@pytest.mark.parametrize("edit, key, reason", SHAPE_MISTAKES, ids=[m[1] + ":" + m[2] for m in SHAPE_MISTAKES])
def test_each_mistake_in_a_map_is_one_line_naming_the_file_and_the_key(tmp_path, edit, key, reason):
    path = write_map(tmp_path, edit(GOOD))
    with pytest.raises(ControllerMapError) as caught:
        load_controller_map(path)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: {key}: "), message
    assert reason in message, message


def test_a_file_that_is_not_toml_or_not_there_is_one_line(tmp_path):
    path = write_map(tmp_path, "period = = 3\n")
    with pytest.raises(ControllerMapError, match=rf"^{path}: not TOML: "):
        load_controller_map(path)
    with pytest.raises(ControllerMapError, match=r"^controller_map .*missing.toml: no such file$") as caught:
        load_controller_map(tmp_path / "missing.toml")
    assert caught.value.command_line().startswith("--controller-map ")  # the option, worded by the command line
    with pytest.raises(ControllerMapError, match=r"is a folder, not a file$"):
        load_controller_map(tmp_path)


def test_the_default_rules_follow_what_the_controller_requests(tmp_path):
    """A mapped channel without an [arbitration] entry: brake max, throttle and steer override; an unmapped one:
    driver; a deceleration is arbitrated as the brake."""
    text = GOOD.split("[arbitration]")[0] + "[parameters]\n"
    assert load_controller_map(write_map(tmp_path, text)).rules == {"throttle": "driver", "brake": "max",
                                                                    "steer": "driver"}
    text = text.replace('brake  = { variable = "brake_cmd_pct", scale = 0.01 }',
                        'deceleration = { variable = "decel_cmd" }\nthrottle = { variable = "t" }\n'
                        'steer = { variable = "s" }')
    assert load_controller_map(write_map(tmp_path, text)).rules == {"throttle": "override", "brake": "max",
                                                                    "steer": "override"}


# ---- the map against the FMU ---------------------------------------------------------------------------------------

FMU_MISTAKES = [
    (lambda t: t.replace('"v_host"', '"v_car"'), "inputs.ego_v", "has no variable 'v_car'"),
    (lambda t: t.replace('variable = "v_host"', 'variable = "brake_cmd_pct"'), "inputs.ego_v",
     "is an output of the FMU; this entry needs input"),
    (lambda t: t.replace('variable = "brake_cmd_pct"', 'variable = "v_rel"'), "outputs.brake",
     "is an input of the FMU; this entry needs output"),
    (lambda t: t.replace('lead_present        = { variable = "obj_valid" }\n', '')  # obj_valid on ego_v alone
     .replace('{ variable = "v_host", unit = "km/h" }', '{ variable = "obj_valid" }'), "inputs.ego_v",
     "is Boolean; this entry needs a Real variable"),
    (lambda t: t.replace('{ variable = "v_host", unit = "km/h" }', '{ variable = "v_host", unit = "furlong" }'),
     "inputs.ego_v.unit", "unknown unit"),
    (lambda t: t.replace('{ variable = "v_host", unit = "km/h" }', '{ variable = "v_host", unit = "s" }'),
     "inputs.ego_v.unit", "not a unit of m/s"),
    (lambda t: t.replace("cycle_time = 0.01", "cycle_time = 0.01\nspeed_limit = 3.0"), "parameters.speed_limit",
     "has no variable 'speed_limit'"),
    (lambda t: t.replace("cycle_time = 0.01", "cycle_time = true"), "parameters.cycle_time", "does not fit"),
]


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("edit, key, reason", FMU_MISTAKES, ids=[m[1] + ":" + m[2] for m in FMU_MISTAKES])
def test_a_map_that_does_not_fit_its_fmu_is_one_line_naming_the_key(tmp_path, controllers, version, edit, key,
                                                                       reason):
    path = write_map(tmp_path, edit(GOOD))
    with pytest.raises(api.InputError) as caught:
        api.controller_model(controllers[version], path)
    message = str(caught.value)
    assert caught.value.option == "controller_map"
    assert "\n" not in message and message.startswith(f"{path}: {key}: ") and reason in message, message


def test_a_signal_on_an_fmi2_alias_of_a_mapped_input_is_refused(tmp_path, controllers):
    """`closing_speed`, a second name (an FMI 2.0 alias: the same value reference) for the PythonFMU build's v_rel,
    is v_rel itself: a second signal on it is the many-to-one wiring of two names on one variable, one line naming
    both keys."""
    import re

    from helpers import rewritten_fmu

    def alias(text: str) -> str:
        reference = re.search(r'name="v_rel" valueReference="(\d+)"', text)[1]
        return text.replace("</ModelVariables>", f'<ScalarVariable name="closing_speed" valueReference="{reference}" '
                            'causality="input" variability="continuous"><Real start="0.0"/></ScalarVariable>\n'
                            "</ModelVariables>")

    fmu = rewritten_fmu(controllers[2], tmp_path / "Alias.fmu", alias)
    line = 'collisions          = { variable = "crash_count" }\n'
    path = write_map(tmp_path, GOOD.replace(line, line + 'ego_ax = { variable = "closing_speed" }\n'))
    with pytest.raises(api.InputError) as caught:
        api.controller_model(fmu, path)
    message = str(caught.value)
    assert caught.value.option == "controller_map" and "\n" not in message
    assert re.fullmatch(rf"{re.escape(str(path))}: inputs\.ego_ax: 'closing_speed' is an alias of 'v_rel', "
                        r"inputs\.lead_relative_speed's variable \(value reference \d+\): one FMU variable cannot "
                        r"take two values \(map each to a variable of its own\)", message), message
    assert api.controller_model(fmu, FOREIGN_AEB_MAP).inputs  # the alias alone changes nothing


def test_a_declared_unit_the_map_contradicts_is_refused(tmp_path, controllers):
    """The FMI 3.0 build declares v_host in km/h (UnitDefinitions): a map saying m/s disagrees; the FMI 2.0 build
    declares no unit, so there the map's unit is the only one."""
    path = write_map(tmp_path, GOOD.replace('{ variable = "v_host", unit = "km/h" }',
                                            '{ variable = "v_host", unit = "m/s" }'))
    with pytest.raises(api.InputError, match=r"inputs.ego_v.unit: 'm/s' disagrees with the FMU's unit 'km/h'"):
        api.controller_model(controllers[3], path)
    assert api.controller_model(controllers[2], path).inputs[0].factor == 1.0


@pytest.mark.parametrize("version", [2, 3])
def test_the_conversions_take_si_to_the_controllers_units(controllers, version):
    """ego_v in m/s -> v_host in km/h: x 3.6; lead_ttc in s -> ttc_ms: x 1000; brake_cmd_pct in % -> pedal: x 0.01
    (the map's scale); from the FMI 3.0 build's UnitDefinitions or the map's units through pint alike."""
    model = api.controller_model(controllers[version], FOREIGN_AEB_MAP)
    ports = {port.name: port for port in (*model.inputs, *model.outputs)}
    assert ports["ego_v"].factor == pytest.approx(3.6, rel=1e-12) and ports["ego_v"].offset == 0.0
    assert ports["lead_ttc"].factor == pytest.approx(1000.0, rel=1e-12)
    assert ports["lead_gap"].factor == 1.0
    assert ports["brake"].factor == 0.01 and ports["brake"].kind == "pedal"
    assert ports["active"].type == "Boolean" and ports["lead_id"].type in ("Integer", "Int32")
    assert model.period == 0.01 and not model.can_roll_back
    assert model.summary()["arbitration"] == {"throttle": "driver", "brake": "max", "steer": "driver"}


def test_two_signals_on_one_controller_input_are_refused_before_the_run(tmp_path):
    """The example AEB's map with lead_ttc and lead_relative_speed both on its input ttc was once run
    (the AEB never activated; the ego hit the stopped car at 88 ft/s; exit 0). Now `run` refuses it in one line naming
    both keys (exit 2), before anything runs and with nothing written; the shipped map itself still runs."""
    from helpers import sdl_fmu

    fmu, cmap = api.example_controller()
    text = cmap.read_text()
    assert 'lead_relative_speed = { variable = "relative_speed" }' in text
    both = write_map(tmp_path, text.replace('lead_relative_speed = { variable = "relative_speed" }',
                                            'lead_relative_speed = { variable = "ttc" }'))
    scenario = tmp_path / "stopped.sdl"
    scenario.write_text("English\n0,A,0,400,*0,1\n1000,ES\n")  # a stopped car 400 ft ahead of the ego's centre
    failed = sdl_fmu("run", scenario, "--controller", fmu, "--controller-map", both, "--out", tmp_path / "never")
    assert failed.returncode == 2 and failed.stdout == ""
    assert failed.stderr == (f"sdl-fmu: {both}: inputs.lead_relative_speed: 'ttc' is also inputs.lead_ttc's variable: "
                             "one controller variable cannot take two values (map each to a variable of its own)\n")
    assert not (tmp_path / "never").exists()
    with pytest.raises(api.InputError, match="is also inputs.lead_ttc's variable"):
        api.run(scenario, controller=fmu, controller_map=both)
    assert api.controller_model(fmu, cmap).map.inputs["lead_relative_speed"].variable == "relative_speed"


def test_a_controller_needs_a_map_and_an_fmu(tmp_path, controllers):
    with pytest.raises(api.InputError, match=r"^controller .*: needs a controller map") as caught:
        api.controller_model(controllers[2], None)
    assert caught.value.command_line().startswith("--controller ")
    with pytest.raises(api.InputError, match=r"fmu: missing \(give the FMU as the controller option or in the map\)"):
        api.controller_model(None, FOREIGN_AEB_MAP)
    with pytest.raises(api.InputError, match=r"^controller .*nothing.fmu: no such file$"):
        api.controller_model(tmp_path / "nothing.fmu", FOREIGN_AEB_MAP)
    (tmp_path / "fake.fmu").write_text("not a zip")
    with pytest.raises(api.InputError, match=r"^controller .*fake.fmu: is not a readable FMU") as caught:
        api.controller_model(tmp_path / "fake.fmu", FOREIGN_AEB_MAP)
    assert caught.value.command_line().startswith("--controller ")
    relative = write_map(tmp_path, f'fmu = "{controllers[3]}"\n' + GOOD)
    assert ControllerModel.open(None, relative).fmu_path == controllers[3]


# ---- arbitration --------------------------------------------------------------------------------------------------

RULES = {"throttle": "override", "brake": "max", "steer": "override"}


def test_arbitration_by_rule():
    driver = (0.4, 0.1, 0.02)
    assert arbitrate(driver, Request(False, 0.9, 0.5, 0.1, None), RULES, 8.0) == driver  # inactive: the driver's
    # active: throttle overridden, brake the larger (0.5), and a brake above 0 cuts the throttle
    assert arbitrate(driver, Request(True, 0.9, 0.5, 0.1, None), RULES, 8.0) == (0.0, 0.5, 0.1)
    assert arbitrate(driver, Request(True, 0.9, 0.05, 0.1, None), RULES, 8.0) == (0.0, 0.1, 0.1)
    assert arbitrate(driver, Request(True, 0.9, 0.0, None, None), RULES, 8.0) == (0.9, 0.1, 0.02)
    override = {**RULES, "brake": "override"}
    assert arbitrate(driver, Request(True, 0.9, 0.0, None, None), override, 8.0) == (0.9, 0.0, 0.02)
    ignored = {"throttle": "driver", "brake": "driver", "steer": "driver"}
    assert arbitrate(driver, Request(True, 0.9, 1.0, 0.3, 4.0), ignored, 8.0) == driver  # no cut: brake ignored
    maximum = {**RULES, "throttle": "max"}
    assert arbitrate(driver, Request(True, 0.3, None, None, None), maximum, 8.0) == (0.4, 0.1, 0.02)


def test_a_deceleration_is_turned_into_pedal_and_requests_are_limited():
    """brake = a / brake_decel_max (4 m/s2 of 8: 0.5), the larger of it and a brake pedal request; pedals 0..1,
    steer within +-MAX_STEER."""
    assert requested_brake(Request(True, None, None, None, 4.0), 8.0) == 0.5
    assert requested_brake(Request(True, None, 0.7, None, 4.0), 8.0) == 0.7
    assert requested_brake(Request(True, None, None, None, None), 8.0) is None
    driver = (0.4, 0.0, 0.0)
    assert arbitrate(driver, Request(True, None, None, None, 4.0), RULES, 8.0) == (0.0, 0.5, 0.0)
    assert arbitrate(driver, Request(True, None, None, None, 20.0), RULES, 8.0) == (0.0, 1.0, 0.0)
    assert arbitrate(driver, Request(True, 1.7, -0.2, 2.0, None), RULES, 8.0) == (1.0, 0.0, MAX_STEER)
    assert arbitrate(driver, Request(True, -1.0, None, -2.0, None), RULES, 8.0) == (0.0, 0.0, -MAX_STEER)


# ---- the sample clocks ---------------------------------------------------------------------------------------------

def test_clocks_sample_at_multiples_of_their_periods_and_merge_coincident_instants():
    clocks = SampleClocks({"driver": 0.05, "controller": 0.01, "follow": 2 / 3})
    seen = {"driver": [], "controller": [], "follow": []}
    t = 0.0
    while t < 2.0:
        t = clocks.earliest
        for name, k in clocks.due(t).items():
            seen[name].append((k, t))
    # every sample once, in order, at its own k x period (0.15 = 3 x 0.05 and 15 x 0.01 differ in their last bit:
    # one instant); k = 0 is the start, taken by the master before the loop
    for name, period in clocks.periods.items():
        ks = [k for k, _ in seen[name]]
        assert ks == list(range(1, len(ks) + 1))
        assert all(abs(instant - k * period) < 1e-12 for k, instant in seen[name])
    assert len(seen["controller"]) == 200 and len(seen["driver"]) == 40 and len(seen["follow"]) == 3
    instants = sorted({instant for samples in seen.values() for _, instant in samples})
    assert min(b - a for a, b in zip(instants, instants[1:])) > 1e-3  # no sliver steps
    assert clocks.due(clocks.earliest - 1e-6) == {}  # a step that ended at a trigger before the sample


# ---- the follow driver's law (Gipps 1981) ------------------------------------------------------------------------

def test_gipps_safe_speed_at_hand_computed_points():
    """v(t + tau) = b tau + sqrt(b^2 tau^2 - b [2 (gap - margin) - v tau - v_lead^2 / b^]) with Gipps' tau = 2/3 s,
    b = -3.4 m/s2, b^ = -3.2 m/s2 and the margin 2 m, worked by hand:
    - at rest at the margin (gap 2 m, v 0, lead 0): sqrt(b^2 tau^2) + b tau = 0;
    - gap - margin = 10 m, v = 0, lead stopped: b^2 tau^2 = 5.13778,
      -b 2 x 10 = 68, sqrt(73.13778) = 8.55206, v = 8.55206 - 2.26667 = 6.28539 m/s;
    - following at the lead's speed: gap - margin = 15 m, v = v_lead = 10 m/s: 5.13778 + 3.4 (30 - 6.66667 + 31.25)
      = 5.13778 + 185.5833 = 190.7211, sqrt = 13.81018, v = 11.54351 m/s;
    - closer than the law allows (1.5 m inside the margin at 10 m/s behind a stopped vehicle: 5.13778 + 3.4 (-3 -
      6.66667) < 0): 0."""
    assert safe_speed(0.0, 2.0, 0.0) == 0.0
    assert safe_speed(0.0, 12.0, 0.0) == pytest.approx(math.sqrt(3.4**2 * 4 / 9 + 68.0) - 3.4 * 2 / 3, rel=1e-12)
    assert safe_speed(0.0, 12.0, 0.0) == pytest.approx(6.28539, abs=1e-5)
    assert safe_speed(10.0, 17.0, 10.0) == pytest.approx(11.54351, abs=1e-5)
    assert safe_speed(10.0, 0.5, 0.0) == 0.0 and safe_speed(20.0, 0.0, 0.0) == 0.0
    assert safe_speed(0.0, 12.0, -5.0) == safe_speed(0.0, 12.0, 0.0)  # an oncoming vehicle counts as stopped
