"""The Advanced FMU's tire slots, on the build side: SLOT_COUNT slots of the Magic Formula coefficients
(tire_files.SLOT_COEFFICIENTS), parameters named by the slot rule with the prefix TIRE_SLOTS (tire<slot>_<KEY>,
e.g. tire3_PDX1), their start values taken from the shipped Tire Attribute File. Its Integer inputs
surface_fl..surface_rr are road surface attribute numbers; the FMU uses slot = attribute for
0 <= attribute < SLOT_COUNT and slot 0 (standard tires) for any other number.

The files are read by sdl_fmu/tire_files.py, which the run side shares (`--tires` fills the slots of a vehicle whose
map declares `tire_slots`, named by the same rule with the map's prefix; the shipped Advanced map's is TIRE_SLOTS).
"""

from __future__ import annotations

from pathlib import Path

from ..tire_files import DEFAULT_ATTRIBUTE_FILE, SLOT_KEYS, slot_parameter, slot_values

SLOT_COUNT = 8
TIRE_SLOTS = "tire{slot}_"  # the slots' parameter prefix (modelDescription/EgoVehicleAdvanced.json's repeated group)


def slot_parameter_name(slot: int, key: str) -> str:
    """The FMU parameter of one coefficient of one slot, e.g. tire3_PDX1."""
    return slot_parameter(TIRE_SLOTS, slot, key)


def slot_of(attribute: int) -> int:
    """The slot the FMU uses for a surface attribute number (same rule as the FMU's equations)."""
    return attribute if 0 <= attribute < SLOT_COUNT else 0


def slot_parameters(attribute_file: Path | str = DEFAULT_ATTRIBUTE_FILE
                    ) -> tuple[dict[str, float], dict[int, int], list[str]]:
    """The FMU's start values of all tire slots from a Tire Attribute File (tire_files.slot_values), by parameter
    name; with attribute -> slot and the warnings."""
    slots, attributes, warnings = slot_values(attribute_file, SLOT_COUNT)
    starts = {slot_parameter_name(slot, key): values[key] for slot, values in enumerate(slots) for key in SLOT_KEYS}
    return starts, attributes, warnings
