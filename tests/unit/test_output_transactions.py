"""Output transactions and signals (issue 27), in-process: a signal Python drops (raised inside a
garbage-collector callback it becomes an "Exception ignored" report) still stops the commit; a
committed run is not interrupted afterwards; the lock is re-entrant in a process and refuses
another process naming it."""

from __future__ import annotations

import gc
import os
import signal
import subprocess
import sys

import pytest

from calidar import interrupts, run_lock
from calidar.errors import OutputExistsError
from calidar.outputs import output_folder


@pytest.fixture(autouse=True)
def _fresh():
    interrupts.reset()
    yield
    interrupts.reset()


def test_signal_swallowed_in_a_gc_callback_still_stops_the_commit(tmp_path, monkeypatch):
    from calidar.cli import signals

    swallowed, fired = [], []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: swallowed.append(u.exc_type))

    def callback(phase, info):
        if phase == "start" and not fired:
            fired.append(1)
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(10_000):  # the handler runs here, inside the callback: Python drops its exception
                pass

    old = signal.signal(signal.SIGINT, signals._handler)
    gc.callbacks.append(callback)
    out = tmp_path / "out"
    try:
        with pytest.raises(interrupts.Interrupted):
            with output_folder(out) as tmp:
                (tmp / "a.json").write_text("{}")
                gc.collect()
                (tmp / "b.json").write_text("{}")  # the run went on: the signal was dropped
        assert swallowed == [interrupts.Interrupted] and fired
    finally:
        gc.callbacks.remove(callback)
        signal.signal(signal.SIGINT, old)
    assert list(tmp_path.iterdir()) == []  # not committed, nothing left


def test_a_committed_run_is_not_interrupted(tmp_path):
    with output_folder(tmp_path / "out") as tmp:
        (tmp / "a.json").write_text("{}")
    assert interrupts.committed()
    interrupts.record(signal.SIGTERM)
    interrupts.check()  # no exception: the result is complete
    assert interrupts.pending() is None and (tmp_path / "out" / "a.json").exists()


def test_lock_is_reentrant_and_refuses_another_process(tmp_path):
    out = tmp_path / "out"
    with run_lock.hold(out):
        with run_lock.hold(out):  # the same run claims it again (e.g. quality, then its output folder)
            pass
        assert run_lock.lock_path(out).exists()
        code = ("import sys; from calidar import run_lock\n"
                "try:\n    run_lock.hold(sys.argv[1]).__enter__()\nexcept Exception as e:\n    print(e)")
        r = subprocess.run([sys.executable, "-c", code, str(out)], capture_output=True, text=True, timeout=60)
        assert f"in use by another calidar run (pid {os.getpid()}, started " in r.stdout, r.stdout + r.stderr
    assert not run_lock.lock_path(out).exists()
    with pytest.raises(OutputExistsError, match="not empty"):
        out.mkdir()
        (out / "x").write_text("x")
        with output_folder(out):
            pass
