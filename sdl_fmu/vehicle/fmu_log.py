"""The FMU's log messages, as sdl-fmu passes them on: to stderr (stdout carries the command's own output), decoded
leniently (bytes that are not UTF-8 become U+FFFD, never an exception inside the callback), terminal control
characters escaped, each line prefixed with the FMU's file name and the status, and at most MAX_LINES per
instance (then one line saying the rest are not shown)."""

from __future__ import annotations

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
        from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                               fmi2CallbackLoggerTYPE)
        from fmpy.fmi2 import calloc, free

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(lambda component, name, status, category, message:
                                                  self(status, category, message))
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:  # a native proxy formats the printf-style message with its arguments before it reaches Python
            from ctypes import byref

            from fmpy.logging import addLoggerProxy

            addLoggerProxy(byref(callbacks))
        except Exception:  # noqa: BLE001 - without it the format string itself is shown
            pass
        return callbacks

    def fmi3_log_message(self):
        return lambda environment, status, category, message: self(status, category, message)


def _decoded(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return str(value)
