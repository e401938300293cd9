"""A test hook, for tests that must catch a command in progress whatever the machine's speed (Ctrl-C, SIGTERM,
timeouts, a worker killed mid-run): when $SDL_FMU_TEST_HOLD names a file that exists, a command reaching one of its
hold points appends its process id to that path + ".running" and then waits until the file is removed (or
`check()`, called while it waits, raises: a run's deadline), or it is interrupted. If the file holds a number n, a
process holds at its n-th hold point only and passes the others (a build caught at its second FMU). Without the
variable a hold point costs one environment look-up.

The hold points: every run after its first communication step (api.run), each manoeuvre of the vehicle test pack
once its vehicle is instantiated (verify/drive.py), `check` once the scenario is checked (api.check), and `build`
once an FMU's copy into --out is written but not yet in place (cli.py). None is in the build side (dynamics/, fmu/):
its code is an input of the FMU cache's key, so a hold point there would change every FMU; a test catches a build
in the cache by a compiler that keeps the same protocol. Imports nothing of the package."""

from __future__ import annotations

import os
import time
from typing import Callable

HOLD_VARIABLE = "SDL_FMU_TEST_HOLD"
_reached = 0  # the hold points this process reached while the hook was on


def holding() -> str | None:
    """The hold file, when the hook is on (its variable names a file that exists), else None."""
    hold = os.environ.get(HOLD_VARIABLE)
    return hold if hold and os.path.exists(hold) else None


def hold_here(check: Callable[[], None] | None = None) -> None:
    """A hold point (see the module)."""
    global _reached
    hold = holding()
    if hold is None:
        return
    _reached += 1
    try:
        with open(hold, encoding="utf-8") as file:
            wanted = file.read().strip()
    except OSError:  # removed meanwhile: released
        return
    if wanted.isdigit() and int(wanted) != _reached:
        return
    with open(hold + ".running", "a", encoding="utf-8") as running:
        running.write(f"{os.getpid()}\n")
    while os.path.exists(hold):
        time.sleep(0.01)
        if check is not None:
            check()
