"""The foreign AEB controller's logic, shared by its FMI 2.0 (PythonFMU) and FMI 3.0 (pythonfmu3) packagings: an
emergency brake latched on time to collision, with its own names and units (speeds in km/h, TTC in ms, the brake
request in %, a deceleration request in g).

Each step: when a valid object closes on the host (obj_valid, closing speed > 0) with ttc_ms / 1000 <= ttc_trigger
(s), the brake latches; latched, aeb_active is true, brake_cmd_pct is 100 % and decel_cmd is decel_g (g). The latch
never releases. The controller checks how it is stepped: every step must start where the previous one ended and last
cycle_time s; a step that does not (a re-step after a rollback, a step of another length) fails (do_step returns
False), so a run that completes shows it was stepped only forward, once per period.
"""

INPUTS = {  # name: (start, unit, description)
    "v_host": (0.0, "km/h", "host speed"),
    "obj_distance": (0.0, "m", "distance to the object ahead"),
    "v_rel": (0.0, "km/h", "object speed minus host speed (negative: closing)"),
    "ttc_ms": (0.0, "ms", "time to collision"),
}
BOOLEAN_INPUTS = {"obj_valid": (False, "an object is ahead in the host's path")}
INTEGER_INPUTS = {"obj_id": (0, "the object's id"), "crash_count": (0, "collisions so far")}
PARAMETERS = {
    "ttc_trigger": (1.5, "s", "time to collision at which the brake latches"),
    "decel_g": (0.7, "g", "deceleration request once latched"),
    "cycle_time": (0.01, "s", "the period the controller expects to be stepped at"),
}
OUTPUTS = {
    "brake_cmd_pct": (0.0, "%", "brake request, 0..100 %"),
    "decel_cmd": (0.0, "g", "deceleration request"),
    "latch_distance": (-1.0, "m", "obj_distance when the brake latched (-1 before)"),
}
BOOLEAN_OUTPUTS = {"aeb_active": (False, "the brake is latched")}
INTEGER_OUTPUTS = {"steps": (0, "steps taken")}
# FMI 3 UnitDefinitions: (factor, {base unit: exponent})
UNITS = {"km/h": (1 / 3.6, {"m": 1, "s": -1}), "m": (1.0, {"m": 1}), "ms": (1e-3, {"s": 1}), "s": (1.0, {"s": 1}),
         "%": (0.01, {}), "g": (9.80665, {"m": 1, "s": -2})}
STEP_TOLERANCE = 1e-9  # s: the master gives k x period and (k + 1) x period - k x period, exact to rounding


def defaults(controller) -> None:
    for table in (INPUTS, PARAMETERS, OUTPUTS, BOOLEAN_INPUTS, INTEGER_INPUTS, BOOLEAN_OUTPUTS, INTEGER_OUTPUTS):
        for name, entry in table.items():
            setattr(controller, name, entry[0])
    controller.latched = False
    controller.step_end = 0.0


def step(controller, current_time: float, step_size: float) -> bool:
    if abs(current_time - controller.step_end) > STEP_TOLERANCE \
            or abs(step_size - controller.cycle_time) > STEP_TOLERANCE:
        return False
    closing = controller.v_rel < 0.0
    if not controller.latched and controller.obj_valid and closing \
            and controller.ttc_ms / 1000.0 <= controller.ttc_trigger:
        controller.latched = True
        controller.latch_distance = controller.obj_distance
    controller.aeb_active = controller.latched
    controller.brake_cmd_pct = 100.0 if controller.latched else 0.0
    controller.decel_cmd = controller.decel_g if controller.latched else 0.0
    controller.steps += 1
    controller.step_end = current_time + step_size
    return True
