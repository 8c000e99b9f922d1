"""numba kernels of the macro model: packing relaxation, Hertz-Mindlin contacts, the container.

Arrays in, arrays out; serial loops that scatter into per-pellet arrays (deterministic).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shared.dem._kernels import _turned_shear, apply_contact, contact_velocity


@njit(cache=True)
def _pair_overlap(positions, radii, i, j):  # type: ignore[no-untyped-def]
    """Branch vector i -> j, centre distance and overlap r_i + r_j - distance [m]."""
    dx = positions[j, 0] - positions[i, 0]
    dy = positions[j, 1] - positions[i, 1]
    dz = positions[j, 2] - positions[i, 2]
    dist = np.sqrt(dx * dx + dy * dy + dz * dz)
    return dx, dy, dz, dist, radii[i] + radii[j] - dist


@njit(cache=True)
def relax_overlaps(positions, radii, pairs, cylinder_radius, z_low, z_high, fraction):
    """Move pellets apart by ``fraction`` of their overlaps (pairs, curved wall, plates).

    Overdamped (position-based) relaxation of a radius-growth packing. Returns the
    largest overlap found [m] before the move.
    """
    n = positions.shape[0]
    move = np.zeros((n, 3))
    largest = 0.0
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        dx, dy, dz, dist, overlap = _pair_overlap(positions, radii, i, j)
        if overlap <= 0.0 or dist == 0.0:
            continue
        largest = max(largest, overlap)
        s = 0.5 * fraction * overlap / dist
        move[i, 0] -= s * dx
        move[i, 1] -= s * dy
        move[i, 2] -= s * dz
        move[j, 0] += s * dx
        move[j, 1] += s * dy
        move[j, 2] += s * dz
    for i in range(n):
        rho = np.sqrt(positions[i, 0] ** 2 + positions[i, 1] ** 2)
        wall = rho + radii[i] - cylinder_radius
        if wall > 0.0 and rho > 0.0:
            largest = max(largest, wall)
            move[i, 0] -= fraction * wall * positions[i, 0] / rho
            move[i, 1] -= fraction * wall * positions[i, 1] / rho
        low = z_low + radii[i] - positions[i, 2]
        if low > 0.0:
            largest = max(largest, low)
            move[i, 2] += fraction * low
        high = positions[i, 2] + radii[i] - z_high
        if high > 0.0:
            largest = max(largest, high)
            move[i, 2] -= fraction * high
    for i in range(n):
        for c in range(3):
            positions[i, c] += move[i, c]
    return largest


@njit(cache=True)
def hertz_yield(e_star, r_star, overlap, plastic, yield_force):  # type: ignore[no-untyped-def]
    """Normal force of a Hertz contact that yields (Eq. 4.4, Thornton's elastic-perfectly
    plastic contact); returns the force [N], the new plastic overlap [m] and the elastic
    contact radius [m].

    Elastic: F = 4/3 E* sqrt(R*) (delta - delta_p)^(3/2). The contact yields when F
    reaches ``yield_force`` F_y; the mean contact pressure F / (pi a^2) at that force,
    p_y = F_y / (pi a_y^2) with a_y^3 = 3 F_y R* / (4 E*), is the limit past which the
    force grows only with the contact area, F = pi p_y R* delta; delta_p then moves so
    that unloading is elastic from there.
    """
    elastic = max(overlap - plastic, 0.0)
    fn = 4.0 / 3.0 * e_star * np.sqrt(r_star) * elastic**1.5
    if fn > yield_force:
        a_y = (3.0 * yield_force * r_star / (4.0 * e_star)) ** (1.0 / 3.0)
        limit = yield_force / (a_y * a_y) * r_star * overlap
        if fn > limit:
            fn = limit
            elastic = (fn / (4.0 / 3.0 * e_star * np.sqrt(r_star))) ** (2.0 / 3.0)
            plastic = overlap - elastic
    return fn, plastic, np.sqrt(r_star * elastic)


@njit(cache=True)
def hertz_mindlin_pairs(positions, velocities, spins, radii, young, poisson, friction, pairs,
                        shear, forces, torques, stiffness, yield_force, plastic):
    """Hertz-Mindlin forces between pellets (Eqs. 4.1-4.9); updates ``shear`` in place.

    Normal: F_n = 4/3 E* sqrt(R*) delta^(3/2), E* = E_a E_b / ((E_a + E_b)(1 - nu^2))
    from each pellet's modulus (Eq. 4.2). Shear (Eqs. 4.5-4.9): the stored force, turned
    into the current tangent plane, changes by -k_t times the tangential part of the
    contact point's relative displacement in the substep (velocities and spins are per
    substep: time unit 1), k_t = 4 G a / (2 - nu), G the mean of the two shear moduli
    E / (2 (1 + nu)), a = sqrt(R* delta); Coulomb's limit |F_s| <= tan(phi) F_n with
    ``friction`` = tan(phi). ``shear[k]`` is the force on ``pairs[k, 0]`` [N]. The normal
    force yields at the smaller ``yield_force`` of the two pellets (:func:`hertz_yield`;
    ``plastic`` [m] per pair, updated in place, reset when the pellets part). Adds the
    forces, the torques and the normal tangent stiffness 2 E* a per pellet; returns the
    normal force of each pair [N] (0 if apart).
    """
    normal = np.zeros(pairs.shape[0])
    factor = 1.0 - poisson * poisson
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        dx, dy, dz, dist, overlap = _pair_overlap(positions, radii, i, j)
        if overlap <= 0.0 or dist == 0.0:
            shear[k, 0] = shear[k, 1] = shear[k, 2] = 0.0
            plastic[k] = 0.0
            continue
        nx, ny, nz = dx / dist, dy / dist, dz / dist
        e_star = young[i] * young[j] / (factor * (young[i] + young[j]))
        fn, plastic[k], a = hertz_yield(e_star, radii[i] * radii[j] / (radii[i] + radii[j]), overlap,
                                        plastic[k], min(yield_force[i], yield_force[j]))
        normal[k] = fn
        arm_i, arm_j = radii[i] - 0.5 * overlap, radii[j] - 0.5 * overlap
        vx, vy, vz = contact_velocity(velocities, spins, i, j, nx, ny, nz, arm_i, arm_j)
        vn = vx * nx + vy * ny + vz * nz
        sx, sy, sz = _turned_shear(shear[k, 0], shear[k, 1], shear[k, 2], nx, ny, nz)
        shear_modulus = 0.25 * (young[i] + young[j]) / (1.0 + poisson)
        k_t = 4.0 * shear_modulus * a / (2.0 - poisson)
        sx -= k_t * (vx - vn * nx)
        sy -= k_t * (vy - vn * ny)
        sz -= k_t * (vz - vn * nz)
        magnitude = np.sqrt(sx * sx + sy * sy + sz * sz)
        if magnitude > friction * fn:
            scale = friction * fn / magnitude
            sx, sy, sz = sx * scale, sy * scale, sz * scale
        shear[k, 0], shear[k, 1], shear[k, 2] = sx, sy, sz
        apply_contact(forces, torques, i, j, fn, nx, ny, nz, sx, sy, sz, arm_i, arm_j)
        stiffness[i] += 2.0 * e_star * a
        stiffness[j] += 2.0 * e_star * a
    return normal


@njit(cache=True)
def container_contacts(positions, radii, young, poisson, cylinder_radius, z_low, z_high,
                       forces, stiffness, yield_force, plastic):
    """Frictionless Hertz contacts with a rigid cylinder and two rigid end plates.

    A pellet of radius r at distance rho from the axis overlaps the curved wall by
    rho + r - R and a plate by r - (distance to the plate); force 4/3 E* sqrt(r) delta^(3/2)
    with E* = E / (1 - nu^2) (rigid wall, R* = r; the wall's curvature is neglected),
    yielding at the pellet's ``yield_force`` (:func:`hertz_yield`; ``plastic`` (n, 3) [m]
    per pellet for the wall, lower and upper plate, updated in place). Returns per pellet
    the force on the curved wall (radial, outwards), on the lower and on the upper plate [N].
    """
    n = positions.shape[0]
    loads = np.zeros((n, 3))
    for i in range(n):
        e_star = young[i] / (1.0 - poisson * poisson)
        rho = np.sqrt(positions[i, 0] ** 2 + positions[i, 1] ** 2)
        if rho == 0.0:
            rho = 1e-300
        # outward normal of each surface at the pellet and the pellet's overlap with it
        normals = ((positions[i, 0] / rho, positions[i, 1] / rho, 0.0), (0.0, 0.0, -1.0), (0.0, 0.0, 1.0))
        overlaps = (rho + radii[i] - cylinder_radius, z_low + radii[i] - positions[i, 2],
                    positions[i, 2] + radii[i] - z_high)
        for w in range(3):
            if overlaps[w] <= 0.0:
                plastic[i, w] = 0.0
                continue
            fn, plastic[i, w], a = hertz_yield(e_star, radii[i], overlaps[w], plastic[i, w], yield_force[i])
            loads[i, w] = fn
            forces[i, 0] -= fn * normals[w][0]
            forces[i, 1] -= fn * normals[w][1]
            forces[i, 2] -= fn * normals[w][2]
            stiffness[i] += 2.0 * e_star * a
    return loads[:, 0].copy(), loads[:, 1].copy(), loads[:, 2].copy()
