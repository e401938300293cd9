"""The Advanced ego FMU (two-track vehicle on Magic Formula tires), loaded through fmpy, against analytic
references computed here from the FMU's own parameters (its tire slots come from scenarios/tires/)."""

import itertools
import math
from functools import partial

import casadi as ca
import numpy as np
import pytest

from sdl_fmu.dynamics import advanced

import helpers
from helpers import NO_RESISTANCES, WHEELS, G, input_table

ICE = 3  # attribute of ice in scenarios/tires/attributes.txt
simulate = partial(helpers.simulate, output=("s", "vx", "y", "psi", "yaw_rate", "stopped"))


# --- Magic Formula, written out again from Pacejka (MF 5.2, no shifts, no camber) ------------------------


def tire(parameters, slot=0):
    key_start = f"tire{slot}_"
    return {name[len(key_start):]: value for name, value in parameters.items() if name.startswith(key_start)}


def load_increment(c, fz):
    fz0 = c["FNOMIN"] * c["LFZO"]
    return fz0, (fz - fz0) / fz0


def longitudinal_force(c, fz, kappa):
    """Pure-slip Fx = D sin(C atan(B k - E (B k - atan(B k)))), D = mux Fz, B = Kx / (C D)."""
    _, dfz = load_increment(c, fz)
    mu = abs(c["PDX1"] + c["PDX2"] * dfz) * c["LMUX"]
    shape, peak = c["PCX1"], mu * fz
    curvature = min(c["PEX1"] + c["PEX2"] * dfz + c["PEX3"] * dfz**2, 1.0)
    stiffness = fz * abs(c["PKX1"] + c["PKX2"] * dfz) * math.exp(c["PKX3"] * dfz) * c["LKX"]
    bk = stiffness / (shape * peak) * kappa
    return peak * math.sin(shape * math.atan(bk - curvature * (bk - math.atan(bk))))


def peak_longitudinal_friction(c, fz):
    return abs(c["PDX1"] + c["PDX2"] * load_increment(c, fz)[1]) * c["LMUX"]


def cornering_stiffness(c, fz):
    """K_y = B C D = |PKY1| Fz0 sin(2 atan(Fz / (PKY2 Fz0))) LKY (N/rad)."""
    fz0, _ = load_increment(c, fz)
    return abs(c["PKY1"]) * fz0 * math.sin(2 * math.atan(fz / (c["PKY2"] * fz0))) * c["LKY"]


def lateral_force(c, fz, alpha):
    """Magnitude of the pure-slip Fy at slip angle alpha > 0."""
    _, dfz = load_increment(c, fz)
    shape, peak = c["PCY1"], abs(c["PDY1"] + c["PDY2"] * dfz) * c["LMUY"] * fz
    curvature = min(c["PEY1"] + c["PEY2"] * dfz, 1.0)
    ba = cornering_stiffness(c, fz) / (shape * peak) * alpha
    return peak * math.sin(shape * math.atan(ba - curvature * (ba - math.atan(ba))))


def bisect(function, low, high, iterations=200):
    for _ in range(iterations):
        middle = 0.5 * (low + high)
        if function(low) * function(middle) <= 0:
            high = middle
        else:
            low = middle
    return 0.5 * (low + high)


def geometry(p):
    a, b = p["cg_to_front_axle"], p["cg_to_rear_axle"]
    wheelbase = a + b
    return a, b, wheelbase, p["mass"] * G * b / (2 * wheelbase), p["mass"] * G * a / (2 * wheelbase)


# --- steady-state cornering -------------------------------------------------------------------------


def secant_stiffnesses(p, c, lateral_acceleration):
    """Front and rear axle secant stiffnesses F / alpha in steady cornering at a_y: the axle force m_axle a_y
    shared by its two tires under the lateral load transfer dFz = m a_y h k / track (k: roll stiffness share),
    each on its Magic Formula curve."""
    m = p["mass"]
    a, b, wheelbase, fz_front, fz_rear = geometry(p)

    def secant(fz, axle_mass, share, track):
        force = axle_mass * lateral_acceleration
        transfer = m * lateral_acceleration * p["cg_height"] * share / track
        alpha = bisect(lambda al: lateral_force(c, fz + transfer, al) + lateral_force(c, fz - transfer, al) - force,
                       0.0, 0.2)
        return force / alpha

    k_front = p["roll_stiffness_front_share"]
    return (secant(fz_front, m * b / wheelbase, k_front, p["track_front"]),
            secant(fz_rear, m * a / wheelbase, 1 - k_front, p["track_rear"]))


def understeer_gradient(p, c_front, c_rear):
    """K_us = (m / L)(b / C_f - a / C_r) + D_f m b / L (rad per m/s2): axle stiffnesses and compliance steer."""
    m = p["mass"]
    a, b, wheelbase, _, _ = geometry(p)
    return m / wheelbase * (b / c_front - a / c_rear) + p["steer_compliance"] * m * b / wheelbase


def test_understeer_gradient_is_a_passenger_cars(advanced_fmu, defaults_advanced):
    # Passenger cars: 2-5 deg/g. Source: characteristic speeds v_ch = sqrt(L / K_us) of passenger cars of
    # about 65-100 km/h (M. Mitschke, H. Wallentowitz, Dynamik der Kraftfahrzeuge, 4th ed., Springer 2004,
    # ch. on steady-state cornering), i.e. K_us = L / v_ch^2 = 1.9-4.7 deg/g at L = 2.7 m.
    # The tires alone give ~0.6 deg/g (their cornering stiffness is nearly proportional to load); the
    # front lateral-force compliance steer (Gillespie, Fundamentals of Vehicle Dynamics, ch. 6) adds D_f m b / L.
    # Measured in steady state at a_y <= 3 m/s2 (constant speed test, ISO 4138): K = (delta - L r / v) / a_y.
    p, c = defaults_advanced, tire(defaults_advanced)
    a, b, wheelbase, fz_front, fz_rear = geometry(p)
    linear = understeer_gradient(p, 2 * cornering_stiffness(c, fz_front), 2 * cornering_stiffness(c, fz_rear))
    speed = 20.0
    for lateral_acceleration in (1.0, 3.0):
        steer = lateral_acceleration * (wheelbase + linear * speed**2) / speed**2
        result = simulate(advanced_fmu, 6.0, {"v0": speed, "steer": steer, **NO_RESISTANCES}, step=0.1)
        vx, yaw_rate = result["vx"][-1], result["yaw_rate"][-1]
        measured = (steer - wheelbase * yaw_rate / vx) / (vx * yaw_rate)
        # Tolerance: the tire curvature and load transfer at this a_y (secant stiffnesses), doubled as in the
        # bicycle-model test above
        secant = understeer_gradient(p, *secant_stiffnesses(p, c, vx * yaw_rate))
        print(f"a_y {vx * yaw_rate:.3f} m/s2: K = {math.degrees(measured * G):.3f} deg/g, linear "
              f"{math.degrees(linear * G):.3f}, with secant stiffnesses {math.degrees(secant * G):.3f}")
        assert abs(measured - linear) <= 2 * abs(secant - linear)
        assert 2.0 <= math.degrees(measured * G) <= 5.0
    assert 2.0 <= math.degrees(linear * G) <= 5.0



@pytest.mark.parametrize("speed", [10.0, 25.0])
def test_steady_state_cornering_matches_linear_bicycle_model(advanced_fmu, defaults_advanced, speed):
    # Linear bicycle model (Milliken & Milliken, RCVD ch. 5; Gillespie ch. 6): in steady state
    #   delta = L / R + K_us a_y,  a_y = v r,  R = v / r   =>   r / delta = v / (L + K_us v^2),
    #   K_us = m_f / C_f - m_r / C_r + D_f m_f = (m / L) (b / C_f - a / C_r) + D_f m b / L,
    # with axle cornering stiffness C = 2 B C D = 2 K_y(Fz) at the static wheel load Fz and the front
    # lateral-force compliance steer D_f (steer_compliance, rad per N of front axle force m_f a_y;
    # Gillespie, Fundamentals of Vehicle Dynamics, ch. 6).
    p, c = defaults_advanced, tire(defaults_advanced)
    m = p["mass"]
    a, b, wheelbase, fz_front, fz_rear = geometry(p)
    c_front, c_rear = 2 * cornering_stiffness(c, fz_front), 2 * cornering_stiffness(c, fz_rear)
    compliance = p["steer_compliance"] * m * b / wheelbase
    understeer = m / wheelbase * (b / c_front - a / c_rear) + compliance
    lateral_acceleration = 0.5  # m/s2
    steer = lateral_acceleration * (wheelbase + understeer * speed**2) / speed**2

    result = simulate(advanced_fmu, 6.0, {"v0": speed, "steer": steer, **NO_RESISTANCES}, step=0.1)
    # the cornering drag slows the car by ~1e-4 v per second: compare with the gain at the current speed
    vx, yaw_rate = result["vx"], result["yaw_rate"]
    linear_gains = vx / (wheelbase + understeer * vx**2)
    relative = yaw_rate / steer / linear_gains
    assert abs(relative[-1] - relative[-11]) < 1e-5  # settled
    gain, linear_gain, vx = yaw_rate[-1] / steer, linear_gains[-1], vx[-1]

    # Tolerance: what the linear model leaves out at this a_y. Each axle's secant stiffness F / alpha, with
    # the Magic Formula's curvature and the lateral load transfer dFz = m a_y h k / track (k: roll stiffness
    # share), is lower than its C by eps = 1 - F / (C alpha); the bicycle gain with those secant stiffnesses
    # differs from the linear one by d_nl. Allowed: 2 |d_nl| (the rest, e.g. two-track kinematics, is
    # smaller); the solver's error (< 1e-9) does not count.
    s_front, s_rear = secant_stiffnesses(p, c, lateral_acceleration)
    nonlinear_gain = vx / (wheelbase + (m / wheelbase * (b / s_front - a / s_rear) + compliance) * vx**2)
    nonlinearity = abs(nonlinear_gain / linear_gain - 1)
    error = gain / linear_gain - 1
    print(f"v = {speed} m/s: r/delta = {gain:.6f} 1/s, linear {linear_gain:.6f}, relative error {error:.2e}, "
          f"nonlinearity {nonlinearity:.2e}")
    assert abs(error) <= 2 * nonlinearity
    assert 0 < nonlinearity < 1e-3  # the reference is meaningful: a_y is small


# --- braking -------------------------------------------------------------------------------------------


def test_locked_wheel_braking_matches_sliding_friction(advanced_fmu, defaults_advanced):
    # Brake torque far above what the tires can carry: the wheels lock at once and each tire slides at
    # kappa = -1 with Fx = mu_slide(Fz) Fz (Magic Formula at kappa = -1). No load transfer (cg_height 0),
    # no drag, no rolling resistance: constant deceleration a = sum Fx / m = mu_slide g, so
    # s = v0^2 / (2 mu_slide g).
    # The tire is the measured one of Pacejka's Table A3.1 (the shipped surfaces scale its friction and
    # shape: LMUX, LMUY, PCX1): the lock-up bound (3.) assumes the solver resolves the spin-down, which
    # takes ~0.1 ms at this brake torque; with the dry-surface scaling B = Kx / (C D) is 1.7 x steeper
    # and a fixed 1 ms solver step would need 1e-5 s to resolve it (measured error then -0.43 mm, in budget).
    # The default error-controlled step resolves the spin-down with steps as short as it needs.
    measured = {"tire0_LMUX": 1.0, "tire0_LMUY": 1.0, "tire0_PCX1": 1.685}
    p = {**defaults_advanced, **measured}
    c = tire(p)
    m, v0 = p["mass"], 20.0
    _, _, _, fz_front, fz_rear = geometry(p)
    sliding = -2 * (longitudinal_force(c, fz_front, -1.0) + longitudinal_force(c, fz_rear, -1.0))
    mu_slide = sliding / (m * G)
    reference = v0**2 / (2 * mu_slide * G)
    brake_decel_max = 1e4
    start = {"v0": v0, "brake": 1.0, "brake_decel_max": brake_decel_max, "cg_height": 0.0, **NO_RESISTANCES,
             **measured}
    distance = simulate(advanced_fmu, 4.0, start)["s"][-1]

    # Error budget (all terms shorten the stop), from the model's definitions:
    # 1. slip floor: kappa = -v / sqrt(v^2 + v_low^2) nears the friction peak below ~1 m/s:
    #    ds = integral over v of v (1 / a(v) - 1 / a_slide) dv;
    # 2. the stop is declared at STOP_SPEED: ds = -v_stop^2 / (2 a(v_stop));
    # 3. lock-up: each wheel spins down in t = I omega0 / (T_brake - mu_peak Fz R), taking at most
    #    (mu_peak + mu_slide) Fz more than sliding meanwhile: ds <= v0 dp / (m a_slide).
    def deceleration(v):
        kappa = -v / math.hypot(v, advanced.SLIP_SPEED_FLOOR)
        return -2 * (longitudinal_force(c, fz_front, kappa) + longitudinal_force(c, fz_rear, kappa)) / m

    a_slide = sliding / m
    speeds = np.geomspace(advanced.STOP_SPEED, v0, 20001)
    floor = np.trapezoid([v * (1 / deceleration(v) - 1 / a_slide) for v in speeds], speeds)
    stop = -advanced.STOP_SPEED**2 / (2 * deceleration(advanced.STOP_SPEED))
    omega0, radius = v0 / p["wheel_radius"], p["wheel_radius"]
    lock_momentum = 0.0
    for fz, share in ((fz_front, p["brake_front_share"]), (fz_rear, 1 - p["brake_front_share"])):
        torque = share * brake_decel_max * m * radius / 2
        lock_time = p["wheel_inertia"] * omega0 / (torque - peak_longitudinal_friction(c, fz) * fz * radius)
        lock_momentum += 2 * (peak_longitudinal_friction(c, fz) * fz + longitudinal_force(c, fz, -1.0)) * lock_time
    lock = -v0 * lock_momentum / (m * a_slide)
    budget = floor + stop + lock
    error = distance - reference
    print(f"mu_slide {mu_slide:.6f}: distance {distance:.6f} m, reference {reference:.6f} m, error {error:.2e} m; "
          f"budget: slip floor {floor:.2e}, stop {stop:.2e}, lock-up >= {lock:.2e}")
    assert budget - 1e-6 <= error <= 1e-6
    assert abs(budget) < 1e-4 * reference  # the reference is the point, not the budget


def test_full_braking_on_dry_asphalt_stops_between_sliding_and_peak_distances(advanced_fmu, defaults_advanced):
    # Without ABS the stop lies between the locked-wheel distance v0^2 / (2 mu_slide g) and the ideal
    # v0^2 / (2 mu_peak g). Both coefficients vary with the wheel load (PDX2 etc.), so the bounds use the
    # most favourable values over the loads the load transfer can produce (decelerations up to mu_peak g).
    p, c = defaults_advanced, tire(defaults_advanced)
    m, v0 = p["mass"], 20.0
    _, _, wheelbase, fz_front, fz_rear = geometry(p)
    transfer = m * 1.3 * G * p["cg_height"] / (2 * wheelbase)
    loads = np.linspace(max(fz_rear - transfer, 1.0), fz_front + transfer, 200)
    mu_peak = max(peak_longitudinal_friction(c, fz) for fz in loads)
    mu_slide = min(-longitudinal_force(c, fz, -1.0) / fz for fz in loads)
    shortest, longest = v0**2 / (2 * mu_peak * G), v0**2 / (2 * mu_slide * G)
    distance = simulate(advanced_fmu, 5.0, {"v0": v0, "brake": 1.0, **NO_RESISTANCES})["s"][-1]
    print(f"distance {distance:.4f} m in [{shortest:.4f}, {longest:.4f}] (mu_peak {mu_peak:.4f}, "
          f"mu_slide {mu_slide:.4f})")
    assert shortest < distance < longest


def test_split_mu_braking_yaws_toward_the_high_friction_side(advanced_fmu):
    # Left wheels on ice, right wheels on dry asphalt, full brake: the right tires brake harder, so the
    # yaw moment sum(-y_i Fx_i) with y_right < 0 and Fx < 0 is negative (ISO 8855: clockwise, to the right).
    start = {"v0": 20.0, "brake": 1.0, "surface_fl": ICE, "surface_rl": ICE}
    result = simulate(advanced_fmu, 0.5, start, step=0.01)
    assert np.all(result["yaw_rate"][1:] < 0)
    assert result["psi"][-1] < -0.01
    symmetric = simulate(advanced_fmu, 0.5, {"v0": 20.0, "brake": 1.0}, step=0.01)
    assert np.all(np.abs(symmetric["yaw_rate"]) < 1e-9)


def test_locked_steered_wheels_do_not_steer_the_car(advanced_fmu):
    # Brake torque of 10 g: all four wheels lock within a few ms; fronts steered +0.1 rad. A locked tire
    # slides against its contact point's velocity (sliding_blend), so the steered fronts push straight back
    # like the rears: no lateral force, no yaw moment, and the car keeps its heading up to the stop (held
    # to +-1 deg; MF 5.2's combined-slip weighting alone turned it by -14 deg).
    start = {"v0": 20.0, "brake": 1.0, "brake_decel_max": 100.0, "steer": 0.1}
    result = simulate(advanced_fmu, 5.0, start, output=("psi", "vx", "stopped", *(f"wheel_mode_{w}" for w in WHEELS)))
    locking = result["time"] < 0.05
    assert all(np.all(result[f"wheel_mode_{w}"][~locking] == 0) for w in WHEELS)  # locked (or held at rest)
    assert result["stopped"][-1]
    print(f"max |heading| {math.degrees(np.abs(result['psi']).max()):.4f} deg")
    assert math.degrees(np.abs(result["psi"]).max()) <= 1.0


def wheel_force_function(c):
    """The FMU's wheel force equations for one tire (advanced.wheel_forces) as a numeric function of
    (Fz, contact velocity along and across the wheel, omega R)."""
    fz, along, across, surface = (ca.SX.sym(n) for n in ("fz", "along", "across", "surface"))
    fx, fy, _, _ = advanced.wheel_forces(c, fz, along, across, surface)
    return ca.Function("wheel", [fz, along, across, surface], [fx, fy])


def test_pure_slip_forces_are_magic_formula_5_2(defaults_advanced):
    # Pure longitudinal slip (no lateral velocity) and pure lateral slip (free rolling, omega R = v_cx): the
    # FMU's forces equal the Magic Formula written out again above, at the model's slips
    # kappa = (omega R - u) / sqrt(u^2 + v_low^2), alpha = atan(w / sqrt(u^2 + v_low^2)). Same formula, so
    # only round-off separates them: 1e-12 relative.
    c = tire(defaults_advanced)
    forces = wheel_force_function(c)
    floor = advanced.SLIP_SPEED_FLOOR
    for fz in (2000.0, 4000.0, 6000.0):
        for u in (2.0, 20.0):
            for surface in (0.0, 0.5 * u, 0.9 * u, 0.98 * u, u, 1.05 * u, 1.5 * u):
                kappa = (surface - u) / math.hypot(u, floor)
                fx, fy = (float(value) for value in forces(fz, u, 0.0, surface))
                assert fx == pytest.approx(longitudinal_force(c, fz, kappa), rel=1e-12, abs=1e-9)
                assert fy == 0.0
            for angle in (0.005, 0.05, 0.2, 0.6):
                across = u * math.tan(angle)
                alpha = math.atan(across / math.hypot(u, floor))
                fx, fy = (float(value) for value in forces(fz, u, across, u))
                assert fy == pytest.approx(-lateral_force(c, fz, alpha), rel=1e-12)
                assert fx == 0.0


def test_a_sliding_tire_pushes_against_its_sliding_velocity(defaults_advanced):
    # Locked (omega = 0) at slip angle beta: the sliding velocity is the contact velocity (u, w). The force
    # turns toward -(u, w) with weight lambda = s^4, s = |V_s| / sqrt(u^2 + w^2 + v_low^2) = 1 - 1.25e-5 at
    # 20 m/s, so its angle to -(u, w) is at most (1 - lambda) x the MF 5.2 force's angle = 5e-5 x beta.
    # At small combined slip (kappa, alpha ~ 0.02) lambda = s^4 ~ 1e-6: F is MF 5.2 to that order.
    c = tire(defaults_advanced)
    forces = wheel_force_function(c)
    fz, speed = 4000.0, 20.0
    for beta in (0.05, 0.1, 0.3):
        u, w = speed * math.cos(beta), speed * math.sin(beta)
        fx, fy = (float(value) for value in forces(fz, u, w, 0.0))
        angle = math.atan2(fx * w - fy * u, -(fx * u + fy * w))  # from -(u, w) to F
        print(f"beta {beta}: force angle to the sliding direction {angle:.2e} rad, "
              f"|F| / Fz {math.hypot(fx, fy) / fz:.4f}")
        assert abs(angle) <= 5e-5 * beta * 1.01
    u = 20.0
    surface, across = u * (1 - 0.02), u * math.tan(0.02)
    fx, fy = (float(value) for value in forces(fz, u, across, surface))
    kappa = (surface - u) / math.hypot(u, advanced.SLIP_SPEED_FLOOR)
    alpha = math.atan(across / math.hypot(u, advanced.SLIP_SPEED_FLOOR))
    mf_x, mf_y = (float(ca.evalf(v)) for v in advanced.tire_forces(c, fz, kappa, alpha)[:2])
    share = (math.hypot(u - surface, across) / math.hypot(u, across, advanced.SLIP_SPEED_FLOOR)) ** 4
    assert math.hypot(fx - mf_x, fy - mf_y) <= 2 * share * math.hypot(mf_x, mf_y)
    assert share < 1e-5


def test_a_locked_tire_slides_with_the_same_force_in_every_direction(defaults_advanced):
    # Locked (omega = 0), sliding at 20 m/s in the direction beta from the wheel's axis: Coulomb friction, |F| =
    # mu_slide Fz whatever beta, mu_slide Fz = |Fx(kappa = -1)| of the pure-slip Magic Formula (the tire files set
    # that to the road's sliding friction). The model turns its force toward -V_s with weight lambda = s^4,
    # s = |V_s| / sqrt(|V_s|^2 + v_low^2) = 1 - 1.25e-5, and takes the sliding force at kappa_s = -s (not -1): the
    # rest, (1 - lambda) = 5e-5 of the MF 5.2 force, and dFx/dkappa (kappa_s + 1) Fz-relative, 1e-5 at most, bound
    # the difference: 1e-4 relative. (MF 5.2's combined slip alone gave 0.619 Fz at 45 deg against 0.750 straight.)
    c = tire(defaults_advanced)
    forces = wheel_force_function(c)
    fz, speed = 4000.0, 20.0
    sliding = -longitudinal_force(c, fz, -1.0)
    assert sliding / fz == pytest.approx(0.75, abs=5e-3)  # dry asphalt: Wong's sliding value (test_friction_scale)
    for beta in (0.0, 0.1, 0.4, math.pi / 4, 1.2, 1.5, math.pi / 2):
        u, w = speed * math.cos(beta), speed * math.sin(beta)
        fx, fy = (float(value) for value in forces(fz, u, w, 0.0))
        print(f"beta {beta:.3f}: |F| / Fz {math.hypot(fx, fy) / fz:.6f} (sliding {sliding / fz:.6f})")
        assert math.hypot(fx, fy) == pytest.approx(sliding, rel=1e-4)


def test_locked_steered_wheels_stop_as_straight_ones(advanced_fmu, defaults_advanced):
    # Brake torque of 1000 m/s2 x m R: every wheel locks within ~0.4 ms and slides with Coulomb friction along its
    # sliding velocity, so fronts steered 0.5 rad push straight back like unsteered ones: the same deceleration,
    # the same stop. Only the spin-down before the lock differs (a steered tire's MF force along x is smaller): each
    # front wheel spins down in t_lock <= I omega0 / (T_brake - mu_peak Fz R) with a force difference of at most
    # (mu_peak + mu_slide) Fz, so the car keeps dv <= 2 (mu_peak + mu_slide) Fz t_lock / m more speed, dv t_stop
    # of distance at most (t_stop = 2 s / v0 of the straight stop). With MF 5.2's combined slip the steered car
    # stopped 2.55 m (9.3 %) later.
    start = {"v0": 20.0, "brake": 1.0, "brake_decel_max": 1000.0, **NO_RESISTANCES}
    straight = simulate(advanced_fmu, 4.0, start)
    steered = simulate(advanced_fmu, 4.0, {**start, "steer": 0.5})
    assert straight["stopped"][-1] and steered["stopped"][-1]
    p = defaults_advanced
    c = tire(p)
    m, radius, v0 = p["mass"], p["wheel_radius"], start["v0"]
    _, _, wheelbase, fz_front, _ = geometry(p)
    fz = fz_front + m * G * p["cg_height"] / (2 * wheelbase)  # the most load the transfer can put on a front wheel
    mu_peak, mu_slide = peak_longitudinal_friction(c, fz), -longitudinal_force(c, fz, -1.0) / fz
    torque = p["brake_front_share"] * start["brake_decel_max"] * m * radius / 2
    t_lock = p["wheel_inertia"] * v0 / radius / (torque - mu_peak * fz * radius)
    bound = 2 * (mu_peak + mu_slide) * fz * t_lock / m * 2 * straight["s"][-1] / v0
    difference = steered["s"][-1] - straight["s"][-1]
    print(f"straight {straight['s'][-1]:.4f} m, steered {steered['s'][-1]:.4f} m, difference {difference:.4f} m "
          f"(bound {bound:.4f} m)")
    assert abs(difference) <= bound
    assert bound < 1e-3 * straight["s"][-1]  # the reference is the point


def test_compliance_steer_follows_the_front_lateral_force(advanced_fmu, defaults_advanced):
    # Compliance steer delta_c = -D_f Fy_f, Fy_f the front tires' lateral force, at every instant: for linear tires
    # the front axle then acts as one of cornering stiffness C_f / (1 + D_f C_f) (F = C_f (alpha_0 - D_f F) at every
    # instant, alpha_0 its slip without compliance), and a small step steer is the linear bicycle model's response
    # with that stiffness
    # (x = (vy, r), x' = A x + B delta as in the Simple model's test; C = 2 Ky at the static loads). The rolling
    # wheels' spin inertia adds to the yaw inertia (a yawing car's left and right wheels spin at speeds r t / 2 apart:
    # Iz + I_w sum y_i^2 / R^2, 1 % here). The steer is a 0.1 s ramp to 0.5 m/s2 at 80 km/h, held each 1 ms step
    # (the reference is stepped exactly, e^{A h}). What the linear model leaves out is of second order: the tires'
    # curvature (B alpha)^2, B = Ky / (C D), the lateral load transfer's (dFz / Fz)^2, the steer's delta^2 (cos, sin);
    # bounded by their sum. Driven by the a_y lagged 0.1 s, the compliance gave 20 % overshoot against this
    # model's 10.6 % (deviation 15 % of the steady state).
    p = defaults_advanced
    c = tire(p)
    m, a, b = p["mass"], p["cg_to_front_axle"], p["cg_to_rear_axle"]
    _, _, wheelbase, fz_front, fz_rear = geometry(p)
    c_front, c_rear = 2 * cornering_stiffness(c, fz_front), 2 * cornering_stiffness(c, fz_rear)
    c_effective = c_front / (1 + p["steer_compliance"] * c_front)
    iz = p["yaw_inertia"] + p["wheel_inertia"] * 2 * ((p["track_front"] / 2) ** 2 + (p["track_rear"] / 2) ** 2) \
        / p["wheel_radius"] ** 2
    u, h, duration, lateral = 80 / 3.6, 1e-3, 3.0, 0.5
    gradient = m / wheelbase * (b / c_effective - a / c_rear)
    amplitude = lateral * (wheelbase + gradient * u * u) / u**2
    time = np.arange(0.0, duration + h / 2, h)
    steer = amplitude * np.minimum(time / 0.1, 1.0)
    result = simulate(advanced_fmu, duration, {"v0": u, **NO_RESISTANCES}, step=h,
                      inputs=input_table(time, steer=steer), output=("yaw_rate", "vx"))
    A = np.array([[-(c_effective + c_rear) / (m * u), -u - (a * c_effective - b * c_rear) / (m * u)],
                  [-(a * c_effective - b * c_rear) / (iz * u), -(a * a * c_effective + b * b * c_rear) / (iz * u)]])
    B = np.array([c_effective / m, a * c_effective / iz])
    values, vectors = np.linalg.eig(A)
    e_ah = (vectors @ np.diag(np.exp(values * h)) @ np.linalg.inv(vectors)).real
    forced = np.linalg.solve(A, (e_ah - np.eye(2)) @ B)
    x, expected = np.zeros(2), []
    for delta in steer[:len(result)]:
        expected.append(x[1])
        x = e_ah @ x + forced * delta
    expected = np.array(expected)
    r_ss = u / (wheelbase + gradient * u * u) * amplitude
    alpha = m * lateral * b / wheelbase / c_front
    shape = cornering_stiffness(c, fz_front) / (c["PCY1"] * abs(c["PDY1"]) * c["LMUY"] * fz_front)
    transfer = m * lateral * p["cg_height"] * p["roll_stiffness_front_share"] / p["track_front"] / fz_front
    bound = (shape * alpha) ** 2 + transfer**2 + amplitude**2
    deviation = np.max(np.abs(result["yaw_rate"] - expected)) / r_ss
    overshoot = result["yaw_rate"].max() / result["yaw_rate"][-1] - 1
    print(f"deviation {deviation:.2e} of r_ss (bound {bound:.2e}); overshoot {overshoot:.3%}, "
          f"linear {expected.max() / expected[-1] - 1:.3%}")
    assert deviation <= bound
    assert bound < 0.01


# --- numerics -------------------------------------------------------------------------------------------


def test_halving_the_solver_step_converges_at_fourth_order(advanced_fmu):
    # With fixed steps (solver_tolerance 0) RODAS4 has order 4: the global error is e(h) ~ C h^4, so the
    # change on halving the step, d(h) = e(h) - e(h/2), shrinks by 2^4 = 16 per halving. Required:
    # d(1 ms -> 0.5 ms) <= d(2 ms -> 1 ms) / 8,
    # i.e. an observed order >= 3 (one order of slack for the events and the kinks of max/min in the
    # equations), plus 1e-10 m of round-off; and below the Simple FMU's 1e-6 m.
    # Measured: stop distance d = 9.1e-8, 2.1e-9 m; lane change end y d = 3.8e-11, 8e-13 m.
    time = np.arange(0.0, 6.0 + 1e-9, 0.01)
    steer = np.where(time < 3.0, 0.03 * np.sin(2 * np.pi * time / 3.0), 0.0)  # one-period sine: a lane change
    lane_change = input_table(time, steer=steer)
    stops, lateral = [], []
    for solver_step in (2e-3, 1e-3, 5e-4):
        # 70 % pedal (6.9 m/s2) locks no wheel on dry asphalt (peak 0.85 g): a smooth stop. At full pedal
        # every wheel locks within ~1 ms, a transient the coarse steps do not resolve (change 1.6e-6 m).
        fixed = {"solver_step": solver_step, "solver_tolerance": 0.0}
        stops.append(simulate(advanced_fmu, 5.0, {"v0": 20.0, "brake": 0.7, **fixed})["s"][-1])
        lateral.append(simulate(advanced_fmu, 6.0, {"v0": 20.0, **fixed}, inputs=lane_change)["y"][-1])
    for name, values in (("stop distance", stops), ("lane change y", lateral)):
        coarse, fine = abs(values[0] - values[1]), abs(values[1] - values[2])
        print(f"{name}: {values[2]:.12f} m; change on halving 2->1 ms {coarse:.2e} m, 1->0.5 ms {fine:.2e} m")
        assert fine <= coarse / 8 + 1e-10
        assert fine < 1e-6
    assert 1.0 < abs(lateral[-1]) < 10.0  # it was a lane change


def test_communication_steps_give_the_same_stop(advanced_fmu):
    # With fixed internal steps (solver_tolerance 0) the internal step stays solver_step (1 ms) whatever the
    # communication step (1, 10, 100 ms all divide into whole solver steps), and the stop is an event located
    # to 1e-12 s inside a step: only round-off of the time grid differs, ~1e4 steps x 1e-16 x 20 m; allowed
    # 1e-9 m. (The error-controlled default: tests/fmu/test_solver.py.)
    fixed = {"solver_tolerance": 0.0, "solver_step": 1e-3}
    distances = [simulate(advanced_fmu, 4.0, {"v0": 20.0, "brake": 1.0, **fixed}, step=step)["s"][-1]
                 for step in (0.001, 0.01, 0.1)]
    print("stop distances", distances)
    assert max(distances) - min(distances) < 1e-9


# --- standstill -----------------------------------------------------------------------------------------


def test_holds_at_rest_under_brake_without_creep(advanced_fmu):
    result = simulate(advanced_fmu, 12.0, {"v0": 10.0, "brake": 1.0}, step=0.01)
    stopped = result["stopped"]
    first = int(np.argmax(stopped))
    assert 0 < first and result["time"][first] < 2.0
    assert np.all(stopped[first:])  # held, no chatter
    assert result["time"][-1] - result["time"][first] >= 10.0
    assert np.ptp(result["s"][first:]) < 1e-9
    assert np.all(result["vx"][first:] == 0)


def test_holds_at_rest_with_no_pedal_and_starts_on_throttle(advanced_fmu):
    assert_rest = simulate(advanced_fmu, 10.0, {"v0": 0.0}, step=0.1)
    assert np.all(assert_rest["stopped"]) and np.all(assert_rest["s"] == 0)
    # coasting on rolling resistance (f_r g = 0.12 m/s2) from 1 m/s stops after ~8.5 s, is held, and starts
    # again once the throttle exceeds the holding force
    time = np.arange(0.0, 25.0 + 1e-9, 0.1)
    result = simulate(advanced_fmu, 25.0, {"v0": 1.0}, step=0.1,
                      inputs=input_table(time, throttle=np.where(time >= 20.0, 0.2, 0.0)))
    held = (result["time"] > 10.0) & (result["time"] < 20.0)
    assert np.all(result["stopped"][held]) and np.ptp(result["s"][held]) < 1e-9
    assert not result["stopped"][-1] and result["s"][-1] > result["s"][held][-1] + 1.0


def test_jacobian_is_finite_at_standstill_and_low_speed():
    equations = advanced.equations()
    functions = equations.functions()
    interface = equations.interface
    states, inputs = interface.names("state"), interface.names("input")
    declared = [v.start for v in interface.of_role("parameter")]
    rng = np.random.default_rng(1)
    # the runtime's own parameter (equations.MODEL_EXCHANGE) last: co-simulation (dynamic wheels) and model
    # exchange (quasi-static wheels)
    for stopped, model_exchange in itertools.product((0, 1), (0.0, 1.0)):
        parameters = np.array(declared + [model_exchange], dtype=float)
        for mode in (-1, 0, 1):
            for speed in (0.0, 1e-9, 1e-3, 0.05, 0.3, 5.0):
                x = np.zeros(len(states))
                x[states.index("vx")] = speed
                x[states.index("vy")] = rng.uniform(-1, 1) * speed
                for w in WHEELS:
                    x[states.index(f"wheel_speed_{w}")] = 0.0 if mode == 0 else mode * rng.uniform(0, 1) * speed
                d = np.array([stopped] + [mode] * 4, dtype=float)
                u = np.zeros(len(inputs))
                u[inputs.index("throttle")], u[inputs.index("brake")] = rng.uniform(0, 1, 2)
                u[inputs.index("surface_fl")] = ICE
                for name in ("derivatives", "jacobian", "event_indicators", "outputs"):
                    assert np.all(np.isfinite(np.array(functions[name](x, d, u, parameters)))), (name, x, d)


def test_generated_functions_run_one_wheel_spin_case():
    # Each generated function is a CasADi Switch over the two wheel-spin cases (dynamic, quasi-static), the
    # fixed selection folded into each case's expressions. Folding if_else(0, a, b) to b (and if_else(1, a, b)
    # to a) changes no floating-point operation on the selected branch, so the switched functions equal the
    # union expressions (both branches, as the dependencies are read) bit for bit, in every selection.
    equations = advanced.equations()
    switched, union = equations.functions(), equations._functions("")
    interface = equations.interface
    states, inputs = interface.names("state"), interface.names("input")
    parameters = interface.names("parameter")
    declared = [v.start for v in interface.of_role("parameter")]
    rng = np.random.default_rng(2)
    for model_exchange, wheel_spin in itertools.product((0.0, 1.0), advanced.WHEEL_SPIN.values()):
        p = np.array(declared + [model_exchange], dtype=float)
        p[parameters.index("wheel_spin")] = wheel_spin
        for stopped, mode, speed in itertools.product((0, 1), (-1, 0, 1), (1e-3, 0.3, 20.0)):
            x = rng.normal(size=len(states))
            x[states.index("vx")] = speed
            d = np.array([stopped] + [mode] * 4, dtype=float)
            u = rng.uniform(0, 1, len(inputs))
            for name, function in switched.items():
                for ours, theirs in zip(function.call([x, d, u, p]), union[name].call([x, d, u, p])):
                    assert np.array_equal(np.array(ours), np.array(theirs), equal_nan=True), (name, x, d, p)
    # the solver Jacobian switches between the cases' own functions; co-simulation's (dynamic) case has none of the
    # quasi-static slip solve (per wheel a peak search, bisection and Newton steps on the tire curve: about 2/3 of
    # the union's operations; the rest, the compliance steer's Newton steps on the front tires included, is common
    # to both cases), so the dynamic case has well under 2/5 of them
    model = interface.model_name
    called = {function.name() for function in switched["jacobian"].find_functions()}
    assert {f"{model}_case0_jacobian", f"{model}_case1_jacobian"} <= called
    dynamic = next(f for f in switched["jacobian"].find_functions() if f.name() == f"{model}_case0_jacobian")
    assert dynamic.n_instructions() < union["jacobian"].n_instructions() * 2 / 5
