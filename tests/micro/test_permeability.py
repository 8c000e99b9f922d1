"""Permeability measurement: homogeneous media return the input permeability."""

from __future__ import annotations

import numpy as np
import pytest

from micro.permeability import FrozenState, axis_permeabilities, measure_permeability, measurement_pattern
from shared.fv import facet_conductance, facet_flux, flow_pattern, steady_pressure
from shared.mesh import WALLS, Mesh, boundary_cell_mask, build_mesh
from shared.solver import SPDSolver
from tests._defaults import clay

K0 = 3e-20  # m2
MATERIAL = clay(intrinsic_permeability_reference=K0, reference_porosity=0.3)


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
    result = axis_permeabilities(FrozenState(mesh, saturated, porosity, 1e6, MATERIAL))
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
    result = axis_permeabilities(FrozenState(mesh, saturated, porosity, 1e6, MATERIAL), method="velocity")
    for axis in ("x", "y", "z"):
        assert result["water"][axis] == pytest.approx(K0, rel=1e-9)


def test_no_free_cell_in_the_inner_region_is_nan_with_a_warning_for_both_methods(caplog) -> None:
    """27 points (the smallest specimen the configuration allows): every cell whose
    centroid lies in the inner 80 % is a wall cell. The velocity method and the tensor,
    which average over that region, are NaN with the same warning (one policy, not an
    error for one and NaN for the other); the wall-flux method, which needs no inner
    region, still returns the input permeability of a uniform medium."""
    import logging

    from micro.permeability import measure_permeability_tensor

    coarse = jittered_mesh(3, seed=0)
    conductance = facet_conductance(coarse, np.ones(coarse.n_cells), np.full(coarse.n_cells, 0.3),
                                    "water", MATERIAL)
    with caplog.at_level(logging.WARNING, logger="micro.permeability"):
        velocity = measure_permeability(coarse, conductance, MATERIAL.water_viscosity, 0,
                                        mean_pressure=-1e6, pressure_drop=1e5, method="velocity")
        tensor = measure_permeability_tensor(coarse, conductance, MATERIAL.water_viscosity,
                                             pressure_drop=1e5)
    assert np.isnan(velocity) and np.all(np.isnan(tensor))
    assert caplog.text.count("no free cell in the inner region") == 2
    wall = measure_permeability(coarse, conductance, MATERIAL.water_viscosity, 0,
                                mean_pressure=-1e6, pressure_drop=1e5)
    assert wall == pytest.approx(K0, rel=0.1)


def test_permeability_partial_saturation_and_porosity(mesh: Mesh) -> None:
    # S = 0.5: k_r = 0.25 for water and gas (n = 2); phi = 0.4: k_M = K0 exp(2 * 0.1).
    water = np.full(mesh.n_cells, 0.5)
    porosity = np.full(mesh.n_cells, 0.4)
    result = axis_permeabilities(FrozenState(mesh, water, porosity, 5e7, MATERIAL), method="velocity")
    expected = K0 * np.exp(0.2) * 0.25
    for phase in ("water", "gas"):
        for axis in ("x", "y", "z"):
            assert result[phase][axis] == pytest.approx(expected, rel=1e-9)


def test_permeability_uses_given_conductances(mesh: Mesh) -> None:
    saturated = np.ones(mesh.n_cells)
    porosity = np.full(mesh.n_cells, 0.3)
    doubled = 2.0 * facet_conductance(mesh, saturated, porosity, "water", MATERIAL)
    result = axis_permeabilities(
        FrozenState(mesh, saturated, porosity, 1e6, MATERIAL, {"water": doubled}), method="velocity",
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


@pytest.mark.parametrize("seed", [2, 3])
def test_permeability_with_near_perfect_cracks_matches_moderate_contrast(seed: int) -> None:
    """Gas-filled cracks 1e15 times the clay's conductance (rings of facets around 25
    edges, none percolating): the rate computed in double precision is unbalanced beyond
    the measurement's tolerance, and the extended-precision refinement returns the
    permeability of the same cracks at a contrast of 1e6, where double precision is
    exact to 1e-10 (the cracked cells are equipotential either way, to 1e-6).
    """
    mesh = jittered_mesh(10, seed)
    rng = np.random.default_rng(seed)
    inlet = boundary_cell_mask(mesh, [WALLS[4]])
    outlet = boundary_cell_mask(mesh, [WALLS[5]]) & ~inlet
    edges = np.sort(mesh.facet_vertices, axis=1)
    internal = np.flatnonzero(~(inlet | outlet)[mesh.facet_cells].any(axis=1))
    ring = np.zeros(mesh.n_facets, dtype=bool)
    for a, b in edges[rng.choice(internal, 25, replace=False)][:, :2]:
        ring |= (edges == a).any(axis=1) & (edges == b).any(axis=1)
    clay = rng.uniform(0.5, 2.0, mesh.n_facets) * 1e-22
    cracked = np.where(ring, clay * 1e15, clay)
    # the plain double-precision solve, as the measurement starts
    low, high = mesh.bounds[:, 2]
    departure = -100.0 / (high - low) * (np.clip(mesh.circumcentres[:, 2], low, high)
                                         - 0.5 * (low + high))
    pattern = flow_pattern(mesh, inlet | outlet)
    pressure = steady_pressure(mesh, pattern, SPDSolver(residual_tolerance=1e-13),
                               cracked, departure, departure)
    flux = facet_flux(mesh, cracked, pressure)
    inside, outside = inlet[mesh.facet_cells], outlet[mesh.facet_cells]
    entering = flux[inside[:, 0] & ~inside[:, 1]].sum() - flux[~inside[:, 0] & inside[:, 1]].sum()
    leaving = flux[~outside[:, 0] & outside[:, 1]].sum() - flux[outside[:, 0] & ~outside[:, 1]].sum()
    assert abs(entering - leaving) > 1e-3 * 0.5 * (entering + leaving)
    k = {contrast: measure_permeability(mesh, np.where(ring, clay * contrast, clay), 1.8e-5, 2,
                                        mean_pressure=-1e3, pressure_drop=100.0,
                                        conductance_floor=1e-30)
         for contrast in (1e6, 1e15)}
    assert k[1e15] == pytest.approx(k[1e6], rel=2e-3)


def test_a_pattern_of_another_axis_is_refused(mesh: Mesh) -> None:
    """The two phases share one pattern per axis; a pattern of the x walls passed for a
    z measurement would impose pressure on the wrong walls: it is refused by name."""
    conductance = facet_conductance(mesh, np.ones(mesh.n_cells), np.full(mesh.n_cells, 0.3),
                                    "water", MATERIAL)
    with pytest.raises(ValueError, match="pattern"):
        measure_permeability(mesh, conductance, MATERIAL.water_viscosity, 2, mean_pressure=-1e6,
                             pressure_drop=1e5, pattern=measurement_pattern(mesh, 0))


def _state() -> tuple[tuple, dict, np.ndarray]:
    """A state where every solve differs (1e4-contrast cracks and a saturation field):
    the arguments, conductances and crack-mouth cells of a checkpoint's measurements."""
    mesh = jittered_mesh(9, seed=4)
    rng = np.random.default_rng(4)
    saturation = rng.uniform(0.4, 0.95, mesh.n_cells)
    porosity = rng.uniform(0.25, 0.4, mesh.n_cells)
    phases = {phase: facet_conductance(mesh, saturation, porosity, phase, MATERIAL)
              * np.where(rng.random(mesh.n_facets) < 0.02, 1e4, 1.0)
              for phase in ("water", "gas")}
    return (mesh, saturation, porosity, 5e7, MATERIAL), phases, rng.random(mesh.n_cells) < 0.05


def _measured(executor=None) -> tuple[dict, np.ndarray]:
    """Axis permeabilities and tensors of :func:`_state`, as a checkpoint measures them."""
    from micro import permeability

    arguments, phases, mouths = _state()
    return permeability.checkpoint_permeabilities(permeability.FrozenState(*arguments, phases),
                                                  sealed=mouths, executor=executor)


def test_a_checkpoints_eight_solves_in_one_gather_are_the_axes_and_the_tensors() -> None:
    """Gathered in one go (the worker receives the mesh once), the eight solves come back
    in the places that the axes' and the tensor's own functions give them."""
    from micro import permeability

    arguments, phases, mouths = _state()
    axes, tensor = _measured()
    state = permeability.FrozenState(*arguments, phases)
    assert axes == permeability.axis_permeabilities(state)
    np.testing.assert_array_equal(
        tensor, permeability.permeability_tensor(state, sealed=mouths))


@pytest.mark.parametrize("amg_unknowns", [1, 10**9])
def test_permeabilities_measured_on_two_threads_equal_the_serial_ones(
    amg_unknowns: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The eight solves of a checkpoint share nothing mutable: run on two threads (both
    solver paths), they return bit for bit what one thread returns."""
    from concurrent.futures import ThreadPoolExecutor

    from micro.permeability import steady

    monkeypatch.setattr(steady, "_MEASUREMENT_AMG_UNKNOWNS", amg_unknowns)
    serial, tensor = _measured()
    with ThreadPoolExecutor(1) as pool:
        threaded, threaded_tensor = _measured(pool)
    assert threaded == serial
    assert len({value for axes in serial.values() for value in axes.values()}) == 6
    np.testing.assert_array_equal(threaded_tensor, tensor)
    assert np.all(np.isfinite(tensor))


def test_permeabilities_measured_with_a_worker_process_equal_the_serial_ones(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The run's measurement executor (a spawned process, forced here for a small mesh
    on two threads) returns bit for bit what this process measures alone."""
    import numba

    from micro import pool

    monkeypatch.setattr(pool, "MEASUREMENT_PROCESS_CELLS", 0)
    monkeypatch.setattr(numba, "get_num_threads", lambda: 2)
    serial, tensor = _measured()
    with pool.measurement_executor(1) as executor:
        assert executor is not None
        shared, shared_tensor = _measured(executor)
    assert shared == serial
    np.testing.assert_array_equal(shared_tensor, tensor)
    # below the size threshold this process measures alone
    monkeypatch.setattr(pool, "MEASUREMENT_PROCESS_CELLS", 2)
    with pool.measurement_executor(1) as executor:
        assert executor is None


def test_the_measurement_worker_logs_here_and_runs_one_blas_thread(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture,
) -> None:
    """A record logged in the spawned worker (a solver's fallback, say) arrives at this
    process's handlers (the case's log file) with the worker's process id; the worker's
    BLAS runs one thread (an idle one would spin on the core the run solves on)."""
    import logging
    import os

    import numba
    import threadpoolctl

    from micro import pool

    monkeypatch.setattr(pool, "MEASUREMENT_PROCESS_CELLS", 0)
    monkeypatch.setattr(numba, "get_num_threads", lambda: 2)
    caplog.set_level(logging.INFO)
    with pool.measurement_executor(1) as executor:
        worker = executor.submit(os.getpid).result()
        executor.submit(logging.getLogger("shared.solver").info, "from %s", "the worker").result()
        libraries = executor.submit(threadpoolctl.threadpool_info).result()
    assert {lib["num_threads"] for lib in libraries if lib["user_api"] == "blas"} == {1}
    records = [r for r in caplog.records if r.getMessage() == "from the worker"]
    assert [r.process for r in records] == [worker]
    assert worker != os.getpid()
