"""`sdl-fmu export` without running a master (tests/ssp/test_export_masters.py runs them): the SSP keeps to the portable
subset (docs/export.md) and validates against the SSP 1.0 schemas fmpy ships; the ego's parameter set is what
`sdl-fmu run` sets (hand-converted for the foreign car's map: km/h, degrees, SAE signs); every signal the vehicle map
names is connected, its scale, offset and unit in a linear transformation (hand-computed); the stop time is run's
end on the step grid; the export folder is as safe as a results folder; every mistake is one line, exit 1 or 2,
nothing written."""

import math
import zipfile
from pathlib import Path

import pytest
from fmpy.ssp.ssd import read_ssd
from lxml import etree

from sdl_fmu import api
from sdl_fmu.cli import main
from sdl_fmu.tire_files import SLOT_KEYS, default_attribute_file, slot_parameter, slot_values
from sdl_fmu.results.folder import MANIFEST_NAME
from sdl_fmu.ssp.document import OSP, SSC, SSD, SSV, schema_directory

from helpers import FOREIGN_AEB_MAP, build_foreign_controller
from hostile_fmus import held_work, interrupted

FOOT = 0.3048
START_SPEED = 88 * FOOT  # m/s, the driver's default start speed
LANE_1 = 6 * FOOT  # m, the centre of lane 1 on the default road (12 ft lanes): the ego starts at y = -LANE_1


def members(ssp: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(ssp) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def ssd_root(ssp: Path):
    return etree.fromstring(members(ssp)["SystemStructure.ssd"])


def connections(ssp: Path) -> dict[tuple[str, str], tuple[str, str, float, float, bool]]:
    """(end component, end connector) -> (start component, start connector, factor, offset, unit conversion
    suppressed)."""
    found = {}
    for connection in ssd_root(ssp).iter(f"{{{SSD}}}Connection"):
        transformation = connection.find(f"{{{SSC}}}LinearTransformation")
        factor = float(transformation.get("factor")) if transformation is not None else 1.0
        offset = float(transformation.get("offset")) if transformation is not None else 0.0
        found[(connection.get("endElement"), connection.get("endConnector"))] = (
            connection.get("startElement"), connection.get("startConnector"), factor, offset,
            connection.get("suppressUnitConversion") == "true")
    return found


def parameter_set(ssp: Path, component: str) -> dict[str, tuple[str, str]]:
    root = etree.fromstring(members(ssp)[f"resources/{component}.ssv"])
    assert root.get("name") == "start"
    return {p.get("name"): (etree.QName(p[0]).localname, p[0].get("value"))
            for p in root.iter(f"{{{SSV}}}Parameter")}


@pytest.fixture(scope="module")
def demo(tmp_path_factory, simple_fmu):
    return api.export("demo", out=tmp_path_factory.mktemp("export") / "demo")


# ---- the portable subset ----------------------------------------------------------------------------------------


def test_the_ssd_keeps_to_the_portable_subset(demo):
    text = members(demo.ssp)["SystemStructure.ssd"].decode()
    root = ssd_root(demo.ssp)
    assert root.get("version") == "1.0"
    # the literal prefixes libcosim's and ecos' readers look for: every element is ssd:, ssc: or osp:
    assert root.nsmap == {"ssd": SSD, "ssc": SSC, "ssv": SSV, "osp": OSP}
    assert "ns0:" not in text and "<ssd:SystemStructureDescription" in text
    assert {etree.QName(e).namespace for e in root.iter()} <= {SSD, SSC, OSP}
    # every FMU under resources/, and beside the SSP, byte for byte
    components = {c.get("name"): c.get("source") for c in root.iter(f"{{{SSD}}}Component")}
    assert set(components) == {"scenario", "ego"}
    inside = members(demo.ssp)
    for name, source in components.items():
        assert source.startswith("resources/") and source.endswith(".fmu")
        assert inside[source] == demo.fmus[name].read_bytes()
        assert demo.fmus[name].parent == demo.folder and demo.fmus[name].name == Path(source).name
    # a named parameter set bound to each component
    for component in root.iter(f"{{{SSD}}}Component"):
        bindings = component.findall(f"{{{SSD}}}ParameterBindings/{{{SSD}}}ParameterBinding")
        assert [b.get("source") for b in bindings] == [f"resources/{component.get('name')}.ssv"]
    # the stop time and the OSP step annotation
    experiment = root.find(f"{{{SSD}}}DefaultExperiment")
    assert float(experiment.get("stopTime")) == demo.stop_time
    step = experiment.find(f".//{{{OSP}}}FixedStepAlgorithm")
    assert float(step.get("baseStepSize")) == demo.step == 0.01
    # every connector typed, each connection joins two connectors of one type
    types = {(c.getparent().getparent().get("name"), c.get("name")): etree.QName(c[0]).localname
             for c in root.iter(f"{{{SSD}}}Connector")}
    for (end_component, end), (start_component, start, *_rest) in connections(demo.ssp).items():
        assert types[(start_component, start)] == types[(end_component, end)]


def test_the_ssd_and_the_parameter_sets_validate_against_the_ssp_schemas_fmpy_ships(demo):
    inside = members(demo.ssp)
    for name, schema in (("SystemStructure.ssd", "SystemStructureDescription.xsd"),
                         ("resources/ego.ssv", "SystemStructureParameterValues.xsd"),
                         ("resources/scenario.ssv", "SystemStructureParameterValues.xsd")):
        checker = etree.XMLSchema(etree.parse(str(schema_directory() / schema)))
        assert checker.validate(etree.fromstring(inside[name])), (name, checker.error_log)
    read_ssd(str(demo.ssp), validate=True)  # fmpy's own reader, validating, as simulate_ssp does


def test_an_export_writes_the_same_bytes_every_time(demo, tmp_path):
    # every file of the folder byte for byte: the SSP (its SSD, parameter sets and FMUs), the scenario FMU and the
    # ego FMU beside it, the manifest; the zips carry fixed dates and modes and the scenario FMU's model description
    # no generation date, so neither the clock nor the files' dates in the cache show
    again = api.export("demo", out=tmp_path / "again")
    first = {path.name: path.read_bytes() for path in demo.ssp.parent.iterdir()}
    second = {path.name: path.read_bytes() for path in again.ssp.parent.iterdir()}
    assert sorted(first) == sorted(second) and len(first) == 4  # the SSP, two FMUs, the manifest
    assert [name for name in first if first[name] != second[name]] == []
    scenario = demo.fmus["scenario"]
    with zipfile.ZipFile(scenario) as archive:
        assert {entry.date_time for entry in archive.infolist()} == {(1980, 1, 1, 0, 0, 0)}
        assert b"generationDateAndTime" not in archive.read("modelDescription.xml")


# ---- the parameter sets and connections --------------------------------------------------------------------------


def test_the_shipped_simple_ego_starts_where_run_starts_it_and_every_signal_is_connected_one_to_one(demo):
    ego = parameter_set(demo.ssp, "ego")
    assert ego == {"v0": ("Real", repr(START_SPEED)), "x0": ("Real", "0.0"), "y0": ("Real", repr(-LANE_1)),
                   "psi0": ("Real", "0.0")}
    found = connections(demo.ssp)
    identity = {("ego", name): ("scenario", name) for name in ("throttle", "brake", "steer", "mu_fl", "mu_fr",
                                                               "mu_rl", "mu_rr")}
    identity.update({("scenario", f"ego_{name}"): ("ego", source) for name, source in (
        ("x", "x"), ("y", "y"), ("psi", "psi"), ("v", "v"), ("s", "s"), ("yaw_rate", "yaw_rate"), ("ax", "ax"))})
    for end, start in identity.items():
        assert found[end] == (*start, 1.0, 0.0, False), end


def test_the_advanced_ego_gets_its_tire_slots_and_integer_surfaces(tmp_path, advanced_fmu):
    export = api.export("demo_advanced", dynamics="advanced", out=tmp_path / "advanced")
    ego = parameter_set(export.ssp, "ego")
    # the tire slots as run fills them: the shipped Tire Attribute File, slot k named tire<k>_<KEY> (the map's prefix)
    count = sum(1 for name in ego if name.endswith(f"_{SLOT_KEYS[0]}"))
    slots, _, _ = slot_values(default_attribute_file(), count)
    expected = {slot_parameter("tire{slot}_", k, key): value for k, values in enumerate(slots)
                for key, value in values.items()}
    assert count >= 2 and expected and all(ego[name] == ("Real", repr(float(value))) for name, value in expected.items())
    found = connections(export.ssp)
    for wheel in ("fl", "fr", "rl", "rr"):
        assert found[("ego", f"surface_{wheel}")] == ("scenario", f"surface_{wheel}", 1.0, 0.0, False)
    types = {c.get("name"): etree.QName(c[0]).localname for c in ssd_root(export.ssp).iter(f"{{{SSD}}}Connector")}
    assert types["surface_fl"] == "Integer"


def test_a_foreign_vehicle_is_connected_through_its_map_with_hand_computed_transformations(tmp_path,
                                                                                        foreign_vehicle):
    fmu, vehicle_map = foreign_vehicle(2)
    export = api.export("demo", fmu=fmu, vehicle=vehicle_map, out=tmp_path / "foreign")
    ego = parameter_set(export.ssp, "ego")
    # [start]: 88 ft/s in km/h; y flipped (SAE: y to the right), so +6 ft; heading 0 deg
    assert float(ego["v_init"][1]) == pytest.approx(88 * FOOT * 3.6, rel=1e-15)
    assert float(ego["y_init"][1]) == pytest.approx(LANE_1, rel=1e-15)
    assert float(ego["x_init"][1]) == 0.0 and float(ego["heading_init"][1]) == 0.0
    found = connections(export.ssp)
    degree = math.pi / 180
    expected = {  # end -> (start, factor): the map's scale times the unit's factor
        ("ego", "accel_pedal"): (("scenario", "throttle"), 100.0),  # pedal 0..1 -> %
        ("ego", "brake_pressure"): (("scenario", "brake"), 120.0),  # pedal 0..1 -> bar
        ("ego", "steering_wheel_angle"): (("scenario", "steer"), -15.5 / degree),  # road-wheel rad -> wheel deg
        ("ego", "road_grip"): (("scenario", "mu_mean"), 1.0),  # one mu for the car: the mean of the four wheels
        ("scenario", "ego_x"): (("ego", "earth_x"), 1.0),
        ("scenario", "ego_y"): (("ego", "earth_y"), -1.0),  # y to the right -> y to the left
        ("scenario", "ego_psi"): (("ego", "heading_angle"), -degree),  # clockwise deg -> counter-clockwise rad
        ("scenario", "ego_v"): (("ego", "veh_speed"), 1 / 3.6),  # km/h -> m/s
        ("scenario", "ego_yaw_rate"): (("ego", "yaw_velocity"), -degree),  # clockwise deg/s -> rad/s
    }
    for end, (start, factor) in expected.items():
        got = found.pop(end)
        assert got[:2] == start and got[2] == pytest.approx(factor, rel=1e-15) and got[3] == 0.0, end
        assert got[4] == (factor != 1.0), end  # a transformation's conversion is never applied twice
    assert ("scenario", "ego_s") not in found  # the car has no distance output: the scenario FMU derives it
    assert found == {}


# ---- the stop time ----------------------------------------------------------------------------------------------


def test_the_stop_time_is_runs_end_and_a_margin_on_the_step_grid(demo):
    end = demo.reference.final["time_s"]  # 129.8 s: the margin is 1 % of it (more than 1 s)
    steps = round(demo.stop_time / demo.step)
    assert demo.stop_time == pytest.approx(steps * demo.step, abs=1e-12)
    assert (steps - 1) * demo.step < 1.01 * end <= steps * demo.step + 1e-9


def test_with_until_time_the_stop_time_is_that_time_on_the_grid_and_one_step(tmp_path, simple_fmu):
    export = api.export("demo", until_time=12.345, step=0.01, out=tmp_path / "t")
    assert export.stop_time == pytest.approx(12.36, abs=1e-12)


# ---- the export folder -------------------------------------------------------------------------------------------


def listing(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def test_new_empty_and_earlier_export_folders_are_written(tmp_path, simple_fmu):
    new = api.export("head_on", out=tmp_path / "a" / "b")
    assert sorted(p.name for p in new.folder.iterdir()) == sorted(
        [MANIFEST_NAME, "head_on.ssp", *(p.name for p in new.fmus.values())])
    empty = tmp_path / "empty"
    empty.mkdir()
    api.export("head_on", out=empty)
    again = api.export("head_on", out=empty, until_time=2.0)  # an earlier export folder: replaced
    assert float(ssd_root(again.ssp).find(f"{{{SSD}}}DefaultExperiment").get("stopTime")) == 2.01


@pytest.mark.parametrize("make, reason", [
    (lambda folder: (folder / "notes.txt").write_text("mine"), "did not write"),
    (lambda folder: api.run("head_on", until_time=1.0, out=folder, plot=False),
     r"holds a run's results \(sdl-fmu run\), which sdl-fmu export does not replace"),
], ids=["a user's file", "a run's results"])
def test_a_folder_holding_anything_else_is_refused_and_left_alone(tmp_path, simple_fmu, make, reason):
    folder = tmp_path / "out"
    folder.mkdir()
    make(folder)
    before = listing(folder)
    with pytest.raises(api.InputError, match=reason):
        api.export("head_on", out=folder)
    assert listing(folder) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_mistake_found_while_building_leaves_an_earlier_export_as_it_was(tmp_path, simple_fmu, foreign_vehicle):
    folder = tmp_path / "out"
    api.export("head_on", out=folder)
    before = listing(folder)
    fmu, vehicle_map = foreign_vehicle(2)
    broken = tmp_path / "no_start.toml"  # a map without [start]: export refuses it
    broken.write_text("\n".join(line for line in Path(vehicle_map).read_text().splitlines()
                                if not line.startswith(("[start]", "speed =", "x     =", "y     =", "yaw   ="))))
    with pytest.raises(api.InputError, match=r"no_start\.toml: start\.speed: missing"):
        api.export("head_on", fmu=fmu, vehicle=broken, out=folder)
    assert listing(folder) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["no_start.toml", "out"]


# ---- mistakes on the command line -----------------------------------------------------------------------------


MISTAKES = [
    (["export", "demo"], 2, "--out"),  # --out is required
    (["export", "demo", "--out", "{ws}/x", "--until-time", "3", "--until-distance", "4"], 2, "--until-distance"),
    (["export", "demo", "--out", "{ws}/x", "--fmi-version", "4"], 2, "--fmi-version"),
    (["export", "demo", "--out", "{ws}/x", "--step", "0"], 2, "--step"),
    (["export", "demo", "--out", "{ws}/x", "--step", "nan"], 2, "--step"),
    (["export", "demo", "--out", "{ws}/x", "--speed", "-1"], 2, "--speed"),
    (["export", "demo", "--out", "{ws}/x", "--until-time", "0"], 2, "--until-time"),
    (["export", "demo", "--out", "{ws}/x", "--seed", "-1"], 2, "--seed"),
    (["export", "demo", "--out", "{ws}/x", "--dynamics", "turbo"], 2, "--dynamics"),
    (["export", "demo", "--out", "{ws}/x", "--fmu", "{ws}/missing.fmu"], 2, "--fmu"),
    (["export", "demo", "--out", "{ws}/x", "--vehicle", "{ws}/missing.toml"], 2, "--vehicle"),
    (["export", "{ws}/bad.sdl", "--out", "{ws}/x"], 1, "bad.sdl:1"),
    (["export", "{ws}/missing.sdl", "--out", "{ws}/x"], 1, "missing.sdl"),
    (["export", "demo", "--out", "{ws}/users"], 2, "--out"),
    (["export", "demo", "--out", "{ws}/bad.sdl"], 2, "--out"),
    (["export", "demo", "--out", "/proc/sdl-fmu-export"], 2, "--out"),
]


@pytest.mark.parametrize("argv, code, needle", MISTAKES, ids=[" ".join(m[0][1:])[:60] for m in MISTAKES])
def test_every_mistake_is_one_line_and_writes_nothing(argv, code, needle, tmp_path, simple_fmu, monkeypatch, capsys):
    (tmp_path / "bad.sdl").write_text("10,XYZ\n")
    (tmp_path / "users").mkdir()
    (tmp_path / "users" / "thesis.tex").write_text("mine")
    monkeypatch.chdir(tmp_path)
    before = sorted(str(p) for p in tmp_path.rglob("*"))
    argv = [arg.format(ws=tmp_path) for arg in argv]
    assert main(argv) == code
    out, err = capsys.readouterr()
    assert out == "" and len(err.splitlines()) == 1 and needle.format(ws=tmp_path) in err, err
    assert "Traceback" not in err
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before


def test_the_command_says_where_the_ssp_is(tmp_path, simple_fmu, capsys):
    assert main(["export", "head_on", "--out", str(tmp_path / "out")]) == 0
    out, err = capsys.readouterr()
    assert str(tmp_path / "out" / "head_on.ssp") in out and "docs/export.md" in out and err == ""


# ---- a controller in the loop --------------------------------------------------------------------------------------

CCRS = "Metric\n// a stationary compact car 60 m ahead in the ego's lane\n0, A, 0, 60, *0, 1\n200, ES\n"


@pytest.fixture(scope="module")
def aeb(tmp_path_factory):
    """The foreign AEB controller (tests/controllers, PythonFMU, FMI 2.0) and a CCRs-like scenario."""
    folder = tmp_path_factory.mktemp("aeb")
    (folder / "ccrs.sdl").write_text(CCRS)
    return build_foreign_controller(folder, 2), folder / "ccrs.sdl"


def test_a_controller_is_a_third_component_connected_through_its_map(tmp_path, simple_fmu, aeb):
    fmu, ccrs = aeb
    export = api.export(ccrs, speed=50 / 3.6, until_time=8.0, controller=fmu, controller_map=FOREIGN_AEB_MAP,
                        out=tmp_path / "aeb")
    assert set(export.fmus) == {"scenario", "ego", "controller"} and export.fmus["controller"].name == fmu.name
    found = connections(export.ssp)
    expected = {  # end -> (start, factor): the controller map's conversions, composed with the vehicle map's for ego_v
        ("controller", "v_host"): (("ego", "v"), 3.6),  # m/s -> km/h
        ("controller", "obj_valid"): (("scenario", "lead_present"), 1.0),
        ("controller", "obj_id"): (("scenario", "lead_id"), 1.0),
        ("controller", "obj_distance"): (("scenario", "lead_gap"), 1.0),
        ("controller", "v_rel"): (("scenario", "lead_relative_speed"), 3.6),
        ("controller", "ttc_ms"): (("scenario", "lead_ttc"), 1000.0),  # s -> ms
        ("controller", "crash_count"): (("scenario", "collisions"), 1.0),
        ("scenario", "request_active"): (("controller", "aeb_active"), 1.0),
        ("scenario", "request_brake"): (("controller", "brake_cmd_pct"), 0.01),  # % -> pedal
    }
    for end, (start, factor) in expected.items():
        assert found[end][:2] == start and found[end][2] == pytest.approx(factor, rel=1e-15), end
    assert parameter_set(export.ssp, "controller") == {"ttc_trigger": ("Real", "1.5"), "cycle_time": ("Real", "0.01")}
    scenario = parameter_set(export.ssp, "scenario")  # the map's arbitration: brake max, throttle and steer driver
    assert (scenario["arbitration_brake"], scenario["arbitration_throttle"], scenario["arbitration_steer"]) == (
        ("Integer", "2"), ("Integer", "0"), ("Integer", "0"))
    assert "request_active" not in scenario  # the map has `active`


UNCONNECTABLE = {
    # an Integer signal into a Real variable
    "inputs.events": ('lead_ttc            = { variable = "ttc_ms", unit = "ms" }', 'events = { variable = "ttc_ms" }'),
    # a Boolean signal into a Real variable (run sends 1 or 0): an SSP connection joins connectors of one type
    "inputs.lead_present": ('lead_present        = { variable = "obj_valid" }\nlead_id             = { variable = '
                            '"obj_id" }\nlead_gap            = { variable = "obj_distance", unit = "m" }',
                            'lead_present        = { variable = "obj_distance" }'),
}


@pytest.mark.parametrize("key", UNCONNECTABLE)
def test_a_controller_map_the_ssp_cannot_connect_is_one_line_naming_its_key(tmp_path, simple_fmu, aeb, key, capsys):
    fmu, ccrs = aeb
    old, new = UNCONNECTABLE[key]
    assert old in FOREIGN_AEB_MAP.read_text()
    changed = tmp_path / "changed.toml"
    changed.write_text(FOREIGN_AEB_MAP.read_text().replace(old, new))
    assert main(["export", str(ccrs), "--controller", str(fmu), "--controller-map", str(changed),
                 "--out", str(tmp_path / "out")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"sdl-fmu: {changed}: {key}: ") and len(err.splitlines()) == 1, err
    assert not (tmp_path / "out").exists()


def test_the_driver_and_the_end_at_a_collision_are_the_scenario_fmus_options(tmp_path, simple_fmu):
    follow = api.export("head_on", driver="follow", out=tmp_path / "follow")
    assert parameter_set(follow.ssp, "scenario")["driver"] == ("Integer", "2")  # 1 lane, 2 follow
    stop = api.export("head_on", on_collision="stop", out=tmp_path / "stop")
    assert parameter_set(stop.ssp, "scenario")["on_collision_stop"] == ("Boolean", "true")
    contact = next(e for e in stop.reference.events if e["action"] == "collision")
    assert stop.reference.final["time_s"] == contact["time_s"]  # run's end, the stop time's base: the contact
    default = parameter_set(api.export("head_on", out=tmp_path / "lane").ssp, "scenario")
    assert default["driver"] == ("Integer", "1") and default["on_collision_stop"] == ("Boolean", "false")


def test_ctrl_c_during_an_export_exits_130_and_writes_nothing(tmp_path, simple_fmu):
    # the export's reference run is held at its first step (the test hook, sdl_fmu/hold.py: hostile_fmus.interrupted),
    # so the signal arrives mid-export however fast the machine is
    work = held_work(tmp_path)
    code, stdout, stderr = interrupted(work, ["export", "demo", "--out", work / "work" / "demo"], "ctrl-c")
    assert code == 130
    assert stderr.splitlines() == ["sdl-fmu: interrupted (Ctrl-C); nothing was written"] and stdout == ""
    assert list((work / "work").iterdir()) == []


def test_the_warnings_are_those_check_gives_and_the_mixed_fmi_versions(tmp_path, simple_fmus, capsys):
    # demo's BRK events with the Advanced ego: ignored, as run and check say, and the scenario FMU does the same
    advanced = api.export("demo", dynamics="advanced", until_time=1.0, out=tmp_path / "advanced")
    assert advanced.warnings == api.check("demo", dynamics="advanced").warnings and advanced.warnings
    # an FMI 3.0 ego in an FMI 2.0 system: written, with a warning that libcosim and fmpy cannot load it
    assert main(["export", "head_on", "--fmu", str(simple_fmus[3]), "--until-time", "1",
                 "--out", str(tmp_path / "mixed")]) == 0
    err = capsys.readouterr().err
    assert err.startswith("warning: the ego FMU EgoVehicleSimple.fmu is FMI 3.0 and the scenario FMU FMI 2.0") \
        and len(err.splitlines()) == 1, err
