"""numba kernels of the image analyses: chord runs along image lines.

Arrays in, arrays out; no Python objects. The ``prange`` loop runs over chunks of lines
whose integer histograms go to separate slots, so the result does not depend on the
thread count.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, parallel=True)
def line_run_histograms(lines, include_edges, n_chunks):  # pragma: no cover - compiled
    """Histograms of run lengths of 1s and 0s along the rows of a 2-D uint8 array.

    Returns two int64 arrays of shape ``(length + 1,)``: the count of runs of each length
    for phase 1 and for phase 0. Runs touching either end of a line are truncated by the
    image and are counted only if ``include_edges``. Lines are split into ``n_chunks``
    chunks with one histogram each; integer sums make the result thread-count independent.
    """
    n_lines, length = lines.shape
    ones = np.zeros((n_chunks, length + 1), dtype=np.int64)
    zeros = np.zeros((n_chunks, length + 1), dtype=np.int64)
    per_chunk = (n_lines + n_chunks - 1) // n_chunks
    for c in nb.prange(n_chunks):
        for k in range(c * per_chunk, min(n_lines, (c + 1) * per_chunk)):
            start = 0
            for m in range(1, length + 1):
                if m == length or lines[k, m] != lines[k, start]:
                    if include_edges or (start > 0 and m < length):
                        if lines[k, start] != 0:
                            ones[c, m - start] += 1
                        else:
                            zeros[c, m - start] += 1
                    start = m
    return ones.sum(axis=0), zeros.sum(axis=0)
