"""A checkpoint's eight permeability solves, gathered in one go."""

from __future__ import annotations

from collections.abc import Mapping
from concurrent.futures import Executor

import numpy as np
import numpy.typing as npt

from micro.permeability.axes import axes_calls, axes_result
from micro.permeability.steady import DROP_FRACTION, INNER_FRACTION, FloatArray, phase_conductances
from micro.permeability.tensor import tensor_calls
from micro.pool import gathered
from shared.materials import ClayParameters
from shared.mesh import Mesh

__all__ = ["checkpoint_permeabilities"]


def checkpoint_permeabilities(
    mesh: Mesh,
    saturation: FloatArray,
    porosity: FloatArray,
    suction: float,
    material: ClayParameters,
    *,
    conductances: Mapping[str, FloatArray] | None = None,
    sealed: npt.NDArray[np.bool_] | None = None,
    executor: Executor | None = None,
) -> tuple[dict[str, dict[str, float]], FloatArray]:
    """A checkpoint's eight solves: the axes' (wall-flux method) and the tensors, with
    their default fractions, in one gather.

    With ``executor``, the worker makes one phase's four solves and this thread the
    other's, and the mesh they share is sent to the worker once.

    Parameters
    ----------
    mesh, saturation, porosity, suction, material, conductances
        As for :func:`micro.permeability.axes.axis_permeabilities`: the frozen state
        [1, 1], the suction [Pa], the clay parameters, optional facet conductances per
        phase [m3/(Pa s)].
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
    phases = phase_conductances(mesh, saturation, porosity, suction, material, conductances)
    axes = axes_calls(mesh, phases, suction, material, "wall_flux", DROP_FRACTION)
    values = gathered(executor, [*axes, *tensor_calls(mesh, phases, suction, material,
                                                        DROP_FRACTION, INNER_FRACTION, sealed)])
    return axes_result(values[:len(axes)]), np.stack(values[len(axes):])
