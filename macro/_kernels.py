"""numba kernels of the macro model: the packing's soft-sphere overlap energy in a
cylinder, and the powder's push on the pellets in one pass over cells and triangles.

Arrays in, arrays out; parallel loops write only their own rows, serial loops sum them
into per-pellet arrays in order (deterministic whatever the thread count).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def overlap_energy(positions, radii, pairs, cylinder_radius, z_low, z_high, gradient):
    """Harmonic overlap energy of spheres in a closed cylinder (axis z), its gradient.

    E = sum over the listed pairs of (r_i + r_j - d_ij)^2 / 2, plus (rho_i + r_i - R)^2 / 2
    for the curved wall and (z_low + r_i - z_i)^2 / 2, (z_i + r_i - z_high)^2 / 2 for
    the plates, each term only where it overlaps. Lengths in any one unit; the energy
    is in that unit squared.

    Parameters
    ----------
    positions
        (n, 3) sphere centres.
    radii
        (n,) sphere radii.
    pairs
        (m, 2) candidate pairs (i, j).
    cylinder_radius, z_low, z_high
        The container's radius and the heights of its plates.
    gradient
        (n, 3) output: dE/dpositions (overwritten).

    Returns
    -------
    energy, largest
        The energy and the largest overlap (0 when none; same unit as the lengths).
    """
    n = positions.shape[0]
    gradient[:] = 0.0
    energy = 0.0
    largest = 0.0
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        dx = positions[j, 0] - positions[i, 0]
        dy = positions[j, 1] - positions[i, 1]
        dz = positions[j, 2] - positions[i, 2]
        dist = np.sqrt(dx * dx + dy * dy + dz * dz)
        overlap = radii[i] + radii[j] - dist
        if overlap <= 0.0 or dist == 0.0:
            continue
        largest = max(largest, overlap)
        energy += 0.5 * overlap * overlap
        # dE/dx_i = overlap (x_j - x_i) / d, and the opposite for j
        s = overlap / dist
        gradient[i, 0] += s * dx
        gradient[i, 1] += s * dy
        gradient[i, 2] += s * dz
        gradient[j, 0] -= s * dx
        gradient[j, 1] -= s * dy
        gradient[j, 2] -= s * dz
    for i in range(n):
        rho = np.sqrt(positions[i, 0] ** 2 + positions[i, 1] ** 2)
        wall = rho + radii[i] - cylinder_radius
        if wall > 0.0 and rho > 0.0:
            largest = max(largest, wall)
            energy += 0.5 * wall * wall
            gradient[i, 0] += wall * positions[i, 0] / rho
            gradient[i, 1] += wall * positions[i, 1] / rho
        low = z_low + radii[i] - positions[i, 2]
        if low > 0.0:
            largest = max(largest, low)
            energy += 0.5 * low * low
            gradient[i, 2] -= low
        high = positions[i, 2] + radii[i] - z_high
        if high > 0.0:
            largest = max(largest, high)
            energy += 0.5 * high * high
            gradient[i, 2] += high
    return energy, largest


@njit(cache=True)
def _squared(p, q):
    """|q - p|^2."""
    return (q[0] - p[0]) ** 2 + (q[1] - p[1]) ** 2 + (q[2] - p[2]) ** 2


@njit(cache=True)
def _solid_angle(triple, la, lb, lc, ab, ac, bc):
    """Solid angle at a tetrahedron's vertex [sr] (Van Oosterom-Strackee) from six times
    its volume, the lengths of its edges to the other three vertices a, b, c and the
    squared lengths of the edges between those."""
    dab = 0.5 * (la * la + lb * lb - ab)
    dac = 0.5 * (la * la + lc * lc - ac)
    dbc = 0.5 * (lb * lb + lc * lc - bc)
    return 2.0 * np.arctan2(triple, la * lb * lc + dab * lc + dac * lb + dbc * la)


@njit(cache=True)
def _corner_angle(opposite, left, right):
    """Interior angle of a triangle [rad] from the squared lengths of its sides: the one
    opposite the corner and the two that meet there."""
    cos = (left + right - opposite) / (2.0 * np.sqrt(left * right))
    return np.arccos(min(1.0, max(-1.0, cos)))


@njit(cache=True)
def incidence(entries, n_rows):
    """Where each row below ``n_rows`` occurs in an (m, k) array of row indices (a mesh's
    tetrahedra or triangles): CSR offsets (n_rows + 1,) and the flat positions i k + j,
    ascending for each row, the order in which a serial scatter over the array visits
    them (so a gather over them sums in the same order)."""
    flat = entries.ravel()
    start = np.zeros(n_rows + 1, dtype=np.int64)
    for e in flat:
        if e < n_rows:
            start[e + 1] += 1
    for r in range(n_rows):
        start[r + 1] += start[r]
    fill = start[:-1].copy()
    where = np.empty(start[n_rows], dtype=np.int64)
    for i in range(flat.size):
        e = flat[i]
        if e < n_rows:
            where[fill[e]] = i
            fill[e] += 1
    return start, where


@njit(cache=True, parallel=True)
def powder_push(points, tetrahedra, facet_vertices, facet_cells, clay_radii, sphere_radii, n_pellets,
                solid_mass, densest, free, candidate, bound, scale, alpha, onset_strain, void_floor,
                cell_incidence, facet_incidence):
    """The powder's push on the pellets at the mesh's current points, in one pass.

    Per cell: the void (tetrahedron less the clay spheres' solid-angle shares, floored
    at ``void_floor`` of the tetrahedron), the volume it holds, max(void, densest), and
    its pressure P = scale exp(alpha m_s / held) where the cell is a ``candidate`` and
    its clay is held below its ``free`` volume, times min(1, (free - held) / (onset_strain
    free)) (:func:`macro.laws.onset_ramp`), at most ``bound``; per interior
    triangle: each pellet's sector theta r^2 / 2 pushed by the pressure jump across it
    along the normal from the first cell to the second (as :meth:`macro.mechanics.
    Mechanics.hydro_forces`). ``cell_incidence`` and ``facet_incidence`` are
    :func:`incidence` of the tetrahedra and triangles: each pellet gathers its cells'
    stiffness and its triangles' push in mesh order, in parallel and deterministic.

    Returns
    -------
    forces
        (n_pellets, 3) push on the pellets [N].
    pressure
        (n_c,) the cells' pressures [Pa].
    stiffness
        (n_pellets,) sum over each pellet's cells of |dP/dV| (Omega r^2)^2 [N/m] (0 for
        capped cells).
    inverted
        True if a candidate cell is inverted (its signed volume is not positive).
    """
    n_cells, n_facets = tetrahedra.shape[0], facet_vertices.shape[0]
    pressure = np.zeros(n_cells)
    slope = np.zeros(n_cells)
    # read only at pellet vertices of pressing cells, which set them
    omega = np.empty((n_cells, 4))
    flipped = np.zeros(n_cells, dtype=np.bool_)
    for c in prange(n_cells):
        if not candidate[c]:
            continue
        p0, p1 = points[tetrahedra[c, 0]], points[tetrahedra[c, 1]]
        p2, p3 = points[tetrahedra[c, 2]], points[tetrahedra[c, 3]]
        e1x, e1y, e1z = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
        e2x, e2y, e2z = p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]
        e3x, e3y, e3z = p3[0] - p0[0], p3[1] - p0[1], p3[2] - p0[2]
        signed = (e1x * (e2y * e3z - e2z * e3y) + e1y * (e2z * e3x - e2x * e3z) + e1z * (e2x * e3y - e2y * e3x)) / 6.0
        flipped[c] = signed <= 0.0
        volume = abs(signed)
        # the six edges, shared by the four vertices' solid angles
        s01, s02, s03 = _squared(p0, p1), _squared(p0, p2), _squared(p0, p3)
        s12, s13, s23 = _squared(p1, p2), _squared(p1, p3), _squared(p2, p3)
        l01, l02, l03 = np.sqrt(s01), np.sqrt(s02), np.sqrt(s03)
        l12, l13, l23 = np.sqrt(s12), np.sqrt(s13), np.sqrt(s23)
        triple = 6.0 * volume
        # container points hold no clay (radius 0): their solid angles are not needed
        if tetrahedra[c, 0] < n_pellets:
            omega[c, 0] = _solid_angle(triple, l01, l02, l03, s12, s13, s23)
        if tetrahedra[c, 1] < n_pellets:
            omega[c, 1] = _solid_angle(triple, l01, l12, l13, s02, s03, s23)
        if tetrahedra[c, 2] < n_pellets:
            omega[c, 2] = _solid_angle(triple, l02, l12, l23, s01, s03, s13)
        if tetrahedra[c, 3] < n_pellets:
            omega[c, 3] = _solid_angle(triple, l03, l13, l23, s01, s02, s12)
        inside = 0.0
        for v in range(4):
            if tetrahedra[c, v] < n_pellets:
                inside += omega[c, v] * clay_radii[tetrahedra[c, v]] ** 3
        void = max(volume - inside / 3.0, void_floor * volume)
        held = max(void, densest[c])
        if free[c] <= held:
            continue
        # the law, reached linearly over the onset strain below the free volume
        law = scale[c] * np.exp(alpha * solid_mass[c] / held)
        ramp = min(1.0, (free[c] - held) / (onset_strain * free[c]))
        value = law * ramp
        if value > bound[c]:
            pressure[c] = bound[c]
        else:
            pressure[c] = value
            slope[c] = value * alpha * solid_mass[c] / (held * held)
            if ramp < 1.0:
                slope[c] += law / (onset_strain * free[c])
    # each triangle's push on its pellet vertices (read only where the triangle pushes),
    # then gathered per pellet in mesh order (deterministic)
    parts = np.empty((n_facets, 3, 3))
    pushes = np.zeros(n_facets, dtype=np.bool_)
    for f in prange(n_facets):
        c0, c1 = facet_cells[f, 0], facet_cells[f, 1]
        jump = pressure[c0] - pressure[c1]
        if jump == 0.0:
            continue
        pushes[f] = True
        a, b, c = points[facet_vertices[f, 0]], points[facet_vertices[f, 1]], points[facet_vertices[f, 2]]
        nx = (b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1])
        ny = (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2])
        nz = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        norm = max(np.sqrt(nx * nx + ny * ny + nz * nz), 1e-300)
        # from the first cell to the second, read off a pressing cell (never inverted):
        # away from its vertex off the triangle for the first, towards it for the second
        side = c0 if pressure[c0] > 0.0 else c1
        o = points[tetrahedra[side, 0] + tetrahedra[side, 1] + tetrahedra[side, 2] + tetrahedra[side, 3]
                   - facet_vertices[f, 0] - facet_vertices[f, 1] - facet_vertices[f, 2]]
        if (nx * (a[0] - o[0]) + ny * (a[1] - o[1]) + nz * (a[2] - o[2]) < 0.0) == (side == c0):
            norm = -norm
        # squared side opposite each corner
        sides = (_squared(b, c), _squared(a, c), _squared(a, b))
        for k in range(3):
            vertex = facet_vertices[f, k]
            if vertex >= n_pellets:
                continue
            theta = _corner_angle(sides[k], sides[(k + 1) % 3], sides[(k + 2) % 3])
            push = 0.5 * theta * sphere_radii[vertex] ** 2 * jump / norm
            parts[f, k, 0] = push * nx
            parts[f, k, 1] = push * ny
            parts[f, k, 2] = push * nz
    cell_start, cell_where = cell_incidence
    facet_start, facet_where = facet_incidence
    stiffness = np.zeros(n_pellets)
    forces = np.zeros((n_pellets, 3))
    for p in prange(n_pellets):
        for e in range(cell_start[p], cell_start[p + 1]):
            c, v = cell_where[e] // 4, cell_where[e] % 4
            if slope[c] > 0.0:
                area = omega[c, v] * sphere_radii[p] ** 2
                stiffness[p] += slope[c] * area * area
        for e in range(facet_start[p], facet_start[p + 1]):
            f, k = facet_where[e] // 3, facet_where[e] % 3
            if pushes[f]:
                for d in range(3):
                    forces[p, d] += parts[f, k, d]
    inverted = flipped.any()
    return forces, pressure, stiffness, inverted
