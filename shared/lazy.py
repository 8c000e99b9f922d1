"""Public names of a package imported from their submodules on first use (PEP 562), so
that importing a light submodule (a key list for the workflow) does not import numba.

A package writes its public names once, as the ``from .x import (...)`` statements of
its ``if TYPE_CHECKING:`` block: type checkers and IDEs read them there, and
:func:`lazy_package` reads the same statements from the package's source to build the
lazy map and ``__all__``.
"""

from __future__ import annotations

import ast
import importlib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

__all__ = ["lazy_getattr", "lazy_package", "type_checking_exports"]


def lazy_getattr(package: str, exports: Mapping[str, str], namespace: dict[str, Any]) -> Callable[[str], Any]:
    """The module ``__getattr__`` of ``package``: a name of ``exports`` (name -> submodule)
    is imported from ``package.<submodule>`` on first use and kept in ``namespace``."""

    def getattr_(name: str) -> Any:
        if name in exports:
            value = getattr(importlib.import_module(f"{package}.{exports[name]}"), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return getattr_


def _is_type_checking(test: ast.expr) -> bool:
    """Whether an ``if`` test is ``TYPE_CHECKING`` or ``typing.TYPE_CHECKING``."""
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def type_checking_exports(source: str | Path, package: str) -> dict[str, str]:
    """The names a package's ``if TYPE_CHECKING:`` block imports from its submodules.

    Parameters
    ----------
    source
        The package's ``__init__.py``.
    package
        Its dotted name; the block's imports are ``from <package>.<submodule> import ...``
        or ``from .<submodule> import ...``.

    Returns
    -------
    dict[str, str]
        Public name -> the submodule (relative to ``package``) that defines it, in the
        block's order.

    Raises
    ------
    ValueError
        If the block holds a statement other than such an import, an alias
        (``import a as b``) or a name given twice: the lazy map could not follow it.
    """
    tree = ast.parse(Path(source).read_text(), filename=str(source))
    blocks = [node.body for node in tree.body if isinstance(node, ast.If) and _is_type_checking(node.test)]
    exports: dict[str, str] = {}
    for node in (statement for block in blocks for statement in block):
        module = node.module if isinstance(node, ast.ImportFrom) else None
        if isinstance(node, ast.ImportFrom) and node.level == 1 and module:
            submodule = module
        elif isinstance(node, ast.ImportFrom) and not node.level and module and module.startswith(f"{package}."):
            submodule = module.removeprefix(f"{package}.")
        else:
            raise ValueError(f"{source}:{node.lineno}: the TYPE_CHECKING block holds only "
                             f"'from {package}.<submodule> import ...' statements")
        for alias in node.names:
            if alias.asname not in (None, alias.name) or alias.name in exports:
                raise ValueError(f"{source}:{node.lineno}: {alias.name!r} is aliased or exported twice")
            exports[alias.name] = submodule
    return exports


def lazy_package(namespace: dict[str, Any]) -> tuple[list[str], Callable[[str], Any]]:
    """``__all__`` and ``__getattr__`` of the package whose ``globals()`` is ``namespace``,
    both from its ``if TYPE_CHECKING:`` block (:func:`type_checking_exports`)::

        __all__, __getattr__ = lazy_package(globals())
    """
    package = namespace["__name__"]
    exports = type_checking_exports(namespace["__file__"], package)
    return sorted(exports), lazy_getattr(package, exports, namespace)
