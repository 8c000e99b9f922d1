"""The pellet packing: count from the packing fraction, radii of a size distribution."""

from __future__ import annotations

import numpy as np

from macro.packing import pack_cylinder, pellet_count


def test_size_distribution_fills_the_target_fraction():
    """Radii uniform within +-30 %: all inside the bounds, the count from the analytic mean
    volume r^3 (1 + spread^2) gives the target packing fraction within sampling error
    (about 1/sqrt(n) of the volume), the overlaps relaxed."""
    height, radius, r, fraction, spread = 0.05, 0.015, 3e-3, 0.45, 0.3
    packing = pack_cylinder(height, radius, r, fraction, np.random.default_rng(4), 1500, spread)
    n = packing.radii.size
    assert n == pellet_count(height, radius, r, fraction, spread)
    assert packing.radii.min() >= 0.7 * r and packing.radii.max() <= 1.3 * r
    assert packing.radii.std() > 0.1 * r
    assert abs(packing.packing_fraction - fraction) < 3.0 * fraction / np.sqrt(n)
    assert packing.largest_overlap < 1e-2 * r
    inside = np.hypot(packing.positions[:, 0], packing.positions[:, 1]) + packing.radii
    assert inside.max() <= radius * (1 + 1e-3)
