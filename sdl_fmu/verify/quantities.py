"""Numbers as the test packs' reports show them: each rounded to what it means (a distance to the centimetre, a speed
to 0.1 km/h, a time to the millisecond, ...) with its unit, read from the key's unit suffix (verify.json's keys carry
their units: stopping_distance_m, mfdd_mps2, impact_speed_kmh). Units are written in ASCII as the results' column
names write them (m/s2, kg.m2), so the printed table shows on any terminal."""

from __future__ import annotations

import math

# key suffix -> (unit shown, scale from the key's unit, decimals), longest suffixes first where one ends another
UNITS: tuple[tuple[str, tuple[str, float, int]], ...] = (
    ("_deg_per_g", ("deg/g", 1.0, 2)),
    ("_mps2", ("m/s2", 1.0, 2)),
    ("_radps", ("rad/s", 1.0, 3)),
    ("_kgpm3", ("kg/m3", 1.0, 3)),
    ("_kgm2", ("kg.m2", 1.0, 0)),
    ("_kmh", ("km/h", 1.0, 1)),
    ("_mps", ("m/s", 1.0, 2)),
    ("_pct", ("%", 1.0, 1)),
    ("_deg", ("deg", 1.0, 1)),
    ("_rad", ("rad", 1.0, 4)),
    ("_m2", ("m2", 1.0, 2)),
    ("_kg", ("kg", 1.0, 0)),
    ("_W", ("kW", 1e-3, 1)),
    ("_N", ("N", 1.0, 0)),
    ("_m", ("m", 1.0, 2)),
    ("_s", ("s", 1.0, 3)),
)
PLAIN_DECIMALS = 3  # a number without a unit (a ratio, a coefficient)


def unit_of(key: str) -> tuple[str, float, int] | None:
    """(unit shown, scale, decimals) of a key by its suffix, None for a number without a unit."""
    for suffix, unit in UNITS:
        if key.endswith(suffix):
            return unit
    return None


def label(key: str) -> str:
    """The key without its unit suffix, words spaced: `stopping_distance_m` -> `stopping distance`."""
    for suffix, _ in UNITS:
        if key.endswith(suffix):
            key = key[:-len(suffix)]
            break
    return key.replace("_", " ")


def shown(key: str, value) -> str:
    """The value as a report shows it: rounded to its meaning, with its unit; text and booleans as they are; a
    missing or non-finite number as "-"."""
    if value is None:
        return "-"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if not math.isfinite(value):
        return "-"
    unit = unit_of(key)
    if unit is None:
        return str(value) if isinstance(value, int) else f"{value:.{PLAIN_DECIMALS}f}"
    name, scale, decimals = unit
    return f"{value * scale:.{decimals}f} {name}"
