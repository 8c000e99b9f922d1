"""Permeability measurement: homogeneous media return the input permeability."""

from __future__ import annotations

import numpy as np
import pytest

from micro.permeability import measure_permeability, permeability_tensor_axes
from shared.fv import facet_conductance
from shared.materials import ClayParameters
from shared.mesh import Mesh, build_mesh

K0 = 3e-20  # m2
MATERIAL = ClayParameters(intrinsic_permeability_reference=K0, reference_porosity=0.3)


def jittered_mesh(per_side: int, seed: int, edge: float = 7e-3) -> Mesh:
    rng = np.random.default_rng(seed)
    spacing = edge / per_side
    axis = (np.arange(per_side) + 0.5) * spacing
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    return build_mesh(grid + rng.uniform(-0.25, 0.25, grid.shape) * spacing)


@pytest.fixture(scope="module")
def mesh() -> Mesh:
    return jittered_mesh(12, seed=11)


def test_permeability_wall_flux_returns_input_within_two_percent(mesh: Mesh) -> None:
    saturated = np.ones(mesh.n_cells)
    porosity = np.full(mesh.n_cells, 0.3)
    result = permeability_tensor_axes(mesh, saturated, porosity, 1e6, MATERIAL)
    for axis in ("x", "y", "z"):
        assert result["water"][axis] == pytest.approx(K0, rel=0.02)
        assert result["gas"][axis] == 0.0


def test_permeability_velocity_average_is_exact_for_uniform_media(mesh: Mesh) -> None:
    _assert_velocity_method_exact(mesh)


def test_permeability_velocity_average_is_exact_on_random_points() -> None:
    rng = np.random.default_rng(4)
    _assert_velocity_method_exact(build_mesh(rng.uniform(0.0, 7e-3, (1500, 3))))


def _assert_velocity_method_exact(mesh: Mesh) -> None:
    saturated = np.ones(mesh.n_cells)
    porosity = np.full(mesh.n_cells, 0.3)
    result = permeability_tensor_axes(mesh, saturated, porosity, 1e6, MATERIAL, method="velocity")
    for axis in ("x", "y", "z"):
        assert result["water"][axis] == pytest.approx(K0, rel=1e-9)


def test_permeability_partial_saturation_and_porosity(mesh: Mesh) -> None:
    # S = 0.5: k_r = 0.25 for water and gas (n = 2); phi = 0.4: k_M = K0 exp(2 * 0.1).
    water = np.full(mesh.n_cells, 0.5)
    porosity = np.full(mesh.n_cells, 0.4)
    result = permeability_tensor_axes(mesh, water, porosity, 5e7, MATERIAL, method="velocity")
    expected = K0 * np.exp(0.2) * 0.25
    for phase in ("water", "gas"):
        for axis in ("x", "y", "z"):
            assert result[phase][axis] == pytest.approx(expected, rel=1e-9)


def test_permeability_uses_given_conductances(mesh: Mesh) -> None:
    saturated = np.ones(mesh.n_cells)
    porosity = np.full(mesh.n_cells, 0.3)
    doubled = 2.0 * facet_conductance(mesh, saturated, porosity, "water", MATERIAL)
    result = permeability_tensor_axes(
        mesh, saturated, porosity, 1e6, MATERIAL, conductances={"water": doubled},
        method="velocity",
    )
    assert result["water"]["y"] == pytest.approx(2.0 * K0, rel=1e-9)


def test_permeability_of_a_layered_medium_is_anisotropic() -> None:
    # Horizontal layers alternating k and 10 k: along the layers the arithmetic mean
    # 5.5 k, across them the harmonic mean 1.82 k (continuum values; the layer
    # interfaces cross cells, so the discrete values only bracket the trend).
    mesh = jittered_mesh(10, seed=3)
    layer = np.floor(mesh.centroids[:, 2] / 7e-4).astype(int) % 2
    conductance = facet_conductance(
        mesh, np.ones(mesh.n_cells), np.full(mesh.n_cells, 0.3), "water", MATERIAL
    )
    i, j = mesh.facet_cells.T
    factor = np.where(layer == 1, 10.0, 1.0)
    conductance = conductance * 2.0 / (1.0 / factor[i] + 1.0 / factor[j])
    along = measure_permeability(mesh, conductance, 1e-3, 0, mean_pressure=-1e6, pressure_drop=1e5)
    across = measure_permeability(mesh, conductance, 1e-3, 2, mean_pressure=-1e6, pressure_drop=1e5)
    assert 3.0 * K0 < along < 7.0 * K0
    assert 1.2 * K0 < across < 3.0 * K0


def test_permeability_rejects_bad_arguments(mesh: Mesh) -> None:
    conductance = np.ones(mesh.n_facets)
    with pytest.raises(ValueError, match="axis"):
        measure_permeability(mesh, conductance, 1e-3, 3, mean_pressure=0.0, pressure_drop=1.0)
    with pytest.raises(ValueError, match="method"):
        measure_permeability(
            mesh, conductance, 1e-3, 0, mean_pressure=0.0, pressure_drop=1.0,
            method="mean",  # type: ignore[arg-type]
        )
    assert measure_permeability(
        mesh, np.zeros(mesh.n_facets), 1e-3, 0, mean_pressure=0.0, pressure_drop=1.0
    ) == 0.0
