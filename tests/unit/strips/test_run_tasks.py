"""Independent tasks in this process: in order on threads, errors as raised, what Dask tasks
send back counted, calidar's errors surviving a trip through pickle."""

from __future__ import annotations

import pickle
import threading

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.strips.distribute import TaskLog, Workers, pickled_bytes, run_tasks


def _slow_square(scale, k):
    threading.Event().wait(0.01 * (5 - k % 5))  # later tasks finish first
    return scale * k * k, threading.get_ident()


def test_threads_keep_task_order_and_use_several_threads():
    got = list(run_tasks(_slow_square, [(k,) for k in range(10)], shared=(2,), threads=3))
    assert [v for v, _ in got] == [2 * k * k for k in range(10)]
    assert len({t for _, t in got}) > 1
    assert [v for v, _ in Workers().run(_slow_square, [(k,) for k in range(4)], (1,))] == [0, 1, 4, 9]


def _fails(k):
    if k == 2:
        raise InputError("f.laz", "gps_time", "a bad time")
    return k


def test_a_task_error_reaches_the_caller_as_raised():
    with pytest.raises(InputError, match="f.laz: gps_time: a bad time"):
        list(run_tasks(_fails, [(k,) for k in range(5)], threads=2))


def test_input_errors_survive_pickling():
    e = pickle.loads(pickle.dumps(InputError("a.laz", "x", "metres")))
    assert (e.source, e.field, e.problem, str(e)) == ("a.laz", "x", "metres", "a.laz: x: metres")


def test_task_log_counts_the_pickled_bytes():
    a = {"m": np.zeros((1000, 3)), "k": [1, 2]}
    log = TaskLog()
    log.add("read", a)
    log.add("read", np.zeros(10))
    d = log.to_dict()["read"]
    assert d["tasks"] == 2 and d["bytes_sent_back"] == pickled_bytes(a) + pickled_bytes(np.zeros(10))
    assert pickled_bytes(a) == len(pickle.dumps(a, protocol=5)) and 24_000 < pickled_bytes(a) < 25_000


def _sleep(s):
    threading.Event().wait(s)
    return s


def test_an_abandoned_run_does_not_wait_for_the_tasks_in_flight():
    """An interrupted run (the consumer gone) ends at once; the threads finish on their own."""
    import time

    clock = time.perf_counter()
    run = run_tasks(_sleep, [(0.0,), (3.0,), (3.0,)], threads=2)
    assert next(run) == 0.0
    run.close()
    assert time.perf_counter() - clock < 1.0


def test_thread_map_keeps_item_order_and_runs_items_at_once():
    from calidar.strips.distribute import thread_map

    barrier = threading.Barrier(2, timeout=10)

    def together(k):  # returns only when another call reached the barrier too
        barrier.wait()
        return _slow_square(1, k)

    got = thread_map(together, list(range(6)), threads=2)
    assert [v for v, _ in got] == [k * k for k in range(6)]
    assert len({t for _, t in got}) == 2
    assert thread_map(lambda k: k + 1, [1, 2, 3], threads=1) == [2, 3, 4]
    assert thread_map(lambda k: k, [], threads=2) == []


def test_thread_map_raises_a_call_error_and_drops_the_calls_not_started():
    """An error (or an interruption raised in a call) reaches the caller as raised; the calls
    queued behind it are cancelled, not run after the caller has gone."""
    from calidar.strips.distribute import thread_map

    ran = []

    def work(k):
        if k == 1:
            raise KeyboardInterrupt
        threading.Event().wait(0.05)
        ran.append(k)
        return k

    with pytest.raises(KeyboardInterrupt):
        thread_map(work, list(range(40)), threads=2)
    threading.Event().wait(0.3)
    assert len(ran) < 5
    with pytest.raises(InputError, match="a bad time"):
        thread_map(_fails, list(range(5)), threads=2)
