"""Figure output shared by the stages: headless backend and atomic PNG writes."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from shared.io import atomic_write  # noqa: E402

__all__ = ["new_figure", "save_figure"]


def new_figure(n_rows: int, n_cols: int, width: float = 4.0, height: float = 3.4) -> tuple[Figure, object]:
    """A figure with a grid of axes, each ``width`` x ``height`` inches."""
    return plt.subplots(
        n_rows, n_cols, figsize=(width * n_cols, height * n_rows), squeeze=False, layout="constrained"
    )


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Write a figure as PNG through a temporary file and a rename, then close it."""
    try:
        return atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"))
    finally:
        plt.close(fig)
