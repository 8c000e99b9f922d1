"""Benchmark harness: ``python -m benchmarks list | run CASE [--size N]``.

Each case runs in a process of its own so that its peak memory (``ru_maxrss`` above the
process's baseline after imports) is its own. Results are JSON in ``results/benchmarks/``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import platform
import resource
import subprocess
import sys
from pathlib import Path

CASE_MODULES = (
    "benchmarks.imaging",
    "benchmarks.deposition",
    "benchmarks.deposition_validation",
    "benchmarks.flow",
    "benchmarks.dem",
    "benchmarks.yade_compare",
    "benchmarks.macro",
    "benchmarks.macro_kill_resume",
    "benchmarks.macro_homogenised",
    "benchmarks.macro_ogs",
    "benchmarks.macro_balance",
    "benchmarks.macro_fire",
    "benchmarks.macro_packing",
    "benchmarks.macro_mixture",
    "benchmarks.micro_profile",
)
OUT = Path("results/benchmarks")


def _cases() -> dict:
    cases = {}
    for name in CASE_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as err:
            if err.name != name:
                raise
            continue
        cases.update({k[len("bench_"):]: getattr(module, k) for k in dir(module) if k.startswith("bench_")})
    return cases


def _peak_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _run_here(case: str, size: int | None) -> None:
    function = _cases()[case]
    baseline = _peak_bytes()
    result = function(size) if size is not None else function()
    result["peak_memory_bytes_above_baseline"] = _peak_bytes() - baseline
    print(json.dumps(result))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list")
    run = sub.add_parser("run")
    run.add_argument("cases", nargs="+")
    run.add_argument("--size", type=int, default=None)
    inner = sub.add_parser("_case")
    inner.add_argument("case")
    inner.add_argument("size", type=int, nargs="?")
    args = parser.parse_args(argv)
    if args.command == "list":
        for name, function in sorted(_cases().items()):
            print(f"{name:<28} {(function.__doc__ or '').strip().splitlines()[0]}")
        return 0
    if args.command == "_case":
        _run_here(args.case, args.size)
        return 0
    unknown = sorted(set(args.cases) - set(_cases()))
    if unknown:
        parser.error(f"unknown case(s) {unknown}; see 'list'")
    OUT.mkdir(parents=True, exist_ok=True)
    for case in args.cases:
        command = [sys.executable, "-m", "benchmarks", "_case", case]
        command += [] if args.size is None else [str(args.size)]
        # the case's log (progress lines) goes to the terminal as it runs
        done = subprocess.run(command, stdout=subprocess.PIPE, text=True)
        if done.returncode != 0:
            return done.returncode
        result = json.loads(done.stdout.strip().splitlines()[-1])
        result.update(case=case, machine=platform.node(), cpus=__import__("os").cpu_count())
        suffix = "" if args.size is None else f"_{args.size}"
        (OUT / f"{case}{suffix}.json").write_text(json.dumps(result, indent=2))
        print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
