"""ICESat-2 ATL03 photon files (HDF5): read beams as users have them, write the same layout.

Layout read (ATL03 v006, the subset calidar needs)::

    /<beam>/heights/     delta_time [s since 2018-01-01], lat_ph, lon_ph [deg], h_ph [m],
                         dist_ph_along, dist_ph_across [m], signal_conf_ph (N×5 int8:
                         land, ocean, sea ice, land ice, inland water), quality_ph
    /<beam>/geolocation/ segment_id, ph_index_beg (1-based), segment_ph_cnt, segment_dist_x [m]
                         (or segment_length), delta_time [s] (the segments' reference photons)
    /<beam> attributes   atlas_beam_type ("strong"/"weak"), atlas_spot_number (1–6)
    /orbit_info/sc_orient  0 backward, 1 forward, 2 transition (when the attributes are absent)

Along-track distance of a photon = segment_dist_x of its 20 m segment + dist_ph_along
(ATL03 ATBD, Neumann et al. 2019). Subsetters and clipping tools often keep the segment
arrays of the whole granule (or rewrite them partly) while keeping only some photons, so
``ph_index_beg``/``segment_ph_cnt`` no longer tile the photons. Then each photon is placed on
its segment by its own fields (:func:`along_track`): its time, interpolated between the
segments' reference-photon times, predicts its along-track distance to a few metres, and
the segment whose start + dist_ph_along is nearest to it (segments are 20 m long) is its
segment. ``PhotonBeam.along_track_source`` says which way was taken, and ``calidar info``
shows it; without segment times or starts a clipped file is refused, naming the field.

Strong/weak: the beam group's ``atlas_beam_type``, else ``orbit_info/sc_orient`` (backward:
the left beams gt1l, gt2l, gt3l are strong; forward: the right beams).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.io.atl03_along import SEGMENTS_SOURCE, along_track
from calidar.validate import existing_file
from calidar.validate import values as checked

#: The six ATLAS beams (ground tracks).
BEAMS = ("gt1l", "gt1r", "gt2l", "gt2r", "gt3l", "gt3r")
#: Columns of signal_conf_ph (surface types).
SURFACE_TYPES = ("land", "ocean", "sea_ice", "land_ice", "inland_water")
#: Detector channels of a strong and of a weak ATLAS beam.
CHANNELS = {"strong": 16, "weak": 4}
EPOCH_UNITS = "seconds since 2018-01-01"  #: the units attribute of ATL03's delta_time
_HEIGHTS = ("delta_time", "lat_ph", "lon_ph", "h_ph", "dist_ph_along", "dist_ph_across",
            "signal_conf_ph")
_SEGMENTS = ("segment_id", "ph_index_beg", "segment_ph_cnt")
#: Ranges every photon's values must lie in (SI; lat/lon in degrees as in the file).
_RANGES = {"delta_time": (0.0, 1e10, "s"), "lat_ph": (-90.0, 90.0, "deg"),
           "lon_ph": (-180.0, 360.0, "deg"), "h_ph": (-2000.0, 15000.0, "m"),
           "dist_ph_along": (-1000.0, 1000.0, "m"), "dist_ph_across": (-20000.0, 20000.0, "m"),
           "signal_conf_ph": (-2.0, 4.0, "")}


@dataclass
class PhotonBeam:
    """The photons of one beam. Angles in radians, distances in metres, time in seconds."""

    beam: str
    delta_time: np.ndarray  #: (N,) s since the ATLAS epoch 2018-01-01 (per shot)
    lat: np.ndarray  #: (N,) rad
    lon: np.ndarray  #: (N,) rad
    h: np.ndarray  #: (N,) m, height above the WGS84 ellipsoid
    dist_along: np.ndarray  #: (N,) m, dist_ph_along (within the segment, 0–20 m)
    dist_across: np.ndarray  #: (N,) m, dist_ph_across
    signal_conf: np.ndarray  #: (N, 5) int8 ATL03 confidence per surface type (-2..4)
    quality: np.ndarray  #: (N,) int8 quality_ph
    segment_id: np.ndarray  #: (S,) int
    ph_index_beg: np.ndarray  #: (S,) 1-based index of each segment's first photon (0 = empty)
    segment_ph_cnt: np.ndarray  #: (S,) photons per segment
    #: (S,) m, along-track distance of each segment start
    segment_dist_x: np.ndarray | None = None
    source: str | None = None
    #: (S,) s, delta_time of each segment's reference photon
    segment_time: np.ndarray | None = None
    strength: str | None = None  #: "strong", "weak" or None (unknown)
    spot: int | None = None  #: ATLAS laser spot 1–6 (the physical beam), None when unknown
    #: (N,) m, set by :func:`~calidar.io.atl03_along.along_track` (computed on first use)
    along_track: np.ndarray | None = None
    #: how ``along_track`` was found (SEGMENTS_SOURCE or a note)
    along_track_source: str | None = None

    def __len__(self) -> int:
        return int(self.h.size)

    @property
    def x(self) -> np.ndarray:
        """Along-track distance of every photon (m): segment_dist_x + dist_ph_along."""
        if self.along_track is None:
            self.along_track, self.along_track_source = along_track(self)
        return self.along_track

    @property
    def channels(self) -> int | None:
        """Detector channels of the beam (16 strong, 4 weak), None when the strength is unknown."""
        return CHANNELS.get(self.strength)

    @property
    def label(self) -> str:
        """The ground track with its laser spot and strength when known: 'gt1l (spot 6, weak)'."""
        parts = (f"spot {self.spot}" if self.spot else "", self.strength or "")
        extra = ", ".join(x for x in parts if x)
        return f"{self.beam} ({extra})" if extra else self.beam

    def shot_index(self) -> np.ndarray:
        """Integer id of the laser shot of each photon (photons of one pulse share delta_time)."""
        t = self.delta_time
        if t.size and np.all(t[1:] >= t[:-1]):  # ATL03 order: O(N), no sort
            return np.concatenate([[0], np.cumsum(t[1:] != t[:-1])])
        _, inv = np.unique(t, return_inverse=True)
        return inv


def _need(group, name: str, path, where: str):
    if name not in group:
        raise InputError(path, f"{where}/{name}", "missing from the ATL03 file")
    return group[name][()]


def _open_hdf5(path: Path):
    """An open h5py.File; a clear error when the file is not HDF5."""
    import h5py

    existing_file(path, "ATL03 file")
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


def select_beams(path: str | Path, beams: tuple[str, ...] | None) -> list[str]:
    """The beams to read: every beam the file has (``beams`` None), else ``beams`` (ATL03 beam
    names, parsed from ``--beam`` at the edge) each checked against the file, in their order, each
    once."""
    have = atl03_beams(path)
    if beams is None:
        if not have:
            raise InputError(path, None, "no ATL03 beam groups (gt1l … gt3r with a heights group)")
        return have
    for b in beams or ("",):
        if b not in BEAMS:
            raise InputError(None, "--beam", f"expected all, one of {', '.join(BEAMS)} or several "
                             f"separated by commas, got {', '.join(beams)!r}")
        if b not in have:
            raise InputError(path, b,
                             f"beam group missing; the file has {', '.join(have) or 'no beams'}")
    return list(dict.fromkeys(beams))


def _text(v) -> str:
    """An HDF5 attribute (bytes, a one-element array or a scalar) as lower-case text."""
    if isinstance(v, bytes):
        return v.decode().strip().lower()
    return str(np.asarray(v).ravel()[0] if np.ndim(v) else v).strip().lower()


def beam_strength(f, beam: str) -> tuple[str | None, int | None]:
    """(strong/weak/None, spot 1–6/None) of a beam of an open ATL03 file: the group's
    atlas_beam_type/atlas_spot_number, else orbit_info/sc_orient."""
    attrs = f[beam].attrs
    strength = _text(attrs["atlas_beam_type"]) if "atlas_beam_type" in attrs else None
    spot = int(_text(attrs["atlas_spot_number"])) if "atlas_spot_number" in attrs else None
    if strength not in CHANNELS:
        strength = None
        if "orbit_info/sc_orient" in f:
            orient = int(np.asarray(f["orbit_info/sc_orient"][()]).ravel()[0])
            if orient in (0, 1):  # 0 backward: left beams strong; 1 forward: right beams strong
                strength = "strong" if (beam.endswith("l") == (orient == 0)) else "weak"
    return strength, spot


def read_atl03(path: str | Path, beam: str = "gt1l") -> PhotonBeam:
    """Read the photons of one beam of an ATL03 file (degrees in the file → radians); every
    value checked (finite, in range); the along-track distance resolved
    (:func:`~calidar.io.atl03_along.along_track`)."""
    path = Path(path)
    if beam not in BEAMS:
        raise InputError(None, "--beam", f"expected one of {', '.join(BEAMS)} or all, got {beam!r}")
    d, s, quality, dist_x, seg_time, strength, spot = _read_beam(path, beam)
    _check_heights(d, path, beam)
    conf = d["signal_conf_ph"]
    if conf.ndim != 2 or conf.shape[1] != len(SURFACE_TYPES):
        raise InputError(path, f"{beam}/heights/signal_conf_ph",
                         f"expected shape (N, 5), got {conf.shape}")

    def f64(a):
        return a.astype(np.float64)

    pb = PhotonBeam(
        beam=beam, delta_time=f64(d["delta_time"]), lat=np.radians(f64(d["lat_ph"])),
        lon=np.radians(f64(d["lon_ph"])), h=f64(d["h_ph"]), dist_along=f64(d["dist_ph_along"]),
        dist_across=f64(d["dist_ph_across"]), signal_conf=conf.astype(np.int8),
        quality=np.asarray(quality, np.int8), segment_id=s["segment_id"].astype(np.int64),
        ph_index_beg=s["ph_index_beg"].astype(np.int64),
        segment_ph_cnt=s["segment_ph_cnt"].astype(np.int64),
        segment_dist_x=None if dist_x is None else np.asarray(dist_x, np.float64),
        source=str(path),
        segment_time=None if seg_time is None else np.asarray(seg_time, np.float64),
        strength=strength, spot=spot,
    )
    pb.along_track, pb.along_track_source = along_track(pb)
    return pb


def _read_beam(path: Path, beam: str):
    """The raw arrays of one beam: its heights fields, its segments' bookkeeping, quality_ph
    (zeros when absent), the segments' starts (m; from their lengths when absent; None), their
    reference times (s; None) and the beam's strength and spot."""
    with _open_hdf5(path) as f:
        if beam not in f:
            have = [b for b in BEAMS if b in f]
            raise InputError(path, beam,
                             f"beam group missing; the file has {', '.join(have) or 'no beams'}")
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
        seg_time = gg["delta_time"][()] if "delta_time" in gg else None
        strength, spot = beam_strength(f, beam)
    return d, s, quality, dist_x, seg_time, strength, spot


def _check_heights(d: dict, path: Path, beam: str) -> None:
    """One value per photon in every heights field (signal_conf_ph: five; a 2-D field is named,
    not its neighbours), each in its range, the photons in time order."""
    for k in _HEIGHTS:
        if d[k].ndim != (2 if k == "signal_conf_ph" else 1):
            want = "shape (N, 5)" if k == "signal_conf_ph" else "one value per photon (1-D)"
            raise InputError(path, f"{beam}/heights/{k}",
                             f"expected {want}, got shape {d[k].shape}")
    n = d["h_ph"].shape[0]
    for k in _HEIGHTS:
        if d[k].shape[0] != n:
            raise InputError(path, f"{beam}/heights/{k}",
                             f"expected {n} rows like h_ph, got {d[k].shape[0]}")
        lo, hi, unit = _RANGES[k]
        checked(d[k], path, f"{beam}/heights/{k}", lo, hi, unit, what="photon")
    t = d["delta_time"]
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0])
        raise InputError(path, f"{beam}/heights/delta_time", "expected photons in time order; "
                         f"{back.size} steps back, the first at photon {i + 1} "
                         f"({t[i]:.6f} → {t[i + 1]:.6f} s)")


def atl03_summary(path: str | Path) -> dict:
    """What ``calidar info`` shows of an ATL03 file. Per beam: photons, laser shots, 20 m
    segments, strength and laser spot, how the along-track distance was found, delta_time span
    (s since 2018-01-01), lat/lon (deg) and height (m, ellipsoidal) ranges; a top-level
    ``warning`` when a beam's segment bookkeeping is partial."""
    path = Path(path)
    beams = atl03_beams(path)
    if not beams:
        raise InputError(path, None, "an HDF5 file without ATL03 beam groups (gt1l … "
                         "gt3r/heights); calidar info reads LAS/LAZ, SBET, text trajectories and "
                         "ICESat-2 ATL03 (HDF5)")

    def span(a):
        return [float(a.min()), float(a.max())] if a.size else None

    rows = []
    for b in beams:
        pb = read_atl03(path, b)
        shots = int(pb.shot_index().max() + 1) if len(pb) else 0
        rows.append({"beam": b, "photons": len(pb), "shots": shots,
                     "segments": int(pb.segment_id.size), "strength": pb.strength, "spot": pb.spot,
                     "along_track_from": pb.along_track_source, "delta_time": span(pb.delta_time),
                     "lat_deg": span(np.degrees(pb.lat)), "lon_deg": span(np.degrees(pb.lon)),
                     "h_m": span(pb.h)})
    partial = [r["beam"] for r in rows
               if r["photons"] and r["along_track_from"] != SEGMENTS_SOURCE]
    warning = None
    if partial:
        how = next(r for r in rows if r["beam"] == partial[0])["along_track_from"]
        warning = f"{', '.join(partial)}: along-track distance from the {how}"
    return {"file": str(path), "kind": "photons (ICESat-2 ATL03)",
            "photons": sum(r["photons"] for r in rows), "beams": rows, "warning": warning}


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
    """Write beams in the ATL03 layout read by :func:`read_atl03` (radians → degrees).

    The file is built in memory and then written out as plain bytes: HDF5 failing a write itself
    (a full disk) leaves its library in a state that prints pages of errors and can crash the
    process at exit; a plain write fails with one OSError (ENOSPC)."""
    import io

    import h5py

    path = Path(path)
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as f:
        _write_beams(f, beams)
    with open(path, "wb") as out:
        out.write(buffer.getbuffer())
    return path


def _write_beams(f, beams: list[PhotonBeam]) -> None:
    """The ATL03 groups and datasets of ``beams`` into the open file ``f``."""
    f.attrs["short_name"] = "ATL03"
    f.attrs["source"] = "calidar simulate photons (synthetic)"
    for b in beams:
        grp = f.create_group(b.beam)
        if b.strength:
            grp.attrs["atlas_beam_type"] = b.strength
        if b.spot:
            grp.attrs["atlas_spot_number"] = str(b.spot)
        hg = grp.create_group("heights")
        with_units = (("delta_time", b.delta_time, EPOCH_UNITS),
                      ("lat_ph", np.degrees(b.lat), "degrees_north"),
                      ("lon_ph", np.degrees(b.lon), "degrees_east"),
                      ("h_ph", b.h.astype(np.float32), "meters"),
                      ("dist_ph_along", b.dist_along.astype(np.float32), "meters"),
                      ("dist_ph_across", b.dist_across.astype(np.float32), "meters"))
        for name, data, units in with_units:
            hg.create_dataset(name, data=data).attrs["units"] = units
        hg.create_dataset("signal_conf_ph", data=b.signal_conf.astype(np.int8))
        hg.create_dataset("quality_ph", data=b.quality.astype(np.int8))
        gg = grp.create_group("geolocation")
        gg.create_dataset("segment_id", data=b.segment_id.astype(np.int32))
        gg.create_dataset("ph_index_beg", data=b.ph_index_beg.astype(np.int64))
        gg.create_dataset("segment_ph_cnt", data=b.segment_ph_cnt.astype(np.int32))
        if b.segment_dist_x is not None:
            gg.create_dataset("segment_dist_x", data=b.segment_dist_x).attrs["units"] = "meters"
        if b.segment_time is not None:
            gg.create_dataset("delta_time", data=b.segment_time).attrs["units"] = EPOCH_UNITS
