"""Geolocation calibration of a photon-counting lidar from corner-cube retroreflector (CCR) returns.

After the method of Magruder et al. (2019, 2021; ICESat-2 CCR arrays at White Sands), carried
to the information limit:

1. each pass's photons near the CCRs are denoised and the ground modelled
   (:mod:`calidar.photon.passes`); each CCR's window of shots and their photon counts, and the
   published method's segment, are extracted (:mod:`calidar.photon.segments`);
2. the published grid search over footprint diameter × cross-track bias on the segments' chords
   and midpoints (:mod:`calidar.photon.search`) gives the start, and its other local minima
   over the cross-track bias give alternative starts (which side of the track each CCR is on);
3. the final estimate is the maximum of the exact per-shot count likelihood
   (:mod:`calidar.photon.likelihood`: binomial channels, lost shots, pointing jitter,
   background), with the CCR peak photons Λ and the shot-loss rate q as nuisance parameters,
   solved by the one engine (:mod:`calidar.photon.fit`), the best of the starts;
4. σ from the same problem: the observed information, a parametric bootstrap that simulates
   counts from the fitted model and repeats steps 2–3, the Cramér–Rao bound, and
   profile-likelihood intervals (:mod:`calidar.photon.uncertainty`).

Several beams and passes are solved jointly: one parameter row per beam (its laser spot when
the file says it, else its ground track), or one along/cross bias shared by all beams
(``SearchSettings.shared_bias``); strong and weak beams each with their own channels, Λ and q.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from calidar.errors import CalibrationError, InputError
from calidar.photon.checks import verdict_of
from calidar.photon.estimate import Estimate, estimate, shots_of, windows_of
from calidar.photon.fit import Layout, Problem
from calidar.photon.passes import PassData, SystemParameters
from calidar.photon.search import SearchSettings
from calidar.photon.segments import CCRWindow
from calidar.photon.uncertainty import Uncertainty, assess, sigma_from_profile
from calidar.verdict import Verdict


@dataclass
class CCRResult:
    """Calibration outcome: the Solution (σ from the observed information) and everything behind
    it."""

    estimate: Estimate
    problem: Problem
    windows: list[CCRWindow]
    passes: list[PassData]
    system: SystemParameters
    settings: SearchSettings
    warnings: list[str] = field(default_factory=list)
    uncertainty: Uncertainty | None = None
    fits: list | None = None  #: calidar.photon.checks.CCRFit per window
    verdict: Verdict | None = None

    @property
    def solution(self):
        return self.estimate.fit.solution

    @property
    def layout(self) -> Layout:
        return self.problem.layout


def calibrate(passes: list[PassData], survey, system: SystemParameters | None = None,
              settings: SearchSettings | None = None, progress=None) -> CCRResult:
    """Solve along/cross-track bias and footprint diameter (per beam, or shared biases) from the
    CCR returns of one or more passes; σ, intervals and the verdict with it."""
    system = system or SystemParameters()
    settings = settings or SearchSettings()
    if survey.lat is None and len(passes) > 1:
        raise InputError(survey.source, "columns", "x,y are along/cross-track positions in ONE "
                         f"pass's track, but {len(passes)} passes were given; give the CCRs as "
                         "id,lat,lon,height")
    windows, warnings = windows_of(passes, survey, system, settings)
    lit = {w.pass_name for w in windows}  # the passes with CCR photons
    keys = list(dict.fromkeys(p.group_key for p in passes if p.name in lit))
    if not windows:
        raise CalibrationError("no CCR photons found in any pass: " + "; ".join(warnings))
    for p in passes:
        p.group = keys.index(p.group_key) if p.group_key in keys else -1
    for w in windows:
        w.group = next(p.group for p in passes if p.name == w.pass_name)
    layout = Layout(tuple(keys), settings.shared_bias)
    problem = Problem(shots_of(windows), layout, system.pointing_jitter)
    est = estimate(windows, problem, settings, system.shot_spacing)
    result = CCRResult(est, problem, windows, passes, system, settings, warnings)
    result.uncertainty = assess(result, progress)
    result.uncertainty.profile_sigma = sigma_from_profile(result)
    result.verdict = verdict_of(result)
    return result


def describe(result: CCRResult) -> dict:
    """What solution.json holds beside the parameters: method, σ three ways, intervals, the grid
    search, segments, CCR fits, beams, settings and the verdict."""
    from dataclasses import asdict

    s, system = result.settings, result.system
    grids = zip(result.layout.groups, result.estimate.grids)
    return {
        "method": METHOD,
        "sigma_source": SIGMA_SOURCE,
        "uncertainty": result.uncertainty.to_dict() if result.uncertainty else None,
        "held_at_bound": result.estimate.fit.at_limit,
        "grid_search": {k: g.to_dict() for k, g in grids},
        "segments": [sg.summary() for sg in result.estimate.segments],
        "ccr_fit": [{"pass": f.pass_name, "ccr": f.ccr_id, "detections": f.detections,
                     "expected": f.expected, "z": f.z, "photons": f.photons,
                     "expected_photons": f.expected_photons} for f in (result.fits or [])],
        "beams": [_beam(result, k) for k in result.layout.groups],
        "shared_bias": result.layout.shared_bias,
        "system": {"dead_time_s": system.dead_time, "pulse_width_s": system.pulse_width,
                   "shot_spacing_m": system.shot_spacing,
                   "pointing_jitter_m": system.pointing_jitter, "delta_h_m": system.delta_h},
        "settings": asdict(s),
        "verdict": result.verdict.to_dict() if result.verdict else None,
        "warnings_input": result.warnings,
    }


#: how the solution was found and where its σ come from, as solution.json states them
METHOD = ("maximum of the exact per-shot CCR count likelihood (calidar.adjust.solve on "
          "√(2·(−log P + ½)) residuals, Fisher scoring), started from the published chord grid "
          "search")
SIGMA_SOURCE = ("geolocation: the 95 % profile-likelihood interval's wider half / 1.96 (at least "
                "the observed information's where the interval is open); nuisance: observed "
                "information (inverse Hessian of −log L at the estimate); both in uncertainty")


def _beam(result: CCRResult, key: str) -> dict:
    """One beam's entry of solution.json: its labels, detector channels and passes."""
    passes = [p for p in result.passes if p.group_key == key]
    return {"key": key, "labels": sorted({p.label for p in passes}),
            "channels": next(p.channels for p in passes), "passes": [p.name for p in passes]}
