"""The diagonal path of the SPD solver: conjugate gradients preconditioned by the
inverse of the current matrix's diagonal (Jacobi).

Nothing is bought and nothing is kept: the scaling is taken afresh from every matrix, at
one division per unknown. It pays where storage weighs on the diagonal (a transient step
whose values change at every solve, as the macro transport's): CG then converges in tens
of iterations, where a factorisation of ten thousand unknowns costs several times more.
A system it does not solve within its iterations goes to the factor
(:class:`shared.solver.SPDSolver`, ``method="jacobi"``).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

__all__ = ["DiagonalScaling"]

FloatArray = npt.NDArray[np.float64]


class DiagonalScaling:
    """The Jacobi preconditioner of one solve.

    Attributes
    ----------
    inverse
        1 / a_ii of the matrix being solved, None outside a solve on this path.
    """

    def __init__(self) -> None:
        self.inverse: FloatArray | None = None

    def build(self, lower: sp.csc_matrix) -> None:
        """Take the diagonal of the lower triangle ``lower`` (diagonal first in each column).

        A non-positive diagonal entry gives a non-positive or infinite scaling, on which
        CG stops (non-positive curvature) short of the tolerance.
        """
        with np.errstate(divide="ignore"):
            self.inverse = 1.0 / lower.data[lower.indptr[:-1]]

    def apply(self, vector: FloatArray) -> FloatArray:
        """The scaled ``vector``, a_ii^-1 v_i."""
        assert self.inverse is not None
        return self.inverse * vector
