"""FMU archives, checked and unpacked once per process.

An FMU is a zip archive from anyone. Before anything is read from it, `check_archive` refuses what could escape
or exhaust the machine: a member whose name is absolute, has a drive letter, a backslash, a `..` part or a NUL (it
would be written outside the folder), more than MAX_MEMBERS members, or more than MAX_UNPACKED bytes unpacked (the
sizes the archive declares; reading a member never yields more than it declares), and a `modelIdentifier` that is
not a C identifier (it names the binary's file: `../../elsewhere/lib` would load a library outside the FMU).

`unpacked(fmu)` unpacks an FMU once per process into `$TMPDIR/sdl-fmu-<pid>-<random>/` and returns that folder (what
an instance on this platform loads: not the FMU's sources, documentation or other platforms' binaries; the Advanced
FMU: 4 of 14 MB); every instance of the FMU in the process (a run, each manoeuvre of the vehicle test pack, a sweep worker's runs) uses
it. The folders go when the process ends (normally, by an exception, Ctrl-C or SIGTERM through the command line);
a folder left by a process that was killed outright (SIGKILL) is removed by the next process that unpacks an FMU.
A partial unpack (a full disk, a damaged member) is removed at once. Imports nothing of the package."""

from __future__ import annotations

import atexit
import contextlib
import os
import re
import shutil
import stat
import tempfile
import threading
import zipfile
from pathlib import Path

MAX_UNPACKED = 1 << 30  # bytes: the shipped FMUs unpack to a few MB
MAX_MEMBERS = 10000
MAX_DESCRIPTION = 64 * 2**20  # bytes of modelDescription.xml (read into memory whole; the shipped ones: < 1 MB)
IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
PREFIX = "sdl-fmu-"
MARKER = ".sdl-fmu-unpacked"  # written first into every folder sdl-fmu unpacks into: only such folders are removed
_FOLDER = re.compile(rf"{PREFIX}(?P<pid>\d+)-[A-Za-z0-9_]+")


class UnpackError(ValueError):
    """An FMU archive sdl-fmu will not unpack, or could not: one line naming the FMU."""


def _unsafe(name: str) -> str | None:
    """Why a member name could escape the unpack folder, or None."""
    if "\\" in name:
        return "a backslash"
    if "\0" in name:
        return "a NUL character"
    if name.startswith("/") or re.match(r"[A-Za-z]:", name):
        return "an absolute path"
    if ".." in name.split("/"):
        return "a '..' part"
    return None


def check_identifier(fmu: str | os.PathLike, model_identifier: str) -> None:
    """UnpackError unless the modelIdentifier is a C identifier (as FMI requires: it names the binary's file)."""
    if not IDENTIFIER.fullmatch(model_identifier or ""):
        raise UnpackError(f"{fmu}: modelIdentifier {model_identifier!r} is not a C identifier (letters, digits and "
                          "_; it names the FMU's binary)")


def check_archive(fmu: str | os.PathLike) -> list[zipfile.ZipInfo]:
    """The archive's members, each checked (see the module); UnpackError naming the FMU and the member otherwise."""
    try:
        with zipfile.ZipFile(fmu) as archive:
            members = archive.infolist()
    except (OSError, zipfile.BadZipFile, ValueError) as error:
        raise UnpackError(f"{fmu}: is not a readable FMU ({str(error).strip() or type(error).__name__})") from None
    if len(members) > MAX_MEMBERS:
        raise UnpackError(f"{fmu}: {len(members)} members, more than the {MAX_MEMBERS} an FMU may hold here")
    total = 0
    for member in members:
        reason = _unsafe(member.filename)
        if reason is not None:
            raise UnpackError(f"{fmu}: the member name {member.filename!r} has {reason}; an FMU's members are "
                              "relative paths inside it")
        total += member.file_size
        if member.filename == "modelDescription.xml" and member.file_size > MAX_DESCRIPTION:
            raise UnpackError(f"{fmu}: its modelDescription.xml unpacks to {member.file_size / 2**20:.0f} MB, more "
                              f"than the {MAX_DESCRIPTION / 2**20:.0f} MB sdl-fmu reads")
    if total > MAX_UNPACKED:
        raise UnpackError(f"{fmu}: unpacks to {total / 2**20:.0f} MB, more than the {MAX_UNPACKED / 2**20:.0f} MB "
                          "an FMU may take here")
    return members


_lock = threading.Lock()
_folders: dict[tuple, Path] = {}  # (resolved path, mtime, size) -> the folder it is unpacked in
_owned: list[Path] = []  # the folders this process made (and removes)
_swept = False


def _key(fmu: Path) -> tuple:
    status = fmu.stat()
    return str(fmu.resolve()), status.st_mtime_ns, status.st_size


def _needed(name: str) -> bool:
    """Whether an instance on this platform needs the member: all but sources/, documentation/ and the binaries of
    other platforms (this one's folder is fmpy.platform for FMI 2.0, fmpy.platform_tuple for FMI 3.0)."""
    if name.startswith(("sources/", "documentation/")):
        return False
    if not name.startswith("binaries/"):
        return True
    import fmpy

    return name.startswith((f"binaries/{fmpy.platform}/", f"binaries/{fmpy.platform_tuple}/"))


def unpacked(fmu: str | os.PathLike) -> Path:
    """The folder the FMU is unpacked in, unpacked on the first call in this process (see the module)."""
    global _swept
    fmu = Path(fmu)
    key = _key(fmu)
    with _lock:
        folder = _folders.get(key)
        if folder is not None and (folder / MARKER).exists():
            return folder
        if not _swept:
            _swept = True
            remove_leftovers()
        members = check_archive(fmu)
        folder = Path(tempfile.mkdtemp(prefix=f"{PREFIX}{os.getpid()}-"))
        _owned.append(folder)
        try:
            (folder / MARKER).write_text(f"{fmu}\n", encoding="utf-8")
            with zipfile.ZipFile(fmu) as archive:
                for member in members:
                    if not _needed(member.filename):
                        continue
                    target = folder / member.filename
                    if member.is_dir():
                        target.mkdir(parents=True, exist_ok=True)
                        continue
                    target.parent.mkdir(parents=True, exist_ok=True)
                    with archive.open(member) as source, open(target, "wb") as copy:
                        shutil.copyfileobj(source, copy, 1 << 20)
        except (OSError, zipfile.BadZipFile, EOFError, RuntimeError, ValueError) as error:
            _remove(folder)
            reason = error.strerror if isinstance(error, OSError) and error.strerror else str(error)
            raise UnpackError(f"{fmu}: cannot be unpacked into {folder.parent}: {reason}") from None
        except BaseException:
            _remove(folder)
            raise
        _folders[key] = folder
        return folder


def adopt(fmu: str | os.PathLike, folder: str | os.PathLike) -> None:
    """Uses `folder` (unpacked by another process, which removes it) for `fmu` in this process."""
    with _lock:
        _folders[_key(Path(fmu))] = Path(folder)


def _remove(folder: Path) -> None:
    """Removes an unpack folder, its marker last: a removal cut short leaves a folder the next process removes."""
    try:
        entries = list(os.scandir(folder))
    except OSError:
        entries = []
    for entry in entries:
        if entry.name == MARKER:
            continue
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(entry.path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                os.unlink(entry.path)
    with contextlib.suppress(OSError):
        os.unlink(folder / MARKER)
    with contextlib.suppress(OSError):
        os.rmdir(folder)
    if folder in _owned:
        _owned.remove(folder)


def remove_all() -> None:
    """Removes every folder this process unpacked into (at exit)."""
    with _lock:
        for folder in list(_owned):
            _remove(folder)
        _folders.clear()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # someone else's
    return True


def remove_leftovers(root: str | os.PathLike | None = None) -> list[Path]:
    """Removes unpack folders left in `root` (default $TMPDIR) by processes that are gone: only folders named as
    sdl-fmu names them, that carry its marker, are real folders and whose process no longer exists."""
    root = Path(root or tempfile.gettempdir())
    removed = []
    try:
        entries = list(os.scandir(root))
    except OSError:
        return removed
    for entry in entries:
        match = _FOLDER.fullmatch(entry.name)
        if not match or int(match["pid"]) == os.getpid() or _alive(int(match["pid"])):
            continue
        try:
            if not stat.S_ISDIR(entry.stat(follow_symlinks=False).st_mode):
                continue
            if not os.path.isfile(os.path.join(entry.path, MARKER)):
                continue
        except OSError:
            continue
        shutil.rmtree(entry.path, ignore_errors=True)
        removed.append(Path(entry.path))
    return removed


atexit.register(remove_all)
