"""The project modules a script imports, found by reading the sources (nothing is imported).

A rule's code hash (:func:`shared.provenance.script_sha256`) covers the source files of
every module of our packages that its script imports, directly or through other modules,
so that an edit of that code reruns the rule and an edit of any other code does not.
The import graph is read statically: every ``import`` statement counts, at module level,
inside a function or under ``if TYPE_CHECKING:`` (a package that imports its names lazily
lists them there), and importing a submodule also runs its parent packages' ``__init__``
files.
"""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

__all__ = ["PACKAGES", "imported_sources"]

# The pipeline's packages, the one list: the code hashes, the provenance and the tests
# import it; pyproject.toml's import-linter lists, which cannot import it, are checked
# against it, and so is the set of packages at the repository root (tests/shared/test_imports.py).
PACKAGES: tuple[str, ...] = ("imaging", "micro", "macro", "shared")


def _module_file(name: str, folders: tuple[Path, ...]) -> Path | None:
    """The source file of a dotted module name under one of the folders, if any."""
    parts = name.split(".")
    for folder in folders:
        base = folder.joinpath(*parts)
        for candidate in (base.with_suffix(".py"), base / "__init__.py"):
            if candidate.is_file():
                return candidate
    return None


def _imported_names(source: Path, module: str) -> tuple[str, ...]:
    """The dotted names a source file imports (``from a import b`` gives ``a`` and ``a.b``:
    ``b`` may be a submodule), relative imports resolved against ``module``."""
    stat = source.stat()
    return _parsed_names(source, module, stat.st_mtime_ns, stat.st_size)


# an import statement at the start of a line, parenthesised names over several lines
_IMPORT = re.compile(r"^[ \t]*(?:from[ \t]+[\w.]+[ \t]+import[ \t]*(?:\([^)]*\)|.*)|import[ \t]+.*)$",
                     re.MULTILINE)


@cache
def _parsed_names(source: Path, module: str, mtime_ns: int, size: int) -> tuple[str, ...]:
    """:func:`_imported_names` cached on the file's modification time and size.

    Only the import statements are parsed (a line-start regex picks them, then :mod:`ast`
    reads each): parsing whole modules made the DAG's build seconds slower. A statement
    of a docstring's example counts too, which at worst adds a module to the hash.
    """
    is_package = source.name == "__init__.py"
    names: list[str] = []
    for match in _IMPORT.finditer(source.read_text()):
        try:
            statement = ast.parse(match.group(0).strip().rstrip("\\")).body
        except SyntaxError:  # prose in a docstring, or a line continued by a backslash
            continue
        for node in statement:
            if isinstance(node, ast.Import):
                names.extend(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = module.split(".")
                    anchor = anchor if is_package else anchor[:-1]
                    anchor = anchor[: len(anchor) - (node.level - 1)]
                    base = ".".join([*anchor, base] if base else anchor)
                names.append(base)
                names.extend(f"{base}.{a.name}" for a in node.names if a.name != "*")
    return tuple(name for name in names if name)


def imported_sources(
    script: str | Path,
    root: str | Path,
    packages: tuple[str, ...] = PACKAGES,
    *,
    lookups: dict[tuple[str, tuple[Path, ...]], Path | None] | None = None,
) -> dict[str, Path]:
    """Return the source files of our modules that a script imports, transitively.

    Parameters
    ----------
    script
        The Python file whose imports are followed (a rule's script).
    root
        The folder that holds the packages (the repository root).
    packages
        The top-level package names whose modules count; standard library and third-party
        imports are not followed.
    lookups
        Where a module's name was found, kept across calls that share this dict (the
        rules of one Snakemake invocation: the tree does not change meanwhile).

    Returns
    -------
    dict[str, Path]
        Module name to source file, in name order. Modules beside the script (the
        scripts' own helpers, such as ``_logging``) count as well, under their bare name.
    """
    if lookups is None:
        lookups = {}

    def module_file(name: str, folders: tuple[Path, ...]) -> Path | None:
        key = (name, folders)
        if key not in lookups:
            lookups[key] = _module_file(name, folders)
        return lookups[key]

    script = Path(script).resolve()
    root = Path(root).resolve()
    local = script.parent
    found: dict[str, Path] = {}
    seen: set[str] = set()  # a name imported by several modules is looked up once
    pending = list(_imported_names(script, "__main__"))
    while pending:
        name = pending.pop()
        if name in seen:
            continue
        seen.add(name)
        top = name.split(".")[0]
        if top in packages:
            folders: tuple[Path, ...] = (root,)
            # importing a.b.c runs a/__init__.py and a/b/__init__.py first
            chain = [".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 2)]
        elif module_file(name, (local,)) is not None:
            folders, chain = (local,), [name]
        else:
            continue
        for module in chain:
            if module in found:
                continue
            path = module_file(module, folders)
            if path is None:  # ``from a import b`` where b is a name, not a submodule
                continue
            found[module] = path
            pending.extend(_imported_names(path, module))
    return dict(sorted(found.items()))
