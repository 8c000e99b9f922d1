"""macro.mechanics: the powder's push on a pellet through its sectors of the cells' facets
(Eqs. 4.34-4.38) against the pressure on a hemisphere; the relaxation's balance."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from macro._kernels import incidence
from macro.laws import free_volume, swelling_pressure, yield_force, young_modulus
from macro.mechanics import Mechanics
from macro.settings import macro_settings
from shared.dem import cylinder_contacts
from shared.mesh import build_mesh
from tests._macro_cases import small_config
from tests.macro._hand_placed import placed_model


class _Octahedron(Mechanics):
    """A pellet of radius r at the origin, the six container points (+-1, 0, 0), ... around
    it: the eight octant cells."""

    def __init__(self, r: float) -> None:
        points = np.vstack([np.zeros(3), np.eye(3), -np.eye(3)])
        self.mesh = build_mesh(points)
        self.n_pellets, self.n_vertices, self._radius = 1, 7, r

    def vertex_radii(self) -> np.ndarray:
        return np.array([self._radius, 0, 0, 0, 0, 0, 0], dtype=np.float64)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_pressure_on_one_half_pushes_the_pellet_with_p_times_its_cross_section(axis):
    """The cells on one side of a coordinate plane at P, the others at 0: the pellet is
    pushed across the plane by P pi r^2 (a uniform pressure on a hemisphere); equal
    pressures on both sides push it nowhere."""
    model = _Octahedron(0.3)
    mesh = model.mesh
    assert mesh.n_cells == 8 and mesh.n_facets == 12
    upper = mesh.centroids[:, axis] > 0.0
    force = model.hydro_forces(np.where(upper, 2.0e5, 0.0))
    expected = np.zeros(3)
    expected[axis] = -2.0e5 * np.pi * 0.3**2
    np.testing.assert_allclose(force[0], expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(model.hydro_forces(np.full(8, 2.0e5))[0], 0.0, atol=1e-9)


@pytest.mark.parametrize("tolerance", [1e-2, 1e-3])
def test_relaxation_of_the_small_column_balances_to_the_tolerance(model, tolerance):
    """After hydration steps (the pellets swollen and pushed by their powder), FIRE
    balances the small column to the default unbalanced force ratio 0.01 and to 0.001,
    per pellet and for the pellets' net resultant, within 400 steps. (Before the powder's
    onset of confinement was regularised, macro.laws.onset_ramp, 0.001 was not reached:
    the ratio stalled at 0.002-0.01 over 3 000 steps.)"""
    model.settings = replace(model.settings, dem_balance_tolerance=tolerance)
    for _ in range(5):
        model.step()
    used = model.counters.dem_substeps
    readings = model.relax(400)
    assert readings.unbalanced < tolerance and readings.net_unbalanced < tolerance
    assert model.counters.dem_substeps - used < 400


@pytest.mark.parametrize("rigid_correction", [False, True])
def test_net_resultant_is_that_of_the_push_and_the_container_alone(model, rigid_correction):
    """Newton's third law: the pair contacts cancel in the pellets' net resultant, so the
    relaxation's net ratio equals the one of the powder's push and the container's
    contacts alone, evaluated apart at the balanced positions; once the plates carry
    the column it is below the tolerance, with FIRE alone and with the rigid correction
    (:func:`shared.dem.rigid_translation`) that removes it."""
    model.settings = replace(model.settings, dem_rigid_correction=rigid_correction)
    for _ in range(8):
        model.step()
    readings = model.relax(400)
    n_p, s, rest = model.n_pellets, model.settings, np.zeros((model.n_pellets, 3))
    forces = model.push_field()(model.positions)[0].copy()
    _, lower, upper = cylinder_contacts(
        model.positions, rest, rest, model.radii, young_modulus(-model.pressure[:n_p], model.material),
        model.material.poisson_ratio, 0.0, s.radius, -0.5 * s.height, 0.5 * s.height, forces, np.zeros((n_p, 3)),
        np.zeros(n_p), yield_force(-model.pressure[:n_p], model.material), np.zeros((n_p, 3)),
        np.zeros((n_p, 3, 3)), model.contacts.wall_plastic, np.zeros((n_p, 3, 3)), np.zeros((n_p, 3, 3)))
    assert lower.sum() > 0.0 and upper.sum() > 0.0
    net = np.linalg.norm(forces.sum(axis=0)) / (0.5 * (lower.sum() + upper.sum()))
    assert readings.net_unbalanced == pytest.approx(net, rel=1e-9)
    assert net < s.dem_balance_tolerance


def test_frictional_walls_keep_the_balance_and_carry_shear(model):
    """With a wall friction angle of 20 deg the column still balances to 0.01, and the
    wall's tangential forces stay within Coulomb's tan(20 deg) times their normal force."""
    model.settings = replace(model.settings, wall_friction=float(np.tan(np.radians(20.0))))
    for _ in range(5):
        model.step()
    assert model.readings.unbalanced < 0.01
    tangential = np.linalg.norm(model.contacts.wall_shear, axis=2)
    assert tangential.max() > 0.0
    # the normal forces of the same contacts (plastic overlaps of a copy)
    n_p, s, rest = model.n_pellets, model.settings, np.zeros((model.n_pellets, 3))
    young = young_modulus(-model.pressure[:n_p], model.material)
    strength = yield_force(-model.pressure[:n_p], model.material)
    normal = np.column_stack(cylinder_contacts(
        model.positions, rest, rest, model.radii, young, model.material.poisson_ratio, 0.0, s.radius,
        -0.5 * s.height, 0.5 * s.height, np.zeros((n_p, 3)), np.zeros((n_p, 3)), np.zeros(n_p), strength,
        np.zeros((n_p, 3)), np.zeros((n_p, 3, 3)), model.contacts.wall_plastic, np.zeros((n_p, 3, 3)),
        np.zeros((n_p, 3, 3))))
    assert np.all(tangential <= s.wall_friction * normal * (1.0 + 1e-12))
    assert np.all(tangential[normal == 0.0] == 0.0)


def test_fused_push_equals_the_pressure_and_facet_forces_computed_apart(model):
    """The relaxation's push (one numba pass, :meth:`Mechanics._push_field`) against
    :meth:`Mechanics.powder_pressure` and :meth:`Mechanics.hydro_forces` (numpy, from the
    moved mesh's voids and angles) at positions moved off the mesh's own: the same cell
    pressures and forces to round-off, and the same inverted-cell verdict."""
    for _ in range(3):
        model.step()
    push = model.push_field()
    model.positions += np.random.default_rng(3).normal(scale=1e-3 * model.radii.mean(), size=model.positions.shape)
    forces, pressure, stiffness, inverted = push(model.positions)
    assert model.move_geometry() is not inverted
    reference, slope = model.powder_pressure()
    assert (reference > 0.0).sum() > 10
    np.testing.assert_allclose(pressure, reference, rtol=1e-10, atol=1e-6)
    np.testing.assert_allclose(forces, model.hydro_forces(reference), rtol=1e-8, atol=1e-9 * np.abs(forces).max())
    area = model.cells.solid_angles * model.vertex_radii()[model.mesh.tetrahedra] ** 2
    by_pellet = np.bincount(model.mesh.tetrahedra.ravel(), (slope[:, None] * area**2).ravel(),
                            minlength=model.n_vertices)[:model.n_pellets]
    np.testing.assert_allclose(stiffness, by_pellet, rtol=1e-10)


def test_incidence_lists_each_pellets_entries_in_mesh_order():
    """:func:`macro._kernels.incidence`, the gather order of the fused push, against
    numpy's search of the flattened array: every row below the bound, its flat
    positions ascending, the container's rows left out."""
    entries = np.random.default_rng(5).integers(0, 40, size=(300, 4))
    start, where = incidence(entries, 30)
    for row in range(30):
        np.testing.assert_array_equal(where[start[row]:start[row + 1]], np.flatnonzero(entries.ravel() == row))
    assert start[-1] == (entries < 30).sum()


def test_pellets_pushed_before_any_contact_are_not_balanced(table_path):
    """Pellets that touch nothing, each pushed by the dry powder: with no contact force to
    compare with, the mean ratio is the resultant over the push, 1 (it read 0, balanced,
    before), and a relaxation moves them."""
    config = small_config()
    settings = macro_settings(config["macro"], "small")
    r, half = settings.pellet_radius, 0.5 * settings.height
    positions = np.array([[0.0, 0.0, z] for z in (-0.6, -0.2, 0.2, 0.6)]) * half \
        + np.array([[0.3, 0.0, 0.0], [0.0, 0.3, 0.0], [-0.3, 0.0, 0.0], [0.0, -0.3, 0.0]]) * settings.radius
    assert np.all(np.abs(positions[:, 2]) < half - r)
    assert np.all(np.hypot(positions[:, 0], positions[:, 1]) < settings.radius - r)
    model = placed_model(table_path, config, positions)
    assert np.abs(model.push_field()(model.positions)[0]).max() > 0.0
    assert model.readings.unbalanced == pytest.approx(1.0, rel=1e-12)
    before = model.positions.copy()
    model.relax(50)
    assert np.abs(model.positions - before).max() > 0.0


def test_the_powders_push_is_continuous_at_its_free_volume_and_its_slope_is_the_derivative(model):
    """A cell's push as its void V_c passes the powder's free volume V_f: 0 at or above
    V_f, rising from 0 below it (no jump, which left the pellets around such a cell no
    balanced state), the law S p'_vc(m_s / V_c) once V_c is the onset strain below V_f;
    the slope :meth:`powder_pressure` returns is the centred difference of the push in
    V_c on the ramp and past it."""
    n_p, onset = model.n_pellets, model.settings.powder_onset_strain
    cells = slice(n_p, None)
    c = int(np.flatnonzero(~model.inert[cells] & ~model.held[cells])[0])
    free = float(free_volume(-model.pressure[n_p + c], model.reference_volume[n_p + c], model.material))
    solid_mass = model.solid_mass()[n_p + c]
    law = float(swelling_pressure(solid_mass / (free * (1.0 - 2.0 * onset)), -model.pressure[n_p + c],
                                  model.retention_porosity()[n_p + c], model.material))
    assert law > 0.0

    def push(void):
        model.cells.voids[c] = void
        return model.powder_pressure()

    assert push(free)[0][c] == 0.0 and push(1.001 * free)[0][c] == 0.0
    near = push(free * (1.0 - 1e-9))[0][c]
    assert 0.0 < near < 1e-6 * law
    assert push(free * (1.0 - 2.0 * onset))[0][c] == pytest.approx(law, rel=1e-12)
    for void in (free * (1.0 - 0.5 * onset), free * (1.0 - 2.0 * onset)):
        h = 1e-6 * onset * free
        centred = (push(void - h)[0][c] - push(void + h)[0][c]) / (2.0 * h)
        assert push(void)[1][c] == pytest.approx(centred, rel=1e-5)
