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


@nb.njit(cache=True, parallel=True)
def column_runs(slab, include_edges, carry_phase, carry_length, carry_bounded, n_chunks):  # pragma: no cover - compiled
    """Run lengths along z (axis 0) of a ``(c, ny, nx)`` uint8 slab that continues lines
    begun in earlier slabs, and the runs left open at its far end.

    ``carry_phase`` (-1: no earlier slab), ``carry_length`` and ``carry_bounded`` (the run
    began after the other phase, not at the image's edge) describe, per ``(y, x)`` line,
    the run open at the slab's near end; they are updated in place to the run open at its
    far end. A run is counted when it closes, in the histogram of its phase, if it is
    bounded at both ends or ``include_edges``. Returns the two histograms (phase 1, phase
    0) of length ``max_length + 1`` where ``max_length`` is the slab's thickness plus the
    longest carried run; integer sums make them thread-count independent.
    """
    c, ny, nx = slab.shape
    longest = 0
    for j in range(ny):
        for i in range(nx):
            longest = max(longest, carry_length[j, i])
    size = c + longest + 1
    ones = np.zeros((n_chunks, size), dtype=np.int64)
    zeros = np.zeros((n_chunks, size), dtype=np.int64)
    per_chunk = (ny + n_chunks - 1) // n_chunks
    for chunk in nb.prange(n_chunks):
        for j in range(chunk * per_chunk, min(ny, (chunk + 1) * per_chunk)):
            for i in range(nx):
                phase = carry_phase[j, i]
                length = carry_length[j, i]
                bounded = carry_bounded[j, i]
                for k in range(c):
                    value = slab[k, j, i]
                    if phase == value:
                        length += 1
                        continue
                    if phase >= 0 and (bounded or include_edges):
                        if phase == 1:
                            ones[chunk, length] += 1
                        else:
                            zeros[chunk, length] += 1
                    bounded = phase >= 0
                    phase = value
                    length = 1
                carry_phase[j, i] = phase
                carry_length[j, i] = length
                carry_bounded[j, i] = bounded
    return ones.sum(axis=0), zeros.sum(axis=0)


@nb.njit(cache=True)
def close_runs(carry_phase, carry_length, size):  # pragma: no cover - compiled
    """Histograms (phase 1, phase 0) of the runs left open at the image's far edge."""
    ones = np.zeros(size, dtype=np.int64)
    zeros = np.zeros(size, dtype=np.int64)
    ny, nx = carry_phase.shape
    for j in range(ny):
        for i in range(nx):
            if carry_phase[j, i] == 1:
                ones[carry_length[j, i]] += 1
            elif carry_phase[j, i] == 0:
                zeros[carry_length[j, i]] += 1
    return ones, zeros


@nb.njit(cache=True, parallel=True)
def add_box_sums(table, low, high, out):  # pragma: no cover - compiled
    """``out[k] +=`` the sum over the box ``[low[k], high[k])`` of the array whose
    summed-volume table (zero first plane, row and column) is ``table``."""
    for k in nb.prange(low.shape[0]):
        z0, y0, x0 = low[k, 0], low[k, 1], low[k, 2]
        z1, y1, x1 = high[k, 0], high[k, 1], high[k, 2]
        out[k] += (table[z1, y1, x1] - table[z0, y1, x1] - table[z1, y0, x1]
                   - table[z1, y1, x0] + table[z0, y0, x1] + table[z0, y1, x0]
                   + table[z1, y0, x0] - table[z0, y0, x0])
