"""The run side's vehicle model (sdl_fmu.vehicle): EgoModel built from an FMU's model description and a vehicle map,
the shipped FMUs (FMI 2.0 and 3.0) through their shipped maps, exactly as any FMU."""


import pytest

from sdl_fmu.vehicle import EgoModel, VehicleMapError, shipped_map_path, shipped_model

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
