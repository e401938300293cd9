"""Text from outside (scenario, FMU and map names, FMU log messages, option values) made safe to show.

- `printable(text)`: terminal control characters escaped (`\\x1b` for ESC), so that a name cannot move the cursor,
  clear the screen, ring the bell or rewrite a line; line feeds and tabs stay (`keep_lines=False` escapes those
  too, for a name inside a one-line message). `EscapingStream` applies it to everything the command line prints.
- `plain_text()`: matplotlib text drawn as written: a `$` in a name is a dollar sign, never the start of mathtext
  (which, unbalanced or malformed, fails the whole plot).
- `safe_identifier(name)`: a name made safe to become a file name, a word of a shell command and a URI path segment
  (what `sdl-fmu export` names the SSP and the FMUs after: docs/export.md, Names); UnsafeName when it cannot be.

Imports nothing of the package."""

from __future__ import annotations

import contextlib
import re
import unicodedata

# C0 controls but tab and line feed, DEL, C1 controls, the Unicode line separators and bidirectional overrides
# (which reorder what a terminal shows), and what no UTF-8 text or XML document can hold: the surrogates (a file name
# of bytes that are not UTF-8 reaches Python as them) and the non-characters U+FFFE, U+FFFF
_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069\ud800-\udfff\ufffe\uffff]")
_CONTROL_AND_LINES = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069\ud800-\udfff\ufffe\uffff]")


def _escape(match: re.Match) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def printable(text: str, keep_lines: bool = True) -> str:
    """`text` with its terminal control characters escaped (`\\x1b`, `\\u202e`); line feeds and tabs kept unless
    keep_lines is False."""
    return (_CONTROL if keep_lines else _CONTROL_AND_LINES).sub(_escape, text)


SAFE_LENGTH = 128  # characters of a safe identifier at most (docs/export.md, Names)
# the POSIX portable file name characters: none has a meaning to a shell or needs escaping in a URI; a name starts with
# neither "." (a hidden file, "..") nor "-" (an option to a command)
_UNSAFE = re.compile(r"^[.-]+|[^A-Za-z0-9._-]+")
# names Windows keeps for its devices, whatever follows a "." (CON.fmu is the console)
_DEVICES = {"CON", "PRN", "AUX", "NUL", *(f"{port}{digit}" for port in ("COM", "LPT") for digit in range(10))}


class UnsafeName(ValueError):
    """A name that cannot be made a safe identifier (the message says why: "it has ...", "it is ...")."""


def safe_identifier(name: str) -> str:
    """`name` made safe to be a file name (with a suffix), a word of a shell command and a URI path segment, on every
    common file system: letters lose their accents (Unicode compatibility decomposition, é -> e, ﬁ -> fi), each run
    of other characters than A-Z, a-z, 0-9, ".", "-" and "_" becomes one "_", as does a leading run of "." or "-",
    and a Windows device name (CON, NUL, COM1, ...) before the first "." gets a "_" after it. A safe name is its own
    identifier. Raises UnsafeName when no letter or digit is left, or the identifier has more than SAFE_LENGTH
    characters."""
    decomposed = "".join(c for c in unicodedata.normalize("NFKD", name) if not unicodedata.combining(c))
    identifier = _UNSAFE.sub("_", decomposed)
    stem = identifier.split(".", 1)[0]
    if stem.upper() in _DEVICES:
        identifier = f"{stem}_{identifier[len(stem):]}"
    if not re.search("[A-Za-z0-9]", identifier):
        raise UnsafeName("it has no letter or digit (A-Z, a-z, 0-9)")
    if len(identifier) > SAFE_LENGTH:
        raise UnsafeName(f"it is {len(identifier)} characters long made safe, more than {SAFE_LENGTH}")
    return identifier


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
