"""The FMU's log messages, as sdl-fmu passes them on: to stderr (stdout carries the command's own output), decoded
leniently (bytes that are not UTF-8 become U+FFFD, never an exception inside the callback), terminal control
characters escaped, each line prefixed with the FMU's file name and the status, and at most MAX_LINES per
instance (then one line saying the rest are not shown)."""

from __future__ import annotations

import functools
import itertools
import sys

from ..text import printable

MAX_LINES = 100
STATUS = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")


class FmuLog:
    """The logger of one instance: `fmi2_callbacks()` / `fmi3_log_message()` are the callbacks fmpy hands the FMU."""

    def __init__(self, label: str):
        self.label = label
        self.lines = 0

    def __call__(self, status, category, message) -> None:
        try:
            if self.lines > MAX_LINES:
                return
            self.lines += 1
            if self.lines > MAX_LINES:
                text = f"{self.label}: further log messages of the FMU are not shown (at most {MAX_LINES})"
            else:
                name = STATUS[status] if isinstance(status, int) and 0 <= status < len(STATUS) else str(status)
                text = f"{self.label}: [{name}] {_decoded(category)}: {_decoded(message)}"
            sys.stderr.write(printable(text, keep_lines=False) + "\n")
            sys.stderr.flush()
        except Exception:  # noqa: BLE001 - nothing may leave a ctypes callback (it would print a traceback per call)
            pass

    def fmi2_callbacks(self):
        """FMI 2.0 callbacks whose logger reaches this log. fmpy's native proxy (which formats the printf-style
        message with its arguments) keeps ONE logger for the whole process, so every instance's callbacks share one
        logger that lives as long as the process, and it finds the instance's log by its componentEnvironment."""
        from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions
        from fmpy.fmi2 import calloc, free

        self.key = next(_keys)
        _logs[self.key] = self
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = _dispatcher()
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        callbacks.componentEnvironment = self.key
        try:
            from ctypes import byref

            from fmpy.logging import addLoggerProxy

            addLoggerProxy(byref(callbacks))
        except Exception:  # noqa: BLE001 - without it the format string itself is shown
            pass
        return callbacks

    def fmi3_log_message(self):
        return lambda environment, status, category, message: self(status, category, message)

    def release(self) -> None:
        """The instance is freed: its messages have nowhere to go (a late one is shown under no FMU's name)."""
        _logs.pop(getattr(self, "key", None), None)


_logs: dict[int, FmuLog] = {}
_keys = itertools.count(1)
_others = FmuLog("FMU")  # an instance with fmpy's own callbacks, whose messages the shared logger now gets too


@functools.lru_cache(maxsize=None)
def _dispatcher():
    """The one FMI 2.0 logger of the process (kept for its whole life: fmpy's proxy calls it for every FMU)."""
    from fmpy.fmi2 import fmi2CallbackLoggerTYPE

    def log(environment, name, status, category, message):
        _logs.get(environment or 0, _others)(status, category, message)

    return fmi2CallbackLoggerTYPE(log)


def _decoded(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return str(value)
