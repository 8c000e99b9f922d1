"""Slab reading (imaging.morphology.slabs): slab sizes, numpy and dask slabs alike, results
in order with a bounded number of slabs in flight."""

import threading
import time

import dask.array as da
import numpy as np

from imaging.morphology.slabs import slab, slab_size, slabs_in_order


def test_slab_size_is_the_setting_else_the_first_dask_chunk_else_the_whole_image():
    image = np.zeros((10, 4, 4))
    assert slab_size(image, None) == 10
    assert slab_size(image, 3) == 3
    assert slab_size(image, 0) == 1
    assert slab_size(da.from_array(image, chunks=(4, 4, 4)), None) == 4
    assert slab_size(da.from_array(image, chunks=(4, 4, 4)), 6) == 6


def test_a_dask_slab_is_the_numpy_slab():
    image = np.arange(7 * 3 * 2).reshape(7, 3, 2)
    lazy = da.from_array(image, chunks=(2, 3, 2))
    part = slab(lazy, 3, 6)
    assert type(part) is np.ndarray
    np.testing.assert_array_equal(part, image[3:6])
    np.testing.assert_array_equal(slab(image, 5, 9), image[5:])


def test_slabs_come_in_order_with_at_most_workers_plus_one_in_flight():
    """The first slabs take longest, so they finish last: the results still come in the
    order of the starts; with a slow consumer, no more than workers + 1 slabs are started
    ahead of the one consumed (submitting every slab at once would start all ten)."""
    workers, starts = 2, list(range(0, 40, 4))
    started: list[int] = []
    lock = threading.Lock()

    def work(z0: int) -> int:
        with lock:
            started.append(z0)
        time.sleep(0.002 * (len(starts) - z0 // 4))
        return z0 * z0

    results = []
    for k, value in enumerate(slabs_in_order(work, starts, workers)):
        with lock:
            assert len(started) <= k + 1 + workers
        results.append(value)
        time.sleep(0.01)
    assert results == [z0 * z0 for z0 in starts]
    assert list(slabs_in_order(work, [], workers)) == []
