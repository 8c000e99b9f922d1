"""Signed volumes, centroids and circumcentres of tetrahedra (numba).

The geometry both the Delaunay construction (:mod:`shared.delaunay`, which tests empty
circumspheres) and the finite-volume mesh (:mod:`shared.mesh`, dual points and cell
volumes) compute from vertex coordinates. A positively oriented cell (o, p, q, r) has
volume ((p - o) . ((q - o) x (r - o))) / 6 > 0.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit, prange

__all__ = ["cell_geometry", "cell_volumes"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@njit(cache=True, parallel=True)
def _signed_volumes(points: FloatArray, tetrahedra: IntArray) -> FloatArray:
    signed = np.empty(tetrahedra.shape[0])
    for c in prange(tetrahedra.shape[0]):
        o, p, q, r = tetrahedra[c, 0], tetrahedra[c, 1], tetrahedra[c, 2], tetrahedra[c, 3]
        ux, uy, uz = points[p, 0] - points[o, 0], points[p, 1] - points[o, 1], \
            points[p, 2] - points[o, 2]
        vx, vy, vz = points[q, 0] - points[o, 0], points[q, 1] - points[o, 1], \
            points[q, 2] - points[o, 2]
        wx, wy, wz = points[r, 0] - points[o, 0], points[r, 1] - points[o, 1], \
            points[r, 2] - points[o, 2]
        signed[c] = (ux * (vy * wz - vz * wy) + uy * (vz * wx - vx * wz)
                     + uz * (vx * wy - vy * wx)) / 6.0
    return signed


def cell_volumes(points: npt.ArrayLike, tetrahedra: npt.ArrayLike) -> FloatArray:
    """Signed volumes of tetrahedra [m3]: positive for positively oriented cells.

    Parameters
    ----------
    points
        (n_points, 3) vertex coordinates [m].
    tetrahedra
        (n_cells, 4) vertex indices.
    """
    return _signed_volumes(np.ascontiguousarray(points, dtype=np.float64),
                           np.ascontiguousarray(tetrahedra, dtype=np.int64))


@njit(cache=True, parallel=True)
def cell_geometry(
    points: FloatArray, tetrahedra: IntArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Signed volumes [m3], centroids and circumcentres [m] of tetrahedra (NaN
    circumcentres for flat cells), from (n_points, 3) coordinates [m] and (n_cells, 4)
    vertex indices."""
    n = tetrahedra.shape[0]
    signed = np.empty(n)
    centroids = np.empty((n, 3))
    circumcentres = np.empty((n, 3))
    for c in prange(n):
        o, p, q, r = tetrahedra[c, 0], tetrahedra[c, 1], tetrahedra[c, 2], tetrahedra[c, 3]
        ox, oy, oz = points[o, 0], points[o, 1], points[o, 2]
        ux, uy, uz = points[p, 0] - ox, points[p, 1] - oy, points[p, 2] - oz
        vx, vy, vz = points[q, 0] - ox, points[q, 1] - oy, points[q, 2] - oz
        wx, wy, wz = points[r, 0] - ox, points[r, 1] - oy, points[r, 2] - oz
        vw = (vy * wz - vz * wy, vz * wx - vx * wz, vx * wy - vy * wx)
        wu = (wy * uz - wz * uy, wz * ux - wx * uz, wx * uy - wy * ux)
        uv = (uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx)
        edges = ((ux, vx, wx), (uy, vy, wy), (uz, vz, wz))
        triple = ux * vw[0] + uy * vw[1] + uz * vw[2]
        signed[c] = triple / 6.0
        # A flat cell has no circumcentre; the caller rejects it.
        inverse = np.nan if triple == 0.0 else 1.0 / (2.0 * triple)
        uu = ux * ux + uy * uy + uz * uz
        vv = vx * vx + vy * vy + vz * vz
        ww = wx * wx + wy * wy + wz * wz
        for d in range(3):
            base = points[o, d]
            centroids[c, d] = base + 0.25 * (edges[d][0] + edges[d][1] + edges[d][2])
            circumcentres[c, d] = base + (uu * vw[d] + vv * wu[d] + ww * uv[d]) * inverse
    return signed, centroids, circumcentres
