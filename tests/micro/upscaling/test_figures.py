"""The upscaling figure (micro.upscaling.figures) reads: a column per condition, labelled
log ticks, legends off the data, the realizations counted in the titles."""

from __future__ import annotations

from pathlib import Path

from micro.upscaling import upscaling_table
from micro.upscaling.figures import table_figure
from tests._figures import check_figure, kept_figures  # noqa: F401
from tests.micro.upscaling.test_table import RANGE, _micro


def test_table_figure(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    table = upscaling_table({"free": [("a", _micro(1)), ("b", _micro(2))],
                             "confined": [("c", _micro(3))]}, RANGE)
    path = table_figure(table, tmp_path / "table.png")
    assert path.stat().st_size > 0
    fig = kept_figures[-1]
    labels = check_figure(fig)
    assert {"suction [Pa]", "permeability [m2]", "saturation, volumetric strain [-]"} <= labels
    assert len(fig.get_axes()) == 2 * 2
    titles = {ax.get_title() for ax in fig.get_axes()}
    assert {"free pellet (n = 2)", "confined pellet (n = 1)"} <= titles
