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
import tempfile

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


def test_signals_during_a_lock_step_are_held_back_then_acted_upon(tmp_path, monkeypatch):
    """A signal that falls while a lock file is created or removed is acted upon once the step ends:
    the first raises Interrupted (the lock file is already registered, so the unwinding removes it);
    a second one during the clean-up ends the run only after the file is gone."""
    from calidar.cli import signals

    ended = []
    monkeypatch.setattr(signals, "end_now", lambda signum: ended.append(signum))
    old = signal.signal(signal.SIGINT, signals._handler)
    interrupts.set_delivery(signals._act)
    real_acquire = run_lock._acquire

    def acquire_then_signal(path, shown):
        fd = real_acquire(path, shown)
        os.kill(os.getpid(), signal.SIGINT)  # between the file's creation and its registration
        for _ in range(10_000):
            pass
        return fd

    monkeypatch.setattr(run_lock, "_acquire", acquire_then_signal)
    out = tmp_path / "out"
    try:
        with pytest.raises(interrupts.Interrupted):
            with run_lock.hold(out):
                raise AssertionError("the block must not run after the signal")  # pragma: no cover
        assert list(tmp_path.iterdir()) == [] and run_lock.held_paths() == []

        monkeypatch.setattr(run_lock, "_acquire", real_acquire)
        real_unlink = type(out).unlink

        def unlink_then_signal(self, *a, **k):
            os.kill(os.getpid(), signal.SIGINT)  # the second Ctrl-C, while the lock file is removed
            for _ in range(10_000):
                pass
            return real_unlink(self, *a, **k)

        with run_lock.hold(out) as lock:
            monkeypatch.setattr(type(out), "unlink", unlink_then_signal)
        monkeypatch.setattr(type(out), "unlink", real_unlink)
        assert ended == [signal.SIGINT] and not lock.exists() and run_lock.held_paths() == []
    finally:
        signal.signal(signal.SIGINT, old)


def test_signal_while_the_temporary_folder_is_created_leaves_nothing(tmp_path, monkeypatch):
    from calidar.cli import signals

    old = signal.signal(signal.SIGINT, signals._handler)
    interrupts.set_delivery(signals._act)
    real = tempfile.mkdtemp

    def mkdtemp_then_signal(*a, **k):
        made = real(*a, **k)
        os.kill(os.getpid(), signal.SIGINT)  # the folder exists, not yet registered
        for _ in range(10_000):
            pass
        return made

    monkeypatch.setattr(tempfile, "mkdtemp", mkdtemp_then_signal)
    try:
        with pytest.raises(interrupts.Interrupted):
            with output_folder(tmp_path / "out"):
                raise AssertionError("the block must not run after the signal")  # pragma: no cover
    finally:
        signal.signal(signal.SIGINT, old)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("as_command", [True, False])
def test_the_command_reports_a_crash_with_its_stacks(as_command):
    """The ``calidar`` command (its script's name, as ``calidar`` runs it) prints Python's stacks on
    a crash (faulthandler) rather than dying in silence; a library import changes nothing."""
    name = "sys.argv[0] = 'calidar'; " if as_command else ""
    code = (f"import sys; {name}import calidar, faulthandler, ctypes; "
            "print(faulthandler.is_enabled(), flush=True); ctypes.string_at(0)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                       env={k: v for k, v in os.environ.items() if k != "PYTHONFAULTHANDLER"})
    assert p.returncode == -signal.SIGSEGV
    assert p.stdout.strip() == str(as_command)
    assert ("Fatal Python error: Segmentation fault" in p.stderr) == as_command, p.stderr
    assert ("string_at" in p.stderr) == as_command, p.stderr


def test_memory_release_and_commit_start_no_process(tmp_path, monkeypatch):
    """``malloc_trim`` (once per quality task) and ``renameat2`` (the commit) come from the libc
    this process runs on: no ``/sbin/ldconfig -p`` is started from the multi-threaded run, as
    ``ctypes.util.find_library`` did at every call (strace: 6 in one boresight run on the
    bad-input corpus's survey)."""
    from calidar import outputs
    from calidar.ingest import release_memory

    started = []

    class Spy(subprocess.Popen):
        def __init__(self, args, *a, **k):
            started.append(args)
            super().__init__(args, *a, **k)

    monkeypatch.setattr(subprocess, "Popen", Spy)
    release_memory()
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "new").touch()
    exchanged = outputs._renameat2(a, b)
    assert started == []
    assert not exchanged or ((b / "new").exists() and not (a / "new").exists())


def test_a_signal_while_the_cli_imports_ends_without_finalisation(tmp_path):
    """A Ctrl-C while the CLI's modules load ends the run as every interrupted run ends: one line,
    130, and no interpreter finalisation (which aborted an interrupted run on CI once): an atexit
    function registered before does not run."""
    code = ("import atexit, os, signal, sys; sys.argv = ['calidar', 'info', 'x.laz']; "
            "import calidar; atexit.register(lambda: print('finalised', flush=True)); "
            "os.kill(os.getpid(), signal.SIGINT); import calidar.cli; calidar.cli.main()")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       cwd=tmp_path)
    assert (p.returncode, p.stderr.strip(), p.stdout) == (130, "interrupted", "")


@pytest.mark.parametrize("when", ["install", "after run"])
def test_a_signal_outside_the_run_ends_without_a_traceback(tmp_path, when):
    """A signal as the CLI's handlers are being installed (the handler raises from the next
    bytecode of ``signals.install``: before ``run``'s own ``try``) ends the run "interrupted",
    130; one that falls after ``run`` returned, before the handlers are removed, keeps the run's
    exit code. Never a traceback."""
    hook = {
        "install": ("setsig = signal.signal\n"
                    "def watched(signum, handler):\n"
                    "    old = setsig(signum, handler)\n"
                    "    if getattr(handler, '__name__', '') == '_handler':\n"
                    "        os.kill(os.getpid(), signal.SIGINT)\n"
                    "    return old\n"
                    "signal.signal = watched\n"),
        "after run": ("from calidar.cli import signals\n"
                      "finish, sent = signals.finish, []\n"
                      "def late():\n"
                      "    if not sent:\n"
                      "        sent.append(1)\n"
                      "        os.kill(os.getpid(), signal.SIGINT)\n"
                      "    finish()\n"
                      "signals.finish = late\n"),
    }[when]
    code = ("import os, signal, sys\nsys.argv = ['calidar', 'info', 'missing.laz']\n"
            f"import calidar\n{hook}import calidar.cli\ncalidar.cli.main()\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       cwd=tmp_path)
    assert "Traceback" not in p.stderr, p.stderr
    if when == "install":
        assert (p.returncode, p.stderr.strip()) == (130, "interrupted")
    else:  # the run's own error and code
        assert p.returncode == 1 and "missing.laz" in p.stderr and "interrupted" not in p.stderr


def test_a_run_that_ends_runs_atexit_but_not_the_finalisation(tmp_path):
    """A run whose threads have all ended (here ``--help``): the atexit functions run (the
    temporaries' removal, logging) and the output is flushed, but the interpreter's finalisation
    after them does not (freeing every object one by one: 0.3–0.8 s after a 64 M point run), so
    an object's ``__del__`` left to the finalisation does not run; the exit code stands."""
    code = ("import atexit, sys\nsys.argv = ['calidar', '--help']\nimport calidar.cli\n"
            "class Kept:\n    def __del__(self):\n        print('finalised', flush=True)\n"
            "kept = Kept()\natexit.register(lambda: print('atexit ran'))\ncalidar.cli.main()\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       cwd=tmp_path)
    assert p.returncode == 0 and "Usage" in p.stdout, p.stderr
    assert p.stdout.rstrip().endswith("atexit ran") and "finalised" not in p.stdout
