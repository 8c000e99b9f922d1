"""Log axes that read (shared.figures.log_ticks): at least three labelled ticks, and not
a crowd of them, whatever the range."""

from __future__ import annotations

import matplotlib.pyplot as plt
import pytest

from shared.figures import log_ticks  # sets the Agg backend


@pytest.mark.parametrize(
    ("low", "high", "fewest", "most"),
    [
        (1e-22, 1e-17, 3, 7),  # decades
        (2.3e-21, 1.2e-20, 3, 5),  # under a decade: 1, 2, 3 and 5 per decade
        (1.0, 3.0, 3, 5),  # 1, 2, 3
        (4.1, 4.9, 3, 3),  # narrow: widened to three integer multiples
    ],
)
def test_a_log_axis_has_three_to_a_few_labelled_ticks(low, high, fewest, most):
    fig, ax = plt.subplots()
    ax.plot([0, 1], [low, high])
    ax.set_yscale("log")
    ax.set_ylim(low, high)
    log_ticks(fig)
    fig.canvas.draw()
    bottom, top = ax.get_ylim()
    labels = [t.get_text() for t in ax.get_yticklabels()
              if t.get_text() and bottom * (1 - 1e-9) <= t.get_position()[1] <= top * (1 + 1e-9)]
    plt.close(fig)
    assert fewest <= len(labels) <= most, labels
