"""Benchmark case of the sequential deposition (Ferrage et al. 2015, Table II series 2).

Monodisperse disks of aspect ratio 0.1 in a box of 7.5 equivalent diameters, theta_ini
random, A_swiv = 80 deg, A_slide = 5 d, 3 x 800 attempts. The issue's target is the full
Table II run (2500 disks) in 10 min or less on 2 cores, with a cost per particle that does
not grow with the bed.
"""

from __future__ import annotations

import time

import numpy as np

from imaging.deposition import DepositionParameters, Population, deposit, sample_semi_axes
from imaging.deposition.analysis import legendre_order

DIAMETER = 1.0e-6


def _parameters(attempts_per_cycle: int = 800) -> DepositionParameters:
    return DepositionParameters(
        box_width=7.5 * DIAMETER, contact_distance=5e-4 * DIAMETER, theta_max=np.pi / 2,
        theta_random=True, slide_amplitude=5 * DIAMETER, swivel_amplitude=np.radians(80),
        rotation_amplitude=np.radians(80), attempts_per_cycle=attempts_per_cycle,
        log_interval=60.0)


def bench_deposition(n_particles: int = 500) -> dict:
    """Deposit ``n_particles`` Table II disks; report particles/s and the cost per particle
    over successive tenths of the bed.

    Returns
    -------
    dict
        ``particles_per_second``, ``total_s``, ``cost_per_particle_s`` (mean wall time per
        particle in each tenth of the deposition order), ``cost_growth`` (last tenth over
        second tenth; the first tenth lands on the floor, which is cheaper),
        ``projected_table2_s`` (2500 particles at the measured late cost), bed height and
        order parameter.
    """
    population = Population(basal_surface_median=np.pi / 4 * DIAMETER**2, aspect_ratio_median=0.1)
    warm = np.random.default_rng(1)
    deposit(sample_semi_axes(population, 3, warm), _parameters(10), warm)
    rng = np.random.default_rng(0)
    semi_axes = sample_semi_axes(population, n_particles, rng)
    start = time.perf_counter()
    packing = deposit(semi_axes, _parameters(), rng)
    total = time.perf_counter() - start
    tenths = np.array_split(packing.wall_time, 10)
    cost = [float(np.mean(t)) for t in tenths if t.size]
    return {
        "n_particles": n_particles,
        "total_s": total,
        "particles_per_second": n_particles / total,
        "cost_per_particle_s": cost,
        "cost_growth": cost[-1] / cost[1] if len(cost) > 2 else float("nan"),
        "projected_table2_s": 2500 * cost[-1],
        "accepted_moves_mean": float(packing.accepted_moves.mean()),
        "bed_height_diameters": float(packing.centers[:, 2].max() / DIAMETER),
        "S_part": legendre_order(packing.normals),
    }
