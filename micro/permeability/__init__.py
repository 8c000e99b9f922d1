"""Numerical permeability measurement of the frozen micro model (docs/design.md §3).

Thesis Sec. 3.5.3 and Appendix .2 (``emulatePermeability``), corrected as in
docs/yade.md §§4 and 10: saturation, porosity and mesh are frozen, a pressure drop of
``drop_fraction`` of the suction is imposed along one axis, the steady problem is solved
(:mod:`~micro.permeability.steady`):

* per axis (:mod:`~micro.permeability.axes`): the ``"wall_flux"`` and ``"velocity"``
  methods;
* the tensor (:mod:`~micro.permeability.tensor`): velocity method for gradients along
  x, y and z, K[:, j] = -mu <v> / (grad p)_j;
* a checkpoint's eight solves in one gather (:mod:`~micro.permeability.checkpoint`);
* the tensor's symmetric part, principal values and directions
  (:mod:`~micro.permeability.principal`).

One failure policy: a measurement that cannot be made (wall fluxes unbalanced or
reversed, a failed factorisation, no free cell in the averaged inner region, a tensor
whose symmetric part is not positive definite) is NaN with a warning in the case's log,
since it is one diagnostic of a checkpoint and the run's other results stand; only
invalid arguments raise (ValueError). The rest: docs/micro.md, "micro.permeability".
"""

from micro.permeability.axes import axis_permeabilities, measure_permeability, measurement_pattern
from micro.permeability.checkpoint import checkpoint_permeabilities
from micro.permeability.principal import PrincipalPermeability, principal_permeability
from micro.permeability.steady import AXES, PHASES, FrozenState
from micro.permeability.tensor import measure_permeability_tensor, permeability_tensor, tensor_pattern

__all__ = [
    "AXES",
    "PHASES",
    "FrozenState",
    "PrincipalPermeability",
    "measure_permeability",
    "measure_permeability_tensor",
    "measurement_pattern",
    "tensor_pattern",
    "permeability_tensor",
    "axis_permeabilities",
    "checkpoint_permeabilities",
    "principal_permeability",
]
