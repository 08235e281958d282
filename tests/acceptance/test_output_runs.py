"""An output folder belongs to one run (issue 27): real subprocesses on the bad-input corpus's
simulated survey. Two concurrent runs into one folder: the second is refused naming the first,
whose result is complete and alone; ``--force`` leaves exactly the new run's files; a commit that
cannot be made leaves the previous folder byte-identical; a stale lock (its process gone) is taken
over; a full disk and a read-only destination are one line naming ``--out`` (test_disk_full.py)."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from calidar import outputs, run_lock

ENV = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
BORESIGHT_FILES = {"config.toml", "report.html", "sbet_corrected.out", "sensor.toml", "solution.json"}


def _boresight(corpus, out, strips=None, *extra):
    s = corpus.root / "survey"
    strips = strips or sorted((s / "strips").glob("*.laz"))
    return [sys.executable, "-m", "calidar", "boresight", *map(str, strips), "--trajectory", str(s / "sbet.out"),
            "--sensor", str(s / "sensor.toml"), "--out", str(out), *extra]


def _run(argv):
    r = subprocess.run(argv, capture_output=True, text=True, env=ENV, timeout=300)
    return r.returncode, r.stdout, r.stderr


def _tree(folder):
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _error_line(err):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    return lines[0]


def test_second_run_into_the_same_folder_is_refused(corpus, tmp_path):
    out = tmp_path / "out"
    first = subprocess.Popen(_boresight(corpus, out, None, "--write-strips"), stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=ENV)
    lock = run_lock.lock_path(out)
    deadline = time.monotonic() + 120
    while not (lock.exists() and lock.read_text()):  # the first run holds --out
        assert first.poll() is None and time.monotonic() < deadline, first.communicate()
        time.sleep(0.02)
    s = corpus.root / "survey"
    second = [_boresight(corpus, out, sorted((s / "strips").glob("*.laz"))[:2]),
              [sys.executable, "-m", "calidar", "quality", *map(str, sorted((s / "strips").glob("*.laz"))),
               "--out", str(out)]]
    # the first run held stopped while the others try: it would otherwise finish first on a fast
    # machine (it did once the calibration needed fewer outer iterations: the others then met its
    # finished folder instead of its lock)
    first.send_signal(signal.SIGSTOP)
    try:
        for argv in second:  # a boresight of other strips and a quality run, while the first runs
            code, _, err = _run(argv)
            line = _error_line(err)
            assert code == 1, err
            assert f"{out}: in use by another calidar run (pid {first.pid}, started " in line, line
            assert "calidar boresight" in line and "UTC" in line, line
    finally:
        first.send_signal(signal.SIGCONT)
    _, err = first.communicate(timeout=300)
    assert first.returncode == 0, err
    n = len(list((s / "strips").glob("*.laz")))
    assert {p.name for p in out.iterdir()} == BORESIGHT_FILES | {f"strip_{i}.laz" for i in range(1, n + 1)}
    assert {p.name for p in tmp_path.iterdir()} == {"out"}  # no lock, no temporary left


def test_force_leaves_exactly_the_new_runs_files(corpus, tmp_path):
    s = corpus.root / "survey"
    strips = sorted((s / "strips").glob("*.laz"))
    out = tmp_path / "out"
    code, _, err = _run(_boresight(corpus, out, strips, "--write-strips"))
    assert code == 0, err
    assert (out / f"strip_{len(strips)}.laz").exists()
    (out / "notes.txt").write_text("a file of the user's in the old folder\n")
    code, _, err = _run(_boresight(corpus, out, strips[:-1], "--write-strips", "--force"))
    assert code == 0, err
    assert {p.name for p in out.iterdir()} == BORESIGHT_FILES | {f"strip_{i}.laz" for i in range(1, len(strips))}
    assert json.loads((out / "solution.json").read_text())  # the new run's, complete
    assert {p.name for p in tmp_path.iterdir()} == {"out"}


def test_force_never_touches_an_input_inside_the_output(corpus, tmp_path):
    """An --out holding an input is refused, --force or not (the input would go with the folder)."""
    s = corpus.root / "survey"
    out = tmp_path / "out"
    out.mkdir()
    strip = out / "line_001.laz"
    strip.write_bytes((s / "strips" / "line_001.laz").read_bytes())
    before = _tree(out)
    code, _, err = _run(_boresight(corpus, out, [strip, *sorted((s / "strips").glob("*.laz"))[1:]], "--force"))
    assert code == 1 and "holds the input" in _error_line(err), err
    assert _tree(out) == before


def test_commit_that_cannot_be_made_leaves_the_old_folder(tmp_path):
    """--out is a mount point: the finished run cannot take its place; the old folder stays as it was."""
    out = tmp_path / "out"
    out.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(out)], capture_output=True).returncode:
        pytest.skip("mounting a tmpfs is not permitted here")
    try:
        (out / "observations.csv").write_text("the previous run's\n")
        (out / "sub").mkdir()
        (out / "sub" / "old.txt").write_text("old\n")
        before = _tree(out)
        code, _, err = _run([sys.executable, "-m", "calidar", "simulate", "total-station", "--out", str(out),
                             "--force"])
        assert code == 1, err
        assert f"{out}: cannot replace the folder" in _error_line(err)
        assert "the previous result is left as it was" in err
        assert _tree(out) == before
        assert {p.name for p in tmp_path.iterdir()} == {"out"}
    finally:
        subprocess.run(["umount", str(out)], check=True)


def test_commit_failing_between_its_two_renames_restores_the_old_folder(tmp_path, monkeypatch):
    """Where the kernel cannot exchange two folders in one step, the commit is two renames; when the
    second fails, the first is undone: the old folder byte-identical, the new run's gone."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.json").write_text('{"old": 1}')
    (out / "strip_4.laz").write_bytes(b"old strip")
    before = _tree(out)
    monkeypatch.setattr(outputs, "_renameat2", lambda a, b: False)
    real_rename, calls = os.rename, []

    def rename(src, dst):
        calls.append((src, dst))
        if len(calls) == 2:  # the new folder onto --out
            raise OSError(28, "No space left on device", str(dst))
        return real_rename(src, dst)

    monkeypatch.setattr(outputs.os, "rename", rename)
    with pytest.raises(Exception, match="cannot replace the folder"):
        with outputs.output_folder(out, force=True) as tmp:
            (tmp / "a.json").write_text('{"new": 1}')
    assert len(calls) == 3  # aside, onto (failed), back
    assert _tree(out) == before
    assert {p.name for p in tmp_path.iterdir()} == {"out"}


def test_stale_lock_of_a_dead_run_is_taken_over(corpus, tmp_path):
    """A lock file left by a killed run (its flock gone with it) does not block the next run."""
    out = tmp_path / "out"
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    run_lock.lock_path(out).write_text(json.dumps({"pid": dead.pid, "command": "calidar boresight (killed)",
                                                   "started": "2026-01-01 00:00:00 UTC"}))
    code, _, err = _run([sys.executable, "-m", "calidar", "simulate", "total-station", "--out", str(out)])
    assert code == 0, err
    assert {p.name for p in tmp_path.iterdir()} == {"out"}
