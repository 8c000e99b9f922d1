"""Cube specimens of DEM points: jittered cubic grid or random sequential addition."""

from __future__ import annotations

from typing import Literal

import numpy as np
import numpy.typing as npt

from shared.dem.contacts import detect_contacts

__all__ = ["cube_points"]

FloatArray = npt.NDArray[np.float64]


def cube_points(
    n_points: int,
    rng: np.random.Generator,
    edge_length: float = 7e-3,
    kind: Literal["grid", "random"] = "grid",
    jitter: float = 0.1,
    radius_factor: float = 1.0,
    min_separation: float = 0.7,
) -> tuple[FloatArray, FloatArray]:
    """Points filling the cube [0, edge_length]^3 and their interaction radii.

    Parameters
    ----------
    n_points
        Requested number of points; the grid returns round(n^(1/3))^3 of them, the
        random packing exactly ``n_points``.
    rng
        Seeded generator; the only source of randomness.
    edge_length
        Cube edge L [m] (Caulk 2022 Sec. 3.5: 7 mm).
    kind
        "grid": cubic grid of spacing h = L / m, nodes at cell centres, each moved
        uniformly within +-jitter h / 2 per axis. "random": random sequential
        addition of uniform points at least ``min_separation`` h apart,
        h = L / n^(1/3).
    jitter
        Grid perturbation amplitude as a fraction of h [1], in [0, 1).
    radius_factor
        Interaction radius r = radius_factor h / 2 [1]; 1 makes grid neighbours touch.
    min_separation
        Smallest centre distance of the random packing, fraction of h [1]
        (random sequential addition jams near 0.9).

    Returns
    -------
    positions : ndarray, shape (n, 3)
        Point centres [m].
    radii : ndarray, shape (n,)
        Interaction radii [m], all equal.
    """
    if n_points < 1 or not edge_length > 0.0 or not radius_factor > 0.0:
        raise ValueError("need n_points >= 1, edge_length > 0 and radius_factor > 0")
    if kind == "grid":
        if not 0.0 <= jitter < 1.0:
            raise ValueError("jitter must lie in [0, 1)")
        per_side = max(1, int(round(n_points ** (1.0 / 3.0))))
        spacing = edge_length / per_side
        centres = (np.arange(per_side) + 0.5) * spacing
        positions = np.stack(np.meshgrid(centres, centres, centres, indexing="ij"), -1)
        positions = positions.reshape(-1, 3)
        positions += rng.uniform(-0.5, 0.5, positions.shape) * jitter * spacing
    elif kind == "random":
        spacing = edge_length / n_points ** (1.0 / 3.0)
        positions = _random_sequential_addition(
            n_points, rng, edge_length, min_separation * spacing
        )
    else:
        raise ValueError(f"kind must be 'grid' or 'random', got {kind!r}")
    radii = np.full(positions.shape[0], 0.5 * radius_factor * spacing)
    return positions, radii


def _random_sequential_addition(
    n_points: int, rng: np.random.Generator, edge_length: float, separation: float
) -> FloatArray:
    """Uniform points in the cube, no two closer than ``separation``.

    Candidates come in batches; a batch drops its points that come too close to an
    accepted point or to an earlier point of the same batch, so the result depends on
    the seed only.
    """
    accepted: FloatArray = np.empty((0, 3))
    half = np.full(1, 0.5 * separation)
    for _ in range(10_000):
        missing = n_points - accepted.shape[0]
        if missing == 0:
            return accepted
        batch = rng.uniform(0.0, edge_length, (max(missing, 64), 3))
        cloud = np.vstack((accepted, batch))
        pairs = detect_contacts(cloud, np.repeat(half, cloud.shape[0]), 1.0, 0.0)
        later = np.maximum(pairs[:, 0], pairs[:, 1])
        rejected = np.zeros(cloud.shape[0], dtype=np.bool_)
        rejected[later] = True
        keep = ~rejected[accepted.shape[0]:]
        accepted = np.vstack((accepted, batch[keep][:missing]))
    raise RuntimeError("random sequential addition did not converge; lower min_separation")
