"""A parsed scenario checked against what will drive it, before anything is built or loaded: the vehicle table (every
model an A event could use) and the vehicle map's friction meaning (RSA values that are attribute numbers must be
whole). What a run would warn of for the scenario and this vehicle is worded here too, once: the master words its
warnings with these functions when the events fire, and `sdl-fmu check` lists them beforehand.

Only plain values of the vehicle come in (its friction meaning, whether BRK acts, the attribute numbers its tire file
gives): the map is read by the caller, without its FMU."""

from __future__ import annotations

from typing import Literal

from .events import Brake, Scenario, SurfaceAttribute
from .parser import ScenarioError, SdlError
from .vehicles import VehicleModel, check_models

FrictionMeaning = Literal["mu", "attribute"]


def check_scenario(scenario: Scenario, table: dict[int, VehicleModel], meaning: FrictionMeaning | None) -> None:
    """ScenarioError listing every problem (file, line, field) of a parsed scenario for this vehicle table and a
    vehicle whose friction input means `meaning` (None: none)."""
    problems = check_models(scenario, table)
    if meaning == "attribute":
        problems += fractional_attributes(scenario)
    if problems:
        raise ScenarioError(sorted(problems, key=lambda problem: problem.line))


def fractional_attributes(scenario: Scenario) -> list[SdlError]:
    """For a vehicle whose friction input means an attribute (the Advanced FMU), an RSA value is an attribute number:
    a fraction is an error naming the line."""
    errors = []
    for event in scenario.events:
        if isinstance(event, SurfaceAttribute):
            for index, (_lane, value) in enumerate(event.settings):
                if value != int(value):
                    errors.append(SdlError(scenario.path, event.line, f"RSA parameter {2 * index + 2} (value)",
                                           f"{value:g}: for this vehicle the value is a surface attribute "
                                           "number and must be whole"))
    return errors


def brk_ignored(line: int) -> str:
    return f"line {line}: BRK ignored: brake events act only with simple dynamics"


def rsa_without_effect(line: int, vehicle: str) -> str:
    return (f"line {line}: RSA has no effect: the vehicle map of {vehicle} has no friction input, so the road surface "
            "cannot act on the vehicle")


def attribute_without_tire(line: int, attribute: int, lane: int) -> str:
    return (f"line {line}: RSA attribute {attribute} (lane {lane}) has no entry in the Tire Attribute File: "
            "attribute 0 (standard tires) is used")


def vehicle_warnings(scenario: Scenario, vehicle: str, meaning: FrictionMeaning | None, brk_acts: bool,
                     known_attributes: frozenset[int] | set[int] | None) -> list[str]:
    """What a run of the whole scenario with this vehicle warns of because of the vehicle, in the order a run gives
    them (RSA lines without effect first, then per event as it fires): BRK events it ignores, RSA values it cannot
    feel, attribute numbers its Tire Attribute File lacks."""
    warnings = []
    if meaning is None:
        warnings += [rsa_without_effect(event.line, vehicle) for event in scenario.events
                     if isinstance(event, SurfaceAttribute)]
    for event in scenario.events:
        if isinstance(event, Brake) and not brk_acts:
            warnings.append(brk_ignored(event.line))
        elif isinstance(event, SurfaceAttribute) and known_attributes is not None:
            warnings += [attribute_without_tire(event.line, int(value), lane) for lane, value in event.settings
                         if int(value) not in known_attributes]
    return warnings
