"""The pellet permeability table: its contract, and the interpolator the macro model uses.

``results/upscaling/pellet_permeability.nc`` (docs/design.md §2) holds the micro model's pellet
permeability against suction, per condition (free, confined), phase, axis, and as a
tensor. Permeability spans orders of magnitude, so it is interpolated as log10 k against
log10 suction, with a monotone cubic (PCHIP): exact at the nodes, no overshoot between
them. Tensors are interpolated in the log-Euclidean sense (the matrix logarithm of each
symmetric positive definite node, component by component), which keeps them symmetric
positive definite. Suctions outside the table are clamped to its range and counted, so
that the consumer can record how often it read beyond the micro model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
import xarray as xr
from scipy.interpolate import PchipInterpolator

from shared.errors import InputError
from shared.io import OutputError, read_dataset

__all__ = [
    "TABLE_VARIABLES",
    "PermeabilityTable",
    "check_suction_coverage",
    "check_table",
    "read_table",
]

FloatArray = npt.NDArray[np.float64]

TABLE_VARIABLES: dict[str, tuple[str, ...]] = {
    "k": ("condition", "phase", "axis", "suction"),
    "k_tensor": ("condition", "phase", "suction", "i", "j"),
    "saturation": ("condition", "suction"),
    "eps_v": ("condition", "suction"),
}
"""Variables of the table and their dimensions (the contract macro relies on)."""


def check_table(table: xr.Dataset, source: str = "the upscaling table") -> None:
    """Check a table against the contract: dimensions, positive finite k, suctions.

    Raises
    ------
    OutputError
        Naming ``source`` and the offending variable.
    """
    for name, dims in TABLE_VARIABLES.items():
        if name not in table:
            raise OutputError(f"{source}: missing variable {name!r}")
        if tuple(table[name].dims) != dims:
            raise OutputError(
                f"{source}: {name!r} has dimensions {tuple(table[name].dims)}, expected {dims}"
            )
    suction = np.asarray(table["suction"].values, dtype=float)
    if suction.size < 2 or not np.all(np.diff(suction) > 0) or not suction[0] > 0:
        raise OutputError(f"{source}: suctions must be positive and strictly increasing")
    k = np.asarray(table["k"].values, dtype=float)
    if not np.all(np.isfinite(k) & (k > 0)):
        bad = int(np.count_nonzero(~(np.isfinite(k) & (k > 0))))
        raise OutputError(f"{source}: {bad} non-positive or NaN permeabilities in 'k'")
    tensor = np.asarray(table["k_tensor"].values, dtype=float)
    if not np.all(np.isfinite(tensor)):
        raise OutputError(f"{source}: NaN in 'k_tensor'")
    eigenvalues = np.linalg.eigvalsh(0.5 * (tensor + np.swapaxes(tensor, -1, -2)))
    if not np.all(eigenvalues > 0):
        raise OutputError(f"{source}: a 'k_tensor' node is not positive definite")


def check_suction_coverage(table: PermeabilityTable, low: float, high: float, source: str, key: str) -> None:
    """Refuse a table whose suctions miss a case's range [low, high] [Pa] by more than a decade.

    Within a decade, the look-ups outside the table are clamped and counted
    (:class:`PermeabilityTable`).

    Raises
    ------
    shared.errors.InputError
        Naming ``source``, both ranges and ``key`` (what sets the case's range).
    """
    table_low, table_high = table.suction_range
    if table_low > 10.0 * low or table_high < 0.1 * high:
        raise InputError(
            f"{source}: its suctions [{table_low:.3g}, {table_high:.3g}] Pa miss the case's range "
            f"[{low:.3g}, {high:.3g}] Pa ({key}) by more than a decade: a table in other units "
            "(MPa?) or of other cases"
        )


def read_table(path: str | Path) -> xr.Dataset:
    """Read and check ``pellet_permeability.nc``; errors name the file."""
    table = read_dataset(path, TABLE_VARIABLES)
    check_table(table, str(path))
    return table


def _log_matrix(tensors: FloatArray) -> FloatArray:
    """Matrix logarithm of symmetric positive definite matrices (..., 3, 3)."""
    values, vectors = np.linalg.eigh(0.5 * (tensors + np.swapaxes(tensors, -1, -2)))
    return (vectors * np.log(values)[..., None, :]) @ np.swapaxes(vectors, -1, -2)


def _exp_matrix(logs: FloatArray) -> FloatArray:
    values, vectors = np.linalg.eigh(logs)
    return (vectors * np.exp(values)[..., None, :]) @ np.swapaxes(vectors, -1, -2)


@dataclass
class PermeabilityTable:
    """Interpolator of one condition of the pellet permeability table.

    Parameters
    ----------
    table
        The table (checked with :func:`check_table`).
    condition
        ``free`` or ``confined`` (a value of the ``condition`` coordinate).

    Attributes
    ----------
    clamped
        Number of suctions looked up outside the table's range so far (clamped).
    looked_up
        Number of suctions looked up so far.
    """

    table: xr.Dataset
    condition: str
    clamped: int = 0
    looked_up: int = 0
    _scalar: dict[tuple[str, str], PchipInterpolator] = field(default_factory=dict, repr=False)
    _tensor: dict[str, PchipInterpolator] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        check_table(self.table)
        conditions = [str(c) for c in self.table["condition"].values]
        if self.condition not in conditions:
            raise OutputError(
                f"the upscaling table has no condition {self.condition!r} (has {conditions})"
            )
        self._view = self.table.sel(condition=self.condition)
        self._log_suction = np.log10(np.asarray(self.table["suction"].values, dtype=float))

    @classmethod
    def from_file(cls, path: str | Path, condition: str) -> PermeabilityTable:
        """Read, check and wrap one condition of a table file."""
        return cls(read_table(path), condition)

    @property
    def suction_range(self) -> tuple[float, float]:
        """Smallest and largest suction of the table [Pa]."""
        return float(10 ** self._log_suction[0]), float(10 ** self._log_suction[-1])

    def _clamped_log_suction(self, suction: npt.ArrayLike) -> FloatArray:
        suction = np.asarray(suction, dtype=float)
        if not np.all(np.isfinite(suction)):
            raise ValueError("suction must be finite")
        low, high = self.suction_range
        self.clamped += int(np.count_nonzero((suction < low) | (suction > high)))
        self.looked_up += int(suction.size)
        return np.log10(np.clip(suction, low, high))

    def permeability(self, suction: npt.ArrayLike, phase: str, axis: str = "mean") -> FloatArray:
        """Pellet permeability at a suction [m2].

        Parameters
        ----------
        suction
            Suction [Pa], any shape; values outside the table are clamped (and counted).
        phase
            ``water`` or ``gas``.
        axis
            ``x``, ``y``, ``z``, or ``mean`` (the geometric mean of the three axes).
        """
        key = (phase, axis)
        if key not in self._scalar:
            k = self._view["k"].sel(phase=phase)
            log_k = np.log10(k.values)
            values = log_k.mean(axis=0) if axis == "mean" else log_k[list(k["axis"].values).index(axis)]
            self._scalar[key] = PchipInterpolator(self._log_suction, values)
        return 10.0 ** self._scalar[key](self._clamped_log_suction(suction))

    def tensor(self, suction: npt.ArrayLike, phase: str) -> FloatArray:
        """Pellet permeability tensor at a suction [m2], shape ``suction.shape + (3, 3)``.

        Interpolated log-Euclidean between the nodes' symmetric parts; symmetric
        positive definite everywhere, equal to the nodes' symmetric parts at the nodes.
        """
        if phase not in self._tensor:
            nodes = self._view["k_tensor"].sel(phase=phase).values
            logs = _log_matrix(nodes).reshape(nodes.shape[0], 9)
            self._tensor[phase] = PchipInterpolator(self._log_suction, logs)
        logs = self._tensor[phase](self._clamped_log_suction(suction))
        logs = logs.reshape(*logs.shape[:-1], 3, 3)
        return _exp_matrix(0.5 * (logs + np.swapaxes(logs, -1, -2)))
