"""Reading a 3-D image slab by slab along z: numpy or dask arrays alike.

The image analyses (:mod:`.rev`, :mod:`.chords`) touch every voxel once per slab, so
their memory is set by the slab, not the image. A dask array is computed one slab at a
time by whichever dask scheduler is active (threads by default, a ``dask.distributed``
cluster when a client is connected).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

__all__ = ["slab", "slab_size", "slabs_in_order"]


def slab(array: Any, z0: int, z1: int) -> np.ndarray:
    """Slices ``[z0, z1)`` of a numpy or dask array, as numpy."""
    part = array[z0:z1]
    return np.asarray(part.compute() if hasattr(part, "compute") else part)


def slabs_in_order(function: Callable[[int], Any], starts: Iterable[int], workers: int
                   ) -> Iterator[Any]:
    """``function(z0)`` for each slab start, computed ``workers`` at a time (threads) and
    yielded in order, with at most ``workers`` results waiting: memory stays a few slabs."""
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        pending: deque = deque()
        for z0 in starts:
            pending.append(pool.submit(function, z0))
            if len(pending) > max(1, workers):
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()


def slab_size(array: Any, chunk_slices: int | None) -> int:
    """Slices per slab: ``chunk_slices``, else a dask array's first chunk, else all."""
    if chunk_slices is not None:
        return max(1, int(chunk_slices))
    chunks = getattr(array, "chunks", None)
    return int(chunks[0][0]) if chunks else int(array.shape[0])
