"""The foreign car (tests/vehicles): a vehicle FMU built at test time by PythonFMU (FMI 2.0) and pythonfmu3 (FMI 3.0)
from its own Python equations, with names, units and axes unlike sdl-fmu's. Here it is checked on its own, through
fmpy, against the closed forms of its equations (foreign_car_dynamics.py's docstring); test_foreign_vehicle_runs.py
drives it through SDL scenarios."""

import math
import tomllib

import numpy as np
import pytest

from helpers import WEAK_PARAMETERS, FmpyCar, foreign_parameters

G = 9.80665  # the car's own g (foreign_car_dynamics.G), the standard value
OUTPUTS = {"earth_x", "earth_y", "heading_angle", "veh_speed", "yaw_velocity", "long_accel"}
# RK4 (2 ms sub-steps) on these smooth equations has a truncation error far below 1e-12 (h^4 = 1.6e-11 times
# derivatives of order 1e-2 or less); what remains is rounding, about 1e-16 per operation over some 1e4 sub-steps
# on values below 100: 1e-10. The tolerances below take 1e-9 (m, m/s).
RK4_TOLERANCE = 1e-9


def shipped_names() -> set[str]:
    """Every variable name of sdl-fmu's two FMUs (their interface files; tire slots as tire0_.., tire7_..)."""
    import json

    from sdl_fmu.paths import MODEL_DESCRIPTION_DIRECTORY

    names = set()
    for model in ("EgoVehicleSimple", "EgoVehicleAdvanced"):
        interface = json.loads((MODEL_DESCRIPTION_DIRECTORY / f"{model}.json").read_text())
        for entry in interface["variables"]:
            if "repeat" in entry:
                repeat = entry["repeat"]
                names |= {v["name"].replace(f"{{{repeat['placeholder']}}}", str(k))
                          for v in entry["variables"] for k in range(repeat["count"])}
            else:
                names.add(entry["name"])
    return names


@pytest.mark.slow  # the tests that build the FMUs with PythonFMU / pythonfmu3
@pytest.mark.parametrize("fmi_version", [2, 3])
def test_foreign_car_has_its_own_interface(foreign_vehicle, fmi_version):
    from fmpy import read_model_description

    fmu, _ = foreign_vehicle(fmi_version)
    description = read_model_description(str(fmu))
    assert description.fmiVersion == f"{fmi_version}.0"
    assert description.coSimulation is not None and description.modelExchange is None
    assert not description.coSimulation.canGetAndSetFMUstate
    assert description.coSimulation.canHandleVariableCommunicationStepSize
    names = {v.name for v in description.modelVariables}
    assert not names & shipped_names()  # not one name in common with sdl-fmu's own FMUs
    assert {v.name for v in description.modelVariables if v.causality == "output"} == OUTPUTS  # no path length
    units = {v.name: v.declaredType.unit if v.declaredType else v.unit for v in description.modelVariables}
    if fmi_version == 3:
        assert (units["accel_pedal"], units["brake_pressure"], units["steering_wheel_angle"]) == ("%", "bar", "deg")
        assert (units["veh_speed"], units["heading_angle"], units["yaw_velocity"]) == ("km/h", "deg", "deg/s")
        definitions = {u.name: u.baseUnit for u in description.unitDefinitions}
        assert definitions["km/h"].factor == pytest.approx(1 / 3.6, rel=1e-15) and definitions["km/h"].m == 1
        assert definitions["bar"].factor == 1e5 and definitions["deg"].rad == 1
    else:
        assert not description.unitDefinitions and not any(units.values())  # PythonFMU declares none


def braking_closed_form(parameters, pressure, mu, v0):
    """Straight braking without throttle, from the car's equations:
        v' = -(A + K v^2),  A = min(brake_gain p, mu m G) / m + roll_coeff G,  K = air_rho cd_a / (2 m).
    Separating variables, atan(v sqrt(K/A)) falls linearly at the rate sqrt(A K):
        v(t) = sqrt(A/K) tan(theta0 - sqrt(A K) t),  theta0 = atan(v0 sqrt(K/A)),  stop at t_stop = theta0 / sqrt(A K);
    with v dv/ds = -(A + K v^2) the distance is s(v) = ln((A + K v0^2) / (A + K v^2)) / (2 K)."""
    m = parameters["vehicle_mass"]
    A = min(parameters["brake_gain"] * pressure, mu * m * G) / m + parameters["roll_coeff"] * G
    K = parameters["air_rho"] * parameters["cd_a"] / (2 * m)
    theta0 = math.atan(v0 * math.sqrt(K / A))
    t_stop = theta0 / math.sqrt(A * K)

    def speed(t):
        return math.sqrt(A / K) * math.tan(theta0 - math.sqrt(A * K) * t) if t < t_stop else 0.0

    def distance(t):
        return math.log((A + K * v0**2) / (A + K * speed(t) ** 2)) / (2 * K)

    return speed, distance, t_stop


@pytest.mark.slow
@pytest.mark.parametrize("fmi_version", [2, 3])
@pytest.mark.parametrize("pressure, mu", [(60.0, 0.8), (120.0, 0.8), (120.0, 0.2)],
                         ids=["pressure-limited", "grip-limited", "ice"])
def test_foreign_car_brakes_as_its_closed_form(foreign_vehicle, fmi_version, pressure, mu):
    fmu, _ = foreign_vehicle(fmi_version)
    parameters = foreign_parameters(fmu)
    v0 = 100 / 3.6
    speed, distance, t_stop = braking_closed_form(parameters, pressure, mu, v0)
    car = FmpyCar(fmu, {"v_init": 100.0})
    car.set(brake_pressure=pressure, road_grip=mu)
    h = 0.05  # communication step; the car sub-steps it by its own rk4_step
    try:
        while car.time < t_stop + 2.0:  # beyond the stop: it must stay where it stopped
            car.step(h)
            x, y, heading, v_kmh = car.get("earth_x", "earth_y", "heading_angle", "veh_speed")
            assert v_kmh / 3.6 == pytest.approx(speed(car.time), abs=RK4_TOLERANCE)
            assert x == pytest.approx(distance(car.time), abs=RK4_TOLERANCE)
            assert y == 0.0 and heading == 0.0
    finally:
        car.close()
    assert v_kmh == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("fmi_version", [2, 3])
def test_foreign_car_turns_right_for_a_positive_steering_wheel_angle(foreign_vehicle, fmi_version):
    """SAE axes: a positive (right) steering-wheel angle turns the car clockwise, to +y. Without drag and rolling
    resistance the speed stays v, so the kinematic bicycle's CG runs on a circle:
        delta = radians(swa) / ratio, beta = atan(tan(delta) / 2), r = psi' = v cos(beta) tan(delta) / L,
        x' = v cos(r t + beta), y' = v sin(r t + beta)
        => x = (v / r) (sin(r t + beta) - sin(beta)),  y = (v / r) (cos(beta) - cos(r t + beta))."""
    fmu, _ = foreign_vehicle(fmi_version)
    parameters = foreign_parameters(fmu)
    v, swa = 10.0, 90.0
    delta = math.radians(swa) / parameters["steering_ratio"]
    beta = math.atan(math.tan(delta) / 2)
    r = v * math.cos(beta) * math.tan(delta) / parameters["wheel_base"]
    car = FmpyCar(fmu, {"v_init": v * 3.6, "roll_coeff": 0.0, "cd_a": 0.0})
    car.set(steering_wheel_angle=swa)
    try:
        for _ in range(50):
            car.step(0.1)
        x, y, heading, rate, v_kmh = car.get("earth_x", "earth_y", "heading_angle", "yaw_velocity", "veh_speed")
    finally:
        car.close()
    t = car.time
    assert rate == pytest.approx(math.degrees(r), rel=1e-12) and rate > 0
    assert heading == pytest.approx(math.degrees(r * t), abs=RK4_TOLERANCE)
    assert x == pytest.approx(v / r * (math.sin(r * t + beta) - math.sin(beta)), abs=RK4_TOLERANCE)
    assert y == pytest.approx(v / r * (math.cos(beta) - math.cos(r * t + beta)), abs=RK4_TOLERANCE) and y > 0
    assert v_kmh == pytest.approx(v * 3.6, abs=1e-12)


@pytest.mark.slow
def test_weak_foreign_car_cannot_reach_100_kmh(foreign_vehicle, tmp_path):
    """The weak variant (its map's [parameters]) caps the drive power at P. At full pedal above P / max_tractive_force
    the equations give a(v) = P / (m v) - roll_coeff G - K v^2, zero at the top speed v_top, the positive root of
    K v^3 + roll_coeff G v - P / m = 0. Below v_top a > 0, so v rises towards v_top and never passes it; with
    lambda = min over [0, v_top) of a(v) / (v_top - v), the gap obeys gap' <= -lambda gap, so after T seconds from
    rest v >= v_top (1 - exp(-lambda T))."""
    from sdl_fmu.vehicle import EgoModel

    fmu, map_path = foreign_vehicle(3, weak=True)
    with open(map_path, "rb") as file:
        assert tomllib.load(file)["parameters"] == WEAK_PARAMETERS
    # the run side sees the cap too: the driver model's power limit comes from the FMU parameter the map sets
    assert EgoModel.open(fmu, map_path).drive_power_max == WEAK_PARAMETERS["max_engine_power"]
    parameters = {**foreign_parameters(fmu), **WEAK_PARAMETERS, "rk4_step": 0.01}
    m, power = parameters["vehicle_mass"], parameters["max_engine_power"]
    K = parameters["air_rho"] * parameters["cd_a"] / (2 * m)
    rolling = parameters["roll_coeff"] * G
    v_top = max(root.real for root in np.roots([K, 0.0, rolling, -power / m]) if abs(root.imag) < 1e-12)
    assert v_top < 100 / 3.6
    v = np.linspace(0.0, v_top, 100001)[:-1]
    drive = np.minimum(parameters["max_tractive_force"], power / np.maximum(v, 1.0))
    lam = np.min((drive / m - rolling - K * v**2) / (v_top - v))
    car = FmpyCar(fmu, {**WEAK_PARAMETERS, "rk4_step": 0.01})
    car.set(accel_pedal=100.0)
    speeds = []
    try:
        for _ in range(400):
            car.step(1.0)
            speeds.append(car.get("veh_speed")[0] / 3.6)
    finally:
        car.close()
    assert np.all(np.diff(speeds) > 0) and max(speeds) < v_top
    assert speeds[-1] >= v_top * (1 - math.exp(-lam * 400.0)) - RK4_TOLERANCE
    assert v_top * 3.6 == pytest.approx(84.7, abs=0.05)  # the figure helpers.WEAK_PARAMETERS quotes


@pytest.mark.slow
@pytest.mark.parametrize("fmi_version", [2, 3])
def test_foreign_car_through_its_map_speaks_iso_si(foreign_vehicle, fmi_version):
    """Through its vehicle map (sdl_fmu.vehicle) the SAE car reads in sdl-fmu's ISO 8855 SI frame. A road-wheel
    angle delta > 0 (left) goes to the FMU as -15.5 degrees(delta) of steering wheel (right-negative), so the car
    turns left: in ISO axes (y left, yaw counter-clockwise) the kinematic bicycle's CG, at constant speed (drag and
    rolling resistance off), follows
        beta = atan(tan(delta) / 2), r = v cos(beta) tan(delta) / L,
        psi = r t, x = (v / r) (sin(r t + beta) - sin(beta)), y = y0 + (v / r) (cos(beta) - cos(r t + beta)).
    The distance the car lacks is derived by the trapezoid rule over the speed, exact for a constant speed: v t."""
    from sdl_fmu.vehicle import EgoModel

    fmu, map_path = foreign_vehicle(fmi_version)
    model = EgoModel.open(fmu, map_path)
    assert not model.can_roll_back and model.wheelbase == 2.7 and model.mass == 1450.0
    v, delta, y0 = 15.0, 0.05, -1.8288
    beta = math.atan(math.tan(delta) / 2)
    r = v * math.cos(beta) * math.tan(delta) / model.wheelbase
    with model.instantiate(start={"speed": v, "x": 0.0, "y": y0, "yaw": 0.0},
                           parameters={"roll_coeff": 0.0, "cd_a": 0.0}) as ego:
        ego.set_controls(0.0, 0.0, delta)
        ego.set_friction((0.8,) * 4)
        for k in range(1, 31):
            ego.step_to(0.1 * k)
        state = ego.read()
    t = state.time
    assert state.v == pytest.approx(v, abs=1e-12) and state.s == pytest.approx(v * t, abs=1e-9)
    assert state.psi == pytest.approx(r * t, abs=RK4_TOLERANCE) and state.psi > 0
    assert state.yaw_rate == pytest.approx(r, rel=1e-12)
    assert state.x == pytest.approx(v / r * (math.sin(r * t + beta) - math.sin(beta)), abs=RK4_TOLERANCE)
    assert state.y == pytest.approx(y0 + v / r * (math.cos(beta) - math.cos(r * t + beta)), abs=RK4_TOLERANCE)
    assert state.y > y0 and not state.stopped


def test_the_docs_show_the_foreign_car_map_as_it_is():
    """The vehicle-map document's complete map example for a foreign FMU is the test suite's map, key for key."""
    from helpers import FOREIGN_CAR_MAP

    docs = (FOREIGN_CAR_MAP.parents[2] / "docs" / "vehicle-maps.md").read_text()
    section = docs[docs.index("## A vehicle built elsewhere: the test suite's foreign car"):]
    block = section[section.index("```toml\n") + len("```toml\n"):]
    block = block[:block.index("```")]
    with open(FOREIGN_CAR_MAP, "rb") as file:
        assert tomllib.loads(block) == tomllib.load(file)
