"""Results folders that never destroy what sdl-fmu did not write.

A results folder carries a manifest, MANIFEST_NAME, listing the files sdl-fmu wrote into it, each with its size and
SHA-256, signed with this user's key (ownership.py): a planted manifest, or a file changed since, proves nothing, and
what is not proved sdl-fmu's is never deleted or overwritten. The results are put in place under a lock on the
parent folder, so runs into one folder finish one after the other (the last one's results stay, whole). `--out` may be
a new folder, an empty folder or an earlier results folder; anything else is refused before a run starts.
New results are written into a hidden sibling folder and swapped in with renames, so the folder holds
either the old or the new results, never a mix. An empty folder keeps its identity (it may be the
user's working folder) and receives the files by rename. If the user added files of their own to an
earlier results folder, those stay where they are: sdl-fmu then replaces only the files its manifest
lists, each one by an atomic rename. Hidden siblings left by a killed run (they carry the manifest and the dead
process's id) are removed by the next run into the same place.

Folders of one kind stay that kind: the manifest records which command wrote the folder (`kind`: run, verify or
export; a sweep's folder has a manifest of its own, SWEEP_MANIFEST_NAME, written by sweep.py), and a folder sdl-fmu
provably wrote is replaced only by a command of its own kind (`run --out` never replaces an export or a test pack's
report); anything else is refused in one line naming the folder and what it holds.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Callable, Literal

MANIFEST_NAME = ".sdl-fmu-results.json"
MANIFEST_FORMAT = "sdl-fmu results 2"  # 1: names only, unsigned (proves nothing now)
# a sweep's folder: its own manifest (sweep.py writes it; named here, where every command's --out is told apart)
SWEEP_MANIFEST_NAME, SWEEP_MANIFEST_FORMAT = ".sdl-fmu-sweep.json", "sdl-fmu sweep 1"
SEARCH_MANIFEST_NAME, SEARCH_MANIFEST_FORMAT = ".sdl-fmu-search.json", "sdl-fmu search 1"  # search.py writes it
FolderKind = Literal["run", "verify", "export", "sweep", "search"]  # the command that wrote a folder
FOLDER_KINDS: tuple[FolderKind, ...] = ("run", "verify", "export", "sweep", "search")
# what a folder of each kind holds, and the words for an earlier one, as the refusals say them
HOLDS = {"run": "a run's results (sdl-fmu run)", "verify": "a test pack's results (sdl-fmu verify)",
         "export": "an export (sdl-fmu export: an SSP and its FMUs)", "sweep": "a sweep's table (sdl-fmu sweep)",
         "search": "a worst-case search (sdl-fmu search)"}
EARLIER = {"run": "an earlier run's results folder", "verify": "an earlier verify folder",
           "export": "an earlier export folder", "sweep": "an interrupted sweep's folder",
           "search": "an earlier search's folder"}
# the names sdl-fmu writes into results folders (run, verify): one of them held by a file that is not sdl-fmu's is
# refused before the run (it would have to be overwritten)
RESULT_NAMES = ("timeseries.csv", "traffic.csv", "summary.json", "plot.png", "verify.json", "report.html",
                "tests.csv", "tests-rows.jsonl")
_PARTIAL, _OLD = "partial", "old"
_SIBLING = re.compile(r"\.(?P<name>.+)\.(?P<kind>partial|old)-(?P<pid>\d+)-[A-Za-z0-9_]+")


class ResultsFolderError(Exception):
    """The results folder cannot be used; one line naming the folder and why."""


def read_manifest(folder: Path) -> list[str] | None:
    """The files in `folder` that sdl-fmu provably wrote (its signed manifest lists them and they are unchanged; a
    listed name with nothing there counts too), or None when it is not a results folder of this user's sdl-fmu."""
    from .. import ownership

    folder = Path(folder)
    try:
        data = json.loads((folder / MANIFEST_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        return None
    files = data.get("files")
    if not isinstance(files, dict) or not all(isinstance(f, str) and f and "/" not in f and f not in (".", "..")
                                              and f != MANIFEST_NAME for f in files):
        return None
    if not ownership.authentic(data):
        return None
    def ours(name: str, entry) -> bool:
        if isinstance(entry, list):  # any of several forms (while files are exchanged); None: absent
            return any(ours(name, form) for form in entry)
        return not os.path.lexists(folder / name) if entry is None else ownership.unchanged(folder / name, entry)

    return sorted(name for name, entry in files.items() if ours(name, entry))


def _authentic_manifest(path: Path, format: str) -> dict | None:
    """A manifest of this format with this user's valid signature, or None."""
    from .. import ownership

    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != format or not ownership.authentic(data):
        return None
    return data


def folder_kind(folder: Path) -> FolderKind | None:
    """Which command provably wrote `folder` (a signed manifest of this user's sdl-fmu says so), or None. A results
    manifest written before manifests recorded their kind is told by its files: an .ssp (export), verify.json
    (verify), anything else (run)."""
    folder = Path(folder)
    if _authentic_manifest(folder / SWEEP_MANIFEST_NAME, SWEEP_MANIFEST_FORMAT) is not None:
        return "sweep"
    if _authentic_manifest(folder / SEARCH_MANIFEST_NAME, SEARCH_MANIFEST_FORMAT) is not None:
        return "search"
    data = _authentic_manifest(folder / MANIFEST_NAME, MANIFEST_FORMAT)
    if data is None:
        return None
    if data.get("kind") in FOLDER_KINDS:
        return data["kind"]
    names = [name for name in data.get("files") or {} if isinstance(name, str)]
    if any(name.endswith(".ssp") for name in names):
        return "export"
    return "verify" if "verify.json" in names else "run"


def _other_kind(folder: Path, shown: str, kind: FolderKind) -> None:
    """Refuses (ResultsFolderError) a folder that sdl-fmu wrote for another command than `kind`."""
    found = folder_kind(folder)
    if found is not None and found != kind:
        raise ResultsFolderError(other_kind_text(shown, found, kind))


def other_kind_text(shown: str, found: FolderKind, kind: FolderKind) -> str:
    """The refusal of a folder of the kind `found` as --out of the command `kind`."""
    return (f"{shown}: holds {HOLDS[found]}, which sdl-fmu {kind} does not replace; give a new or empty folder or "
            f"{EARLIER[kind]}")


def _write_manifest(folder: Path, files: list[str], complete: bool, kind: FolderKind = "run") -> None:
    from .. import ownership

    data = {"format": MANIFEST_FORMAT, "kind": kind, "complete": complete,
            "files": {name: ownership.record(folder / name) for name in sorted(files)}}
    ownership.write_json(folder / MANIFEST_NAME, ownership.signed(data))


def _foreign_entries(folder: Path, own: list[str]) -> list[str]:
    """Names in `folder` that sdl-fmu did not write there."""
    return sorted(entry.name for entry in folder.iterdir() if entry.name not in {*own, MANIFEST_NAME})


def _nearest_existing(path: Path) -> Path:
    while not os.path.lexists(path):
        path = path.parent
    return path


def _probe_writable(folder: Path, shown: str) -> None:
    """Create and remove a hidden folder: the only sure test (root, read-only mounts, ACLs)."""
    try:
        probe = tempfile.mkdtemp(prefix=".sdl-fmu-probe-", dir=folder)
        os.rmdir(probe)
    except OSError as error:
        raise ResultsFolderError(f"{shown}: cannot write in {folder}: {error.strerror or error}") from None


def check_results_folder(out: str | os.PathLike, kind: FolderKind = "run") -> Path:
    """Refuses (ResultsFolderError) an `--out` that sdl-fmu may not or cannot write for the command `kind` (run,
    verify, export); returns it absolute.

    Call before the simulation, so a refusal costs nothing."""
    shown = os.fspath(out)
    if not shown.strip():
        raise ResultsFolderError("empty folder name")
    target = Path(os.path.abspath(shown))
    if target == Path(target.anchor):
        raise ResultsFolderError(f"{shown}: the file system root cannot be a results folder")
    if os.path.lexists(target):
        if target.is_symlink():
            raise ResultsFolderError(f"{shown}: is a symbolic link; give the real folder")
        if not target.is_dir():
            raise ResultsFolderError(f"{shown}: exists and is not a folder")
        try:
            _other_kind(target, shown, kind)
            own = read_manifest(target) or []
            foreign = _foreign_entries(target, own)
        except OSError as error:
            raise ResultsFolderError(f"{shown}: cannot be read: {error.strerror or error}") from None
        if foreign and not own:
            listed = ", ".join(repr(name) for name in foreign[:3]) + (" ..." if len(foreign) > 3 else "")
            raise ResultsFolderError(f"{shown}: holds files sdl-fmu did not write ({listed}); give a new or empty "
                                     f"folder or {EARLIER[kind]}")
        clash = [name for name in foreign if name in RESULT_NAMES]
        if clash:
            raise ResultsFolderError(_clash(shown, clash[0]))
        _probe_writable(target, shown)
        _probe_writable(target.parent, shown)
        return target
    existing = _nearest_existing(target.parent)
    if not existing.is_dir():
        raise ResultsFolderError(f"{shown}: {existing} is not a folder")
    _probe_writable(existing, shown)
    return target


def with_journal(out: str | os.PathLike, name: str, kind: FolderKind) -> Path:
    """The journal `name` (sdl_fmu/journal.py) in the results folder `out` (new, empty or an earlier results folder
    of `kind`, as check_results_folder allows; made if need be), and the folder's signed manifest proving it
    sdl-fmu's whatever is appended to it (its start, empty, is recorded: a sweep's journal is proved the same way),
    the files sdl-fmu wrote there before still proved. The folder is left incomplete (`complete` false) until
    write_results_folder replaces it with the results, the journal gone. An existing journal it proves is kept."""
    from .. import ownership

    shown = os.fspath(out)
    target = check_results_folder(out, kind)
    path = target / name
    try:
        target.mkdir(parents=True, exist_ok=True)
        own = read_manifest(target) or []
        if name in own and path.is_file():
            return path
        if os.path.lexists(path):
            raise ResultsFolderError(_clash(shown, name))
        files = {other: ownership.record(target / other) for other in own if os.path.lexists(target / other)}
        start = {"size": 0, "sha256": hashlib.sha256(b"").hexdigest(), "appended": True}
        files[name] = [None, start]  # absent, or appended to from empty
        ownership.write_json(target / MANIFEST_NAME, ownership.signed({"format": MANIFEST_FORMAT, "kind": kind,
                                                                      "complete": False, "files": files}))
        path.touch()
    except OSError as error:
        raise ResultsFolderError(f"{shown}: cannot write: {error.strerror or error}") from None
    return path


def _clash(shown: str, name: str) -> str:
    return (f"{shown}: its {name} is not sdl-fmu's (changed since sdl-fmu wrote it, or never written by it) and would "
            "be overwritten; move it away, or give another folder")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # exists, owned by someone else
    return True


def clean_leftovers(target: Path) -> list[Path]:
    """Removes hidden siblings of `target` left by killed runs: only folders that carry sdl-fmu's manifest and
    whose process is gone. A partial folder is sdl-fmu's from its creation (private, manifest first); an
    old one (an earlier results folder set aside) must hold nothing but its manifest's files. Returns what
    was removed."""
    removed = []
    try:
        siblings = list(target.parent.iterdir())
    except OSError:
        return removed
    for sibling in siblings:
        match = _SIBLING.fullmatch(sibling.name)
        if (not match or match["name"] != target.name or sibling.is_symlink() or not sibling.is_dir()
                or _alive(int(match["pid"]))):
            continue
        own = read_manifest(sibling)
        if own is None or (match["kind"] == _OLD and _foreign_entries(sibling, own)):
            continue
        shutil.rmtree(sibling, ignore_errors=True)
        removed.append(sibling)
    return removed


def _sibling(target: Path, kind: str) -> Path:
    return Path(tempfile.mkdtemp(prefix=f".{target.name}.{kind}-{os.getpid()}-", dir=target.parent))


def write_results_folder(out: str | os.PathLike, write: Callable[[Path], None], kind: FolderKind = "run") -> Path:
    """Runs `write(folder)` into a fresh hidden folder, then puts its files in place at `out`: all of them or
    none, and nothing sdl-fmu did not write is removed; the folder is of the command `kind` (run, verify, export).
    Returns the results folder (absolute)."""
    from .. import ownership

    shown = os.fspath(out)
    target = check_results_folder(out, kind)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = _sibling(target, _PARTIAL)
    except OSError as error:
        raise ResultsFolderError(f"{shown}: cannot write: {error.strerror or error}") from None
    try:
        os.chmod(partial, 0o755)  # mkdtemp makes it private; results are ordinary files
        _write_manifest(partial, [], complete=False, kind=kind)  # marks it as ours from the first moment
        write(partial)
        files = sorted(entry.name for entry in partial.iterdir() if entry.name != MANIFEST_NAME)
        _write_manifest(partial, files, complete=True, kind=kind)
        with ownership.locked(target.parent, wait=True):  # one run at a time puts its results in place here
            target = check_results_folder(out, kind)  # again: another run may have finished meanwhile
            clean_leftovers(target)
            own = read_manifest(target) if os.path.lexists(target) else None
            foreign = _foreign_entries(target, own or []) if own is not None else []
            clash = [name for name in files if name in foreign]
            if clash:
                raise ResultsFolderError(_clash(shown, clash[0]))
            if not os.path.lexists(target):
                os.rename(partial, target)
            elif own is not None and not foreign:
                _swap(partial, target)  # an earlier results folder: replaced as a whole
            else:
                _replace_files(partial, target, files, kind)
    except OSError as error:
        shutil.rmtree(partial, ignore_errors=True)
        raise ResultsFolderError(f"{shown}: cannot write the results: {error.strerror or error}; the folder is as it "
                                 "was") from None
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    return target


def _swap(new: Path, target: Path) -> None:
    """Replaces a folder holding only sdl-fmu's files by `new`; the old one is set aside, removed after."""
    aside = _sibling(target, _OLD)
    os.rename(target, aside)  # replaces the empty `aside` made by mkdtemp
    try:
        os.rename(new, target)
    except BaseException:
        os.rename(aside, target)
        raise
    shutil.rmtree(aside, ignore_errors=True)


def _replace_files(new: Path, target: Path, files: list[str], kind: FolderKind) -> None:
    """Updates a results folder that also holds the user's files: each of sdl-fmu's files is renamed into
    place (atomic per file), files of the old manifest that this run did not write are removed, the
    manifest comes last. The user's files are never touched."""
    from .. import ownership

    old = read_manifest(target) or []
    # while the files are exchanged, each is sdl-fmu's in its old form or its new one (or absent)
    entries = {name: [ownership.record(target / name) if name in old else None, ownership.record(new / name)]
               for name in files}
    entries.update({name: [ownership.record(target / name), None] for name in set(old) - set(files)})
    ownership.write_json(target / MANIFEST_NAME, ownership.signed({"format": MANIFEST_FORMAT, "kind": kind,
                                                                   "complete": False,
                                                                   "files": entries}))
    for name in files:
        os.replace(new / name, target / name)
    for name in set(old) - set(files):
        path = target / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        elif os.path.lexists(path):
            path.unlink()
    os.replace(new / MANIFEST_NAME, target / MANIFEST_NAME)
    shutil.rmtree(new, ignore_errors=True)
