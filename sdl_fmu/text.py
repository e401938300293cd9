"""Text from outside (scenario, FMU and map names, FMU log messages, option values) made safe to show.

- `printable(text)`: terminal control characters escaped (`\\x1b` for ESC), so that a name cannot move the cursor,
  clear the screen, ring the bell or rewrite a line; line feeds and tabs stay (`keep_lines=False` escapes those
  too, for a name inside a one-line message). `EscapingStream` applies it to everything the command line prints.
- `plain_text()`: matplotlib text drawn as written: a `$` in a name is a dollar sign, never the start of mathtext
  (which, unbalanced or malformed, fails the whole plot).

Imports nothing of the package."""

from __future__ import annotations

import contextlib
import re

# C0 controls but tab and line feed, DEL, C1 controls, and the Unicode line separators and bidirectional overrides
# (which reorder what a terminal shows)
_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")
_CONTROL_AND_LINES = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def _escape(match: re.Match) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def printable(text: str, keep_lines: bool = True) -> str:
    """`text` with its terminal control characters escaped (`\\x1b`, `\\u202e`); line feeds and tabs kept unless
    keep_lines is False."""
    return (_CONTROL if keep_lines else _CONTROL_AND_LINES).sub(_escape, text)


class EscapingStream:
    """A text stream that writes through `printable`: every line the command line prints. `unescaped` is the stream
    itself, for the progress bars (their carriage returns are theirs, and they show only numbers)."""

    def __init__(self, stream):
        self.unescaped = stream

    def write(self, text: str) -> int:
        self.unescaped.write(printable(text))
        return len(text)

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name):
        return getattr(self.unescaped, name)


def unescaped(stream):
    """The stream under an EscapingStream (for a progress bar), or the stream itself."""
    return getattr(stream, "unescaped", stream)


@contextlib.contextmanager
def plain_text():
    """Inside it, matplotlib draws every text as written (no mathtext, no TeX). Figures are made and saved in it."""
    import matplotlib

    with matplotlib.rc_context({"text.parse_math": False, "text.usetex": False}):
        yield
