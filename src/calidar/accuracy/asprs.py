"""Vertical accuracy statistics of the ASPRS Positional Accuracy Standards for Digital Geospatial
Data, Edition 2, Version 1.0 (ASPRS 2023), from checkpoint residuals dz = surface − checkpoint.

What the standard asks, as implemented here:

- **NVA** (non-vegetated vertical accuracy) is the RMSE of dz over the non-vegetated
  checkpoints, RMSE_V(data) = sqrt(Σdz²/n). Edition 2 includes the checkpoints' own survey
  error in the product's accuracy: RMSE_V = sqrt(RMSE_V(data)² + RMSE_V(survey)²), the survey
  term being the RMSE the surveyor states for the checkpoints (here sqrt of the mean σ², or a
  given value).
- The data are of the **"X-cm" vertical accuracy class** when RMSE_V ≤ X. The standard names
  classes by their X; this module states the smallest of :data:`VERTICAL_CLASSES_CM` met.
- **VVA** (vegetated) is reported as the 95th percentile of |dz| over the vegetated
  checkpoints; Edition 2 removed its pass/fail test (the 3 × X of Edition 1 is shown for
  reference only).
- At least :data:`MIN_NVA_CHECKPOINTS` = 30 NVA checkpoints (Edition 2 raised it from 20;
  at most 120 are needed for any project).
- Edition 2 dropped the 95 % confidence measure; older contracts still quote the NSSDA
  "accuracy at 95 %" = 1.96 × RMSE_V (valid for normally distributed errors without bias),
  given here as the legacy figure.

Beyond the standard, for an honest figure: mean, standard deviation and the standard error of
the mean, an uncertainty of the RMSE from its χ² distribution (n·RMSE²/ρ² ~ χ²_n for normal
errors of zero mean and true RMSE ρ: the 95 % interval of ρ), and the outliers (|dz| > 3 ×
RMSE) listed — never dropped.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

#: vertical accuracy classes (RMSE_V, cm) as the ASPRS standards tabulate them (Edition 1 Table 7.5,
#: Edition 2 keeps the "X-cm" naming; any X may be specified by a contract)
VERTICAL_CLASSES_CM = (1.0, 2.5, 5.0, 10.0, 15.0, 20.0, 33.3, 66.7, 100.0, 333.3)
MIN_NVA_CHECKPOINTS = 30  #: Edition 2's minimum for an NVA test
LEGACY_95_FACTOR = 1.96  #: NSSDA vertical accuracy at 95 % = 1.96 × RMSEz
#: Edition 1: VVA (95th percentile) ≤ 3.0 × X for the X-cm class (reference only)
VVA_REFERENCE_FACTOR = 3.0
OUTLIER_FACTOR = 3.0  #: |dz| > 3 × RMSE_V(data) is listed as an outlier
STANDARD = "ASPRS Positional Accuracy Standards for Digital Geospatial Data, Edition 2 (2023)"


def percentile95(values) -> float:
    """95th percentile by linear interpolation between order statistics (rank p·(n − 1) from 0),
    the method of the ASPRS standard's percentile computation (and numpy's default)."""
    v = np.sort(np.asarray(values, float))
    if v.size == 0:
        return float("nan")
    rank = 0.95 * (v.size - 1)
    lo = int(np.floor(rank))
    hi = min(lo + 1, v.size - 1)
    return float(v[lo] + (rank - lo) * (v[hi] - v[lo]))


def rmse_interval(rmse: float, n: int, level: float = 0.95) -> tuple[float, float]:
    """Interval of the true RMSE ρ from a sample RMSE of ``n`` normal errors (n·RMSE²/ρ² ~ χ²_n)."""
    from scipy.stats import chi2

    if n < 1 or not np.isfinite(rmse):
        return float("nan"), float("nan")
    a = (1.0 - level) / 2.0
    chi2_high, chi2_low = chi2.ppf(1.0 - a, n), chi2.ppf(a, n)
    return float(rmse * np.sqrt(n / chi2_high)), float(rmse * np.sqrt(n / chi2_low))


def accuracy_class_cm(rmse_m: float) -> float | None:
    """The smallest tabulated X (cm) with RMSE_V ≤ X, None beyond the largest."""
    for x in VERTICAL_CLASSES_CM:
        if rmse_m <= x / 100.0 + 1e-12:
            return x
    return None


def class_name(x_cm: float) -> str:
    """'10-cm', '33.3-cm'."""
    return f"{x_cm:g}-cm"


@dataclass(frozen=True)
class VerticalAccuracy:
    """The ASPRS Edition 2 vertical statistics of one set of residuals (lengths in m)."""

    n_nva: int
    n_vva: int
    mean_m: float | None  #: NVA mean dz
    std_m: float | None  #: NVA standard deviation (n − 1)
    sdom_m: float | None  #: standard error of the mean, std/√n
    rmse_data_m: float | None  #: RMSE_V(data) of the NVA residuals
    rmse_survey_m: float | None  #: the checkpoints' survey RMSE (None: not given)
    #: RMSE_V = sqrt(data² + survey²) (the data term alone when the survey's is unknown)
    rmse_m: float | None
    rmse_interval_m: tuple[float, float] | None  #: 95 % interval of the true RMSE_V(data) (χ²)
    rmse_sigma_m: float | None  #: ≈ RMSE/√(2n), the RMSE's standard uncertainty
    class_cm: float | None  #: the smallest tabulated class met
    legacy95_m: float | None  #: 1.96 × RMSE_V
    vva95_m: float | None  #: 95th percentile of |dz| over vegetated checkpoints
    vva_rmse_m: float | None
    outliers: tuple[int, ...]  #: indices (into the NVA residuals) of |dz| > 3 × RMSE_V(data)

    @property
    def enough(self) -> bool:
        return self.n_nva >= MIN_NVA_CHECKPOINTS

    def statement(self) -> str:
        """'tested 7.4 cm RMSEz: meets the 10-cm vertical accuracy class' (with the survey term)."""
        if self.rmse_m is None:
            return "no non-vegetated checkpoint could be tested: no NVA statement"
        if self.class_cm is not None:
            cls = f"meets the {class_name(self.class_cm)} vertical accuracy class"
        else:
            cls = f"beyond the largest tabulated class ({class_name(VERTICAL_CLASSES_CM[-1])})"
        text = f"tested {self.rmse_m * 100:.1f} cm RMSEz (NVA, {self.n_nva} checkpoints): {cls}"
        if self.rmse_survey_m is not None:
            text += (f" (data {self.rmse_data_m * 100:.1f} cm combined with the checkpoints' "
                     f"survey {self.rmse_survey_m * 100:.1f} cm, as Edition 2 prescribes)")
        return text

    def meets(self, x_cm: float) -> bool | None:
        """Whether RMSE_V ≤ X cm (None: nothing tested)."""
        return None if self.rmse_m is None else bool(self.rmse_m <= x_cm / 100.0 + 1e-12)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["outliers"] = list(self.outliers)
        d["rmse_interval_m"] = None if self.rmse_interval_m is None else list(self.rmse_interval_m)
        d.update(statement=self.statement(),
                 class_name=None if self.class_cm is None else class_name(self.class_cm),
                 minimum_nva_checkpoints=MIN_NVA_CHECKPOINTS, enough_checkpoints=self.enough,
                 standard=STANDARD)
        return d


def vertical_accuracy(dz_nva, dz_vva=(), survey_rmse_m: float | None = None) -> VerticalAccuracy:
    """The statistics of NVA residuals ``dz_nva`` and VVA residuals ``dz_vva`` (m), the survey
    term ``survey_rmse_m`` combined as Edition 2 says."""
    a, v = np.asarray(dz_nva, float), np.asarray(dz_vva, float)
    n = a.size
    vva95 = percentile95(np.abs(v)) if v.size else None
    vva_rmse = float(np.sqrt(np.mean(v**2))) if v.size else None
    if n == 0:
        return VerticalAccuracy(0, v.size, None, None, None, None, survey_rmse_m, None, None, None,
                                None, None, vva95, vva_rmse, ())
    data = float(np.sqrt(np.mean(a**2)))
    total = float(np.hypot(data, survey_rmse_m)) if survey_rmse_m is not None else data
    std = float(np.std(a, ddof=1)) if n > 1 else None
    sdom = None if std is None else std / np.sqrt(n)
    outliers = ()
    if n > 2:
        outliers = tuple(int(i) for i in np.flatnonzero(np.abs(a) > OUTLIER_FACTOR * data))
    return VerticalAccuracy(n, v.size, float(np.mean(a)), std, sdom, data, survey_rmse_m, total,
                            rmse_interval(data, n), data / np.sqrt(2 * n), accuracy_class_cm(total),
                            LEGACY_95_FACTOR * total, vva95, vva_rmse, outliers)
