"""The upscaling stage (micro.upscaling.run): the table, its CSV and figure written, nothing
written on a refusal; a hand edit of the CSV export refused."""

import csv

import pytest
import xarray as xr

from micro.upscaling import run as upscaling_run
from shared.config import ConfigError
from shared.errors import InputError
from shared.io import write_dataset
from shared.table_export import check_csv_export
from shared.upscaling import PermeabilityTable, read_table
from tests.micro.upscaling.test_table import CHECKPOINTS, RANGE, _micro


def _write(ds, path):
    write_dataset(ds, path, stage="micro", title="synthetic micro result")
    return path


def _outputs(stem):
    """The table, its CSV export and its figure at ``stem`` with their suffixes."""
    return upscaling_run.TableOutputs(*(stem.with_suffix(suffix) for suffix in (".nc", ".csv", ".png")))


def test_run_writes_table_csv_and_figure_and_nothing_on_refusal(tmp_path):
    section = {"conditions": {"free": ["a", "b"], "confined": "c"}, "suction_range_pa": list(RANGE)}
    inputs = {"free": [_write(_micro(1), tmp_path / "a.nc"), _write(_micro(2), tmp_path / "b.nc")],
              "confined": [_write(_micro(3), tmp_path / "c.nc")]}
    out = tmp_path / "up" / "pellet_permeability"
    out.parent.mkdir()
    table = upscaling_run.run(section, inputs, _outputs(out))
    back = read_table(out.with_suffix(".nc"))
    xr.testing.assert_allclose(back[["k", "k_tensor", "saturation"]], table[["k", "k_tensor", "saturation"]])
    assert str(tmp_path / "a.nc") in back.attrs["inputs"]
    with open(out.with_suffix(".csv")) as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 2 * 2 * 3 * CHECKPOINTS.size
    row = rows[7]
    expected = table["k"].sel(condition=row["condition"], phase=row["phase"], axis=row["axis"],
                              suction=float(row["suction_pa"]))
    assert float(row["k_m2"]) == pytest.approx(float(expected), rel=1e-9)
    assert out.with_suffix(".png").stat().st_size > 0
    curve = PermeabilityTable.from_file(out.with_suffix(".nc"), "confined")
    assert curve.permeability(1e5, "water", "x") == pytest.approx(
        float(table["k"].sel(condition="confined", phase="water", axis="x", suction=1e5)), rel=1e-12)
    # a refused source leaves no partial table
    refused = tmp_path / "refused"
    refused.mkdir()
    bad = _write(_micro(4).assign(permeability=lambda d: -d["permeability"]), tmp_path / "d.nc")
    with pytest.raises(ConfigError, match="d.nc"):
        upscaling_run.run(section, {**inputs, "confined": [bad]}, _outputs(refused / "t"))
    assert not any(refused.iterdir())


def test_a_hand_edit_of_the_csv_export_is_refused_naming_the_route(tmp_path):
    """The table records its export's sha256: the export as written passes, a hand edit
    (k x 1000 in one row) is refused, naming the CSV and macro.table_path; without the
    export nothing is checked."""
    section = {"conditions": {"free": "a", "confined": "a"}, "suction_range_pa": list(RANGE)}
    inputs = {"free": [_write(_micro(1), tmp_path / "a.nc")], "confined": [tmp_path / "a.nc"]}
    out = tmp_path / "up" / "pellet_permeability"
    out.parent.mkdir()
    upscaling_run.run(section, inputs, _outputs(out))
    check_csv_export(out.with_suffix(".nc"))
    export = out.with_suffix(".csv")
    lines = export.read_text().splitlines()
    fields = lines[3].split(",")
    fields[-1] = f"{float(fields[-1]) * 1000:.10g}"
    export.write_text("\n".join([*lines[:3], ",".join(fields), *lines[4:]]) + "\n")
    with pytest.raises(InputError, match=r"pellet_permeability\.csv: edited since .*macro\.table_path"):
        check_csv_export(out.with_suffix(".nc"))
    export.unlink()
    check_csv_export(out.with_suffix(".nc"))
