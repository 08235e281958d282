"""A reference point cloud of a simulated survey (issue 28): control for ``calidar boresight
--control reference.laz --control-sigma σ``.

What a surveyor brings as a reference: a dense, precise scan of the open ground in part of the
area (a terrestrial or mobile survey): points every ``SPACING_M`` on the scene's true terrain over
the central ``SHARE`` of the flown area (each way), clear of buildings and tree crowns as the
checkpoints are (:mod:`calidar.sim.checkpoints`), each with ``NOISE_M`` of height noise, the whole
cloud shifted by a datum offset drawn from N(0, σ) — the cloud's stated vertical accuracy. The
file is ``reference.laz`` in the survey's CRS; ``truth.json`` gets the offset under
"reference_cloud".
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pyproj import CRS

SPACING_M = 0.25  #: 16 points per m²
NOISE_M = 0.005  #: each point's height noise, m
SHARE = 0.5  #: of the flown area's width and length, about its centre
MAX_SIGMA_M = 1.0


@dataclass(eq=False)
class SimulatedReferenceCloud:
    """The reference cloud: points (N, 3) in the survey's CRS, the stated σ, the true datum
    offset."""

    xyz: np.ndarray
    crs: CRS
    sigma_m: float
    datum_offset_m: float
    noise_m: float

    def write(self, out_dir: str | Path, force: bool = True) -> Path:
        """reference.laz into ``out_dir``, the truth under "reference_cloud" in its truth.json."""
        import datetime

        from calidar.io.las import write_las
        from calidar.outputs import write_text_atomic

        out = Path(out_dir)
        n = len(self.xyz)
        path = write_las(out / "reference.laz", self.xyz, self.crs, gps_time=np.zeros(n),
                         scan_angle_deg=np.zeros(n), point_source_id=np.zeros(n, np.uint16),
                         creation_date=datetime.date(2026, 1, 1), force=force)
        truth = out / "truth.json"
        doc = json.loads(truth.read_text(encoding="utf-8")) if truth.exists() else {}
        doc["reference_cloud"] = {"sigma_m": self.sigma_m, "datum_offset_m": self.datum_offset_m,
                                  "noise_m": self.noise_m, "spacing_m": SPACING_M, "n_points": n}
        write_text_atomic(truth, json.dumps(doc, indent=2) + "\n", force=True)
        return path


def check_reference_options(sigma_m: float) -> None:
    """``--reference-cloud-sigma`` in (0, MAX_SIGMA_M] m."""
    from calidar.validate import number

    number(sigma_m, "--reference-cloud-sigma", 0.0, MAX_SIGMA_M, "m", open_lo=True)


def simulate_reference_cloud(result, sigma_m: float = 0.02, seed: int = 0,
                             noise_m: float = NOISE_M,
                             spacing_m: float = SPACING_M) -> SimulatedReferenceCloud:
    """The reference cloud of a :class:`calidar.sim.survey.SurveyResult`, its datum off by N(0,
    ``sigma_m``)."""
    from calidar.crs import to_crs
    from calidar.sim.checkpoints import (CROWN_CLEARANCE_M, MARGIN, _clear_of_buildings,
                                         _crown_distance)

    check_reference_options(sigma_m)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 2029]))
    scene = result.scene
    x0, x1, y0, y1 = scene.extent
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    hx, hy = SHARE * (1 - 2 * MARGIN) * (x1 - x0) / 2, SHARE * (1 - 2 * MARGIN) * (y1 - y0) / 2
    gx, gy = np.meshgrid(np.arange(cx - hx, cx + hx, spacing_m),
                         np.arange(cy - hy, cy + hy, spacing_m))
    x, y = gx.ravel(), gy.ravel()
    keep = _clear_of_buildings(scene, x, y)
    chunk = 20000  # points a time: the distances to every crown are (chunk, crowns)
    beyond = np.concatenate([_crown_distance(scene, x[i:i + chunk], y[i:i + chunk])[1]
                             for i in range(0, x.size, chunk)])
    keep &= beyond >= CROWN_CLEARANCE_M
    x, y = x[keep], y[keep]
    z = scene.terrain_height(x, y)
    ok = np.isfinite(z)
    enu = np.c_[x[ok], y[ok], z[ok] + rng.normal(0.0, noise_m, int(ok.sum()))]
    xyz = to_crs(scene.enu_to_ecef(enu), result.crs)
    offset = float(rng.normal(0.0, sigma_m))
    xyz[:, 2] += offset
    return SimulatedReferenceCloud(xyz, result.crs, float(sigma_m), offset, noise_m)
