"""LAS/LAZ files rewritten with extra-byte dimensions added (LAS 1.4 extra bytes, e.g. the
per-point uncertainty of ``calidar tpu``), streamed chunk by chunk, every other attribute kept."""

from __future__ import annotations

from pathlib import Path

import laspy
import numpy as np

from calidar.io.las import OPTIONAL_FIELDS, _open, _options, _points, _records, _resolve_crs, gps_time_system
from calidar.outputs import atomic_path


def rewrite_las_with_extra(src: str | Path, dst: str | Path, extra: dict[str, str], values, *, chunk_points: int,
                           force: bool = False, options=None) -> int:
    """Copy a LAS/LAZ file chunk by chunk with float32 extra-byte dimensions added (LAS 1.4 extra
    bytes: ``extra`` maps each name to its description, units in the text) and every other
    attribute kept; ``values(points) -> {name: (n,) array}`` for each chunk's
    :class:`calidar.io.las.LasPoints`. Streamed and atomic. Returns the point count."""
    src, opts = Path(src), _options(None, options)
    n = 0
    with _open(src) as reader, atomic_path(dst, force) as tmp:
        header = reader.header
        time_system = gps_time_system(header, src, opts.time_system)
        file_crs = _resolve_crs(header, opts.crs, src)
        out_header = laspy.LasHeader(point_format=header.point_format.id, version=header.version)
        for d in header.point_format.extra_dimensions:
            out_header.add_extra_dim(laspy.ExtraBytesParams(d.name, d.dtype, description=d.description or ""))
        out_header.add_extra_dims([laspy.ExtraBytesParams(k, np.float32, description=v) for k, v in extra.items()])
        out_header.scales, out_header.offsets = header.scales, header.offsets
        out_header.global_encoding = header.global_encoding
        out_header.vlrs.extend(v for v in header.vlrs if not isinstance(v, laspy.vlrs.known.ExtraBytesVlr))
        with laspy.open(tmp, mode="w", header=out_header, do_compress=Path(dst).suffix.lower() == ".laz") as writer:
            for first, rec in _records(reader, chunk_points, src):
                points = _points(rec, header, src, file_crs, time_system, OPTIONAL_FIELDS, opts.geoid_undulation_m,
                                 first)
                out = laspy.ScaleAwarePointRecord.zeros(len(rec), header=out_header)
                for name in rec.point_format.dimension_names:
                    out[name] = rec[name]
                for name, v in values(points).items():
                    out[name] = np.asarray(v, np.float32)
                writer.write_points(out)
                n += len(rec)
    return n
