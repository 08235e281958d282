"""Benchmark: calidar's streamed commands against the floor — reading the same LAZ files.

    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/against_read.py \
        [--size 8.75 | --sim DATA/flight_64M] [--what quality,planes,vgicp] [--runs 3] [--baseline ../main/src]

The survey of ``benchmarks/strips_scale.py`` (8 airborne strips at ≈ ``--size`` million points,
simulated once under ``--cache``, not timed; or ``--sim``: a survey simulated already, such as
``benchmarks/large_flight.py simulate``'s). Each run is a whole child process, interleaved
with the floor in one loop (floor, then each command, ``--runs`` times), so a comparison holds
when the shared machine's speed drifts: the floor is laspy + lazrs decompressing every field of
every file (chunks of 2 M points, laspy's default parallel LAZ backend, as calidar reads);
``quality`` is ``python -m calidar quality STRIPS --out`` and ``planes`` / ``vgicp`` ``python -m
calidar boresight STRIPS --trajectory --sensor --method --out`` (ingest, calibration, the three
overlap-quality stages, report, outputs), whole commands as a user runs them, so that another
version's (``--baseline``) run the same way. Printed per command: the median wall and CPU time,
the median of each run's ratio to the floor run just before it, the peak RSS (``os.wait4``) and
the load average at each run.

The CPU is the whole process tree's: this process makes itself the children's subreaper
(``prctl(PR_SET_CHILD_SUBREAPER)``), so the VGICP workers' forkserver, which the command leaves to
exit after it and never waits for, is reparented here and waited for too, with the workers it
reaped (before the twelfth session the figures left them out: VGICP's CPU read low). "tree" is the
peak of the tree's summed proportional set size (``/proc/PID/smaps_rollup``, sampled every 50 ms):
the memory the command's processes hold together, each shared page counted once.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np



def child(sim: Path) -> None:
    """The floor: laspy + lazrs decompressing every field of every file (a JSON line: the points)."""
    import laspy

    n = 0
    for path in sorted((sim / "strips").glob("*.laz")):
        with laspy.open(path) as reader:
            for rec in reader.chunk_iterator(2_000_000):
                n += len(rec)
    print(json.dumps({"points": n}))


def command(sim: Path, what: str, out: Path) -> list[str]:
    """The child's command line: the floor, or the ``calidar`` command as a user runs it."""
    strips = [str(p) for p in sorted((sim / "strips").glob("*.laz"))]
    if what == "read":
        return [sys.executable, __file__, "--child", str(sim)]
    if what == "quality":
        return [sys.executable, "-m", "calidar", "quality", *strips, "--out", str(out), "--force"]
    return [sys.executable, "-m", "calidar", "boresight", *strips, "--trajectory", str(sim / "sbet.out"), "--sensor",
            str(sim / "sensor.toml"), "--method", what, "--out", str(out), "--force"]


def _subreaper() -> None:
    """Make this process the subreaper of its descendants (Linux ``PR_SET_CHILD_SUBREAPER``): an
    orphan (the forkserver once the command exits) is reparented here, and its CPU can be waited for."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(36, 1, 0, 0, 0) != 0:  # 36: PR_SET_CHILD_SUBREAPER
        raise SystemExit(f"prctl(PR_SET_CHILD_SUBREAPER) failed: errno {ctypes.get_errno()}")


def _descendants(root: int) -> list[int]:
    """``root`` and every process below it now (by /proc/*/stat's parent pids)."""
    parent: dict[int, int] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    parent[int(d)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
    tree, grew = {root}, True
    while grew:
        new = {p for p, pp in parent.items() if pp in tree and p not in tree}
        tree |= new
        grew = bool(new)
    return sorted(tree)


def _tree_pss_bytes(root: int) -> int:
    """The summed proportional set size of ``root``'s process tree (bytes)."""
    total = 0
    for pid in _descendants(root):
        try:
            with open(f"/proc/{pid}/smaps_rollup") as f:
                total += next(int(line.split()[1]) * 1024 for line in f if line.startswith("Pss:"))
        except (OSError, StopIteration, ValueError):
            continue
    return total


def _sample_tree(root: int, stop: threading.Event, peak: list[int]) -> None:
    """Keep in ``peak[0]`` the largest summed PSS of ``root``'s tree, every 50 ms until ``stop``."""
    while not stop.wait(0.05):
        peak[0] = max(peak[0], _tree_pss_bytes(root))


def _wait_orphans(deadline_s: float = 30.0) -> float:
    """Wait for the descendants reparented here (the forkserver and what it reaped): their CPU s."""
    cpu, end = 0.0, time.monotonic() + deadline_s
    while True:
        try:
            pid, _, usage = os.wait4(-1, os.WNOHANG)
        except ChildProcessError:
            return cpu
        if pid == 0:
            if time.monotonic() > end:
                raise SystemExit("a descendant of the command did not exit within 30 s")
            time.sleep(0.02)
            continue
        cpu += usage.ru_utime + usage.ru_stime


def run(sim: Path, what: str, src: Path | None = None) -> dict:
    """A child run (importing calidar from ``src``, default this checkout's): wall and CPU
    seconds of its whole process tree, peak RSS of its main process and summed PSS of its tree
    (GiB), the load average before it."""
    env = {**os.environ, "PYTHONPATH": str(src or Path(__file__).resolve().parents[1] / "src")}
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as out:
        t = time.perf_counter()
        proc = subprocess.Popen(command(sim, what, Path(out) / "out"), env=env, stdout=subprocess.PIPE, text=True)
        stop, peak = threading.Event(), [0]
        sampler = threading.Thread(target=_sample_tree, args=(proc.pid, stop, peak), daemon=True)
        sampler.start()
        text = proc.stdout.read()
        stop.set()  # the tree is sampled while the command runs (its stdout closes as it exits)
        sampler.join()
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t
        orphans_cpu = _wait_orphans()
    if os.waitstatus_to_exitcode(status) not in (0, 3):  # 3: a FAIL verdict, outputs written
        raise SystemExit(f"run failed: {sim} {what}")
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime + orphans_cpu,
            "rss_gib": usage.ru_maxrss * 1024 / 2**30, "tree_gib": peak[0] / 2**30,
            "load": load, "out": json.loads(text.strip().splitlines()[-1]) if what == "read" else None}


def _which(label: str, baseline: Path | None) -> tuple[str, Path | None]:
    """(command, source tree) of a label ("quality", "quality@base")."""
    return (label[:-5], baseline) if label.endswith("@base") else (label, None)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=8.75, help="survey size, million points")
    ap.add_argument("--what", default="quality,planes", help="commands: quality, planes, vgicp")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=1, help="unmeasured rounds first (page cache, numba caches)")
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "calidar_bench_strips_scale")
    ap.add_argument("--baseline", type=Path, help="another calidar source tree (e.g. main's src/): its runs "
                    "interleaved too, labelled @base")
    ap.add_argument("--sim", type=Path, help="a survey simulated already (strips/*.laz, sbet.out, sensor.toml), "
                    "e.g. benchmarks/large_flight.py's DATA/flight_64M, instead of --size's")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(Path(args.child))
    _subreaper()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from strips_scale import simulate  # the shared 8-strip survey at a size

    sim = args.sim if args.sim else simulate(args.cache, args.size)
    what = args.what.split(",")
    if args.baseline:
        what += [f"{w}@base" for w in what]
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS')} OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}; "
          f"{sim.name}", flush=True)
    for _ in range(args.warmup):  # the files in the page cache, numba's caches compiled
        run(sim, "read")
        for w in what:
            run(sim, *_which(w, args.baseline))
    rows: dict[str, list[dict]] = {w: [] for w in ["read", *what]}
    for k in range(args.runs):
        floor = run(sim, "read")
        rows["read"].append(floor)
        for w in what:
            r = run(sim, *_which(w, args.baseline))
            r["ratio"] = r["wall_s"] / floor["wall_s"]
            r["cpu_ratio"] = r["cpu_s"] / floor["cpu_s"]
            rows[w].append(r)
            print(f"run {k + 1}: {w:13s} {r['wall_s']:6.2f} s (floor {floor['wall_s']:5.2f} s: {r['ratio']:.2f}×), "
                  f"CPU {r['cpu_s']:6.2f} s, peak {r['rss_gib']:.2f} GiB (tree {r['tree_gib']:.2f}), "
                  f"load {r['load']:.2f}", flush=True)
    points = rows["read"][0]["out"]["points"]
    print(f"{points / 1e6:.2f} M points; medians of {args.runs} interleaved runs:")
    for w, rs in rows.items():
        med = {k: float(np.median([r[k] for r in rs])) for k in ("wall_s", "cpu_s", "rss_gib", "tree_gib", "load")}
        ratio = f"{np.median([r['ratio'] for r in rs]):.2f}× wall, {np.median([r['cpu_ratio'] for r in rs]):.2f}× CPU" \
            if w != "read" else "(the floor)"
        print(f"  {w:13s} {med['wall_s']:6.2f} s wall, {med['cpu_s']:6.2f} s CPU, peak {med['rss_gib']:.2f} GiB "
              f"(tree {med['tree_gib']:.2f}), {ratio}; load {min(r['load'] for r in rs):.1f}–{max(r['load'] for r in rs):.1f}", flush=True)


if __name__ == "__main__":
    main()
