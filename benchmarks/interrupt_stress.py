"""Interrupt ``calidar boresight`` at many moments and count the runs that do not end cleanly
(issue 27's rare SIGSEGV; the acceptance test is tests/acceptance/test_signals_random.py).

Each try starts ``python -m calidar boresight`` on a small simulated survey (the bad-input
corpus's: ``simulate survey --density 0.02``, simulated once into ``--survey``), waits until
calidar handles SIGTERM (its first line has run, as the test does), sleeps a moment drawn
uniformly in [--min, --max] s, sends SIGINT or SIGTERM (alternately) and checks the end: exit
130 / 143 with the one stderr line "interrupted" (or 0 with the complete output, when the signal
came after the commit). Anything else is counted, with its stderr (``PYTHONFAULTHANDLER=1``: a
crash prints its Python stacks) kept in ``--log``.

    cd /work/wt/segv && nice -n 10 env PYTHONPATH=$PWD/src /work/main/.venv/bin/python \\
        benchmarks/interrupt_stress.py --survey /work/mc/segv/survey --tries 200 --load 2 --cold

``--load K`` runs K busy loops (``python -c "while 1: pass"``) beside the tries, as a loaded CI
machine; ``--perturb`` sets MALLOC_PERTURB_ (freed memory overwritten: a use after free crashes
sooner); ``--threads 4 --min 0 --max 1.5`` counts the moments from the reader threads' start;
``--cold`` gives every try a fresh numba cache and bytecode cache (``NUMBA_CACHE_DIR``,
``PYTHONPYCACHEPREFIX``), as a fresh clone; ``--neighbour`` runs uninterrupted boresight runs
with the same caches beside the tries (pytest-xdist's other worker; with ``--cold`` one fresh cache
that both fill at once).
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

EXPECTED = {"config.toml", "report.html", "sbet_corrected.out", "sensor.toml", "solution.json"}


def argv(survey: Path, out: Path) -> list[str]:
    strips = sorted(map(str, (survey / "strips").glob("*.laz")))
    return [sys.executable, "-m", "calidar", "boresight", *strips, "--trajectory",
            str(survey / "sbet.out"), "--sensor", str(survey / "sensor.toml"), "--out", str(out)]


def wait_for_calidar(proc: subprocess.Popen) -> float:
    """The moment calidar handles SIGTERM in ``proc`` (its first line has run)."""
    while True:
        try:
            with open(f"/proc/{proc.pid}/status") as f:
                caught = next(ln for ln in f if ln.startswith("SigCgt:"))
        except (OSError, StopIteration):
            caught = "SigCgt: 0"
        if int(caught.split()[1], 16) >> (signal.SIGTERM - 1) & 1:
            return time.monotonic()
        if proc.poll() is not None:
            return time.monotonic()
        time.sleep(0.001)


def wait_for_threads(proc: subprocess.Popen, threads: int) -> float:
    """The moment ``proc`` runs ``threads`` threads or more (its reader pool has started)."""
    while proc.poll() is None:
        try:
            if len(os.listdir(f"/proc/{proc.pid}/task")) >= threads:
                break
        except OSError:
            break
        time.sleep(0.001)
    return time.monotonic()


def one_try(survey: Path, work: Path, env: dict, delay: float, signum: int,
            threads: int = 0) -> tuple[str, str]:
    """('interrupted' | 'completed' | 'crash' | 'wrong', what) of one interrupted run: ``delay``
    s after calidar's first line, or after the process runs ``threads`` threads when given."""
    work.mkdir()
    out = work / "out"
    proc = subprocess.Popen(argv(survey, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    wait_for_calidar(proc)
    if threads:
        wait_for_threads(proc, threads)
    time.sleep(delay)
    proc.send_signal(signum)
    stdout, stderr = proc.communicate(timeout=300)
    rc = proc.returncode
    what = f"{signal.Signals(signum).name} after {delay:.3f} s: exit {rc}, stderr {stderr!r}"
    left = sorted(p.name for p in work.iterdir())
    if rc < 0:
        return "crash", what
    if rc == 0 and left == ["out"] and {p.name for p in out.iterdir()} == EXPECTED:
        return "completed", what
    line = "interrupted" + (" (SIGTERM)" if signum == signal.SIGTERM else "")
    if rc == 128 + signum and stderr.strip() == line and not left:
        return "interrupted", what
    return "wrong", f"{what}; left {left}; stdout {stdout[-500:]!r}"


def neighbour(survey: Path, env: dict, work: Path) -> subprocess.Popen:
    """An uninterrupted run beside the tries (restarted by the caller when it ends)."""
    out = Path(tempfile.mkdtemp(dir=work)) / "out"
    return subprocess.Popen(argv(survey, out), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=env)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--survey", type=Path, required=True, help="simulated once when missing")
    p.add_argument("--tries", type=int, default=100)
    p.add_argument("--min", type=float, default=0.3, help="earliest signal, s after first line")
    p.add_argument("--max", type=float, default=3.0, help="latest signal, s after first line")
    p.add_argument("--load", type=int, default=0, help="busy loops beside the tries")
    p.add_argument("--cold", action="store_true", help="fresh numba and bytecode caches a try")
    p.add_argument("--neighbour", action="store_true", help="an uninterrupted run beside")
    p.add_argument("--threads", type=int, default=0,
                   help="count the moment from when the run has this many threads (4: main, the "
                        "progress bar's, two readers)")
    p.add_argument("--perturb", action="store_true",
                   help="glibc fills freed and new memory with a pattern (MALLOC_PERTURB_): a read "
                        "of freed memory shows as a crash or an error, not as luck")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--log", type=Path, default=Path("interrupt_stress.log"))
    a = p.parse_args()
    base = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
            "PYTHONFAULTHANDLER": "1"}
    if a.perturb:
        base["MALLOC_PERTURB_"] = "165"
    if not (a.survey / "sbet.out").exists():
        subprocess.run([sys.executable, "-m", "calidar", "simulate", "survey", "--density",
                        "0.02", "--out", str(a.survey)], check=True, env=base)
    busy = [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(a.load)]
    rng = np.random.default_rng(a.seed)
    counts = {"interrupted": 0, "completed": 0, "crash": 0, "wrong": 0}
    root = Path(tempfile.mkdtemp(prefix="interrupt_stress_"))
    near, ends = None, {}
    try:
        with open(a.log, "a") as log:
            for i in range(a.tries):
                env = dict(base)
                if a.cold:  # with a neighbour: one fresh cache for both, as a fresh clone's
                    caches = root / ("cache" if a.neighbour else f"cache{i}")
                    env.update(NUMBA_CACHE_DIR=str(caches / "numba"),
                               PYTHONPYCACHEPREFIX=str(caches / "pyc"))
                if a.neighbour and (near is None or near.poll() is not None):
                    if near is not None:  # its exit code: 0, or a crash of the neighbour
                        ends[near.returncode] = ends.get(near.returncode, 0) + 1
                    near = neighbour(a.survey, env, root)
                delay = rng.uniform(a.min, a.max)
                kind, what = one_try(a.survey, root / f"run{i}", env, delay,
                                     (signal.SIGINT, signal.SIGTERM)[i % 2], a.threads)
                counts[kind] += 1
                if kind in ("crash", "wrong"):
                    log.write(f"try {i}: {what}\n")
                    log.flush()
                    print(f"try {i}: {kind}: {what[:2000]}", flush=True)
                shutil.rmtree(root / f"run{i}", ignore_errors=True)
                if a.cold and not a.neighbour:
                    shutil.rmtree(root / f"cache{i}", ignore_errors=True)
                if (i + 1) % 10 == 0:
                    print(f"{i + 1} tries: {counts}", flush=True)
    finally:
        for b in busy + ([near] if near else []):
            b.kill()
            b.wait()
        shutil.rmtree(root, ignore_errors=True)
    print(f"{a.tries} tries, {a.min}-{a.max} s after {a.threads or 'calidar'}"
          f"{' threads' if a.threads else ''}, load {a.load}, cold {a.cold}, neighbour "
          f"{a.neighbour}, perturb {a.perturb}: {counts}"
          + (f"; neighbour runs' exit codes {ends}" if a.neighbour else ""))


if __name__ == "__main__":
    main()
