"""ICESat-2 ATL03 photon files (HDF5): read one beam, write the same layout (for the simulator).

Layout read (ATL03 v006, the subset calidar needs)::

    /<beam>/heights/     delta_time [s since 2018-01-01], lat_ph, lon_ph [deg], h_ph [m],
                         dist_ph_along, dist_ph_across [m], signal_conf_ph (N×5 int8:
                         land, ocean, sea ice, land ice, inland water), quality_ph
    /<beam>/geolocation/ segment_id, ph_index_beg (1-based), segment_ph_cnt,
                         segment_dist_x [m] (optional)

Along-track distance of a photon = segment_dist_x of its 20 m segment + dist_ph_along
(ATL03 ATBD, Neumann et al. 2019); without segment_dist_x it is the cumulative
segment_length, or dist_ph_along alone when there is a single segment.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError

#: The six ATLAS beams (ground tracks).
BEAMS = ("gt1l", "gt1r", "gt2l", "gt2r", "gt3l", "gt3r")
#: Columns of signal_conf_ph (surface types).
SURFACE_TYPES = ("land", "ocean", "sea_ice", "land_ice", "inland_water")
_HEIGHTS = ("delta_time", "lat_ph", "lon_ph", "h_ph", "dist_ph_along", "dist_ph_across", "signal_conf_ph")
_SEGMENTS = ("segment_id", "ph_index_beg", "segment_ph_cnt")


@dataclass
class PhotonBeam:
    """The photons of one beam. Angles in radians, distances in metres, time in seconds."""

    beam: str
    delta_time: np.ndarray  #: (N,) s since the ATLAS epoch 2018-01-01 (per shot)
    lat: np.ndarray  #: (N,) rad
    lon: np.ndarray  #: (N,) rad
    h: np.ndarray  #: (N,) m, height above the WGS84 ellipsoid
    dist_along: np.ndarray  #: (N,) m, dist_ph_along (within the segment)
    dist_across: np.ndarray  #: (N,) m, dist_ph_across
    signal_conf: np.ndarray  #: (N, 5) int8 ATL03 confidence per surface type (-2..4)
    quality: np.ndarray  #: (N,) int8 quality_ph
    segment_id: np.ndarray  #: (S,) int
    ph_index_beg: np.ndarray  #: (S,) 1-based index of each segment's first photon (0 = empty)
    segment_ph_cnt: np.ndarray  #: (S,) photons per segment
    segment_dist_x: np.ndarray | None = None  #: (S,) m, along-track distance of each segment start
    source: str | None = None

    def __len__(self) -> int:
        return int(self.h.size)

    @property
    def x(self) -> np.ndarray:
        """Along-track distance of every photon (m): segment_dist_x + dist_ph_along."""
        start = self._segment_start()
        seg = np.full(self.h.size, -1, dtype=np.int64)
        cnt = self.segment_ph_cnt.astype(np.int64)
        ok = (cnt > 0) & (self.ph_index_beg > 0)
        idx = np.repeat(np.flatnonzero(ok), cnt[ok])
        first = np.repeat(self.ph_index_beg[ok].astype(np.int64) - 1, cnt[ok])
        pos = first + np.arange(idx.size) - np.repeat(np.cumsum(cnt[ok]) - cnt[ok], cnt[ok])
        good = (pos >= 0) & (pos < self.h.size)
        seg[pos[good]] = idx[good]
        if np.any(seg < 0):
            raise InputError(self.source, f"{self.beam}/geolocation/ph_index_beg",
                             "segment bookkeeping does not cover every photon")
        return start[seg] + self.dist_along.astype(np.float64)

    def _segment_start(self) -> np.ndarray:
        if self.segment_dist_x is not None:
            return np.asarray(self.segment_dist_x, np.float64)
        return np.zeros(self.segment_id.size)

    def shot_index(self) -> np.ndarray:
        """Integer id of the laser shot of each photon (photons of one pulse share delta_time)."""
        _, inv = np.unique(self.delta_time, return_inverse=True)
        return inv


def _need(group, name: str, path, where: str):
    if name not in group:
        raise InputError(path, f"{where}/{name}", "missing from the ATL03 file")
    return group[name][()]


def _open_hdf5(path: Path):
    """An open h5py.File; a clear error when the file is not HDF5."""
    import h5py

    try:
        return h5py.File(path, "r")
    except FileNotFoundError:
        raise
    except OSError as e:
        raise InputError(path, None, f"not a readable HDF5 file ({e})") from None


def atl03_beams(path: str | Path) -> list[str]:
    """The beams (of :data:`BEAMS`) an ATL03 file holds photons of (a ``<beam>/heights`` group)."""
    with _open_hdf5(Path(path)) as f:
        return [b for b in BEAMS if b in f and "heights" in f[b]]


def read_atl03(path: str | Path, beam: str = "gt1l") -> PhotonBeam:
    """Read the photons of one beam of an ATL03 file (degrees in the file → radians)."""
    path = Path(path)
    if beam not in BEAMS:
        raise InputError(None, "--beam", f"expected one of {', '.join(BEAMS)}, got {beam!r}")
    with _open_hdf5(path) as f:
        if beam not in f:
            have = [b for b in BEAMS if b in f]
            raise InputError(path, beam, f"beam group missing; the file has {', '.join(have) or 'no beams'}")
        for grp in ("heights", "geolocation"):
            if grp not in f[beam]:
                raise InputError(path, f"{beam}/{grp}", "group missing from the ATL03 file")
        hg, gg = f[beam]["heights"], f[beam]["geolocation"]
        d = {k: _need(hg, k, path, f"{beam}/heights") for k in _HEIGHTS}
        s = {k: _need(gg, k, path, f"{beam}/geolocation") for k in _SEGMENTS}
        quality = hg["quality_ph"][()] if "quality_ph" in hg else np.zeros(d["h_ph"].size, np.int8)
        if "segment_dist_x" in gg:
            dist_x = gg["segment_dist_x"][()]
        elif "segment_length" in gg:
            seg_len = gg["segment_length"][()]
            dist_x = np.concatenate([[0.0], np.cumsum(seg_len[:-1])])
        else:
            dist_x = None
    n = d["h_ph"].size
    for k in _HEIGHTS:
        if d[k].shape[0] != n:
            raise InputError(path, f"{beam}/heights/{k}", f"expected {n} rows like h_ph, got {d[k].shape[0]}")
    conf = d["signal_conf_ph"]
    if conf.ndim != 2 or conf.shape[1] != len(SURFACE_TYPES):
        raise InputError(path, f"{beam}/heights/signal_conf_ph", f"expected shape (N, 5), got {conf.shape}")
    return PhotonBeam(
        beam=beam, delta_time=d["delta_time"].astype(np.float64),
        lat=np.radians(d["lat_ph"].astype(np.float64)), lon=np.radians(d["lon_ph"].astype(np.float64)),
        h=d["h_ph"].astype(np.float64), dist_along=d["dist_ph_along"].astype(np.float64),
        dist_across=d["dist_ph_across"].astype(np.float64), signal_conf=conf.astype(np.int8),
        quality=np.asarray(quality, np.int8), segment_id=s["segment_id"].astype(np.int64),
        ph_index_beg=s["ph_index_beg"].astype(np.int64), segment_ph_cnt=s["segment_ph_cnt"].astype(np.int64),
        segment_dist_x=None if dist_x is None else np.asarray(dist_x, np.float64), source=str(path),
    )


def segment_photons(x_m: np.ndarray, segment_length_m: float = 20.0, first_id: int = 1):
    """ATL03 segment bookkeeping for photons sorted by along-track distance ``x_m``.

    Returns (segment_id, ph_index_beg (1-based, 0 when empty), segment_ph_cnt,
    segment_dist_x [m], dist_ph_along [m])."""
    x = np.asarray(x_m, np.float64)
    if x.size and np.any(np.diff(x) < 0):
        raise ValueError("photons must be sorted by along-track distance")
    x0 = np.floor(x.min() / segment_length_m) * segment_length_m if x.size else 0.0
    seg = ((x - x0) // segment_length_m).astype(np.int64)
    nseg = int(seg.max()) + 1 if x.size else 0
    cnt = np.bincount(seg, minlength=nseg)
    beg = np.concatenate([[0], np.cumsum(cnt)[:-1]]) + 1
    beg[cnt == 0] = 0
    dist_x = x0 + segment_length_m * np.arange(nseg)
    return first_id + np.arange(nseg), beg, cnt, dist_x, x - dist_x[seg]


def write_atl03(path: str | Path, beams: list[PhotonBeam]) -> Path:
    """Write beams in the ATL03 layout read by :func:`read_atl03` (radians → degrees)."""
    import h5py

    path = Path(path)
    with h5py.File(path, "w") as f:
        f.attrs["short_name"] = "ATL03"
        f.attrs["source"] = "calidar simulate photons (synthetic)"
        for b in beams:
            hg = f.create_group(f"{b.beam}/heights")
            hg.create_dataset("delta_time", data=b.delta_time).attrs["units"] = "seconds since 2018-01-01"
            hg.create_dataset("lat_ph", data=np.degrees(b.lat)).attrs["units"] = "degrees_north"
            hg.create_dataset("lon_ph", data=np.degrees(b.lon)).attrs["units"] = "degrees_east"
            hg.create_dataset("h_ph", data=b.h.astype(np.float32)).attrs["units"] = "meters"
            hg.create_dataset("dist_ph_along", data=b.dist_along.astype(np.float32)).attrs["units"] = "meters"
            hg.create_dataset("dist_ph_across", data=b.dist_across.astype(np.float32)).attrs["units"] = "meters"
            hg.create_dataset("signal_conf_ph", data=b.signal_conf.astype(np.int8))
            hg.create_dataset("quality_ph", data=b.quality.astype(np.int8))
            gg = f.create_group(f"{b.beam}/geolocation")
            gg.create_dataset("segment_id", data=b.segment_id.astype(np.int32))
            gg.create_dataset("ph_index_beg", data=b.ph_index_beg.astype(np.int64))
            gg.create_dataset("segment_ph_cnt", data=b.segment_ph_cnt.astype(np.int32))
            if b.segment_dist_x is not None:
                gg.create_dataset("segment_dist_x", data=b.segment_dist_x).attrs["units"] = "meters"
    return path
