"""A job's task split over the workers (:mod:`multieye.imaging.pool_tasks`): the same result as
in one process, its parts on every worker at once, errors and "no start" passed on."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from multieye.imaging.pool_tasks import OnPool, SplitTask


def _first(items):
    return None if not items else sum(items)


def _each(total, part):
    time.sleep(0.05)            # long enough for the other worker to take the next part
    return [(x * total, threading.current_thread().name) for x in part]


def _join(total, items):
    return total, [x for x, _ in items], {who for _, who in items}


TASK = SplitTask(_first, _each, _join)


@pytest.mark.parametrize("n", [1, 2, 3, 7])
def test_on_the_pool_the_result_is_the_one_of_one_process(n):
    items = list(range(1, n + 1))
    with ThreadPoolExecutor(2, thread_name_prefix="worker") as pool:
        total, values, workers = OnPool(pool, TASK, items, 2).result()
    here_total, here_values, _ = TASK(items)
    assert (total, values) == (here_total, here_values) == (sum(items),
                                                            [x * sum(items) for x in items])
    assert len(workers) == min(n, 2)        # every worker took a part


def test_no_state_is_no_result_and_errors_come_out():
    with ThreadPoolExecutor(2) as pool:
        assert OnPool(pool, TASK, [], 2).result() is None
        assert TASK([]) is None

        def broken(items):
            raise ValueError("no lens")

        with pytest.raises(ValueError, match="no lens"):
            OnPool(pool, SplitTask(broken, _each, _join), [1, 2], 2).result()


def test_a_pool_shut_down_before_the_parts_are_sent_still_gives_the_result():
    gate = threading.Event()

    def first(items):
        gate.wait(5)
        return sum(items)

    pool = ThreadPoolExecutor(2)
    task = OnPool(pool, SplitTask(first, _each, _join), [1, 2, 3], 2)
    pool.shutdown(wait=False)           # no more work may be submitted
    gate.set()
    total, values, _ = task.result()    # the parts run here instead
    assert (total, values) == (6, [6, 12, 18])
