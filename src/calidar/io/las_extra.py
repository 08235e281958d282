"""LAS/LAZ files rewritten with extra-byte dimensions added (LAS 1.4 extra bytes, e.g. the
per-point uncertainty of ``calidar tpu``), streamed chunk by chunk, every other attribute kept."""

from __future__ import annotations

from pathlib import Path

import laspy
import numpy as np

from calidar.io.las_rewrite import rewrite_las


def rewrite_las_with_extra(src: str | Path, dst: str | Path, extra: dict[str, str], values, *,
                           chunk_points: int, force: bool = False, options=None) -> int:
    """Copy a LAS/LAZ file chunk by chunk with float32 extra-byte dimensions added (LAS 1.4 extra
    bytes: ``extra`` maps each name to its description, units in the text) and every other
    attribute kept; ``values(points) -> {name: (n,) array}`` for each chunk's
    :class:`calidar.io.las.LasPoints`. Streamed and atomic. Returns the point count."""
    made = {}

    def with_extra(header: laspy.LasHeader) -> laspy.LasHeader:
        out = laspy.LasHeader(point_format=header.point_format.id, version=header.version)
        for d in header.point_format.extra_dimensions:
            kept = laspy.ExtraBytesParams(d.name, d.dtype, description=d.description or "")
            out.add_extra_dim(kept)
        out.add_extra_dims([laspy.ExtraBytesParams(k, np.float32, description=v)
                            for k, v in extra.items()])
        out.scales, out.offsets = header.scales, header.offsets
        out.global_encoding = header.global_encoding
        out.vlrs.extend(v for v in header.vlrs if not isinstance(v, laspy.vlrs.known.ExtraBytesVlr))
        made["header"] = out
        return out

    def add(rec, points):
        out = laspy.ScaleAwarePointRecord.zeros(len(rec), header=made["header"])
        for name in rec.point_format.dimension_names:
            out[name] = rec[name]
        for name, v in values(points).items():
            out[name] = np.asarray(v, np.float32)
        return out

    return rewrite_las(src, dst, with_extra, add, chunk_points=chunk_points, force=force,
                       options=options)
