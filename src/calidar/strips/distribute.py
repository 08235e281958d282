"""Run independent per-pair tasks in-process or on a Dask cluster.

Only the small per-pair results travel back; the solver stays in this process.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calidar.errors import CalibrationError
from calidar.memory import release_memory

#: arrays larger than this are sent to the workers once, ahead of the tasks
SCATTER_BYTES = 1_000_000
CONNECT_TIMEOUT_S = 10.0  #: how long to wait for a scheduler given by address
#: how long the first TCP connection and the scheduler's greeting may take each
PROBE_TIMEOUT_S = 5.0
#: a Dask scheduler's first message (its handshake) is a few hundred bytes
MAX_GREETING_BYTES = 1 << 20
MAX_LOCAL_WORKERS = 256  #: local worker processes accepted (each takes a process and its memory)
#: files read at once in this process (each holds one chunk's working arrays, ≈ 0.2 GB at 0.5 M
#: points)
IN_PROCESS_THREADS = min(2, os.cpu_count() or 1)
JOIN_S = 0.5  #: how long a closing reader pool waits for its threads' current calls


def check_cluster(scheduler: str | None = None, workers: int | None = None) -> None:
    """Refuse, before any work, a scheduler given with local workers and a number of local workers
    outside [1, MAX_LOCAL_WORKERS]."""
    from calidar.validate import integer

    if scheduler is not None and workers is not None:
        raise CalibrationError("give either --scheduler (a Dask scheduler address) or --workers "
                               "(local processes), not both")
    if workers is not None:
        integer(workers, "--workers", 1, MAX_LOCAL_WORKERS, why="local worker processes")
    if scheduler is not None:
        scheduler_address(scheduler)


def scheduler_address(text: str) -> tuple[str, str, int | None]:
    """(protocol, host, port) of a ``--scheduler`` address ("tcp://host:8786", "host:8786"), or a
    clear error for a malformed one."""
    from calidar.errors import InputError

    expected = f"expected a Dask scheduler address such as tcp://host:8786, got {text!r}"
    protocol, _, rest = text.rpartition("://") if "://" in text else ("tcp", "", text)
    if protocol not in ("tcp", "tls", "inproc", "ucx", "ws", "wss") or not rest:
        raise InputError(None, "--scheduler", expected)
    if protocol not in ("tcp", "tls"):
        return protocol, rest, None
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")
    odd_host = any(c.isspace() or c in "/?#@" for c in host)
    if not host or not port.isdigit() or not 0 < int(port) < 65536 or odd_host:
        raise InputError(None, "--scheduler", expected)
    return protocol, host, int(port)


def probe_scheduler(text: str, timeout: float = PROBE_TIMEOUT_S) -> None:
    """Check, within 2 × ``timeout``, that a tcp:// address answers as a Dask scheduler does: on a
    new connection it sends its handshake first, a short message framed by its length (8 bytes,
    little-endian). An HTTP server says nothing; a proxy answering "HTTP/1.1 400" gives an absurd
    length (which Dask itself would try to allocate: 3 EiB). Either is a clear error."""
    import socket
    import struct

    protocol, host, port = scheduler_address(text)
    if protocol != "tcp":
        return  # TLS and the other transports: left to Dask's own connect timeout
    where = f"the Dask scheduler at {text}"
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            head = _recv(sock, 8)
            (n,) = struct.unpack("<Q", head)
            if not 0 < n <= MAX_GREETING_BYTES:
                raise CalibrationError(f"{where}: not a Dask scheduler (it answered {head!r}…); "
                                       "check the address and port (the scheduler's default is "
                                       "8786)")
            _recv(sock, n)
    except socket.timeout:
        raise CalibrationError(f"{where}: no answer within {timeout:g} s as a Dask scheduler would "
                               "give; is it one (the scheduler's default port is 8786)?") from None
    except OSError as exc:
        raise CalibrationError(f"cannot reach {where}: {exc.strerror or exc}") from None


def _recv(sock, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise CalibrationError(f"{sock.getpeername()}: closed the connection: not a Dask "
                                   "scheduler")
        data += chunk
    return data


@contextmanager
def cluster_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A dask.distributed Client for ``scheduler`` (an address such as "tcp://host:8786") or
    for a LocalCluster of ``workers`` processes (one thread each, no dashboard); None when
    both are None (in-process). A LocalCluster is closed on exit."""
    check_cluster(scheduler, workers)
    if scheduler is None and workers is None:
        yield None
        return
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        probe_scheduler(scheduler)
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            reason = f"cannot reach the Dask scheduler at {scheduler}: {exc}"
            raise CalibrationError(reason) from None
        with client:
            yield client
        return
    # no dashboard; the scheduler's small HTTP endpoint on a free port, so clusters never collide
    # the cluster's own log (its processes' too) only with CALIDAR_DEBUG: the tasks' errors come
    # back as exceptions, and an interrupted run tears the cluster down mid-way (connections closed
    # under it)
    quiet = logging.ERROR if os.environ.get("CALIDAR_DEBUG") else logging.CRITICAL
    with _workers_in_own_session(), LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
            scheduler_kwargs={"dashboard": False, "dashboard_address": ":0"},
            silence_logs=quiet) as cluster, \
            Client(cluster) as client:
        try:
            yield client
        except KeyboardInterrupt:
            # "Task exception was never retrieved" and the like
            for name in ("distributed", "asyncio", "tornado"):
                logging.getLogger(name).setLevel(quiet)
            raise


@contextmanager
def _workers_in_own_session() -> Iterator[None]:
    """Worker processes started in a session of their own while the block runs (multiprocessing's
    spawn, which a LocalCluster's nannies use, made to call ``setsid``): a Ctrl-C, which the
    terminal sends to every process of its foreground group, reaches this process alone — which ends
    the run and closes the cluster — instead of printing each worker's KeyboardInterrupt traceback.
    (Blocking or ignoring SIGINT around the start does not reach them: they are spawned later, from
    Dask's own threads, and asyncio installs its own SIGINT handler in each.)"""
    import subprocess
    from multiprocessing import util

    # kept so that no Popen object warns when collected; multiprocessing reaps them
    spawned: list = []

    def spawn(path, args, passfds):
        fds = tuple(sorted(map(int, passfds)))
        proc = subprocess.Popen(args, executable=path, pass_fds=fds, close_fds=True,
                                start_new_session=True)
        spawned.append(proc)
        return proc.pid

    original = getattr(util, "spawnv_passfds", None)
    if original is None or os.name != "posix":
        yield
        return
    util.spawnv_passfds = spawn
    try:
        yield
    finally:
        util.spawnv_passfds = original


def map_pairs(func: Callable[..., Any], tasks: Sequence[tuple], scheduler: str | None = None,
              workers: int | None = None, *, client: Any = None, log: "TaskLog | None" = None,
              kind: str = "match pair", threads: int = 1) -> list[Any]:
    """``[func(*task) for task in tasks]``, in-process (default; ``threads`` tasks at once: for a
    ``func`` that releases the GIL) or on Dask.

    scheduler / workers: as :func:`cluster_client` (a cluster for this call only);
    client: an open Client to reuse across calls (e.g. every round of an iterated
    calibration). Results keep task order. ``func`` and the tasks must be picklable
    (module-level functions, arrays, frozen dataclasses). ``log``: records what each task sent
    back (on Dask) under ``kind``.
    """
    if client is not None:
        return list(run_tasks(func, tasks, client=client, log=log, kind=kind))
    with cluster_client(scheduler, workers) as own:
        return list(run_tasks(func, tasks, client=own, log=log, kind=kind,
                              threads=threads if own is None else 1))


def run_tasks(func: Callable[..., Any], tasks: Sequence[tuple], *, shared: tuple = (),
              client: Any = None, threads: int = 1, log: "TaskLog | None" = None,
              kind: str = "task") -> Iterator[Any]:
    """``func(*shared, *task)`` for each task, yielded in task order as they finish: in this
    process (``threads`` at once, each result taken before more start, so that at most
    ``threads`` + 1 results are held) or on a Dask ``client`` (``shared`` sent to the workers
    once; each array over :data:`SCATTER_BYTES` once however many tasks use it). Folding the
    results in task order keeps the outcome identical however the tasks ran."""
    if client is not None:
        yield from _on_dask(client, func, tasks, shared, log, kind)
        return
    if threads <= 1 or len(tasks) <= 1:
        for t in tasks:
            yield func(*shared, *t)
        return
    from collections import deque

    todo, pool = iter(tasks), _DaemonPool(threads)
    try:
        pending = deque(pool.submit(func, *shared, *t) for _, t in zip(range(threads), todo))
        while pending:
            result = pending.popleft().result()
            nxt = next(todo, None)
            if nxt is not None:
                pending.append(pool.submit(func, *shared, *nxt))
            yield result
    finally:
        pool.close()


def thread_map(func: Callable[[Any], Any], items: Sequence[Any],
               threads: int = IN_PROCESS_THREADS) -> list[Any]:
    """``[func(x) for x in items]``, ``threads`` calls at once in this process (for a ``func``
    whose work releases the GIL: numba ``nogil`` kernels, numpy on large arrays), every item
    submitted at once so that no thread waits behind a long call. Each result is its own call's,
    kept in item order: the same list whatever the threads' timing (nothing summed across
    items). An error or interruption cancels the calls not started and is raised here. The
    memory the calls freed is given back after (each thread allocates in its own malloc arena,
    which the main thread's arrays never reuse: untrimmed, the 8.75 M-point calibration's peak
    rose by 0.03 GiB)."""
    if threads <= 1 or len(items) <= 1:
        return [func(x) for x in items]
    pool = _DaemonPool(min(threads, len(items)))
    try:
        futures = [pool.submit(func, x) for x in items]
        return [f.result() for f in futures]
    finally:
        pool.close()
        release_memory()  # what the calls freed in the threads' own arenas


class _DaemonPool:
    """Threads that run submitted calls (daemons: never what keeps the process alive); closing it
    cancels the calls not started and waits for the running ones (one chunk each)."""

    def __init__(self, threads: int):
        import queue
        import threading

        self.todo: queue.Queue = queue.Queue()
        self.threads = [threading.Thread(target=self._work, daemon=True) for _ in range(threads)]
        for t in self.threads:
            t.start()

    def _work(self) -> None:
        while (job := self.todo.get()) is not None:
            future, func, args = job
            if future.set_running_or_notify_cancel():
                try:
                    future.set_result(func(*args))
                except BaseException as e:  # handed to the caller, which re-raises it
                    future.set_exception(e)

    def submit(self, func, *args):
        from concurrent.futures import Future

        future = Future()
        self.todo.put((future, func, args))
        return future

    def close(self, wait_s: float = JOIN_S) -> None:
        """Cancel the calls not started and wait up to ``wait_s`` for the threads to end their
        current one: a thread still inside a native decoder (lazrs) when the interpreter exits is
        unwound by force and aborts the process ("FATAL: exception not rethrown", exit 134) after
        the run's own error. An interrupted run does not wait longer: the CLI ends a process whose
        threads still run without the interpreter's finalisation (``calidar.cli.main``)."""
        import queue
        import time

        while True:
            try:
                job = self.todo.get_nowait()
            except queue.Empty:
                break
            if job is not None:
                job[0].cancel()
        for _ in self.threads:
            self.todo.put(None)
        deadline = time.monotonic() + wait_s
        for t in self.threads:
            t.join(max(0.0, deadline - time.monotonic()))


def _on_dask(client, func, tasks, shared, log, kind) -> Iterator[Any]:
    """Scatter the shared arguments and each large array once, submit all tasks, gather in order."""
    scattered: dict[int, Any] = {}

    def ship(arg):
        if isinstance(arg, np.ndarray) and arg.nbytes > SCATTER_BYTES:
            if id(arg) not in scattered:
                scattered[id(arg)] = client.scatter(arg)
            return scattered[id(arg)]
        return arg

    common = [client.scatter(a, broadcast=True) for a in shared]
    futures = [client.submit(func, *common, *map(ship, t), pure=False) for t in tasks]
    for f in futures:
        result = f.result()
        f.release()
        if log is not None:
            log.add(kind, result)
        yield result


class TaskLog:
    """What the tasks run on Dask sent back, by kind of task: bytes each (as pickled)."""

    def __init__(self):
        self.sent: dict[str, list[int]] = {}

    def add(self, kind: str, result: Any) -> None:
        self.sent.setdefault(kind, []).append(pickled_bytes(result))

    def to_dict(self) -> dict:
        """{kind: tasks, bytes sent back in all and by the largest}."""
        return {k: {"tasks": len(v), "bytes_sent_back": int(sum(v)),
                    "max_bytes_per_task": int(max(v))}
                for k, v in self.sent.items()}


def pickled_bytes(obj: Any) -> int:
    """The size of ``obj`` pickled (protocol 5), counted without holding the bytes."""
    import pickle

    class _Count:
        n = 0

        def write(self, b) -> int:
            n = memoryview(b).nbytes
            self.n += n
            return n

    out = _Count()
    pickle.Pickler(out, protocol=5).dump(obj)
    return out.n


@dataclass
class Workers:
    """Where independent tasks run: ``threads`` at once in this process, or on the Dask
    ``client``; ``log`` keeps what the Dask tasks sent back."""

    client: Any = None
    threads: int = 1
    log: TaskLog = field(default_factory=TaskLog)

    @property
    def local_threads(self) -> int:
        """Threads for work kept in this process (its arrays are here): ours, 1 beside a cluster."""
        return self.threads if self.client is None else 1

    def run(self, func: Callable[..., Any], tasks: Sequence[tuple], shared: tuple = (),
            kind: str = "task") -> Iterator[Any]:
        """:func:`run_tasks` here."""
        return run_tasks(func, tasks, shared=shared, client=self.client, threads=self.threads,
                         log=self.log, kind=kind)


@contextmanager
def workers_for(scheduler: str | None = None, workers: int | None = None,
                threads: int = IN_PROCESS_THREADS) -> Iterator[Workers]:
    """:class:`Workers` on the cluster of :func:`cluster_client`, or ``threads`` in this process."""
    with cluster_client(scheduler, workers) as client:
        yield Workers(client, 1 if client is not None else threads)
