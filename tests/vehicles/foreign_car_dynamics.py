"""The foreign car's equations: a vehicle model sdl-fmu did not design, packaged by PythonFMU (FMI 2.0) and
pythonfmu3 (FMI 3.0) at test time (foreign_car_fmi2.py, foreign_car.py). Plain Python, no sdl-fmu import.

It speaks SAE J670 rather than ISO 8855: earth axes x forward, y to the RIGHT, heading and yaw velocity
positive CLOCKWISE (turning right), steering-wheel angle positive to the right. Its own units: pedal in percent,
brake line pressure in bar, steering-wheel angle in degrees through a steering ratio, speed in km/h, heading in
degrees. It has no path-length output and cannot get or set its state.

Equations (SI inside; the interface converts):
    road-wheel angle   delta = radians(steering_wheel_angle) / steering_ratio
    slip at the CG     beta = atan(tan(delta) / 2)              (kinematic bicycle, CG mid-wheelbase)
    x' = v cos(psi + beta),  y' = v sin(psi + beta),  psi' = v cos(beta) tan(delta) / wheel_base
    grip force         F_grip  = road_grip * vehicle_mass * G
    drive force        F_drive = min(accel_pedal / 100 * min(max_tractive_force, max_engine_power / max(v, 1 m/s)),
                                     F_grip)
    brake force        F_brake = min(brake_gain * brake_pressure, F_grip)
    v' = (F_drive - F_brake) / m - roll_coeff * G - air_rho * cd_a / (2 m) * v^2     while v > 0
At rest (v = 0) the car stays at rest unless F_drive > F_brake + roll_coeff m G; it never rolls backwards.
Integration: classical Runge-Kutta 4 with fixed sub-steps of at most rk4_step inside each communication
step; a sub-step in which braking would carry v below 0 ends the motion at the stop instant v / |v'| taken
with the deceleration at the sub-step's start (exact for constant deceleration; drag changes it by K v^2 / A, below
1e-7 for the sub-step's speeds), and the car then holds.
"""

from __future__ import annotations

from math import atan, ceil, cos, radians, sin, tan, degrees

G = 9.80665  # m/s2

# name: (start, unit, description). Units are the FMU's own; FMI 3.0 declares them in UnitDefinitions.
INPUTS = {
    "accel_pedal": (0.0, "%", "accelerator pedal travel, 0..100 %"),
    "brake_pressure": (0.0, "bar", "brake line pressure, 0.. bar"),
    "steering_wheel_angle": (0.0, "deg", "steering-wheel angle, positive to the right (SAE)"),
    "road_grip": (0.8, "1", "tyre-road friction coefficient under the car"),
}
PARAMETERS = {
    "vehicle_mass": (1450.0, "kg", "mass"),
    "wheel_base": (2.7, "m", "wheel base"),
    "steering_ratio": (15.5, "1", "steering-wheel angle per road-wheel angle"),
    "max_tractive_force": (5800.0, "N", "largest drive force at full pedal"),
    "max_engine_power": (95000.0, "W", "largest drive power at full pedal"),
    "brake_gain": (100.0, "N/bar", "brake force per bar of line pressure"),
    "roll_coeff": (0.011, "1", "rolling-resistance coefficient"),
    "cd_a": (0.68, "m2", "drag coefficient times frontal area"),
    "air_rho": (1.2, "kg/m3", "air density"),
    "rk4_step": (0.002, "s", "largest Runge-Kutta 4 sub-step"),
    "v_init": (0.0, "km/h", "initial speed along the heading"),
    "x_init": (0.0, "m", "initial earth x (forward)"),
    "y_init": (0.0, "m", "initial earth y (SAE: to the right)"),
    "heading_init": (0.0, "deg", "initial heading (SAE: clockwise)"),
}
OUTPUTS = {
    "earth_x": (0.0, "m", "CG position, earth x (forward)"),
    "earth_y": (0.0, "m", "CG position, earth y (SAE: to the right)"),
    "heading_angle": (0.0, "deg", "heading (SAE: clockwise)"),
    "veh_speed": (0.0, "km/h", "speed of the CG"),
    "yaw_velocity": (0.0, "deg/s", "yaw velocity (SAE: clockwise)"),
    "long_accel": (0.0, "m/s2", "rate of change of the speed"),
}
# the FMU's unit names as multiples of SI base units: (factor, {base unit: exponent}), for FMI 3 UnitDefinitions
UNITS = {
    "%": (0.01, {}),
    "bar": (1e5, {"kg": 1, "m": -1, "s": -2}),
    "deg": (0.017453292519943295, {"rad": 1}),
    "deg/s": (0.017453292519943295, {"rad": 1, "s": -1}),
    "km/h": (1 / 3.6, {"m": 1, "s": -1}),
    "kg": (1.0, {"kg": 1}),
    "m": (1.0, {"m": 1}),
    "N": (1.0, {"kg": 1, "m": 1, "s": -2}),
    "W": (1.0, {"kg": 1, "m": 2, "s": -3}),
    "N/bar": (1e-5, {"m": 2}),
    "m2": (1.0, {"m": 2}),
    "kg/m3": (1.0, {"kg": 1, "m": -3}),
    "s": (1.0, {"s": 1}),
    "m/s2": (1.0, {"m": 1, "s": -2}),
}


def defaults(car) -> None:
    """Sets every interface variable of `car` to its start value."""
    for table in (INPUTS, PARAMETERS, OUTPUTS):
        for name, (start, _, _) in table.items():
            setattr(car, name, start)


def initialise(car) -> None:
    """The state from the initial-value parameters; the outputs from the state."""
    car.state = [car.x_init, car.y_init, radians(car.heading_init), max(car.v_init / 3.6, 0.0)]
    _publish(car, _derivatives(car, car.state, _forces(car)))


def _forces(car):
    """Everything that stays constant over a communication step (inputs and parameters)."""
    m = car.vehicle_mass
    delta = radians(car.steering_wheel_angle) / car.steering_ratio
    beta = atan(tan(delta) / 2)
    grip = max(car.road_grip, 0.0) * m * G
    pedal = min(max(car.accel_pedal, 0.0), 100.0) / 100
    brake = min(car.brake_gain * max(car.brake_pressure, 0.0), grip)
    return (m, beta, cos(beta) * tan(delta) / car.wheel_base, grip, pedal, brake,
            car.roll_coeff * G, car.air_rho * car.cd_a / (2 * m))


def _derivatives(car, state, forces):
    m, beta, curvature, grip, pedal, brake, rolling, drag = forces
    _, _, psi, v = state
    drive = min(pedal * min(car.max_tractive_force, car.max_engine_power / max(v, 1.0)), grip)
    if v > 0:
        dv = (drive - brake) / m - rolling - drag * v * v
    else:
        dv = max((drive - brake) / m - rolling, 0.0)
    return (v * cos(psi + beta), v * sin(psi + beta), v * curvature, dv)


def advance(car, step_size: float) -> None:
    """Integrates the equations over one communication step with the inputs held."""
    forces = _forces(car)
    n = max(1, ceil(step_size / car.rk4_step - 1e-9))
    h = step_size / n
    state = car.state
    derivative = _derivatives(car, state, forces)
    for _ in range(n):
        k1 = derivative
        s2 = [a + 0.5 * h * b for a, b in zip(state, k1)]
        k2 = _derivatives(car, s2, forces)
        s3 = [a + 0.5 * h * b for a, b in zip(state, k2)]
        k3 = _derivatives(car, s3, forces)
        s4 = [a + h * b for a, b in zip(state, k3)]
        k4 = _derivatives(car, s4, forces)
        new = [a + h / 6 * (b1 + 2 * b2 + 2 * b3 + b4) for a, b1, b2, b3, b4 in zip(state, k1, k2, k3, k4)]
        if state[3] > 0 and (new[3] <= 0 or min(s2[3], s3[3], s4[3]) < 0):
            # the car stops inside this sub-step: end the motion at the stop instant, then hold
            v, dv = state[3], k1[3]
            tau = min(v / -dv, h) if dv < 0 else h
            x, y, psi, _ = state
            travelled = v * tau / 2
            new = [x + travelled * cos(psi + forces[1]), y + travelled * sin(psi + forces[1]),
                   psi + travelled * forces[2], 0.0]
        state = new
        derivative = _derivatives(car, state, forces)
    car.state = state
    _publish(car, derivative)


def _publish(car, derivative) -> None:
    x, y, psi, v = car.state
    car.earth_x = x
    car.earth_y = y
    car.heading_angle = degrees(psi)
    car.veh_speed = v * 3.6
    car.yaw_velocity = degrees(derivative[2])
    car.long_accel = derivative[3]
