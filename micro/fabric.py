"""Crack fabric tensor (Caulk 2022, Eq. 3.39), kept apart for imbibed and gas-filled cracks.

Lambda = (1/N) sum_c a_c n_c (x) n_c, with n_c the unit vector along the bond of crack c
(the crack plane is normal to it). A tensor, so opposite normals add up instead of
cancelling as in Yade's vector sum (docs/yade.md §3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["CrackFabric", "fabric_tensor", "crack_fabric"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class CrackFabric:
    """Fabric and totals of a crack set, for all, imbibed and gas-filled cracks.

    Attributes
    ----------
    tensor, tensor_imbibed, tensor_gas
        (3, 3) fabric tensors Lambda [m2] (zero for an empty class).
    count, count_imbibed, count_gas
        Number of cracks.
    area, area_imbibed, area_gas
        Summed crack area a_c [m2].
    volume, volume_imbibed, volume_gas
        Summed crack volume a_c w [m3].
    """

    tensor: FloatArray
    tensor_imbibed: FloatArray
    tensor_gas: FloatArray
    count: int
    count_imbibed: int
    count_gas: int
    area: float
    area_imbibed: float
    area_gas: float
    volume: float
    volume_imbibed: float
    volume_gas: float


def fabric_tensor(normals: npt.ArrayLike, areas: npt.ArrayLike) -> FloatArray:
    """Lambda = (1/N) sum_c a_c n_c (x) n_c (Eq. 3.39).

    Parameters
    ----------
    normals
        (N, 3) crack normals; normalised here, so any non-zero length works.
    areas
        (N,) crack areas a_c [m2].

    Returns
    -------
    ndarray, shape (3, 3)
        Symmetric fabric tensor [m2]; its trace is the mean crack area. Zero if N = 0.
    """
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    areas = np.asarray(areas, dtype=np.float64)
    if areas.shape != (normals.shape[0],):
        raise ValueError("need one area per normal")
    if areas.size == 0:
        return np.zeros((3, 3))
    unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    return np.einsum("c,ci,cj->ij", areas, unit, unit) / areas.size


def crack_fabric(
    normals: npt.ArrayLike,
    areas: npt.ArrayLike,
    apertures: npt.ArrayLike,
    imbibed: npt.ArrayLike,
) -> CrackFabric:
    """Fabric tensors, counts, areas and volumes of all, imbibed and gas-filled cracks.

    Parameters
    ----------
    normals
        (N, 3) crack normals (along the bonds).
    areas
        (N,) crack areas a_c [m2].
    apertures
        (N,) apertures w [m].
    imbibed
        (N,) True for water-filled cracks.

    Returns
    -------
    CrackFabric
        Each class normalised by its own count.
    """
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    areas = np.asarray(areas, dtype=np.float64)
    volumes = areas * np.asarray(apertures, dtype=np.float64)
    imbibed = np.asarray(imbibed, dtype=np.bool_)
    if volumes.shape != areas.shape or imbibed.shape != areas.shape:
        raise ValueError("areas, apertures and imbibed must have one value per crack")
    gas = ~imbibed
    return CrackFabric(
        tensor=fabric_tensor(normals, areas),
        tensor_imbibed=fabric_tensor(normals[imbibed], areas[imbibed]),
        tensor_gas=fabric_tensor(normals[gas], areas[gas]),
        count=int(areas.size),
        count_imbibed=int(imbibed.sum()),
        count_gas=int(gas.sum()),
        area=float(areas.sum()),
        area_imbibed=float(areas[imbibed].sum()),
        area_gas=float(areas[gas].sum()),
        volume=float(volumes.sum()),
        volume_imbibed=float(volumes[imbibed].sum()),
        volume_gas=float(volumes[gas].sum()),
    )
