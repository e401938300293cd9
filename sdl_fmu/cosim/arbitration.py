"""Arbitration: the ego's commands from the driver's (the built-in driver's, or BRK's while a brake event holds the
pedals) and a controller's requests, per channel by the controller map's rules (docs/controllers.md):

- `driver`: the driver's command; the controller's request on that channel is ignored;
- `override`: the controller's request while it is active, else the driver's;
- `max`: the larger of the two while the controller is active (pedals only), else the driver's.

The controller's brake request is the larger of its brake pedal and its deceleration / brake_decel_max (each where
mapped). While the controller is active and its brake request counts (rule not `driver`) and is above zero, the
throttle is 0, as BRK cuts it. Pedals are limited to 0..1 and the steer to +-MAX_STEER (the road-wheel angle the
trigger bounds assume). A pure function of its arguments: the scenario FMU computes the same."""

from __future__ import annotations

from ..vehicle.controller import Request
from .driver import MAX_STEER


def _pedal(value: float) -> float:
    return 0.0 if value < 0.0 else 1.0 if value > 1.0 else value


def requested_brake(request: Request, brake_decel_max: float) -> float | None:
    """The controller's brake pedal request (not yet limited): the larger of its brake pedal and its deceleration
    turned into pedal (a / brake_decel_max); None when it requests neither."""
    brake, deceleration = request.brake, request.deceleration
    if deceleration is not None:
        from_deceleration = deceleration / brake_decel_max
        brake = from_deceleration if brake is None or from_deceleration > brake else brake
    return brake


def arbitrate(driver: tuple[float, float, float], request: Request, rules: dict[str, str],
              brake_decel_max: float) -> tuple[float, float, float]:
    """(throttle, brake, steer) sent to the ego, from the driver's (throttle, brake, steer) and the request."""
    if not request.active:
        return driver
    throttle, brake, steer = driver
    rule = rules["brake"]
    wanted = requested_brake(request, brake_decel_max) if rule != "driver" else None
    if wanted is not None:
        pedal = _pedal(wanted)
        brake = pedal if rule == "override" or pedal > brake else brake
    rule = rules["throttle"]
    if rule != "driver" and request.throttle is not None:
        pedal = _pedal(request.throttle)
        throttle = pedal if rule == "override" or pedal > throttle else throttle
    if wanted is not None and wanted > 0.0:
        throttle = 0.0
    if rules["steer"] == "override" and request.steer is not None:
        steer = request.steer
        steer = -MAX_STEER if steer < -MAX_STEER else MAX_STEER if steer > MAX_STEER else steer
    return throttle, brake, steer
