"""The AEB car-to-car pack's finished tests kept as they finish, so that an interrupted pack (Ctrl-C, SIGTERM, a full
disk) loses none and the same command resumes it, as a sweep resumes (the same journal: sdl_fmu/journal.py).

Each finished test is appended at once to JOURNAL_NAME in the results folder (proved sdl-fmu's by the folder's
signed manifest: results/folder.py with_journal), one row: the test's key (its parameters), the pack's identity
(`identity`: the contents of the FMUs and maps and the options the tests ran with), the timeout it ran under, and
its outcome as verify.json writes it. Resuming keeps the rows of the same identity: a test that scored, failed or
timed out is the controller's result and is not run again (a timed-out one again only under a longer timeout);
a test its worker was lost for (`rerun`) is. The folder holds the journal until the pack writes its results there,
which replace it."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ... import journal
from ...results.folder import ResultsFolderError, read_manifest, with_journal
from .outcome import TestOutcome
from .protocol import Test

JOURNAL_NAME = "tests-rows.jsonl"
FILE_OPTIONS = ("fmu", "vehicle", "controller", "controller_map")  # whose contents make the pack what it is


def key(test: Test) -> str:
    """A test's identity in the journal: its parameters."""
    return json.dumps(test.parameters(), sort_keys=True)


def identity(options: dict, version: str) -> str:
    """SHA-256 of what a test's outcome depends on: the sdl-fmu version, the options (dynamics, params) and the
    contents of the files the tests read."""
    files = {option: hashlib.sha256(Path(options[option]).read_bytes()).hexdigest()
             for option in FILE_OPTIONS if options.get(option)}
    plain = {option: value for option, value in options.items() if option not in FILE_OPTIONS}
    text = json.dumps({"version": version, "options": plain, "files": files}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def finished(out: Path, tests: list[Test], pack: str, timeout: float) -> list[TestOutcome]:
    """The outcomes of `tests` kept in `out`'s journal for the pack `pack` (its identity), in the tests' order; a
    timed-out test only if it ran under at least `timeout`. [] without a journal sdl-fmu provably wrote."""
    path = Path(out) / JOURNAL_NAME
    if JOURNAL_NAME not in (read_manifest(Path(out)) or []) or not path.is_file():
        return []

    def keep(row: dict) -> bool:
        outcome = row.get("outcome")
        return (row.get("pack") == pack and isinstance(outcome, dict)
                and (outcome.get("end") != "timeout" or _number(row.get("timeout_s")) >= timeout))

    rows = journal.rows(path, keep)
    return [TestOutcome.from_json(test, rows[key(test)]["outcome"]) for test in tests if key(test) in rows]


def _number(value) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else float("-inf")


class Recorder:
    """Appends each finished test to the journal in `out` (the folder and the journal made at the first one, so a
    pack interrupted before any test finished leaves nothing); a test its worker was lost for is not kept."""

    def __init__(self, out: Path, pack: str, timeout: float):
        self.out, self.pack, self.timeout = out, pack, timeout
        self.stream = None

    def __call__(self, outcome: TestOutcome) -> None:
        if outcome.extra.get("rerun"):
            return
        try:
            if self.stream is None:
                self.stream = open(with_journal(self.out, JOURNAL_NAME, "verify"), "a", encoding="utf-8")
            journal.append(self.stream, {"key": key(outcome.test), "pack": self.pack, "timeout_s": self.timeout,
                                         "outcome": outcome.to_json()})
        except OSError as error:
            raise ResultsFolderError(f"{self.out}: cannot write: {error.strerror or error}; the finished tests are "
                                     "kept: the same command resumes the pack") from None

    def close(self) -> None:
        if self.stream is not None:
            self.stream.close()
            self.stream = None
