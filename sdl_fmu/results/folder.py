"""Results folders that never destroy what sdl-fmu did not write.

A results folder carries a manifest, MANIFEST_NAME, listing the files sdl-fmu wrote into it. `--out` may be
a new folder, an empty folder or an earlier results folder; anything else is refused before a run starts.
New results are written into a hidden sibling folder and swapped in with renames, so the folder holds
either the old or the new results, never a mix. An empty folder keeps its identity (it may be the
user's working folder) and receives the files by rename. If the user added files of their own to an
earlier results folder, those stay where they are: sdl-fmu then replaces only the files its manifest
lists, each one by an atomic rename. Hidden siblings left by a killed run (they carry the manifest and the dead
process's id) are removed by the next run into the same place.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Callable

MANIFEST_NAME = ".sdl-fmu-results.json"
MANIFEST_FORMAT = "sdl-fmu results 1"
_PARTIAL, _OLD = "partial", "old"
_SIBLING = re.compile(r"\.(?P<name>.+)\.(?P<kind>partial|old)-(?P<pid>\d+)-[A-Za-z0-9_]+")


class ResultsFolderError(Exception):
    """The results folder cannot be used; one line naming the folder and why."""


def read_manifest(folder: Path) -> list[str] | None:
    """The files sdl-fmu wrote into `folder`, or None when it is not a results folder of sdl-fmu."""
    try:
        data = json.loads((Path(folder) / MANIFEST_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        return None
    files = data.get("files")
    if not isinstance(files, list) or not all(isinstance(f, str) and f and "/" not in f and f not in (".", "..")
                                              for f in files):
        return None
    return files


def _write_manifest(folder: Path, files: list[str], complete: bool) -> None:
    data = {"format": MANIFEST_FORMAT, "complete": complete, "files": sorted(files)}
    (folder / MANIFEST_NAME).write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")


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


def check_results_folder(out: str | os.PathLike) -> Path:
    """Refuses (ResultsFolderError) an `--out` that sdl-fmu may not or cannot write; returns it absolute.

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
            own = read_manifest(target) or []
            foreign = _foreign_entries(target, own)
        except OSError as error:
            raise ResultsFolderError(f"{shown}: cannot be read: {error.strerror or error}") from None
        if foreign and not own:
            listed = ", ".join(repr(name) for name in foreign[:3]) + (" ..." if len(foreign) > 3 else "")
            raise ResultsFolderError(f"{shown}: holds files sdl-fmu did not write ({listed}); give a new or empty "
                                     "folder or an earlier results folder")
        _probe_writable(target, shown)
        _probe_writable(target.parent, shown)
        return target
    existing = _nearest_existing(target.parent)
    if not existing.is_dir():
        raise ResultsFolderError(f"{shown}: {existing} is not a folder")
    _probe_writable(existing, shown)
    return target


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


def write_results_folder(out: str | os.PathLike, write: Callable[[Path], None]) -> Path:
    """Runs `write(folder)` into a fresh hidden folder, then puts its files in place at `out`: all of them or
    none, and nothing sdl-fmu did not write is removed. Returns the results folder (absolute)."""
    target = check_results_folder(out)
    clean_leftovers(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = _sibling(target, _PARTIAL)
    try:
        os.chmod(partial, 0o755)  # mkdtemp makes it private; results are ordinary files
        _write_manifest(partial, [], complete=False)  # marks it as ours from the first moment
        write(partial)
        files = sorted(entry.name for entry in partial.iterdir() if entry.name != MANIFEST_NAME)
        _write_manifest(partial, files, complete=True)
        if not os.path.lexists(target):
            os.rename(partial, target)
        elif read_manifest(target) is not None and not _foreign_entries(target, read_manifest(target)):
            _swap(partial, target)  # an earlier results folder: replaced as a whole
        else:
            _replace_files(partial, target, files)
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


def _replace_files(new: Path, target: Path, files: list[str]) -> None:
    """Updates a results folder that also holds the user's files: each of sdl-fmu's files is renamed into
    place (atomic per file), files of the old manifest that this run did not write are removed, the
    manifest comes last. The user's files are never touched."""
    old = read_manifest(target) or []
    _write_manifest(target, sorted({*old, *files}), complete=False)
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
