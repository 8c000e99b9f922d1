"""Calls shared between a worker and this thread (micro.pool): results in order, every
other call on the executor, all of them here without one."""

import threading
from concurrent.futures import ThreadPoolExecutor

from micro.pool import gathered


def _calls(n: int, threads: list[int | None]) -> list:
    def call(k: int):
        def run() -> int:
            threads[k] = threading.get_ident()
            return 10 * k + 1
        return run
    return [call(k) for k in range(n)]


def test_every_other_call_runs_on_the_executor_and_the_results_keep_their_order():
    here = threading.get_ident()
    threads: list[int | None] = [None] * 5
    with ThreadPoolExecutor(max_workers=1) as executor:
        assert gathered(executor, _calls(5, threads)) == [1, 11, 21, 31, 41]
    assert threads[1] == threads[3] == here
    assert here not in (threads[0], threads[2], threads[4])


def test_without_an_executor_or_with_one_call_everything_runs_here():
    here = threading.get_ident()
    threads: list[int | None] = [None] * 3
    assert gathered(None, _calls(3, threads)) == [1, 11, 21]
    assert threads == [here] * 3
    single: list[int | None] = [None]
    with ThreadPoolExecutor(max_workers=1) as executor:
        assert gathered(executor, _calls(1, single)) == [1]
    assert single == [here]
    assert gathered(None, []) == []
