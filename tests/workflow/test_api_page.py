"""docs/api.md: its Python blocks run as they stand, in order, in one namespace (those
marked ``python skip`` are sketches of code that needs files); the values they print are
checked against what the page claims of them."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from shared.config import default_config

PAGE = Path(__file__).resolve().parents[2] / "docs" / "api.md"


def _blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```$", text, flags=re.MULTILINE | re.DOTALL)


def test_the_api_page_runs_without_files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a file written anywhere would land here
    namespace: dict = {}
    blocks = _blocks(PAGE.read_text(encoding="utf-8"))
    assert len(blocks) == 6
    for block in blocks:
        exec(compile(block, str(PAGE), "exec"), namespace)  # noqa: S102
    assert not any(tmp_path.iterdir())
    grid, rev, bed, table = (namespace[name] for name in ("grid", "rev", "bed", "table"))
    # a porosity inside the calibration's bounds, the REV's on the same voxels
    low, high = grid["porosity"].attrs["valid_min"], grid["porosity"].attrs["valid_max"]
    assert low <= grid.attrs["porosity_mean"] <= high
    assert 0 < float(rev["porosity_total"]) < 1
    assert 0 < float(bed["porosity"]) < 1 and bed.sizes["particle"] == 25
    # the free condition's k: the geometric mean of its two results
    members = [namespace["micro_result"](seed) for seed in (1, 2)]
    k = np.sqrt(np.prod([m["permeability"].values for m in members], axis=0))[::-1]
    np.testing.assert_allclose(table["k"].sel(condition="free").transpose("suction", "phase", "axis"),
                               k, rtol=1e-12)
    # the chain goes on: micro at the two checkpoints it was given, the table of that one
    # result its own k (suction ascending)
    micro, mixture = namespace["micro"], namespace["mixture"]
    np.testing.assert_array_equal(micro["suction"].values, [132e6, 60e6])
    np.testing.assert_allclose(namespace["chained"]["k"].sel(condition="free").transpose("suction", "phase", "axis"),
                               micro["permeability"].values[::-1], rtol=1e-12)
    assert mixture.attrs["stop_reason"] == "max_steps" and mixture.sizes["time"] == 4
    # the solid is conserved, read off the state: the mixture's dry density stays the
    # configured one at every record
    np.testing.assert_allclose(mixture["dry_density"].values,
                               default_config()["macro"]["mixture"]["dry_density_kg_m3"], rtol=1e-12)

