"""Coarse correction of a static solve: one Newton step on the rigid translation of all
the points, which removes their net resultant.

A relaxation with one mass per point (FIRE, :func:`shared.dem.fire_step`) balances each
point against its neighbours in a few steps, but a residual that pushes every point the
same way is resisted only by what holds the assembly as a whole (walls, a surrounding
medium): against the masses, set by the contacts, that mode is soft, and FIRE needs many
steps per e-fold of it, more the more points share it. Its own 3 x 3 tangent, from
finite differences of the resultant, solves it in one step.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

__all__ = ["rigid_translation"]


def rigid_translation(resultant_at: Callable[[FloatArray], tuple[FloatArray, float]], resultant: FloatArray,
                      ratio: float, step: float, halvings: int = 4) -> tuple[FloatArray | None, int]:
    """Translation t of all the points that cancels their net resultant R(t), to first order.

    The tangent dR/dt (3 x 3) is taken by forward differences of ``step`` along each
    axis; t solves dR/dt t = -R(0). It is halved until the imbalance ratio at x + t falls
    below ``ratio``, at most ``halvings`` times.

    Parameters
    ----------
    resultant_at
        ``resultant_at(t)``: the net resultant (3,) [N] of the points translated by ``t``
        (3,) [m], and the imbalance ratio [1] that the step must lower.
    resultant
        (3,) net resultant at t = 0 [N].
    ratio
        Imbalance ratio at t = 0 [1].
    step
        Finite-difference step [m], small against the contacts' overlaps.
    halvings
        Largest number of halvings of the Newton step.

    Returns
    -------
    tuple
        The accepted translation (3,) [m], or None (a singular tangent or no step that
        lowers the ratio), and the number of evaluations of ``resultant_at`` used.
    """
    tangent = np.empty((3, 3))
    for axis in range(3):
        shift = np.zeros(3)
        shift[axis] = step
        tangent[:, axis] = (resultant_at(shift)[0] - resultant) / step
    evaluations = 3
    try:
        translation = np.asarray(np.linalg.solve(tangent, -resultant), dtype=np.float64)
    except np.linalg.LinAlgError:
        return None, evaluations
    for _ in range(halvings + 1):
        evaluations += 1
        if resultant_at(translation)[1] < ratio:
            return translation, evaluations
        translation = 0.5 * translation
    return None, evaluations
