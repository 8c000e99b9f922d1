"""Independent calls of a micro run shared between a worker and this thread.

The worker is :func:`micro.run.measurement_executor`'s process (pyamg's cycles and
CHOLMOD hold the GIL, so a thread would not overlap them); the calls are the steady
solves of a checkpoint's permeability measurements (:mod:`micro.permeability`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Executor

__all__ = ["gathered"]


def _called(calls: Sequence[Callable[[], object]]) -> list:
    return [call() for call in calls]


def gathered(executor: Executor | None, calls: Sequence[Callable[[], object]]) -> list:
    """Results of independent calls, in order: every other call on ``executor`` (one
    task, so that a worker process receives the mesh they share once) while this thread
    makes the others, or all of them here."""
    if executor is None or len(calls) < 2:
        return _called(calls)
    remote = executor.submit(_called, calls[0::2])
    results: list = [None] * len(calls)
    results[1::2] = _called(calls[1::2])
    results[0::2] = remote.result()
    return results
