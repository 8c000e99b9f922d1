"""A checkpoint's eight permeability solves, gathered in one go."""

from __future__ import annotations

from concurrent.futures import Executor

import numpy as np
import numpy.typing as npt

from micro.permeability.axes import axes_calls, axes_result
from micro.permeability.steady import DROP_FRACTION, INNER_FRACTION, FloatArray, FrozenState
from micro.permeability.tensor import tensor_calls
from micro.pool import gathered

__all__ = ["checkpoint_permeabilities"]


def checkpoint_permeabilities(
    state: FrozenState,
    *,
    sealed: npt.NDArray[np.bool_] | None = None,
    executor: Executor | None = None,
) -> tuple[dict[str, dict[str, float]], FloatArray]:
    """A checkpoint's eight solves: the axes' (wall-flux method) and the tensors, with
    their default fractions, in one gather.

    With ``executor``, the worker makes one phase's four solves and this thread the
    other's, and the mesh they share is sent to the worker once.

    Parameters
    ----------
    state
        The frozen state (:class:`micro.permeability.steady.FrozenState`).
    sealed
        Cells that stay free in the tensor's wall layers (crack mouths), as for
        :func:`micro.permeability.tensor.permeability_tensor`.
    executor
        A worker, as for :func:`micro.permeability.axes.axis_permeabilities`; the
        results do not depend on it.

    Returns
    -------
    axes : dict
        ``{phase: {axis: permeability [m2]}}``, as ``axis_permeabilities``.
    tensor : ndarray, shape (2, 3, 3)
        K[phase, i, j] [m2], as ``permeability_tensor``.
    """
    mesh, suction, material, phases = state.mesh, state.suction, state.material, state.phases()
    axes = axes_calls(mesh, phases, suction, material, "wall_flux", DROP_FRACTION)
    values = gathered(executor, [*axes, *tensor_calls(mesh, phases, suction, material,
                                                        DROP_FRACTION, INNER_FRACTION, sealed)])
    return axes_result(values[:len(axes)]), np.stack(values[len(axes):])
