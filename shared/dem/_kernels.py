"""numba kernels of the DEM core: cell lists, Hertz-Mindlin contacts (bonded, or yielding
with friction), bonds, walls (a box, or a cylinder with two plates), leapfrog.

Arrays in, arrays out; no Python objects and no globals (the on-disk cache freezes them).
Every sum over contacts or bonds into shared per-point arrays runs serially, in list
order: the summation order, hence the results, are the same from run to run and
whatever the thread count. Only work without such sums runs in parallel (each contact's
Hertz-Mindlin force or each bond's tension into its own row, per-point updates). A
parallel gather per point in the same order would be bit-identical too, but its
scattered reads cost more on one thread than the second thread wins back.
"""

from __future__ import annotations

import types

import numpy as np
from numba import njit, prange


@njit(cache=True)
def bounding_box(positions):
    """Lower and upper corners of (n >= 1, 3) points (numpy's axis-0 reductions of an
    (n, 3) array are strided and several times slower)."""
    lower = positions[0].copy()
    upper = positions[0].copy()
    for i in range(1, positions.shape[0]):
        for d in range(3):
            lower[d] = min(lower[d], positions[i, d])
            upper[d] = max(upper[d], positions[i, d])
    return lower, upper


@njit(cache=True)
def cell_indices(positions, lower, spacing, dims):
    """Flat index (x-major, z fastest) of the grid cell of each point."""
    cells = np.empty(positions.shape[0], dtype=np.int64)
    for i in range(positions.shape[0]):
        flat = 0
        for d in range(3):
            c = min(max(int((positions[i, d] - lower[d]) / spacing[d]), 0), dims[d] - 1)
            flat = flat * dims[d] + c
        cells[i] = flat
    return cells


@njit(cache=True)
def bin_points(cell_of_point, n_cells):
    """Counting sort of points by cell: CSR ``cell_start`` (n_cells + 1) and ``cell_points``."""
    cell_start = np.zeros(n_cells + 1, dtype=np.int64)
    for i in range(cell_of_point.shape[0]):
        cell_start[cell_of_point[i] + 1] += 1
    for c in range(n_cells):
        cell_start[c + 1] += cell_start[c]
    fill = cell_start[:-1].copy()
    cell_points = np.empty(cell_of_point.shape[0], dtype=np.int64)
    for i in range(cell_of_point.shape[0]):
        c = cell_of_point[i]
        cell_points[fill[c]] = i
        fill[c] += 1
    return cell_start, cell_points


@njit(cache=True)
def find_pairs(positions, radii, cutoff_factor, skin, dims, cell_start, cell_points,
               capacity):
    """Pairs i < j with |x_i - x_j| < cutoff_factor (r_i + r_j) + skin, sorted by (i, j).

    Each unordered pair is tested once: a point against the points after it in its own
    cell and in the 13 cells of the forward half stencil, walked in cell order so that
    the positions are read nearly sequentially. The pairs found are then counting-sorted
    by their first point, and each row's few second points by insertion.

    Returns ``(pairs, count)``; ``count > capacity`` means the buffer was too small and
    the caller must retry with at least ``count`` rows (a buffer grown inside the search
    loop would double its cost).
    """
    n = positions.shape[0]
    sorted_positions = positions[cell_points]
    sorted_radii = radii[cell_points]
    first = np.empty(capacity, dtype=np.int64)
    second = np.empty(capacity, dtype=np.int64)
    count = 0
    nx, ny, nz = dims[0], dims[1], dims[2]
    for c in range(nx * ny * nz):
        cz = c % nz
        cy = (c // nz) % ny
        cx = c // (nz * ny)
        for s in range(cell_start[c], cell_start[c + 1]):
            xs, ys, zs, rs = (sorted_positions[s, 0], sorted_positions[s, 1],
                              sorted_positions[s, 2], sorted_radii[s])
            # runs of z-adjacent cells, contiguous in cell order: the rest of this cell
            # and the next one up, then the three columns at x + 1 and the one at y + 1
            for run in range(5):
                if run == 0:
                    lo = s + 1
                    hi = cell_start[c + 1 + (1 if cz + 1 < nz else 0)]
                else:
                    ox = 1 if run < 4 else 0
                    oy = run - 2 if run < 4 else 1
                    if cx + ox >= nx or cy + oy < 0 or cy + oy >= ny:
                        continue
                    column = ((cx + ox) * ny + cy + oy) * nz
                    lo = cell_start[column + max(cz - 1, 0)]
                    hi = cell_start[column + min(cz + 1, nz - 1) + 1]
                for t in range(lo, hi):
                    cut = cutoff_factor * (rs + sorted_radii[t]) + skin
                    ddx = sorted_positions[t, 0] - xs
                    ddy = sorted_positions[t, 1] - ys
                    ddz = sorted_positions[t, 2] - zs
                    if ddx * ddx + ddy * ddy + ddz * ddz < cut * cut:
                        if count < capacity:
                            i, j = cell_points[s], cell_points[t]
                            first[count] = min(i, j)
                            second[count] = max(i, j)
                        count += 1
    if count > capacity:
        return np.empty((0, 2), dtype=np.int64), count
    row_start = np.zeros(n + 1, dtype=np.int64)
    for k in range(count):
        row_start[first[k] + 1] += 1
    for i in range(n):
        row_start[i + 1] += row_start[i]
    fill = row_start[:-1].copy()
    pairs = np.empty((count, 2), dtype=np.int64)
    for k in range(count):
        i = first[k]
        # insertion keeps each row (a few neighbours) sorted as it fills
        slot = fill[i]
        while slot > row_start[i] and pairs[slot - 1, 1] > second[k]:
            pairs[slot, 1] = pairs[slot - 1, 1]
            slot -= 1
        pairs[slot, 1] = second[k]
        fill[i] += 1
    for i in range(n):
        for slot in range(row_start[i], row_start[i + 1]):
            pairs[slot, 0] = i
    return pairs, count


@njit(cache=True)
def _strictly_sorted(pairs):
    """Whether the (n, 2) rows increase strictly in lexicographic order."""
    for p in range(1, pairs.shape[0]):
        if pairs[p, 0] < pairs[p - 1, 0] or (
            pairs[p, 0] == pairs[p - 1, 0] and pairs[p, 1] <= pairs[p - 1, 1]
        ):
            return False
    return True


@njit(cache=True)
def match_sorted_pairs(pairs, keyed_pairs):
    """Row of each pair in ``keyed_pairs``, -1 where absent, by one merge of the two lists.

    Both lists must be sorted lexicographically; a ValueError says which one is not.
    """
    if not _strictly_sorted(pairs):
        raise ValueError("pairs are not sorted lexicographically without repeats")
    if not _strictly_sorted(keyed_pairs):
        raise ValueError("keyed pairs are not sorted lexicographically without repeats")
    found = np.full(pairs.shape[0], -1, dtype=np.int64)
    k = 0
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        while k < keyed_pairs.shape[0] and (
            keyed_pairs[k, 0] < i or (keyed_pairs[k, 0] == i and keyed_pairs[k, 1] < j)
        ):
            k += 1
        if k < keyed_pairs.shape[0] and keyed_pairs[k, 0] == i and keyed_pairs[k, 1] == j:
            found[p] = k
    return found


@njit(cache=True)
def gather_rows(values, rows):
    """``values[rows]`` for the (k, c) array, zero rows where ``rows`` is -1."""
    result = np.zeros((rows.shape[0], values.shape[1]))
    for p in range(rows.shape[0]):
        if rows[p] >= 0:
            for c in range(values.shape[1]):
                result[p, c] = values[rows[p], c]
    return result


@njit(cache=True, parallel=True)
def hertz_mindlin(positions, velocities, spins, radii, reference_radii, pairs,
                  reference_overlaps, shear_forces, effective_modulus, shear_coefficient,
                  time_step, forces, torques):
    """Add Hertz-Mindlin contact forces and torques; update ``shear_forces`` in place.

    ``shear_forces[k]`` is the shear force on ``pairs[k, 0]`` [N]; stiffness follows
    the current radii. The normal force acts on the overlap beyond the pair's
    stress-free overlap, ``reference_overlaps[k]`` at the reference radii, scaled with
    r_i + r_j; the shear stiffness on the whole overlap.
    Returns the normal force magnitude per contact [N] (0 if apart).
    The contacts are evaluated in parallel, each into its own row, and scattered onto
    the points serially in contact order: the sums, hence the results, do not depend
    on the thread count. Scalar arithmetic only: small temporary arrays would be
    heap-allocated per contact.
    """
    n_pairs = pairs.shape[0]
    normal_forces = np.zeros(n_pairs)
    touching = np.zeros(n_pairs, dtype=np.bool_)
    # per contact: force on i, n x (shear force) and the two branch lengths
    pushes = np.empty((n_pairs, 3))
    turns = np.empty((n_pairs, 3))
    arms = np.empty((n_pairs, 2))
    for k in prange(n_pairs):
        i, j = pairs[k, 0], pairs[k, 1]
        dx, dy, dz, dist = _separation(positions, i, j)
        overlap = radii[i] + radii[j] - dist
        if overlap <= 0.0 or dist == 0.0:
            shear_forces[k, 0] = shear_forces[k, 1] = shear_forces[k, 2] = 0.0
            continue
        touching[k] = True
        loaded = -_stretch(overlap, reference_overlaps[k], radii[i], radii[j],
                           reference_radii[i], reference_radii[j])
        nx, ny, nz = dx / dist, dy / dist, dz / dist
        # shear stiffness follows the contact's area (the whole overlap), the normal
        # force only the overlap beyond the stress-free one
        r_star = radii[i] * radii[j] / (radii[i] + radii[j])
        a = np.sqrt(r_star * overlap)
        fn = 0.0
        if loaded > 0.0:
            fn = 4.0 / 3.0 * effective_modulus * np.sqrt(r_star * loaded) * loaded
        normal_forces[k] = fn
        # branch lengths from each centre to the contact point, mid-overlap
        arm_i, arm_j = radii[i] - 0.5 * overlap, radii[j] - 0.5 * overlap
        vx, vy, vz = contact_velocity(velocities, spins, i, j, nx, ny, nz, arm_i, arm_j)
        sx, sy, sz = _turned_shear(shear_forces[k, 0], shear_forces[k, 1],
                                   shear_forces[k, 2], nx, ny, nz)
        vn = vx * nx + vy * ny + vz * nz
        kdt = shear_coefficient * a * time_step
        sx -= kdt * (vx - vn * nx)
        sy -= kdt * (vy - vn * ny)
        sz -= kdt * (vz - vn * nz)
        shear_forces[k, 0], shear_forces[k, 1], shear_forces[k, 2] = sx, sy, sz
        pushes[k, 0], pushes[k, 1], pushes[k, 2] = sx - fn * nx, sy - fn * ny, sz - fn * nz
        turns[k, 0] = ny * sz - nz * sy
        turns[k, 1] = nz * sx - nx * sz
        turns[k, 2] = nx * sy - ny * sx
        arms[k, 0], arms[k, 1] = arm_i, arm_j
    for k in range(n_pairs):
        if touching[k]:
            _scatter_contact(forces, torques, pairs[k, 0], pairs[k, 1], pushes[k, 0],
                             pushes[k, 1], pushes[k, 2], turns[k, 0], turns[k, 1],
                             turns[k, 2], arms[k, 0], arms[k, 1])
    return normal_forces


@njit(cache=True)
def contact_velocity(velocities, spins, i, j, nx, ny, nz, arm_i, arm_j):
    """Velocity of i's contact point relative to j's (Eq. 3.6): v + omega x branch, the
    branches ``arm_i`` n from i and -``arm_j`` n from j."""
    wx = arm_i * spins[i, 0] + arm_j * spins[j, 0]
    wy = arm_i * spins[i, 1] + arm_j * spins[j, 1]
    wz = arm_i * spins[i, 2] + arm_j * spins[j, 2]
    vx = velocities[i, 0] - velocities[j, 0] + wy * nz - wz * ny
    vy = velocities[i, 1] - velocities[j, 1] + wz * nx - wx * nz
    vz = velocities[i, 2] - velocities[j, 2] + wx * ny - wy * nx
    return vx, vy, vz


@njit(cache=True)
def apply_contact(forces, torques, i, j, fn, nx, ny, nz, sx, sy, sz, arm_i, arm_j):
    """Add a contact's normal force fn along -n and shear (sx, sy, sz) on i, the opposite
    on j, and the shear's torques about each centre (arms to the contact point)."""
    # torques arm_i n x F_s on i and (-arm_j n) x (-F_s) on j point the same way
    _scatter_contact(forces, torques, i, j, sx - fn * nx, sy - fn * ny, sz - fn * nz,
                     ny * sz - nz * sy, nz * sx - nx * sz, nx * sy - ny * sx, arm_i, arm_j)


@njit(cache=True)
def _scatter_contact(forces, torques, i, j, fx, fy, fz, tx, ty, tz, arm_i, arm_j):
    """Add the force (fx, fy, fz) on i and its opposite on j, and the torques arm t on
    both (t = n x F_s)."""
    forces[i, 0] += fx
    forces[i, 1] += fy
    forces[i, 2] += fz
    forces[j, 0] -= fx
    forces[j, 1] -= fy
    forces[j, 2] -= fz
    torques[i, 0] += arm_i * tx
    torques[i, 1] += arm_i * ty
    torques[i, 2] += arm_i * tz
    torques[j, 0] += arm_j * tx
    torques[j, 1] += arm_j * ty
    torques[j, 2] += arm_j * tz


@njit(cache=True)
def _turned_shear(sx, sy, sz, nx, ny, nz):
    """Stored shear force projected on the current tangent plane, magnitude kept.

    A rigid rotation of the pair must not shrink the stored force.
    """
    old2 = sx * sx + sy * sy + sz * sz
    sn = sx * nx + sy * ny + sz * nz
    sx, sy, sz = sx - sn * nx, sy - sn * ny, sz - sn * nz
    new2 = sx * sx + sy * sy + sz * sz
    if new2 > 0.0:
        scale = np.sqrt(old2 / new2)
        return sx * scale, sy * scale, sz * scale
    return sx, sy, sz


@njit(cache=True)
def _mindlin_shear(sx, sy, sz, vx, vy, vz, nx, ny, nz, k_t, limit):
    """A contact's new shear force: the stored one (sx, sy, sz) turned into the tangent
    plane of n (:func:`_turned_shear`), minus ``k_t`` times the tangential part of the
    contact point's relative displacement (vx, vy, vz), scaled down to Coulomb's
    ``limit`` [N] if above it."""
    vn = vx * nx + vy * ny + vz * nz
    sx, sy, sz = _turned_shear(sx, sy, sz, nx, ny, nz)
    sx -= k_t * (vx - vn * nx)
    sy -= k_t * (vy - vn * ny)
    sz -= k_t * (vz - vn * nz)
    magnitude = np.sqrt(sx * sx + sy * sy + sz * sz)
    if magnitude > limit:
        scale = limit / magnitude
        sx, sy, sz = sx * scale, sy * scale, sz * scale
    return sx, sy, sz


@njit(cache=True)
def gershgorin_rates(positions, radii, pairs, masses, inertia, effective_modulus,
                     shear_coefficient, rates):
    """Add, per point, block-Gershgorin row sums of M^-1/2 K M^-1/2 [1/s^2].

    ``rates[:, 0]`` bounds the translational rows, ``rates[:, 1]`` the rotational
    ones. Blocks of one contact: force-translation max(k_n, k_t), force-rotation and
    torque-translation k_t l, torque-rotation k_t l_i l_j, with k_n = 2 E* sqrt(R* delta),
    k_t = c_s sqrt(R* delta), l = r - delta / 2; M holds masses and moments of inertia.
    """
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        d2 = 0.0
        for c in range(3):
            d2 += (positions[j, c] - positions[i, c]) ** 2
        overlap = radii[i] + radii[j] - np.sqrt(d2)
        if overlap <= 0.0:
            continue
        a = np.sqrt(radii[i] * radii[j] / (radii[i] + radii[j]) * overlap)
        k_max = max(2.0 * effective_modulus * a, shear_coefficient * a)
        k_t = shear_coefficient * a
        arm_i, arm_j = radii[i] - 0.5 * overlap, radii[j] - 0.5 * overlap
        mi, mj = np.sqrt(masses[i]), np.sqrt(masses[j])
        ii, ij = np.sqrt(inertia[i]), np.sqrt(inertia[j])
        rotation = arm_i / ii + arm_j / ij
        rates[i, 0] += k_max / mi * (1.0 / mi + 1.0 / mj) + k_t * rotation / mi
        rates[j, 0] += k_max / mj * (1.0 / mi + 1.0 / mj) + k_t * rotation / mj
        translation = 1.0 / mi + 1.0 / mj
        rates[i, 1] += k_t * arm_i / ii * (rotation + translation)
        rates[j, 1] += k_t * arm_j / ij * (rotation + translation)


@njit(cache=True)
def bond_rates(bonds, broken, radii, masses, effective_modulus):
    """Per point, the Gershgorin row sums of the intact bonds' springs k = E* r_m
    [1/s^2], summed bond by bond (i before j), as numpy's bincount of them would."""
    rates = np.zeros(radii.shape[0])
    for b in range(bonds.shape[0]):
        if broken[b]:
            continue
        i, j = bonds[b, 0], bonds[b, 1]
        stiffness = effective_modulus * 0.5 * (radii[i] + radii[j])
        root_i, root_j = np.sqrt(masses[i]), np.sqrt(masses[j])
        coupling = stiffness * (1.0 / root_i + 1.0 / root_j)
        rates[i] += coupling / root_i
        rates[j] += coupling / root_j
    return rates


@njit(cache=True)
def holding_points(pairs, normal_forces, bonds, broken, n_points):
    """Points with a compressive contact (normal force > 0) or an intact bond."""
    held = np.zeros(n_points, dtype=np.bool_)
    for k in range(pairs.shape[0]):
        if normal_forces[k] > 0.0:
            held[pairs[k, 0]] = True
            held[pairs[k, 1]] = True
    for b in range(bonds.shape[0]):
        if not broken[b]:
            held[bonds[b, 0]] = True
            held[bonds[b, 1]] = True
    return held


@njit(cache=True)
def _separation(positions, i, j):
    """Vector from point i to point j and its length [m]."""
    dx = positions[j, 0] - positions[i, 0]
    dy = positions[j, 1] - positions[i, 1]
    dz = positions[j, 2] - positions[i, 2]
    return dx, dy, dz, np.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def _stretch(overlap, reference_overlap, r_i, r_j, r0_i, r0_j):
    """Opening of a pair beyond its stress-free overlap [m]: > 0 stretched (a bond
    opening, a crack's aperture), < 0 the overlap that loads the Hertz contact.

    u = delta0 (r_i + r_j) / (r0_i + r0_j) - overlap, delta0 the stress-free overlap at
    the reference radii r0 (0 for a pair without bond).
    """
    return reference_overlap * ((r_i + r_j) / (r0_i + r0_j)) - overlap


@njit(cache=True)
def bond_stretches(positions, radii, reference_radii, bonds, bond_overlaps):
    """Stretch u of every bond (:func:`_stretch`) [m], broken or not."""
    stretches = np.empty(bonds.shape[0])
    for b in range(bonds.shape[0]):
        i, j = bonds[b, 0], bonds[b, 1]
        dx, dy, dz, dist = _separation(positions, i, j)
        stretches[b] = _stretch(radii[i] + radii[j] - dist, bond_overlaps[b], radii[i],
                                radii[j], reference_radii[i], reference_radii[j])
    return stretches


@njit(cache=True, parallel=True)
def bond_tension(positions, radii, reference_radii, bonds, bond_overlaps, broken,
                 effective_modulus, strength, forces):
    """Add the tension of intact bonds stretched beyond their stress-free overlap.

    Stretch u > 0 (:func:`_stretch`); tension k u with k = E* r_m (r_m the mean radius
    of the pair) while k u <= strength pi r_m^2, else the bond breaks for good
    (``broken`` set) and carries nothing. The bonds are tested in parallel; the few
    stretched ones are then added serially in bond order.
    """
    n_bonds = bonds.shape[0]
    pulls = np.empty((n_bonds, 3))
    pulling = np.zeros(n_bonds, dtype=np.bool_)
    for b in prange(n_bonds):
        if broken[b]:
            continue
        i, j = bonds[b, 0], bonds[b, 1]
        dx, dy, dz, dist = _separation(positions, i, j)
        stretch = _stretch(radii[i] + radii[j] - dist, bond_overlaps[b], radii[i], radii[j],
                           reference_radii[i], reference_radii[j])
        mean_radius = 0.5 * (radii[i] + radii[j])
        k = effective_modulus * mean_radius
        if stretch <= 0.0 or dist == 0.0:
            continue
        tension = k * stretch
        if tension > strength * np.pi * mean_radius * mean_radius:
            broken[b] = True
            continue
        f = tension / dist
        pulling[b] = True
        pulls[b, 0], pulls[b, 1], pulls[b, 2] = f * dx, f * dy, f * dz
    for b in range(n_bonds):
        if pulling[b]:
            i, j = bonds[b, 0], bonds[b, 1]
            for c in range(3):
                forces[i, c] += pulls[b, c]
                forces[j, c] -= pulls[b, c]


@njit(cache=True)
def wall_contacts(positions, radii, lower, upper, active, effective_modulus, forces,
                  stiffness):
    """Add frictionless Hertz forces of six axis-aligned rigid walls.

    Wall w = 2 axis + side (side 0 lower, 1 upper). Returns per wall the compressive
    force magnitude [N] and the summed tangent stiffness of its contacts [N/m]; the
    tangent stiffness is also added to ``stiffness`` per point.
    """
    wall_force = np.zeros(6)
    wall_stiffness = np.zeros(6)
    for i in range(positions.shape[0]):
        for axis in range(3):
            for side in range(2):
                w = 2 * axis + side
                if not active[w]:
                    continue
                if side == 0:
                    overlap = radii[i] - (positions[i, axis] - lower[axis])
                else:
                    overlap = radii[i] - (upper[axis] - positions[i, axis])
                if overlap <= 0.0:
                    continue
                a = np.sqrt(radii[i] * overlap)
                fn = 4.0 / 3.0 * effective_modulus * a * overlap
                forces[i, axis] += fn if side == 0 else -fn
                wall_force[w] += fn
                wall_stiffness[w] += 2.0 * effective_modulus * a
                stiffness[i] += 2.0 * effective_modulus * a
    return wall_force, wall_stiffness


@njit(cache=True, parallel=True)
def leapfrog(values, rates, drives, inertia, fixed, damping, time_step):
    """Advance half-step ``rates`` (and ``values`` if given) by one step, in place.

    rate += dt drive / inertia, then value += dt rate. Translation passes positions,
    velocities, forces and masses; rotation passes an empty ``values`` (spheres need
    no orientation), spins, torques and moments of inertia. Cundall damping scales
    each drive component by 1 - damping sign(drive rate_mid), rate_mid the rate at
    the current time (second-order form of Yade's NewtonIntegrator).
    """
    for i in prange(rates.shape[0]):
        if fixed[i]:
            continue
        for c in range(3):
            f = drives[i, c]
            if damping > 0.0:
                rate_mid = rates[i, c] + 0.5 * time_step * f / inertia[i]
                f *= 1.0 - damping * np.sign(f * rate_mid)
            rates[i, c] += time_step * f / inertia[i]
            if values.shape[0] > 0:
                values[i, c] += time_step * rates[i, c]


@njit(cache=True)
def largest_distance(points, reference):
    """max_i |points_i - reference_i| over the rows of two (n, 3) arrays [m]; 0 if n = 0."""
    largest = 0.0
    for i in range(points.shape[0]):
        dx = points[i, 0] - reference[i, 0]
        dy = points[i, 1] - reference[i, 1]
        dz = points[i, 2] - reference[i, 2]
        largest = max(largest, np.sqrt(dx * dx + dy * dy + dz * dz))
    return largest


@njit(cache=True, parallel=True)
def cap_speed(velocities, max_speed):
    """Scale down, in place, the rows of ``velocities`` faster than ``max_speed``."""
    for i in prange(velocities.shape[0]):
        speed = np.sqrt(velocities[i, 0] ** 2 + velocities[i, 1] ** 2 + velocities[i, 2] ** 2)
        if speed > max_speed:
            scale = max_speed / speed
            velocities[i, 0] *= scale
            velocities[i, 1] *= scale
            velocities[i, 2] *= scale


@njit(cache=True)
def hertz_yield(e_star, r_star, overlap, plastic, yield_force):
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
def _slipped(ux, uy, uz, vx, vy, vz, nx, ny, nz):
    """A contact's tangential displacement since its last committed state: the stored one
    turned into the tangent plane of n (:func:`_turned_shear`) plus the tangential part of
    the substep's relative displacement (vx, vy, vz) [m]."""
    vn = vx * nx + vy * ny + vz * nz
    ux, uy, uz = _turned_shear(ux, uy, uz, nx, ny, nz)
    return ux + vx - vn * nx, uy + vy - vn * ny, uz + vz - vn * nz


@njit(cache=True)
def yielding_hertz_mindlin(positions, velocities, spins, radii, young, poisson, friction, pairs,
                           shear, forces, torques, stiffness, yield_force, plastic,
                           committed_shear, committed_plastic, slip):
    """Hertz-Mindlin forces between points of their own moduli, with Coulomb friction and
    yield (Eqs. 4.1-4.9 of the macro model), returned from the last committed state.

    Normal: F_n = 4/3 E* sqrt(R*) delta^(3/2), E* = E_a E_b / ((E_a + E_b)(1 - nu^2))
    from each pellet's modulus (Eq. 4.2). Shear (Eqs. 4.5-4.9): the committed force,
    turned into the current tangent plane, changes by -k_t times the tangential
    displacement of the contact point since the commit (``slip`` [m], updated in place
    with the substep's relative displacement: velocities and spins are per substep,
    time unit 1), k_t = 4 G a / (2 - nu), G the mean of the two shear moduli
    E / (2 (1 + nu)), a = sqrt(R* delta); Coulomb's limit |F_s| <= tan(phi) F_n with
    ``friction`` = tan(phi). The normal force yields at the smaller ``yield_force`` of the
    two pellets (:func:`hertz_yield`, from the committed plastic overlap [m]). Writes the
    trial ``shear`` (on ``pairs[k, 0]`` [N]) and ``plastic`` per pair (0 where the
    pellets are apart), which a caller commits once balanced: the forces at given
    positions then do not depend on the path that led there (a solver's iterations slide
    and yield nothing). Passing the committed arrays as the trial ones, with a zero
    ``slip``, commits at every call (the explicit incremental update). Adds the forces,
    the torques and the normal tangent stiffness 2 E* a per pellet; returns the normal
    force of each pair [N] (0 if apart).
    """
    normal = np.zeros(pairs.shape[0])
    factor = 1.0 - poisson * poisson
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        dx, dy, dz, dist = _separation(positions, i, j)
        overlap = radii[i] + radii[j] - dist
        if dist > 0.0:
            nx, ny, nz = dx / dist, dy / dist, dz / dist
            arm_i, arm_j = radii[i] - 0.5 * max(overlap, 0.0), radii[j] - 0.5 * max(overlap, 0.0)
            vx, vy, vz = contact_velocity(velocities, spins, i, j, nx, ny, nz, arm_i, arm_j)
            slip[k, 0], slip[k, 1], slip[k, 2] = _slipped(slip[k, 0], slip[k, 1], slip[k, 2], vx, vy, vz,
                                                         nx, ny, nz)
        if overlap <= 0.0 or dist == 0.0:
            shear[k, 0] = shear[k, 1] = shear[k, 2] = 0.0
            plastic[k] = 0.0
            continue
        e_star = young[i] * young[j] / (factor * (young[i] + young[j]))
        fn, plastic[k], a = hertz_yield(e_star, radii[i] * radii[j] / (radii[i] + radii[j]), overlap,
                                        committed_plastic[k], min(yield_force[i], yield_force[j]))
        normal[k] = fn
        shear_modulus = 0.25 * (young[i] + young[j]) / (1.0 + poisson)
        k_t = 4.0 * shear_modulus * a / (2.0 - poisson)
        sx, sy, sz = _mindlin_shear(committed_shear[k, 0], committed_shear[k, 1], committed_shear[k, 2],
                                    slip[k, 0], slip[k, 1], slip[k, 2], nx, ny, nz, k_t, friction * fn)
        shear[k, 0], shear[k, 1], shear[k, 2] = sx, sy, sz
        apply_contact(forces, torques, i, j, fn, nx, ny, nz, sx, sy, sz, arm_i, arm_j)
        stiffness[i] += 2.0 * e_star * a
        stiffness[j] += 2.0 * e_star * a
    return normal


@njit(cache=True)
def cylinder_contacts(positions, velocities, spins, radii, young, poisson, friction, cylinder_radius,
                      z_low, z_high, forces, torques, stiffness, yield_force, plastic, shear,
                      committed_plastic, committed_shear, slip):
    """Hertz-Mindlin contacts with a rigid cylinder and two rigid end plates, with
    Coulomb friction, returned from the last committed state.

    A pellet of radius r at distance rho from the axis overlaps the curved wall by
    rho + r - R and a plate by r - (distance to the plate); force 4/3 E* sqrt(r) delta^(3/2)
    with E* = E / (1 - nu^2) (rigid wall, R* = r; the wall's curvature is neglected),
    yielding at the pellet's ``yield_force`` (:func:`hertz_yield` from
    ``committed_plastic``, (n, 3) [m] per pellet for the wall, lower and upper plate;
    the trial ``plastic`` written). With ``friction`` = tan(phi_w) > 0, the tangential
    force (n, 3, 3) [N] is Mindlin's against a rigid surface: ``committed_shear``, turned
    into the current tangent plane, minus k_t times the contact point's tangential
    displacement since the commit (``slip`` [m], updated in place with the substep's:
    ``velocities`` and ``spins`` are per substep, the contact point ``r - delta`` from the
    centre), k_t = 8 G a / (2 - nu), G = E / (2 (1 + nu)), a = sqrt(r delta), within
    Coulomb's |F_t| <= tan(phi_w) F_n; written to the trial ``shear`` (0 off the surface)
    with its torque about the centre. As for :func:`yielding_hertz_mindlin`, the caller
    commits the trial arrays once balanced, or passes the committed ones as the trial
    ones with a zero ``slip`` to commit at every call. ``friction`` 0 leaves the
    contacts frictionless (``shear``, ``slip`` and ``torques`` untouched). Adds the
    normal tangent stiffness 2 E* a per pellet. Returns per pellet the normal force on
    the curved wall (radial, outwards), on the lower and on the upper plate [N].
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
            nx, ny, nz = normals[w]
            arm = radii[i] - max(overlaps[w], 0.0)
            if friction > 0.0:
                # the contact point's displacement: the centre's plus spin x (arm n)
                vx = velocities[i, 0] + arm * (spins[i, 1] * nz - spins[i, 2] * ny)
                vy = velocities[i, 1] + arm * (spins[i, 2] * nx - spins[i, 0] * nz)
                vz = velocities[i, 2] + arm * (spins[i, 0] * ny - spins[i, 1] * nx)
                slip[i, w, 0], slip[i, w, 1], slip[i, w, 2] = _slipped(
                    slip[i, w, 0], slip[i, w, 1], slip[i, w, 2], vx, vy, vz, nx, ny, nz)
            if overlaps[w] <= 0.0:
                plastic[i, w] = 0.0
                shear[i, w, 0] = shear[i, w, 1] = shear[i, w, 2] = 0.0
                continue
            fn, plastic[i, w], a = hertz_yield(e_star, radii[i], overlaps[w], committed_plastic[i, w],
                                               yield_force[i])
            loads[i, w] = fn
            forces[i, 0] -= fn * nx
            forces[i, 1] -= fn * ny
            forces[i, 2] -= fn * nz
            stiffness[i] += 2.0 * e_star * a
            if friction <= 0.0:
                continue
            k_t = 4.0 * young[i] * a / ((1.0 + poisson) * (2.0 - poisson))
            sx, sy, sz = _mindlin_shear(committed_shear[i, w, 0], committed_shear[i, w, 1],
                                        committed_shear[i, w, 2], slip[i, w, 0], slip[i, w, 1], slip[i, w, 2],
                                        nx, ny, nz, k_t, friction * fn)
            shear[i, w, 0], shear[i, w, 1], shear[i, w, 2] = sx, sy, sz
            forces[i, 0] += sx
            forces[i, 1] += sy
            forces[i, 2] += sz
            torques[i, 0] += arm * (ny * sz - nz * sy)
            torques[i, 1] += arm * (nz * sx - nx * sz)
            torques[i, 2] += arm * (nx * sy - ny * sx)
    return loads[:, 0].copy(), loads[:, 1].copy(), loads[:, 2].copy()


PARALLEL_MIN_ROWS = 4096
"""Rows (contacts, bonds or points) from which :func:`sized` picks a parallel kernel."""


def _serial_twin(kernel):
    """``kernel`` compiled without ``parallel=True`` (its ``prange`` runs as ``range``).

    The same source and scalar arithmetic, without the sums that a parallel loop would
    reorder: the results are bit-identical. A twin of its own name and qualified name,
    so that numba's on-disk cache keeps the two compilations apart.
    """
    py_func = kernel.py_func
    name = f"{py_func.__name__}_serial"
    twin = types.FunctionType(py_func.__code__.replace(co_name=name), py_func.__globals__,
                              name, py_func.__defaults__, py_func.__closure__)
    twin.__qualname__ = name
    twin.__doc__ = py_func.__doc__
    return njit(cache=True)(twin)


hertz_mindlin_serial = _serial_twin(hertz_mindlin)
bond_tension_serial = _serial_twin(bond_tension)
leapfrog_serial = _serial_twin(leapfrog)
cap_speed_serial = _serial_twin(cap_speed)


def sized(parallel, serial, rows: int):
    """The parallel kernel from ``PARALLEL_MIN_ROWS`` rows, else its serial twin.

    Below, the start and join of the parallel region (a few microseconds on idle cores,
    tens to hundreds when other processes hold them) cost more than a second thread
    wins: the 216-point test cases spend most of their DEM steps there.
    """
    return parallel if rows >= PARALLEL_MIN_ROWS else serial
