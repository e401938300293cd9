"""Proof that sdl-fmu wrote a file, and one writer per folder.

A results or sweep folder carries a manifest listing the files sdl-fmu wrote there, each with its size and SHA-256,
signed with an HMAC-SHA256 key of this user's sdl-fmu (`ownership.key` in the FMU cache folder, made on first use,
readable by the user only). A file counts as sdl-fmu's only if a manifest with a valid signature lists it and its
bytes are still those listed: a manifest planted by hand (or written by another user's sdl-fmu, or an older
sdl-fmu), or a file changed since sdl-fmu wrote it, proves nothing, and such files are never deleted or
overwritten. An appended file (a sweep's journal) is recorded by the size and SHA-256 of its start: what sdl-fmu
appended later is its own too.

`locked(folder)` holds an exclusive lock (flock) on a folder while a command writes into it: a second writer is
refused at once (a sweep) or waits its turn (the few renames that put a run's results in place)."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import hmac
import json
import os
from pathlib import Path

KEY_NAME = "ownership.key"


class Locked(Exception):
    """Another process holds the folder's lock."""


@functools.lru_cache(maxsize=1)
def _key(root: str) -> bytes | None:
    path = Path(root) / KEY_NAME
    try:
        return path.read_bytes()[:64] or None
    except FileNotFoundError:
        pass
    except OSError:
        return None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:  # another process made it first
        try:
            return path.read_bytes()[:64] or None
        except OSError:
            return None
    except OSError:
        return None
    with os.fdopen(descriptor, "wb") as file:
        file.write(os.urandom(32))
    return path.read_bytes()[:64]


def key() -> bytes | None:
    """This user's signing key (None when the cache folder can be neither read nor written: nothing is proved)."""
    from .paths import cache_directory

    return _key(str(cache_directory()))


@functools.lru_cache(maxsize=256)
def _digest(path: str, size: int, mtime: int, inode: int, length: int) -> str:
    hashed = hashlib.sha256()
    with open(path, "rb") as file:
        left = length
        while left > 0:
            block = file.read(min(left, 1 << 20))
            if not block:
                break
            hashed.update(block)
            left -= len(block)
    return hashed.hexdigest()


def record(path: Path, prefix: bool = False) -> dict | None:
    """{"size", "sha256"} of a file (of its whole content; `prefix`: also marks it as appended to later), None if it
    is not a regular file."""
    try:
        status = path.lstat()
    except OSError:
        return None
    if not path.is_file() or path.is_symlink():
        return None
    entry = {"size": status.st_size,
             "sha256": _digest(str(path), status.st_size, status.st_mtime_ns, status.st_ino, status.st_size)}
    if prefix:
        entry["appended"] = True
    return entry


def unchanged(path: Path, entry) -> bool:
    """Whether the file is still what `entry` records (an appended file: its first `size` bytes are); `entry` may
    list forms, any of which counts (None in the list: absent), for a file being exchanged."""
    if isinstance(entry, list):
        return any(not os.path.lexists(path) if form is None else unchanged(path, form) for form in entry)
    if not isinstance(entry, dict) or not isinstance(entry.get("size"), int) or not isinstance(entry.get("sha256"),
                                                                                               str):
        return False
    try:
        status = path.lstat()
    except OSError:
        return False
    if not path.is_file() or path.is_symlink():
        return False
    if entry.get("appended"):
        if status.st_size < entry["size"]:
            return False
    elif status.st_size != entry["size"]:
        return False
    return hmac.compare_digest(_digest(str(path), status.st_size, status.st_mtime_ns, status.st_ino, entry["size"]),
                               entry["sha256"])


def _canonical(data: dict) -> bytes:
    return json.dumps({k: v for k, v in data.items() if k != "signature"}, sort_keys=True,
                      separators=(",", ":")).encode()


def signed(data: dict) -> dict:
    """`data` with its signature (none, when there is no key: such a manifest proves nothing)."""
    secret = key()
    if secret is None:
        return dict(data)
    return {**data, "signature": hmac.new(secret, _canonical(data), hashlib.sha256).hexdigest()}


def authentic(data) -> bool:
    """Whether a manifest's signature is this user's sdl-fmu's."""
    secret = key()
    if secret is None or not isinstance(data, dict) or not isinstance(data.get("signature"), str):
        return False
    return hmac.compare_digest(hmac.new(secret, _canonical(data), hashlib.sha256).hexdigest(), data["signature"])


def write_json(path: Path, data: dict) -> None:
    """Writes JSON to a temporary sibling and renames it into place: the old file or the new, never a part."""
    partial = path.with_name(path.name + ".partial")
    try:
        partial.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
        os.replace(partial, path)
    except BaseException:
        with contextlib.suppress(OSError):
            partial.unlink()
        raise


@contextlib.contextmanager
def locked(folder: Path, wait: bool = False):
    """An exclusive lock on `folder` (flock on the folder itself) while the block runs; Locked if another process
    holds it and `wait` is False."""
    import fcntl

    descriptor = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            raise Locked(str(folder)) from None
        yield
    finally:
        os.close(descriptor)  # releases the lock
