"""The project's error types: what a user can act on, told apart by type alone.

Every failure that a user's input, configuration, results folder or a diverging run can
cause is a :class:`ClaychainError`; a rule's error hook (workflow/scripts/_logging.py)
prints any of them as one line ``claychain: <message>`` and keeps the traceback for the
job's log, and prints any other exception (a bug) with its traceback. Each class keeps
the built-in base it had before the hierarchy (``ValueError`` for bad values,
``RuntimeError`` for failed solutions), so ``except ValueError`` around our calls still
catches what it caught. The classes are re-exported where they were first defined
(:class:`shared.config.ConfigError`, :class:`shared.io.OutputError`,
:class:`imaging.ct.io.ImageError`, :class:`micro.hydration.DivergenceError`,
:class:`macro.newton.NewtonError`, :class:`shared.solver.base.SolverError`).
"""

from __future__ import annotations

__all__ = [
    "ClaychainError",
    "ConfigError",
    "DivergenceError",
    "ImageError",
    "InputError",
    "NewtonError",
    "OutputError",
    "SnapshotError",
    "SolverError",
]


class ClaychainError(Exception):
    """A failure the user can act on; its message names the file or key at fault."""


class ConfigError(ClaychainError, ValueError):
    """An invalid configuration; the message names the offending key."""


class InputError(ClaychainError, ValueError):
    """An input file (scan, porosity grid, table) that is missing or unusable."""


class ImageError(InputError):
    """An image that is missing, unreadable, or of the wrong shape or type."""


class OutputError(ClaychainError, ValueError):
    """A dataset that does not meet the data contract, or a file that cannot be read or written."""


class SnapshotError(OutputError):
    """A restart file that fails its checks (format, checksum, content)."""


class DivergenceError(ClaychainError, RuntimeError):
    """The coupled solution became non-finite or left its physical range."""


class NewtonError(ClaychainError, RuntimeError):
    """A local pressure-volume system without solution or without convergence."""


class SolverError(ClaychainError, RuntimeError):
    """The linear solve failed: singular/indefinite matrix or non-finite values."""
