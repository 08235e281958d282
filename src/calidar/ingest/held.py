"""What a streamed command needs of each point after its first pass, kept as the first pass reads
it, so that the second pass reads these few fields back instead of decompressing every file again.

Named arrays, chunk by chunk, per key (a file): appended to one plain binary file per key in a
temporary folder (the operating system's page cache holds them while memory is free; the process
holds one chunk), read back in the order and with the boundaries they were written. ``calidar
quality`` keeps 23 bytes per candidate point (the stored integer coordinates, point_source_id, GPS
time and which selection rules keep it): reading a LAZ point again costs more than 100 times as
much as reading those bytes back.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np
from numba import njit


class HeldPoints:
    """Chunks of named arrays per key, written to files of ``folder`` (which the caller removes)."""

    def __init__(self, folder: Path):
        import threading

        self.folder = Path(folder)
        self.files: dict = {}  #: key → (path, {name: dtype}, [points per chunk])
        self._lock = threading.Lock()  # keys added from several threads (one key per thread)

    def add(self, key, **arrays: np.ndarray) -> None:
        """One chunk's arrays (the same names and dtypes, one length) after those already added
        under ``key``: written one after another."""
        fields = {name: (a.dtype, a.shape[1:]) for name, a in arrays.items()}
        with self._lock:
            if key not in self.files:
                self.files[key] = (self.folder / f"held_{len(self.files)}.bin", fields, [])
        path, known, sizes = self.files[key]
        if fields != known:
            raise ValueError(f"arrays {fields} under a key holding {known}")
        with open(path, "ab") as f:
            for a in arrays.values():
                f.write(np.ascontiguousarray(a).data)
        sizes.append(len(next(iter(arrays.values()))))

    def chunks(self, key, which: range | None = None) -> Iterator[dict[str, np.ndarray]]:
        """The arrays added under ``key``, chunk by chunk as added (``which``: those chunks only;
        none added: nothing)."""
        if key not in self.files:
            return
        path, fields, sizes = self.files[key]
        which = range(len(sizes)) if which is None else which
        per_point = sum(d.itemsize * int(np.prod(s)) for d, s in fields.values())
        with open(path, "rb") as f:
            f.seek(per_point * sum(sizes[:which.start]))
            for n in sizes[which.start:which.stop]:
                yield {name: np.fromfile(f, dtype, n * int(np.prod(shape))).reshape((n, *shape))
                       for name, (dtype, shape) in fields.items()}

    @property
    def nbytes(self) -> int:
        """Bytes written."""
        return sum(sum(d.itemsize * int(np.prod(s)) for d, s in fields.values()) * sum(sizes)
                   for _, fields, sizes in self.files.values())


@contextmanager
def spill_folder(prefix: str) -> Iterator[Path]:
    """A temporary folder for a command's held points and spills, registered as the run's
    temporaries are (an interruption removes it, :func:`calidar.outputs.remove_temporaries`):
    removed at once when the block fails, in a thread beside what the run does next when it
    ends (:func:`calidar.outputs.remove_soon`: unlinking large files is the kernel's work)."""
    import tempfile

    from calidar import outputs

    folder = outputs._temporary(lambda: Path(tempfile.mkdtemp(prefix=prefix)), "held points")
    try:
        yield folder
    except BaseException:
        _remove_folder(str(folder))
        raise
    outputs.remove_soon(folder)


#: what the strip ingest keeps of a point: the stored coordinates, the time in the trajectory's
#: system, point_source_id and the selection's fields (pass 2 and the overlap-quality stages need
#: no more)
STRIP_FIELDS = ("point_source_id", "classification", "return_number", "number_of_returns")
STRIP_BYTES_PER_POINT = 12 + 8 + 2 + 3


class HeldFiles:
    """The points of LAS/LAZ files as the strip ingest's first pass read them, chunk by chunk
    (LasPoints with xyz, the times in the trajectory's system and :data:`STRIP_FIELDS`), kept in
    a temporary folder removed with this object (or by :meth:`close`); not sent to other
    processes (a copy pickles without them: those read the files)."""

    def __init__(self):
        import tempfile
        import threading
        import weakref

        from calidar import outputs

        # registered as the run's temporaries are: removed by outputs.remove_temporaries (an
        # interrupted command ending while reader threads still hold this) as well as when it goes
        # or at exit
        def create() -> Path:
            return Path(tempfile.mkdtemp(prefix="calidar-held-"))

        self.folder = outputs._temporary(create, "held points")
        self._remove = weakref.finalize(self, _remove_folder, str(self.folder))
        self.points = HeldPoints(self.folder)
        self.meta: dict = {}  #: path → (LasPoints of no points: CRS, time system…; scales; offsets)
        self.complete: set = set()  #: paths held whole
        self._lock = threading.Lock()

    def close(self) -> None:
        self._remove()

    def release(self) -> None:
        """The folder removed in a thread (:func:`calidar.outputs.remove_soon`), beside what the
        run does next, once the last pass has read it; nothing can be read afterwards."""
        from calidar.outputs import remove_soon

        if self._remove.detach() is not None:
            self.complete.clear()
            remove_soon(self.folder)

    def add(self, path: Path, chunk, t: np.ndarray, scales, offsets) -> bool:
        """A chunk (LasPoints with STRIP_FIELDS) of ``path`` and its times; False (nothing kept)
        when its coordinates are not the stored integers × scales + offsets exactly."""
        from calidar.io.las import OPTIONAL_FIELDS
        stored = stored_integers(chunk.xyz, scales, offsets)
        if stored is None:
            return False
        with self._lock:
            # no points (copies, not views: a view would keep the chunk's buffers for the run)
            empty = replace(chunk.select(np.zeros(0, np.int64)), **dict.fromkeys(OPTIONAL_FIELDS))
            self.meta.setdefault(path, (empty, np.asarray(scales), np.asarray(offsets)))
        fields = {f: np.asarray(getattr(chunk, f)) for f in STRIP_FIELDS}
        self.points.add(path, X=stored[:, 0], Y=stored[:, 1], Z=stored[:, 2],
                        t=np.asarray(t, float), **fields)
        return True

    def chunks(self, path: Path, span: tuple[int, int | None]):
        """(LasPoints, times) of the held chunks of ``path`` covering its points [span), or None
        when the file is not held whole or the span does not start and end at chunk boundaries."""
        if path not in self.complete:
            return None
        _, _, sizes = self.points.files[path]
        edges = np.r_[0, np.cumsum(sizes)]
        a, b = span[0], edges[-1] if span[1] is None else min(span[1], edges[-1])
        first, last = np.searchsorted(edges, [a, b])
        if first >= edges.size or edges[first] != a or last >= edges.size or edges[last] != b:
            return None
        empty, scales, offsets = self.meta[path]

        def read():
            for c in self.points.chunks(path, range(first, last)):
                xyz = scaled_integers(c["X"], c["Y"], c["Z"], scales, offsets)
                fields = {f: c[f] for f in STRIP_FIELDS}
                yield replace(empty, xyz=xyz, gps_time=c["t"], **fields), c["t"]
        return read()

    def __getstate__(self):
        raise TypeError("held points stay in their process")


def stored_integers(xyz: np.ndarray, scales, offsets) -> np.ndarray | None:
    """The LAS integers (N, 3) int32 whose X · scale + offset, as laspy scales them (and so a
    second pass will), are ``xyz`` bit for bit; None when some coordinate is not such a value.
    One numba pass: round((xyz − offset) / scale) within ±2³¹, then scaled back and compared."""
    xyz = np.ascontiguousarray(xyz, dtype=np.float64)
    stored = np.empty(xyz.shape, np.int32)
    scales, offsets = (np.ascontiguousarray(v, dtype=np.float64) for v in (scales, offsets))
    return stored if _stored_kernel(xyz, scales, offsets, stored) else None


def scaled_integers(x: np.ndarray, y: np.ndarray, z: np.ndarray, scales, offsets) -> np.ndarray:
    """Coordinates (N, 3) float64 of stored LAS integers: X · scale + offset as laspy (and numpy,
    axis by axis) scale them, in one numba pass without the per-axis temporaries."""
    scales, offsets = (np.ascontiguousarray(v, dtype=np.float64) for v in (scales, offsets))
    if any(a.dtype.kind not in "iu" for a in (x, y, z)):
        return np.stack([a * scales[k] + offsets[k] for k, a in enumerate((x, y, z))], axis=1)
    return _scaled_kernel(x, y, z, scales, offsets)


@njit(cache=True, nogil=True, inline="always")
def las_coordinate(stored, scale, offset):  # pragma: no cover - numba
    """The coordinate of one stored LAS integer as laspy scales it: the integer as float64, times
    ``scale``, plus ``offset`` (no fused multiply-add) — the one implementation for every kernel
    (:func:`_scaled_kernel`, :func:`_stored_kernel`, :mod:`calidar.ingest.chunk_pass`)."""
    return np.float64(stored) * scale + offset


@njit(cache=True, nogil=True)
def _scaled_kernel(x, y, z, scales, offsets):  # pragma: no cover - numba
    out = np.empty((x.size, 3))
    for i in range(x.size):
        out[i, 0] = las_coordinate(x[i], scales[0], offsets[0])
        out[i, 1] = las_coordinate(y[i], scales[1], offsets[1])
        out[i, 2] = las_coordinate(z[i], scales[2], offsets[2])
    return out


@njit(cache=True, nogil=True)
def _stored_kernel(xyz, scales, offsets, stored):  # pragma: no cover - numba
    for i in range(xyz.shape[0]):
        for a in range(3):
            r = np.rint((xyz[i, a] - offsets[a]) / scales[a])  # np.round: half to even
            if not abs(r) < 2147483648.0:  # (NaN too)
                return False
            s = np.int32(r)
            if las_coordinate(s, scales[a], offsets[a]) != xyz[i, a]:
                return False
            stored[i, a] = s
    return True


def _remove_folder(folder: str) -> None:
    """A held folder removed and no longer registered as a temporary."""
    import shutil

    from calidar import outputs

    shutil.rmtree(folder, ignore_errors=True)
    outputs._TEMPORARIES.pop(folder, None)
