"""The one place where scenario units (feet or metres) meet SI.

Everything inside the FMUs and the physics is SI; feet and ft/s (or metres with `Metric`)
exist only at the SDL / results boundary, converted here.
"""

from typing import Literal

STANDARD_GRAVITY = 9.80665  # m/s2
FOOT = 0.3048  # m, exact by definition

Units = Literal["English", "Metric"]  # a scenario's units: feet and ft/s, or metres and m/s
ENGLISH: Units = "English"
METRIC: Units = "Metric"


def length_scale(units: Units) -> float:
    """Metres per scenario length unit (ft for English, m for Metric)."""
    if units == ENGLISH:
        return FOOT
    if units == METRIC:
        return 1.0
    raise ValueError(f"unknown units {units!r}")


def to_si(value: float, units: Units) -> float:
    """A scenario distance (ft or m) or speed (ft/s or m/s) in SI."""
    return value * length_scale(units)


def from_si(value: float, units: Units) -> float:
    """An SI distance or speed in the scenario's units."""
    return value / length_scale(units)


def length_label(units: Units) -> str:
    return "ft" if units == ENGLISH else "m"


def speed_label(units: Units) -> str:
    return "ft/s" if units == ENGLISH else "m/s"

KILOMETRE_PER_HOUR = 1 / 3.6  # m/s: the vehicle test pack's speeds are given in km/h by its standards
