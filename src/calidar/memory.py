"""Memory the process freed handed back to the system (:func:`release_memory`), where a long run
moves from one stage or outer iteration to the next."""

from __future__ import annotations


def release_memory() -> None:
    """Hand the memory freed by a finished stage back to the system (glibc keeps freed pages of
    its arenas: after the calibration, half a GiB of an 8.75 M-point run; each thread that
    allocated has an arena of its own, which the others do not reuse); elsewhere nothing.
    ``malloc_trim`` is looked up in the libc this process runs on (``CDLL(None)``, 0.02 ms), not
    through ``ctypes.util.find_library``, which starts ``/sbin/ldconfig -p`` at every call: a
    process created from this one while its reader threads run, ≈ 10 ms each, once per task of
    the overlap quality."""
    import ctypes

    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass
