"""Checkpoint residuals, the ASPRS statistics and where the errors are: the result of ``calidar
accuracy`` once the TIN heights are known (:func:`assess`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calidar.accuracy.asprs import VerticalAccuracy, vertical_accuracy
from calidar.accuracy.tin import TinHeights
from calidar.io.checkpoints import Checkpoints


@dataclass(frozen=True)
class StripError:
    """The residuals at the NVA checkpoints of one flight line's own TIN."""

    point_source_id: int
    n: int
    mean_m: float
    rmse_m: float
    #: d(dz)/d(scan angle) by least squares (None: too few checkpoints or angles too close)
    slope_m_per_deg: float | None = None
    slope_sigma_m_per_deg: float | None = None


@dataclass(eq=False)
class Assessment:
    """Everything ``calidar accuracy`` reports (lengths in m, heights in the points' CRS)."""

    checkpoints: Checkpoints  #: as read
    xyz: np.ndarray  #: (N, 3) the checkpoints in the points' CRS
    heights: TinHeights
    dz: np.ndarray  #: (N,) surface − checkpoint (NaN: not used)
    accuracy: VerticalAccuracy
    survey_rmse_m: float | None
    #: where the survey term came from ("sigma column", "--survey-sigma", "not given")
    survey_source: str
    strip_errors: list[StripError] = field(default_factory=list)
    #: source → calidar.strips.selection.PointSelection
    selections: dict = field(default_factory=dict)
    crs_name: str | None = None
    usgs_swaths: object = None  #: calidar.accuracy.usgs.SwathChecks (``--swaths``), None: not run

    @property
    def used(self) -> np.ndarray:
        return np.isfinite(self.dz)

    @property
    def nva(self) -> np.ndarray:
        return self.used & ~self.checkpoints.vegetated

    @property
    def vva(self) -> np.ndarray:
        return self.used & self.checkpoints.vegetated

    def unused(self) -> list[tuple[str, str]]:
        """(id, reason) of the checkpoints without a surface."""
        ids, reasons = self.checkpoints.ids, self.heights.reason
        return [(str(ids[i]), reasons[i]) for i in np.flatnonzero(~self.used)]

    def outliers(self) -> list[int]:
        """Indices (into the checkpoints) of the NVA outliers."""
        nva = np.flatnonzero(self.nva)
        return [int(nva[k]) for k in self.accuracy.outliers]

    def rows(self) -> list[dict]:
        """One dict per checkpoint: what checkpoints.csv and the report's table hold."""
        cp, h, out = self.checkpoints, self.heights, set(self.outliers())
        rows = []
        for i in range(len(cp)):
            rows.append({"id": str(cp.ids[i]), "line": int(cp.lines[i]),
                         "x": float(self.xyz[i, 0]), "y": float(self.xyz[i, 1]),
                         "z": float(self.xyz[i, 2]), "cover": str(cp.cover()[i]),
                         "sigma_m": None if cp.sigma_m is None else float(cp.sigma_m[i]),
                         "surface_z": _finite_or_none(h.z[i]), "dz_m": _finite_or_none(self.dz[i]),
                         "ground_points": int(h.n_points[i]),
                         "triangle_edge_m": _finite_or_none(h.max_edge_m[i]),
                         "strips": list(h.strips[i]), "outlier": i in out,
                         "not_used": h.reason[i] or None})
        return rows

    def to_dict(self) -> dict:
        from calidar.accuracy.usgs import usgs_dict

        cp = self.checkpoints
        counts = {"file": str(cp.path), "total": len(cp), "used": int(self.used.sum()),
                  "nva_used": int(self.nva.sum()), "vva_used": int(self.vva.sum())}
        outliers = [{"id": str(cp.ids[i]), "dz_m": float(self.dz[i])} for i in self.outliers()]
        return {"accuracy": self.accuracy.to_dict(), "crs": self.crs_name, "usgs": usgs_dict(self),
                "survey_rmse_source": self.survey_source,
                "checkpoints": counts,
                "not_used": [{"id": i, "reason": r} for i, r in self.unused()],
                "outliers": outliers,
                "strips": [vars(s) for s in self.strip_errors],
                "points_used": {str(k): s.to_dict() for k, s in self.selections.items()},
                "rows": self.rows()}


def _finite_or_none(v: float) -> float | None:
    """``v`` as a float, None when it is NaN or infinite (a JSON null)."""
    return float(v) if np.isfinite(v) else None


def survey_term(checkpoints, mask: np.ndarray,
                survey_sigma_m: float | None) -> tuple[float | None, str]:
    """RMSE_V(survey) of the checkpoints in ``mask``: ``survey_sigma_m`` when given, else
    sqrt(mean σ²) of the file's σ column, else None."""
    if survey_sigma_m is not None:
        return float(survey_sigma_m), "--survey-sigma"
    if checkpoints.sigma_m is not None and mask.any():
        rms_sigma_m = float(np.sqrt(np.mean(checkpoints.sigma_m[mask] ** 2)))
        return rms_sigma_m, "the checkpoint file's sigma column"
    return None, "not given"


MIN_SLOPE_POINTS = 5  #: checkpoints a line must cover to fit dz against the scan angle
MIN_ANGLE_SPREAD_DEG = 5.0  #: ... spread over at least this many degrees (std of the angles)


def _slope(d: np.ndarray, angle: np.ndarray) -> tuple[float | None, float | None]:
    """Least-squares slope of d over angle, and its σ from the scatter (n − 2 degrees of
    freedom)."""
    ok = np.isfinite(angle)
    d, angle = d[ok], angle[ok]
    if d.size < MIN_SLOPE_POINTS or np.std(angle) < MIN_ANGLE_SPREAD_DEG:
        return None, None
    c = angle - angle.mean()
    b = float(c @ (d - d.mean()) / (c @ c))
    r = d - d.mean() - b * c
    return b, float(np.sqrt(r @ r / (d.size - 2) / (c @ c)))


def strip_errors(per_strip: dict, z_cp: np.ndarray, nva: np.ndarray) -> list[StripError]:
    """Per flight line (its own TIN, :class:`TinHeights`): mean and RMSE of surface − checkpoint at
    the NVA checkpoints it covers, and how that changes with the scan angle (a mounting's
    signature)."""
    out = []
    for sid, h in sorted(per_strip.items()):
        use = nva & np.isfinite(h.z)
        d = (h.z - z_cp)[use]
        if d.size:
            aux = h.aux[use] if h.aux is not None else np.full(d.size, np.nan)
            rmse_m = float(np.sqrt(np.mean(d**2)))
            out.append(StripError(sid, int(d.size), float(d.mean()), rmse_m, *_slope(d, aux)))
    return out


def assess(checkpoints, xyz: np.ndarray, heights: TinHeights,
           per_strip: dict[int, TinHeights] | None = None, survey_sigma_m: float | None = None,
           selections: dict | None = None, crs_name: str | None = None) -> Assessment:
    """The residuals dz = surface − checkpoint and their statistics (``xyz`` in the surface's
    frame, m)."""
    dz = heights.z - xyz[:, 2]
    used = np.isfinite(dz)
    nva, vva = used & ~checkpoints.vegetated, used & checkpoints.vegetated
    survey, source = survey_term(checkpoints, nva, survey_sigma_m)
    acc = vertical_accuracy(dz[nva], dz[vva], survey)
    strips = strip_errors(per_strip or {}, xyz[:, 2], nva)
    return Assessment(checkpoints, xyz, heights, dz, acc, survey, source, strips, selections or {},
                      crs_name)
