"""Unit strings from FMUs and vehicle maps (`unit = "km/h"`), read by a small grammar before pint sees anything.

pint's own parser evaluates what it is given as arithmetic: `10**10**10*m/s` computes a number with ten billion
digits, and sdl-fmu hung while resolving the FMU. Here a unit string is at most MAX_CHARACTERS characters of

    unit  = term { ("*" | "." | "/" | " ") term }        evaluated left to right: a/b*c = (a/b)*c, a/b/c = a/(b c)
    term  = "1" | name [ ["**" | "^"] ["-"] digit ]      a name's exponent: m2, s-2, s**2, m^3 (|exponent| <= 9)
    name  = letters (and _ ° µ Ω %), no digits

at most MAX_TERMS terms, and pint is asked only for each name on its own (a lookup) and for products of those
units with small whole exponents: no input can make it compute. A single name keeps pint's offset (degC); a
product of offset units is refused, as pint refuses it.
"""

from __future__ import annotations

import functools
import re

MAX_CHARACTERS = 64
MAX_TERMS = 8
MAX_EXPONENT = 9
_NAME = re.compile(r"[A-Za-z_°µΩ%]+")
_EXPONENT = re.compile(r"(?:\*\*|\^)?(-?\d+)")
_SEPARATOR = re.compile(r"\s*([*./])\s*|\s+")


class UnitTextError(ValueError):
    """A unit string outside the grammar (the reason)."""


def terms(text: str) -> list[tuple[str | None, int]]:
    """(name, exponent) per term, the exponent's sign taking a preceding '/' into account; None is the number 1."""
    if len(text) > MAX_CHARACTERS:
        raise UnitTextError(f"longer than {MAX_CHARACTERS} characters")
    text = text.strip()
    if not text:
        raise UnitTextError("empty")
    found, position, sign = [], 0, 1
    while True:
        name = _NAME.match(text, position)
        if name is not None:
            position = name.end()
            exponent = _EXPONENT.match(text, position)
            power = 1
            if exponent is not None:
                power = int(exponent.group(1)) if len(exponent.group(1).lstrip("-")) <= 2 else MAX_EXPONENT + 1
                position = exponent.end()
            if not 0 < abs(power) <= MAX_EXPONENT:
                raise UnitTextError(f"the exponent of {name.group()!r} is not a whole number from -{MAX_EXPONENT} "
                                    f"to {MAX_EXPONENT} (other than 0)")
            found.append((name.group(), sign * power))
        elif text.startswith("1", position) and not text[position + 1:position + 2].isdigit():
            position += 1
            found.append((None, sign))
        else:
            raise UnitTextError(f"expected a unit name or 1 at {text[position:position + 10]!r}")
        if len(found) > MAX_TERMS:
            raise UnitTextError(f"more than {MAX_TERMS} terms")
        if position == len(text):
            return found
        separator = _SEPARATOR.match(text, position)
        if separator is None or separator.end() == len(text):
            raise UnitTextError(f"expected *, . or / at {text[position:position + 10]!r}")
        sign = -1 if separator.group(1) == "/" else 1
        position = separator.end()


@functools.lru_cache(maxsize=None)
def _registry():
    import pint

    return pint.UnitRegistry()


@functools.lru_cache(maxsize=256)
def conversion(text: str, si: str) -> tuple[float, float] | None:
    """(factor, offset) taking values in the unit `text` to the SI unit `si` (value_si = factor * value + offset);
    None if the text is outside the grammar, names a unit pint does not know, or is of another dimension."""
    try:
        parsed = terms(text)
    except UnitTextError:
        return None
    registry = _registry()
    try:
        target = registry.Unit(si)  # one of sdl-fmu's own SI spellings
        if len(parsed) == 1 and parsed[0][0] is not None and parsed[0][1] == 1:
            unit = registry.Unit(parsed[0][0])  # a single name: pint's offset, if it has one, applies
            zero = registry.Quantity(0.0, unit).to(target).magnitude
            one = registry.Quantity(1.0, unit).to(target).magnitude
            return float(one - zero), float(zero)
        quantity = registry.Quantity(1.0)
        for name, power in parsed:
            if name is not None:
                quantity = quantity * registry.Quantity(1.0, registry.Unit(name)) ** power
        return float(quantity.to(target).magnitude), 0.0
    except Exception:  # noqa: BLE001 - pint's UndefinedUnitError, DimensionalityError, OffsetUnitCalculusError
        return None


def refusal(text: str) -> str | None:
    """Why `text` is outside the grammar (for a message), or None."""
    try:
        terms(text)
    except UnitTextError as error:
        return str(error)
    return None
