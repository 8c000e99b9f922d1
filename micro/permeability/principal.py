"""Principal values and directions, and asymmetry, of permeability tensors."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["PrincipalPermeability", "principal_permeability"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class PrincipalPermeability:
    """Derived quantities of permeability tensors (:func:`principal_permeability`).

    Attributes
    ----------
    symmetric : ndarray, shape (..., 3, 3)
        Symmetric part (K + K^T) / 2 [m2].
    values : ndarray, shape (..., 3)
        Eigenvalues of the symmetric part in ascending order [m2].
    directions : ndarray, shape (..., 3, 3)
        Unit eigenvectors of the symmetric part as columns: ``directions[..., :, k]``
        belongs to ``values[..., k]``; each has its largest-magnitude component
        positive (the first such component on a tie) [1].
    asymmetry : ndarray, shape (...)
        ||K - K^T||_F / ||K||_F [1] (0 for a zero tensor).
    """

    symmetric: FloatArray
    values: FloatArray
    directions: FloatArray
    asymmetry: FloatArray


def principal_permeability(tensor: npt.ArrayLike) -> PrincipalPermeability:
    """Symmetric part, principal values and directions, and asymmetry of tensors.

    Parameters
    ----------
    tensor
        Permeability tensors [m2], shape (..., 3, 3).

    Returns
    -------
    PrincipalPermeability
        All fields NaN for a tensor with a non-finite entry.
    """
    tensor = np.asarray(tensor, dtype=np.float64)
    if tensor.shape[-2:] != (3, 3):
        raise ValueError(f"tensors must have shape (..., 3, 3), got {tensor.shape}")
    finite = np.all(np.isfinite(tensor), axis=(-2, -1))
    clean = np.where(finite[..., None, None], tensor, 0.0)
    transposed = np.swapaxes(clean, -1, -2)
    symmetric = 0.5 * (clean + transposed)
    values, directions = np.linalg.eigh(symmetric)
    # sign convention: the largest-magnitude component of each direction is positive
    largest = np.argmax(np.abs(directions), axis=-2)[..., None, :]
    sign = np.where(np.take_along_axis(directions, largest, axis=-2) < 0.0, -1.0, 1.0)
    directions = directions * sign
    norm = np.linalg.norm(clean, axis=(-2, -1))
    skew = np.linalg.norm(clean - transposed, axis=(-2, -1))
    asymmetry = np.divide(skew, norm, out=np.zeros_like(norm), where=norm > 0.0)
    nan = ~finite
    symmetric[nan] = np.nan
    values[nan] = np.nan
    directions[nan] = np.nan
    asymmetry = np.where(nan, np.nan, asymmetry)
    return PrincipalPermeability(symmetric=symmetric, values=values, directions=directions,
                                 asymmetry=asymmetry)
