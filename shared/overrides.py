"""Configuration values from the command line: ``--set key=value``, typed by the schema.

``bash claychain run --set KEY=VALUE`` calls this module's command line, which writes
the assignments as an overlay YAML file that the launcher passes to Snakemake after the
configuration files. A value takes the type the schema gives its key (arrays and
mappings as JSON); an unknown key or a value of the wrong type is refused naming the
key, and the merged configuration is validated against the schema. Types and merge
order: docs/development.md, "shared.overrides".

Command line::

    python -m shared.overrides [--output OVERLAY.yaml] [--configfile FILE ...] [--set KEY=VALUE ...]

Without ``--output`` it only checks the configuration files, merged in order
(:func:`shared.config.read_config_file`, then the schema).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from shared.config import (
    DEFAULT_CONFIG_PATH,
    ConfigError,
    _merged,
    load_schema,
    read_config_file,
    validate_config,
)

__all__ = ["changes", "key_schema", "main", "overlay", "parse_value"]

_NULL = {"null", "none", "~"}
_TRUE = {"true", "yes", "on"}
_FALSE = {"false", "no", "off"}


def _resolve(node: Mapping[str, Any], schema: Mapping[str, Any]) -> Mapping[str, Any]:
    """A schema node with its local ``$ref`` (``#/$defs/...``) followed."""
    while "$ref" in node:
        target: Any = schema
        for part in node["$ref"].lstrip("#/").split("/"):
            target = target[part]
        node = target
    return node


def _branches(node: Mapping[str, Any], schema: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    """The node and the alternatives of its ``oneOf``/``anyOf``, resolved."""
    node = _resolve(node, schema)
    out = [node]
    for keyword in ("oneOf", "anyOf"):
        out += [_resolve(branch, schema) for branch in node.get(keyword, [])]
    return out


def key_schema(schema: Mapping[str, Any], key: str) -> Mapping[str, Any]:
    """The schema node of a dotted configuration key.

    Parameters
    ----------
    schema
        The configuration's JSON schema.
    key
        ``materials.pellet.swelling_beta_per_pa``; a name of a mapping of entries
        (``micro.cases.het.n_points``) is any name.

    Returns
    -------
    Mapping[str, Any]
        The key's schema node.

    Raises
    ------
    ConfigError
        Naming the key, if the schema does not know it.
    """
    node: Mapping[str, Any] = schema
    done: list[str] = []
    for part in key.split("."):
        found = None
        for branch in _branches(node, schema):
            if part in branch.get("properties", {}):
                found = branch["properties"][part]
                break
            if isinstance(branch.get("additionalProperties"), Mapping):
                found = branch["additionalProperties"]
                break
        if found is None:
            known = sorted({name for branch in _branches(node, schema)
                            for name in branch.get("properties", {})})
            where = f"'{'.'.join(done)}'" if done else "the configuration"
            raise ConfigError(
                f"unknown config key '{key}': {part!r} is not a key of {where}"
                + (f" (keys: {', '.join(known)})" if known else "")
            )
        node = found
        done.append(part)
    return _resolve(node, schema)


def _types(node: Mapping[str, Any], schema: Mapping[str, Any]) -> list[str]:
    """The JSON types a node allows, in the order its alternatives list them."""
    types: list[str] = []
    for branch in _branches(node, schema):
        kind = branch.get("type")
        types += [kind] if isinstance(kind, str) else list(kind or [])
        if "enum" in branch and not kind:
            types += [{str: "string", bool: "boolean", int: "integer", float: "number",
                       type(None): "null"}.get(type(v), "string") for v in branch["enum"]]
    return list(dict.fromkeys(types))


def parse_value(text: str, node: Mapping[str, Any], key: str,
                schema: Mapping[str, Any] | None = None) -> Any:
    """The value of a ``key=text`` assignment, typed by the key's schema node.

    Parameters
    ----------
    text
        The value as typed on the command line.
    node
        The key's schema node (:func:`key_schema`).
    key
        The dotted key, for the message.
    schema
        The whole schema, to follow ``$ref``.

    Returns
    -------
    Any
        ``None``, a bool, an int, a float, a string, or a list or mapping (JSON).

    Raises
    ------
    ConfigError
        Naming the key and the types it takes, if the text is none of them.
    """
    types = _types(node, schema or {})
    word = text.strip().lower()
    if not types:
        return yaml.safe_load(text)
    if "null" in types and word in _NULL:
        return None
    if "boolean" in types and word in _TRUE | _FALSE:
        return word in _TRUE
    if "integer" in types or "number" in types:
        try:
            return int(text)
        except ValueError:
            pass
        if "number" in types:
            try:
                return float(text)
            except ValueError:
                pass
    if {"array", "object"} & set(types):
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = None
        if (isinstance(value, list) and "array" in types) or (
                isinstance(value, dict) and "object" in types):
            return value
    if "string" in types:
        return text
    expected = " or ".join("JSON " + t if t in ("array", "object") else t for t in types)
    raise ConfigError(f"config key '{key}': {text!r} is not {expected}")


def overlay(assignments: Sequence[str], schema: Mapping[str, Any]) -> dict[str, Any]:
    """The nested mapping of ``key=value`` assignments, each typed by the schema.

    Raises
    ------
    ConfigError
        For an assignment without ``=``, an unknown key, or a value of the wrong type.
    """
    out: dict[str, Any] = {}
    for assignment in assignments:
        key, sep, text = assignment.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"--set {assignment!r}: expected key=value")
        value = parse_value(text, key_schema(schema, key), key, schema)
        *parents, last = key.split(".")
        target = out
        for part in parents:
            target = target.setdefault(part, {})
        target[last] = value
    return out


def changes(assignments: Sequence[str], before: Mapping[str, Any],
            schema: Mapping[str, Any]) -> list[str]:
    """One line per assignment: the key, its value before (defaults filled in) and after.

    Parameters
    ----------
    assignments
        ``key=value`` texts, valid.
    before
        The validated configuration without them.
    schema
        The configuration schema, which types the values.

    Returns
    -------
    list of str
        ``key: old -> new``, or ``key: new (unchanged)``.
    """
    lines = []
    for assignment in assignments:
        key, _, text = assignment.partition("=")
        key = key.strip()
        value = parse_value(text, key_schema(schema, key), key, schema)
        old: Any = before
        for part in key.split("."):
            old = old.get(part) if isinstance(old, Mapping) else None
        lines.append(f"--set {key}: {old!r} -> {value!r}" if old != value
                     else f"--set {key}: {value!r} (unchanged)")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: write the overlay of ``--set`` assignments, validated; 0 or 2."""
    parser = argparse.ArgumentParser(
        prog="python -m shared.overrides",
        description="Write --set key=value assignments as a configuration overlay (YAML).")
    parser.add_argument("--set", dest="assignments", action="append", default=[],
                        metavar="KEY=VALUE", help="a configuration value (repeatable)")
    parser.add_argument("--configfile", action="append", default=[], type=Path,
                        help="configuration the overlay applies to, in order "
                             "(default: config/config.yaml)")
    parser.add_argument("--output", type=Path,
                        help="the overlay to write (none: only check the configuration files)")
    args = parser.parse_args(argv)
    if args.assignments and args.output is None:
        parser.error("--set needs --output, the overlay to write")
    schema = load_schema()
    try:
        values = overlay(args.assignments, schema)
        merged: dict[str, Any] = {}
        for path in args.configfile or [DEFAULT_CONFIG_PATH]:
            merged = _merged(merged, read_config_file(path))
        before = validate_config(_merged(merged, {}), schema)
        validate_config(_merged(merged, values), schema)
    except ConfigError as err:
        print(f"claychain: invalid configuration: {err}", file=sys.stderr)
        return 2
    for line in changes(args.assignments, before, schema):
        print(f"claychain: {line}", file=sys.stderr)
    if args.output is None:
        return 0
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text("# written by: python -m shared.overrides "
                           + " ".join(f"--set {a}" for a in args.assignments) + "\n"
                           + yaml.safe_dump(values, sort_keys=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
