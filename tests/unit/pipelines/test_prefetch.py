"""Chunks decompressed ahead in a thread (calidar.ingest.prefetch): the same items in order, the
reader's error raised in the caller, the reader closed when the caller stops early."""

import threading

import pytest

from calidar.errors import InputError
from calidar.ingest.prefetch import prefetched


def test_items_in_order_and_produced_in_another_thread():
    threads = []

    def gen():
        for k in range(50):
            threads.append(threading.current_thread())
            yield k

    assert list(prefetched(gen(), depth=2)) == list(range(50))
    assert all(t is not threading.current_thread() for t in threads)


def test_reader_error_raised_in_the_caller_after_the_items_before_it():
    def gen():
        yield 1
        yield 2
        raise InputError("a.laz", "points", "expected more")

    got = []
    with pytest.raises(InputError, match="a.laz"):
        for x in prefetched(gen()):
            got.append(x)
    assert got == [1, 2]


def test_stopping_early_closes_the_reader():
    closed = threading.Event()

    def gen():
        try:
            for k in range(10**6):
                yield k
        finally:
            closed.set()

    it = prefetched(gen())
    assert next(it) == 0 and next(it) == 1
    it.close()
    assert closed.wait(5)
