"""SDL "simple dynamics": a planar vehicle with side slip and yaw on four friction-limited wheels.

States: x, y, psi, s, body velocities vx, vy and the yaw rate r. The centre of gravity lies midway
between the axles (a = b = wheelbase / 2) and each wheel carries a quarter of the weight, Fz = m g / 4
(no load transfer), so on uniform mu straight-line braking meets the closed forms v0^2 / (2 a) exactly.
Wheel i sits at (x_i, y_i): front x = +a, rear x = -b, left y = +track / 2, right y = -track / 2; the
front wheels are steered by `steer` (parallel steer). Per wheel, with the contact-point velocity
(vx - r y_i, vy + r x_i), in the wheel frame (u_i, w_i):

  rolling   (brake demand m a_b / 4 <= mu_i Fz): the wheel delivers its share of the pedal demand,
            longitudinal first, within its friction circle, and the lateral force from the lateral slip
            s_i = w_i / sqrt(u_i^2 + v_low^2) with the cornering stiffness C_i, within what is left:
              F_u = clamp(m (a_drive - sigma_i a_brake) / 4, -mu_i Fz, mu_i Fz) - sigma_i f_r Fz
              F_w = clamp(-C_i s_i, -sqrt((mu_i Fz)^2 - F_u^2), +sqrt(...))
  held      (a rolling wheel whose along force resists its rolling: the brake and the rolling resistance can at
            most stop its spin): its along force is at most the along share of the same force turned against the
            sliding velocity, its across force at least the across share (n = sqrt(|c_i|^2 + (rho_p r)^2)):
              F_u = -sigma_i min(-sigma_i F_u,roll, |F_roll| sigma_i u_i / n),
              |F_w| = max(|F_w,roll|, |F_roll| |w_i| / n)
            With a small slip angle this is the rolling force; once the wheel slides more sideways than its rolling
            force points it stands still and pushes -|F_roll| c_i / n. Continuous: the along force passes through
            u_i = 0 while the wheel slides sideways, with no Coulomb jump that would stick it there.
  sliding   (brake demand > mu_i Fz: the brake locks the wheel): it slides; its force opposes its
            contact point's sliding velocity c_i, with no lateral guidance left:
              F = -(mu_i + f_r) Fz c_i / sqrt(|c_i|^2 + (rho_p r)^2)   (rho_p: CONTACT_PATCH_RADIUS)
  sigma_i = +1 while the wheel rolls (slides) forward, -1 backward: a discrete state switched by an event
            when the longitudinal contact velocity crosses 0 (a held or locked wheel: once it has turned back
            by DIRECTION_HYSTERESIS of its sideways velocity), so that brake and rolling resistance
            oppose the motion exactly (Coulomb friction) and the right-hand side is continued smoothly
            past the crossing inside a solver step.
  Body      m (dvx/dt - r vy) = sum F_x - rho CdA |v| vx / 2,  m (dvy/dt + r vx) = sum F_y - rho CdA |v| vy / 2
            Iz dr/dt = sum (x_i F_y,i - y_i F_x,i)
            dx/dt = vx cos psi - vy sin psi, dy/dt = vx sin psi + vy cos psi, dpsi/dt = r, ds/dt = |v|.

The vehicle does not drive backwards: when it comes to rest it is held (discrete state `stopped`) until the drive
exceeds the holding forces. At rest means the whole planar motion: rolling forward on every wheel, the forward
speed reaches 0 with the sideways motion sqrt(vy^2 + (r L / 2)^2) below STOP_SPEED; otherwise the motion
sqrt(vx^2 + vy^2 + (r L / 2)^2) falls below STOP_SPEED.
"""

from __future__ import annotations

import casadi as ca

from ..interface import DISCRETE, STATE, load_interface
from ..names import SHIPPED_MODELS, WHEELS
from ..units import STANDARD_GRAVITY
from .equations import Equations, make_symbols
from .planar import body_derivatives

MODEL_NAME = SHIPPED_MODELS["simple"]
# Holding margin: the net tire force must exceed the holding forces by this much (m/s2) to start moving;
# it keeps the at-rest event indicator strictly negative when nothing pushes.
START_MARGIN = 1e-6
# Speed below which the power limit of the drive is not evaluated (m/s), to avoid P / 0.
POWER_LIMIT_MIN_SPEED = 1e-3
# v_low of the lateral slip w / sqrt(u^2 + v_low^2) (m/s): finite at standstill, where the tire acts as
# a stiff viscous damper (time constant m v_low / (4 C) ~ 1 ms, which the L-stable solver handles).
SLIP_SPEED_FLOOR = 0.1
# A vehicle is held once its motion falls below this (m/s): moving forward on every wheel, once its forward speed is
# not positive and its sideways motion sqrt(vy^2 + (r L / 2)^2) is below it (a straight stop: the half-line vx <= 0,
# which no step can jump over); otherwise (spun, sliding) once its whole motion sqrt(vx^2 + vy^2 + (r L / 2)^2) is.
# What such a stop takes away is at most m STOP_SPEED^2 / 2 (0.075 J at 1500 kg).
STOP_SPEED = 0.01
# Event indicator of a wheel while the vehicle is held (m/s): constant, negative like the wheel indicators
# that cross at a forward stop, so the stop does not flip their sign.
HELD_WHEEL_INDICATOR = -1.0
# Smoothing of |v| at v = 0 (m/s): keeps derivatives finite; it changes |v| by < 1e-12 m/s.
SPEED_SMOOTHING = 1e-12
# Radius of the contact patch (m): a sliding wheel whose contact point turns about a centre closer than
# this gives less than mu Fz (see sliding_norm).
CONTACT_PATCH_RADIUS = 0.1
TINY = 1e-30  # floor of denominators that vanish only at exact rest
# A sliding wheel's direction switches once its along velocity has turned back by this share of its sideways velocity
# (the force's error from continuing the sliding norm past the switch is below twice this share)
DIRECTION_HYSTERESIS = 1e-3


def clamp(value, low, high):
    return ca.fmin(ca.fmax(value, low), high)


def smooth_norm(a, b):
    """sqrt(a^2 + b^2) with finite derivatives at 0 (exact to round-off elsewhere)."""
    return ca.sqrt(a**2 + b**2 + SPEED_SMOOTHING**2) - SPEED_SMOOTHING


def sliding_norm(sigma, u, w, spin):
    """|(u, w)| of a sliding contact point, regularised by its patch and continued past u = 0.

    With q^2 = u^2 + w^2 + spin^2 (spin = CONTACT_PATCH_RADIUS * yaw rate: when the instantaneous centre
    of rotation comes within the contact patch, part of the patch sticks and the force drops below
    mu Fz instead of turning infinitely fast), q = |u| + (w^2 + spin^2) / (q + |u|). Replacing |u| by
    sigma u changes nothing on the side sigma describes and makes the sliding direction constant through
    u = 0 in straight-line motion (w = spin = 0): the locked wheel keeps pushing against the motion up
    to the stop, which an event then locates. Past u = 0 with w or spin != 0 (only inside the solver
    step before the event switches sigma), the norm is kept >= |c| / 2 so the force stays bounded.
    """
    lateral = w**2 + spin**2
    length = ca.sqrt(u**2 + lateral + TINY**2)
    norm = sigma * u + lateral / ca.fmax(length + ca.fabs(u), TINY)
    bound = ca.fmax(ca.sqrt(u**2 + w**2 + TINY**2) / 2, TINY)
    return ca.if_else(ca.fabs(norm) >= bound, norm, ca.if_else(norm < 0, -bound, bound))


def wheel_positions(s):
    half_wheelbase, half_track = s["wheelbase"] / 2, s["track"] / 2
    return {"fl": (half_wheelbase, half_track), "fr": (half_wheelbase, -half_track),
            "rl": (-half_wheelbase, half_track), "rr": (-half_wheelbase, -half_track)}


def equations() -> Equations:
    interface = load_interface(MODEL_NAME)
    s = make_symbols(interface)
    g = STANDARD_GRAVITY
    m = s["mass"]
    vx, vy, r, psi, stopped = s["vx"], s["vy"], s["yaw_rate"], s["psi"], s["stopped"]
    moving = 1 - stopped
    speed = smooth_norm(vx, vy)

    drive_accel = s["throttle"] * ca.fmin(
        s["drive_accel_max"], s["drive_power_max"] / (m * ca.fmax(speed, POWER_LIMIT_MIN_SPEED)))
    brake_accel = s["brake"] * s["brake_decel_max"]
    load = m * g / 4
    rolling = s["rolling_resistance"] * load

    force_x = force_y = yaw_moment = friction_used = 0
    wheel_indicators, next_sigma = [], {}
    forward = 1  # every wheel moves forward (all sigma = +1)
    for w, (x_i, y_i) in wheel_positions(s).items():
        sigma = s[f"direction_{w}"]
        limit = s[f"mu_{w}"] * load
        delta = s["steer"] if w.startswith("f") else 0
        stiffness = s["cornering_stiffness_front"] if w.startswith("f") else s["cornering_stiffness_rear"]
        contact_x, contact_y = vx - r * y_i, vy + r * x_i
        cos_d, sin_d = ca.cos(delta), ca.sin(delta)
        along = contact_x * cos_d + contact_y * sin_d  # wheel frame
        across = -contact_x * sin_d + contact_y * cos_d

        # rolling: demand first, lateral slip force within what the friction circle leaves
        longitudinal = clamp(m * (drive_accel - sigma * brake_accel) / 4, -limit, limit)
        available = ca.sqrt(ca.fmax(limit**2 - longitudinal**2, 1e-12))
        lateral_slip = across / ca.sqrt(along**2 + SLIP_SPEED_FLOOR**2)
        lateral = clamp(-stiffness * lateral_slip, -available, available)
        roll_u = longitudinal - sigma * rolling
        # held: the brake and the rolling resistance can at most stop the wheel's spin. A wheel stood still slides
        # against its contact point's sliding velocity with the force it had rolling, |F_roll| (Coulomb friction,
        # regularised by the contact patch as a locked wheel's). So a wheel whose along force resists its rolling
        # (resisting > 0) gives along no more than the sliding force's along share, and across no less than its
        # across share:
        #   F_u = -sigma min(resisting, |F_roll| sigma u / n),   |F_w| = max(|F_roll,w|, |F_roll| |w| / n)
        # (n: sliding_norm, continued past u = 0 as sigma u). Rolling with a small slip angle the first terms
        # hold: the rolling force. Sliding more sideways than the rolling force points, both second terms: the
        # wheel is held (it no longer turns) and pushes -|F_roll| c / n. Each component is continuous (a min or
        # max of continuous terms): the along force passes through u = 0 without a Coulomb jump while the wheel
        # slides sideways (a Coulomb jump there makes the wheel stick at u = 0 and its direction switch without
        # end). In a straight stop (w = 0, r = 0) n = sigma u and the rolling force is exact.
        resisting = -sigma * roll_u
        roll_norm = ca.sqrt(roll_u**2 + lateral**2 + TINY**2)
        patch = CONTACT_PATCH_RADIUS * r
        held_norm = sliding_norm(sigma, along, across, patch)
        along_share = roll_norm * sigma * along / held_norm
        held = ca.logic_and(resisting > 0, along_share < resisting)
        held_u = ca.if_else(resisting > 0, -sigma * ca.fmin(resisting, along_share), roll_u)
        across_share = -roll_norm * across / held_norm
        held_w = ca.if_else(ca.logic_and(resisting > 0, ca.fabs(across_share) > ca.fabs(lateral)), across_share,
                            lateral)
        roll_x, roll_y = held_u * cos_d - held_w * sin_d, held_u * sin_d + held_w * cos_d

        # locked: sliding against the contact point's velocity, whatever the steering
        locked = m * brake_accel / 4 > limit
        scale = -(limit + rolling) / sliding_norm(sigma, contact_x, contact_y, CONTACT_PATCH_RADIUS * r)
        slide_x, slide_y = scale * contact_x, scale * contact_y

        f_x = ca.if_else(locked, slide_x, roll_x)
        f_y = ca.if_else(locked, slide_y, roll_y)
        force_x += f_x
        force_y += f_y
        yaw_moment += x_i * f_y - y_i * f_x
        tire_force = ca.if_else(locked, limit, ca.sqrt((held_u + sigma * rolling) ** 2 + held_w**2 + TINY**2))
        friction_used += tire_force / ca.fmax(limit, TINY) / 4

        # direction of motion of the wheel: rolling along its own axis, sliding along the body axis (the motion
        # itself, not sigma times it: a switch of sigma keeps the indicator's sign). No hysteresis for a rolling
        # wheel: one whose rolling resistance holds it at the switch (Coulomb sticking) would switch back and forth
        # across a band, an event every few nanoseconds. A sliding wheel (locked or held) has no such jump: its
        # force turns smoothly through the switch and damps the along velocity toward 0, where it may stay while
        # the wheel slides sideways; it switches once its along velocity has turned back by DIRECTION_HYSTERESIS
        # of its sideways velocity, so that round-off about 0 does not switch it without end
        sideways_slide = ca.sqrt(ca.if_else(locked, contact_y, across) ** 2 + patch**2)
        indicator = (ca.if_else(locked, contact_x, along)
                     + ca.if_else(ca.logic_or(locked, held), sigma * DIRECTION_HYSTERESIS * sideways_slide, 0))
        wheel_indicators.append(ca.if_else(stopped, HELD_WHEEL_INDICATOR, indicator))
        next_sigma[w] = ca.if_else(indicator > 0, 1, ca.if_else(indicator < 0, -1, sigma))
        forward = forward * (sigma > 0)

    drag = s["air_density"] * s["drag_area"] / 2 * speed
    ax = moving * (force_x - drag * vx) / m
    ay = moving * (force_y - drag * vy) / m
    derivative = body_derivatives(s, moving, ax, ay, yaw_moment, speed)

    # Standstill. The net force at rest (per unit mass) that could start the vehicle forward:
    start_drive = s["throttle"] * ca.fmin(s["drive_accel_max"],
                                          s["drive_power_max"] / (m * POWER_LIMIT_MIN_SPEED))
    start_force = sum(clamp(start_drive - brake_accel, -s[f"mu_{w}"] * g, s[f"mu_{w}"] * g) for w in WHEELS) / 4
    net_start = start_force - s["rolling_resistance"] * g
    drive_excess = net_start - START_MARGIN
    wants_to_move = drive_excess > 0
    # held: event when the drive could start it (drive_excess > 0). Moving: event when it comes to rest and the
    # drive could not keep it going. At rest is a statement on the whole planar motion (no stop while the car
    # slides sideways or turns at vx = 0): moving forward on every wheel, vx <= 0 with the sideways motion below
    # STOP_SPEED (in a straight stop the half-line vx <= 0, which no step of any length can pass through);
    # otherwise (spun, sliding) the whole motion below STOP_SPEED.
    # The moving indicator is > 0 exactly where the vehicle stays moving, and equals drive_excess (the held
    # indicator) at a start, so neither event changes its sign.
    sideways = ca.sqrt(vy**2 + (r * s["wheelbase"] / 2) ** 2 + TINY**2)
    motion = ca.sqrt(vx**2 + sideways**2)
    at_rest = ca.if_else(forward, ca.fmax(vx, sideways - STOP_SPEED), motion - STOP_SPEED)
    moving_indicator = ca.fmax(at_rest, drive_excess)
    indicator = ca.if_else(stopped, drive_excess, moving_indicator)
    next_stopped = ca.if_else(stopped, 1 - wants_to_move, moving_indicator <= 0)

    states = interface.names(STATE)
    velocity = {"vx", "vy", "yaw_rate"}
    next_state = [ca.if_else(next_stopped, 0, s[name]) if name in velocity else s[name] for name in states]
    next_discrete = {"stopped": next_stopped,
                     **{f"direction_{w}": ca.if_else(next_stopped, 1, next_sigma[w]) for w in WHEELS}}
    initial = {"x": s["x0"], "y": s["y0"], "psi": s["psi0"], "s": 0, "vx": s["v0"], "vy": 0, "yaw_rate": 0}
    initial_discrete = {"stopped": 0, **{f"direction_{w}": 1 for w in WHEELS}}

    return Equations(
        interface=interface,
        symbols=s,
        derivatives=ca.vertcat(*[derivative[name] for name in states]),
        outputs={"v": moving * speed, "ax": ax, "ay": ay, "friction_used": moving * friction_used},
        event_indicators=ca.vertcat(indicator, *wheel_indicators),
        state_update=ca.vertcat(*next_state),
        discrete_update=ca.vertcat(*[next_discrete[name] for name in interface.names(DISCRETE)]),
        initial_states=ca.vertcat(*[initial[name] for name in states]),
        initial_discrete=ca.vertcat(*[initial_discrete[name] for name in interface.names(DISCRETE)]),
    )
