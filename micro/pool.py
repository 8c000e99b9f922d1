"""The measurement worker of a micro run, and the independent calls it shares with this thread.

The worker is :func:`measurement_executor`'s process (pyamg's cycles and CHOLMOD hold
the GIL, so a thread would not overlap them); the calls are the steady solves of a
checkpoint's permeability measurements (:mod:`micro.permeability`), shared by
:func:`gathered`.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import AbstractContextManager, contextmanager, nullcontext
from logging.handlers import QueueHandler, QueueListener
from multiprocessing.queues import Queue

import numba
from threadpoolctl import threadpool_limits

__all__ = ["gathered", "measurement_executor", "measuring"]

MEASUREMENT_PROCESS_CELLS = 100_000
"""Cells from which a worker process makes the permeability solves (:func:`measurement_executor`)."""
WORKER_NICENESS = 10
"""Niceness the measurement worker adds to its own (the hydration goes first)."""
WORKER_PARENT_POLL_S = 1.0
"""Interval [s] at which the measurement worker checks that the run's process lives."""

log = logging.getLogger("micro")


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


@contextmanager
def measuring(n_cells: int) -> Iterator[Executor | None]:
    """The measurement worker of a mesh of ``n_cells`` cells (:func:`measurement_executor`),
    with one BLAS thread in this process: numba's kernels own the job's threads, and an
    idle OpenBLAS thread spins after every call (pyamg's norms), taking the core the
    worker solves on."""
    with measurement_executor(n_cells) as executor, threadpool_limits(1, user_api="blas"):
        yield executor


def measurement_executor(n_cells: int) -> AbstractContextManager[Executor | None]:
    """A worker process for the checkpoints' permeability solves, or None.

    It makes the eight solves of a checkpoint while this process hydrates towards the
    next (a save of the state waits for them), and half of those of the last checkpoint,
    of a checkpoint reached while it still measures the one before or with a save
    overdue. One process beside this one when the job has two threads or more (numba's,
    as the Snakemake job sets them) and the mesh has ``MEASUREMENT_PROCESS_CELLS`` cells
    or more (below, the mesh's transfer and the process's start cost more than they
    save).
    A process, not a thread: pyamg's cycles and CHOLMOD hold the GIL. The worker is
    spawned (forking a process whose OpenMP threads run is unsafe) and runs numba and
    BLAS on one thread at a lower priority; its log records go to this process's
    handlers (the case's log). A script that runs the micro stage must guard its main
    code with ``if __name__ == "__main__":``, since the spawned worker imports it.
    """
    if numba.get_num_threads() < 2 or n_cells < MEASUREMENT_PROCESS_CELLS:
        return nullcontext(None)
    log.info("measurements: the permeability solves in a worker process, in the "
             "background while the run hydrates")
    return _worker_pool()


@contextmanager
def _worker_pool() -> Iterator[Executor]:
    """The spawned measurement worker, its log records relayed to this process's."""
    context = multiprocessing.get_context("spawn")
    records = context.Queue()
    root = logging.getLogger()
    relay = QueueListener(records, *root.handlers, respect_handler_level=True)
    relay.start()
    try:
        with ProcessPoolExecutor(1, mp_context=context, initializer=_measurement_worker,
                                 initargs=(records, root.level)) as executor:
            yield executor
    finally:
        relay.stop()


def _measurement_worker(records: Queue, level: int) -> None:
    """The worker runs numba and BLAS on one thread and yields the cores to the
    hydration, the run's critical path, whenever its threads want both (niceness
    ``WORKER_NICENESS``). Its log records go to ``records`` at the run's ``level``. It
    exits when the run's process dies: a killed run leaves no orphan that keeps solving
    and holding a copy of the mesh (gigabytes at 300k points). It ignores Ctrl-C: the
    run's process stops when the task under way returns, and reports the interrupt in one
    line (a worker ended by it would end the run with a broken pool's traceback)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    root = logging.getLogger()
    root.handlers[:] = [QueueHandler(records)]
    root.setLevel(level)
    numba.set_num_threads(1)
    threadpool_limits(1, user_api="blas")
    os.nice(WORKER_NICENESS)
    threading.Thread(target=_exit_with_parent, args=(os.getppid(),), daemon=True).start()


def _exit_with_parent(parent: int) -> None:
    """Exit this process once ``parent`` is no longer its parent (it died)."""
    while os.getppid() == parent:
        time.sleep(WORKER_PARENT_POLL_S)
    os._exit(1)
