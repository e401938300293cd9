"""The run options' defaults and limits, and the one error type for a user mistake outside the scenario file,
defined once: api.py checks the options with them, the command line words their errors, the master runs with the
defaults, the vehicle side raises InputError subclasses.

The limits are SI. A run never goes beyond MAX_TIME, and a distance the fastest ego cannot reach within it could
never end a run (docs/decisions.md, Command line).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from .units import FOOT, Units, from_si, length_label, speed_label, to_si

MAX_SPEED = 150.0  # m/s (335 mph)
MAX_TIME = 3600.0  # s: no run goes beyond it
LIMITS = {
    "speed": (0.0, MAX_SPEED),  # scenario units on input, checked in m/s
    "step": (1e-5, 10.0),  # s
    "driver_period": (1e-3, 1.0),  # s
    "until_time": (0.0, MAX_TIME),  # s, > 0
    "until_distance": (0.0, MAX_SPEED * MAX_TIME),  # m, > 0
    "seed": (0, 2**63 - 1),
    "test_timeout": (0.0, MAX_TIME),  # s of wall clock, > 0: one test of the AEB car-to-car pack
}
DEFAULT_SPEED = 88 * FOOT  # m/s: 60 mph, the driver's start and target speed unless --speed says otherwise
DEFAULT_STEP = 1.0  # s, longest communication step (the driver's samples and the triggers cut it shorter)
DEFAULT_DRIVER_PERIOD = 0.05  # s, the driver model's sampling period (20 Hz)
# s of wall clock for one test of the AEB car-to-car pack (a test takes about 0.15 s with the shipped FMUs, a few s
# with slow foreign ones on a busy machine); a test that runs longer ends as `timeout` (docs/verification.md)
DEFAULT_TEST_TIMEOUT = 60.0
DRIVERS = ("lane", "follow")  # the built-in drivers (docs/controllers.md); lane is the default
ON_COLLISION = ("continue", "stop")  # what the first contact does; continue is the default

# keywords whose command-line flag is not the keyword with - for _
COMMAND_LINE_FLAGS = {"params": "param"}


class InputError(ValueError):
    """A user mistake outside the scenario file: a bad option, FMU, vehicle map, tire file or results folder.

    `option` is the keyword (e.g. "until_time", "params", "fmu"). With a `subject` (the value and the reason,
    "nan: must be ..."), the message is keyword + subject as the API spells it (`until_time nan: must be a finite
    number`), and `command_line()` gives the same line with the command line's flag (`--until-time nan: ...`);
    without one, the message stands as it is (it names a file and key)."""

    def __init__(self, option: str | None, message: str, subject: str | None = None):
        self.option = option
        self.subject = subject
        super().__init__(message if subject is None else f"{option} {subject}")

    def command_line(self) -> str:
        """The message as the command line words it: the keyword replaced by its flag."""
        if self.subject is None:
            return str(self)
        return f"--{COMMAND_LINE_FLAGS.get(self.option, self.option.replace('_', '-'))} {self.subject}"


class RunTimeout(RuntimeError):
    """A run stopped because it exceeded its wall-clock `timeout` (api.run(..., timeout=...)); an AEB test's end
    `timeout` (verify --test-timeout)."""


def option_error(option: str, value, reason: str) -> InputError:
    """`option value: reason` (`--option value: reason` on the command line)."""
    return InputError(option, "", subject=f"{value}: {reason}")


def checked_option(option: str, value, units: Units | None = None, low_open: bool = False) -> float | None:
    """A numeric option's value checked: a finite number within LIMITS[option] (given in scenario units when
    `units`); returns SI (None stays None)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise option_error(option, value, "must be a number")
    value = float(value)
    if not math.isfinite(value):
        raise option_error(option, f"{value:g}", "must be a finite number")
    si = to_si(value, units) if units else value
    low, high = LIMITS[option]
    if si < low or (low_open and si == low) or si > high:
        if units:
            label = speed_label(units) if option == "speed" else length_label(units)
            low, high = from_si(low, units), from_si(high, units)
        else:
            label = "s"
        relation = ">" if low_open else ">="
        raise option_error(option, f"{value:g}", f"must be {relation} {low:g} and <= {high:.6g} {label}")
    return si


def checked_choice(option: str, value, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise option_error(option, value, f"must be one of {', '.join(choices)}")
    return value


def checked_seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise option_error("seed", seed, "must be a whole number")
    low, high = LIMITS["seed"]
    if not low <= seed <= high:
        raise option_error("seed", seed, f"must be from {low} to {high}")
    return int(seed)


def regular_file(option: str, path: str | os.PathLike) -> Path:
    """An input file that exists and is a regular file."""
    path = Path(path)
    if not path.exists():
        raise option_error(option, path, "no such file")
    if path.is_dir():
        raise option_error(option, path, "is a folder, not a file")
    if not path.is_file():
        raise option_error(option, path, "is not a regular file")
    return path
