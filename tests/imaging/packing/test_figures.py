"""The packing figure (imaging.packing.figures) reads: the zone marked at its altitudes,
the measured porosity in the title, the voxel slices over the imaged zone, labelled log
ticks and legends off the data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from imaging.packing.dataset import packing_dataset
from imaging.packing.figures import packing_figure
from tests._figures import check_figure, kept_figures  # noqa: F401
from tests.imaging.packing.test_measures import ZONE, W, _measure, _stack


def test_packing_figure(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    measures = _measure()
    path = packing_figure(packing_dataset(_stack(), measures), measures.image,
                          tmp_path / "packing.png")
    assert path.stat().st_size > 0
    fig = kept_figures[-1]
    assert {"z [um]", "I_c, orientation density [1/sr]", "x [um]", "y [um]"} <= check_figure(fig)
    profiles, _, vertical, horizontal = fig.get_axes()[:4]
    marked = sorted(float(line.get_ydata()[0]) for line in profiles.get_lines()
                    if len(line.get_ydata()) == 2 and line.get_ydata()[0] == line.get_ydata()[1])
    np.testing.assert_allclose(marked, np.array(ZONE) * 1e6, rtol=1e-12)
    assert f"porosity {measures.porosity:.3f}" in profiles.get_title()
    np.testing.assert_allclose(vertical.get_images()[0].get_extent(),
                               [0.0, W * 1e6, ZONE[0] * 1e6, ZONE[1] * 1e6], rtol=1e-9)
    assert horizontal.get_images()[0].get_extent() == pytest.approx([0.0, W * 1e6] * 2)
