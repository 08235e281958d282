"""Per-point uncertainty (``calidar tpu``): each point's horizontal and vertical 1σ from the
trajectory's accuracy, the sensor's noise, its footprint and the calibration's covariance
(:mod:`calidar.tpu.propagate`), written as LAS extra bytes ``total_thu`` / ``total_tvu``
(metres, as cBLUE names them) beside a summary and a report. Streamed: memory does not grow with
the files."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.pipelines import Progress, no_progress
from calidar.pipelines.inputs import CHUNK_POINTS
from calidar.pipelines.tpu_config import TpuConfig

EXTRA_BYTES = {"total_thu": "horizontal TPU, 1 sigma [m]",
               "total_tvu": "vertical TPU, 1 sigma [m]"}
SCAN_BINS_DEG = (0.0, 10.0, 20.0, 30.0, 45.0, 90.0)
SAMPLE_POINTS = 100_000  #: points per file kept for the report's figures


@dataclass
class FileTpu:
    """One file's result: counts, percentiles (m) and a sample for the figures."""

    path: Path
    written: Path
    n_points: int
    thu: dict
    tvu: dict
    tvu_by_scan_angle: list[dict]
    sample: dict = field(repr=False, default_factory=dict)

    def to_dict(self) -> dict:
        return {"file": str(self.path), "written": self.written.name, "points": self.n_points,
                "thu_m": self.thu, "tvu_m": self.tvu, "tvu_by_scan_angle": self.tvu_by_scan_angle}


def _percentiles(v: np.ndarray) -> dict:
    q = np.percentile(v, [50, 95]) if v.size else [np.nan, np.nan]
    largest = float(v.max()) if v.size else float("nan")
    return {"median": float(q[0]), "p95": float(q[1]), "max": largest}


class _Collector:
    """THU/TVU of a file's chunks: a histogram-free summary from a reservoir of points."""

    def __init__(self, seed: int):
        self.rng, self.parts, self.n = np.random.default_rng(seed), [], 0

    def add(self, xy, thu, tvu, scan):
        keep = self.rng.random(thu.size) < SAMPLE_POINTS / max(SAMPLE_POINTS, thu.size)
        self.parts.append((xy[keep], thu[keep], tvu[keep], scan[keep]))
        self.n += thu.size

    def sample(self) -> dict:
        if self.parts:
            cat = [np.concatenate([p[k] for p in self.parts]) for k in range(4)]
        else:
            cat = [np.zeros((0, 2))] + [np.zeros(0)] * 3
        keep = self.rng.permutation(cat[1].size)[:SAMPLE_POINTS]
        return dict(zip(("xy", "thu", "tvu", "scan"), (c[keep] for c in cat)))


def tpu_file(path: Path, out: Path, traj, sensor, accuracy, config: TpuConfig,
             calibration) -> FileTpu:
    """One file: stream, propagate, write it with the extra bytes (see the module docstring)."""
    from calidar.ingest.rewrite import with_extra_bytes
    from calidar.io.las import las_header
    from calidar.pipelines.inputs import trajectory_for
    from calidar.tpu.propagate import point_covariance, thu_tvu

    if las_header(path).point_count == 0:
        raise InputError(path, "points", "no points; expected points to give an uncertainty to")
    traj, week = trajectory_for(path, traj, config.points, CHUNK_POINTS)
    collect = _Collector(len(str(path)))

    def values(t, ecef, points):
        cov = point_covariance(traj, sensor, accuracy, t, ecef, config.noise, calibration)
        thu, tvu = thu_tvu(cov)
        if points.scan_angle_deg is not None:
            scan = np.abs(points.scan_angle_deg)
        else:
            scan = np.full(thu.size, np.nan)
        collect.add(points.xyz[:, :2], thu, tvu, scan)
        return {"total_thu": thu, "total_tvu": tvu}

    n = with_extra_bytes(path, out, EXTRA_BYTES, traj, week, values, config.points, CHUNK_POINTS)
    s = collect.sample()
    return FileTpu(path, out, n, _percentiles(s["thu"]), _percentiles(s["tvu"]), _scan_bins(s), s)


def _scan_bins(s: dict) -> list[dict]:
    """The TVU percentiles (m) of a file's sample ``s`` in each bin of |scan angle|
    (:data:`SCAN_BINS_DEG`) that holds points."""
    bins = []
    for lo, hi in zip(SCAN_BINS_DEG[:-1], SCAN_BINS_DEG[1:]):
        m = (s["scan"] >= lo) & (s["scan"] < hi)
        if m.any():
            bins.append({"scan_angle_deg": [lo, hi], "points_in_sample": int(m.sum()),
                         **_percentiles(s["tvu"][m])})
    return bins


def load_calibration(path: Path | None, sensor):
    """The calibration covariance of a solution.json (None: none given)."""
    if path is None:
        return None
    from calidar.io.calibration import read_calibration_covariance
    from calidar.tpu.propagate import CalibrationCovariance

    return CalibrationCovariance(*read_calibration_covariance(path, set(sensor.parameters())))


def run_tpu(points: list[Path], trajectory: Path, sensor_path: Path, out_dir: Path,
            config: TpuConfig = TpuConfig(), *, accuracy: Path | None = None,
            calibration: Path | None = None,
            progress: Progress = no_progress) -> list[FileTpu]:
    """Every file of ``points`` with per-point THU/TVU into ``out_dir`` (same names), ``tpu.json``,
    ``config.toml`` and ``report.html``. ``accuracy``: the trajectory's smrmsg file (default: found
    beside an sbet*.out); ``calibration``: a calidar solution.json whose covariance is propagated.
    Returns the per-file summaries."""
    import json

    from calidar.outputs import write_text_atomic
    from calidar.pipelines.boresight import resolve_accuracy
    from calidar.pipelines.inputs import load_trajectory
    from calidar.sensor import Sensor

    names = [Path(p).name for p in points]
    if len(set(names)) != len(names):
        raise InputError(None, "POINTS",
                         f"expected distinct file names (outputs share the folder), got {names}")
    sensor = Sensor.read(sensor_path)
    traj = load_trajectory(trajectory, config.trajectory_input)
    stated, _, note = resolve_accuracy(Path(trajectory), traj, accuracy, config.trajectory_sigma)
    covariance = load_calibration(calibration, sensor)
    results = []
    for k, p in enumerate(points):
        out = Path(out_dir) / Path(p).name
        results.append(tpu_file(Path(p), out, traj, sensor, stated, config, covariance))
        progress("per-point uncertainty", k + 1, len(points))
    doc = {"accuracy": stated.to_dict(), "accuracy_note": note,
           "settings": {k: float(v) for k, v in config.noise.__dict__.items()},
           "calibration": None if covariance is None else {
               "file": str(calibration), "parameters": list(covariance.names),
               "sigma_si": np.sqrt(np.diag(covariance.covariance)).tolist()},
           "files": [r.to_dict() for r in results]}
    write_text_atomic(Path(out_dir) / "tpu.json", json.dumps(doc, indent=2) + "\n", force=True)
    config.write(Path(out_dir) / "config.toml")
    from calidar.tpu.report import tpu_report

    tpu_report(results, doc).write(Path(out_dir) / "report.html")
    return results
