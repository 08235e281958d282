"""Is the CCR calibration good, and why: the fit of each CCR's counts, and the verdict.

Thresholds (m, 95 %): a bias is "known" when its interval is within ±``BIAS_TOLERANCE`` (a tenth
of ICESat-2's 6.5 m geolocation requirement is 0.65 m; 0.5 m leaves margin), the footprint
diameter when within ±``DIAMETER_TOLERANCE``. A CCR whose number of detecting shots is more
than ``FIT_Z`` standard deviations from what the fitted model expects does not fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.photon.estimate import shots_of
from calidar.photon.likelihood import count_distribution
from calidar.photon.parameters import GEOLOCATION
from calidar.verdict import Finding, Verdict

BIAS_TOLERANCE = 0.5  #: m, 95 % half-width for a pass
DIAMETER_TOLERANCE = 1.0  #: m
FIT_Z = 3.0
SIGMA_AGREEMENT = 0.25  #: relative
GOOD_CCRS = 4  #: lit CCRs per beam for a well-determined footprint
#: a shot-loss rate at most this has run to its bound 0 (the solver nears it asymptotically)
LOSS_AT_BOUND = 1e-3


@dataclass
class CCRFit:
    """How one CCR window's counts compare with the fitted model."""

    pass_name: str
    ccr_id: str
    detections: int  #: shots with ≥ 1 photon in the count band
    expected: float  #: what the fitted model expects
    z: float
    photons: int
    expected_photons: float
    curve_x: np.ndarray  #: m, reported along-track positions (a fine grid over the window)
    curve_mean: np.ndarray  #: expected photons per shot there (model incl. background)


def ccr_fits(result) -> list[CCRFit]:
    """Observed vs expected detections and photons per CCR window, and the model's mean count
    curve."""
    prob = result.problem
    theta = prob.layout.theta(result.solution.values)
    table, _ = count_distribution(theta, prob.shots, prob.jitter)
    k = np.arange(table.shape[1])
    out = []
    for i, w in enumerate(result.windows):
        m = prob.shots.window == i
        p0 = table[m, 0]
        exp_det, var = float(np.sum(1 - p0)), float(np.sum(p0 * (1 - p0)))
        det = int(np.count_nonzero(w.counts))
        xs = np.linspace(w.shot_x.min(), w.shot_x.max(), 200)
        grid = shots_of([_at(w, xs)])
        grid.group[:] = w.group
        t, _ = count_distribution(theta, grid, prob.jitter, table.shape[1] - 1)
        z = (det - exp_det) / np.sqrt(max(var, 1e-9))
        out.append(CCRFit(w.pass_name, w.ccr_id, det, exp_det, z, int(w.counts.sum()),
                          float((table[m] * k).sum()), xs, t @ k))
    return out


def _at(w, xs):
    """A copy of window ``w`` with shots at ``xs`` (counts 0): for the model's curve."""
    from dataclasses import replace

    return replace(w, shot_x=xs, counts=np.zeros(xs.size, np.int64))


def _geometry(result) -> list[Finding]:
    out = []
    for g, key in enumerate(result.layout.groups):
        segs = [s for s in result.estimate.segments if s.window.group == g]
        sides = result.estimate.grids[g].sides
        both = 1 in sides and -1 in sides
        detail = (f"{len(segs)} lit CCRs ({sides.count(1)} left, {sides.count(-1)} right of the "
                  "footprint track)")
        who = f"{key}: " if len(result.layout.groups) > 1 else ""
        if len(segs) >= GOOD_CCRS and both:
            out.append(Finding("pass", f"{who}CCR geometry", detail))
        else:
            out.append(Finding("warn", f"{who}CCR geometry", detail + ": few CCR profiles fix the "
                               "footprint diameter and the cross-track bias only loosely",
                               f"lay out at least {GOOD_CCRS} CCRs on both sides of the predicted "
                               "track"))
    return out


def _precision(result) -> list[Finding]:
    u, sol, out = result.uncertainty, result.solution, []
    for n in sol.parameters.free_names:
        base = result.layout.quantity[n]
        if base not in GEOLOCATION:
            continue
        iv = u.profile.get(n)
        v = sol.values[n]
        half = max(v - iv.low, iv.high - v) if iv else 1.96 * sol.sigma[n]
        tol = DIAMETER_TOLERANCE if base == "footprint_diameter" else BIAS_TOLERANCE
        detail = _interval_text(base, v, iv, half, u.profile_sigma.get(n, (1.0, 1.0)))
        out.append(_interval_finding(n, iv, detail, half, tol))
    return out


def _interval_text(base: str, v: float, iv, half: float, sigmas: tuple[float, float]) -> str:
    """A parameter's value with its 95 % interval (``iv``, or ± ``half``), m, and what the
    interval says of the likelihood's shape (``sigmas``: σ from the curvature, from the
    interval)."""
    f = "{:.2f}" if base == "footprint_diameter" else "{:+.2f}"
    if iv:
        detail = f"{f.format(v)} m, 95 % interval {f.format(iv.low)} … {f.format(iv.high)} m"
    else:
        detail = f"{f.format(v)} ± {half:.2f} m"
    was, now = sigmas
    if not 1 / 1.1 < now / was < 1.1:
        detail += (f"; σ {now:.2f} m from this interval (the curvature at the maximum gives "
                   f"{was:.2f} m: the likelihood is not quadratic here)")
    if iv and iv.level > 3.85:
        detail += (f" (deviance level {iv.level:.2f}, not χ²₁'s 3.84: fewer than 4 lit CCRs, a "
                   "small sample)")
    return detail


def _interval_finding(n: str, iv, detail: str, half: float, tol: float) -> Finding:
    """The finding of parameter ``n``: no honest interval, an open one, or within ± ``tol`` m."""
    if iv and iv.failed:
        return Finding("warn", n, detail + ": no honest interval — the likelihood has no maximum "
                       "with this parameter held just beyond the estimate (a bound or another "
                       "parameter's limit is reached); treat its σ as a lower bound",
                       "add lit CCRs (or passes), or check the CCR survey")
    if iv and (iv.open_low or iv.open_high):
        return Finding("warn", n, detail + ": the interval reaches the search limit, the data do "
                       "not bound it there (σ and the other intervals assume the value within the "
                       "searched range)",
                       "add lit CCRs (or passes); widen --diameter-range/--max-bias only if values "
                       "beyond are physically possible")
    if half <= tol:
        return Finding("pass", n, detail + f" (within ±{tol:g} m)")
    return Finding("warn", n, detail + f": wider than ±{tol:g} m",
                   "add lit CCRs or solve several passes together (--shared-bias if one bias fits "
                   "all)")


def _solve_checks(result) -> list[Finding]:
    fit, sol, out = result.estimate.fit, result.solution, []
    held = {result.layout.quantity[n] for n in fit.at_limit}
    if "footprint_diameter" in held:
        s = result.settings
        out.append(Finding("fail", "footprint diameter", "held at the search limit "
                           f"({s.diameter_min:g}–{s.diameter_max:g} m): the likelihood's maximum "
                           "lies beyond it",
                           "check the CCR survey (positions, pole heights); widen --diameter-range "
                           "only if a footprint that size is physically possible"))
    if "ccr_peak_photons" in held:
        out.append(Finding("warn", "CCR peak photons",
                           "not bounded by the counts: held at its limit",
                           "the footprint's edge is seen but not its centre: add CCRs nearer the "
                           "predicted track"))
    loss = [n for n in fit.at_limit if result.layout.quantity[n] == "shot_loss_rate"]
    if loss:
        if any("profiled out" in w for w in sol.warnings):
            how = ("profiled out: their σ are from the Schur complement of the observed "
                   "information")
        else:
            how = ("taken as known (the likelihood is not convex there); the profile intervals "
                   "re-maximise it")
        out.append(Finding("pass", "shot-loss rate", f"{', '.join(loss)} held at 0 (the counts "
                           f"show no lost shots); for the other parameters' σ it is {how}"))
    out += _loss_at_zero_with_few_ccrs(result)
    if not sol.converged:
        out.append(Finding("warn", "solver", "the maximum-likelihood iterations did not converge",
                           "report this pass; treat the values with care"))
    u = result.uncertainty
    if u.bootstrap_requested and u.bootstrap_failed > 0.05 * u.bootstrap_requested:
        out.append(Finding("warn", "bootstrap", f"{u.bootstrap_failed} of "
                           f"{u.bootstrap_requested} simulated passes like this one gave no "
                           "estimate",
                           "add lit CCRs: this pass is at the edge of what can be solved"))
    return out


def _loss_at_zero_with_few_ccrs(result) -> list[Finding]:
    """A beam with fewer than GOOD_CCRS lit CCRs whose shot-loss rate ran to its bound 0 (free or
    held): its gaps are then read as a sharp footprint edge, and the along-track bias and diameter
    rest on that edge, which two chords do not fix: no honest interval can be had from such a pass
    (docs/validation.md, "CCR on 2-CCR passes", has the simulated passes that showed it)."""
    lay, vals, out = result.layout, result.solution.values, []
    for g, key in enumerate(lay.groups):
        q = lay.name(g, "shot_loss_rate")
        lit = sum(1 for s in result.estimate.segments if s.window.group == g)
        if vals.get(q, 1.0) <= LOSS_AT_BOUND and lit < GOOD_CCRS:
            who = f"{key}: " if len(lay.groups) > 1 else ""
            out.append(Finding("warn", f"{who}intervals", "no honest interval: the shot-loss rate "
                               f"ran to its bound 0 with {lit} lit CCRs, so the counts' gaps are "
                               "read as a sharp footprint edge that two or three chords do not "
                               "fix; the along-track bias and the diameter (then short) may lie "
                               "well outside their intervals",
                               f"add lit CCRs (at least {GOOD_CCRS}) or solve several passes "
                               "together"))
    return out


def _sigma_agreement(result) -> Finding:
    notes = result.uncertainty.disagreements()
    u = result.uncertainty
    if not notes:
        which = "observed information" + (", bootstrap" if u.bootstrap else "") + " and Cramér–Rao"
        return Finding("pass", "σ", f"{which} agree within {SIGMA_AGREEMENT:.0%}")
    return Finding("warn", "σ", "; ".join(notes), "use the profile intervals (the σ given are "
                   "their wider halves / 1.96 where the likelihood is not quadratic)")


def _model_fit(fits: list[CCRFit]) -> Finding:
    bad = [f for f in fits if abs(f.z) > FIT_Z]
    if not bad:
        return Finding("pass", "CCR returns", f"every CCR's detections within {FIT_Z:g}σ of the "
                       f"fitted footprint ({len(fits)} CCR windows)")
    seen = "; ".join(f"{f.ccr_id} ({f.pass_name}) saw {f.detections} shots where "
                     f"{f.expected:.1f} were expected" for f in bad)
    return Finding("warn", "CCR returns", seen, "check those CCRs' surveyed positions and heights, "
                   "and whether they were covered or tilted")


def verdict_of(result) -> Verdict:
    """The calibration's verdict (numbers in m, 95 % intervals)."""
    fits = result.fits if result.fits is not None else ccr_fits(result)
    result.fits = fits
    n_ccr = len(result.estimate.segments)
    tracks, beams = len({w.pass_name for w in result.windows}), len(result.layout.groups)
    shared = ", one bias shared by all beams" if result.layout.shared_bias and beams > 1 else ""
    summary = (f"along/cross-track geolocation bias and footprint diameter from {n_ccr} lit CCR "
               f"segment(s) in {tracks} beam track(s) of {beams} beam(s){shared}")
    findings = (_solve_checks(result) + _geometry(result) + _precision(result)
                + [_sigma_agreement(result), _model_fit(fits)])
    return Verdict(summary, findings)
