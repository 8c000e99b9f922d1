"""An object's state as plain data and arrays, and back: what a snapshot stores.

:class:`Encoder` walks an object's attributes (all of ``vars(obj)``, dataclass fields or
not, so an attribute added to a model later is saved without editing any snapshot code)
and turns them into a JSON tree whose arrays are set apart by name; :class:`Decoder`
rebuilds the object from that tree. What can be stored:

- ``None``, ``bool``, ``int``, ``float`` (NaN and infinities too) and ``str``, in the tree;
- numpy arrays (not of object dtype) and numpy scalars, as arrays (an array held twice is
  stored once and comes back as one object; a list of arrays of one shape and dtype, or of
  numpy scalars of one dtype, is stacked into one array);
- lists, tuples and dicts with string keys of these;
- instances of dataclasses, rebuilt as the class that the owner's type annotation
  declares (``Mesh``, ``Readings | None``): the class comes from the code, never from the
  file, and is rebuilt without calling its ``__init__``, as :mod:`pickle` would;
- *given* attributes (by name, e.g. settings built from the configuration): not stored,
  but supplied by the caller when decoding; the integer, float, bool and string fields of a
  given mutable dataclass (e.g. a table's look-up counters) are stored and set on a
  shallow copy of the given object.

Anything else (a set, a function, a dataclass without a declared type, an object array)
raises :class:`TypeError` naming the attribute at save time: a state that cannot be
stored is an error, never a silent omission (tests/shared/test_plain_state.py).
"""

from __future__ import annotations

import copy
import dataclasses
import types
import typing
from collections.abc import Callable, Collection, Mapping
from functools import cache
from typing import Any, TypeVar

import numpy as np

from shared.errors import SnapshotError

__all__ = ["Decoder", "Encoder"]

_PLAIN = (bool, int, float, str, type(None))

T = TypeVar("T")


def _type_hints(cls: type) -> dict[str, Any]:
    """The resolved type annotations of a class and its bases (empty if none resolve)."""
    try:
        return typing.get_type_hints(cls)
    except (NameError, TypeError):
        return {}


# typed as a function of a class: to mypy, functools.cache takes Hashable arguments, and
# a type[X] is not one
_hints: Callable[[type], dict[str, Any]] = cache(_type_hints)


def _declared_dataclass(hint: Any) -> type | None:
    """The one dataclass a type annotation names (``X`` or ``X | None``), else None."""
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        return hint
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        classes = [a for a in typing.get_args(hint) if isinstance(a, type) and dataclasses.is_dataclass(a)]
        if len(classes) == 1:
            return classes[0]
    return None


def _given_scalars(value: object) -> dict[str, Any]:
    """The plain scalar fields of a mutable dataclass (none of a frozen one)."""
    if not dataclasses.is_dataclass(value) or type(value).__dataclass_params__.frozen:  # type: ignore[union-attr]  # typeshed's DataclassInstance lacks __dataclass_params__
        return {}
    return {f.name: getattr(value, f.name) for f in dataclasses.fields(value)
            if type(getattr(value, f.name)) in _PLAIN}


class Encoder:
    """Turns objects into a plain tree; the arrays it sets apart are in :attr:`arrays`.

    Parameters
    ----------
    given
        Attribute names whose values the decoder will be given (see the module's text).
    """

    def __init__(self, given: Collection[str] = ()) -> None:
        self.given = frozenset(given)
        self.arrays: dict[str, np.ndarray] = {}
        self._names: dict[int, str] = {}

    def _array(self, array: np.ndarray, where: str) -> str:
        if array.dtype.hasobject:
            raise TypeError(f"{where}: an array of Python objects cannot be saved in a snapshot")
        name = self._names.get(id(array))
        if name is None:
            name = self._names[id(array)] = f"a{len(self.arrays)}"
            self.arrays[name] = array
        return name

    def encode(self, value: object, hint: Any = None, where: str = "state") -> Any:
        """The plain tree of ``value``; ``hint`` is its declared type, ``where`` its name
        in error messages.

        Raises
        ------
        TypeError
            Naming the attribute whose value cannot be stored.
        """
        if type(value) in _PLAIN:
            return value
        if isinstance(value, np.ndarray):
            return {"array": self._array(value, where)}
        if isinstance(value, np.generic):
            return {"scalar": self._array(np.asarray(value), where)}
        if isinstance(value, list):
            return self._list(value, where)
        if isinstance(value, tuple) and type(value) is tuple:
            return {"tuple": [self.encode(v, None, f"{where}[{i}]") for i, v in enumerate(value)]}
        if isinstance(value, dict):
            if not all(isinstance(k, str) for k in value):
                raise TypeError(f"{where}: a dict with keys other than strings cannot be saved in a snapshot")
            return {"dict": {k: self.encode(v, None, f"{where}[{k!r}]") for k, v in value.items()}}
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            if _declared_dataclass(hint) is not type(value):
                raise TypeError(f"{where}: a {type(value).__name__} without a declared type "
                                f"(annotate the attribute as {type(value).__name__} in its class)")
            return {"object": self.attributes(value, where)}
        raise TypeError(f"{where}: a {type(value).__module__}.{type(value).__qualname__} cannot be "
                        "saved in a snapshot (arrays, numbers, strings, lists, dicts and "
                        "declared dataclasses can)")

    def attributes(self, obj: object, where: str) -> dict[str, Any]:
        """The plain trees of all of an object's attributes, by name."""
        if not hasattr(obj, "__dict__"):
            raise TypeError(f"{where}: a {type(obj).__name__} without __dict__ cannot be saved in a snapshot")
        hints = _hints(type(obj))
        return {name: ({"given": _given_scalars(value)} if name in self.given
                       else self.encode(value, hints.get(name), f"{where}.{name}"))
                for name, value in vars(obj).items()}

    def _list(self, values: list[Any], where: str) -> Any:
        first = values[0] if values else None
        if len(values) > 1 and isinstance(first, np.ndarray | np.generic) and all(
                type(v) is type(first) and v.dtype == first.dtype and np.shape(v) == np.shape(first)
                for v in values):
            kind = "arrays" if isinstance(first, np.ndarray) else "scalars"
            return {"stack": self._array(np.stack(values), where), "of": kind}
        return [self.encode(v, None, f"{where}[{i}]") for i, v in enumerate(values)]


class Decoder:
    """Rebuilds objects from an :class:`Encoder`'s tree and arrays.

    Parameters
    ----------
    arrays
        The arrays by name.
    given
        The objects of the given attributes, by attribute name.
    """

    def __init__(self, arrays: Mapping[str, np.ndarray], given: Mapping[str, object] | None = None) -> None:
        self.arrays = arrays
        self.given = dict(given or {})

    def _array(self, name: str, where: str) -> np.ndarray:
        try:
            return self.arrays[name]
        except KeyError:
            raise SnapshotError(f"{where}: array {name} missing") from None

    def decode(self, node: Any, hint: Any = None, where: str = "state") -> Any:
        """The value a plain tree stands for; ``hint`` is its declared type.

        Raises
        ------
        shared.errors.SnapshotError
            For a tree that does not fit the code (an array missing, a dataclass where
            the class declares none).
        """
        if type(node) in _PLAIN:
            return node
        if isinstance(node, list):
            return [self.decode(v, None, f"{where}[{i}]") for i, v in enumerate(node)]
        if not isinstance(node, dict) or len(node) not in (1, 2):
            raise SnapshotError(f"{where}: unexpected entry {str(node)[:60]!r}")
        if "array" in node:
            return self._array(node["array"], where)
        if "scalar" in node:
            return self._array(node["scalar"], where)[()]
        if "stack" in node:
            stacked = self._array(node["stack"], where)
            return [stacked[i, ...] if node.get("of") == "arrays" else stacked[i] for i in range(len(stacked))]
        if "tuple" in node:
            return tuple(self.decode(v, None, f"{where}[{i}]") for i, v in enumerate(node["tuple"]))
        if "dict" in node:
            return {k: self.decode(v, None, f"{where}[{k!r}]") for k, v in node["dict"].items()}
        if "object" in node:
            cls = _declared_dataclass(hint)
            if cls is None:
                raise SnapshotError(f"{where}: the code declares no dataclass for a saved object")
            return self.build(cls, node["object"], where)
        raise SnapshotError(f"{where}: unexpected entry {str(node)[:60]!r}")

    def build(self, cls: type[T], attributes: Mapping[str, Any], where: str) -> T:
        """An instance of ``cls`` (without calling its ``__init__``) with these attributes."""
        obj = cls.__new__(cls)
        hints = _hints(cls)
        for name, node in attributes.items():
            if isinstance(node, dict) and "given" in node:
                if name not in self.given:
                    raise SnapshotError(f"{where}.{name}: given when saved, not given now")
                value = self.given[name]
                if node["given"]:  # on a copy: the caller's object stays as it was
                    value = copy.copy(value)
                    for key, scalar in node["given"].items():
                        setattr(value, key, scalar)
            else:
                value = self.decode(node, hints.get(name), f"{where}.{name}")
            object.__setattr__(obj, name, value)
        return obj
