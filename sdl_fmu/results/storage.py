"""The run's samples and its event log, streamed to temporary files in chunks instead of held per sample or
per event in Python objects: memory stays bounded however long the run and however many vehicles pass.

The sample arrays handed to the results are read-only maps of those files (or plain arrays for a run that
fits in one chunk); whoever reads through a long one in order (the CSV writers) calls `release_pages`
now and then, so that the pages already read leave the process's resident memory again."""

from __future__ import annotations

import mmap
import pickle
import tempfile

import numpy as np

from ..lazy_sequence import LazySequence

CHUNK_ROWS = 8192


class ChunkedTable:
    """Rows of floats appended one at a time or as a block; `finish` returns a (rows, columns) array."""

    def __init__(self, columns: int):
        self.columns = columns
        self.buffer = np.empty((CHUNK_ROWS, columns))
        self.pending: list = []  # rows appended since the last block was copied into the buffer
        self.filled = 0
        self.rows = 0
        self.file = None

    def append(self, row) -> None:
        """One row (a tuple of floats): kept in a list, copied into the buffer a block at a time."""
        self.pending.append(row)
        if len(self.pending) == 1024:
            self._take_pending()

    def _take_pending(self) -> None:
        if self.pending:
            block, self.pending = np.array(self.pending, dtype=float), []
            self.extend(block)

    def extend(self, block: np.ndarray) -> None:
        for start in range(0, len(block), CHUNK_ROWS):
            part = block[start:start + CHUNK_ROWS]
            if self.filled + len(part) > CHUNK_ROWS:
                self._flush()
            self.buffer[self.filled:self.filled + len(part)] = part
            self.filled += len(part)
            self.rows += len(part)

    def _flush(self) -> None:
        if self.file is None:
            self.file = tempfile.TemporaryFile(prefix="sdl-fmu-samples-")
        self.file.write(self.buffer[:self.filled].tobytes())
        self.filled = 0

    def finish(self) -> np.ndarray:
        self._take_pending()
        if self.file is None:
            return self.buffer[:self.filled].copy()
        self._flush()
        self.file.flush()
        self.buffer = None
        if self.rows == 0:
            return np.empty((0, self.columns))
        # a read-only map of the whole file; the map keeps its own handle, the unlinked file goes with it
        pages = mmap.mmap(self.file.fileno(), 0, access=mmap.ACCESS_READ)
        self.file.close()
        return np.frombuffer(pages, dtype=float).reshape(self.rows, self.columns)


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


EVENT_BATCH = 1024  # events pickled to the file at a time


class EventLog(LazySequence):
    """The run's event log (one dict per event, in order), appended to a temporary file in batches: its
    memory stays bounded however many events a run logs. Reads back as a sequence of dicts (each read
    unpickles afresh: a dict taken from it is the caller's own)."""

    def __init__(self):
        self.pending: list[dict] = []  # events since the last batch went to the file
        self.offsets: list[int] = []  # file offset of each (full) batch written
        self.file = None

    def append(self, event: dict) -> None:
        self.pending.append(event)
        if len(self.pending) == EVENT_BATCH:
            if self.file is None:
                self.file = tempfile.TemporaryFile(prefix="sdl-fmu-events-")
            self.file.seek(0, 2)
            self.offsets.append(self.file.tell())
            pickle.dump(self.pending, self.file, protocol=pickle.HIGHEST_PROTOCOL)
            self.pending = []

    def _batch(self, k: int) -> list[dict]:
        if k == len(self.offsets):
            return pickle.loads(pickle.dumps(self.pending, protocol=pickle.HIGHEST_PROTOCOL))
        self.file.seek(self.offsets[k])
        return pickle.load(self.file)

    def __len__(self) -> int:
        return len(self.offsets) * EVENT_BATCH + len(self.pending)

    def __iter__(self):
        for k in range(len(self.offsets) + 1):
            yield from self._batch(k)

    def _item(self, index: int) -> dict:
        return self._batch(index // EVENT_BATCH)[index % EVENT_BATCH]

    def __eq__(self, other) -> bool:
        if isinstance(other, (EventLog, list, tuple)):
            return len(self) == len(other) and all(a == b for a, b in zip(self, other))
        return NotImplemented

    def __repr__(self) -> str:
        return f"EventLog({len(self)} events)"

    def __reduce__(self):
        return list, (list(self),)  # pickled (e.g. sent to another process) as a plain list
