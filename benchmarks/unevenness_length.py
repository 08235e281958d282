"""The unevenness length ℓ, σ_u and σ_e read from LAS/LAZ files' own points (issue 26, 13th session).

No trajectory needed: per file and flight line (point source id), VGICP's neighbourhoods are
formed on the delivered points as VGICP forms b's (the ``num_neighbors`` nearest about a spread
of centres, found again about their centroid; kept when thin and not a line, VGICP's
``max_surface_variation`` and ``min_spread``), and :func:`calidar.strips.unevenness_length.
estimate_length` fits ℓ to their residuals about their planes. Coordinates are converted to
metres by the CRS's horizontal unit (a file in US feet, e.g. pdal_autzen, is scaled).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/unevenness_length.py \
        FILE.laz … [--classes 2] [--rows 2000] [--centres 20000] [--neighbours 12]

One line per file and flight line: points, median neighbourhood radius (m), ℓ (m) and its 95 %
range, σ_u, σ_e (mm), rows used, CPU s of the fit, its maximum log L (``--kernel exponential``:
the same rows under an exponential R, to compare).

    python benchmarks/unevenness_length.py --mc RUN.jsonl …

reads what VGICP's pairs estimated in ``strips_montecarlo.py --json`` rows instead: per file, the
pairs' ℓ (quartiles, share read white), σ_u and σ_e (medians), rows per pair.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import laspy
import numpy as np

from calidar.strips.unevenness_length import KERNELS, estimate_length
from calidar.strips.vgicp import VgicpSettings
from calidar.strips.vgicp_planes import local_planes


def _metres(las) -> float:
    """The CRS's horizontal unit in metres (1 without a CRS)."""
    try:
        crs = las.header.parse_crs()
    except Exception:  # noqa: BLE001 (a benchmark: an unreadable CRS is taken as metres)
        crs = None
    if crs is None or not crs.axis_info:
        return 1.0
    return float(crs.axis_info[0].unit_conversion_factor or 1.0)


def fit_line(points: np.ndarray, n_centres: int, max_rows: int, quantile: float,
             k: int = 0, kernel: str = "gaussian") -> dict:
    """ℓ fit on one flight line's ``points`` (N, 3) m, neighbourhoods of ``k`` points (0:
    VGICP's ``num_neighbors``)."""
    s = VgicpSettings()
    k = k or s.num_neighbors
    points = points - points.mean(axis=0)
    rng = np.random.default_rng(0)
    centres = points[rng.choice(len(points), min(n_centres, len(points)), replace=False)]
    first = local_planes(points, centres, k, 1)
    planes = local_planes(points, first.centroid, k, 1)
    keep = (planes.variation < s.max_surface_variation) & (planes.spread >= s.min_spread)
    clock = time.process_time()
    fit = estimate_length(points[planes.index[keep]], planes.centroid[keep],
                          planes.eigvec[keep], quantile, max_rows, kernel)
    return {"radius_m": float(np.median(planes.distance[keep, -1])), "rows_kept": int(keep.sum()),
            "cpu_s": time.process_time() - clock, "loglik": fit.loglik} | fit.to_dict()


def mc_summary(path: Path) -> str:
    """The pairs' ℓ fits recorded in a Monte-Carlo's JSON lines (``unevenness`` of each row)."""
    fits = [u for line in path.read_text().splitlines() if line.strip()
            for u in json.loads(line).get("unevenness", [])]
    if not fits:
        return f"{path.name} | no ℓ recorded"
    ell = np.array([f["length_m"] for f in fits])
    q = np.quantile(ell, [0.25, 0.5, 0.75])
    med = lambda key: 1e3 * np.median([f[key] for f in fits])  # noqa: E731
    return (f"{path.name} | {len(fits)} pairs | ℓ {q[0]:.2f} / {q[1]:.2f} / {q[2]:.2f} m | white "
            f"{np.mean(ell == 0):.0%} | σ_u {med('sigma_u_m'):.1f} mm | σ_e {med('sigma_e_m'):.1f}"
            f" mm | rows {np.median([f['rows'] for f in fits]):.0f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--classes", type=int, nargs="*", default=[], help="only these classes")
    ap.add_argument("--rows", type=int, default=2000, help="rows in the fit (at most)")
    ap.add_argument("--centres", type=int, default=20000, help="neighbourhoods formed")
    ap.add_argument("--quantile", type=float, default=VgicpSettings().unevenness_quantile)
    ap.add_argument("--neighbours", type=int, default=0,
                    help="points a neighbourhood (0: VGICP's num_neighbors)")
    ap.add_argument("--kernel", default="gaussian", choices=sorted(KERNELS),
                    help="R(d) (exponential: to compare the maximum log L on the same rows)")
    ap.add_argument("--mc", action="store_true", help="the files are Monte-Carlo JSON lines")
    args = ap.parse_args()
    if args.mc:
        print("file | pairs | ℓ quartiles | read white | σ_u | σ_e | rows a pair")
        for path in args.files:
            print(mc_summary(path))
        return
    print("file | line | points | radius m | ℓ m (95 %) | σ_u mm | σ_e mm | rows | CPU s | log L")
    for path in args.files:
        las = laspy.read(path)
        xyz = np.column_stack([las.x, las.y, las.z]) * _metres(las)
        keep = np.isin(las.classification, args.classes) if args.classes else np.ones(len(xyz), bool)
        for line in np.unique(las.point_source_id[keep]):
            pts = xyz[keep & (las.point_source_id == line)]
            if len(pts) < 100:
                continue
            f = fit_line(pts, args.centres, args.rows, args.quantile, args.neighbours,
                         args.kernel)
            lo, hi = f["length_range_m"]
            print(f"{path.name} | {line} | {len(pts)} | {f['radius_m']:.2f} | {f['length_m']:.2f} "
                  f"({lo:.2f}–{hi:.2f}) | {1e3 * f['sigma_u_m']:.1f} | {1e3 * f['sigma_e_m']:.1f}"
                  f" | {f['rows']} of {f['rows_kept']} | {f['cpu_s']:.2f} | {f['loglik']:.1f}",
                  flush=True)


if __name__ == "__main__":
    main()
