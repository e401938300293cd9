"""SDL "simple dynamics": a planar point-mass vehicle on friction-limited tires.

Each wheel carries a quarter of the weight (no load transfer) and gives at most mu_i * g per unit
mass. Longitudinal demand (drive minus brake) is served first, up to each wheel's limit; cornering
gets what is left of that wheel's friction circle, so under full braking no steering authority is
left. Drag and rolling resistance act on top of the tire forces, as in the closed form
dv/dt = -(min(brake * brake_decel_max, mu g) + f_r g + rho CdA v^2 / (2 m)).
The vehicle only drives forward: when it comes to rest it is held (discrete state `stopped`) until
the tire force exceeds the holding forces.
"""

from __future__ import annotations

import casadi as ca

from ..interface import load_interface
from ..units import STANDARD_GRAVITY
from .equations import Equations, make_symbols

MODEL_NAME = "EgoVehicleSimple"
WHEELS = ("fl", "fr", "rl", "rr")
# Holding margin: the net tire force must exceed the holding forces by this much (m/s2) to start moving;
# it keeps the at-rest event indicator strictly negative when nothing pushes.
START_MARGIN = 1e-6
# Speed below which the power limit of the drive is not evaluated (m/s), to avoid P / 0.
POWER_LIMIT_MIN_SPEED = 1e-3


def friction_limited_accelerations(s, v):
    """Per-unit-mass tire accelerations (longitudinal, lateral scale) under each wheel's friction circle."""
    g = STANDARD_GRAVITY
    drive_demand = s["throttle"] * ca.fmin(
        s["drive_accel_max"], s["drive_power_max"] / (s["mass"] * ca.fmax(v, POWER_LIMIT_MIN_SPEED))
    )
    longitudinal_demand = drive_demand - s["brake"] * s["brake_decel_max"]
    lateral_demand = v**2 * ca.tan(s["steer"]) / s["wheelbase"]
    longitudinal, lateral_scale = [], []
    for wheel in WHEELS:
        limit = s[f"mu_{wheel}"] * g
        along = ca.fmin(ca.fmax(longitudinal_demand, -limit), limit)
        # what the friction circle leaves for cornering; the floor keeps d/dx sqrt finite at the limit
        available = ca.sqrt(ca.fmax(limit**2 - along**2, 1e-12))
        longitudinal.append(along)
        lateral_scale.append(available / ca.fmax(ca.fmax(ca.fabs(lateral_demand), available), 1e-9))
    return sum(longitudinal) / 4, sum(lateral_scale) / 4


def equations() -> Equations:
    interface = load_interface(MODEL_NAME)
    s = make_symbols(interface)
    g = STANDARD_GRAVITY
    v, psi, stopped = s["v"], s["psi"], s["stopped"]

    tire_acceleration, lateral_scale = friction_limited_accelerations(s, v)
    drag_factor = s["air_density"] * s["drag_area"] / (2 * s["mass"])  # K in dv/dt = -(A + K v^2)
    net_acceleration = tire_acceleration - s["rolling_resistance"] * g - drag_factor * v**2
    yaw_rate = v * ca.tan(s["steer"]) / s["wheelbase"] * lateral_scale
    moving = 1 - stopped
    dv = moving * net_acceleration

    derivatives = ca.vertcat(v * ca.cos(psi), v * ca.sin(psi), yaw_rate, v, dv)
    wants_to_move = net_acceleration > START_MARGIN
    # moving: event when v reaches 0; at rest: event when the net force could start the vehicle
    indicator = ca.if_else(stopped, net_acceleration - START_MARGIN, v)
    next_stopped = ca.if_else(stopped, 1 - wants_to_move, (v <= 0) * (1 - wants_to_move))
    next_v = ca.if_else(next_stopped, 0, ca.fmax(v, 0))
    mean_mu = sum(s[f"mu_{w}"] for w in WHEELS) / 4
    lateral_acceleration = v * yaw_rate

    return Equations(
        interface=interface,
        symbols=s,
        derivatives=derivatives,
        outputs={
            "vx": v,
            "vy": ca.SX(0),
            "ax": dv,
            "ay": lateral_acceleration,
            "yaw_rate": yaw_rate,
            "friction_used": moving
            * ca.sqrt(tire_acceleration**2 + lateral_acceleration**2)
            / (g * ca.fmax(mean_mu, 1e-9)),
        },
        event_indicators=indicator,
        state_update=ca.vertcat(s["x"], s["y"], psi, s["s"], next_v),
        discrete_update=next_stopped,
        initial_states=ca.vertcat(s["x0"], s["y0"], s["psi0"], 0, s["v0"]),
        initial_discrete=ca.SX(0),
    )
