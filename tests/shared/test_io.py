"""netCDF writer: round trip, contract checks, provenance and atomicity."""

import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from shared.figures import new_figure, save_figure
from shared.io import OutputError, read_dataset, write_dataset, write_outputs
from shared.provenance import config_sha256, file_sha256, module_sha256


def _dataset() -> xr.Dataset:
    z = xr.Variable(("z",), np.linspace(0, 1e-3, 4), {"units": "m", "long_name": "height"})
    return xr.Dataset(
        {"porosity": (("z",), np.array([0.2, 0.25, np.nan, 0.3]),
                      {"units": "1", "long_name": "porosity"})},
        coords={"z": z},
    )


def test_round_trip_is_identical(tmp_path):
    ds = _dataset()
    path = write_dataset(ds, tmp_path / "a" / "out.nc", stage="imaging", title="test",
                         config={"b": [1, 2], "a": True}, seed=4)
    back = read_dataset(path, ["porosity"])
    xr.testing.assert_identical(back.drop_attrs(deep=False), ds)
    assert back.attrs["seed"] == 4
    assert back.attrs["config_sha256"] == config_sha256({"a": True, "b": [1, 2]})
    assert back.attrs["Conventions"] == "CF-1.11"


def test_write_outputs_writes_the_file_the_others_then_the_figure(tmp_path):
    """The stages' one writer: the netCDF round trip, a file given as bytes and one given
    as a writer function, the figure drawn last with its path; the code hash is the
    caller's module; a refused dataset leaves nothing."""
    drawn = []

    def draw(path):
        assert (tmp_path / "t.csv").read_bytes() == b"a,b\n"  # the other files come first
        fig, axes = new_figure(1, 1)
        axes.flat[0].plot([0, 1], [0, 1])
        drawn.append(save_figure(fig, path))

    path = write_outputs(_dataset(), tmp_path / "t.nc", stage="imaging", title="t", seed=2,
                         files={tmp_path / "t.csv": b"a,b\n",
                                tmp_path / "t.txt": lambda tmp: Path(tmp).write_text("x")},
                         figure=(tmp_path / "t.png", draw))
    back = read_dataset(path)
    xr.testing.assert_identical(back.drop_attrs(deep=False), _dataset())
    assert back.attrs["seed"] == 2 and back.attrs["code_sha256"] == module_sha256(__file__)
    assert (tmp_path / "t.txt").read_text() == "x"
    assert drawn == [tmp_path / "t.png"] and (tmp_path / "t.png").stat().st_size > 1000
    refused = tmp_path / "refused"
    with pytest.raises(OutputError, match="units"):
        write_outputs(_dataset().assign(bad=("z", np.zeros(4))), refused / "t.nc", stage="imaging",
                      title="t", files={refused / "t.csv": b""}, figure=(refused / "t.png", draw))
    assert not refused.exists() or not any(refused.iterdir())


def test_inputs_are_hashed(tmp_path):
    source = tmp_path / "in.txt"
    source.write_text("grey values")
    path = write_dataset(_dataset(), tmp_path / "o.nc", stage="imaging", title="t", inputs=[source])
    record = json.loads(read_dataset(path).attrs["inputs"])
    assert record == [{"path": str(source), "sha256": file_sha256(source)}]


def test_attributes_netcdf_cannot_hold_are_converted(tmp_path):
    ds = _dataset()
    ds.attrs.update(flag=True, nested={"k": 1}, nothing=None, words=["a", "b"])
    back = read_dataset(write_dataset(ds, tmp_path / "o.nc", stage="micro", title="t"))
    assert back.attrs["flag"] == 1
    assert json.loads(back.attrs["nested"]) == {"k": 1}
    assert "nothing" not in back.attrs
    assert json.loads(back.attrs["words"]) == ["a", "b"]


def test_variable_without_units_is_refused_and_nothing_written(tmp_path):
    ds = _dataset()
    del ds["porosity"].attrs["units"]
    with pytest.raises(OutputError, match="'porosity' lacks attribute"):
        write_dataset(ds, tmp_path / "o.nc", stage="imaging", title="t")
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    path = write_dataset(_dataset(), tmp_path / "o.nc", stage="imaging", title="first")
    bad = _dataset()
    bad["text"] = (("z",), np.array([object()] * 4, dtype=object), {"units": "1", "long_name": "x"})
    with pytest.raises(ValueError):
        write_dataset(bad, path, stage="imaging", title="second")
    assert read_dataset(path).attrs["title"] == "first"
    assert [p.name for p in tmp_path.iterdir()] == ["o.nc"]


def test_unreadable_file_is_named(tmp_path):
    junk = tmp_path / "junk.nc"
    junk.write_bytes(b"not netcdf")
    with pytest.raises(OutputError, match="junk.nc"):
        read_dataset(junk)
    with pytest.raises(OutputError, match="missing variable"):
        read_dataset(write_dataset(_dataset(), tmp_path / "o.nc", stage="imaging", title="t"),
                     ["permeability"])


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_outputs_get_the_permissions_the_umask_gives(tmp_path, umask):
    """Written through a temporary file, an output still gets 0666 & ~umask (a plain
    open() would), not the temporary file's owner-only 0600."""
    old = os.umask(umask)
    try:
        path = write_dataset(
            xr.Dataset({"a": ("x", np.arange(3.0), {"units": "1", "long_name": "a"})},
                       coords={"x": ("x", np.arange(3), {"units": "1", "long_name": "x"})}),
            tmp_path / "out.nc", stage="micro", title="t")
        figure, _ = new_figure(1, 1)
        png = save_figure(figure, tmp_path / "out.png")
    finally:
        os.umask(old)
    for written in (path, png):
        assert stat.S_IMODE(written.stat().st_mode) == 0o666 & ~umask
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.nc", "out.png"]
