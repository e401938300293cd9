"""A journal of finished work: one JSON row per line, each with its `key`, appended and flushed as each piece of work
finishes, so that a command interrupted at any moment (Ctrl-C, SIGTERM, a full disk) keeps what it finished and the
same command resumes from it. Used by the sweep (its runs, sweep-rows.jsonl) and the AEB car-to-car pack (its tests,
tests-rows.jsonl). A line cut short by the interruption, or damaged, is dropped: its work is simply done again.
Which rows are kept, and what proves the file sdl-fmu's (a signed manifest recording its start), is the caller's."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable, TextIO

import numpy as np


def line(row: dict) -> str:
    """A row as the journal holds it: one line of JSON (NumPy numbers as plain ones, anything else as text)."""
    return json.dumps(row, default=_plain) + "\n"


def append(journal: TextIO, row: dict) -> None:
    """Appends a row to an open journal and flushes it: once this returns, the row survives an interruption."""
    journal.write(line(row))
    journal.flush()


def rows(path: Path, keep: Callable[[dict], bool] = lambda row: True) -> dict[str, dict]:
    """The rows of the journal at `path` that `keep` accepts, by their key (a later row of a key replaces an earlier
    one); {} without a journal. Lines that cannot be read, and rows without a text `key`, are dropped."""
    found: dict[str, dict] = {}
    if not path.exists():
        return found
    for text in path.read_text(encoding="utf-8", errors="replace").splitlines():
        try:
            row = json.loads(text)
        except ValueError:
            continue
        if isinstance(row, dict) and isinstance(row.get("key"), str) and keep(row):
            found[row["key"]] = row
    return found


def _plain(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return str(value)
