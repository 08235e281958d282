"""Benchmark: where `calidar boresight`'s peak memory is set, and what is alive there (issue 32).

    nice -n 10 env NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/peak_memory.py \
        DATA/flight_8.75M [--method planes] [--alive 12] [--top 25]

Runs ``calidar boresight``'s pipeline in this process (:func:`calidar.pipelines.boresight.calibrate_strips`,
default settings, outputs into a temporary folder; the flight of ``benchmarks/large_flight.py simulate``)
with a thread reading ``VmRSS`` of ``/proc/self/status`` every 20 ms, each sample labelled with the stage
the progress last named. Prints per stage its time span and largest RSS, the sample at the peak and the
process's ``VmHWM``.

``--alive N``: tracemalloc on (N frames a trace; it slows the run and its own bookkeeping adds to the RSS),
a snapshot whenever the traced memory grew 20 MiB past its largest so far; printed: the traced total at
its peak and the RSS then, and the ``--top`` sites holding most of it (the last three calidar frames of
each allocation's stack: what allocated the arrays alive at the peak). numpy's and numba's arrays are
traced; memory glibc keeps after a free and the libraries' own are not: RSS − traced.
"""

from __future__ import annotations

import argparse
import collections
import tempfile
import threading
import time
import tracemalloc
from pathlib import Path


def rss_gib(field: str = "VmRSS") -> float:
    """This process's resident (or, ``VmHWM``, peak resident) memory, GiB."""
    with open("/proc/self/status") as f:
        return next(int(ln.split()[1]) for ln in f if ln.startswith(field)) / 2**20


def sites(snapshot: tracemalloc.Snapshot, top: int) -> list[tuple[float, str]]:
    """(MiB, the last three calidar frames) of the ``top`` largest allocation sites."""
    held: collections.Counter = collections.Counter()
    for trace in snapshot.traces:
        frames = [f"{f.filename.split('/src/')[-1]}:{f.lineno}" for f in trace.traceback
                  if "calidar" in f.filename and "benchmarks" not in f.filename]
        held[" > ".join(frames[-3:]) or "(outside calidar)"] += trace.size
    return [(size / 2**20, where) for where, size in held.most_common(top)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("sim", type=Path, help="a flight of large_flight.py simulate (strips/, sbet.out, sensor.toml)")
    ap.add_argument("--method", default="planes")
    ap.add_argument("--alive", type=int, default=0, help="tracemalloc with this many frames (0: off)")
    ap.add_argument("--top", type=int, default=25)
    args = ap.parse_args()

    from calidar.pipelines.boresight import calibrate_strips
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import CalibrationConfig, matchers_named

    if args.alive:
        tracemalloc.start(args.alive)
    t0, stage, samples, stop = time.perf_counter(), ["start"], [], threading.Event()
    peak = {"traced": 0, "snapshot": None, "rss": 0.0, "stage": ""}

    def sample() -> None:
        while not stop.wait(0.02):
            samples.append((time.perf_counter() - t0, rss_gib(), stage[0]))
            traced = tracemalloc.get_traced_memory()[0] if args.alive else 0
            if args.alive and traced > peak["traced"] + 20 * 2**20:
                peak.update(traced=traced, snapshot=tracemalloc.take_snapshot(), rss=rss_gib(),
                            stage=stage[0])

    def progress(description: str, done: int, total: int) -> None:
        stage[0] = description.split(":")[0]

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    config = StripConfig(CalibrationConfig(matchers=matchers_named(args.method)))
    strips = sorted((args.sim / "strips").glob("*.laz"))
    with tempfile.TemporaryDirectory() as out:
        run = calibrate_strips(strips, args.sim / "sbet.out", args.sim / "sensor.toml", config,
                               progress=progress)
        stage[0] = "writing outputs"
        run.write(Path(out))
    stop.set()
    sampler.join()
    spans: dict = {}
    for t, rss, s in samples:
        first, _, top = spans.get(s, (t, t, 0.0))
        spans[s] = (first, t, max(top, rss))
    for s, (a, b, top) in spans.items():
        print(f"{s:45s} {a:7.1f}–{b:7.1f} s  largest RSS {top:.3f} GiB")
    t, rss, s = max(samples, key=lambda x: x[1])
    print(f"peak sampled: {rss:.3f} GiB at {t:.1f} s ({s}); VmHWM {rss_gib('VmHWM'):.3f} GiB")
    if peak["snapshot"] is not None:
        print(f"traced at its peak: {peak['traced'] / 2**30:.3f} GiB, RSS then {peak['rss']:.3f} GiB "
              f"({peak['stage']}); the sites holding it:")
        for mib, where in sites(peak["snapshot"], args.top):
            print(f"  {mib:7.1f} MiB  {where}")


if __name__ == "__main__":
    main()
