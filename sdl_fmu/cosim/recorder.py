"""The run's samples, streamed to temporary files in chunks instead of held per sample in Python objects:
memory stays bounded however long the run and however many vehicles pass; the arrays handed to the
results are memory maps of those files (or plain arrays for a run that fits in one chunk)."""

from __future__ import annotations

import tempfile

import numpy as np

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
        table = np.memmap(self.file, dtype=float, mode="r", shape=(self.rows, self.columns))
        self.file.close()  # the map keeps its own handle; the unlinked file goes with the map
        return table
