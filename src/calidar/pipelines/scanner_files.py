"""The files of a structural-error analysis (``calidar scanner analyze``): pattern and
displacement curves (CSV + PNG) and the JSON summary."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from calidar.io.raster import write_png
from calidar.outputs import atomic_path, write_text_atomic
from calidar.scanners.analysis import ScannerAnalysis
from calidar.scanners.separability import Separability
from calidar.scanners.sources import ARCSEC


def _write_csv(path: Path, header: list[str], rows) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def write_curves(a: ScannerAnalysis, out_dir: Path) -> list[Path]:
    """pattern.csv/.png and displacement_<error>.csv/.png (combined included) in ``out_dir``."""
    from calidar.scanners.figures import displacement_figure, pattern_figure

    out_dir = Path(out_dir)
    lab = "scan_angle_deg" if a.model == "linear" else "encoder_angle_deg"
    deg = np.degrees(a.angles)
    _write_csv(out_dir / "pattern.csv", [lab, "x_m", "y_m", "z_m"],
               ([f"{b:.6f}", *(f"{v:.6f}" for v in p)] for b, p in zip(deg, a.points_m)))
    figs = {"pattern.png": pattern_figure(a)}
    effects = dict(a.effects, **a.comparisons)
    if a.combined is not None:
        effects["combined"] = a.combined
    for name, e in effects.items():
        rows = ([f"{b:.6f}", *(f"{v:.9f}" for v in d), f"{p / ARCSEC:.6f}"]
                for b, d, p in zip(deg, e.displacement_m, e.pointing_rad))
        _write_csv(out_dir / f"displacement_{name}.csv",
                   [lab, "dx_m", "dy_m", "dz_m", "pointing_arcsec"], rows)
        figs[f"displacement_{name}.png"] = displacement_figure(a, e, e.title(name, a.range_m))
    for name, fig in figs.items():
        write_png(out_dir / name, fig, force=True)
    return [out_dir / n for n in figs]


def separability_summary(sep: Separability) -> dict:
    """The separability for summary.json: own part and best boresight per component,
    correlations."""
    names = [n for n in sep.names[3:]]
    matrix = [[round(float(v), 6) for v in row] for row in sep.correlation]
    return {
        "own_part": {n: sep.unexplained[n] for n in names},
        "best_boresight_rad_per_unit": {n: [float(v) for v in sep.mimic[n]] for n in names},
        "correlation": {"names": list(sep.names), "matrix": matrix},
    }


def write_summary(doc: dict, path: Path) -> Path:
    """summary.json (strict JSON: no NaN or infinity)."""
    return write_text_atomic(path, json.dumps(doc, indent=2, allow_nan=False) + "\n")
