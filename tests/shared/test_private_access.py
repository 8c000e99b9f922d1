"""No module of the packages reads a private attribute (``x._name``) of another object:
parts talk through public methods and attributes (the standard library's ``os._exit`` and
``sys._getframe`` aside)."""

from __future__ import annotations

import ast
from pathlib import Path

from shared.imports import PACKAGES

ROOT = Path(__file__).resolve().parents[2]
STANDARD = {"os._exit", "sys._getframe"}


def test_no_package_module_reads_another_objects_private_attribute() -> None:
    found, modules = [], 0
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            modules += 1
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__") \
                        and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")) \
                        and ast.unparse(node) not in STANDARD:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno} {ast.unparse(node)}")
    assert found == []
    assert modules > 100  # the walk saw the packages
