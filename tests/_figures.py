"""Checks of a rendered figure: a title naming what it shows, labelled log ticks, axis
labels and colorbars with units, integer ticks on counts, no empty panel, legends off the
data that say each line once."""
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


def _is_colorbar(ax: object) -> bool:
    return getattr(ax, "_colorbar", None) is not None


def _check_units_and_counts(ax: object) -> None:
    """Every axis label names a unit in brackets, but a count ("number of ..."), which
    has integer ticks only."""
    for name in ("x", "y"):
        label = getattr(ax, f"get_{name}label")()
        if not label:
            continue
        if not label.startswith("number of"):
            assert "[" in label and "]" in label, f"{ax.get_title()!r}: {name} label {label!r} has no unit"
        else:
            low, high = sorted(getattr(ax, f"get_{name}lim")())
            ticks = [v for v in getattr(ax, f"get_{name}ticks")() if low <= v <= high]
            assert all(float(v).is_integer() for v in ticks), f"{label!r}: ticks {ticks}"


def check_figure(fig: Figure) -> set[str]:
    """Draw ``fig`` and assert that it has a title (``suptitle``: what it shows, its
    case); that every log axis has >= 3 labelled ticks; that every axis label and
    colorbar names its unit and counts ("number of ...") sit on integer ticks; that no
    panel with its frame on is empty (an empty one is switched off, ``ax.axis("off")``);
    and that every legend lies outside its axes (or is the figure's) and names each line
    once.

    Returns
    -------
    set of str
        The x and y labels of all axes, for the caller's checks.
    """
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    title = fig._suptitle.get_text() if fig._suptitle is not None else ""  # type: ignore[attr-defined]
    assert title, "the figure has no title naming what it shows"
    labels: set[str] = set()
    for ax in fig.get_axes():
        if _is_colorbar(ax):
            label = ax._colorbar.ax.get_ylabel() or ax._colorbar.ax.get_xlabel()  # type: ignore[attr-defined]
            assert label and "[" in label, f"a colorbar without a label with units: {label!r}"
            continue
        if not ax.axison:
            continue
        assert ax.has_data(), f"{ax.get_title()!r}: an empty panel (switch it off)"
        _check_units_and_counts(ax)
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
    for legend in [ax.get_legend() for ax in fig.get_axes() if ax.get_legend()] + list(fig.legends):
        texts = [text.get_text() for text in legend.get_texts()]
        assert len(texts) == len(set(texts)), f"a legend repeats a line: {texts}"
    return labels - {""}
