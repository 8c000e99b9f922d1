"""Shared fixtures and the --run-slow option."""

from __future__ import annotations

import numpy as np
import pytest


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--run-slow", action="store_true", default=False, help="run tests marked slow")


# Test folders whose files call the same numba kernels. Under ``--dist loadgroup`` (bash
# claychain test) each runs on one worker, so that a fresh clone compiles its kernels once
# rather than on both workers at once; every other file is a group of its own, as under
# ``--dist loadfile``.
_KERNEL_FOLDERS = ("tests/macro", "tests/micro", "tests/imaging/packing")


def _group(item: pytest.Item) -> str:
    """The xdist group of a test: its kernel folder, else its file."""
    path = item.path.relative_to(item.config.rootpath).as_posix()
    return next((folder for folder in _KERNEL_FOLDERS if path.startswith(f"{folder}/")), path)


# The type check (mypy over the packages, 16 to 20 CPU seconds without its cache): it needs no
# kernel, so it runs beside the kernel folders rather than last
_EARLY_FILES = ("tests/shared/test_types.py",)

# The files that run a whole chain once for their tests (the longest files, 100 and 35
# seconds from a fresh clone on 2 shared cores, 2026-12-02)
_CHAIN_FILES = ("tests/workflow/test_workflow.py", "tests/workflow/test_own_scan.py")


def _rank(group: str) -> int:
    """Where a group runs (under ``--no-loadscope-reorder``): the kernel folders and the
    type check first, the chain files next (their Snakemake jobs find the kernels cached by then), the other
    workflow files, then the many short files, which fill the workers' ends instead of a
    long file starting last (the tiny chain last cost a worker 50 s alone)."""
    if group in _KERNEL_FOLDERS or group in _EARLY_FILES:
        return 0
    if group in _CHAIN_FILES:
        return 1
    return 2 if group.startswith("tests/workflow/") else 3


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if getattr(config.option, "loadgroup", False):  # xdist sets it on every worker
        for item in items:
            item.add_marker(pytest.mark.xdist_group(_group(item)))
        items.sort(key=lambda item: _rank(_group(item)))  # stable: files keep their order
    if config.getoption("--run-slow"):
        return
    skip_slow = pytest.mark.skip(reason="slow: run with --run-slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip_slow)


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator, fresh for each test."""
    return np.random.default_rng(20221121)
