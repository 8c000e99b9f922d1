"""Figure output shared by the stages: headless backend and atomic PNG writes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.axis import Axis  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.legend import Legend  # noqa: E402
from matplotlib.ticker import (  # noqa: E402
    FuncFormatter,
    LogFormatterSciNotation,
    LogLocator,
    NullFormatter,
)

from shared.io import atomic_write  # noqa: E402

__all__ = ["new_figure", "save_figure", "log_ticks", "outside_legend", "plain_number"]


def new_figure(n_rows: int, n_cols: int, width: float = 4.0, height: float = 3.4) -> tuple[Figure, np.ndarray]:
    """A figure with a grid of axes, each ``width`` x ``height`` inches (an (n_rows,
    n_cols) array of :class:`~matplotlib.axes.Axes`)."""
    return plt.subplots(
        n_rows, n_cols, figsize=(width * n_cols, height * n_rows), squeeze=False, layout="constrained"
    )


def plain_number(value: float) -> str:
    """A tick or label value without exponent for 1e-3..1e6 (``210``, ``1.5``, ``0.02``),
    scientific notation outside."""
    if value == 0 or not np.isfinite(value):
        return f"{value:g}"
    if 1e-3 <= abs(value) < 1e6:
        digits = max(0, 2 - int(np.floor(np.log10(abs(value)))))
        return f"{value:.{digits}f}".rstrip("0").rstrip(".") if digits else f"{value:.0f}"
    return f"{value:.2g}"


def _log_axis(axis: Axis, low: float, high: float) -> None:
    """At least three labelled major ticks: at the decades when three are in view, else
    at 1, 2 and 5 (then 1, 2, 3 and 5) per decade when that gives three, else at every
    integer multiple (and
    a narrow view widened to three of them); minor tick labels off. Labels are plain
    numbers between 1e-3 and 1e6 (``0.05``, ``210``), scientific beyond; a custom
    formatter (e.g. plain days) is kept."""
    low, high = sorted((abs(low), abs(high)))
    if not (low > 0 and np.isfinite(high)):
        return
    first, last = int(np.floor(np.log10(low))) - 1, int(np.ceil(np.log10(high))) + 1

    def ticks(subs: tuple[float, ...]) -> np.ndarray:
        return np.array([k * 10.0**e for e in range(first, last + 1) for k in subs])

    def in_view(values: np.ndarray) -> int:
        return int(np.count_nonzero((values >= low * (1 - 1e-12)) & (values <= high * (1 + 1e-12))))

    every = tuple(float(k) for k in range(1, 10))
    subs = next((c for c in ((1.0,), (1.0, 2.0, 5.0), (1.0, 2.0, 3.0, 5.0)) if in_view(ticks(c)) >= 3), every)
    if in_view(ticks(every)) < 3:
        # a narrow range: widen the view to three neighbouring integer multiples
        candidates = ticks(every)
        below = candidates[candidates <= low * (1 + 1e-12)].max()
        above = np.sort(candidates[candidates >= high * (1 - 1e-12)])
        inside = candidates[(candidates >= below) & (candidates <= above[0])]
        top = above[0] if inside.size >= 3 else above[1]
        limits = (below, top)
        if axis is axis.axes.xaxis:
            axis.axes.set_xlim(*(limits[::-1] if axis.axes.xaxis_inverted() else limits))
        else:
            axis.axes.set_ylim(*(limits[::-1] if axis.axes.yaxis_inverted() else limits))
    axis.set_major_locator(LogLocator(base=10.0, subs=subs, numticks=60))
    if not isinstance(axis.get_major_formatter(), FuncFormatter):
        if low >= 1e-3 and high < 1e6:
            axis.set_major_formatter(FuncFormatter(lambda value, _: plain_number(value)))
        else:
            axis.set_major_formatter(LogFormatterSciNotation(
                labelOnlyBase=False, minor_thresholds=(np.inf, np.inf)))  # every major tick labelled
    axis.set_minor_formatter(NullFormatter())


def log_ticks(fig: Figure) -> Figure:
    """Give every log axis of ``fig`` at least three labelled ticks (see
    :func:`_log_axis`); :func:`save_figure` calls it.

    Parameters
    ----------
    fig
        A figure whose data are plotted (the view limits are final).

    Returns
    -------
    Figure
        ``fig``.
    """
    for ax in fig.get_axes():
        if ax.get_xscale() == "log":
            _log_axis(ax.xaxis, *ax.get_xlim())
        if ax.get_yscale() == "log":
            _log_axis(ax.yaxis, *ax.get_ylim())
    return fig


def outside_legend(ax: Axes, **kwargs: Any) -> Legend:
    """A legend to the right of ``ax``, outside the data (constrained layout makes room).

    Parameters
    ----------
    ax
        Axes whose labelled artists the legend lists.
    **kwargs
        Passed to :meth:`matplotlib.axes.Axes.legend` (e.g. ``ncol``).

    Returns
    -------
    Legend
        The legend.
    """
    options: dict[str, Any] = {"loc": "upper left", "bbox_to_anchor": (1.02, 1.0),
                                  "borderaxespad": 0.0, "fontsize": "x-small"}
    options.update(kwargs)
    return ax.legend(**options)


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Write a figure as PNG through a temporary file and a rename, then close it
    (log axes get their labelled ticks first, :func:`log_ticks`)."""
    log_ticks(fig)
    try:
        return atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"))
    finally:
        plt.close(fig)
