"""A read-only sequence whose items are made only when asked for (events, vehicle tracks, surface sections of
a long run): negative indices, slices and the range check in one place."""

from __future__ import annotations

from collections.abc import Sequence


class LazySequence(Sequence):
    """Subclasses give `__len__` and `_item(index)` for 0 <= index < len; slices come back as lists."""

    def _item(self, index: int):
        raise NotImplementedError

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self._item(k) for k in range(*index.indices(len(self)))]
        if index < 0:
            index += len(self)
        if not 0 <= index < len(self):
            raise IndexError(f"{type(self).__name__} index out of range")
        return self._item(index)
