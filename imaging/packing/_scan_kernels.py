"""Contact and overlap by the multiscale scan of Ferrage et al. 2015, Sec. II B (numba).

The ``scan`` contact mode; the ``exact`` mode (:mod:`._contact_kernels`) finds contacts
on the disk shape itself. A particle is a flat elliptic disk: semi-axes (l_a, l_b) of its
basal ellipse, half thickness h / 2, frame columns (l_a axis, l_b axis, normal).

Scan points of the settling particle A lie every delta_1 = sqrt(pi l_a l_b / n_sp) on
its bottom face and edge rings; delta_z, the vertical distance of a point down to the
bed particle B, is minimised over offsets of step delta_(n+1) = delta_n / 10 around the
lowest points until delta_n < d_cont. A scan point inside B is an overlap; the overlap
scan is the inverse, from B's basal faces in A's frame. Between scan points nothing is
seen, so small overlaps remain (the paper's f_o, Table IV). Our readings:
docs/packing.md, "imaging.packing._scan_kernels". Reference: E. Ferrage et al.,
Phys. Rev. E 91, 062210 (2015).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from imaging.packing._contact_kernels import INFINITE_DROP, support

__all__ = ["scan_drop", "scan_overlap", "scan_spacing"]

_STEPS = 10
"""Offsets -10..10 of delta_(n+1) cover (-delta_n, +delta_n)."""

_REFINED = 8
"""Points refined per step size: the lowest ones within delta_n of the lowest."""

_SWEEPS = 32
"""Largest number of x-then-y sweeps of one point at one step size."""

_NONE = 1 << 20
"""An offset of no searched window."""


@njit(cache=True)
def scan_spacing(a, b, n_sp):
    """delta_1 [m]: the spacing that puts n_sp grid points on the basal ellipse."""
    return np.sqrt(np.pi * a * b / n_sp)


@njit(cache=True)
def _local_point(kind, u, v, a, b, c, face):
    """A scan point in the particle frame: basal (kind 0: x = u, y = v on the face at
    z = face c) or edge (kind 1: angle u, height v)."""
    if kind == 0:
        return u, v, face * c
    return a * np.cos(u), b * np.sin(u), v


@njit(cache=True)
def _to_world(center, rot, x, y, z):
    return (center[0] + rot[0, 0] * x + rot[0, 1] * y + rot[0, 2] * z,
            center[1] + rot[1, 0] * x + rot[1, 1] * y + rot[1, 2] * z,
            center[2] + rot[2, 0] * x + rot[2, 1] * y + rot[2, 2] * z)


@njit(cache=True)
def _to_local(center, rot, px, py, pz):
    dx, dy, dz = px - center[0], py - center[1], pz - center[2]
    return (rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz,
            rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz,
            rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2] * dz)


@njit(cache=True)
def _grid(a, b, c, n_sp, face, with_edge):
    """Scan points (kind, u, v) of one basal face (and the edge) at delta_1, their
    coordinates (x, y, z) in the particle frame [m], and delta_1 [m]."""
    delta = scan_spacing(a, b, n_sp)
    nx, ny = int(a / delta), int(b / delta)
    basal = 0
    for i in range(-nx, nx + 1):
        for j in range(-ny, ny + 1):
            if (i * delta / a) ** 2 + (j * delta / b) ** 2 <= 1.0:
                basal += 1
    perimeter = np.pi * (3.0 * (a + b) - np.sqrt((3.0 * a + b) * (a + 3.0 * b)))
    n_around = max(8, int(np.ceil(perimeter / delta)))
    n_rings = max(1, int(np.ceil(2.0 * c / delta))) + 1
    total = basal + (n_around * n_rings if with_edge else 0)
    kind = np.empty(total, np.int64)
    u = np.empty(total)
    v = np.empty(total)
    x = np.empty(total)
    y = np.empty(total)
    z = np.empty(total)
    k = 0
    for i in range(-nx, nx + 1):
        for j in range(-ny, ny + 1):
            if (i * delta / a) ** 2 + (j * delta / b) ** 2 <= 1.0:
                kind[k], u[k], v[k] = 0, i * delta, j * delta
                x[k], y[k], z[k] = _local_point(np.int64(0), u[k], v[k], a, b, c, face)
                k += 1
    if with_edge:
        # every ring has the same angles: one cos and sin per angle
        ring_x = np.empty(n_around)
        ring_y = np.empty(n_around)
        for s in range(n_around):
            ring_x[s], ring_y[s], _ = _local_point(np.int64(1), 2.0 * np.pi * s / n_around, 0.0,
                                                   a, b, c, face)
        for r in range(n_rings):
            for s in range(n_around):
                kind[k] = 1
                u[k] = 2.0 * np.pi * s / n_around
                v[k] = -c + 2.0 * c * r / (n_rings - 1)
                x[k], y[k], z[k] = ring_x[s], ring_y[s], v[k]
                k += 1
    return kind, u, v, x, y, z, delta


@njit(cache=True)
def _ray_interval(ox, oy, oz, dx, dy, dz, xb):
    """Interval (t_in, t_out) of the ray o + t d (B's frame) inside B, or (inf, inf)."""
    lo, hi = -np.inf, np.inf
    # slab |z| <= h / 2
    if abs(dz) > 1e-15:
        t1, t2 = (-xb[2] - oz) / dz, (xb[2] - oz) / dz
        lo, hi = min(t1, t2), max(t1, t2)
    elif abs(oz) > xb[2]:
        return np.inf, np.inf
    # elliptic cylinder (x / a)^2 + (y / b)^2 <= 1
    qa = (dx / xb[0]) ** 2 + (dy / xb[1]) ** 2
    qb = 2.0 * (ox * dx / xb[0] ** 2 + oy * dy / xb[1] ** 2)
    qc = (ox / xb[0]) ** 2 + (oy / xb[1]) ** 2 - 1.0
    if qa > 1e-15:
        disc = qb * qb - 4.0 * qa * qc
        if disc < 0.0:
            return np.inf, np.inf
        root = np.sqrt(disc)
        lo = max(lo, (-qb - root) / (2.0 * qa))
        hi = min(hi, (-qb + root) / (2.0 * qa))
    elif qc > 0.0:
        return np.inf, np.inf
    if lo > hi or hi < 0.0:
        return np.inf, np.inf
    return lo, hi


@njit(cache=True)
def _pair_frame(ca, ra, cb, rb):
    """A's frame in B's: (R, o) with x_B = o + R x_A, and the downward vertical in B's frame."""
    relative = rb.T @ ra
    offset = np.empty(3)
    down = np.empty(3)
    for i in range(3):
        offset[i] = rb[0, i] * (ca[0] - cb[0]) + rb[1, i] * (ca[1] - cb[1]) + rb[2, i] * (ca[2] - cb[2])
        down[i] = -rb[2, i]
    return relative, offset, down


@njit(cache=True)
def _gap(x, y, z, relative, offset, down, xb):
    """delta_z of a scan point of A (A's frame, [m]) over B [m]: -inf inside B, inf when B
    is not below."""
    ox = offset[0] + relative[0, 0] * x + relative[0, 1] * y + relative[0, 2] * z
    oy = offset[1] + relative[1, 0] * x + relative[1, 1] * y + relative[1, 2] * z
    oz = offset[2] + relative[2, 0] * x + relative[2, 1] * y + relative[2, 2] * z
    t_in, t_out = _ray_interval(ox, oy, oz, down[0], down[1], down[2], xb)
    if t_in <= 0.0 <= t_out:
        return -np.inf
    return t_in


@njit(cache=True)
def _inside_basal(kind, u, v, a, b):
    return kind == 1 or (u / a) ** 2 + (v / b) ** 2 <= 1.0


@njit(cache=True)
def _window(k, kind, u, v, gap, xa, face, relative, offset, down, xb, fine, span_u, span_v,
            seen_u, seen_v):
    """Move point k to the least gap among offsets (-span..span) x fine on (u, v), in
    place, skipping the offsets of a window already searched around the point at
    offsets (seen_u, seen_v) from here (none of them is lower than the point); the
    offsets (i, j) of the move, (0, 0) if it did not move."""
    a, b, c = xa[0], xa[1], xa[2]
    step_u = fine if kind[k] == 0 else fine / np.sqrt(a * b)
    best_u, best_v, best = u[k], v[k], gap[k]
    best_i, best_j = 0, 0
    for si in range(-span_u, span_u + 1):
        cu = u[k] + si * step_u
        old_column = abs(si - seen_u) <= span_u
        # the edge point's basal position depends on the angle only
        x, y, _ = _local_point(kind[k], cu, 0.0, a, b, c, face)
        for sj in range(-span_v, span_v + 1):
            if old_column and abs(sj - seen_v) <= span_v:
                continue
            cv = v[k] + sj * fine
            if kind[k] == 1 and abs(cv) > c:
                continue
            if not _inside_basal(kind[k], cu, cv, a, b):
                continue
            if kind[k] == 0:
                g = _gap(cu, cv, face * c, relative, offset, down, xb)
            else:
                g = _gap(x, y, cv, relative, offset, down, xb)
            if g < best:
                best_u, best_v, best = cu, cv, g
                best_i, best_j = si, sj
    u[k], v[k], gap[k] = best_u, best_v, best
    return best_i, best_j


@njit(cache=True)
def _refine_contact(kind, u, v, gap, xa, face, relative, offset, down, xb, d_cont, delta):
    """The /10 sequence on the points within delta_n of the lowest (in place): x and y
    sweeps on each, then the whole (u, v) window on the lowest."""
    # int64, not literal constants: each distinct literal would compile _window anew
    steps, none, zero = np.int64(_STEPS), np.int64(_NONE), np.int64(0)
    while delta >= d_cont:
        fine = delta / _STEPS
        order = np.argsort(gap)
        lowest = gap[order[0]]
        for k in order[:_REFINED]:
            if not gap[k] - lowest <= delta:
                break
            _window(k, kind, u, v, gap, xa, face, relative, offset, down, xb, fine, steps, zero,
                    none, zero)
            _window(k, kind, u, v, gap, xa, face, relative, offset, down, xb, fine, zero, steps,
                    zero, none)
            if gap[k] < 0.0:
                return
        k = np.argmin(gap)
        seen_u, seen_v = none, none
        for _ in range(_SWEEPS):
            move_u, move_v = _window(k, kind, u, v, gap, xa, face, relative, offset, down, xb,
                                     fine, steps, steps, seen_u, seen_v)
            if gap[k] < 0.0:
                return
            if move_u == 0 and move_v == 0:
                break
            seen_u, seen_v = -move_u, -move_v
        delta = fine


@njit(cache=True)
def scan_drop(ca, ra, xa, cb, rb, xb, max_drop, n_sp, d_cont, exact):
    """Vertical gap of the settling particle A above B by the contact scan.

    ``exact`` is the exact vertical gap of A above B [m]
    (:func:`._contact_kernels.drop_to_contact`; INFINITE_DROP beyond reach), which bounds
    the scan's from below.

    Returns
    -------
    tuple
        (gap [m], point of B under the lowest scan point (3 floats) [m]), as
        :func:`._contact_kernels.drop_to_contact`: the gap is -1 if A and B overlap
        where A is (a scan point of A inside B, or the overlap scan), INFINITE_DROP if B
        is not below A within ``max_drop`` [m].
    """
    # The exact vertical gap bounds every scan point's from below: B out of reach for it
    # is out of reach for the scan, and disjoint shapes have no point inside each other.
    if exact == INFINITE_DROP:
        return INFINITE_DROP, cb[0], cb[1], cb[2]
    face = -1.0 if ra[2, 2] >= 0.0 else 1.0
    kind, u, v, x, y, z, delta = _grid(xa[0], xa[1], xa[2], n_sp, face, np.bool_(True))
    relative, offset, down = _pair_frame(ca, ra, cb, rb)
    gap = np.empty(kind.size)
    for k in range(kind.size):
        gap[k] = _gap(x[k], y[k], z[k], relative, offset, down, xb)
        if gap[k] < 0.0:
            return -1.0, cb[0], cb[1], cb[2]
    if exact < 0.0 and scan_overlap(ca, ra, xa, cb, rb, xb, n_sp, d_cont):
        return -1.0, cb[0], cb[1], cb[2]
    _refine_contact(kind, u, v, gap, xa, face, relative, offset, down, xb, d_cont, delta)
    low = np.argmin(gap)
    if gap[low] < 0.0:
        return -1.0, cb[0], cb[1], cb[2]
    if gap[low] > max_drop:
        return INFINITE_DROP, cb[0], cb[1], cb[2]
    lx, ly, lz = _local_point(kind[low], u[low], v[low], xa[0], xa[1], xa[2], face)
    px, py, pz = _to_world(ca, ra, lx, ly, lz)
    return gap[low], px, py, pz - gap[low]


@njit(cache=True)
def _outside(lx, ly, lz, xa):
    """How far a point (A's frame) is outside A: <= 0 inside (a scaled level set) [m]."""
    radial = (np.sqrt((lx / xa[0]) ** 2 + (ly / xa[1]) ** 2) - 1.0) * min(xa[0], xa[1])
    return max(radial, abs(lz) - xa[2])


@njit(cache=True)
def _apart_along_normals(ca, ra, xa, cb, rb, xb):
    """True if the normal of A or of B separates the two particles."""
    for own_c, own_r, own_x, other_c, other_r, other_x in ((ca, ra, xa, cb, rb, xb), (cb, rb, xb, ca, ra, xa)):
        nx, ny, nz = own_r[0, 2], own_r[1, 2], own_r[2, 2]
        centre = nx * (other_c[0] - own_c[0]) + ny * (other_c[1] - own_c[1]) + nz * (other_c[2] - own_c[2])
        px, py, pz = support(other_c, other_r, other_x, nx, ny, nz)
        reach = nx * (px - other_c[0]) + ny * (py - other_c[1]) + nz * (pz - other_c[2])
        if abs(centre) > own_x[2] + reach:
            return True
    return False


@njit(cache=True)
def scan_overlap(ca, ra, xa, cb, rb, xb, n_sp, d_cont):
    """The inverse scan: True if a scan point of B's basal faces lies inside A.

    Particles separated along the normal of either one have no point of one inside the
    other: the scan is skipped then, which changes no answer and saves most of its cost.
    """
    if _apart_along_normals(ca, ra, xa, cb, rb, xb):
        return False
    for face in (-1.0, 1.0):
        kind, u, v, _, _, _, delta = _grid(xb[0], xb[1], xb[2], n_sp, face, np.bool_(False))
        level = np.empty(kind.size)
        keep = np.zeros(kind.size, np.bool_)
        for k in range(kind.size):
            px, py, pz = _to_world(cb, rb, u[k], v[k], face * xb[2])
            lx, ly, lz = _to_local(ca, ra, px, py, pz)
            level[k] = _outside(lx, ly, lz, xa)
            if level[k] <= 0.0:
                return True
            keep[k] = level[k] <= delta
        while delta > d_cont and keep.any():
            fine = delta / _STEPS
            for k in range(kind.size):
                if not keep[k]:
                    continue
                for axis in range(2):
                    best_u, best_v, best = u[k], v[k], level[k]
                    for s in range(-_STEPS, _STEPS + 1):
                        cu = u[k] + (s * fine if axis == 0 else 0.0)
                        cv = v[k] + (s * fine if axis == 1 else 0.0)
                        if (cu / xb[0]) ** 2 + (cv / xb[1]) ** 2 > 1.0:
                            continue
                        px, py, pz = _to_world(cb, rb, cu, cv, face * xb[2])
                        lx, ly, lz = _to_local(ca, ra, px, py, pz)
                        g = _outside(lx, ly, lz, xa)
                        if g < best:
                            best_u, best_v, best = cu, cv, g
                    u[k], v[k], level[k] = best_u, best_v, best
                if level[k] <= 0.0:
                    return True
                keep[k] = level[k] <= fine
            delta = fine
    return False
