"""The ground surface at checkpoints from a TIN of the ground points around each, as the ASPRS
and USGS procedures test lidar (a checkpoint rarely falls on a lidar point, so the surface is
interpolated linearly in the triangle of the ground TIN that contains it).

Points are streamed: :class:`GroundCollector` keeps, chunk by chunk, only the points within
``radius_m`` of some checkpoint that could be ground (class 2, or last/single returns), with
the classes each source holds; once every file is read, each source's points are chosen as
:mod:`calidar.strips.selection` does for the swath checks (class 2 where the source has it,
else last and single returns). :func:`tin_heights` triangulates the points around each
checkpoint (``scipy.spatial.Delaunay``), finds the triangle containing it and interpolates;
a checkpoint with too few points, outside every triangle or in a triangle with an edge longer
than ``max_edge_m`` gets no surface, with the reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
from scipy.spatial import Delaunay, QhullError, cKDTree

from calidar.strips.selection import candidate_mask, choose_selection

DEFAULT_RADIUS_M = 5.0  #: ground points within this distance of a checkpoint are kept
DEDUP_M = 1e-4  #: points closer than this in x, y are one TIN node (their mean height)


@dataclass
class GroundCollector:
    """Ground-point candidates near the checkpoints ``xy`` (N, 2, metric), fed chunk by chunk."""

    xy: np.ndarray
    radius_m: float = DEFAULT_RADIUS_M
    #: source → list of (xyz, angle, psid, classification, return_number, n_returns)
    parts: dict = field(default_factory=dict)
    #: source → set of classes seen (None: no classification)
    present: dict = field(default_factory=dict)
    seen: int = 0  #: points fed

    def __post_init__(self):
        self.tree = cKDTree(np.asarray(self.xy, float))

    def add(self, source, xyz: np.ndarray, point_source_id=None, classification=None,
            return_number=None, number_of_returns=None, scan_angle_deg=None) -> None:
        """Feed one chunk of ``source`` (metric xyz (M, 3) and the LAS attributes, None when
        absent)."""
        self.seen += len(xyz)
        if classification is None:
            self.present.setdefault(source, None)
        else:
            self.present.setdefault(source, set()).update(int(c) for c in np.unique(classification))
        if not len(xyz):
            return
        d, _ = self.tree.query(xyz[:, :2], distance_upper_bound=self.radius_m)
        fields = SimpleNamespace(xyz=xyz, classification=classification,
                                 return_number=return_number, number_of_returns=number_of_returns)
        keep = np.isfinite(d) & candidate_mask(fields)
        if not keep.any():
            return
        if scan_angle_deg is None:
            angle = np.full(len(xyz), np.nan)
        else:
            angle = np.asarray(scan_angle_deg, float)
        take = [None if a is None else np.asarray(a)[keep]
                for a in (point_source_id, classification, return_number, number_of_returns)]
        self.parts.setdefault(source, []).append((xyz[keep], angle[keep], *take))

    def ground(self, classes: tuple[int, ...] | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
        """(xyz (K, 3), point_source_id (K,) or −1, scan angle (K,) deg or NaN,
        {source: PointSelection}) of the points each source's selection keeps."""
        xyz, ids, angles = [np.zeros((0, 3))], [np.zeros(0, np.int64)], [np.zeros(0)]
        selections = {}
        for source, present in self.present.items():
            classes_seen = None if present is None else np.array(sorted(present))
            selection = choose_selection(source, classes_seen, classes)
            selections[source] = selection
            for p, angle, psid, cls, rn, nr in self.parts.get(source, []):
                mask = selection.mask(SimpleNamespace(xyz=p, classification=cls, return_number=rn,
                                                      number_of_returns=nr))
                xyz.append(p[mask])
                angles.append(angle[mask])
                if psid is None:
                    ids.append(np.full(int(mask.sum()), -1, np.int64))
                else:
                    ids.append(psid[mask].astype(np.int64))
        return np.concatenate(xyz), np.concatenate(ids), np.concatenate(angles), selections


@dataclass(frozen=True)
class TinHeights:
    """The TIN surface at each checkpoint (NaN where there is none, ``reason`` says why)."""

    z: np.ndarray  #: (N,) surface height, m
    n_points: np.ndarray  #: (N,) ground points within the radius
    max_edge_m: np.ndarray  #: (N,) longest edge of the containing triangle (NaN: none)
    strips: list  #: per checkpoint: the point_source_ids of the triangle's corners (sorted, unique)
    reason: list  #: per checkpoint: "" or why there is no surface
    #: (N,) an attribute of the points interpolated as the height (the scan angle)
    aux: np.ndarray | None = None


def _dedup(xy: np.ndarray, z: np.ndarray, ids: np.ndarray, aux: np.ndarray):
    """Points at one x, y (within DEDUP_M) become one node with their mean height (and aux)."""
    key = np.round(xy / DEDUP_M).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    if first.size == xy.shape[0]:
        return xy, z, ids, aux
    count = np.bincount(inv)
    mean_z, mean_aux = np.bincount(inv, weights=z) / count, np.bincount(inv, weights=aux) / count
    return xy[first], mean_z, ids[first], mean_aux


NONE = (np.nan, np.nan, np.nan, ())


def _barycentric(c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (T, 3) of the origin in triangles (T, 3, 2) (NaN for degenerate
    ones); in closed form: scipy's find_simplex and transform are slow on gridded (cocircular)
    points."""
    v0, v1 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    v2 = -c[:, 0]
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        w1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
        w2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
        return np.c_[1.0 - w1 - w2, w1, w2]


def _one(p_xy, xy, z, ids, aux, max_edge_m):
    """(z, aux, longest edge, corner strips), reason of the TIN of (xy, z) at ``p_xy``."""
    if xy.shape[0] < 3:
        return NONE, f"{xy.shape[0]} ground point{'s' if xy.shape[0] != 1 else ''} near it"
    try:
        tri = Delaunay(xy)
    except (QhullError, ValueError):
        return NONE, "ground points near it are collinear"
    w_all = _barycentric(xy[tri.simplices] - p_xy)
    worst = np.nan_to_num(w_all.min(axis=1), nan=-np.inf)
    s = int(np.argmax(worst))
    if worst[s] < -1e-9:
        return NONE, "outside the TIN of the ground points near it (at the data's edge?)"
    corners = tri.simplices[s]
    c = xy[corners]
    edge = float(max(np.hypot(*(c[0] - c[1])), np.hypot(*(c[1] - c[2])), np.hypot(*(c[2] - c[0]))))
    if edge > max_edge_m:
        why = f"its TIN triangle has a {edge:.1f} m edge (> {max_edge_m:g} m)"
        return (np.nan, np.nan, edge, ()), why + ": a gap in the ground points"
    w = w_all[s]
    corner_strips = tuple(sorted({int(i) for i in ids[corners]}))
    return (float(w @ z[corners]), float(w @ aux[corners]), edge, corner_strips), ""


def tin_heights(points_xyz: np.ndarray, point_ids: np.ndarray, checkpoints_xy: np.ndarray,
                radius_m: float = DEFAULT_RADIUS_M, max_edge_m: float = DEFAULT_RADIUS_M,
                aux=None) -> TinHeights:
    """The TIN surface of ``points_xyz`` (K, 3; ids (K,)) at each of ``checkpoints_xy`` (N, 2),
    from the points within ``radius_m`` (all in one metric frame); ``aux`` (K,) is interpolated
    alike."""
    cps = np.asarray(checkpoints_xy, float)
    n = cps.shape[0]
    z, a, edges = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    npts = np.zeros(n, np.int64)
    strips, reason = [()] * n, [""] * n
    if len(points_xyz) == 0:
        return TinHeights(z, npts, edges, strips, ["no ground points near it"] * n, a)
    aux = np.zeros(len(points_xyz)) if aux is None else np.asarray(aux, float)
    tree = cKDTree(points_xyz[:, :2])
    for i, near in enumerate(tree.query_ball_point(cps, radius_m)):
        near = np.asarray(near, np.int64)
        npts[i] = near.size
        nodes = _dedup(points_xyz[near, :2], points_xyz[near, 2], point_ids[near], aux[near])
        xy, zz, ids, au = nodes
        (z[i], a[i], edges[i], strips[i]), reason[i] = _one(cps[i], xy, zz, ids, au, max_edge_m)
    return TinHeights(z, npts, edges, strips, reason, a)


def heights_per_strip(points_xyz: np.ndarray, point_ids: np.ndarray, checkpoints_xy: np.ndarray,
                      radius_m: float = DEFAULT_RADIUS_M, max_edge_m: float = DEFAULT_RADIUS_M,
                      angles=None) -> dict[int, TinHeights]:
    """{point_source_id: the TIN of that flight line's ground points alone (NaN where it does not
    cover a checkpoint), ``angles`` (scan angles) interpolated as aux}: which line is off, and
    how."""
    out = {}
    angles = np.full(len(points_xyz), np.nan) if angles is None else np.asarray(angles, float)
    for sid in np.unique(point_ids):
        mine = point_ids == sid
        out[int(sid)] = tin_heights(points_xyz[mine], point_ids[mine], checkpoints_xy, radius_m,
                                    max_edge_m, angles[mine])
    return out
