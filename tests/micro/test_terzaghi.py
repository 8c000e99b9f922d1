"""Terzaghi consolidation of the coupled DEM + flow solver (docs/design.md §5.1, docs/yade.md §9).

An oedometric column of DEM points on a jittered face-centred cubic lattice, rigid
walls on the sides and the bottom, a uniform load on the top layer whose cells are
drained (p = 0), brought to equilibrium dry under F_0 (1 MPa), then loaded to 1.2 F_0.
M_oed (drained increment, DEM only) and k (steady Darcy flow) are measured, not fitted;
Cv = k M / mu, Tv = Cv t / H_d^2. The permeability sets the consolidation time to
``scale_ratio`` times the compression wave time, so that inertia barely delays U. U(t)
from the settlement and from the mean excess pore pressure is compared with the series
U(Tv) = 1 - sum_k 2 / M_k^2 exp(-M_k^2 Tv), M_k = pi (2k + 1) / 2; the fluid leaving
the free cells must equal their volume loss. Set-up, parameters and measured errors:
docs/validation.md, "tests.micro.test_terzaghi".
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import pytest

from micro.forces import SectorWeights, hydromechanical_forces
from micro.permeability import measure_permeability
from shared.dem import (
    DEMState,
    Walls,
    new_state,
    stable_time_step,
    step,
    unbalanced_force,
    walls_around,
)
from shared.mesh import build_mesh, mesh_from_tetrahedra
from tests._defaults import DEM, dem

from .terzaghi_setup import coupled_steps, drained_cells, saturated_flow, volume_gradient

NEIGHBOUR_DISTANCE = 1e-3  # m
PRELOAD = 1e6  # Pa on the top face of the lattice
LOAD_STEP = 0.2  # dF / F_0: small, so the Hertz tangent modulus changes little
VISCOSITY = 1e-3  # Pa s
RELAXED = dem(damping=0.4, bond_tensile_strength=0.0)  # dry equilibration
UNDAMPED = dem(damping=0.0, bond_tensile_strength=0.0)  # consolidation: the Darcy drag is the damping


def terzaghi_degree(time_factor: float, terms: int = 200) -> float:
    """Degree of consolidation U(Tv) of the analytic series [1]."""
    m = np.pi * (2 * np.arange(terms) + 1) / 2
    return float(1.0 - np.sum(2.0 / m**2 * np.exp(-(m**2) * time_factor)))


def fcc_column(
    per_side: int, layers: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Jittered FCC column: positions [m], radii [m] and grid layer index per point."""
    spacing = NEIGHBOUR_DISTANCE / np.sqrt(2.0)
    grid = np.stack(
        np.meshgrid(np.arange(per_side), np.arange(per_side), np.arange(layers), indexing="ij"),
        axis=-1,
    ).reshape(-1, 3)
    grid = grid[grid.sum(axis=1) % 2 == 0]
    positions = (grid + rng.uniform(-0.005, 0.005, grid.shape)) * spacing
    radii = np.full(grid.shape[0], 0.5 * 1.005 * NEIGHBOUR_DISTANCE)
    return positions, radii, grid[:, 2]


def relax(state: DEMState, walls: Walls, load: np.ndarray, tolerance: float = 1e-4) -> None:
    """Damped dry DEM steps until the unbalanced force ratio is below ``tolerance``."""
    for _ in range(200):
        time_step = stable_time_step(state, RELAXED, walls)
        for _ in range(200):
            report = step(state, time_step, RELAXED, load, walls)
        if unbalanced_force(report.forces, report.normal_forces) < tolerance:
            return
    raise AssertionError("the dry column did not reach equilibrium")


@dataclass
class Consolidation:
    """Measured parameters and the degree of consolidation at the requested times."""

    modulus: float  # M_oed [Pa]
    permeability: float  # measured k [m2]
    input_permeability: float  # k of the conductances [m2]
    coefficient: float  # Cv [m2/s]
    time_factors: np.ndarray  # Tv reached [1]
    settlement_degree: np.ndarray  # U from settlement [1]
    pressure_degree: np.ndarray  # U from the mean excess pressure [1]
    outflow: float  # fluid volume into the drained cells [m3]
    pore_volume_loss: float  # volume lost by the free cells [m3]


def consolidate(
    per_side: int, layers: int, scale_ratio: float, time_factors: list[float]
) -> Consolidation:
    """Preload, measure M and k, step the load and record U at the given Tv."""
    positions, radii, layer = fcc_column(per_side, layers, np.random.default_rng(20221121))
    # load on the top layer; heights between the bottom layer and the layer below the
    # top, i.e. of the free (consolidating) cells, without the drained layer
    top, gauge, bottom = layer == layers - 1, layer == layers - 2, layer == 0
    state = new_state(positions, radii, RELAXED)
    walls = walls_around(positions, radii, servo=False)
    walls.active[5] = False  # the load acts on the top points directly

    def load(force: float) -> np.ndarray:
        forces = np.zeros_like(positions)
        forces[top, 2] = -force / top.sum()
        return forces

    def height(assembly: DEMState) -> float:
        return float(assembly.positions[gauge, 2].mean() - assembly.positions[bottom, 2].mean())

    preload = PRELOAD * float(np.ptp(positions[:, 0]) + 2 * radii[0]) ** 2
    relax(state, walls, load(preload))
    drained = copy.deepcopy(state)
    relax(drained, walls, load(preload * (1 + LOAD_STEP)))
    initial_height = height(state)
    final_settlement = initial_height - height(drained)

    time_step = stable_time_step(state, UNDAMPED, walls)
    mesh = build_mesh(state.positions)
    area = mesh.volumes.sum() / np.ptp(mesh.points[:, 2])
    stress_step = LOAD_STEP * preload / area
    modulus = stress_step / (final_settlement / initial_height)
    density = state.masses.sum() / mesh.volumes.sum()
    drained = drained_cells(mesh, top)  # as saturated_flow marks them: the cells on the drain
    drained_height = np.average(mesh.centroids[drained, 2], weights=mesh.volumes[drained])
    drainage_length = drained_height - mesh.bounds[0, 2]
    input_permeability = drainage_length * VISCOSITY / (scale_ratio * np.sqrt(modulus * density))

    flow = saturated_flow(state, top, input_permeability, VISCOSITY, time_step)
    permeability = measure_permeability(
        flow.mesh, flow.conductance, VISCOSITY, 2, mean_pressure=0.0, pressure_drop=stress_step
    )
    coefficient = permeability * modulus / VISCOSITY
    consolidation_time = drainage_length**2 / coefficient
    start_volume = flow.free_volume()
    loaded = load(preload * (1 + LOAD_STEP))
    reached, settlement_degree, pressure_degree = [], [], []
    for time_factor in time_factors:
        n_steps = int(round((time_factor * consolidation_time - flow.time) / time_step))
        coupled_steps(state, flow, n_steps, UNDAMPED, walls, loaded)
        reached.append(flow.time / consolidation_time)
        settlement_degree.append((initial_height - height(state)) / final_settlement)
        pressure_degree.append(1.0 - flow.mean_excess_pressure() / stress_step)
    return Consolidation(
        modulus=modulus,
        permeability=permeability,
        input_permeability=input_permeability,
        coefficient=coefficient,
        time_factors=np.array(reached),
        settlement_degree=np.array(settlement_degree),
        pressure_degree=np.array(pressure_degree),
        outflow=flow.drained_volume,
        pore_volume_loss=start_volume - flow.free_volume(),
    )


def test_terzaghi_series_hand_values() -> None:
    # U = 2 sqrt(Tv / pi) while Tv < ~0.2, and 1 - 8/pi^2 exp(-pi^2 Tv / 4) later
    assert terzaghi_degree(0.05) == pytest.approx(2 * np.sqrt(0.05 / np.pi), rel=1e-6)
    assert terzaghi_degree(1.0) == pytest.approx(1 - 8 / np.pi**2 * np.exp(-np.pi**2 / 4))


def test_volume_gradient_matches_volume_change(rng: np.random.Generator) -> None:
    mesh = build_mesh(rng.uniform(0.0, 1e-3, (60, 3)))
    move = rng.normal(0.0, 1e-9, mesh.points.shape)
    moved = mesh_from_tetrahedra(
        mesh.points + move, mesh.tetrahedra, mesh.neighbours, reorient=False
    )
    predicted = volume_gradient(mesh.points, mesh.tetrahedra) @ move.ravel()
    np.testing.assert_allclose(
        predicted, moved.volumes - mesh.volumes, rtol=1e-6, atol=1e-4 * np.abs(predicted).max()
    )


@pytest.mark.parametrize("enclosed", [False, True])
def test_fluid_force_is_hydromechanical_force_with_equal_shares(
    rng: np.random.Generator, enclosed: bool
) -> None:
    positions = rng.uniform(0.0, 1e-3, (80, 3))
    radii = rng.uniform(0.5e-4, 1e-4, 80)
    state = new_state(positions, radii, DEM)
    flow = saturated_flow(state, positions[:, 2] > 0.9e-3, 1e-15, 1e-3, 1e-8, enclosed=enclosed)
    mesh = flow.mesh
    pressure = rng.normal(0.0, 1e5, mesh.n_cells)
    thirds = SectorWeights(
        facets=np.full((mesh.n_facets, 3), 1 / 3),
        boundary=np.full((mesh.boundary_cells.shape[0], 3), 1 / 3),
    )
    # enclosed: the fluid beyond the hull has the pressure of the cell inside it
    exterior = pressure[mesh.boundary_cells] if enclosed else 0.0
    expected = hydromechanical_forces(
        mesh, positions, radii, pressure, np.ones(mesh.n_cells), exterior, thirds
    )
    forces = (flow.gradient.T @ pressure).reshape(-1, 3)
    np.testing.assert_allclose(forces, expected, atol=1e-12 * np.abs(expected).max())
    # enclosed: a point moving anywhere leaves the total fluid volume unchanged
    total_change = np.abs(np.asarray(flow.gradient.sum(axis=0))).max()
    assert (total_change < 1e-12 * np.abs(flow.gradient).max()) == enclosed


def test_terzaghi_short_column() -> None:
    """5 x 5 x 30 grid (375 points), ratio 20: U at Tv = 0.2 within 10 %."""
    result = consolidate(per_side=5, layers=30, scale_ratio=20.0, time_factors=[0.2])
    assert result.permeability == pytest.approx(result.input_permeability, rel=0.05)
    expected = terzaghi_degree(float(result.time_factors[0]))
    assert result.settlement_degree[0] == pytest.approx(expected, rel=0.10)
    assert result.outflow == pytest.approx(result.pore_volume_loss, rel=1e-9)


@pytest.mark.slow
def test_terzaghi_column_against_series() -> None:
    """5 x 5 x 40 grid (500 points), ratio 30: U at Tv = 0.05, 0.2, 0.5 within 5 %."""
    result = consolidate(
        per_side=5, layers=40, scale_ratio=30.0, time_factors=[0.05, 0.2, 0.5]
    )
    assert result.permeability == pytest.approx(result.input_permeability, rel=0.05)
    expected = np.array([terzaghi_degree(float(tv)) for tv in result.time_factors])
    np.testing.assert_allclose(result.settlement_degree, expected, rtol=0.05)
    np.testing.assert_allclose(result.pressure_degree, expected, rtol=0.05)
    assert result.outflow == pytest.approx(result.pore_volume_loss, rel=1e-9)
