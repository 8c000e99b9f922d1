"""Checks of a rendered figure: labelled log ticks, axis labels, legends off the data."""
from __future__ import annotations

from collections.abc import Iterator

import matplotlib.pyplot as plt
import pytest
from matplotlib.figure import Figure

from shared import figures as shared_figures


@pytest.fixture
def kept_figures(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[Figure]]:
    """The figures that ``shared.figures.save_figure`` writes, kept open for checks."""
    kept: list[Figure] = []
    real_close = plt.close
    monkeypatch.setattr(shared_figures.plt, "close", lambda fig=None: kept.append(fig))
    yield kept
    for fig in kept:
        real_close(fig)


def _labelled(axis: object) -> list[str]:
    low, high = sorted(axis.get_view_interval())  # type: ignore[attr-defined]
    return [label.get_text() for tick in axis.get_major_ticks()  # type: ignore[attr-defined]
            if low * (1 - 1e-9) <= tick.get_loc() <= high * (1 + 1e-9)
            for label in (tick.label1, tick.label2)  # left/bottom or right/top (a twin)
            if label.get_visible() and label.get_text()]


def check_figure(fig: Figure) -> set[str]:
    """Draw ``fig`` and assert that every log axis has >= 3 labelled ticks and that
    every axes legend lies outside its axes (or the legend is the figure's).

    Returns
    -------
    set of str
        The x and y labels of all axes, for the caller's checks.
    """
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    labels: set[str] = set()
    for ax in fig.get_axes():
        labels.update({ax.get_xlabel(), ax.get_ylabel()})
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            if getattr(ax, f"get_{name}scale")() == "log":
                ticks = _labelled(axis)
                shared = getattr(ax, f"get_shared_{name}_axes")().get_siblings(ax)
                if not ticks and len(shared) > 1:
                    continue  # a twin: its sibling labels the shared axis
                assert len(ticks) >= 3, f"{ax.get_title()!r}: {name} log axis labels {ticks}"
                assert not any("e+" in t for t in ticks if name == "x" and "[d]" in ax.get_xlabel())
        legend = ax.get_legend()
        if legend is not None:
            box = legend.get_window_extent(renderer)
            frame = ax.get_window_extent(renderer)
            assert not box.overlaps(frame), f"{ax.get_title()!r}: the legend covers the axes"
    return labels - {""}
