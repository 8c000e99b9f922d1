"""Log lines of the imaging scripts: each progress line once, no "nan" REV edge."""
from __future__ import annotations

import logging
import sys
from pathlib import Path
from types import SimpleNamespace

import dask.array as da
import numpy as np
import pytest

from imaging.ct.rev import rev_summary
from imaging.ct.scan import each_slab

SCRIPTS = Path(__file__).resolve().parents[3] / "workflow" / "scripts"


@pytest.fixture
def script_logging(monkeypatch: pytest.MonkeyPatch, tmp_path: Path):
    """Logging configured as a rule's script does (``_logging.setup``); restored after."""
    monkeypatch.syspath_prepend(str(SCRIPTS))
    monkeypatch.setattr(sys, "excepthook", sys.excepthook)
    import _logging

    root = logging.getLogger()
    saved = (root.handlers[:], root.level)
    path = tmp_path / "rule.log"
    _logging.setup(str(path))
    yield path
    for handler in root.handlers:
        if handler not in saved[0]:
            handler.close()
    root.handlers[:] = saved[0]
    root.setLevel(saved[1])


@pytest.mark.parametrize("chunk", [8, 4])
def test_each_progress_line_is_logged_once(script_logging: Path, chunk: int) -> None:
    """A pass over one chunk (its first update is its last) or two logs no line twice
    in the rule's log file."""
    grey = da.zeros((8, 4, 4), chunks=(chunk, 4, 4), dtype=np.uint16)
    list(each_slab(grey, lambda z0, slab: z0, "scan summary", 1))
    for handler in logging.getLogger().handlers:
        handler.flush()
    lines = [line.split(" INFO ", 1)[1] for line in script_logging.read_text().splitlines()
             if "scan summary" in line]
    assert lines and len(lines) == len(set(lines))
    assert lines[-1].startswith("scan summary: 8/8 (100 %)")


def test_an_unconverged_rev_reads_not_reached() -> None:
    nan = float("nan")
    result = SimpleNamespace(porosity_total=0.084, w_rev_porosity_centred=nan,
                             w_rev_porosity=nan, w_rev_interface_centred=nan,
                             w_rev_interface=2.0e-3)
    calibrated = SimpleNamespace(porosity_total=0.28, w_rev_porosity_centred=6.8e-3,
                                 w_rev_porosity=4.0e-3)
    line = rev_summary("pellet", result, calibrated, 0.16, 1.52)
    assert "nan" not in line.lower()
    assert "binary porosity 0.0840: not reached / not reached" in line
    assert "interface: not reached / 0.002 m" in line
    assert "0.0068 m / 0.004 m" in line
