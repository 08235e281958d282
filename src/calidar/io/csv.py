"""Fast CSV writing of numeric columns with fixed decimals (np.savetxt is ~20× slower)."""

from __future__ import annotations

from typing import TextIO

import numpy as np
from numba import njit

_MAX_SCALED = 9.0e18  #: |x| · 10^decimals must fit an int64


@njit(cache=True, nogil=True)
def _format_rows(data, decimals, buf) -> int:
    """Write rows of ``data`` (N, k) as CSV text into ``buf`` (uint8); return the bytes used.

    Each value is rounded to ``decimals[c]`` places (round half to even on x·10^d); non-finite
    values are written as ``nan``.
    """
    pos = 0
    digits = np.empty(20, np.uint8)
    n, k = data.shape
    for r in range(n):
        for c in range(k):
            x = data[r, c]
            d = decimals[c]
            if not np.isfinite(x):
                buf[pos], buf[pos + 1], buf[pos + 2] = 110, 97, 110  # "nan"
                pos += 3
            else:
                scale = np.int64(10) ** d
                v = np.int64(np.rint(abs(x) * scale))
                if x < 0 and v != 0:
                    buf[pos] = 45  # "-"
                    pos += 1
                ip, fp = v // scale, v % scale
                m = 0
                while True:
                    digits[m] = 48 + ip % 10
                    ip //= 10
                    m += 1
                    if ip == 0:
                        break
                for j in range(m):
                    buf[pos + j] = digits[m - 1 - j]
                pos += m
                if d > 0:
                    buf[pos] = 46  # "."
                    for j in range(d, 0, -1):
                        buf[pos + j] = 48 + fp % 10
                        fp //= 10
                    pos += d + 1
            buf[pos] = 44 if c < k - 1 else 10  # "," or newline
            pos += 1
    return pos


def write_csv_rows(f: TextIO, columns, decimals, block_rows: int = 200_000) -> None:
    """Append rows to an open text file: ``columns`` a list of k arrays (N,), ``decimals`` k
    ints."""
    if len(columns):
        data = np.column_stack([np.asarray(c, dtype=float) for c in columns])
    else:
        data = np.empty((0, 0))
    dec = np.asarray(decimals, dtype=np.int64)
    if data.shape[1] != dec.size:
        raise ValueError(f"expected {data.shape[1]} decimals, got {dec.size}")
    finite = np.where(np.isfinite(data), np.abs(data), 0.0)
    if data.size and np.any(finite.max(axis=0) * 10.0 ** dec >= _MAX_SCALED):
        raise ValueError("values too large for their number of decimals")
    width = int(22 + dec.max()) if dec.size else 1
    for start in range(0, data.shape[0], block_rows):
        block = np.ascontiguousarray(data[start:start + block_rows])
        buf = np.empty(block.size * width + 1, np.uint8)
        used = _format_rows(block, dec, buf)
        f.write(buf[:used].tobytes().decode("ascii"))
