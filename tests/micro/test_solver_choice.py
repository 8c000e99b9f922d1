"""A micro run gives the same checkpoints whichever preconditioner solves its flow.

The factor (CHOLMOD) and multigrid (pyamg) paths of :class:`shared.solver.SPDSolver`
stop on the same row-wise backward error (1e-8). What that tolerance lets through the
coupled loop (flow, swelling, a DEM relaxation balanced to an unbalanced-force ratio,
remesh decisions) is measured here independently: runs with the factor path whose
every solution is perturbed by a random error that the criterion accepts. The multigrid
run must stay within that envelope.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import micro.run as micro_run
from shared.config import validate_config
from shared.solver import SPDSolver

from .porosity_grid import write_porosity_grid

CHECKPOINTS = [132.0e6, 40.0e6, 10.0e6, 1.0e6]
NAMES = ("eps_v", "saturation", "porosity_mean")


def _perturbing_solve(seed: int):
    """SPDSolver.solve with an error that the criterion accepts added to x: the
    solution of A e = r for a random residual r of at most half the tolerance,
    |r_i| <= tol |a_ii| ||y||_inf / 2 (y = offset + x). Such an error is what an
    iterative solve leaves: A^-1 amplifies r's smooth part, so e is smooth and far
    larger than r (white noise of the same residual, added to x directly, is not: its
    envelope missed the multigrid run's difference 6 times over on one CPU)."""
    solve = SPDSolver.solve
    rng = np.random.default_rng(seed)

    def perturbed(self, lower, rhs, **options):
        x = solve(self, lower, rhs, **options)
        offset = options.get("offset")
        whole = x if offset is None else offset + x
        scale = 0.5 * self.residual_tolerance * np.abs(lower.diagonal()) * np.abs(whole).max()
        return x + solve(self, lower, scale * rng.uniform(-1.0, 1.0, x.size))

    return perturbed


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Four runs of a 512-point CT case (5 mm) through four checkpoints: factor, multigrid
    and two perturbed factor runs. The case figure is skipped (``test_figures.py``
    checks it)."""
    tmp = tmp_path_factory.mktemp("solver_choice")
    path = write_porosity_grid(tmp / "porosity.nc", 5e-4)
    datasets = {}
    with pytest.MonkeyPatch.context() as patch, pytest.MonkeyPatch.context() as quiet:
        quiet.setattr(micro_run.figures, "case_figure", lambda ds, case, path: path)
        for label, solver, seed in (("direct", "direct", None), ("amg", "amg", None),
                                    ("perturbed 1", "direct", 1), ("perturbed 2", "direct", 2)):
            if seed is not None:
                patch.setattr(SPDSolver, "solve", _perturbing_solve(seed))
            config = validate_config({
                "samples": {"p": {"source": "phantom", "voxel_size_m": 3e-4}},
                "micro": {"sample": "p", "specimen_size_m": 5e-3, "n_points": 512,
                          "checkpoints_suction_pa": CHECKPOINTS,
                          "numerics": {"solver": solver}, "cases": {"c": {"porosity": "ct"}}},
                "upscaling": {"conditions": {"free": "c", "confined": "c"}},
            })
            output = tmp / f"{label}.nc"
            micro_run.run(config, "c", path, micro_run.CaseOutputs(output, tmp / f"{label}.png"))
            patch.undo()
            with xr.open_dataset(output) as ds:
                datasets[label] = ds.load()
    return datasets


def test_the_checkpoints_do_not_depend_on_the_preconditioner(runs) -> None:
    direct, amg = runs["direct"], runs["amg"]
    for ds in runs.values():
        assert ds.sizes["suction"] == len(CHECKPOINTS) and np.all(ds["balanced"] == 1)
    envelope = {name: max(float(np.abs(runs[p][name] - direct[name]).max())
                          for p in ("perturbed 1", "perturbed 2")) for name in NAMES}
    # the envelope is real (the coupled loop does feel solve errors of 1e-8) and small
    assert 1e-6 < envelope["eps_v"] < 0.02
    for name in NAMES:
        assert float(np.abs(amg[name] - direct[name]).max()) <= 2.0 * envelope[name], name
    # the permeabilities span decades: the same envelope in log
    log_direct = np.log10(direct["permeability"])
    spread = max(float(np.abs(np.log10(runs[p]["permeability"]) - log_direct).max())
                 for p in ("perturbed 1", "perturbed 2"))
    assert float(np.abs(np.log10(amg["permeability"]) - log_direct).max()) <= 2.0 * spread
