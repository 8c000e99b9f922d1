"""Orders of the flow unknowns: fill-reducing (nested dissection) or by locality.

The unknowns of the flow system (:func:`shared.fv.flow_pattern`) are numbered in a
fill-reducing order when a factor will solve them, so that CHOLMOD (:mod:`shared.solver`)
factorises them as they come: the order is computed from the cell positions in one pass
over the edges per level, where METIS costs about as much as the factorisation itself.
Each set of more than ``leaf_size`` nodes is cut by a plane normal to its longest
extent; a small vertex separator covers the cut edges and is numbered after the two
halves, which are cut in turn. Multigrid needs no such order, only neighbours close in
memory: :func:`locality_order` sorts the cells along a Z-order (Morton) curve, five
times cheaper than the dissection.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

__all__ = ["locality_order", "nested_dissection"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

# Nested dissection stops at this many cells: smaller blocks barely change the fill.
_LEAF_SIZE = 16
# Candidate positions (quantiles) of a dissection plane: trading some balance for a
# smaller separator reduces the fill.
_CUT_FRACTIONS = np.array([0.42, 0.46, 0.5, 0.54, 0.58])
_BINS = 1024


@njit(cache=True)
def _adjacency(n_nodes: int, pairs: IntArray) -> tuple[IntArray, IntArray]:
    """Symmetric CSR adjacency (start, neighbours) of nodes joined by the listed pairs."""
    start = np.zeros(n_nodes + 1, dtype=np.int64)
    for f in range(pairs.shape[0]):
        start[pairs[f, 0] + 1] += 1
        start[pairs[f, 1] + 1] += 1
    for k in range(n_nodes):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    neighbours = np.empty(start[n_nodes], dtype=np.int64)
    for f in range(pairs.shape[0]):
        a, b = pairs[f, 0], pairs[f, 1]
        neighbours[fill[a]] = b
        fill[a] += 1
        neighbours[fill[b]] = a
        fill[b] += 1
    return start, neighbours


@njit(cache=True)
def _label_halves(
    nodes: IntArray, centres: FloatArray, start: IntArray, neighbours: IntArray,
    side: IntArray, cross: IntArray, stamp: IntArray, segment: int,
) -> None:
    """Label ``nodes`` 0 / 1 (halves) or 2 (separator) in ``side``.

    The nodes are cut by a plane normal to their longest coordinate extent, at the
    quantile of :data:`_CUT_FRACTIONS` that cuts the fewest edges per unit of balance
    (cut edges / (2 min(q, 1 - q))): less fill than the median cut, for one more pass
    over the edges. The cut edges are covered by a small vertex separator, taking the
    nodes with the most uncovered cut edges first (a greedy cover, close to the minimum
    one; see ``benchmarks/reference/README.md``).
    """
    low = np.full(3, np.inf)
    high = np.full(3, -np.inf)
    for node in nodes:
        stamp[node] = segment
        for d in range(3):
            low[d] = min(low[d], centres[node, d])
            high[d] = max(high[d], centres[node, d])
    axis = np.argmax(high - low)
    if not high[axis] > low[axis]:
        side[nodes] = 1  # coincident centres: no cut
        return
    # Quantiles from a histogram of as many bins as nodes (at most 1024): one pass, no
    # sort, balance within a bin.
    bins = min(nodes.shape[0], _BINS)
    width = (high[axis] - low[axis]) / bins
    counts = np.zeros(bins + 1, dtype=np.int64)
    for node in nodes:
        counts[int((centres[node, axis] - low[axis]) / width)] += 1
    planes = np.empty(_CUT_FRACTIONS.shape[0])
    below, k = 0, 0
    for b in range(bins + 1):
        below += counts[b]
        while k < planes.shape[0] and below >= _CUT_FRACTIONS[k] * nodes.shape[0]:
            planes[k] = low[axis] + (b + 1) * width
            k += 1
    cut_edges = np.zeros(planes.shape[0])
    first, final = planes[0], planes[-1]
    for node in nodes:
        here = centres[node, axis]
        if here >= final:
            continue
        for m in range(start[node], start[node + 1]):
            other = neighbours[m]
            there = centres[other, axis]
            if there <= here or there < first or stamp[other] != segment:
                continue
            for k in range(planes.shape[0]):
                # an edge is cut by a plane lying in (here, there]
                if here < planes[k] <= there:
                    cut_edges[k] += 1.0
    score = cut_edges / (2.0 * np.minimum(_CUT_FRACTIONS, 1.0 - _CUT_FRACTIONS))
    plane = planes[np.argmin(score)]
    for node in nodes:
        side[node] = 0 if centres[node, axis] < plane else 1
    cut = np.empty(nodes.shape[0], dtype=np.int64)
    n_cut, most = 0, 0
    for node in nodes:
        cross[node] = 0
        for m in range(start[node], start[node + 1]):
            other = neighbours[m]
            if stamp[other] == segment and side[other] != side[node]:
                cross[node] += 1
        if cross[node] > 0:
            cut[n_cut] = node
            n_cut += 1
            most = max(most, cross[node])
    for level in range(most, 0, -1):
        for node in cut[:n_cut]:
            if side[node] == 2 or cross[node] < level:
                continue
            for m in range(start[node], start[node + 1]):
                other = neighbours[m]
                if stamp[other] == segment and side[other] == 1 - side[node]:
                    cross[other] -= 1
            side[node] = 2


@njit(cache=True)
def _nested_dissection(
    centres: FloatArray, start: IntArray, neighbours: IntArray, leaf_size: int
) -> IntArray:
    """Fill-reducing elimination order of a mesh graph by geometric nested dissection.

    Each set of nodes larger than ``leaf_size`` is split by :func:`_label_halves` and
    reordered as [half 0, half 1, separator]; the halves are split in turn. Returns
    the nodes in elimination order.
    """
    n = centres.shape[0]
    order = np.arange(n)
    side = np.zeros(n, dtype=np.int64)
    cross = np.zeros(n, dtype=np.int64)
    stamp = np.full(n, -1, dtype=np.int64)
    # Depth-first: the stack never holds more than two segments per level.
    stack = np.empty((128, 2), dtype=np.int64)
    stack[0, 0], stack[0, 1] = 0, n
    top, segment = 1, 0
    while top > 0:
        top -= 1
        first, end = stack[top, 0], stack[top, 1]
        if end - first <= leaf_size:
            continue
        segment += 1
        nodes = order[first:end].copy()
        _label_halves(nodes, centres, start, neighbours, side, cross, stamp, segment)
        counts = np.zeros(3, dtype=np.int64)
        for node in nodes:
            counts[side[node]] += 1
        if counts[0] == 0 or counts[1] == 0:
            continue  # coincident centres: no cut, keep as a leaf
        fill = np.array([first, first + counts[0], first + counts[0] + counts[1]])
        for node in nodes:
            order[fill[side[node]]] = node
            fill[side[node]] += 1
        stack[top, 0], stack[top, 1] = first, first + counts[0]
        stack[top + 1, 0], stack[top + 1, 1] = first + counts[0], fill[1]
        top += 2
    return order



def nested_dissection(
    centres: npt.ArrayLike, edges: npt.ArrayLike, leaf_size: int = _LEAF_SIZE
) -> IntArray:
    """Fill-reducing elimination order of a graph whose nodes have positions.

    Parameters
    ----------
    centres
        (n_nodes, 3) node positions [m] (the cell centroids of a mesh).
    edges
        (n_edges, 2) node pairs joined in the graph (cells sharing a facet).
    leaf_size
        Sets of at most this many nodes are not cut further.

    Returns
    -------
    ndarray of int64, shape (n_nodes,)
        The nodes in elimination order (a permutation of ``range(n_nodes)``).
    """
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    edges = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
    if centres.ndim != 2 or centres.shape[1] != 3:
        raise ValueError(f"centres must have shape (n, 3), got {centres.shape}")
    start, neighbours = _adjacency(centres.shape[0], edges)
    return _nested_dissection(centres, start, neighbours, int(leaf_size))


# Bits per coordinate of the Morton key (3 x 21 = 63 bits).
_MORTON_BITS = 21


def locality_order(centres: npt.ArrayLike) -> IntArray:
    """Nodes sorted along a Z-order (Morton) curve of their positions.

    Parameters
    ----------
    centres
        (n_nodes, 3) node positions [m].

    Returns
    -------
    ndarray of int64, shape (n_nodes,)
        A permutation of ``range(n_nodes)``; nodes in one octant of any level of the
        bounding cube's subdivision are contiguous in it.
    """
    centres = np.asarray(centres, dtype=np.float64)
    if centres.ndim != 2 or centres.shape[1] != 3:
        raise ValueError(f"centres must have shape (n, 3), got {centres.shape}")
    if centres.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    low = centres.min(axis=0)
    extent = float(np.max(centres.max(axis=0) - low)) or 1.0
    cells = ((centres - low) / extent * (2**_MORTON_BITS - 1)).astype(np.uint64)
    key = np.zeros(centres.shape[0], dtype=np.uint64)
    for bit in range(_MORTON_BITS):
        for axis in range(3):
            key |= ((cells[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    return np.argsort(key, kind="stable").astype(np.int64)
