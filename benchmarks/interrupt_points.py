"""Interrupt ``calidar boresight`` at chosen points rather than moments (issue 27's rare SIGSEGV;
``benchmarks/interrupt_stress.py`` sends signals at moments from outside).

``calls``: each try runs the command in a subprocess that sends itself SIGINT or SIGTERM
(alternately) at its N-th Python call after the CLI's handler is installed (``sys.settrace``
counting calls in the main thread), N uniform in [--lo, --hi]: points spread over the imports
(a warm run makes ≈ 1.73 M calls; its imports end near 300 000, its reader threads start near
420 000). ``inprocess``: --tries runs of ``calidar.cli.run`` in this one process, each interrupted
by a SIGALRM handed to the CLI's own handler at a moment uniform in [--lo, --hi] s (no process
start between tries; the reader threads of one run may still be ending while the next starts).
Counted as ``interrupt_stress.py`` does; a crash ends the loop with its stacks (faulthandler).

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

#: the command as ``calidar`` (its script's name), with the counter set on the CLI's handler
BOOT = """
import os, signal, sys
N, SIG = int(os.environ["INJECT_AT"]), int(os.environ["INJECT_SIG"])
sys.argv = ["calidar"] + sys.argv[1:]
import calidar.cli as cli
from calidar.cli import signals
count = [0]
def tracer(frame, event, arg):
    count[0] += event == "call"
    if count[0] >= N:
        sys.settrace(None)
        os.kill(os.getpid(), SIG)
install = signals.install
def counted():
    install()
    sys.settrace(tracer)
signals.install = counted
cli.main()
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
    from calidar import interrupts
    from calidar.cli import run, signals

    signal.signal(signal.SIGALRM, lambda s, frame: signals._handler(signal.SIGINT, frame))
    interrupts.set_delivery(signals._act)
    codes: dict[int, int] = {}
    work = Path(tempfile.mkdtemp(prefix="interrupt_points_"))
    try:
        for i in range(a.tries):
            signal.setitimer(signal.ITIMER_REAL, rng.uniform(a.lo, a.hi))
            code = run(boresight(a.survey, work / f"out{i}"))
            signal.setitimer(signal.ITIMER_REAL, 0)
            codes[code] = codes.get(code, 0) + 1
            if (i + 1) % 10 == 0:
                print(f"{i + 1} runs: exit codes {codes}", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return {"interrupted": codes.get(130, 0), "completed": codes.get(0, 0),
            "other": sum(v for k, v in codes.items() if k not in (0, 130))}


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
