"""numba kernels of the image analyses: window sums, interface face counts, chord runs.

Arrays in, arrays out; no Python objects. Each kernel has a ``prange`` loop over
independent items (windows or image lines) whose results go to separate slots, so the
result does not depend on the thread count.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, parallel=True)
def window_sums(values, starts, edges):  # pragma: no cover - compiled
    """Sum of ``values`` over boxes of edges ``edges`` whose lowest corners are ``starts``."""
    n = starts.shape[0]
    out = np.zeros(n, dtype=np.float64)
    for k in nb.prange(n):
        z0, y0, x0 = starts[k, 0], starts[k, 1], starts[k, 2]
        total = 0.0
        for i in range(z0, z0 + edges[0]):
            for j in range(y0, y0 + edges[1]):
                for m in range(x0, x0 + edges[2]):
                    total += values[i, j, m]
        out[k] = total
    return out


@nb.njit(cache=True, parallel=True)
def window_interface_faces(binary, starts, edges):  # pragma: no cover - compiled
    """Number of voxel faces between unlike phases inside each box window."""
    n = starts.shape[0]
    out = np.zeros(n, dtype=np.int64)
    for k in nb.prange(n):
        z0, y0, x0 = starts[k, 0], starts[k, 1], starts[k, 2]
        z1, y1, x1 = z0 + edges[0], y0 + edges[1], x0 + edges[2]
        faces = 0
        for i in range(z0, z1):
            for j in range(y0, y1):
                for m in range(x0, x1):
                    v = binary[i, j, m]
                    if m + 1 < x1 and binary[i, j, m + 1] != v:
                        faces += 1
                    if j + 1 < y1 and binary[i, j + 1, m] != v:
                        faces += 1
                    if i + 1 < z1 and binary[i + 1, j, m] != v:
                        faces += 1
        out[k] = faces
    return out


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
