"""Low-level helpers for the disk-backed arrays a run records (cosim/recorder.py) and the output stage reads
(results.py): below both, so that the output stage never imports the run stage."""

from __future__ import annotations

import mmap

import numpy as np


def release_pages(array) -> None:
    """Drops the pages of the file map behind `array` (a `ChunkedTable.finish` table or a view of one) from
    the process's resident memory; the data stays in the file and is read back if used again. A plain
    array is left alone."""
    base = array
    while isinstance(base, np.ndarray):
        base = base.base
    if isinstance(base, memoryview):  # np.frombuffer's view of the map
        base = base.obj
    if isinstance(base, mmap.mmap) and not base.closed and hasattr(mmap, "MADV_DONTNEED"):
        base.madvise(mmap.MADV_DONTNEED)
