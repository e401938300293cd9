"""When the next trigger could be, and whether one is true: the master's trigger schedule.

Per kind of trigger (the next event's distance, the run's end distance, a BRK threshold, a wheel crossing onto
another surface, a traffic vehicle's closure, contact or departure) the schedule keeps a lower bound on the
instant it could become true (triggers.py), valid until it is reached or something fires, and recomputes only
the bounds that could bind before the step's end. A few traffic vehicles are evaluated one by one in plain
floats, more at once in NumPy arrays (SCALAR_VEHICLES): the choice between the two forms lives here."""

from __future__ import annotations

import bisect
import math
from typing import Literal

import numpy as np

from ..sdl.events import Road
from ..vehicle import EgoState
from .closing import ClosingEnd
from .inputs import Inputs
from .geometry import SCALAR_VEHICLES, reach_time_scalar
from .road import SurfaceMap, WheelGeometry
from .traffic import Traffic
from .triggers import (EgoBounds, EgoKinematics, vehicle_condition, vehicle_conditions, vehicle_horizon,
                       vehicle_horizons, vehicle_triggered)

TriggerKind = Literal["event", "end", "brake", "surface", "traffic", "closing"]

SURFACE_WINDOW = 1.0  # s, how far ahead lane edges between differing surfaces are looked for


class TriggerSchedule:
    """The events still to fire (in distance order), the end distance, and the kept bounds on every trigger."""

    def __init__(self, events: list, end_distance: float, road: Road, surfaces: SurfaceMap, geometry: WheelGeometry,
                 bounds: EgoBounds, traffic: Traffic, inputs: Inputs, closing: ClosingEnd | None = None):
        self.events = events
        self.closing = closing  # the end when the ego no longer closes on a vehicle (closing.py), if asked for
        self.next_event = 0  # index of the first event not yet fired
        self.end_distance = end_distance
        self.road, self.surfaces, self.geometry = road, surfaces, geometry
        self.bounds, self.traffic, self.inputs = bounds, traffic, inputs
        self.surface_changes = _surface_changes(surfaces)
        self.surface_next = -math.inf  # cached lower bound on the next surface change under a wheel
        self.traffic_earliest = -math.inf  # cached min of the vehicles' bounds (valid until something fires)
        self.cached_bounds: dict[str, float] = {}  # event, end, brake: bounds kept until something fires
        self._differing: dict[tuple[int, int], tuple[list[float], list[float]]] = {}
        self._edges: dict[tuple[int, int], list] = {}  # see _lane_edges
        self.bounds_exceeded = False  # whether the ego ever left the bounds the predictions rest on

    def pending_distance(self) -> float:
        if self.next_event < len(self.events):
            return self.events[self.next_event].distance
        return math.inf

    def pop_due_event(self, state: EgoState):
        """The next event if its distance is reached at this state (then it counts as fired), else None."""
        if self.next_event < len(self.events) and self.pending_distance() <= state.s:
            self.next_event += 1
            return self.events[self.next_event - 1]
        return None

    def forget(self) -> None:
        """Something fired (a spawn, an action, a contact, a departure, the next event, a BRK on or off): the
        kept bounds no longer hold."""
        self.traffic_earliest = -math.inf
        self.cached_bounds.clear()

    def exceeded_warning(self, state: EgoState) -> str:
        """The warning, once per run, for a state whose yaw rate or acceleration exceeds the bounds the predictions
        rest on (say so rather than silently risk a late trigger)."""
        self.bounds_exceeded = True
        bounds = self.bounds
        return (f"at t = {state.time:.3f} s the ego's yaw rate ({state.yaw_rate:.3g} rad/s) or acceleration "
                f"({math.hypot(state.ax, state.ay):.3g} m/s2) exceeded the bounds the trigger prediction assumes "
                f"({bounds.yaw_rate:.3g} rad/s, {bounds.acceleration:.3g} m/s2): later triggers may be "
                "located late; rerun with a shorter --step")

    # ---- when the next trigger could be ---------------------------------------------------------

    def horizons(self, state: EgoState, limit: float) -> dict[TriggerKind, float]:
        """Per kind of trigger, a lower bound on the instant it could become true (absolute time). A bound
        holds until it is reached or something fires (the bounds on the ego hold at all times), so each is
        kept and recomputed only when it could bind before `limit`."""
        a = self.bounds.acceleration
        t = state.time
        cached = self.cached_bounds
        near = {}
        if self.next_event < len(self.events):
            bound = cached.get("event", -math.inf)
            if bound < limit:
                distance = self.events[self.next_event].distance
                bound = cached["event"] = t + reach_time_scalar(distance - state.s, state.v, a)
            near["event"] = bound
        if self.end_distance < math.inf:
            bound = cached.get("end", -math.inf)
            if bound < limit:
                bound = cached["end"] = t + reach_time_scalar(self.end_distance - state.s, state.v, a)
            near["end"] = bound
        brake_hold = self.inputs.brake_hold
        if brake_hold is not None:
            bound = cached.get("brake", -math.inf)
            if bound < limit:
                bound = cached["brake"] = brake_hold.earliest_release(state, a)
            near["brake"] = bound
        if self.surface_changes:
            if self.surface_next < limit:
                self.surface_next = t + self.surface_horizon(state)
            near["surface"] = self.surface_next
        if len(self.traffic.active):
            near["traffic"] = self.traffic_horizon(state, limit)
        if self.closing is not None:
            bound = cached.get("closing", -math.inf)
            if bound < limit:
                bound = cached["closing"] = self.closing.horizon(state)
            near["closing"] = bound
        return near

    def surface_horizon(self, state: EgoState) -> float:
        """How long every wheel surely stays on its surface: the nearest station in its lane where the value
        changes, and its lane's edges where the lane beyond differs within the reach of SURFACE_WINDOW (a
        bound then valid for that window only), each reached at the ego's bounded rates."""
        kin = EgoKinematics.of(state)
        station_rate, lateral_rate = kin.station_rate, kin.lateral_rate
        bounds, road = self.bounds, self.road
        a = bounds.acceleration
        turn = bounds.wheel_arm * bounds.yaw_rate
        width = road.lane_width
        reach = (abs(station_rate) + turn) * SURFACE_WINDOW + a * SURFACE_WINDOW**2 / 2
        horizon = SURFACE_WINDOW
        for station, lateral in self.geometry.contact_points(state.x, state.y, state.psi):
            lane = road.lane_at(lateral)
            changes = self.surface_changes.get(lane)
            if changes:
                k = bisect.bisect_right(changes, station)
                if k < len(changes):
                    horizon = min(horizon, reach_time_scalar(changes[k] - station, station_rate + turn, a))
                if k > 0:
                    horizon = min(horizon, reach_time_scalar(station - changes[k - 1], -station_rate + turn, a))
            for edge, side, (starts, ends) in self._lane_edges(math.floor(lateral / width), lane):
                # the lanes differ somewhere between station -+ reach: a stretch starts at or before the
                # upper end and ends after the lower
                k = bisect.bisect_right(starts, station + reach)
                if k > 0 and ends[k - 1] > station - reach:
                    horizon = min(horizon, reach_time_scalar(abs(edge - lateral), side * lateral_rate + turn, a))
        return horizon

    def _lane_edges(self, k: int, lane: int) -> list:
        """For a wheel in `lane` between the lines k w and (k + 1) w: those of the two lines whose lane beyond
        differs from `lane` somewhere, as (line, side toward it, (starts, ends) of the stretches where the
        two lanes differ). Worked out once per (k, lane) and per pair of lanes."""
        edges = self._edges.get((k, lane))
        if edges is None:
            road, width = self.road, self.road.lane_width
            edges = []
            for edge, side in ((k * width, -1.0), ((k + 1) * width, 1.0)):
                if not road.left_edge <= edge <= road.right_edge:
                    continue  # beyond the shoulders' outer edges nothing changes
                beyond = road.lane_at(edge + side * width / 2)
                if beyond != lane:
                    key = (min(lane, beyond), max(lane, beyond))
                    if key not in self._differing:
                        self._differing[key] = _differing_stretches(self.surfaces, *key)
                    if self._differing[key][0]:
                        edges.append((edge, side, self._differing[key]))
            self._edges[(k, lane)] = edges
        return edges

    def traffic_horizon(self, state: EgoState, limit: float) -> float:
        """The earliest instant any vehicle on the road could trigger something. Each vehicle's bound is
        kept until it could bind (it holds while the vehicle's own motion is unchanged); only those are
        recomputed, vectorised (a few vehicles in plain floats, see SCALAR_VEHICLES)."""
        if self.traffic_earliest >= limit:  # no vehicle's bound can bind before the limit: nothing to redo
            return self.traffic_earliest
        traffic = self.traffic
        active = traffic.active
        if len(active) <= SCALAR_VEHICLES:
            checks = traffic.next_check[active].tolist()
            kinematics = None
            for k, i in enumerate(active.tolist()):
                if checks[k] < limit:
                    if kinematics is None:
                        kinematics = EgoKinematics.of(state)
                    checks[k] = state.time + vehicle_horizon(traffic, i, kinematics, self.bounds)
                    traffic.next_check[i] = checks[k]
            self.traffic_earliest = min(checks)
            return self.traffic_earliest
        stale = active[traffic.next_check[active] < limit]
        if 0 < len(stale) <= SCALAR_VEHICLES:
            kinematics = EgoKinematics.of(state)
            for i in stale.tolist():
                traffic.next_check[i] = state.time + vehicle_horizon(traffic, i, kinematics, self.bounds)
        elif len(stale):
            traffic.next_check[stale] = state.time + vehicle_horizons(traffic, stale, EgoKinematics.of(state),
                                                                      self.bounds)
        self.traffic_earliest = float(traffic.next_check[active].min())
        return self.traffic_earliest

    # ---- whether a trigger is true --------------------------------------------------------------

    def triggered(self, state: EgoState, kinds) -> bool:
        """Whether a trigger of the given kinds is true at this state (all are false at a step's start)."""
        if "event" in kinds and self.pending_distance() <= state.s:
            return True
        if "end" in kinds and state.s >= self.end_distance:
            return True
        if "brake" in kinds and self.inputs.brake_hold.release_reason(state):
            return True
        if "surface" in kinds and self.inputs.surfaces_under_wheels(state) != self.inputs.applied_surfaces:
            return True
        if "closing" in kinds and self.closing.triggered(state):
            return True
        if "traffic" in kinds:
            traffic = self.traffic
            active = traffic.active
            if len(active) <= SCALAR_VEHICLES:  # (the bisection's probes: a NumPy selection costs more here)
                due = [i for i, check in zip(active.tolist(), traffic.next_check[active].tolist()) if check <= state.time]
            else:
                due = active[traffic.next_check[active] <= state.time]
            if 0 < len(due) <= SCALAR_VEHICLES:
                kinematics = EgoKinematics.of(state)
                return any(vehicle_triggered(traffic, int(i), kinematics, self.bounds) for i in due)
            if len(due):
                action, overlap, away = vehicle_conditions(traffic, due, EgoKinematics.of(state), self.bounds)
                in_contact = traffic.in_contact[due]
                return bool((action | (overlap != in_contact) | (away & ~in_contact)).any())
        return False

    def vehicle_conditions(self, idx: np.ndarray, kinematics: EgoKinematics):
        """(action due, overlap, may leave) of vehicles idx as boolean arrays; a few in plain floats."""
        if len(idx) > SCALAR_VEHICLES:
            return vehicle_conditions(self.traffic, idx, kinematics, self.bounds)
        rows = [vehicle_condition(self.traffic, i, kinematics, self.bounds) for i in idx.tolist()]
        return tuple(np.array([row[k] for row in rows], dtype=bool) for k in range(3))

    def action_due(self, i: int, kinematics: EgoKinematics) -> bool:
        """Whether vehicle i's next action is due (one vehicle, plain floats)."""
        return vehicle_condition(self.traffic, i, kinematics, self.bounds)[0]


def _differing_stretches(surfaces: SurfaceMap, lane: int, other: int) -> tuple[list[float], list[float]]:
    """(starts, ends) of the stretches of road where two lanes' surface values differ, in station order,
    disjoint (adjacent ones merged); an end may be inf."""
    stations = sorted({*surfaces.starts.get(lane, []), *surfaces.starts.get(other, [])})
    starts, ends = [], []
    for k, station in enumerate(stations):
        end = stations[k + 1] if k + 1 < len(stations) else math.inf
        if surfaces.value(lane, station) != surfaces.value(other, station):
            if ends and ends[-1] == station:
                ends[-1] = end
            else:
                starts.append(station)
                ends.append(end)
    return starts, ends


def _surface_changes(surfaces: SurfaceMap) -> dict[int, list[float]]:
    """Per lane, the stations where its surface value actually changes (a value set again is no change)."""
    changes = {}
    for lane, starts in surfaces.starts.items():
        previous, stations = surfaces.default, []
        for start, value in zip(starts, surfaces.values[lane]):
            if value != previous:
                stations.append(start)
            previous = value
        if stations:
            changes[lane] = stations
    return changes
