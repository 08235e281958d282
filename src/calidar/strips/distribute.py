"""Run independent per-pair tasks in-process or on a Dask cluster.

Only the small per-pair results travel back; the solver stays in this process.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np

from calidar.errors import CalibrationError

SCATTER_BYTES = 1_000_000  #: arrays larger than this are sent to the workers once, ahead of the tasks
CONNECT_TIMEOUT_S = 10.0  #: how long to wait for a scheduler given by address
MAX_LOCAL_WORKERS = 256  #: local worker processes accepted (each takes a process and its memory)


def check_cluster(scheduler: str | None = None, workers: int | None = None) -> None:
    """Refuse, before any work, a scheduler given with local workers and a number of local workers
    outside [1, MAX_LOCAL_WORKERS]."""
    from calidar.validate import integer

    if scheduler is not None and workers is not None:
        raise CalibrationError("give either --scheduler (a Dask scheduler address) or --workers (local processes), "
                               "not both")
    if workers is not None:
        integer(workers, "--workers", 1, MAX_LOCAL_WORKERS, why="local worker processes")


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
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise CalibrationError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        with client:
            yield client
        return
    # no dashboard; the scheduler's small HTTP endpoint on a free port, so clusters never collide
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      scheduler_kwargs={"dashboard": False, "dashboard_address": ":0"},
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        yield client


def map_pairs(func: Callable[..., Any], tasks: Sequence[tuple], scheduler: str | None = None,
              workers: int | None = None, *, client: Any = None) -> list[Any]:
    """``[func(*task) for task in tasks]``, in-process (default) or on Dask.

    scheduler / workers: as :func:`cluster_client` (a cluster for this call only);
    client: an open Client to reuse across calls (e.g. every round of an iterated
    calibration). Results keep task order. ``func`` and the tasks must be picklable
    (module-level functions, arrays, frozen dataclasses).
    """
    if client is not None:
        return _run(client, func, tasks)
    with cluster_client(scheduler, workers) as own:
        return [func(*t) for t in tasks] if own is None else _run(own, func, tasks)


def _run(client, func, tasks) -> list[Any]:
    """Scatter each large array once (a strip serves several pairs), submit one task per
    pair and gather the results in order."""
    scattered: dict[int, Any] = {}

    def ship(arg):
        if isinstance(arg, np.ndarray) and arg.nbytes > SCATTER_BYTES:
            if id(arg) not in scattered:
                scattered[id(arg)] = client.scatter(arg)
            return scattered[id(arg)]
        return arg

    futures = [client.submit(func, *map(ship, t), pure=False) for t in tasks]
    return client.gather(futures)
