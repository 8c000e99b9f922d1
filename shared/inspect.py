"""Print a readable summary of any claychain netCDF output.

Usage: ``python -m shared.inspect FILE [FILE ...]`` (or the ``claychain-inspect`` script).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import xarray as xr

from shared.io import OutputError, read_dataset

__all__ = ["summary", "main"]

_PROVENANCE = ("stage", "created", "code_version", "config_sha256", "seed", "snakemake_rule")


def _range(values: np.ndarray) -> str:
    if values.dtype.kind not in "iufb" or values.size == 0:
        return ""
    finite = values[np.isfinite(values)] if values.dtype.kind == "f" else values
    nan = values.size - finite.size
    if finite.size == 0:
        return "all NaN"
    text = f"{finite.min():.4g} .. {finite.max():.4g}"
    return text + (f" ({nan} NaN)" if nan else "")


def summary(ds: xr.Dataset, name: str = "") -> str:
    """A text table of dimensions, variables (dims, units, range, long name) and provenance."""
    lines = [f"== {name} ==" if name else "== dataset =="]
    lines.append(f"title: {ds.attrs.get('title', '')}")
    lines.append("dimensions: " + ", ".join(f"{d}={n}" for d, n in ds.sizes.items()))
    width = max((len(str(v)) for v in ds.variables), default=4)
    for kind, group in (("coordinates", ds.coords), ("variables", ds.data_vars)):
        lines.append(f"{kind}:")
        for var_name, var in group.items():
            dims = "(" + ",".join(map(str, var.dims)) + ")"
            lines.append(
                f"  {str(var_name):<{width}} {dims:<24} [{var.attrs.get('units', '?')}] "
                f"{_range(np.asarray(var.values)):<32} {var.attrs.get('long_name', '')}"
            )
    lines.append("provenance:")
    for key in _PROVENANCE:
        if key in ds.attrs:
            lines.append(f"  {key}: {ds.attrs[key]}")
    inputs = json.loads(ds.attrs.get("inputs", "[]") or "[]")
    for record in inputs:
        lines.append(f"  input: {record['path']} (sha256 {record['sha256'][:12]}...)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point; returns the exit code."""
    parser = argparse.ArgumentParser(prog="claychain-inspect", description=__doc__)
    parser.add_argument("files", nargs="+", type=Path)
    args = parser.parse_args(argv)
    status = 0
    for path in args.files:
        try:
            print(summary(read_dataset(path), str(path)))
        except OutputError as err:
            print(f"error: {err}", file=sys.stderr)
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
