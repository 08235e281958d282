"""Run independent per-pair tasks in-process or on a Dask cluster.

Only the small per-pair results travel back; the solver stays in this process.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from calidar.errors import CalibrationError

SCATTER_BYTES = 1_000_000  #: arrays larger than this are sent to the workers once, ahead of the tasks


def map_pairs(func: Callable[..., Any], tasks: Sequence[tuple], scheduler: str | None = None,
              workers: int | None = None) -> list[Any]:
    """``[func(*task) for task in tasks]``, in-process (default) or on Dask.

    scheduler: address of a dask.distributed scheduler ("tcp://host:8786");
    workers: start a LocalCluster with that many worker processes (one thread each, no
    dashboard), closed when the tasks are done. Results keep task order. ``func`` and the
    tasks must be picklable (module-level functions, arrays, frozen dataclasses).
    """
    if scheduler is not None and workers is not None:
        raise CalibrationError("give either a scheduler address or a number of local workers, not both")
    if scheduler is None and workers is None:
        return [func(*t) for t in tasks]
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise CalibrationError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        with client:
            return _run(client, func, tasks)
    if workers < 1:
        raise CalibrationError(f"--workers must be at least 1, got {workers}")
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=40) as cluster, Client(cluster) as client:
        return _run(client, func, tasks)


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
