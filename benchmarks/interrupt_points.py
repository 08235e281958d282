"""Interrupt ``calidar boresight`` at chosen points rather than moments (issue 27's rare SIGSEGV;
``benchmarks/interrupt_stress.py`` sends signals at moments from outside).

``calls``: each try runs ``python -m calidar boresight`` in a subprocess that sends itself SIGINT
or SIGTERM (alternately) at its N-th Python call after the CLI has installed its handler
(``sys.settrace`` counting calls in the main thread), N uniform in [--lo, --hi]: points spread
over the imports (a warm run makes ≈ 1.73 M calls; its imports end near 300 000, its reader
threads start near 420 000). Counted as ``interrupt_stress.py`` does. ``inprocess``: --tries runs
of the library's boresight calibration and output in this one process, each cut at a moment
uniform in [--lo, --hi] s by a handler acting as the CLI's (no process start between tries; the
reader threads of one run may still be ending while the next starts); a crash ends the loop
with its stacks (faulthandler).

    cd /work/wt/segv && nice -n 10 env PYTHONPATH=$PWD/src /work/main/.venv/bin/python \\
        benchmarks/interrupt_points.py calls --survey /work/mc/segv/survey --lo 1 --hi 450000
    MALLOC_PERTURB_=165 PYTHONFAULTHANDLER=1 nice -n 10 env PYTHONPATH=$PWD/src \\
        /work/main/.venv/bin/python benchmarks/interrupt_points.py inprocess \\
        --survey /work/mc/segv/survey --lo 0.05 --hi 3 --tries 300
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

#: ``python -m calidar`` started as the ``calidar`` command, the counter set when the CLI installs
#: its handler (``signal.signal`` given the function ``_handler``)
BOOT = """
import os, runpy, signal, sys
N, SIG = int(os.environ["INJECT_AT"]), int(os.environ["INJECT_SIG"])
sys.argv = ["calidar"] + sys.argv[1:]
count = [0]
def tracer(frame, event, arg):
    count[0] += event == "call"
    if count[0] >= N:
        sys.settrace(None)
        os.kill(os.getpid(), SIG)
setsig = signal.signal
def watched(signum, handler):
    old = setsig(signum, handler)
    if signum == signal.SIGTERM and getattr(handler, "__name__", "") == "_handler":
        sys.settrace(tracer)
    return old
signal.signal = watched
runpy.run_module("calidar", run_name="__main__", alter_sys=True)
"""


def boresight(survey: Path, out: Path) -> list[str]:
    strips = sorted(map(str, (survey / "strips").glob("*.laz")))
    return ["boresight", *strips, "--trajectory", str(survey / "sbet.out"), "--sensor",
            str(survey / "sensor.toml"), "--out", str(out)]


def calls(a, rng) -> dict:
    counts = {"interrupted": 0, "completed": 0, "crash": 0, "wrong": 0}
    for i in range(a.tries):
        n, sig = int(rng.integers(int(a.lo), int(a.hi))), (signal.SIGINT, signal.SIGTERM)[i % 2]
        work = Path(tempfile.mkdtemp(prefix="interrupt_points_"))
        env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
               "PYTHONFAULTHANDLER": "1", "INJECT_AT": str(n), "INJECT_SIG": str(int(sig))}
        p = subprocess.run([sys.executable, "-c", BOOT, *boresight(a.survey, work / "out")],
                           capture_output=True, text=True, env=env, timeout=600)
        line = "interrupted" + (" (SIGTERM)" if sig == signal.SIGTERM else "")
        left = os.listdir(work)
        kind = ("crash" if p.returncode < 0 else "completed" if p.returncode == 0 else
                "interrupted" if p.returncode == 128 + sig and p.stderr.strip() == line
                and not left else "wrong")
        counts[kind] += 1
        if kind in ("crash", "wrong"):
            print(f"call {n}, {sig.name}: exit {p.returncode}, left {left}, {p.stderr!r}")
        shutil.rmtree(work, ignore_errors=True)
        if (i + 1) % 10 == 0:
            print(f"{i + 1} tries: {counts}", flush=True)
    return counts


def inprocess(a, rng) -> dict:
    """The library's run (``calibrate_strips`` with ``StripConfig()``, then ``write``) again and
    again, each cut by a handler acting as the CLI's: the first signal raises ``Interrupted``
    unless the result is committed or a short step holds signals back (then acted upon at its
    end)."""
    import calidar
    from calidar import interrupts

    def handler(signum, frame):
        interrupts.record(signal.SIGINT)
        if not (interrupts.committed() or interrupts.is_deferred()):
            raise interrupts.Interrupted(signal.SIGINT)

    def deliver():
        if interrupts.pending() is not None:
            raise interrupts.Interrupted(interrupts.pending())

    signal.signal(signal.SIGALRM, handler)
    interrupts.set_delivery(deliver)
    s = a.survey
    strips = sorted((s / "strips").glob("*.laz"))
    counts = {"interrupted": 0, "completed": 0}
    work = Path(tempfile.mkdtemp(prefix="interrupt_points_"))
    try:
        for i in range(a.tries):
            interrupts.reset()
            signal.setitimer(signal.ITIMER_REAL, rng.uniform(a.lo, a.hi))
            try:
                run = calidar.calibrate_strips(strips, s / "sbet.out", s / "sensor.toml",
                                               calidar.StripConfig())
                run.write(work / f"out{i}")
                counts["completed"] += 1
            except KeyboardInterrupt:
                counts["interrupted"] += 1
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            if (i + 1) % 10 == 0:
                print(f"{i + 1} runs: {counts}", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return counts


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("mode", choices=["calls", "inprocess"])
    p.add_argument("--survey", type=Path, required=True, help="from interrupt_stress.py")
    p.add_argument("--tries", type=int, default=100)
    p.add_argument("--lo", type=float, required=True, help="first call / earliest moment (s)")
    p.add_argument("--hi", type=float, required=True, help="last call / latest moment (s)")
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args()
    rng = np.random.default_rng(a.seed)
    counts = (calls if a.mode == "calls" else inprocess)(a, rng)
    print(f"{a.mode} {a.lo:g}-{a.hi:g}, {a.tries} tries: {counts}")


if __name__ == "__main__":
    main()
