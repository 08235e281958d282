"""The in-process reader pool waits for its threads when it closes (issue 27): a thread left inside
a native decoder when the interpreter exits is unwound by force and aborts the process ("FATAL:
exception not rethrown", exit 134) after the run's own error; calls not started are cancelled."""

from __future__ import annotations

import threading
import time

import pytest

from calidar.strips.distribute import _DaemonPool, run_tasks


def test_close_waits_for_the_running_call_and_cancels_the_rest():
    pool = _DaemonPool(1)
    finished = []
    running = pool.submit(lambda: (time.sleep(0.3), finished.append(1)))
    queued = [pool.submit(finished.append, 2) for _ in range(5)]
    time.sleep(0.05)  # the first call is running, the others wait
    pool.close()
    assert finished == [1] and running.done()
    assert all(f.cancelled() for f in queued)
    assert not any(t.is_alive() for t in pool.threads)


def test_an_error_in_one_file_leaves_no_reader_thread_running():
    """run_tasks over two threads: one task fails while the other still reads; when the error
    reaches the caller, no reader thread is alive."""
    before = threading.active_count()

    def read(i):
        if i == 0:
            raise ValueError("truncated file")
        time.sleep(0.3)
        return i

    with pytest.raises(ValueError, match="truncated"):
        list(run_tasks(read, [(i,) for i in range(6)], threads=2))
    assert threading.active_count() == before
