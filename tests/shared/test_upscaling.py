"""The pellet permeability table's interpolator: exact at nodes, monotone, clamped."""

import numpy as np
import pytest
import xarray as xr

from shared.io import OutputError
from shared.upscaling import PermeabilityTable, check_table

SUCTION = np.array([1e3, 1e4, 1e5, 1e6, 1e7, 1e8])


def _table(k_water=None, tensor=None):
    """A two-condition table; water k rises (wetting) with a plateau, gas k peaks."""
    log_s = np.log10(SUCTION)
    water = k_water if k_water is not None else 10.0 ** np.array([-17, -18, -19.5, -19.6, -20, -21])
    gas = 10.0 ** (-22 + 3 * np.exp(-((log_s - 5) ** 2)))
    axes = np.array([1.0, 1.5, 0.5])
    k = np.empty((2, 2, 3, SUCTION.size))
    k[:, 0] = axes[:, None] * water
    k[:, 1] = axes[:, None] * gas
    k[1] *= 0.1
    if tensor is None:
        tensor = np.zeros((2, 2, SUCTION.size, 3, 3))
        for i in range(3):
            tensor[..., i, i] = np.moveaxis(k[:, :, i, :], -1, -1)
        tensor[..., 0, 1] = tensor[..., 1, 0] = 0.2 * tensor[..., 0, 0]
    zeros = np.zeros((2, SUCTION.size))
    return xr.Dataset(
        {
            "k": (("condition", "phase", "axis", "suction"), k),
            "k_tensor": (("condition", "phase", "suction", "i", "j"), tensor),
            "saturation": (("condition", "suction"), zeros + 0.5),
            "eps_v": (("condition", "suction"), zeros),
        },
        coords={"condition": ["free", "confined"], "phase": ["water", "gas"],
                "axis": ["x", "y", "z"], "suction": SUCTION},
    )


def test_exact_at_the_nodes_per_axis_and_as_geometric_mean():
    table = _table()
    curve = PermeabilityTable(table, "confined")
    k = table["k"].sel(condition="confined", phase="gas")
    np.testing.assert_allclose(curve.permeability(SUCTION, "gas", "y"), k.sel(axis="y"), rtol=1e-12)
    mean = np.exp(np.log(k.values).mean(axis=0))
    np.testing.assert_allclose(curve.permeability(SUCTION, "gas"), mean, rtol=1e-12)


def test_monotone_between_nodes_no_overshoot():
    curve = PermeabilityTable(_table(), "free")
    nodes = curve.permeability(SUCTION, "water", "x")
    for a, b, low, high in zip(SUCTION[:-1], SUCTION[1:], nodes[:-1], nodes[1:], strict=True):
        inside = curve.permeability(np.geomspace(a, b, 50), "water", "x")
        assert np.all(inside >= min(low, high) * (1 - 1e-12))
        assert np.all(inside <= max(low, high) * (1 + 1e-12))
        assert np.all(np.diff(inside) * np.sign(high - low) >= 0)


def test_clamped_outside_the_range_and_counted():
    curve = PermeabilityTable(_table(), "free")
    k = curve.permeability([1.0, 5e2, 1e5, 3e8, 1e9], "water", "z")
    edges = curve.permeability(SUCTION[[0, -1]], "water", "z")
    assert k[0] == k[1] == edges[0] and k[3] == k[4] == edges[1]
    assert (curve.clamped, curve.looked_up) == (4, 7)


def test_tensor_is_the_node_at_nodes_and_positive_definite_between():
    table = _table()
    curve = PermeabilityTable(table, "free")
    nodes = table["k_tensor"].sel(condition="free", phase="water").values
    np.testing.assert_allclose(curve.tensor(SUCTION, "water"), nodes, rtol=1e-9,
                               atol=1e-12 * np.abs(nodes).max())
    between = curve.tensor(np.geomspace(1e3, 1e8, 101), "water")
    np.testing.assert_allclose(between, np.swapaxes(between, -1, -2), rtol=1e-12, atol=0)
    assert np.all(np.linalg.eigvalsh(between) > 0)


def test_diagonal_tensor_interpolates_like_the_axis_curves():
    """Two independent paths: the matrix-log interpolation of a diagonal tensor and the
    scalar PCHIP of each axis's k agree."""
    table = _table()
    tensor = np.zeros(table["k_tensor"].shape)
    for i, axis in enumerate("xyz"):
        tensor[..., i, i] = table["k"].sel(axis=axis).values
    curve = PermeabilityTable(table.assign(k_tensor=(table["k_tensor"].dims, tensor)), "free")
    probe = np.geomspace(2e3, 5e7, 37)
    diagonal = np.diagonal(curve.tensor(probe, "gas"), axis1=-2, axis2=-1)
    for i, axis in enumerate("xyz"):
        np.testing.assert_allclose(diagonal[:, i], curve.permeability(probe, "gas", axis), rtol=1e-9)


@pytest.mark.parametrize(("edit", "message"), [
    (lambda t: t.assign(k=t["k"].where(t["suction"] < 1e7, 0.0)), "non-positive or NaN"),
    (lambda t: t.assign(k=t["k"].where(t["suction"] < 1e7)), "non-positive or NaN"),
    (lambda t: t.drop_vars("k_tensor"), "missing variable 'k_tensor'"),
    (lambda t: t.assign(saturation=t["saturation"].transpose()), "dimensions"),
    (lambda t: t.isel(suction=slice(None, None, -1)), "strictly increasing"),
])
def test_malformed_tables_are_refused(edit, message):
    with pytest.raises(OutputError, match=message):
        check_table(edit(_table()), "table.nc")


def test_unknown_condition_is_refused():
    with pytest.raises(OutputError, match="no condition 'wet'"):
        PermeabilityTable(_table(), "wet")
