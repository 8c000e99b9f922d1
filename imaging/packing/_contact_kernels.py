"""Exact contact geometry of flat elliptic disks (elliptic cylinders), numba kernels.

A particle is the convex set {R (x, y, z) + centre : (x/a)^2 + (y/b)^2 <= 1, |z| <= c},
with R the rotation whose columns are the particle axes in the box frame (l_a, l_b and
the normal) and c = h/2. Every query goes through its support function, which is exact,
so distances come from the GJK algorithm (Gilbert, Johnson & Keerthi 1988) on the
Minkowski difference, and the vertical distance to contact from conservative
advancement along -z with the GJK separating plane: each advance is a proven lower
bound, so a falling particle never enters another one.

Support points are returned as 3-tuples to keep the innermost loop free of allocations.
"""

from __future__ import annotations

import numpy as np
from numba import njit

INFINITE_DROP = 1.0e300


@njit(cache=True)
def support(center, rot, axes, dx, dy, dz):
    """Point of a particle furthest along (dx, dy, dz) (any length), as a 3-tuple [m]."""
    l0 = rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz
    l1 = rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz
    l2 = rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2] * dz
    a2 = axes[0] * axes[0]
    b2 = axes[1] * axes[1]
    s = np.sqrt(a2 * l0 * l0 + b2 * l1 * l1)
    p0 = 0.0
    p1 = 0.0
    if s > 0.0:
        p0 = a2 * l0 / s
        p1 = b2 * l1 / s
    p2 = axes[2] if l2 >= 0.0 else -axes[2]
    return (
        center[0] + rot[0, 0] * p0 + rot[0, 1] * p1 + rot[0, 2] * p2,
        center[1] + rot[1, 0] * p0 + rot[1, 1] * p1 + rot[1, 2] * p2,
        center[2] + rot[2, 0] * p0 + rot[2, 1] * p1 + rot[2, 2] * p2,
    )


@njit(cache=True)
def half_extents(rot, axes, out):
    """Half widths of the axis-aligned bounding box of a particle [m], written to ``out``."""
    for k in range(3):
        out[k] = np.sqrt(
            (axes[0] * rot[k, 0]) ** 2 + (axes[1] * rot[k, 1]) ** 2
        ) + axes[2] * abs(rot[k, 2])


def bounding_half_extents(rotations, semi_axes):
    """Half widths [m] of the axis-aligned bounding boxes of many particles, shape (n, 3)
    (vectorised twin of :func:`half_extents`)."""
    a, b, c = (semi_axes[:, None, k] for k in range(3))
    in_plane = np.hypot(a * rotations[:, :, 0], b * rotations[:, :, 1])
    return in_plane + c * np.abs(rotations[:, :, 2])


@njit(cache=True)
def _closest_on_triangle(w, i, j, k, lam):
    """Barycentric weights (into ``lam``) of the point of triangle w[i], w[j], w[k]
    closest to the origin (Ericson, Real-Time Collision Detection, Sec. 5.1.5)."""
    lam[i] = 0.0
    lam[j] = 0.0
    lam[k] = 0.0
    ab = w[j] - w[i]
    ac = w[k] - w[i]
    d1 = -np.dot(ab, w[i])
    d2 = -np.dot(ac, w[i])
    if d1 <= 0.0 and d2 <= 0.0:
        lam[i] = 1.0
        return
    d3 = -np.dot(ab, w[j])
    d4 = -np.dot(ac, w[j])
    if d3 >= 0.0 and d4 <= d3:
        lam[j] = 1.0
        return
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        lam[i] = 1.0 - v
        lam[j] = v
        return
    d5 = -np.dot(ab, w[k])
    d6 = -np.dot(ac, w[k])
    if d6 >= 0.0 and d5 <= d6:
        lam[k] = 1.0
        return
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        lam[i] = 1.0 - t
        lam[k] = t
        return
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        lam[j] = 1.0 - t
        lam[k] = t
        return
    denom = 1.0 / (va + vb + vc)
    lam[j] = vb * denom
    lam[k] = vc * denom
    lam[i] = 1.0 - lam[j] - lam[k]


@njit(cache=True)
def _closest_on_tetrahedron(w, lam, trial):
    """Barycentric weights of the point of tetrahedron w[0..3] closest to the origin.

    Returns False when the origin is inside. A flat tetrahedron is treated as outside
    every face, which is the robust choice for thin particles (Ericson Sec. 5.1.6).
    """
    faces = ((0, 1, 2, 3), (0, 2, 3, 1), (0, 3, 1, 2), (1, 3, 2, 0))
    best = np.inf
    outside_any = False
    for f in faces:
        i, j, k, m = f
        # np.cross's formula, written out (np.cross compiles three more functions)
        e = w[j] - w[i]
        g = w[k] - w[i]
        n = np.empty(3)
        n[0] = e[1] * g[2] - e[2] * g[1]
        n[1] = e[2] * g[0] - e[0] * g[2]
        n[2] = e[0] * g[1] - e[1] * g[0]
        side_origin = -np.dot(w[i], n)
        side_other = np.dot(w[m] - w[i], n)
        if side_origin * side_other > 0.0:
            continue
        outside_any = True
        trial[:] = 0.0
        _closest_on_triangle(w, i, j, k, trial)
        p = trial[i] * w[i] + trial[j] * w[j] + trial[k] * w[k]
        d2 = np.dot(p, p)
        if d2 < best:
            best = d2
            for q in range(4):
                lam[q] = trial[q]
    return outside_any


@njit(cache=True)
def _reduce_simplex(n, w, pb, lam, trial):
    """Replace the simplex by its closest feature to the origin; returns the new size,
    or 0 if the origin lies inside the tetrahedron."""
    lam[:] = 0.0
    if n == 1:
        lam[0] = 1.0
    elif n == 2:
        ab = w[1] - w[0]
        den = np.dot(ab, ab)
        t = -np.dot(w[0], ab) / den if den > 0.0 else 0.0
        t = min(max(t, 0.0), 1.0)
        lam[0] = 1.0 - t
        lam[1] = t
    elif n == 3:
        # int64 indices, not literals: the compiled _closest_on_triangle is the one of above
        _closest_on_triangle(w, np.int64(0), np.int64(1), np.int64(2), lam)
    elif not _closest_on_tetrahedron(w, lam, trial):
        return 0
    m = 0
    for i in range(n):
        if lam[i] > 0.0:
            for k in range(3):  # element-wise: a row assignment compiles numba's error text
                w[m, k] = w[i, k]
                pb[m, k] = pb[i, k]
            lam[m] = lam[i]
            m += 1
    lam[m:] = 0.0
    return m


@njit(cache=True)
def gjk(ca, ra, xa, cb, rb, xb, tol_abs, tol_rel):
    """Separation of two particles by GJK on the Minkowski difference A - B.

    Parameters
    ----------
    ca, ra, xa, cb, rb, xb
        Centre [m], rotation and semi-axes (a, b, c) [m] of particles A and B.
    tol_abs, tol_rel
        Stop when the upper and lower distance bounds differ by less than
        max(tol_abs [m], tol_rel * distance).

    Returns
    -------
    tuple
        (upper bound of the distance [m], lower bound [m], unit separating direction
        (3 floats, from B towards A), point of B nearest to A (3 floats) [m]). The
        upper bound is 0 when the particles intersect. Every point x of A - B satisfies
        x . direction >= lower bound, which is what makes advancement conservative.
    """
    w = np.zeros((4, 3))
    pb = np.zeros((4, 3))
    lam = np.zeros(4)
    trial = np.zeros(4)
    v = ca - cb
    n = 0
    lower = -np.inf
    for _ in range(96):
        vv = np.dot(v, v)
        if vv <= 1e-30:
            return 0.0, 0.0, 0.0, 0.0, 1.0, cb[0], cb[1], cb[2]
        vnorm = np.sqrt(vv)
        sa = support(ca, ra, xa, -v[0], -v[1], -v[2])
        sb = support(cb, rb, xb, v[0], v[1], v[2])
        lower = (v[0] * (sa[0] - sb[0]) + v[1] * (sa[1] - sb[1]) + v[2] * (sa[2] - sb[2])) / vnorm
        if vnorm - lower <= max(tol_abs, tol_rel * vnorm):
            break
        w[n, 0] = sa[0] - sb[0]
        w[n, 1] = sa[1] - sb[1]
        w[n, 2] = sa[2] - sb[2]
        pb[n, 0], pb[n, 1], pb[n, 2] = sb
        n = _reduce_simplex(n + 1, w, pb, lam, trial)
        if n == 0:
            return 0.0, 0.0, 0.0, 0.0, 1.0, cb[0], cb[1], cb[2]
        v = lam[0] * w[0] + lam[1] * w[1] + lam[2] * w[2] + lam[3] * w[3]
    else:
        # out of iterations: the bound must belong to the direction that is returned
        vnorm = np.sqrt(np.dot(v, v))
        sa = support(ca, ra, xa, -v[0], -v[1], -v[2])
        sb = support(cb, rb, xb, v[0], v[1], v[2])
        lower = (v[0] * (sa[0] - sb[0]) + v[1] * (sa[1] - sb[1]) + v[2] * (sa[2] - sb[2])) / vnorm
    q = lam[0] * pb[0] + lam[1] * pb[1] + lam[2] * pb[2] + lam[3] * pb[3]
    if n == 0:
        q = cb.copy()
    return vnorm, lower, v[0] / vnorm, v[1] / vnorm, v[2] / vnorm, q[0], q[1], q[2]


@njit(cache=True)
def drop_to_contact(ca, ra, xa, cb, rb, xb, max_drop, tol_gap):
    """Vertical fall of A, in the field of the fixed B, until the vertical gap is below
    tol_gap.

    Returns
    -------
    tuple
        (drop [m], contact point on B (3 floats) [m]); the drop is -1 if A and B
        intersect at the start and INFINITE_DROP if A passes B or falls further than
        ``max_drop`` [m] without touching it.
    """
    shifted = ca.copy()
    t = 0.0
    qx, qy, qz = cb[0], cb[1], cb[2]
    for _ in range(64):
        shifted[2] = ca[2] - t
        upper, lower, nx, ny, nz, px, py, pz = gjk(shifted, ra, xa, cb, rb, xb, 0.2 * tol_gap, 0.05)
        if upper <= 0.0:
            # touching after an exact flat-on-flat advance: keep the previous witness
            return (-1.0 if t == 0.0 else t), qx, qy, qz
        qx, qy, qz = px, py, pz
        if nz <= 1e-9:
            # B is beside or above A across the separating plane: falling never closes it
            return INFINITE_DROP, qx, qy, qz
        if lower <= tol_gap * nz:
            # the vertical gap (about lower / nz near contact) is below tol_gap; a small
            # Euclidean gap alone is a particle passing a neighbour's flank, not a contact
            return t, qx, qy, qz
        t += lower / nz
        if t > max_drop:
            return INFINITE_DROP, qx, qy, qz
    return t, qx, qy, qz


@njit(cache=True)
def contains_point(center, rot, axes, px, py, pz):
    """True if the point (px, py, pz) [m] lies inside the particle (boundary included)."""
    dx = px - center[0]
    dy = py - center[1]
    dz = pz - center[2]
    l0 = rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz
    l1 = rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz
    l2 = rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2] * dz
    if abs(l2) > axes[2]:
        return False
    return (l0 / axes[0]) ** 2 + (l1 / axes[1]) ** 2 <= 1.0
