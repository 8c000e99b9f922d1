"""Analyses against hand-computed values (Ferrage et al. 2015, Eqs. 1-11)."""

from __future__ import annotations

import numpy as np
import pytest

from imaging.packing import analysis
from imaging.packing.orientation import rotation_matrices

RHO = 2180.0


def _isotropic(n: int, rng: np.random.Generator) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_all_flat_particles_are_perfectly_ordered() -> None:
    normals = np.tile([0.0, 0.0, 1.0], (50, 1))
    order = analysis.order_parameters(analysis.order_tensor(normals))
    assert order.S == pytest.approx(1.0, abs=1e-12)
    assert order.eta == pytest.approx(0.0, abs=1e-12)
    assert order.beta == pytest.approx(0.0, abs=1e-6)
    assert analysis.legendre_order(normals) == pytest.approx(1.0, abs=1e-12)


def test_isotropic_normals_have_no_order() -> None:
    n = 4000
    normals = _isotropic(n, np.random.default_rng(3))
    order = analysis.order_parameters(analysis.order_tensor(normals))
    assert abs(order.S) < 3.0 / np.sqrt(n)
    assert abs(analysis.legendre_order(normals)) < 3.0 / np.sqrt(n)


def test_uniaxial_cone_has_no_biaxiality_and_legendre_order() -> None:
    n = 4000
    rng = np.random.default_rng(4)
    theta = np.radians(30.0)
    phi = rng.uniform(0, 2 * np.pi, n)
    normals = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                        np.full(n, np.cos(theta))], axis=1)
    order = analysis.order_parameters(analysis.order_tensor(normals))
    # P2(cos 30 deg) = (3 * 3/4 - 1) / 2
    assert order.S == pytest.approx(0.625, abs=3.0 / np.sqrt(n))
    assert order.eta == pytest.approx(0.0, abs=3.0 / np.sqrt(n))
    assert np.degrees(order.beta) < 2.0


def test_biaxial_set_of_hand_computed_eigenvalues() -> None:
    # 60 % along z, 40 % along x: <vv> = diag(.4, 0, .6), Q = diag(.1, -.5, .4)
    normals = np.array([[0, 0, 1.0]] * 6 + [[1.0, 0, 0]] * 4)
    order = analysis.order_parameters(analysis.order_tensor(normals))
    assert order.S == pytest.approx(0.4)
    assert order.eta == pytest.approx(0.3)
    assert order.beta == pytest.approx(0.0, abs=1e-9)


def test_volume_weighted_order() -> None:
    normals = np.array([[0, 0, 1.0], [1.0, 0, 0]])
    # weights 3:1 -> (3 * 1 + 1 * (-1/2)) / 4
    assert analysis.legendre_order(normals, np.array([3.0, 1.0])) == pytest.approx(0.625)


def test_surface_areas_of_three_particles() -> None:
    semi_axes = np.array([[1e-6, 0.5e-6, 0.05e-6], [2e-6, 2e-6, 0.1e-6], [0.3e-6, 0.2e-6, 0.01e-6]])
    a_b, a_l, a_t = analysis.surface_areas(semi_axes, RHO)
    assert a_b == pytest.approx(4.91481, rel=1e-5)
    assert a_l == pytest.approx(0.521828, rel=1e-5)
    assert a_t == pytest.approx(4.91481 + 0.521828, rel=1e-5)


def test_basal_area_of_one_disk_is_two_over_rho_h() -> None:
    a_b, _, _ = analysis.surface_areas(np.array([[1e-6, 1e-6, 5e-8]]), RHO)
    assert a_b == pytest.approx(2.0 / (RHO * 1e-7) / 1000.0, rel=1e-12)


def test_porosity_profile_and_zone_porosity() -> None:
    # box 2 x 2, slices of 1: volumes 1 and 2 in slice 0, 3 in slice 1
    z = np.array([0.2, 0.7, 1.5])
    vol = np.array([1.0, 2.0, 3.0])
    edges = np.array([0.0, 1.0, 2.0])
    assert analysis.porosity_profile(z, vol, 2.0, edges) == pytest.approx([0.25, 0.25])
    assert analysis.zone_porosity(z, vol, 2.0, 0.5, 2.0) == pytest.approx(1 - 5.0 / 6.0)


def test_linear_zone_excludes_dense_bottom_and_open_top() -> None:
    profile = np.array([0.30, 0.36, 0.50, 0.51, 0.49, 0.50, 0.52, 0.75, 0.95])
    edges = np.arange(10) * 0.5
    assert analysis.linear_zone(edges, profile, tolerance=0.05) == pytest.approx((1.0, 3.5))


def test_rocking_curve_normalisation() -> None:
    rng = np.random.default_rng(5)
    theta = np.abs(rng.normal(0.0, 0.3, 500)) % (np.pi / 2)
    centres, f_v, i_c = analysis.rocking_curve(theta, rng.uniform(1, 2, 500), 90)
    width = np.pi / 2 / 90
    assert np.sum(f_v) * width == pytest.approx(1.0)
    assert np.sum(i_c * 2 * np.pi * np.sin(centres)) * width == pytest.approx(1.0)


def test_basal_contact_area_of_stacked_disks() -> None:
    a, c, d_cont = 1e-6, 5e-8, 5e-10
    centers = np.array([[2e-6, 2e-6, c], [2e-6, 2e-6, 3 * c + d_cont / 2]])
    rot = rotation_matrices(np.zeros((2, 3)))
    axes = np.array([[a, a, c], [a, a, c]])
    top = np.array([False, True])
    full = analysis.basal_contact_area(centers, rot, axes, 4e-6, d_cont, top, a / 100, RHO)
    assert full == pytest.approx(2.0 / (RHO * 2 * c) / 1000.0, rel=0.01)
    centers[1, 0] += a
    lens = a**2 * (2 * np.pi / 3 - np.sqrt(3) / 2)
    half = analysis.basal_contact_area(centers, rot, axes, 4e-6, d_cont, top, a / 100, RHO)
    assert half == pytest.approx(full * lens / (np.pi * a**2), rel=0.02)
