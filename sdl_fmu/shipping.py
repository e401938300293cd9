"""Running many runs on Dask `distributed`: the cluster, and the files a run reads sent to the workers as bytes.
Used by the sweep (sweep.py) and the AEB car-to-car pack (verify/aeb/); it imports nothing that runs a scenario.

Every file a run reads goes to the workers as a Bundle, through Dask: a future per bundle, which Dask keeps and
recomputes if the worker holding it dies. A worker writes each bundle once into its own FMU cache, under
shipped/<hash of the contents>/, so a worker needs no shared folder and no FMU of its own."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import logging
import os
import re
import signal
import tempfile
from pathlib import Path

SHIPPED_FOLDER = "shipped"


class ClusterError(ValueError):
    """A cluster that cannot be reached or started (one line naming the option)."""


@dataclasses.dataclass(frozen=True)
class Bundle:
    """A file a run reads and the files it names, as bytes: (relative path, content) pairs, the file itself
    first. The relative paths are the bundle's own layout (the packer rewrites references to match)."""

    files: tuple[tuple[str, bytes], ...]

    @functools.cached_property
    def digest(self) -> str:
        hashed = hashlib.sha256()
        for name, content in self.files:
            hashed.update(name.encode() + b"\0" + hashlib.sha256(content).digest())
        return hashed.hexdigest()


def one_file(path: Path) -> Bundle:
    return Bundle(((path.name, path.read_bytes()),))


def passed_on(bundle: Bundle) -> Bundle:
    """The task whose result is a bundle: Dask holds the bundle in its graph and recomputes it on loss."""
    return bundle


def materialize(bundle: Bundle) -> Path:
    """The bundle as files in this machine's FMU cache, shipped/<digest>/, written once (atomically: into a
    temporary folder renamed into place; a concurrent writer's copy is discarded); the first file's path."""
    from .fmu.cache import cache_directory, made_cache_directory, remove_abandoned_builds

    root = cache_directory() / SHIPPED_FOLDER
    folder = root / bundle.digest[:32]
    if not (folder / bundle.files[0][0]).is_file():
        made_cache_directory()
        root.mkdir(exist_ok=True)
        remove_abandoned_builds(root)  # the temporary folders of killed workers
        work = Path(tempfile.mkdtemp(prefix=f".building-{os.getpid()}-", dir=root))
        try:
            for name, content in bundle.files:
                (work / name).parent.mkdir(parents=True, exist_ok=True)
                (work / name).write_bytes(content)
            try:
                os.rename(work, folder)
            except OSError:
                if not (folder / bundle.files[0][0]).is_file():
                    raise
        finally:
            if work.exists():
                import shutil

                shutil.rmtree(work, ignore_errors=True)
    return folder / bundle.files[0][0]


# Limits checked before a cluster is started or connected to (docs/sweeps.md): worker processes of a local cluster
# per core (a run is CPU-bound: more workers than cores only cost memory, some 100 MB each), and the seconds a Dask
# scheduler has to answer a connection with its handshake
WORKERS_PER_CORE = 4
SCHEDULER_PROBE = 10.0


def max_workers() -> int:
    return WORKERS_PER_CORE * (os.cpu_count() or 1)


def check_workers(workers: int | None) -> None:
    if workers is not None and not 1 <= workers <= max_workers():
        raise ClusterError(f"--workers {workers}: must be from 1 to {max_workers()} ({WORKERS_PER_CORE} per core)")


def check_scheduler(scheduler: str | None) -> None:
    """An address a Dask client can be given: [tcp://]host:port, or another Dask protocol's address."""
    if scheduler is None:
        return
    host_port = r"(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):\d{1,5}"
    if not (re.fullmatch(rf"(?:tcp://)?{host_port}", scheduler)
            or re.fullmatch(r"(?!tcp://)[a-z][a-z0-9+.-]*://\S+", scheduler)):  # tls://, inproc://, ucx://, ...
        raise ClusterError(f"--scheduler {scheduler!r}: expected an address such as tcp://host:8786")


def _probe_scheduler(scheduler: str) -> None:
    """A TCP address must answer as a Dask scheduler does: on connection it sends its handshake first, a message
    whose 8-byte length comes first. An HTTP server (the dashboard, port 8787) sends nothing until asked; another
    server sends something else. Either is one line, within SCHEDULER_PROBE s (a Dask client would wait for ever,
    or fail with a traceback)."""
    import socket
    import struct

    if "://" in scheduler and not scheduler.startswith("tcp://"):
        return  # tls, ucx, ...: only the client itself can speak them
    host, _, port = scheduler.removeprefix("tcp://").rpartition(":")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=SCHEDULER_PROBE) as connection:
            connection.settimeout(SCHEDULER_PROBE)
            header = b""
            while len(header) < 8:
                chunk = connection.recv(8 - len(header))
                if not chunk:
                    break
                header += chunk
    except socket.timeout:
        raise ClusterError(f"--scheduler {scheduler}: no Dask scheduler there (it sent nothing in "
                           f"{SCHEDULER_PROBE:g} s: a web server? The dashboard is usually on 8787, the scheduler "
                           "on 8786)") from None
    except (OSError, ValueError) as error:
        raise ClusterError(f"--scheduler {scheduler}: cannot connect: {getattr(error, 'strerror', None) or error}") \
            from None
    length = struct.unpack("<Q", header)[0] if len(header) == 8 else 0
    if not 0 < length < 2**20:
        raise ClusterError(f"--scheduler {scheduler}: not a Dask scheduler (what it sent is not Dask's handshake)")


def client(workers: int | None, scheduler: str | None, runs: int | None = None):
    """A client of the cluster at `scheduler`, or of a new LocalCluster of `workers` processes (default one per
    core; never more than `runs`); and what to close afterwards. ClusterError (one line) when neither can be had:
    an address that is none, or where no Dask scheduler answers, a number of workers beyond max_workers()."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        check_scheduler(scheduler)
        _probe_scheduler(scheduler)
        try:
            connected = Client(scheduler, timeout=10)
        except Exception as error:  # noqa: BLE001 - OSError, TimeoutError, CommClosedError, a protocol mismatch, ...
            text = (str(error).strip() or type(error).__name__).splitlines()[0]
            raise ClusterError(f"--scheduler {scheduler}: cannot connect: {text}") from None
        return connected, [connected]
    check_workers(workers)
    count = workers or os.cpu_count() or 1
    scratch = _Scratch()  # the workers' files (Dask's dask-scratch-space and its lock files): removed after them
    try:
        import dask

        with dask.config.set({"temporary-directory": str(scratch.path)}):  # the scheduler's workspace too
            # silence_logs: Dask's warnings (a worker killed as the cluster closes after Ctrl-C, a task cancelled)
            # are not the user's business; its errors still show
            # preload: dask_setup below, in each worker process. No dashboard; the scheduler's HTTP server (its
            # health routes, started all the same) on a free port: on its default, 8787, it warns when another
            # cluster of the machine holds it
            cluster = LocalCluster(n_workers=count if runs is None else max(1, min(count, runs)),
                                   threads_per_worker=1, processes=True, dashboard_address=None,
                                   scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                   local_directory=str(scratch.path), silence_logs=logging.ERROR,
                                   preload=[__name__])
    except (OSError, RuntimeError) as error:
        scratch.close()
        raise ClusterError(f"cannot start a local Dask cluster: {str(error).splitlines()[0]}") from None
    except BaseException:
        scratch.close()
        raise
    connected = Client(cluster)
    return connected, [connected, cluster, scratch]


def dask_setup(worker) -> None:
    """Run by Dask in each worker process of a local cluster started here (its preload): Ctrl-C is ignored there. A
    terminal's Ctrl-C reaches the whole process group, and each worker would end with a KeyboardInterrupt traceback
    on the user's terminal; sdl-fmu itself handles it and closes the cluster, which ends the workers."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class _Scratch:
    """What a local cluster's workers leave, removed by close() once the cluster is closed: a private temporary folder
    for them ($TMPDIR/sdl-fmu-dask-*; by default Dask keeps a dask-scratch-space folder with lock files in $TMPDIR
    for good), and the FMUs unpacked by workers the cluster had to kill (an interrupted sweep: a worker busy with a
    run does not stop in time), which their own exit would have removed (vehicle/unpack.py)."""

    def __init__(self):
        self.path = Path(tempfile.mkdtemp(prefix="sdl-fmu-dask-"))

    def close(self) -> None:
        import shutil

        from .vehicle.unpack import remove_leftovers

        shutil.rmtree(self.path, ignore_errors=True)
        remove_leftovers()
