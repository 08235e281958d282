"""USGS Lidar Base Specification swath checks: the quality level (QL0–QL3) each meets.

Table 2 of the USGS Lidar Base Specification (Techniques and Methods 11-B4, "Relative vertical
accuracy for lidar swath data"; its number and title as in version 1.3, 2018): on smooth,
non-vegetated, gently sloped surfaces,

    quality level   intraswath smooth-surface precision   interswath RMSDz   interswath max |dz|
    QL0             ≤ 0.03 m (max diff)                    ≤ 0.04 m           ≤ 0.08 m
    QL1, QL2        ≤ 0.06 m                               ≤ 0.08 m           ≤ 0.16 m
    QL3             ≤ 0.12 m                               ≤ 0.16 m           ≤ 0.32 m

Which edition: the numbers are those of versions 1.2–2.1 and the 2020 revision A as read for calidar
(from memory, not from a text in this repository). The current edition is
the 3DEP online one, "2025 rev. A"; its tables could not be read in the stored sources (27 Nov,
third session: the `search` tool's documentation and web pages hold the 1.0–1.3 and 2.1 texts'
openings and third-party summaries without the tables' values), so no number here is verified
against it. What the sources did confirm: the table's place and title in 1.3 (a vendor's summary of
1.3 lists "Table 2 Relative Vertical Accuracy for LiDAR Swath Data" with smooth-surface
repeatability and swath-overlap RMSDz columns), and for the absolute table the ratio QL0 : QL1 (the
USGS quality-level page: QL0's NVA and VVA "two times better than that of QL1 data").
docs/validation.md lists each number's state.

How calidar measures them, from the cell moments the swath differences already hold:
- interswath: the swath differences of :mod:`calidar.strips.quality` (cells smooth in both lines,
  slope < 10°): RMSDz over all pairs' cells pooled, and the largest |dz| of any cell.
- intraswath: per line, on its own cells that fit a plane within ``max_rms_m`` and slope < 10°
  (vegetation and edges do not: the point selection keeps ground or last returns), the points'
  scatter about the cell's plane σ_k (n/(n−3) for the plane's three parameters). The
  specification's figure is a maximum difference of heights within small sample areas of a
  smooth surface, about 2 × the nominal pulse spacing on a side, which hold ≈ 4 pulses of one
  swath. With the cells holding moments, not points, it is estimated from the range of 4 normal
  deviates (Tippett 1925, Biometrika 17:364–387; the constants d₂(4) = 2.059 and d₃(4) = 0.880 of
  ASTM E2587): the RMS of such ranges is √(d₂² + d₃²)·σ = 2.24·σ, with σ the RMS over the line's
  cells; the survey's figure is the worst line's. (Our cells are larger than those sample areas:
  their own ranges would grow with the density, d₂(n) for n points.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calidar.strips.pca import eigh3

#: pulses of one swath in a sample area of 2 × the nominal pulse spacing on a side
SAMPLE_POINTS = 4
#: d₃(4): the standard deviation of the range of 4 standard normal deviates (ASTM E2587)
RANGE_SD_4 = 0.8798
SPECIFICATION = ("USGS Lidar Base Specification, table 2: relative vertical accuracy of swath data "
                 "(values of v1.2–2020 rev. A as read for calidar; not verified "
                 "against 2025 rev. A)")
#: quality level → (intraswath max diff, interswath RMSDz, interswath max |dz|), metres
THRESHOLDS_M: dict[str, tuple[float, float, float]] = {
    "QL0": (0.03, 0.04, 0.08),
    "QL1": (0.06, 0.08, 0.16),
    "QL2": (0.06, 0.08, 0.16),
    "QL3": (0.12, 0.16, 0.32),
}
CHECKS = ("intraswath max diff", "interswath RMSDz", "interswath max |dz|")

#: The specification's absolute vertical accuracy of the lidar data (its table "absolute vertical
#: accuracy for lidar data and digital elevation models"), tested at checkpoints as ``calidar
#: accuracy`` does: NVA RMSEz and, over vegetated checkpoints, the 95th percentile of |dz| (table 4,
#: "Absolute vertical accuracy for lidar data and digital elevation models", in version 1.3). These
#: are the values of versions 1.2–2.1 and the 2020 revision A as read for calidar; of them only the
#: ratio QL0 = QL1 / 2 was confirmed (USGS quality-level page); whether the 2025 revision (aligned
#: with ASPRS Edition 2, which reports VVA without pass/fail) keeps them, and the VVA column, was
#: not verified (docs/validation.md).
ABSOLUTE_SPECIFICATION = ("USGS Lidar Base Specification, table 4: absolute vertical accuracy of "
                          "the lidar data (values of v1.2–2020 rev. A as read for calidar; not "
                          "verified against 2025 rev. A)")
#: quality level → (NVA RMSEz, VVA 95th percentile), metres
ABSOLUTE_THRESHOLDS_M: dict[str, tuple[float, float]] = {
    "QL0": (0.05, 0.15),
    "QL1": (0.10, 0.30),
    "QL2": (0.10, 0.30),
    "QL3": (0.20, 0.60),
}
ABSOLUTE_CHECKS = ("NVA RMSEz", "VVA 95th percentile")


def threshold_m(check: str, level: str) -> float:
    """The threshold (m) of ``check`` (one of CHECKS or ABSOLUTE_CHECKS) at quality ``level``."""
    if check in ABSOLUTE_CHECKS:
        return ABSOLUTE_THRESHOLDS_M[level][ABSOLUTE_CHECKS.index(check)]
    return THRESHOLDS_M[level][CHECKS.index(check)]


@dataclass
class UsgsCheck:
    """One check: its measured value (m) and the quality levels it meets."""

    name: str
    value_m: float | None
    n_cells: int
    levels_met: list[str] = field(default_factory=list)
    status: str = "not measured"  #: "meets QL0", ..., "meets no quality level", "not measured"

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def levels_met(value_m: float | None, check: str) -> list[str]:
    """The quality levels whose threshold for ``check`` (one of CHECKS or ABSOLUTE_CHECKS) the value
    meets."""
    if value_m is None:
        return []
    return [ql for ql in THRESHOLDS_M if value_m <= threshold_m(check, ql) + 1e-12]


def judged(name: str, value_m: float | None, n_cells: int) -> UsgsCheck:
    met = levels_met(value_m, name)
    if value_m is None:
        status = "not measured"
    else:
        status = f"meets {met[0]}" if met else "meets no quality level"
    return UsgsCheck(name, value_m, n_cells, met, status)


def expected_range(n: np.ndarray) -> np.ndarray:
    """d₂(n): the expected range (max − min) of n independent standard normal deviates,
    ∫ 1 − Φ(x)ⁿ − (1 − Φ(x))ⁿ dx (Tippett 1925), for each n (≥ 2)."""
    from scipy.special import ndtr

    x = np.linspace(-9.0, 9.0, 3601)
    p = ndtr(x)
    un, inv = np.unique(np.maximum(np.asarray(n, np.int64), 2), return_inverse=True)
    integrate = getattr(np, "trapezoid", None) or np.trapz  # numpy < 2 names it trapz
    d2 = np.array([integrate(1.0 - p**k - (1.0 - p) ** k, x) for k in un])
    return d2[inv].reshape(np.shape(n))


@dataclass
class LinePrecision:
    """Smooth-surface precision within one line (swath)."""

    line: int
    n_cells: int
    #: RMS of the points about their cell's plane, pooled over the smooth cells
    sigma_m: float | None
    #: RMS max diff of 4-point sample areas, √(d₂² + d₃²)·σ: the specification's, estimated
    max_diff_m: float | None
    cell_m: float = 0.0

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def line_precision(line: int, moments, max_rms_m: float = 0.08, max_slope_deg: float = 10.0,
                   min_points: int = 6) -> LinePrecision:
    """Intraswath precision of one line from its cell moments
    (:class:`calidar.strips.cell_moments.CellMoments`)."""
    m = moments.select(np.flatnonzero(moments.count >= max(min_points, 4)))
    if len(m) == 0:
        return LinePrecision(line, 0, None, None, moments.cell_m)
    w, v = eigh3(m.covariance())  # closed form: as np.linalg.eigh to ~1e-15 relative, 5× faster
    normal = v[:, :, 0] * np.sign(v[:, 2:3, 0])
    n = m.count
    var = np.maximum(w[:, 0], 0.0) * n / np.maximum(n - 3, 1)
    smooth = (np.sqrt(var) <= max_rms_m) & (normal[:, 2] >= np.cos(np.radians(max_slope_deg)))
    if not smooth.any():
        return LinePrecision(line, 0, None, None, m.cell_m)
    sigma = float(np.sqrt(np.sum(var[smooth] * n[smooth]) / np.sum(n[smooth])))
    factor = np.hypot(expected_range(np.array([SAMPLE_POINTS]))[0], RANGE_SD_4)
    max_diff = float(factor * np.sqrt(np.mean(var[smooth])))
    return LinePrecision(line, int(smooth.sum()), sigma, max_diff, m.cell_m)


def usgs_checks(pairs, lines: list[LinePrecision]) -> list[UsgsCheck]:
    """The three checks over a survey: pairs (PairQuality) and the lines' precisions."""
    n = np.array([q.n_cells for q in pairs if q.n_cells], float)
    rms = np.array([q.rmsdz_m for q in pairs if q.n_cells], float)
    rmsdz = float(np.sqrt(np.sum(n * rms**2) / n.sum())) if n.size else None
    worst = max((q.max_abs_dz_m for q in pairs if q.n_cells), default=None)
    measured = [p for p in lines if p.max_diff_m is not None]
    intra = max((p.max_diff_m for p in measured), default=None)  # the worst line
    return [judged(CHECKS[0], intra, sum(p.n_cells for p in measured)),
            judged(CHECKS[1], rmsdz, int(n.sum())), judged(CHECKS[2], worst, int(n.sum()))]


def common_level(checks: list[UsgsCheck]) -> str | None:
    """The best quality level every measured check meets (None: none, or nothing measured)."""
    got = [c for c in checks if c.value_m is not None]
    common = [ql for ql in THRESHOLDS_M if got and all(ql in c.levels_met for c in got)]
    return common[0] if common else None


def summary(checks: list[UsgsCheck]) -> str:
    """One line: the quality level all measured checks meet."""
    if all(c.value_m is None for c in checks):
        return "USGS swath checks: not measured"
    level = common_level(checks)
    return f"USGS swath checks: all measured checks meet {level}" if level else \
        "USGS swath checks: not all meet any quality level (QL3 is the loosest)"


def absolute_checks(nva_rmse_m: float | None, n_nva: int, vva95_m: float | None,
                    n_vva: int) -> list[UsgsCheck]:
    """The absolute vertical accuracy checks at checkpoints (``n_nva`` / ``n_vva`` of them; a value
    None: not measured). ``n_cells`` holds the checkpoint count."""
    return [judged(ABSOLUTE_CHECKS[0], nva_rmse_m, n_nva),
            judged(ABSOLUTE_CHECKS[1], vva95_m, n_vva)]
