"""The one place where the run's record (SI: m, m/s, m/s2) meets the scenario's units (ft, ft/s and ft/s2, or m,
m/s and m/s2 with `Metric`): `final`, the events and `criticality` as summary.json, `api.Result` and the plot give
them. The time series are converted column by column where the CSV is written (files.py), with the same
`units.from_si`."""

from __future__ import annotations

from ..lazy_sequence import LazySequence
from ..units import Units, from_si

# the keys of `final` and of every event that carry the ego's distance, speed or lateral position
EGO_KEYS = ("distance", "speed", "lateral")
# the keys of some events that carry another speed: a collision's relative impact speed
EVENT_SPEEDS = ("relative_speed",)
# the keys of `criticality` (run-wide and per vehicle) that carry a length (min_distance) or a length per s^2
# (max_drac); the others are times in s
CRITICALITY_LENGTHS = ("min_distance", "max_drac")


def final(values: dict, units: Units) -> dict:
    """summary.json's `final`: the ego's distance, speed and lateral position in the scenario's units."""
    return {key: from_si(value, units) if key in EGO_KEYS else value for key, value in values.items()}


def event(entry: dict, units: Units) -> dict:
    """One summary.json event: the ego's distance, speed and lateral position, a collision's relative impact speed,
    and a BRK event's threshold `magnitude` (a distance or a speed; a time threshold stays in s), in the scenario's
    units."""
    converted = {key: from_si(value, units) if key in EGO_KEYS or key in EVENT_SPEEDS else value
                 for key, value in entry.items()}
    if "magnitude" in converted and converted.get("threshold") != "time":
        converted["magnitude"] = from_si(converted["magnitude"], units)
    return converted


class Events(LazySequence):
    """The record's events (a list, or the run's event log on disk) in the scenario's units, each converted as it
    is read: memory stays bounded however many events a run logs."""

    def __init__(self, events, units: Units):
        self.events, self.units = events, units

    def __len__(self) -> int:
        return len(self.events)

    def _item(self, index: int) -> dict:
        return event(self.events[index], self.units)

    def __iter__(self):
        for entry in self.events:
            yield event(entry, self.units)

    def __eq__(self, other) -> bool:
        if isinstance(other, (LazySequence, list, tuple)):
            return len(self) == len(other) and all(a == b for a, b in zip(self, other))
        return NotImplemented

    def __repr__(self) -> str:
        return f"Events({len(self)} events, {self.units})"

    def __reduce__(self):
        return list, (list(self),)  # pickled (e.g. sent to another process) as a plain list


def criticality(values: dict | None, units: Units) -> dict | None:
    """summary.json's `criticality`: the minimum distance and DRAC (run-wide and per vehicle) in the scenario's
    units; None (not measured) stays None."""
    if values is None:
        return None

    def entry(measures: dict) -> dict:
        return {key: [entry(vehicle) for vehicle in value] if key == "vehicles" else
                from_si(value, units) if key in CRITICALITY_LENGTHS and value is not None else value
                for key, value in measures.items()}

    return entry(values)
