"""Running many runs on Dask `distributed`: the cluster, and the files a run reads sent to the workers as bytes.
Used by the sweep (sweep.py) and the AEB car-to-car pack (verify/aeb/); it imports nothing that runs a scenario.

Every file a run reads goes to the workers as a Bundle, through Dask: a future per bundle, which Dask keeps and
recomputes if the worker holding it dies. A worker writes each bundle once into its own FMU cache, under
shipped/<hash of the contents>/, so a worker needs no shared folder and no FMU of its own."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
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
    from .fmu.cache import cache_directory, remove_abandoned_builds

    root = cache_directory() / SHIPPED_FOLDER
    folder = root / bundle.digest[:32]
    if not (folder / bundle.files[0][0]).is_file():
        root.mkdir(parents=True, exist_ok=True)
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


def client(workers: int | None, scheduler: str | None):
    """A client of the cluster at `scheduler`, or of a new LocalCluster of `workers` processes (default one per
    core); and what to close afterwards. ClusterError (one line) when neither can be had."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            connected = Client(scheduler, timeout=10)
        except (OSError, ValueError, TypeError) as error:
            raise ClusterError(f"--scheduler {scheduler}: cannot connect: {str(error).splitlines()[0]}") from None
        return connected, [connected]
    try:
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                               dashboard_address=None)
    except (OSError, RuntimeError) as error:
        raise ClusterError(f"cannot start a local Dask cluster: {str(error).splitlines()[0]}") from None
    connected = Client(cluster)
    return connected, [connected, cluster]
