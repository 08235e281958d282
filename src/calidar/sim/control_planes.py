"""Surveyed control planes of a simulated survey (issue 28): roof facets, with their truth.

A surveyor measures points on a roof facet near its corners (pulled ``CORNER_INSET_M`` inside,
where a pole or a reflectorless shot stands on the roof, not on its edge), each with a 3-D normal
error of the stated σ; the file is :mod:`calidar.io.control_planes`' CSV (``control_planes.csv``),
and ``truth.json`` gets, per plane, its true normal and offset (n·p = d in the scene's ENU frame)
and the survey's own error along the normal at the surveyed points' centroid. Facets are picked
among the scene's roof faces (:class:`calidar.sim.scene.Scene`) that are large enough
(``MIN_AREA_M2``), not steeper than ``MAX_SLOPE_DEG`` and inside the flown area (the checkpoints'
margin).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError

CORNER_INSET_M = 0.3
MIN_AREA_M2 = 25.0
MAX_SLOPE_DEG = 45.0
MAX_PLANES = 1000
MAX_SIGMA_M = 1.0


@dataclass(eq=False)
class SimulatedControlPlanes:
    """Control planes: the surveyed points (CRS of the survey) and each plane's truth."""

    plane: list[str]  #: per surveyed point, its plane's id
    xyz: np.ndarray  #: (N, 3) as surveyed
    sigma_m: float
    truth: list[dict]  #: per plane: id, normal (ENU), d (m), survey_error_m along the normal

    def write(self, out_dir: str | Path, force: bool = True) -> Path:
        """control_planes.csv into ``out_dir``, the truth under "control_planes" in its
        truth.json."""
        from calidar.io.control_planes import write_control_planes
        from calidar.outputs import write_text_atomic

        out = Path(out_dir)
        sigma = np.full(len(self.plane), self.sigma_m)
        comment = f"simulated roof-facet control planes, survey σ {self.sigma_m} m (3-D, per point)"
        write_control_planes(out / "control_planes.csv", self.plane, self.xyz, sigma, comment,
                             force=force)
        truth = out / "truth.json"
        doc = json.loads(truth.read_text(encoding="utf-8")) if truth.exists() else {}
        doc["control_planes"] = {"sigma_m": self.sigma_m, "facets": self.truth}
        write_text_atomic(truth, json.dumps(doc, indent=2) + "\n", force=True)
        return out / "control_planes.csv"


def roof_facets(scene) -> list[tuple[int, np.ndarray]]:
    """(plane id, corners (k, 3) ENU in order around it) of every roof facet of ``scene`` fit for
    control: area ≥ MIN_AREA_M2, slope ≤ MAX_SLOPE_DEG, inside the flown area."""
    from scipy.spatial import ConvexHull

    from calidar.sim.checkpoints import MARGIN

    x0, x1, y0, y1 = scene.extent
    mx, my = MARGIN * (x1 - x0), MARGIN * (y1 - y0)
    out = []
    for pid in np.flatnonzero(scene.plane_is_roof):
        n = scene.plane_normal[pid]
        if np.degrees(np.arccos(min(abs(n[2]), 1.0))) > MAX_SLOPE_DEG:
            continue
        v = np.unique(np.round(scene.tri[scene.tri_plane == pid].reshape(-1, 3), 9), axis=0)
        if len(v) < 3:
            continue
        hull = ConvexHull(v[:, :2])
        inside_x = (v[:, 0] > x0 + mx) & (v[:, 0] < x1 - mx)
        inside = np.all(inside_x & (v[:, 1] > y0 + my) & (v[:, 1] < y1 - my))
        if hull.volume >= MIN_AREA_M2 and inside:  # a 2-D hull's "volume" is its area
            out.append((int(pid), v[hull.vertices]))
    return out


def check_control_plane_options(n: int, sigma_m: float) -> None:
    """``--control-planes`` in [1, MAX_PLANES] and ``--control-plane-sigma`` in [0, MAX_SIGMA_M]
    m."""
    from calidar.validate import integer, number

    integer(n, "--control-planes", 1, MAX_PLANES)
    number(sigma_m, "--control-plane-sigma", 0.0, MAX_SIGMA_M, "m")


def simulate_control_planes(result, n: int, sigma_m: float = 0.01,
                            seed: int = 0) -> SimulatedControlPlanes:
    """``n`` roof facets of a :class:`calidar.sim.survey.SurveyResult`'s scene, surveyed at their
    corners with σ ``sigma_m`` (3-D); an error when the scene has fewer fit ones."""
    from calidar.crs import to_crs

    check_control_plane_options(n, sigma_m)
    scene = result.scene
    facets = roof_facets(scene)
    if len(facets) < n:
        raise InputError(None, "--control-planes",
                         f"{len(facets)} roof facets of ≥ {MIN_AREA_M2:g} m² and ≤ "
                         f"{MAX_SLOPE_DEG:g}° inside the flown area in this scene; expected ≤ that "
                         "many")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 2029]))
    pick = sorted(rng.choice(len(facets), n, replace=False))
    names, enu, truth = [], [], []
    for j, k in enumerate(pick):
        pid, corners = facets[k]
        c = corners.mean(axis=0)
        towards = c - corners
        pts = corners + CORNER_INSET_M * towards / np.linalg.norm(towards, axis=1, keepdims=True)
        err = rng.normal(0.0, sigma_m, pts.shape) if sigma_m > 0 else np.zeros(pts.shape)
        normal = scene.plane_normal[pid]
        name = f"R{j + 1:03d}"
        names += [name] * len(pts)
        enu.append(pts + err)
        truth.append({"id": name, "normal_enu": normal.tolist(), "d_m": float(scene.plane_d[pid]),
                      "survey_error_m": float(np.mean(err @ normal)),
                      "building": int(scene.plane_building[pid])})
    xyz = to_crs(scene.enu_to_ecef(np.vstack(enu)), result.crs)
    return SimulatedControlPlanes(names, xyz, float(sigma_m), truth)
