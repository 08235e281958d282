"""The next chunks of a file decompressed in a thread while the caller works on the current one
(:func:`prefetched`): LAZ decompression (lazrs) and the numba kernels release the GIL, so on two
cores reading and the per-chunk work overlap. The chunks come in their order, the same chunks:
results are those of reading in line; an error in the reader is raised where the chunk would
have come; memory holds ``depth`` more chunks."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

_DONE = object()


def prefetched(items: Iterable, depth: int = 1) -> Iterator:
    """The items of ``items`` in order, up to ``depth`` of them produced ahead in a thread."""
    import queue
    import threading

    q: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def put(entry) -> bool:
        while not stop.is_set():
            try:
                q.put(entry, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def work() -> None:
        it = iter(items)
        try:
            for x in it:
                if not put((x, None)):
                    return
            put((_DONE, None))
        except BaseException as e:  # raised in the caller's thread, where the chunk would have come
            put((_DONE, e))
        finally:
            close = getattr(it, "close", None)
            if close is not None:
                close()  # the reader's file, closed in its thread

    thread = threading.Thread(target=work, name="calidar-prefetch", daemon=True)
    thread.start()
    try:
        while True:
            x, err = q.get()
            if x is _DONE:
                if err is not None:
                    raise err
                return
            yield x
    finally:
        stop.set()
        thread.join()
