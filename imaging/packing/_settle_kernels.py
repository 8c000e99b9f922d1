"""Settling of one particle on a fixed bed (Ferrage et al. 2015, Sec. II.A), numba kernels.

Bed arrays are passed explicitly (module constants only, so the on-disk cache stays valid):
centres, rotations, semi-axes and bounding half-extents of the particles already placed,
and the spatial hash of :mod:`._grid_kernels`. Scratch buffers hold candidate
indices (``found``), their periodic shifts, their drops and witness points, and the
contacts found by a fall; they are allocated once per deposition.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from imaging.packing._contact_kernels import (
    INFINITE_DROP,
    drop_to_contact,
    half_extents,
    support,
)
from imaging.packing._grid_kernels import gather_levels
from imaging.packing._scan_kernels import scan_drop

MAX_CONTACTS = 8
SLIDE = 0
SWIVEL = 1
ROTATE = 2


@njit(cache=True)
def fall(center, rot, axes, centers, rots, all_axes, exts, fine, coarse, link, geometry,
         found, shifts, drops, witness, contacts):
    """Vertical fall of a particle until its lowest gap to the bed or floor is d_cont/2.

    ``fine``, ``coarse`` and ``link`` are the two grids of the bed and ``geometry`` their
    layout (see :func:`._grid_kernels.gather_levels`), then n_sp: 0 for exact contacts
    (:func:`._contact_kernels.drop_to_contact`), else the contact scan with n_sp points
    (:func:`._scan_kernels.scan_drop`, bounded by the exact drop; the floor is a
    plane, met exactly either way).
    Contacts (points [m] within d_cont after the fall) are written to ``contacts``.

    Returns
    -------
    tuple
        (drop [m], number of contacts); the drop is -1 if the particle overlaps the bed
        where it starts.
    """
    d_cont = geometry[1]
    step = geometry[3]
    n_sp = int(geometry[8])
    ext = np.empty(3)
    half_extents(rot, axes, ext)
    floor_drop = center[2] - ext[2]
    lo = center - ext
    hi = center + ext
    reach = 0.0
    count = 0
    best = floor_drop
    while True:
        reach = min(reach + step, floor_drop + d_cont)
        lo[2] = center[2] - ext[2] - reach
        count = gather_levels(lo, hi, centers, exts, fine, coarse, link, geometry, found, shifts)
        bottom = center[2] - ext[2]
        # Candidates by increasing lower bound of their drop, refined lazily: the
        # bounding-box gap, then (scan mode) the exact drop, then the drop itself; stop
        # where the least bound passes the best drop so far (+ d_cont, the contacts), so
        # that a candidate further below is never computed and the result is the one of
        # computing them all.
        bound = np.empty(count)
        stage = np.zeros(count, np.int64)
        for k in range(count):
            bound[k] = bottom - centers[found[k], 2] - exts[found[k], 2]
            drops[k] = INFINITE_DROP
        while True:
            k = -1
            for m in range(count):
                if stage[m] < 2 and (k < 0 or bound[m] < bound[k]):
                    k = m
            limit = min(best, reach) + d_cont
            if k < 0 or bound[k] > limit:
                break
            j = found[k]
            cb = centers[j].copy()
            cb[0] += shifts[k, 0]
            cb[1] += shifts[k, 1]
            if stage[k] == 0:
                d, qx, qy, qz = drop_to_contact(center, rot, axes, cb, rots[j], all_axes[j], limit,
                                                0.05 * d_cont)
                if n_sp > 0 and d != INFINITE_DROP:
                    # the exact drop bounds the scan's from below
                    bound[k], stage[k] = d, 1
                    continue
            else:
                d, qx, qy, qz = scan_drop(center, rot, axes, cb, rots[j], all_axes[j], limit, n_sp,
                                          d_cont, bound[k])
            stage[k] = 2
            if d < 0.0:
                return -1.0, 0
            drops[k] = d
            witness[k, 0], witness[k, 1], witness[k, 2] = qx, qy, qz
            best = min(best, d)
        if best <= reach:
            break
    drop = max(best - 0.5 * d_cont, 0.0)
    return drop, _collect_contacts(center, rot, axes, drop, floor_drop, drops, witness, count,
                                   d_cont, contacts)


@njit(cache=True)
def _collect_contacts(center, rot, axes, drop, floor_drop, drops, witness, count, d_cont,
                      contacts):
    n = 0
    if floor_drop - drop < d_cont:
        p = support(center, rot, axes, 0.0, 0.0, -1.0)
        contacts[0, 0], contacts[0, 1], contacts[0, 2] = p[0], p[1], 0.0
        n = 1
    for k in range(count):
        if drops[k] - drop < d_cont and n < contacts.shape[0]:
            for m in range(3):
                contacts[n, m] = witness[k, m]
            n += 1
    return n


@njit(cache=True)
def rotation_about(axis, angle, out):
    """Rotation matrix by ``angle`` [rad] about the unit vector ``axis`` (Rodrigues)."""
    c = np.cos(angle)
    s = np.sin(angle)
    x, y, z = axis
    t = 1.0 - c
    out[0, 0] = c + t * x * x
    out[0, 1] = t * x * y - s * z
    out[0, 2] = t * x * z + s * y
    out[1, 0] = t * x * y + s * z
    out[1, 1] = c + t * y * y
    out[1, 2] = t * y * z - s * x
    out[2, 0] = t * x * z - s * y
    out[2, 1] = t * y * z + s * x
    out[2, 2] = c + t * z * z


@njit(cache=True)
def pivot_point(center, contacts, n_contacts, choice, separation, out, line):
    """Point about which a settled particle moves (Sec. II.A).

    One contact: the contact itself. Two or more: the foot of the altitude from the
    barycentre to the line through two contacts (the pair is picked by ``choice`` in
    [0, 1) when there are more than two); two contacts closer than ``separation`` [m]
    count as one. ``line`` receives the unit direction of that contact line, or zeros
    when the pivot is a single contact.
    """
    i = min(int(choice * n_contacts), n_contacts - 1)
    for k in range(3):
        out[k] = contacts[i, k]
    line[:] = 0.0
    if n_contacts < 2:
        return
    j = (i + 1) % n_contacts
    seg = contacts[j] - contacts[i]
    length2 = np.dot(seg, seg)
    if length2 <= separation * separation:
        return
    t = np.dot(center - contacts[i], seg) / length2
    norm = np.sqrt(length2)
    for k in range(3):
        out[k] = contacts[i, k] + t * seg[k]
        line[k] = seg[k] / norm


@njit(cache=True)
def _copy_pose(center, rot, to_center, to_rot):
    """Copy a barycentre and a rotation element by element (the kernels assign no arrays
    to slices: numba's shape check compiles its error message, 10-20 s on a fresh cache)."""
    for k in range(3):
        to_center[k] = center[k]
        for m in range(3):
            to_rot[k, m] = rot[k, m]


@njit(cache=True)
def _horizontal_unit(vx, vy, fallback_angle):
    norm = np.sqrt(vx * vx + vy * vy)
    if norm > 0.0:
        return vx / norm, vy / norm
    return np.cos(fallback_angle), np.sin(fallback_angle)


@njit(cache=True)
def trial_move(kind, amplitude, u_dir, steepest_slide, steepest_swivel, contact_line, center,
               rot, pivot, line, new_center, new_rot, work):
    """Apply one random move; the barycentre is then put back at its former altitude.

    Slide: horizontal translation by ``amplitude`` [m]. Swivel: rotation by
    ``amplitude`` [rad] about an axis through the pivot. With ``steepest_slide`` the
    slide goes away from the pivot, with ``steepest_swivel`` the swivel axis is the
    horizontal one along which the barycentre descends fastest (steepest descent);
    otherwise the direction or axis is drawn from ``u_dir``. With ``contact_line`` and a
    pivot on the line through two contacts (``line`` non-zero), the swivel turns about
    that line instead, in the sense that lowers the barycentre: the one rotation that
    keeps both contacts. Rotate: in-plane rotation by +-``amplitude`` [rad] about the particle
    normal (sign from ``u_dir``).
    """
    _copy_pose(center, rot, new_center, new_rot)
    steepest = steepest_slide if kind == SLIDE else steepest_swivel
    rx = center[0] - pivot[0] if steepest else 0.0
    ry = center[1] - pivot[1] if steepest else 0.0
    if kind == SLIDE:
        ux, uy = _horizontal_unit(rx, ry, 2.0 * np.pi * u_dir)
        new_center[0] += amplitude * ux
        new_center[1] += amplitude * uy
        return
    axis = np.empty(3)
    angle = amplitude
    if kind == SWIVEL:
        ux, uy = _horizontal_unit(-ry, rx, 2.0 * np.pi * u_dir)
        axis[0], axis[1], axis[2] = ux, uy, 0.0
        if contact_line and line[0] * line[0] + line[1] * line[1] > 0.0:
            # the barycentre moves along line x (center - pivot); its z rate must be < 0
            rate = line[0] * (center[1] - pivot[1]) - line[1] * (center[0] - pivot[0])
            if rate != 0.0:
                sign = 1.0 if rate < 0.0 else -1.0
                for k in range(3):
                    axis[k] = sign * line[k]
    else:
        for k in range(3):
            axis[k] = rot[k, 2]
        angle = amplitude if u_dir < 0.5 else -amplitude
    rotation_about(axis, angle, work)
    turned = work @ rot
    for k in range(3):
        for m in range(3):
            new_rot[k, m] = turned[k, m]
    if kind == SWIVEL:
        offset = work @ (center - pivot)
        new_center[0] = pivot[0] + offset[0]
        new_center[1] = pivot[1] + offset[1]


@njit(cache=True)
def settle(center, rot, axes, uniforms, amplitudes, reduction, n_cycles, n_kinds, steepest,
           centers, rots, all_axes, exts, fine, coarse, link, geometry,
           found, shifts, drops, witness):
    """Free fall, then ``n_cycles`` cycles of random moves accepted only if the
    barycentre descends without overlap; ``center`` and ``rot`` are updated in place.

    ``uniforms`` (n_cycles * attempts, 4) in [0, 1) choose the kind of move, its
    amplitude, its direction and the contact pair; ``amplitudes`` = (slide [m],
    swivel [rad], rotate [rad]) are multiplied by ``reduction`` after each cycle;
    ``steepest`` = (slide, swivel, contact line) flags of the direction rules of
    :func:`trial_move`.
    Returns the number of accepted moves.
    """
    contacts = np.empty((MAX_CONTACTS, 3))
    trial_contacts = np.empty((MAX_CONTACTS, 3))
    pivot = np.empty(3)
    line = np.empty(3)
    new_center = np.empty(3)
    new_rot = np.empty((3, 3))
    work = np.empty((3, 3))
    drop, n_contacts = fall(center, rot, axes, centers, rots, all_axes, exts, fine, coarse,
                            link, geometry, found, shifts, drops, witness, contacts)
    center[2] -= drop
    amp = amplitudes.copy()
    per_cycle = uniforms.shape[0] // n_cycles
    eps = 1e-6 * geometry[1]
    accepted = 0
    for attempt in range(uniforms.shape[0]):
        if attempt > 0 and attempt % per_cycle == 0:
            amp *= reduction
        kind = min(int(uniforms[attempt, 0] * n_kinds), n_kinds - 1)
        pivot_point(center, contacts, n_contacts, uniforms[attempt, 3], geometry[1], pivot,
                    line)
        trial_move(kind, uniforms[attempt, 1] * amp[kind], uniforms[attempt, 2], steepest[0],
                   steepest[1], steepest[2], center, rot, pivot, line, new_center, new_rot,
                   work)
        new_center[0] %= geometry[0]
        new_center[1] %= geometry[0]
        drop, n_trial = fall(new_center, new_rot, axes, centers, rots, all_axes, exts, fine,
                             coarse, link, geometry, found, shifts, drops, witness,
                             trial_contacts)
        if drop <= eps:
            continue
        new_center[2] -= drop
        _copy_pose(new_center, new_rot, center, rot)
        for q in range(n_trial):
            for k in range(3):
                contacts[q, k] = trial_contacts[q, k]
        n_contacts = n_trial
        accepted += 1
    return accepted
