"""Range calibration of a circular-scan lidar against total-station observations.

>>> from calidar.io.total_station import read_observations
>>> from calidar.rangecal import calibrate
>>> result = calibrate(read_observations("obs.csv"), tolerance_m=0.02)   # doctest: +SKIP
>>> result.solution.values["range_offset"], result.extra()["intervals95"]  # doctest: +SKIP

``calibrate`` runs the prescribed two-step method (:mod:`.method`) and the least-squares
fit with data snooping (:mod:`.fit`) on the same observations; the fit's estimates are
the result, the method's ΔS and Δ ride along in ``solution.extra``.
"""

from __future__ import annotations

from dataclasses import dataclass

from calidar.adjust import Solution
from calidar.io.total_station import TotalStationObservations
from calidar.rangecal.fit import (FitResult, acceptance, fit_range_model, observation_sigma,
                                  target_distances)
from calidar.rangecal.method import MethodResult, level_check, two_step_method
from calidar.rangecal.units import check_units


@dataclass
class RangeCalibration:
    """Everything one range calibration produced."""

    observations: TotalStationObservations
    fit: FitResult
    method: MethodResult  #: on the observations kept by the outlier tests
    acceptance: dict | None  #: see fit.acceptance; None without a tolerance
    level: dict  #: see method.level_check

    @property
    def solution(self) -> Solution:
        return self.fit.solution

    def extra(self) -> dict:
        """The method-specific results for ``solution.json`` (SI; range_scale also in ppm)."""
        intervals = {}
        for name, unit, f in (("range_offset", "m", 1.0), ("range_scale", "ppm", 1e6)):
            if (iv := self.fit.interval(name)) is not None:
                intervals[name] = {"low": iv[0] * f, "high": iv[1] * f, "unit": unit}
        snooping = "Baarda data snooping, |w| > 3.29 (alpha 0.001)"
        doc = {
            "intervals95": {**intervals, "t_factor": self.fit.t_factor, "dof": self.solution.dof},
            "two_step_method": {**self.method.to_dict(), "level_check": self.level},
            "outliers": {"test": snooping, "rejected": self.fit.rejected},
            "global_test": self.fit.global_test,
            "observations": [self._observation(i) for i in range(len(self.observations))],
        }
        if self.acceptance is not None:
            doc["acceptance"] = self.acceptance
        return doc

    def _observation(self, i: int) -> dict:
        """Row ``i`` of the observations with its distance, σ, residual (m), w and whether the
        outlier tests kept it."""
        obs, fit = self.observations, self.fit
        return {"line": int(obs.line[i]), "setup": obs.setups[obs.setup[i]].id,
                "group": str(obs.group[i]), "point": str(obs.point[i]),
                "scanner_m": float(obs.scanner[i]), "distance_m": float(fit.distance[i]),
                "sigma_m": float(fit.sigma[i]), "residual_m": float(fit.residuals[i]),
                "w": None if not fit.keep[i] else float(fit.w[i]), "used": bool(fit.keep[i])}


def calibrate(obs: TotalStationObservations, tolerance_m: float | None = None,
              fix_scale: bool = False) -> RangeCalibration:
    """Fit offset/scale (``fix_scale``: offset only) with outlier tests, run the two-step
    method on the observations kept, check the tolerance (m). Ranges in the wrong unit are an
    :class:`~calidar.errors.InputError` (:func:`calidar.rangecal.units.check_units`)."""
    check_units(obs, target_distances(obs)[0])
    fit = fit_range_model(obs, fix_scale)
    kept = obs.subset(fit.keep)
    _, partials = target_distances(kept)
    method = two_step_method(kept, target_distances(kept)[0], partials, observation_sigma(kept))
    accepted = acceptance(fit, tolerance_m) if tolerance_m is not None else None
    result = RangeCalibration(obs, fit, method, accepted, level_check(kept))
    fit.solution.extra = result.extra()
    return result


def truth_parameters(truth: dict) -> dict[str, float]:
    """SI truth by parameter name from a simulator's truth.json document."""
    return {"range_offset": float(truth["range_offset_m"]),
            "range_scale": float(truth["range_scale_ppm"]) * 1e-6}
