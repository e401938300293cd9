"""The example AEB controller (ExampleAeb): a forward-collision warning and two braking stages on the time to
collision, after the AEB component of Eclipse openPASS (its reference: example_aeb.md beside this file).

A sampled controller, so a model without continuous states: its discrete states (one flag per stage and the brake
hold) settle on the inputs by the runtime's event iteration at the start of each step, and its outputs are computed
from the settled flags, so they answer the inputs of the same instant (direct feedthrough). Per stage k with
threshold T_k, f = deactivation_factor (openPASS: 1.5):

    on_k' = (TTC <= f T_k) if on_k else (TTC < T_k)

The input TTC is large (sdl-fmu's lead_ttc: 1000 s) while the gap does not close, which switches every stage off.
With brake_to_stop, a braking stage that has acted is followed by a hold of the partial deceleration while the ego
still closes on the lead vehicle (relative_speed < 0):

    holding' = brake_to_stop and closing and (holding or partial_on' or full_on')

The update is idempotent (applying it twice to the same inputs gives the same flags), so the outputs computed from
one application equal those of the settled state.
"""

from __future__ import annotations

import casadi as ca

from ..dynamics.equations import Equations, make_symbols
from ..interface import DISCRETE, load_interface
from ..names import EXAMPLE_CONTROLLER, SHIPPED_CONTROLLERS

MODEL_NAME = SHIPPED_CONTROLLERS[EXAMPLE_CONTROLLER]


def _stage(on: ca.SX, ttc: ca.SX, threshold: ca.SX, factor: ca.SX) -> ca.SX:
    """A stage's next flag: on below its threshold, off above factor x its threshold (1.0 / 0.0)."""
    return ca.if_else(on > 0.5, ttc <= factor * threshold, ttc < threshold)


def equations() -> Equations:
    interface = load_interface(MODEL_NAME)
    s = make_symbols(interface)
    ttc, factor = s["ttc"], s["deactivation_factor"]
    warning = _stage(s["warning_on"], ttc, s["ttc_warning"], factor)
    partial = _stage(s["partial_on"], ttc, s["ttc_partial"], factor)
    full = _stage(s["full_on"], ttc, s["ttc_full"], factor)
    closing = s["relative_speed"] < 0
    braked = ca.logic_or(s["holding"] > 0.5, ca.logic_or(partial, full))
    holding = ca.logic_and(s["brake_to_stop"] > 0.5, ca.logic_and(closing, braked))
    partial_acts = ca.logic_or(partial, holding)
    active = ca.logic_or(full, partial_acts)
    stage = ca.if_else(full, 3, ca.if_else(partial_acts, 2, ca.if_else(warning, 1, 0)))
    deceleration = ca.if_else(full, s["deceleration_full"], ca.if_else(partial_acts, s["deceleration_partial"], 0))
    update = {"warning_on": warning, "partial_on": partial, "full_on": full, "holding": holding}
    empty = ca.SX(0, 1)
    return Equations(
        interface=interface,
        symbols=s,
        derivatives=empty,
        outputs={"warning": warning, "stage": stage, "active": active, "deceleration_request": deceleration,
                 "throttle_request": ca.SX(0)},
        event_indicators=empty,
        state_update=empty,
        discrete_update=ca.vertcat(*[update[name] for name in interface.names(DISCRETE)]),
        initial_states=empty,
        initial_discrete=ca.SX.zeros(len(interface.names(DISCRETE)), 1),
    )
