"""The Simple FMU as a planar vehicle with side slip and yaw: split-mu braking, rear wheels that slide, steady
cornering against the linear bicycle model of the model's own cornering stiffnesses, and the friction circle. Loaded
for real through fmpy; every reference is computed here from the FMU's parameter defaults."""

import contextlib
import ctypes
import math
import shutil
from functools import partial

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Model

import helpers
from helpers import NO_RESISTANCES, WHEELS, G, input_table

simulate = partial(helpers.simulate, output=("psi", "yaw_rate", "vx", "vy", "ax", "ay", "s", "stopped"))


def steer_pulse(stop_time, angle, duration):
    """A steering input of `angle` for the first `duration` seconds, then straight ahead."""
    time = np.arange(0.0, stop_time + 1e-9, 0.01)
    return input_table(time, steer=np.where(time < duration, angle, 0.0))


@contextlib.contextmanager
def continuous_time_model(fmu, start, instance_name):
    """The FMU's model-exchange instance started from `start` ({name: value}) and in continuous-time mode, with its
    model description; terminated, freed and its unpacked folder removed afterwards."""
    description = read_model_description(str(fmu))
    directory = extract(str(fmu))
    model = FMU2Model(guid=description.guid, unzipDirectory=directory,
                      modelIdentifier=description.modelExchange.modelIdentifier, instanceName=instance_name)
    references = {v.name: v.valueReference for v in description.modelVariables}
    try:
        model.instantiate()
        model.setupExperiment(startTime=0.0)
        model.setReal([references[name] for name in start], list(start.values()))
        model.enterInitializationMode()
        model.exitInitializationMode()
        while model.newDiscreteStates()[0]:
            pass
        model.enterContinuousTimeMode()
        yield model, description
        model.terminate()
    finally:
        model.freeInstance()
        shutil.rmtree(directory, ignore_errors=True)


def initial_derivatives(fmu, start):
    """d(state)/dt at t = 0 through the FMU's model-exchange interface: {state name: derivative}."""
    with continuous_time_model(fmu, start, "derivatives") as (model, description):
        n = len(description.derivatives)
        values = (ctypes.c_double * n)()
        model.getDerivatives(values, n)
        names = [d.variable.derivative.name for d in description.derivatives]
    return dict(zip(names, values))


# --- split-mu braking -------------------------------------------------------------------------------------


def test_split_mu_braking_yaw_acceleration_from_the_force_imbalance(simple_fmu, defaults_simple):
    # Left wheels on mu 0.2, right on 0.8, full pedal (9.81 m/s2 > mu_i g: every wheel locks) at 20 m/s
    # straight ahead. Each wheel carries Fz = m g / 4 and slides against its contact point's velocity
    # (v0, 0): F_x,i = -mu_i m g / 4, F_y,i = 0. Left wheels at y = +t/2, right at -t/2:
    #   M_z = sum(-y_i F_x,i) = t m g (mu_left - mu_right) / 4,  dr/dt = M_z / I_z  (< 0: toward the right,
    #   the high-friction side),  dvx/dt = -(mu_left + mu_right) g / 2.
    # Read through model exchange at t = 0, so only round-off (1e-15) separates them: 1e-6 relative asked.
    p = defaults_simple
    mu_left, mu_right, v0 = 0.2, 0.8, 20.0
    start = {"v0": v0, "brake": 1.0, "mu_fl": mu_left, "mu_rl": mu_left, "mu_fr": mu_right, "mu_rr": mu_right,
             **NO_RESISTANCES}
    derivatives = initial_derivatives(simple_fmu, start)
    yaw_acceleration = p["track"] * p["mass"] * G * (mu_left - mu_right) / 4 / p["yaw_inertia"]
    print(f"dr/dt = {derivatives['yaw_rate']:.12f} rad/s2, expected {yaw_acceleration:.12f}")
    assert derivatives["yaw_rate"] == pytest.approx(yaw_acceleration, rel=1e-6)
    assert derivatives["vx"] == pytest.approx(-(mu_left + mu_right) * G / 2, rel=1e-6)
    assert derivatives["vy"] == 0.0

    # In time: yaws to the right from the first step (for the first second, before the rotation's own
    # friction can reverse it); with every wheel sliding nothing guides the car, so the imbalance turns
    # it past 90 degrees (a spin) before it stops; then it is held.
    result = simulate(simple_fmu, 6.0, start)
    first_second = (result["time"] > 0) & (result["time"] <= 1.0)
    assert np.all(result["yaw_rate"][first_second] < 0)
    assert result["psi"].min() < -math.pi / 2
    # it comes to rest (sliding and turning: held once its motion falls below STOP_SPEED) and stays there
    first = int(np.argmax(result["stopped"]))
    assert 0 < first and np.all(result["stopped"][first:]) and result["time"][-1] - result["time"][first] > 1.0
    assert np.ptp(result["s"][first:]) == 0 and np.ptp(result["psi"][first:]) == 0
    symmetric = simulate(simple_fmu, 1.0, {"v0": v0, "brake": 1.0, **NO_RESISTANCES})
    assert np.all(symmetric["yaw_rate"] == 0) and np.all(symmetric["psi"] == 0)


# --- the stop uses the whole planar motion ---------------------------------------------------------------------


def event_indicators_at(fmu, start, states):
    """The FMU's event indicators with its continuous states set to `states` ({name: value}, the others as
    initialised from `start`), through the model-exchange interface in continuous-time mode."""
    with continuous_time_model(fmu, start, "indicators") as (model, description):
        names = [d.variable.derivative.name for d in description.derivatives]
        x = (ctypes.c_double * len(names))()
        model.getContinuousStates(x, len(names))
        for name, value in states.items():
            x[names.index(name)] = value
        model.setContinuousStates(x, len(names))
        z = (ctypes.c_double * description.numberOfEventIndicators)()
        model.getEventIndicators(z, len(z))
    return list(z)


def test_the_stop_indicator_reads_the_whole_planar_motion(simple_fmu, defaults_simple):
    # Indicator 0 of a moving car is > 0 while it stays moving and crosses 0 where it is held. With every wheel
    # rolling forward (the start) it is max(vx, m_side - STOP_SPEED), m_side = sqrt(vy^2 + (r L / 2)^2): a car with
    # vx = 0 that slides sideways or turns is still moving (its kinetic energy m vy^2 / 2 or Iz r^2 / 2 is not 0);
    # one whose sideways motion is below STOP_SPEED = 0.01 m/s is held at vx = 0, the exact forward stop. No
    # pedal: the drive cannot hold it going (drive_excess < 0), so the indicator is the motion's term alone.
    from sdl_fmu.dynamics.simple import STOP_SPEED

    half = defaults_simple["wheelbase"] / 2
    start = {"v0": 10.0, **NO_RESISTANCES}
    for states, expected in [({"vx": 0.0, "vy": 5.0}, 5.0 - STOP_SPEED),
                             ({"vx": 0.0, "yaw_rate": 2.0}, 2.0 * half - STOP_SPEED),
                             ({"vx": -0.5, "vy": 3.0, "yaw_rate": -1.0}, math.hypot(3.0, half) - STOP_SPEED),
                             ({"vx": 0.0, "vy": 0.5 * STOP_SPEED}, 0.0),  # held: sideways motion below STOP_SPEED
                             ({"vx": 4.0, "vy": 0.0}, 4.0)]:
        indicator = event_indicators_at(simple_fmu, start, {"vx": 0.0, "vy": 0.0, "yaw_rate": 0.0, **states})[0]
        print(states, indicator)
        assert indicator == pytest.approx(expected, rel=1e-12, abs=1e-12) if expected > 0 else indicator <= 0


@pytest.mark.parametrize("pedal", [0.65, 0.70, 0.75])
def test_a_sliding_car_is_not_held_while_it_moves(simple_fmu, defaults_simple, pedal):
    # Split friction 0.8 left / 0.2 right, 100 km/h straight ahead, a pedal that locks the low-friction wheels
    # (pedal 9.81 > 0.2 g) and not the high-friction ones (< 0.8 g = 7.85 m/s2): the car yaws, spins and slides
    # sideways on its braked, rolling left wheels. At every communication step the FMU must run to the stop and
    # hold the car only once it has (almost) no motion left:
    # 1. a lower bound on the stop, whatever the car does: each wheel's force is at most (mu_i + f_r) m g / 4
    #    (rolling, held or locked), so |a| <= A + K v^2 with A = (mu_mean + f_r) g and drag K = rho CdA / (2 m);
    #    the speed of the centre of gravity falls no faster (d|v|/dt = v.a / |v| >= -|a|), so the path length s
    #    (ds/dt = |v|) to the stop is at least ln(1 + K v0^2 / A) / (2K) (75.2 m; the old held the car at 40 m);
    # 2. at a 1 ms step, the last sample before the stop moves at most STOP_SPEED + h max d(motion)/dt, motion =
    #    sqrt(vx^2 + vy^2 + (r L / 2)^2): d|v|/dt <= |a| and (L / 2) dr/dt <= (L / 2) sum |F_i| |p_i| / Iz, |p_i| the
    #    wheels' distance from the centre of gravity (bounded with A and v0: the drag term only shrinks);
    # 3. the stop is an event located inside the step: 0.1, 0.01 and 0.001 s give the same stop. They differ by
    #    the solver's error control only, whose internal steps each doStep's end cuts differently: the local error
    #    on s is at most 1e-8 (|s| + 100 m) < 1.8e-6 m per internal step, over a few hundred steps: 1e-3 m.
    from sdl_fmu.dynamics.simple import STOP_SPEED

    p = defaults_simple
    v0 = 100 / 3.6
    start = {"v0": v0, "brake": pedal, "mu_fl": 0.8, "mu_rl": 0.8, "mu_fr": 0.2, "mu_rr": 0.2}
    a_max = ((0.8 + 0.2) / 2 + p["rolling_resistance"]) * G
    k = p["air_density"] * p["drag_area"] / (2 * p["mass"])
    shortest = math.log(1 + k * v0**2 / a_max) / (2 * k)
    assert shortest == pytest.approx(75.2, abs=0.1)
    half, track = p["wheelbase"] / 2, p["track"]
    turning = a_max * p["mass"] * math.hypot(half, track / 2) * half / p["yaw_inertia"]
    stops = {}
    for step in (0.1, 0.01, 0.001):
        result = helpers.simulate(simple_fmu, 7.0, start, step=step, output=("s", "vx", "vy", "yaw_rate", "stopped"))
        first = int(np.argmax(result["stopped"]))
        assert result["stopped"][first] and np.all(result["stopped"][first:])
        stops[step] = result["s"][first]
        if step == 0.001:
            before = result[first - 1]
            motion = math.sqrt(before["vx"] ** 2 + before["vy"] ** 2 + (before["yaw_rate"] * half) ** 2)
            print(f"pedal {pedal}: motion {motion:.4f} m/s one sample before the stop")
            assert motion <= STOP_SPEED + step * (a_max + turning)
    print(f"pedal {pedal}: stops {stops} (at least {shortest:.2f} m)")
    assert min(stops.values()) >= shortest
    assert max(stops.values()) - min(stops.values()) <= 1e-3


# --- rear wheels that slide --------------------------------------------------------------------------------


def sideslip(result):
    return np.arctan2(result["vy"], result["vx"])


def test_car_whose_rear_wheels_slide_under_braking_spins(simple_fmu, defaults_simple):
    # Rear wheels on ice (mu 0.1), fronts on 0.8, 30 % pedal: the rear brake demand 0.3 * 9.81 = 2.94 m/s2
    # exceeds 0.1 g = 0.98 m/s2, so the rears lock and lose all lateral guidance, the fronts (limit 7.8)
    # roll and steer. With rear cornering stiffness C_r = 0 the linear bicycle model is unstable at any
    # speed: its stability condition C_f C_r L^2 / (m v^2) + b C_r - a C_f > 0 (Milliken & Milliken, RCVD
    # ch. 5) reads -a C_f < 0. A 0.2 s steering pulse of 0.02 rad is enough: the car spins (side slip
    # beyond 90 degrees). The same pulse with dry rear wheels dies out (understeer: stable).
    start = {"v0": 25.0, "brake": 0.3, "mu_rl": 0.1, "mu_rr": 0.1, **NO_RESISTANCES}
    pulse = steer_pulse(6.0, 0.02, 0.2)
    icy = simulate(simple_fmu, 6.0, start, inputs=pulse)
    dry = simulate(simple_fmu, 6.0, {**start, "mu_rl": 0.8, "mu_rr": 0.8}, inputs=pulse)
    print(f"rear on ice: max |psi| {np.abs(icy['psi']).max():.3f} rad, max |beta| {np.abs(sideslip(icy)).max():.3f}; "
          f"dry: {np.abs(dry['psi']).max():.4f} rad, {np.abs(sideslip(dry)).max():.4f}")
    assert np.abs(sideslip(icy)).max() > math.pi / 2
    assert np.abs(icy["psi"]).max() > math.pi
    # dry: the pulse turns the car by about v delta t / (L + K v^2) = 25 * 0.02 * 0.2 / 5.2 = 0.02 rad
    assert np.abs(dry["psi"]).max() < 0.05 and np.abs(sideslip(dry)).max() < 0.01


def test_turn_past_the_limit_with_less_grip_at_the_rear_spins(simple_fmu):
    # Steer 0.15 rad at 20 m/s asks for far more than mu g of lateral acceleration. With mu 0.8 all round the
    # fronts saturate first (C_f < C_r at equal loads: understeer) and the car circles with a small side
    # slip. With mu 0.4 at the rear, the rear saturates at 0.4 m g / 2 while the fronts give up to
    # 0.8 m g / 2: the yaw moment a F_yf - b F_yr (a = b) stays positive, the yaw rate grows and the car
    # spins instead of following a circle.
    start = {"v0": 20.0, "steer": 0.15, **NO_RESISTANCES}
    understeer = simulate(simple_fmu, 5.0, start)
    oversteer = simulate(simple_fmu, 5.0, {**start, "mu_rl": 0.4, "mu_rr": 0.4})
    print(f"max |beta|: mu_rear 0.8 {np.abs(sideslip(understeer)).max():.3f}, "
          f"0.4 {np.abs(sideslip(oversteer)).max():.3f}")
    assert np.abs(sideslip(understeer)).max() < 0.2
    assert np.abs(sideslip(oversteer)).max() > math.pi / 2


# --- below the limit: the linear bicycle model ---------------------------------------------------------------


@pytest.mark.parametrize("speed", [10.0, 25.0])
def test_steady_cornering_matches_linear_bicycle_model(simple_fmu, defaults_simple, speed):
    # Linear bicycle model (Milliken & Milliken, RCVD ch. 5; Gillespie ch. 6): in steady state
    #   r / delta = v / (L + K_us v^2),  K_us = (m / L) (b / C_f - a / C_r),
    # with the axle stiffnesses C = 2 x the FMU's per-wheel cornering stiffness and a = b = L / 2.
    p = defaults_simple
    m, wheelbase = p["mass"], p["wheelbase"]
    c_front, c_rear = 2 * p["cornering_stiffness_front"], 2 * p["cornering_stiffness_rear"]
    half = wheelbase / 2
    understeer = m / wheelbase * (half / c_front - half / c_rear)
    lateral_acceleration = 0.5  # m/s2, far below mu g
    steer = lateral_acceleration * (wheelbase + understeer * speed**2) / speed**2
    result = simulate(simple_fmu, 5.0, {"v0": speed, "steer": steer, **NO_RESISTANCES}, step=0.1)
    # the steered fronts' lateral force slows the car by ~1e-4 v per second: compare the gain at the
    # current speed
    vx = result["vx"]
    linear_gains = vx / (wheelbase + understeer * vx**2)
    relative = result["yaw_rate"] / steer / linear_gains - 1
    assert abs(relative[-1] - relative[-11]) < 1e-6  # settled
    # Tolerance: the linear model is the first-order expansion of the FMU's equations in the small
    # quantities delta (cos/sin of the steer), the slip angles alpha (tan alpha vs alpha), v_low / v (the
    # slip's speed floor) and r t / (2 v) (left and right wheels at different speeds); what it leaves out
    # is of second order in them, bounded by the sum of their squares.
    yaw_rate = result["yaw_rate"][-1]
    alpha_front = m * lateral_acceleration / 2 / c_front
    second_order = steer**2 + alpha_front**2 + (0.1 / speed) ** 2 + (yaw_rate * p["track"] / (2 * speed)) ** 2
    print(f"v = {speed}: relative error {relative[-1]:.2e}, second-order bound {second_order:.2e}")
    assert abs(relative[-1]) <= second_order
    assert second_order < 1e-3  # the reference is meaningful: the test runs in the linear range


def test_understeer_gradient_of_the_defaults_is_a_passenger_cars(defaults_simple):
    # K_us = (m / 4)(1 / C_f - 1 / C_r) per wheel stiffnesses at a = b; passenger cars: 2-5 deg/g
    # (Gillespie, Fundamentals of Vehicle Dynamics, ch. 6).
    p = defaults_simple
    gradient = p["mass"] / 4 * (1 / p["cornering_stiffness_front"] - 1 / p["cornering_stiffness_rear"])
    assert 2.0 <= math.degrees(gradient * G) <= 5.0


# --- the friction circle -------------------------------------------------------------------------------------


def test_friction_circles_bound_the_acceleration(simple_fmu):
    # Each wheel's force |F_i| <= mu Fz_i (rolling: the lateral force is clamped to what the longitudinal
    # force leaves; sliding: exactly mu Fz), so |a| = |sum F_i| / m <= mu g. With drag and rolling
    # resistance off nothing else acts. The floor 1e-12 N^2 under the circle's square root adds at most
    # 1e-6 N per wheel: 1e-9 relative covers it. Steer 0.3 rad at 20 m/s demands ~45 m/s2: the limit is
    # reached (>= 95 % of mu g: the rear axle's force is not quite aligned with the front's).
    mu = 0.6
    start = {"v0": 20.0, "steer": 0.3, **{f"mu_{w}": mu for w in WHEELS}, **NO_RESISTANCES}
    result = simulate(simple_fmu, 3.0, start)
    magnitude = np.hypot(result["ax"], result["ay"])
    print(f"max |a| / (mu g) = {magnitude.max() / (mu * G):.12f}")
    assert magnitude.max() <= mu * G * (1 + 1e-9)
    assert magnitude.max() >= 0.95 * mu * G


# --- numerics ---------------------------------------------------------------------------------------------


def test_jacobian_is_finite_at_standstill_low_speed_and_in_a_spin():
    # The solver factorises I / (h gamma) - J every step: J must be finite wherever a run can go, including
    # exact rest (after the stop event), contact points passing through zero velocity and either direction.
    from sdl_fmu.dynamics import simple

    equations = simple.equations()
    functions = equations.functions()
    interface = equations.interface
    states, inputs, discrete = (interface.names(role) for role in ("state", "input", "discrete"))
    parameters = np.array([v.start for v in interface.of_role("parameter")], dtype=float)
    rng = np.random.default_rng(1)
    for stopped in (0, 1):
        for direction in (-1, 1):
            for brake in (0.0, 0.05, 1.0):
                for speed in (0.0, 1e-12, 1e-6, 1e-3, 0.05, 3.0, 30.0):
                    for turning in (0.0, 1.0):
                        x = np.zeros(len(states))
                        x[states.index("vx")] = speed * rng.uniform(-1, 1)
                        x[states.index("vy")] = speed * rng.uniform(-1, 1) * turning
                        x[states.index("yaw_rate")] = speed * rng.uniform(-1, 1) * turning
                        d = np.array([stopped] + [direction] * (len(discrete) - 1), dtype=float)
                        u = np.zeros(len(inputs))
                        u[inputs.index("brake")], u[inputs.index("steer")] = brake, rng.uniform(-0.5, 0.5)
                        for w in WHEELS:
                            u[inputs.index(f"mu_{w}")] = rng.choice([0.0, 0.1, 0.8])
                        for name in ("derivatives", "jacobian", "event_indicators", "outputs", "discrete_update"):
                            values = functions[name](x, d, u, parameters)
                            values = values if isinstance(values, (list, tuple)) else [values]
                            assert all(np.all(np.isfinite(np.array(v))) for v in values), (name, x, d, u)
