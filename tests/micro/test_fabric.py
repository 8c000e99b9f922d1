"""Crack fabric tensors against hand-computed sums of n n^T times area."""

import numpy as np
import pytest

from micro.fabric import crack_fabric, fabric_tensor


def test_fabric_of_cracks_along_x():
    normals = np.array([[1.0, 0, 0], [2.0, 0, 0], [1.0, 0, 0]])
    areas = np.array([1e-8, 2e-8, 3e-8])
    expected = np.diag([6e-8 / 3, 0.0, 0.0])
    np.testing.assert_allclose(fabric_tensor(normals, areas), expected, rtol=1e-15, atol=0)


def test_opposite_normals_add_up():
    tensor = fabric_tensor([[0, 0, 1.0], [0, 0, -1.0]], [4e-8, 4e-8])
    np.testing.assert_allclose(tensor, np.diag([0.0, 0.0, 4e-8]), rtol=1e-15, atol=0)


def test_fabric_separates_imbibed_and_gas_cracks():
    diagonal = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    fabric = crack_fabric(
        [[0, 1.0, 0], diagonal, [1.0, 0, 0]], [2e-8, 4e-8, 6e-8], [1e-6, 2e-6, 3e-6],
        [True, True, False],
    )
    np.testing.assert_allclose(
        fabric.tensor_imbibed, [[1e-8, 1e-8, 0], [1e-8, 2e-8, 0], [0, 0, 0]], rtol=1e-14
    )
    np.testing.assert_allclose(fabric.tensor_gas, np.diag([6e-8, 0, 0]), rtol=1e-15)
    assert (fabric.count, fabric.count_imbibed, fabric.count_gas) == (3, 2, 1)
    assert fabric.area == pytest.approx(1.2e-7, rel=1e-14)
    assert fabric.volume_imbibed == pytest.approx(2e-14 + 8e-14, rel=1e-14)
    assert fabric.volume_gas == pytest.approx(1.8e-13, rel=1e-14)
    np.testing.assert_array_equal(crack_fabric(np.zeros((0, 3)), [], [], []).tensor, 0.0)
