"""The run side's vehicle model (sdl_fmu.vehicle): EgoModel built from an FMU's model description and a vehicle map,
the shipped FMUs (FMI 2.0 and 3.0) through their shipped maps, exactly as any FMU."""


import pytest

from sdl_fmu.shipped import shipped_model
from sdl_fmu.vehicle import EgoModel, VehicleMapError, shipped_map_path

from helpers import G


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_shipped_simple_model_describes_its_fmu(simple_fmus, fmi_version):
    model = EgoModel.open(simple_fmus[fmi_version], shipped_map_path("simple"))
    assert model.fmi_version == f"{fmi_version}.0" and model.can_roll_back and model.brk_acts
    assert model.friction.meaning == "mu" and model.friction.variables == ("mu_fl", "mu_fr", "mu_rl", "mu_rr")
    p = model.parameters
    # the Simple FMU has its CG midway between the axles and one track: contact points at (+-L/2, +-t/2)
    half_l, half_t = p["wheelbase"] / 2, p["track"] / 2
    assert model.wheels == ((half_l, half_t), (half_l, -half_t), (-half_l, half_t), (-half_l, -half_t))
    assert (model.length, model.width) == (p["length"], p["width"])


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_shipped_advanced_model_places_its_cg(advanced_fmus, fmi_version):
    model = EgoModel.open(advanced_fmus[fmi_version], shipped_map_path("advanced"))
    p = model.parameters
    assert model.wheelbase == p["cg_to_front_axle"] + p["cg_to_rear_axle"]
    assert model.wheels[2] == (-p["cg_to_rear_axle"], p["track_rear"] / 2)
    assert not model.brk_acts and model.friction.meaning == "attribute"
    # the drive is a wheel torque: a = T / (m R)
    assert model.drive_accel_max == p["drive_torque_max"] / (p["mass"] * p["wheel_radius"])
    # the friction bound comes from the tire slots the FMU has (8), not from a guessed count
    assert model.tire_slot_numbers() == list(range(8))


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_shipped_simple_brakes_to_its_closed_form(simple_fmus, fmi_version):
    """Straight braking, drag and rolling resistance off: a = min(brake * brake_decel_max, mu g), so the car
    stops after v0 / a seconds and v0^2 / (2 a) metres. The FMU's solver tolerance 1e-10 on a piecewise-constant
    deceleration leaves the stop instant within 1e-6 s of the closed form (the bisection locates it to 1e-9 s)."""
    from sdl_fmu.cosim.ego import step_until

    model = EgoModel.open(simple_fmus[fmi_version], shipped_map_path("simple"))
    v0, brake, mu = 20.0, 0.5, 0.8
    with model.instantiate(start={"speed": v0, "x": 0.0, "y": 0.0, "yaw": 0.0},
                           parameters={"drag_area": 0.0, "rolling_resistance": 0.0}) as ego:
        ego.set_controls(0.0, brake, 0.0)
        ego.set_friction((mu,) * 4)
        a = min(brake * model.parameters["brake_decel_max"], mu * G)
        while not step_until(ego, 0.5, lambda state: state.stopped, 1e-9):
            pass
        state = ego.read()
    assert state.time == pytest.approx(v0 / a, abs=1e-6)
    assert state.s == pytest.approx(v0**2 / (2 * a), abs=1e-5)


def test_fmi3_build_steps_as_the_fmi2_build(simple_fmus):
    """The two builds share one C model: the same inputs give the same outputs, bit for bit."""
    states = []
    for version in (2, 3):
        with shipped_model("simple", version).instantiate(start={"speed": 25.0, "y": -1.8}) as ego:
            ego.set_controls(0.2, 0.0, 0.02)
            ego.set_friction((0.8, 0.8, 0.4, 0.4))
            snapshot = ego.save()
            ego.step_to(2.0)
            first = ego.read()
            ego.restore(snapshot)
            ego.step_to(2.0)
            assert ego.read() == first  # rolled back and stepped again: the same state
            ego.discard(snapshot)
            states.append(first)
    assert states[0] == states[1]


def test_a_map_variable_the_fmu_lacks_is_named(simple_fmu, tmp_path):
    text = shipped_map_path("simple").read_text().replace('variable = "steer"', 'variable = "steering_angle"')
    (tmp_path / "map.toml").write_text(text)
    with pytest.raises(VehicleMapError, match=r"map\.toml: inputs\.steer: .*no variable 'steering_angle'"):
        EgoModel.open(simple_fmu, tmp_path / "map.toml")


# ---- the vehicle owns its data: FMU start values and tire slots, checked and applied by the model -------------------

def test_parameters_are_checked_by_the_model_and_its_properties_follow(simple_fmu):
    model = EgoModel.open(simple_fmu, shipped_map_path("simple"))
    heavier = model.with_parameters({"mass": 1800.0})
    assert (heavier.mass, heavier.overrides, model.mass) == (1800.0, {"mass": 1800.0}, model.parameters["mass"])
    for params, subject in (({"mass": 0.0}, "mass=0.0: below the declared minimum 1 kg of mass"),
                            ({"mass": float("nan")}, "mass=nan: the value must be a finite number"),
                            ({"mass": "heavy"}, "mass=heavy: the value must be a number (SI units)"),
                            ({"stopped": 1.0}, "stopped=1.0: EgoVehicleSimple.fmu has no parameter 'stopped'")):
        with pytest.raises(VehicleMapError) as caught:
            model.with_parameters(params)
        # an option and a subject, which the API and the command line word their way
        assert (caught.value.option, caught.value.subject.split(" (parameters:")[0]) == ("params", subject)
        assert str(caught.value) == f"params {caught.value.subject}"
        assert caught.value.command_line() == f"--param {caught.value.subject}"


def test_the_parameter_list_names_the_tire_slots_by_the_maps_rule(simple_fmu, advanced_fmu, tmp_path):
    def listed(model) -> list[str]:
        with pytest.raises(VehicleMapError) as caught:
            model.with_parameters({"nope": 1.0})
        return caught.value.subject.split("(parameters: ")[1].rstrip(")").split(", ")

    simple = listed(EgoModel.open(simple_fmu, shipped_map_path("simple")))
    assert "mass" in simple and not [name for name in simple if name.startswith("tire")]  # no slots: none shown
    advanced = listed(EgoModel.open(advanced_fmu, shipped_map_path("advanced")))
    assert "wheel_spin" in advanced and advanced[-1] == "tire<slot>_<KEY>"
    assert not [name for name in advanced[:-1] if name.startswith("tire")]  # the 8 x 35 slot parameters: one pattern
    # a map that declares no tire slots: the FMU's tire... parameters are its own, each listed
    text = shipped_map_path("advanced").read_text().replace(', tire_slots = "tire{slot}_"', "")
    (tmp_path / "no_slots.toml").write_text(text)
    own = listed(EgoModel.open(advanced_fmu, tmp_path / "no_slots.toml"))
    assert "tire0_PDX1" in own and "tire7_LYKA" in own and not [name for name in own if "<" in name]


def test_integer_parameters_are_settable_whole_and_within_their_range(advanced_fmu):
    model = EgoModel.open(advanced_fmu, shipped_map_path("advanced"))
    variable = model.variables["wheel_spin"]
    assert variable.type == "Integer" and (variable.min, variable.max) == ("0", "2")
    for value, reason in ((1.5, "wheel_spin is Integer: the value must be a whole number"),
                          (3, "above the declared maximum 2 of wheel_spin"),
                          (-1.0, "below the declared minimum 0 of wheel_spin")):
        with pytest.raises(VehicleMapError, match=reason):
            model.with_parameters({"wheel_spin": value})
    quasi_static = model.with_parameters({"wheel_spin": 2.0})  # --param gives floats: a whole one is taken
    assert quasi_static.overrides == {"wheel_spin": 2} and isinstance(quasi_static.overrides["wheel_spin"], int)
    with quasi_static.instantiate(start={"speed": 10.0}) as ego:
        assert ego.slave.getInteger([variable.valueReference]) == [2]  # it reached the FMU


def test_tire_slots_are_filled_on_the_run_side_by_the_maps_prefix(advanced_fmu, tmp_path):
    from sdl_fmu.dynamics.tires import slot_parameters
    from sdl_fmu.tire_files import SLOT_KEYS, slot_parameter

    model = EgoModel.open(advanced_fmu, shipped_map_path("advanced")).with_tires()
    prefix = model.friction.tire_slots
    assert set(model.overrides) == {slot_parameter(prefix, k, key) for k in range(8) for key in SLOT_KEYS}
    # the same start values the build side gave the FMU from the same file, named by the same rule
    assert model.overrides == slot_parameters()[0] and model.known_attributes == {0, 1, 2, 3, 4}
    # a map whose prefix the FMU does not have: named, with the key
    text = shipped_map_path("advanced").read_text().replace('tire_slots = "tire{slot}_"', 'tire_slots = "tire{slot}"')
    (tmp_path / "other.toml").write_text(text)
    with pytest.raises(VehicleMapError, match=r"other\.toml: inputs\.friction\.tire_slots: the FMU "
                                              r"EgoVehicleAdvanced\.fmu has no tire slot parameter 'tire0FNOMIN'"):
        EgoModel.open(advanced_fmu, tmp_path / "other.toml").with_tires()
    with pytest.raises(VehicleMapError) as caught:
        EgoModel.open(advanced_fmu, shipped_map_path("advanced")).with_tires(tmp_path / "missing.txt")
    assert caught.value.option == "tires" and "missing.txt" in str(caught.value)


def test_vehicle_errors_carry_an_option_and_a_subject_not_a_flag(tmp_path):
    from sdl_fmu.vehicle import load_vehicle_map, read_description

    for error, option in ((lambda: read_description(tmp_path / "nowhere.fmu"), "fmu"),
                          (lambda: load_vehicle_map(tmp_path / "nowhere.toml"), "vehicle")):
        with pytest.raises(VehicleMapError) as caught:
            error()
        assert caught.value.option == option and caught.value.subject.endswith("nowhere" + (
            ".fmu" if option == "fmu" else ".toml") + ": no such file")
        assert "--" not in str(caught.value) and caught.value.command_line().startswith(f"--{option} ")


def test_the_top_speed_is_the_closed_form_of_the_drive_against_the_resistances(simple_fmu):
    """Full throttle on a level road: m min(a_max, P / (m v)) = m g f_r + m K v^2 (K = rho CdA / (2 m)). Where the
    power limit binds, K m v^3 + g f_r m v - P = 0, the depressed cubic v^3 + p v + q = 0 with p = g f_r / K,
    q = -P / (K m), whose one real root is Cardano's (p > 0); where the force limit binds, v = sqrt((a_max - g f_r) /
    K). The model bisects to machine precision: agreement to 1e-12."""
    model = EgoModel.open(simple_fmu, shipped_map_path("simple"))
    p_, m, f_r, k = (model.drive_power_max, model.mass, model.rolling_resistance, model.drag_factor)
    p, q = G * f_r / k, -p_ / (k * m)
    root = (q * q / 4 + p**3 / 27) ** 0.5
    cardano = (-q / 2 + root) ** (1 / 3) - (q / 2 + root) ** (1 / 3)
    assert model.drive_accel_max > p_ / (m * cardano)  # the power limit binds at the top speed
    assert model.top_speed() == pytest.approx(cardano, rel=1e-12)
    assert cardano == pytest.approx(61.3834, abs=1e-4)  # 201.4 ft/s with the Simple FMU's defaults
    strong = model.with_parameters({"drive_power_max": 1e7})  # now the force limit binds
    assert strong.top_speed() == pytest.approx(((strong.drive_accel_max - G * f_r) / k) ** 0.5, rel=1e-12)
    assert model.with_parameters({"drag_area": 0.0, "rolling_resistance": 0.0}).top_speed() == float("inf")


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_a_discarded_snapshot_of_an_sdl_fmu_build_is_reused_and_restores_exactly(simple_fmus, fmi_version):
    """sdl-fmu's runtime updates a snapshot given to GetFMUstate in place (FMI allows it): a discarded snapshot is
    kept and taken again by the next save (the master saves one per step near traffic: no allocation each time),
    and restoring it after it was reused gives the state of its second save, bit for bit."""
    with shipped_model("simple", fmi_version).instantiate(start={"speed": 25.0, "y": -1.8}) as ego:
        ego.set_controls(0.2, 0.0, 0.02)
        first = ego.save()
        ego.discard(first)
        ego.step_to(1.0)
        second = ego.save()
        assert second[0] is first[0]  # the same FMU state handle, updated in place
        at_one = ego.read()
        ego.step_to(2.0)
        ego.restore(second)
        assert ego.read() == at_one
        ego.discard(second)


def test_another_tools_snapshots_are_freed_not_reused(simple_fmus):
    """Another tool's FMU may not update a given snapshot in place: its snapshots are freed on discard and every
    save asks for a new one (the rule reads the model description's generationTool: here the Simple FMU's,
    renamed)."""
    import copy

    model = EgoModel.open(simple_fmus[2], shipped_map_path("simple"))
    model.description = copy.copy(model.description)
    model.description.generationTool = "another tool 1.0"
    with model.instantiate(start={"speed": 10.0, "x": 0.0, "y": 0.0, "yaw": 0.0}) as ego:
        first = ego.save()
        ego.discard(first)
        second = ego.save()
        assert second[0] is not first[0]
        ego.discard(second)
