"""SDL "advanced dynamics": a planar two-track vehicle on Pacejka Magic Formula tires.

States: position x, y, yaw psi, path length s, body velocities vx, vy, yaw rate r, the four wheel
spin rates, and two lagged accelerations for the load transfer. Equations (ISO 8855 axes; wheel i at
(x_i, y_i) from the centre of gravity: front x = a, rear x = -b, left y = +track/2, right y = -track/2):

  Loads      Fz_i = m g (b or a) / (2 L) -/+ m a_l h / (2 L) -/+ m a_t h k_axle / track_axle,  L = a + b,
             front -, rear + for the longitudinal term; left -, right + for the lateral term;
             k_front = roll_stiffness_front_share, k_rear = 1 - k_front; a_l, a_t are the states load_ax,
             load_ay: d(load_ax)/dt = (ax - load_ax) / tau (same for ay), tau = load_transfer_time_constant.
             The lag replaces pitch/roll dynamics and breaks the algebraic loop loads -> forces -> a.
  Kinematics v_i = (vx - r y_i, vy + r x_i) at the contact point, turned into the wheel frame by the steering
             angle (front wheels, parallel steer): (v_cx, v_cy). Front road-wheel angle delta_f = steer - D_f Fy_f,
             Fy_f the front tires' lateral force at delta_f (lateral-force compliance steer, D_f = steer_compliance;
             two Newton steps with the tires' cornering stiffness as slope, from steer - D_f m load_ay b / L).
  Slip       kappa = (omega R - v_cx) / sqrt(v_cx^2 + v_low^2),  alpha = atan(v_cy / sqrt(v_cx^2 + v_low^2))
             v_low = SLIP_SPEED_FLOOR: the usual 1/|v_cx| with a smooth floor, finite at standstill (there
             the tire acts as a stiff viscous damper, which the L-stable solver handles).
  Tires      MF 5.2 pure slip without shifts and camber (Pacejka, Tyre and Vehicle Dynamics, sec. 4.3.2):
               dfz = (Fz - Fz0') / Fz0',  Fz0' = FNOMIN LFZO
               Fx0 = mux Fz sin(Cx atan(Bx k - Ex (Bx k - atan(Bx k)))),  mux = |PDX1 + PDX2 dfz| LMUX,
                 Cx = PCX1, Ex = min(PEX1 + PEX2 dfz + PEX3 dfz^2, 1), Bx = Kx / (Cx mux Fz),
                 Kx = Fz |PKX1 + PKX2 dfz| exp(PKX3 dfz) LKX
               Fy0 = -muy Fz sin(Cy atan(By a - Ey (By a - atan(By a)))),  muy = |PDY1 + PDY2 dfz| LMUY,
                 Cy = PCY1, Ey = min(PEY1 + PEY2 dfz, 1), By = Ky / (Cy muy Fz),
                 Ky = |PKY1| Fz0' sin(2 atan(Fz / (PKY2 Fz0'))) LKY  (= 2 |PKY1 / PKY2| Fz / (1 + u^2) LKY,
                 u = Fz / (PKY2 Fz0'), the form used: finite at Fz = 0)
             Magnitudes make the model independent of the file's sign convention: the lateral force
             always opposes the lateral slip, the longitudinal force follows kappa.
             Combined slip (MF 5.2 weighting functions, without shifts, clipped at 0), then turned toward
             the sliding velocity as the tire slides (sliding_blend): a locked tire pushes against its
             contact point's sliding velocity with Coulomb friction, |F| = |Fx0(kappa = -1)| whatever the
             direction; pure slip and small combined slip stay MF 5.2:
               Fx = Gxa Fx0, Gxa = cos(RCX1 atan(Bxa a - Exa (Bxa a - atan(Bxa a)))),
                 Bxa = RBX1 cos(atan(RBX2 k)) LXAL, Exa = min(REX1 + REX2 dfz, 1)
               Fy = Gyk Fy0, Gyk = cos(RCY1 atan(Byk k - Eyk (Byk k - atan(Byk k)))),
                 Byk = RBY1 cos(atan(RBY2 (a - RBY3))) LYKA, Eyk = min(REY1 + REY2 dfz, 1)
  Wheels     discrete mode per wheel (wheel_mode_*): +1 rolling forward, 0 locked, -1 rolling backward.
             rolling: I_w d(omega)/dt = T_net - mode T_brake - f_r Fz R omega / sqrt(omega^2 + w_s^2),
               T_net = T_drive - Fx R;  locked: omega = 0, held while the brake can: |T_net| < T_brake.
             A rolling wheel whose spin reaches 0 locks if |T_net| < T_brake, else turns the other way; a
             locked wheel is released (event) when |T_net| reaches T_brake, in the direction of T_net.
             Each mode's right-hand side is smooth and is continued past its switching surface, so the
             solver's stages never straddle a discontinuity; the events switch modes. (The brake's Coulomb
             friction is exact; a smooth sign of small width would be stepped over by the fixed-step solver
             and make locked wheels chatter.) Rolling resistance is small enough for a smooth sign of width
             w_s = SPIN_SMOOTHING.
             T_drive = throttle min(T_max, P_max / mean omega of the driven wheels), split by
             drive_front_share and equally left/right (open differentials);
             T_brake = brake brake_decel_max m R, split by brake_front_share and equally left/right.
  Quasi-static wheels (wheel_spin = 2, or 0 "automatic" in a model-exchange instance; 1 and co-simulation's
             automatic are the dynamic wheels above). The spin equation is stiff (time constant I_w v / (C_kappa
             R^2), about 0.5 ms per m/s), so explicit fixed-step integrators cannot integrate it; its fast
             transient is dropped (singular perturbation). A rolling wheel (mode +-1) gives the force its torque
             balance asks for, with its spin's inertia riding on the body's longitudinal acceleration:
               R Fx_i(kappa_i) = T_drive_i - mode (T_brake_i + f_r Fz_i R) - (I_w / R) a_x,
               a_x = (sum_rolling clip((T_drive_i - mode (T_brake_i + f_r Fz_i R)) / R, +-peak force_i)
                      + sum_locked Fx_i + drag) / (m + n_rolling I_w / R^2)
                     (straight ahead; the steer angle is ignored in a_x),
             solved for 0 <= |kappa_i| <= the peak of the pure-slip curve (Newton, from the closed-form peak
             equation) by bisection and Newton steps (exact derivatives through the last Newton steps); Fy_i
             follows from the same slip. A demand beyond the peak gives the peak force; if it is a braking
             demand, the wheel locks (event: mode 0, the locked wheel of the dynamic model, released when
             T_brake + f_r Fz R falls below both |T_net| and T_drive + 0.95 R (peak force) - I_w a_x' / R, a_x'
             the body's acceleration were the wheel rolling forward: released, it passes the lock test with a
             5 % margin; a locked, steered tire can push harder along its axis than the rolling tire's peak).
             Indicator while rolling: min(R (capacity - braking demand),
             mode v_cx + 1e-6 m/s), positive; it turns back (lock or reverse) when its contact point does.
             The spin state follows without stiffness, d(omega)/dt = a_x / R + (omega_qs - omega) / 0.1 s,
             omega_qs = (v_cx + kappa sqrt(v_cx^2 + v_low^2)) / R; no force reads it (only the compliance steer's Newton
             steps, which come before the slip solve, read the tires with it). The power limit uses
             vx / R. While no wheel rolls backward the stop is the half-line max(vx, |vy|) <= STOP_SPEED (a
             locked car is a stiff damper near standstill, so one Euler step can reverse its speed).
  Body       m (dvx/dt - r vy) = sum Fx_b - rho CdA vx |vx| / 2,  m (dvy/dt + r vx) = sum Fy_b,
             Iz dr/dt = sum (x_i Fy_b,i - y_i Fx_b,i),  dx/dt = vx cos psi - vy sin psi,
             dy/dt = vx sin psi + vy cos psi, dpsi/dt = r, ds/dt = speed.
  Standstill discrete state `stopped` (as in the simple model): when the speed falls to STOP_SPEED and the
             drive cannot overcome brakes and rolling resistance, an event sets every velocity and wheel
             spin to 0 (wheel modes 0) and freezes the motion; it ends (event) when the drive force
             exceeds the holding force, and the wheels are released as their torques demand.
Tire coefficients per wheel come from the slot chosen by its surface input (tires.slot_of).
"""

from __future__ import annotations

from dataclasses import replace

import casadi as ca

from ..interface import DISCRETE, STATE, Interface, load_interface
from ..names import SHIPPED_MODELS, WHEELS
from ..tire_files import DEFAULT_ATTRIBUTE_FILE, SLOT_KEYS
from ..units import STANDARD_GRAVITY
from .equations import MODEL_EXCHANGE, Equations, make_symbols
from .planar import body_derivatives
from .tires import SLOT_COUNT, slot_parameter_name, slot_parameters

MODEL_NAME = SHIPPED_MODELS["advanced"]
LEFT_SIDE = {"fl": 1, "fr": -1, "rl": 1, "rr": -1}  # +1 left wheel, -1 right wheel
SLIP_SPEED_FLOOR = 0.1  # m/s, v_low of the slip definitions
SPIN_SMOOTHING = 0.1  # rad/s, w_s of the rolling-resistance torque
STOP_SPEED = 0.05  # m/s: below it, with no drive, the vehicle is held (the rest of the stop is < 1 mm)
START_MARGIN = 1e-6  # m/s2: drive must exceed the holding forces by this to start (as in the simple model)
SPEED_SMOOTHING = 1e-9  # m/s: ds/dt = sqrt(v^2 + e^2) - e keeps d(ds/dt)/dv finite at v = 0
POWER_LIMIT_MIN_SPIN = 1e-3  # rad/s: the power limit P / omega is not evaluated below this spin
TINY = 1e-9  # floor of denominators that are 0 only for meaningless tire data (zero friction)
# Hysteresis of a rolling wheel's direction (rad/s): a wheel rolling forward stops (locks or turns back) when its
# spin falls below -SPIN_HYSTERESIS, one rolling backward when it rises above +SPIN_HYSTERESIS, so its indicator
# is never 0 just after the switch (nor when a locked wheel is released) and keeps its sign through the event.
SPIN_HYSTERESIS = 1e-6
# Event indicator of a wheel while the vehicle is held: constant, negative like the indicators of the wheels
# that stop or lock as the vehicle comes to rest, so the stop does not flip their sign.
HELD_WHEEL_INDICATOR = -1.0
# Quasi-static wheels (wheel_spin 2, or 0 in model exchange): the slip of a rolling wheel solves its torque balance.
# The longitudinal force rises with the slip up to the peak of the pure-slip curve (peak_slip); the slip of a force
# is found by BISECTIONS bisections on 0..peak, then NEWTON_STEPS Newton steps, which also give the slip's exact
# derivatives (implicit function theorem) whatever the bisection left.
KAPPA_SEARCH = 1.0
PEAK_NEWTON_STEPS = 6
BISECTIONS = 6
NEWTON_STEPS = 3
DIRECTION_HYSTERESIS = 1e-6  # m/s: a quasi-static wheel rolling forward turns back below -this contact speed
RELEASE_SHARE = 0.95  # a quasi-static locked wheel is released when its brake falls below this share of the peak
SPIN_RELAXATION_TIME = 0.1  # s: a quasi-static wheel's spin state follows the spin of its slip (forces never read it)
# Newton steps of the compliance steer (see wheel_equations): residual 0.08 % of the compliance steer in the step steer
# of 0.05 rad at 80 km/h, 1.3 % in a 0.12 rad sine with dwell (1.3 % of at most 0.035 rad), against 1.0 % and 3.3 % for
# one step with the exact slope
COMPLIANCE_NEWTON_STEPS = 2
WHEEL_SPIN = {"automatic": 0, "dynamic": 1, "quasi_static": 2}  # values of the wheel_spin parameter


def advanced_interface(attribute_file=DEFAULT_ATTRIBUTE_FILE) -> Interface:
    """The FMU interface with the tire slot start values built in from a Tire Attribute File."""
    starts, _, warnings = slot_parameters(attribute_file)
    if warnings:
        raise ValueError(f"the FMU's built-in tires must come from a clean attribute file: {warnings}")
    return load_interface(MODEL_NAME, starts=starts)


def wheel_coefficients(s, wheel: str) -> dict:
    """The Magic Formula coefficients under one wheel: the slot picked by its surface attribute input."""
    surface = s[f"surface_{wheel}"]
    return {
        key: ca.conditional(surface, [s[slot_parameter_name(k, key)] for k in range(SLOT_COUNT)],
                            s[slot_parameter_name(0, key)])
        for key in SLOT_KEYS
    }


def _magic_formula(b, c, e, slip):
    """sin(C atan(B s - E (B s - atan(B s)))), the Magic Formula without its peak factor."""
    bs = b * slip
    return ca.sin(c * ca.atan(bs - e * (bs - ca.atan(bs))))


def _weighting(b, c, e, slip):
    """MF 5.2 combined-slip weighting cos(C atan(B s - E (B s - atan(B s)))), clipped at 0."""
    bs = b * slip
    return ca.fmax(ca.cos(c * ca.atan(bs - e * (bs - ca.atan(bs)))), 0)


def longitudinal_shape(c: dict, fz):
    """The pure-slip longitudinal Magic Formula's load change dfz, friction mux and factors Bx, Ex (Cx = PCX1)."""
    fz0 = c["FNOMIN"] * c["LFZO"]
    dfz = (fz - fz0) / fz0
    mux = ca.fabs((c["PDX1"] + c["PDX2"] * dfz) * c["LMUX"])
    ex = ca.fmin(c["PEX1"] + c["PEX2"] * dfz + c["PEX3"] * dfz**2, 1)
    kx_per_fz = ca.fabs((c["PKX1"] + c["PKX2"] * dfz) * ca.exp(c["PKX3"] * dfz) * c["LKX"])
    bx = kx_per_fz / ca.fmax(c["PCX1"] * mux, TINY)
    return dfz, mux, bx, ex


def cornering_stiffness(c: dict, fz):
    """The pure-slip cornering stiffness Ky = |PKY1| Fz0' sin(2 atan(Fz / (PKY2 Fz0'))) LKY (N/rad), in the form
    2 |PKY1 / PKY2| Fz LKY / (1 + u^2), u = Fz / (PKY2 Fz0'), finite at Fz = 0."""
    u = fz / (c["PKY2"] * c["FNOMIN"] * c["LFZO"])
    return fz * ca.fabs(2 * c["PKY1"] / (c["PKY2"] * (1 + u**2)) * c["LKY"])


def tire_forces(c: dict, fz, kappa, alpha):
    """Combined-slip Magic Formula forces (Fx, Fy) in the wheel frame and the friction coefficients (mux, muy)."""
    fz0 = c["FNOMIN"] * c["LFZO"]
    dfz, mux, bx, ex = longitudinal_shape(c, fz)
    fx0 = mux * fz * _magic_formula(bx, c["PCX1"], ex, kappa)

    muy = ca.fabs((c["PDY1"] + c["PDY2"] * dfz) * c["LMUY"])
    ey = ca.fmin(c["PEY1"] + c["PEY2"] * dfz, 1)
    u = fz / (c["PKY2"] * fz0)
    ky_per_fz = ca.fabs(2 * c["PKY1"] / (c["PKY2"] * (1 + u**2)) * c["LKY"])
    by = ky_per_fz / ca.fmax(c["PCY1"] * muy, TINY)
    fy0 = -muy * fz * _magic_formula(by, c["PCY1"], ey, alpha)

    bxa = c["RBX1"] * ca.cos(ca.atan(c["RBX2"] * kappa)) * c["LXAL"]
    gxa = _weighting(bxa, c["RCX1"], ca.fmin(c["REX1"] + c["REX2"] * dfz, 1), alpha)
    byk = c["RBY1"] * ca.cos(ca.atan(c["RBY2"] * (alpha - c["RBY3"]))) * c["LYKA"]
    gyk = _weighting(byk, c["RCY1"], ca.fmin(c["REY1"] + c["REY2"] * dfz, 1), kappa)
    return gxa * fx0, gyk * fy0, mux, muy


def sliding_force(c: dict, fz, sliding_speed):
    """The force of the tire sliding at sliding_speed, whatever the direction (Coulomb friction): the pure-slip
    longitudinal Magic Formula of the locked wheel, |Fx0(kappa_s)|, kappa_s = -|V_s| / sqrt(|V_s|^2 + v_low^2), so that
    a locked wheel sliding straight gives exactly the MF value (the tire files set it to the road's sliding
    friction: docs of scenarios/tires) and one sliding in any other direction the same."""
    _, mux, bx, ex = longitudinal_shape(c, fz)
    kappa = -sliding_speed / ca.sqrt(sliding_speed**2 + SLIP_SPEED_FLOOR**2)
    return ca.fabs(mux * fz * _magic_formula(bx, c["PCX1"], ex, kappa))


def sliding_blend(fx, fy, slide_x, slide_y, reference_speed, coulomb, wheel_x, surface_speed):
    """The Magic Formula force turned toward the sliding velocity as the tire slides (wheel frame).

    MF 5.2's combined-slip weighting does not make a sliding tire push against its sliding velocity: a
    locked, steered tire keeps a force along its own axis and steers the car; nor does it keep a locked tire's
    force when it slides sideways (at kappa = -1 the weighting takes 17 % off at 45 deg). With the sliding velocity
    V_s = (v_cx - omega R, v_cy) and the sliding share s = |V_s| / sqrt(v_cx^2 + v_cy^2 + v_low^2) (0 rolling
    freely, 1 locked), lambda = min(s, 1)^4 and
        F = (1 - lambda) F_MF + lambda S (-V_s / |V_s|),   S = |F_MF| + g (F_c - |F_MF|),
    F_c the tire's sliding force (sliding_force: Coulomb friction, the same in every direction) and g the share of
    it: g = l chi with the locked share l = (V_sx^2) / (V_sx^2 + (omega R)^2) (1 at omega = 0, 0 rolling freely)
    and chi = v_cy^2 / (v_cy^2 + (1 - l)(v_cx^2 + v_low^2)) (0 in pure longitudinal slip, 1 locked).
    In pure slip (v_cy = 0, or omega R = v_cx) -V_s is along F_MF and g = 0, so F = F_MF exactly; at small combined
    slip F differs from MF 5.2 by O(s^4); a locked tire (omega = 0: s -> 1, g = 1) pushes exactly against its
    sliding velocity with the sliding force F_c, whatever the direction it slides in."""
    slide = ca.sqrt(slide_x**2 + slide_y**2 + TINY**2)
    share = ca.fmin(slide / reference_speed, 1) ** 4
    magnitude = ca.sqrt(fx**2 + fy**2 + TINY**2)
    if coulomb is None:
        sliding = magnitude
    else:
        locked = (slide_x**2 + TINY**2) / (slide_x**2 + surface_speed**2 + TINY**2)
        lateral = slide_y**2 / (slide_y**2 + (1 - locked) * (wheel_x**2 + SLIP_SPEED_FLOOR**2) + TINY**2)
        sliding = magnitude + locked * lateral * (coulomb - magnitude)
    return ((1 - share) * fx - share * sliding * slide_x / slide,
            (1 - share) * fy - share * sliding * slide_y / slide)


def wheel_forces(c: dict, fz, wheel_x, wheel_y, surface_speed, coulomb: bool = True):
    """Tire forces (Fx, Fy) in the wheel frame and (mux, muy) from the contact-point velocity in the wheel
    frame (wheel_x, wheel_y) and the wheel's surface speed omega R: slip, MF 5.2, sliding blend. coulomb=False
    leaves out the locked wheel's sliding force (for the quasi-static slip solve of a rolling wheel, whose slip
    stays below the peak: there the sliding force's share lambda l chi is below 1e-4)."""
    slip_speed = ca.sqrt(wheel_x**2 + SLIP_SPEED_FLOOR**2)
    kappa = (surface_speed - wheel_x) / slip_speed
    alpha = ca.atan(wheel_y / slip_speed)
    fx, fy, mux, muy = tire_forces(c, fz, kappa, alpha)
    slide_x = wheel_x - surface_speed
    sliding = sliding_force(c, fz, ca.sqrt(slide_x**2 + wheel_y**2 + TINY**2)) if coulomb else None
    fx, fy = sliding_blend(fx, fy, slide_x, wheel_y, ca.sqrt(wheel_x**2 + wheel_y**2 + SLIP_SPEED_FLOOR**2),
                           sliding, wheel_x, surface_speed)
    return fx, fy, mux, muy


def force_curve() -> ca.Function:
    """(kappa, Fz, v_cx, v_cy, the slot's coefficients in SLOT_KEYS order) -> (Fx, Fy, dFx/dkappa) of a wheel
    whose slip is kappa: one function, so the solver's many calls repeat only the tire formula."""
    kappa, fz, wheel_x, wheel_y = (ca.SX.sym(name) for name in ("kappa", "fz", "wheel_x", "wheel_y"))
    values = ca.SX.sym("coefficients", len(SLOT_KEYS))
    coefficients = {key: values[i] for i, key in enumerate(SLOT_KEYS)}
    slip_speed = ca.sqrt(wheel_x**2 + SLIP_SPEED_FLOOR**2)
    fx, fy, _, _ = wheel_forces(coefficients, fz, wheel_x, wheel_y, wheel_x + kappa * slip_speed, coulomb=False)
    return ca.Function("force_curve", [kappa, fz, wheel_x, wheel_y, values], [fx, fy, ca.jacobian(fx, kappa)])


def peak_slip(c: dict, fz):
    """The slip 0 < kappa <= KAPPA_SEARCH of the pure-slip longitudinal force's peak: C atan(u - E (u - atan u))
    = pi/2 at u = B kappa, i.e. (1 - E) u + E atan u = tan(pi / (2 C)) for C > 1 (no peak for C <= 1: the search
    bound). The left side is increasing, concave for E > 0 and convex for E < 0, so Newton's method from u = t
    approaches the root from one side."""
    _, _, bx, ex = longitudinal_shape(c, fz)
    shape = c["PCX1"]
    target = ca.tan(ca.pi / (2 * ca.fmax(shape, 1 + 1e-9)))
    u = target
    for _ in range(PEAK_NEWTON_STEPS):
        u = u - ((1 - ex) * u + ex * ca.atan(u) - target) / ca.fmax((1 - ex) + ex / (1 + u**2), TINY)
    return ca.if_else(shape > 1, ca.fmin(ca.fmax(u, 0) / ca.fmax(bx, TINY), KAPPA_SEARCH), KAPPA_SEARCH)


def quasi_static_slip(curve, peak, capacity, target):
    """The slip 0 <= kappa <= peak at which the longitudinal force curve(kappa) = (Fx, Fy, dFx/dkappa) reaches
    target, clipped to the tire's capacity (the force at the peak, curve(peak)[0]): bisection, then Newton."""
    goal = ca.fmin(target, capacity)
    low, high = 0, 1  # the slip as a share of the peak's: the bisection's steps are constants (no derivatives)
    for _ in range(BISECTIONS):
        middle = (low + high) / 2
        below = curve(middle * peak)[0] < goal
        low, high = ca.if_else(below, middle, low), ca.if_else(below, high, middle)
    kappa = (low + high) / 2 * peak
    for _ in range(NEWTON_STEPS):
        force, _, slope = curve(kappa)
        kappa = ca.fmin(ca.fmax(kappa - (force - goal) / ca.fmax(slope, TINY), 0), peak)
    return kappa


def smooth_sign(value, width):
    """value / sqrt(value^2 + width^2): a differentiable sign for Coulomb friction."""
    return value / ca.sqrt(value**2 + width**2)


def equations() -> Equations:
    interface = advanced_interface()
    s = make_symbols(interface, runtime=True)
    # the wheel spin model: automatic (0) is quasi-static in a model-exchange instance, dynamic in co-simulation
    quasi_static = ca.if_else(s["wheel_spin"] == WHEEL_SPIN["automatic"], s[MODEL_EXCHANGE],
                              s["wheel_spin"] == WHEEL_SPIN["quasi_static"])
    # the generated code runs one case (dynamic 0, quasi-static 1): co-simulation never pays for the slip solve
    cases = tuple(wheel_equations(interface, s, ca.SX(value)) for value in (0, 1))
    return replace(wheel_equations(interface, s, quasi_static), cases=cases, case=quasi_static)


def wheel_equations(interface: Interface, s, quasi_static) -> Equations:
    """The equations with the wheels' spin model quasi_static (1 quasi-static, 0 dynamic; an expression of p or a
    constant, which CasADi folds into the expressions of one case)."""
    g = STANDARD_GRAVITY
    m, radius = s["mass"], s["wheel_radius"]
    a, b, h = s["cg_to_front_axle"], s["cg_to_rear_axle"], s["cg_height"]
    wheelbase = a + b
    vx, vy, r, psi, stopped = s["vx"], s["vy"], s["yaw_rate"], s["psi"], s["stopped"]
    moving = 1 - stopped
    inertia = s["wheel_inertia"]

    position = {"fl": (a, s["track_front"] / 2), "fr": (a, -s["track_front"] / 2),
                "rl": (-b, s["track_rear"] / 2), "rr": (-b, -s["track_rear"] / 2)}
    front = {"fl": True, "fr": True, "rl": False, "rr": False}
    static = {True: m * g * b / (2 * wheelbase), False: m * g * a / (2 * wheelbase)}
    longitudinal_transfer = m * s["load_ax"] * h / (2 * wheelbase)  # per wheel, to the front when braking
    roll_share = {True: s["roll_stiffness_front_share"], False: 1 - s["roll_stiffness_front_share"]}
    track = {True: s["track_front"], False: s["track_rear"]}

    # drive: power-limited total torque, split front/rear, equal left/right; the quasi-static wheels' spin is
    # the body's speed over the radius (their slip is not known before the drive torque)
    drive_share = {True: s["drive_front_share"], False: 1 - s["drive_front_share"]}
    driven_spin = ca.if_else(quasi_static, vx / radius,
                             sum(drive_share[front[w]] * s[f"wheel_speed_{w}"] / 2 for w in WHEELS))
    drive_torque = s["throttle"] * ca.fmin(
        s["drive_torque_max"], s["drive_power_max"] / ca.fmax(driven_spin, POWER_LIMIT_MIN_SPIN))
    brake_torque = s["brake"] * s["brake_decel_max"] * m * radius
    brake_share = {True: s["brake_front_share"], False: 1 - s["brake_front_share"]}

    # lateral-force compliance steer of the front wheels (steering system and suspension): the road-wheel angle
    # delta_f solves delta_f = steer - D_f Fy_f(delta_f), Fy_f the lateral force of the front tires in their own frame
    # (what deflects the steering linkage and the suspension), which itself depends on delta_f. Newton steps on
    # g(d) = d - steer + D_f Fy_f(d) with the slope dFy_f/dd taken as the tires' cornering stiffness at their loads,
    # sum of Ky(Fz) (exact for linear tires: one step solves it from any start; past the linear range each step
    # still shrinks the error, by at least the factor D_f Ky / (1 + D_f Ky), 1/3 with the defaults), from the
    # steady-state value d0 = steer - D_f m load_ay b / L
    loads = {}
    for w in WHEELS:
        is_front = front[w]
        fz = (static[is_front] + (-1 if is_front else 1) * longitudinal_transfer
              - LEFT_SIDE[w] * m * s["load_ay"] * h * roll_share[is_front] / track[is_front])
        loads[w] = ca.fmax(fz, 0)  # a lifted wheel carries no load

    def kinematics(w, delta):
        x_i, y_i = position[w]
        contact_x, contact_y = vx - r * y_i, vy + r * x_i
        return (contact_x * ca.cos(delta) + contact_y * ca.sin(delta),
                -contact_x * ca.sin(delta) + contact_y * ca.cos(delta))

    def front_lateral(delta):
        return sum(wheel_forces(wheel_coefficients(s, w), loads[w], *kinematics(w, delta),
                                s[f"wheel_speed_{w}"] * radius)[1] for w in ("fl", "fr"))

    compliance = s["steer_compliance"]
    slope = sum(cornering_stiffness(wheel_coefficients(s, w), loads[w]) for w in ("fl", "fr"))
    steer_front = s["steer"] - compliance * m * s["load_ay"] * b / wheelbase
    for _ in range(COMPLIANCE_NEWTON_STEPS):
        steer_front = steer_front - ((steer_front - s["steer"] + compliance * front_lateral(steer_front))
                                     / (1 + compliance * slope))
    wheel = {}
    for w in WHEELS:
        x_i, y_i = position[w]
        is_front = front[w]
        side = LEFT_SIDE[w]
        fz = loads[w]
        delta = steer_front if is_front else 0
        wheel_x, wheel_y = kinematics(w, delta)
        omega, mode = s[f"wheel_speed_{w}"], s[f"wheel_mode_{w}"]
        coefficients = wheel_coefficients(s, w)
        fx, fy, mux, muy = wheel_forces(coefficients, fz, wheel_x, wheel_y, omega * radius)
        wheel_brake = brake_share[is_front] * brake_torque / 2
        wheel_drive = drive_share[is_front] * drive_torque / 2
        # quasi-static: the torque on a rolling wheel besides the tire's, its brake and rolling resistance
        # against its direction of rolling (the mode)
        rolling_torque = s["rolling_resistance"] * fz * radius
        applied = wheel_drive - mode * (wheel_brake + rolling_torque)
        wheel[w] = dict(x_i=x_i, y_i=y_i, is_front=is_front, fz=fz, delta=delta, wheel_x=wheel_x, wheel_y=wheel_y,
                        omega=omega, mode=mode, coefficients=coefficients, fx=fx, fy=fy, mux=mux, muy=muy,
                        wheel_brake=wheel_brake, wheel_drive=wheel_drive, rolling_torque=rolling_torque,
                        applied=applied)

    # quasi-static: every rolling wheel's spin accelerates with the body, I_w a_x / R^2 of force per wheel:
    # m a_x = sum over rolling wheels (applied / R - I_w a_x / R^2) + sum over locked wheels Fx + drag, so
    # a_x = (sum applied / R + sum locked Fx + drag) / (m + n_rolling I_w / R^2) (straight ahead; steer ignored),
    # each rolling wheel's applied / R clipped to its tire's capacity (a demand beyond the peak gets the peak force:
    # unclipped, a light car's full drive gave an a_x whose inertia demand locked the undriven wheels, which the
    # hold test then released, without end)
    curve = force_curve()
    for w in WHEELS:
        c = wheel[w]
        c["arguments"] = (c["fz"], c["wheel_x"], c["wheel_y"],
                          ca.vertcat(*[c["coefficients"][key] for key in SLOT_KEYS]))
        c["peak"] = peak_slip(c["coefficients"], c["fz"])
        c["capacity"] = curve(c["peak"], *c["arguments"])[0]
    rolling_mass = sum(wheel[w]["mode"] ** 2 for w in WHEELS) * inertia / radius**2
    drag = -0.5 * s["air_density"] * s["drag_area"] * vx * ca.fabs(vx)

    def clipped(force, capacity):
        return ca.fmin(ca.fmax(force, -capacity), capacity)

    ax_sum = sum(wheel[w]["mode"] ** 2 * clipped(wheel[w]["applied"] / radius, wheel[w]["capacity"])
                 + (1 - wheel[w]["mode"] ** 2) * wheel[w]["fx"] for w in WHEELS) + drag
    ax_estimate = ax_sum / (m + rolling_mass)

    force_x = force_y = yaw_moment = 0
    friction_used = 0
    spin_derivatives, wheel_indicators, wheel_modes = [], [], []
    all_forward = 1  # every wheel rolls forward (all modes +1)
    none_backward = 1  # no wheel rolls backward (all modes 0 or +1)
    for w in WHEELS:
        c = wheel[w]
        x_i, y_i, fz, delta, mode, omega = c["x_i"], c["y_i"], c["fz"], c["delta"], c["mode"], c["omega"]
        wheel_x, wheel_y, wheel_brake, wheel_drive = c["wheel_x"], c["wheel_y"], c["wheel_brake"], c["wheel_drive"]
        fx_dynamic, fy_dynamic, mux, muy = c["fx"], c["fy"], c["mux"], c["muy"]

        # quasi-static rolling wheel: the slip at which the tire gives the force the torque balance asks for
        slip_speed = ca.sqrt(wheel_x**2 + SLIP_SPEED_FLOOR**2)
        arguments = c["arguments"]
        demand = c["applied"] / radius - inertia * ax_estimate / radius**2  # the force the wheel needs
        capacity = c["capacity"]
        slip = quasi_static_slip(lambda kappa: curve(kappa, *arguments), c["peak"], capacity, ca.fabs(demand))
        kappa = ca.if_else(demand >= 0, slip, -slip)
        fx_quasi, fy_quasi = curve(kappa, *arguments)[:2]
        quasi_rolling = ca.logic_and(quasi_static, mode != 0)
        fx = ca.if_else(quasi_rolling, fx_quasi, fx_dynamic)
        fy = ca.if_else(quasi_rolling, fy_quasi, fy_dynamic)

        body_x = fx * ca.cos(delta) - fy * ca.sin(delta)
        body_y = fx * ca.sin(delta) + fy * ca.cos(delta)
        force_x += body_x
        force_y += body_y
        yaw_moment += x_i * body_y - y_i * body_x

        net_torque = wheel_drive - fx * radius
        rolling_torque = c["rolling_torque"]
        spin_torque = net_torque - mode * wheel_brake - rolling_torque * smooth_sign(omega, SPIN_SMOOTHING)
        # quasi-static: the spin follows the slip's spin (wheel_x + kappa slip_speed) / R without stiffness
        spin_quasi = ax_estimate / radius + ((wheel_x + kappa * slip_speed) / radius - omega) / SPIN_RELAXATION_TIME
        spin_derivatives.append(ca.if_else(quasi_static, moving * mode**2 * spin_quasi,
                                           moving * mode**2 * spin_torque / s["wheel_inertia"]))
        # rolling: event when the spin has passed 0 (by SPIN_HYSTERESIS against the mode); locked: event when the
        # brake can no longer hold (indicator |T_net| - T_brake, negative while it holds). Forward rolling is
        # positive, locked and backward rolling negative: a wheel that locks from forward rolling, or is released
        # forward, keeps its indicator's sign through the event.
        # Quasi-static rolling: event when the brake asks more than the tire's peak force (the wheel locks), or when
        # the contact point has turned back (by DIRECTION_HYSTERESIS); positive while it rolls.
        # quasi-static: a locked wheel is also held while its brake exceeds the drive by RELEASE_SHARE of the rolling
        # tire's peak torque (a locked, steered tire can push harder than the rolling one's peak along its axis;
        # without this a wheel released below that force would lock again at once). Its rolling resistance counts
        # with the brake, as in the lock test: a rolling resistance above the peak force locks the wheel for good
        # instead of locking and releasing it in one event iteration.
        # the body's acceleration were this (locked) wheel released forward: its sliding force replaced by its rolling
        # demand, its inertia added; released, it must pass the lock test with the margin 1 - RELEASE_SHARE
        locked = 1 - mode**2
        rolling_demand = clipped((wheel_drive - wheel_brake - rolling_torque) / radius, capacity)
        ax_released = (ax_sum + locked * (rolling_demand - fx)) / (m + rolling_mass + locked * inertia / radius**2)
        hold_margin = ca.if_else(quasi_static,
                                 wheel_brake + rolling_torque
                                 - ca.fmin(ca.fabs(net_torque), wheel_drive + RELEASE_SHARE * radius * capacity
                                           - inertia * ax_released / radius),
                                 wheel_brake - ca.fabs(net_torque))
        holds = hold_margin > 0
        spin_indicator = omega + mode * SPIN_HYSTERESIS
        lock_margin = radius * (capacity - ca.fmax(-mode * demand, 0))
        direction = mode * wheel_x + DIRECTION_HYSTERESIS
        rolling_indicator = ca.if_else(quasi_static, ca.fmin(lock_margin, direction), spin_indicator)
        wheel_indicators.append(ca.if_else(stopped, HELD_WHEEL_INDICATOR,
                                           ca.if_else(mode == 0, -hold_margin, rolling_indicator)))
        reversed_spin = mode * spin_indicator <= 0
        rolling = ca.if_else(reversed_spin, ca.if_else(holds, 0, -mode), mode)
        turned = ca.if_else(wheel_brake > ca.fabs(wheel_drive), 0, -mode)
        rolling_quasi = ca.if_else(direction <= 0, turned, ca.if_else(lock_margin <= 0, 0, mode))
        released = ca.if_else(holds, 0, ca.if_else(net_torque >= 0, 1, -1))
        wheel_modes.append(ca.if_else(mode == 0, released, ca.if_else(quasi_static, rolling_quasi, rolling)))
        all_forward = all_forward * (mode > 0)
        none_backward = none_backward * (mode >= 0)
        friction_used += ca.sqrt((fx / ca.fmax(mux * fz, TINY)) ** 2 + (fy / ca.fmax(muy * fz, TINY)) ** 2) / 4

    ax = moving * (force_x + drag) / m
    ay = moving * force_y / m
    speed = ca.sqrt(vx**2 + vy**2)
    smooth_speed = ca.sqrt(vx**2 + vy**2 + SPEED_SMOOTHING**2) - SPEED_SMOOTHING
    tau = s["load_transfer_time_constant"]
    derivative = {
        **body_derivatives(s, moving, ax, ay, yaw_moment, smooth_speed),
        **{f"wheel_speed_{w}": spin for w, spin in zip(WHEELS, spin_derivatives)},
        "load_ax": (ax - s["load_ax"]) / tau,
        "load_ay": (ay - s["load_ay"]) / tau,
    }

    # Standstill: the drive force at rest against what brakes and rolling resistance can hold (m/s2).
    # It depends on inputs and parameters only, so it is constant inside a communication step.
    launch_force = s["throttle"] * s["drive_torque_max"] / radius
    holding_force = brake_torque / radius + s["rolling_resistance"] * m * g
    drive_excess = (launch_force - holding_force) / m - START_MARGIN
    # moving: event when the speed has fallen to STOP_SPEED and the drive cannot keep it going; rolling forward
    # on every wheel, the speed is the forward speed: the half-line vx <= STOP_SPEED, which no step can pass
    # through. Held: event when the drive exceeds the holding forces. The moving indicator equals drive_excess
    # (the held indicator) at a start, and both are <= 0 at a stop: neither event changes its sign.
    # Quasi-static (explicit fixed-step integrators): a car on locked wheels is a stiff damper near standstill (the
    # slip's speed floor), so one step can carry vx from above STOP_SPEED to below -STOP_SPEED; while no wheel rolls
    # backward the stop is the half-line max(vx, |vy|) <= STOP_SPEED too (a car sliding backward on locked wheels
    # after a spin is held once its sideways speed has fallen to STOP_SPEED).
    at_rest = ca.if_else(ca.logic_and(quasi_static, none_backward), ca.fmax(vx, ca.fabs(vy)),
                         ca.if_else(all_forward, vx, speed)) - STOP_SPEED
    moving_indicator = ca.fmax(at_rest, drive_excess)
    indicator = ca.if_else(stopped, drive_excess, moving_indicator)
    next_stopped = ca.if_else(stopped, drive_excess <= 0, moving_indicator <= 0)
    # at rest every wheel is still (mode 0); a locked wheel's spin is held at 0
    next_mode = {w: (1 - next_stopped) * mode for w, mode in zip(WHEELS, wheel_modes)}
    next_discrete = {"stopped": next_stopped, **{f"wheel_mode_{w}": next_mode[w] for w in WHEELS}}
    zeroed = {name: next_stopped for name in ("vx", "vy", "yaw_rate")}
    zeroed.update({f"wheel_speed_{w}": next_mode[w] == 0 for w in WHEELS})
    states = interface.names(STATE)
    # a vehicle that starts slower than STOP_SPEED with no drive starts held
    starts_held = (s["v0"] <= STOP_SPEED) * (drive_excess <= 0)
    initial = {name: 0 for name in states}
    initial.update({"x": s["x0"], "y": s["y0"], "psi": s["psi0"], "vx": (1 - starts_held) * s["v0"],
                    **{f"wheel_speed_{w}": (1 - starts_held) * s["v0"] / radius for w in WHEELS}})
    initial_discrete = {"stopped": starts_held, **{f"wheel_mode_{w}": 1 - starts_held for w in WHEELS}}

    return Equations(
        interface=interface,
        symbols=s,
        derivatives=ca.vertcat(*[derivative[name] for name in states]),
        outputs={"v": speed, "ax": ax, "ay": ay, "friction_used": moving * friction_used},
        event_indicators=ca.vertcat(indicator, *wheel_indicators),
        state_update=ca.vertcat(*[ca.if_else(zeroed[name], 0, s[name]) if name in zeroed else s[name]
                                  for name in states]),
        discrete_update=ca.vertcat(*[next_discrete[name] for name in interface.names(DISCRETE)]),
        initial_states=ca.vertcat(*[initial[name] for name in states]),
        initial_discrete=ca.vertcat(*[initial_discrete[name] for name in interface.names(DISCRETE)]),
    )
