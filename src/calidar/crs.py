"""Points between ECEF and a CRS with PROJ (pyproj): cached transformers, geoid heights
(a clear error naming a missing grid instead of PROJ's "ballpark" fallback, or a constant
undulation N), and the fast forms linearized per tile (:func:`tile_linear`: points moved by metres,
points in ECEF to ~1 mm).
:mod:`calidar.georef` re-exports these."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pyproj
from numba import njit

from calidar.cells import group_cells
from calidar.errors import InputError

ECEF_CRS = "EPSG:4978"


@lru_cache(maxsize=64)
def _cached_transformer(src: pyproj.CRS, dst: pyproj.CRS) -> pyproj.Transformer:
    # PROJ's warning "best transformation is not available" is checked by _transformer
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return pyproj.Transformer.from_crs(src, dst, always_xy=True)


def _missing_grids(src: pyproj.CRS, dst: pyproj.CRS) -> list[str]:
    """Names (and download addresses) of the PROJ grids the best transformation needs and lacks."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        group = pyproj.transformer.TransformerGroup(src, dst, always_xy=True)
    names = []
    for op in group.unavailable_operations:
        for g in op.grids:
            known = [n.split(" ")[0] for n in names]
            if not g.available and g.short_name and g.short_name not in known:
                names.append(f"{g.short_name} ({g.url})" if g.url else g.short_name)
    return names


def _transformer(src, dst, source=None) -> pyproj.Transformer:
    """A transformation between two CRSs, cached; a clear error (naming the missing grid) instead of
    PROJ's "ballpark" vertical fallback, which would take heights above a geoid as ellipsoidal."""
    try:
        src, dst = pyproj.CRS.from_user_input(src), pyproj.CRS.from_user_input(dst)
    except (pyproj.exceptions.CRSError, TypeError) as e:
        message = f"expected a CRS pyproj knows (e.g. EPSG:32611): {e}"
        raise InputError(source, "crs", message) from None
    t = _cached_transformer(src, dst)
    if "ballpark vertical" in t.description.lower():
        geoid = src if src.is_compound or src.is_vertical else dst
        grids = ", ".join(_missing_grids(src, dst)[:2]) or "no grid known"
        raise InputError(source, "crs", f"{geoid.name} has heights above a geoid and PROJ lacks "
                         f"its grid ({grids}); install it (projsync --file NAME, or "
                         "PROJ_NETWORK=ON), give --geoid-undulation N (m, constant: a small area) "
                         "or an ellipsoidal --crs (docs/conventions.md, Heights)")
    return t


def _horizontal(crs, source, undulation_m) -> pyproj.CRS:
    """The horizontal part of a compound CRS with a geoid (heights then taken as ellipsoidal after
    adding ``undulation_m``); an error for a CRS without geoid heights."""
    crs = pyproj.CRS.from_user_input(crs)
    if not crs.is_compound:
        raise InputError(source, "--geoid-undulation",
                         f"given ({undulation_m} m) but {crs.name} has ellipsoidal heights; "
                         "expected a compound CRS with a geoid (e.g. EPSG:32632+3855)")
    return crs.sub_crs_list[0]


def to_crs(points_ecef, crs, geoid_undulation_m: float | None = None, source=None) -> np.ndarray:
    """ECEF (N, 3) → coordinates (N, 3) in ``crs`` (x/east/lon first, heights as the CRS has them).

    ``geoid_undulation_m`` N: heights above the geoid of a compound ``crs`` as ellipsoidal − N
    (a constant for a small area, instead of the geoid grid)."""
    p = np.asarray(points_ecef, float)
    if geoid_undulation_m is None:
        x, y, z = _transformer(ECEF_CRS, crs, source).transform(p[:, 0], p[:, 1], p[:, 2])
        return np.stack([x, y, z], axis=-1)
    out = to_crs(p, _horizontal(crs, source, geoid_undulation_m), None, source)
    out[:, 2] -= geoid_undulation_m
    return out


def from_crs(points, crs, geoid_undulation_m: float | None = None, source=None) -> np.ndarray:
    """Coordinates (N, 3) in ``crs`` → ECEF (N, 3); ``geoid_undulation_m`` as in :func:`to_crs`;
    ``source`` (a file) names where the points came from in errors."""
    p = np.asarray(points, float)
    if geoid_undulation_m is not None:
        p = p.copy()
        p[:, 2] += geoid_undulation_m
        crs = _horizontal(crs, source, geoid_undulation_m)
    x, y, z = _transformer(crs, ECEF_CRS, source).transform(p[:, 0], p[:, 1], p[:, 2])
    return np.stack([x, y, z], axis=-1)


@dataclass(frozen=True)
class TileLinear:
    """The transform between ECEF and a CRS linearized per tile of the points' CRS coordinates:
    one anchor per tile (its first point) transformed by PROJ, with the Jacobian ∂crs/∂ECEF
    there by finite differences (four PROJ calls per tile instead of one per point)."""

    xyz: np.ndarray  #: (N, 3) the points' CRS coordinates
    rows: np.ndarray  #: (N,) the tile of each point
    anchor: np.ndarray  #: (T,) the point anchoring each tile
    anchor_ecef: np.ndarray  #: (T, 3) m
    jac: np.ndarray  #: (T, 3, 3) ∂crs/∂ECEF at each anchor

    def moved(self, d_ecef: np.ndarray) -> np.ndarray:
        """CRS coordinates of the points moved by ``d_ecef`` (N, 3) m: xyz + J · d; below 0.1 mm
        from the full transform for moves up to ~10 m (J changes by ~tile/R ≈ 1e-5 across a
        tile, a second-order term by |d|²/R)."""
        return tile_moved(self.xyz, self.jac, self.rows, np.asarray(d_ecef, float))

    def near_ecef(self) -> np.ndarray:
        """The points in ECEF from the anchors' Jacobians: off the full transform by up to ~1 mm
        (≈ d²/R for d ≤ the tile's diagonal, and Δh·d/R across heights), which cancels where only
        the moves of points count (re-georeferencing: inverse and forward through the same
        points)."""
        inv = np.linalg.inv(self.jac)
        from_anchor = self.xyz - self.xyz[self.anchor][self.rows]
        return tile_moved(self.anchor_ecef[self.rows], inv, self.rows, from_anchor)


def tile_linear(xyz, crs, geoid_undulation_m: float | None = None, source=None,
                tile_m: float = 50.0) -> TileLinear:
    """:class:`TileLinear` of points (N, 3) in ``crs`` on tiles of ``tile_m`` m (of ≈ tile_m/1e5
    degrees in a geographic CRS); ``geoid_undulation_m``, ``source`` as in :func:`from_crs`."""
    xyz = np.asarray(xyz, float)
    if xyz.shape[0] == 0:
        none = np.zeros(0, np.int64)
        return TileLinear(xyz, none, none, np.zeros((0, 3)), np.zeros((0, 3, 3)))
    geographic = pyproj.CRS.from_user_input(crs).is_geographic
    tile = tile_m / 1e5 if geographic else tile_m  # ≈ 1e5 m a degree
    # anchor: each tile's first point
    ij = _tile_indices(xyz, float(tile))
    rows, anchor = group_cells(np.floor(xyz[:, :2] / tile).astype(np.int64) if ij is None else ij)
    anchor_ecef = from_crs(xyz[anchor], crs, geoid_undulation_m, source)
    at = to_crs(anchor_ecef, crs, geoid_undulation_m, source)
    def moved(step):
        return to_crs(anchor_ecef + step, crs, geoid_undulation_m, source) - at

    jac = np.stack([moved(step) for step in np.eye(3)], axis=2)
    return TileLinear(xyz, rows, anchor, anchor_ecef, jac)


def _tile_indices(xyz: np.ndarray, tile: float) -> np.ndarray | None:
    """floor(xy / tile) (N, 2) int64 of points (N, 3) in one numba pass, as the numpy steps; None
    when a coordinate is not finite (numpy's cast is the caller's)."""
    ij = np.empty((xyz.shape[0], 2), np.int64)
    return ij if _tile_kernel(xyz, tile, ij) else None


@njit(cache=True, nogil=True)
def _tile_kernel(xyz, tile, ij):  # pragma: no cover - numba
    for k in range(xyz.shape[0]):
        x, y = xyz[k, 0] / tile, xyz[k, 1] / tile
        if not (abs(x) < 9.2e18 and abs(y) < 9.2e18):  # NaN, ±inf, beyond int64: numpy's
            return False
        ij[k, 0], ij[k, 1] = np.int64(np.floor(x)), np.int64(np.floor(y))
    return True


@njit(cache=True, nogil=True)
def plus_jd(b0, b1, b2, jac, j, d0, d1, d2):  # pragma: no cover - numba
    """b + jac[j] · d of one point, component by component: the one form of a tile's linear move
    (:func:`tile_moved`, and the re-georeferencing kernel's, calidar.ingest.regeoref)."""
    return (b0 + (jac[j, 0, 0] * d0 + jac[j, 0, 1] * d1 + jac[j, 0, 2] * d2),
            b1 + (jac[j, 1, 0] * d0 + jac[j, 1, 1] * d1 + jac[j, 1, 2] * d2),
            b2 + (jac[j, 2, 0] * d0 + jac[j, 2, 1] * d1 + jac[j, 2, 2] * d2))


@njit(cache=True, nogil=True)
def tile_moved(base: np.ndarray, jac: np.ndarray, rows: np.ndarray, d: np.ndarray) -> np.ndarray:
    """base + jac[rows] · d, point by point (no (n, 3, 3) gather)."""
    out = np.empty_like(base)
    for i in range(base.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = plus_jd(base[i, 0], base[i, 1], base[i, 2], jac,
                                                  rows[i], d[i, 0], d[i, 1], d[i, 2])
    return out


def vertical_reference(crs, geoid_undulation_m: float | None = None) -> tuple[str, str | None]:
    """(what the heights of points in ``crs`` are taken as, a warning or None) (issue 26): a CRS
    without a vertical part has its heights taken as ellipsoidal, which is wrong for the many
    deliveries whose heights are above a geoid (French LiDAR HD in EPSG:2154: NGF-IGN69)."""
    crs = pyproj.CRS.from_user_input(crs)
    name = f"EPSG:{crs.to_epsg()}" if crs.to_epsg() else crs.name
    if crs.is_geocentric:
        return "ellipsoidal (geocentric coordinates)", None
    if crs.is_compound:
        vertical = crs.sub_crs_list[-1].name
        if geoid_undulation_m is not None:
            return (f"heights above {vertical} made ellipsoidal with a constant geoid undulation "
                    f"N = {geoid_undulation_m:g} m (--geoid-undulation)"), None
        return f"heights above {vertical}, made ellipsoidal with its geoid grid (PROJ)", None
    if len(crs.axis_info) >= 3:
        return f"ellipsoidal ({name} is 3-D: its heights are above the ellipsoid)", None
    return f"ellipsoidal (assumed: {name} has no vertical part)", _no_vertical_warning(crs, name)


def _no_vertical_warning(crs: pyproj.CRS, name: str) -> str:
    """The warning for heights taken as ellipsoidal in a CRS without a vertical part, with the
    compound CRS to give instead (NGF-IGN69, EPSG:5720, beside Lambert-93; else EGM2008 height)."""
    epsg = crs.to_epsg()
    horizontal = f"EPSG:{epsg}+{5720 if epsg == 2154 else 3855}" if epsg else "CRS+3855"
    return (f"{name} has no vertical part: the heights are taken as ellipsoidal (above the "
            "ellipsoid). If they are above a geoid (orthometric, e.g. French LiDAR HD: NGF-IGN69), "
            f"give a compound --crs (e.g. --crs {horizontal}) with --geoid-undulation N (m, the "
            "geoid's height above the ellipsoid there; a constant for a small area), or install "
            "the geoid grid for PROJ (projsync) and give the compound --crs alone; this machine "
            "cannot download grids")
