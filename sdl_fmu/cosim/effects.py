"""What never took effect in a run, as warnings worded once at its end (docs/results.md#warnings): an A action whose
closure time was never reached, an action the next one cut off before its transition ended, a BRK released at the
instant it came on or overridden by a controller, and events a run that ended early never reached.

Each is derived after the loop from what the run recorded anyway: the traffic's motions (one row per spawn and per
action fired, traffic.py), the samples (recorder.py: the ego, the commands sent), the event log's BRK entries and the
schedule's next event. Nothing is added to the steps; the work is per vehicle, per BRK and per unreached event, once."""

from __future__ import annotations

import numpy as np

from ..sdl.events import Action, ApproachingVehicle, ClosureTrigger, EndOfScenario
from .traffic import Traffic

# why the run ended early, for the events it never reached (the user's own --until-distance and --until-time are not
# warned of: a shorter run was asked for)
EARLY_ENDS = {"collision": "at the first contact (--on-collision stop)", "time_limit": "at the time limit",
              "not_closing": "once the ego no longer closed on its target"}
RELEASED_AT_ONCE = {"stopped": "the ego was already stopped", "end": "the run ended at that instant",
                    "time": "its threshold was already reached", "distance": "its threshold was already reached",
                    "velocity": "the speed was already below its threshold",
                    "relative_velocity": "its threshold was already reached"}


def _parameters(k: int) -> str:
    """The A line's parameters of action k (1-based): 5-8, 9-12, ..."""
    return f"parameters {4 * k + 1}-{4 * k + 4}"


def _trigger(trigger: ClosureTrigger) -> str:
    where = {"F": ", the vehicle in front", "B": ", the vehicle behind"}.get(trigger.where, "")
    return f"closure time {trigger.seconds:g} s{where}"


def _action(event: ApproachingVehicle, k: int) -> str:
    """'A action 2 (parameters 9-12, closure time 5 s)'."""
    return f"A action {k} ({_parameters(k)}, {_trigger(event.actions[k - 1].trigger)})"


def _lines(lines: list[int]) -> str:
    shown = ", ".join(map(str, lines[:10])) + (f" and {len(lines) - 10} more" if len(lines) > 10 else "")
    return f"line{'s' * (len(lines) > 1)} {shown}"


def closest_closure(traffic: Traffic, i: int, columns: dict, rows: slice, since: float,
                    trigger: ClosureTrigger) -> tuple[float, float] | None:
    """Over the samples `rows` from `since` on, the closure time nearest to the trigger's (triggers.py's condition):
    for a positive T the smallest |gap| / closing speed while closing, for a negative T the largest |gap| / separating
    speed while separating, only where the F / B restriction allows; (value s, its sample's time), or None where the
    two never closed (separated)."""
    times = np.asarray(columns["time"][rows])
    keep = times >= since
    times = times[keep]
    if not len(times):
        return None
    station, _, speed = traffic.track(i, times)
    psi = np.asarray(columns["psi"][rows])[keep]
    ego_rate = np.asarray(columns["vx"][rows])[keep] * np.cos(psi) - np.asarray(columns["vy"][rows])[keep] * np.sin(psi)
    gap = station - np.asarray(columns["x"][rows])[keep]
    closing = (speed + ego_rate) * np.sign(gap)  # the rate at which |gap| shrinks (gap rate = -speed - ego rate)
    allowed = (gap != 0) & ~((trigger.where == "F") & (gap < 0)) & ~((trigger.where == "B") & (gap > 0))
    if trigger.seconds > 0:
        mask = allowed & (closing > 0)
        if not mask.any():
            return None
        values = np.abs(gap[mask]) / closing[mask]
        k = int(np.argmin(values))
    else:
        mask = allowed & (closing < 0)
        if not mask.any():
            return None
        values = np.abs(gap[mask]) / -closing[mask]
        k = int(np.argmax(values))
    return float(values[k]), float(times[mask][k])


def action_warnings(traffic: Traffic, vehicle_ids, first: np.ndarray, last: np.ndarray, columns: dict,
                    end_time: float, tolerance: float) -> list[tuple[int, str]]:
    """(line, warning) for every action that never took effect: never fired (its closure time never reached before the
    vehicle left the road or the run ended; the actions after it never armed), or cut off by the next action more
    than `tolerance` (how exactly the instants are known) before its transition's end. first / last: each vehicle's
    first sample and the one it left at (-1: on the road at the end)."""
    found = []
    times = columns["time"]
    # cut off: a vehicle's motions in order (row 0 its spawn, row k its action k) where action k + 1 began before
    # action k's transition ended
    for i in np.flatnonzero(traffic.next_action[:traffic.size] >= 2).tolist():  # two actions fired or more
        motions = traffic.history(i)[1:]
        t0, duration = motions[:, 0], motions[:, 6]
        event = traffic.events[i]
        for j in np.flatnonzero(t0[1:] < t0[:-1] + duration[:-1] - tolerance).tolist():
            k, ran = j + 1, t0[j + 1] - t0[j]
            found.append((event.line, f"line {event.line}: {_action(event, k)} of vehicle {vehicle_ids[i]} was cut "
                                      f"off after {ran:.3g} s of its {duration[j]:g} s transition by "
                                      f"{_action(event, k + 1)} at t = {t0[j + 1]:.3f} s"))
    # never fired: an action still armed at the end (traffic.trigger_seconds is NaN where none is)
    for i in np.flatnonzero(~np.isnan(traffic.trigger_seconds[:traffic.size])).tolist():
        event = traffic.events[i]
        fired = int(traffic.next_action[i])
        k = fired + 1
        action: Action = event.actions[fired]
        left = int(last[i])
        since = traffic.history(i)[-1, 0]  # the instant it was armed: the spawn's or the last action's
        rows = slice(int(first[i]), len(times) if left < 0 else left)
        closest = closest_closure(traffic, i, columns, rows, since, action.trigger)
        if action.trigger.seconds > 0:
            reason = "its closure time was never reached" + (
                " (the ego never closed on it)" if closest is None
                else f" (closest {closest[0]:.3g} s, at t = {closest[1]:.3f} s)")
        else:
            reason = "the two never separated for that long" + (
                " (they never separated)" if closest is None
                else f" (longest {closest[0]:.3g} s, at t = {closest[1]:.3f} s)")
        until = (f"the run ended at t = {end_time:.3f} s" if left < 0
                 else f"the vehicle left the road at t = {float(times[left]):.3f} s")
        vehicle = vehicle_ids[i]
        found.append((event.line, f"line {event.line}: {_action(event, k)} of vehicle {vehicle} never fired: "
                                  f"{reason}; {until}"))
        found += [(event.line, f"line {event.line}: {_action(event, later)} of vehicle {vehicle} never fired: "
                               f"action {later - 1} before it never did")
                  for later in range(k + 1, len(event.actions) + 1)]
    return found


def brake_warnings(events, columns: dict, controller) -> list[tuple[int, str]]:
    """(line, warning) for every BRK that came on but never took effect: released at the instant it came on, or, with
    a controller in the loop (controller.ControllerModel), whose commands sent gave less brake than BRK's (the
    driver_brake column: BRK's pedal while it holds) or some throttle (the controller's override, or a throttle rule
    max) for part or all of its hold. events: the event log."""
    found = []
    on = None
    times = np.asarray(columns["time"])
    for entry in events:
        if entry["code"] != "BRK":
            continue
        if entry["action"] == "on":
            on = entry
            continue
        line, start, end = entry["line"], on["time_s"], entry["time_s"]
        pedal = f"{on['pedal']:g} %"
        if end <= start:
            found.append((line, f"line {line}: BRK (brake {pedal}) never took effect: it was released at the instant "
                                f"it came on (t = {start:.3f} s): {RELEASED_AT_ONCE[entry['reason']]}"))
            continue
        if controller is None:
            continue
        # the samples whose commands hold within the hold: each from its instant to the next sample's
        lo, hi = int(np.searchsorted(times, start, side="left")), int(np.searchsorted(times, end, side="left"))
        instants = times[lo:hi]
        spans = np.minimum(np.append(times[lo + 1:hi + 1], end)[:len(instants)], end) - instants
        less = np.asarray(columns["brake"][lo:hi]) < np.asarray(columns["driver_brake"][lo:hi])
        throttle = np.asarray(columns["throttle"][lo:hi]) > 0
        overridden = float(spans[less | throttle].sum())
        if overridden <= 0:
            continue
        rules = controller.rules
        how = [f"less brake than BRK's (arbitration brake = {rules['brake']})"] * bool(less.any()) + \
              [f"throttle (arbitration throttle = {rules['throttle']})"] * bool(throttle.any())
        hold = end - start
        span = (f"all of its {hold:.3g} s hold" if (less | throttle).all()
                else f"{overridden:.3g} s of its {hold:.3g} s hold")
        found.append((line, f"line {line}: BRK (brake {pedal}) was overridden for {span} (t = {start:.3f} to "
                            f"{end:.3f} s): the controller {controller.name} sent {' and '.join(how)}"))
    return found


def unreached_warnings(unreached, reason: str, end_time: float) -> list[tuple[int, str]]:
    """One (line, warning) for the events a run that ended early (EARLY_ENDS) never reached; none for ES, or when the
    run ended where the scenario or the user's --until-distance / --until-time put its end."""
    events = [event for event in unreached if not isinstance(event, EndOfScenario)]
    if reason not in EARLY_ENDS or not events:
        return []
    lines = sorted(event.line for event in events)
    codes = "/".join(dict.fromkeys(event.code for event in sorted(events, key=lambda event: event.line)))
    return [(lines[0], f"line {lines[0]}: {codes} never reached: the run ended {EARLY_ENDS[reason]} at "
                       f"t = {end_time:.3f} s, before the distance of {_lines(lines)}")]


def ineffective(found: list[tuple[int, str]]) -> list[str]:
    """The warnings in line order (a stable sort: one line's in the order found)."""
    return [text for _, text in sorted(found, key=lambda item: item[0])]

