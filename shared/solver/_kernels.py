"""Numba kernels and checks of the SPD solver: symmetric product, drift, CG update."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from numba import njit

FloatArray = npt.NDArray[np.float64]


@njit(cache=True)
def _symmetric_product(
    indptr: npt.NDArray[np.int32], indices: npt.NDArray[np.int32], data: FloatArray,
    vector: FloatArray,
) -> FloatArray:
    """A x for the symmetric A given by its CSC lower triangle (diagonal first)."""
    result = np.zeros(vector.shape[0])
    for column in range(vector.shape[0]):
        x_column = vector[column]
        total = data[indptr[column]] * x_column
        for p in range(indptr[column] + 1, indptr[column + 1]):
            row = indices[p]
            result[row] += data[p] * x_column
            total += data[p] * vector[row]
        result[column] += total
    return result


@njit(cache=True)
def _scaled_drift(
    indptr: npt.NDArray[np.int32], indices: npt.NDArray[np.int32], data: FloatArray,
    old: FloatArray,
) -> float:
    """max |a_ij - a0_ij| / sqrt(|a0_ii a0_jj|); 0 where both vanish, inf for a new entry."""
    largest = 0.0
    for column in range(indptr.shape[0] - 1):
        diagonal = abs(old[indptr[column]])
        for p in range(indptr[column], indptr[column + 1]):
            change = abs(data[p] - old[p])
            if change == 0.0:
                continue
            scale = np.sqrt(diagonal * abs(old[indptr[indices[p]]]))
            largest = max(largest, change / scale if scale > 0.0 else np.inf)
    return largest


@njit(cache=True)
def _dot(a: FloatArray, b: FloatArray) -> float:
    """a . b summed in index order (the same order on every call)."""
    total = 0.0
    for k in range(a.shape[0]):
        total += a[k] * b[k]
    return total


@njit(cache=True)
def _cg_update(
    indptr: npt.NDArray[np.int32], indices: npt.NDArray[np.int32], data: FloatArray,
    preconditioned: FloatArray, solution: FloatArray, residual: FloatArray,
    direction: FloatArray, rho: float,
) -> tuple[float, bool]:
    """One preconditioned CG update of solution, residual and direction (in place).

    Returns the new rho = r . z and whether the step was possible (rho and the
    curvature d . A d positive).
    """
    rho_new = _dot(residual, preconditioned)
    if not rho_new > 0.0:
        return rho_new, False
    beta = rho_new / rho
    for k in range(residual.shape[0]):
        direction[k] = preconditioned[k] + beta * direction[k]
    image = _symmetric_product(indptr, indices, data, direction)
    curvature = _dot(direction, image)
    if not curvature > 0.0:
        return rho_new, False
    step = rho_new / curvature
    for k in range(residual.shape[0]):
        solution[k] += step * direction[k]
        residual[k] -= step * image[k]
    return rho_new, True


def _check_lower(matrix: sp.csc_matrix) -> None:
    """Raise unless ``matrix`` is a square CSC lower triangle with a leading diagonal."""
    if not (sp.issparse(matrix) and matrix.format == "csc"):
        raise ValueError("pass the lower triangle as a scipy.sparse CSC matrix")
    if matrix.shape[0] != matrix.shape[1]:
        raise ValueError(f"matrix must be square, got shape {matrix.shape}")
    counts = np.diff(matrix.indptr)
    columns = np.repeat(np.arange(matrix.shape[1]), counts)
    if np.any(matrix.indices < columns):
        raise ValueError("matrix has entries above the diagonal: pass its lower triangle")
    leading = matrix.indices[matrix.indptr[:-1]]
    if np.any(counts == 0) or np.any(leading != np.arange(matrix.shape[1])):
        raise ValueError("every column must start with its diagonal entry (sorted indices)")


def _full_matrix(lower: sp.csc_matrix) -> sp.csr_matrix:
    """The symmetric matrix of a lower triangle, CSR (what pyamg takes)."""
    full = (lower + sp.tril(lower, k=-1, format="csc").T).tocsr()
    full.sort_indices()
    return full
