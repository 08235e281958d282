"""The verdict of a strip calibration: what was estimated, how well, and what to do.

Findings (each pass / warn / fail, with the numbers and, when not a pass, an action; notes inform):

- every estimated parameter: value ± σ (degrees and arc-seconds, millimetres), determined when
  its σ moves a point on the ground by at most :data:`GROUND_LIMIT_M` at the survey's median
  range (lengths: σ ≤ :data:`LENGTH_LIMIT_M`), not determined otherwise (warn; infinite σ:
  fail), and not determined either when the global test rejects the model (its warn or fail) —
  with a note that "determined" is not "correct";
- the global test of σ0 (the a-posteriori standard deviation of unit weight against 1, with
  the χ² test's 95 % range: inside passes, below is a note — the σ are conservative by that
  factor —, above warns, beyond :data:`SIGMA0_FAIL` fails); when two methods ran, their
  agreement (:func:`agreement_finding`); the residuals against the noise floor the
  correspondences' own scatter predicts, correlations between estimated parameters above
  :data:`CORRELATION_LIMIT`, convergence;
- the model check (:mod:`calidar.strips.model_check_verdict`): structural parameters not
  estimated, freed in turn — one the overlaps see that moves the estimates warns or fails;
- the overlaps before and after (swath differences: no pair worse, no strip left offset by more
  than :data:`OFFSET_LIMIT_M`), and what the σ rest on (the trajectory's
  accuracy: a file, estimated from the overlaps, or a default assumed; the trajectory model off).
"""

from __future__ import annotations

import math

import numpy as np

from calidar.strips.control_verdict import vertical_findings
from calidar.strips.convergence import NUISANCE, moving  # NUISANCE kept importable from here
# the verdict's global test, kept importable from here
from calidar.strips.global_test import (  # noqa: F401
    ROW_SIGMA_TOLERANCE, SIGMA0_FAIL, global_test_sigma0, robust_consistency, sigma0_finding,
    sigma0_range,
)
from calidar.strips.model_check_verdict import finding_or_none, moved_parameters
from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX
from calidar.verdict import NOTE, Finding, Verdict, angle_text, length_text, two_digits

#: an angle (or scale) is "determined" when its σ moves points on the ground by at most this (m)
GROUND_LIMIT_M = 0.02
#: a length (lever arm, range offset) is "determined" when its σ is at most this (m): better
#: than a tape measure on the mounting
LENGTH_LIMIT_M = 0.01
#: |ρ| between two estimated parameters above which the strips barely tell them apart
CORRELATION_LIMIT = 0.9
#: RMSDz of a pair may grow by this much (m) before the verdict calls it worse
WORSE_M = 0.002
#: a pair whose median dz stays beyond this after calibration is still offset (m)
OFFSET_LIMIT_M = 0.02

ANGLES = {"boresight_roll", "boresight_pitch", "boresight_yaw", "scan_angle_offset"}
#: what separates a parameter the strips cannot determine
ACTIONS = {
    "lever_arm_z": "hold it at the measured value or add a flight line at a second height",
    "lever_arm_x": "hold it at the measured value, or fly lines at two heights (a pitch error and "
                   "an along-track lever-arm error then move points differently)",
    "lever_arm_y": "hold it at the measured value, or fly lines at two heights and across",
    "boresight_pitch": "fly lines in opposite directions (and at two heights when the lever arm is "
                       "estimated too)",
    "boresight_roll": "fly overlapping lines in opposite directions",
    "boresight_yaw": "fly cross lines, or lines with more side overlap",
}
GENERIC_ACTION = ("hold it at its known value, or add flight lines that separate it (opposite "
                  "directions, cross lines, a second height)")


def _value_text(p, value: float, sigma: float) -> str:
    if p.name in ANGLES:
        return angle_text(value, sigma)
    if p.unit == "m":
        return length_text(value, sigma)
    return f"{p.to_display(value):+.4g} ± {p.to_display(sigma):.2g} {p.display_unit}"


def _ground_effect(p, sigma: float, range_m: float) -> float:
    """How far (m) a σ of this parameter moves a point at the median range."""
    if p.unit == "rad":
        return sigma * range_m
    if p.name == "range_scale" or p.name == "scan_angle_scale":
        return sigma * range_m * (0.35 if p.name == "scan_angle_scale" else 1.0)
    return sigma if p.unit == "m" else math.nan


def parameter_findings(result, range_m: float, global_test: Finding | None = None) -> list[Finding]:
    """One finding per estimated parameter: "determined" (its σ moves a point by at most the
    limit), "not determined" (more, or infinite σ), or — when ``global_test`` rejects the model
    (warn or fail) — not determined either way, with that test's status: the σ rest on a model the
    data reject."""
    sol = result.solution
    sig = sol.sigma
    rejected = global_test is not None and global_test.status in ("warn", "fail")
    out = []
    for p in sol.parameters.free:
        if p.name.startswith(NUISANCE):
            continue
        s = sig[p.name]
        text = _value_text(p, p.value, s)
        if not math.isfinite(s):
            out.append(Finding("fail", p.name,
                               f"{text}: not determined at all by these strips "
                               "(a singular direction)",
                               ACTIONS.get(p.name, GENERIC_ACTION)))
            continue
        g = _ground_effect(p, s, range_m)
        size = f"{two_digits(g * 100)} cm" if g >= 0.01 else f"{two_digits(g * 1000)} mm"
        ground = f"{size} on the ground at the {range_m:,.0f} m median range"
        where = ground if p.unit != "m" else ""
        if rejected:
            out.append(Finding(global_test.status, p.name,
                               f"{text}: not determined — the global test rejects the "
                               f"model this σ rests on ({global_test.detail.split(' (')[0]}); it "
                               "would hold only if the model did", "see the global test"))
        elif math.isfinite(g) and g > (LENGTH_LIMIT_M if p.unit == "m" else GROUND_LIMIT_M):
            limit_m = LENGTH_LIMIT_M if p.unit == "m" else GROUND_LIMIT_M
            limit = f"{limit_m * 100:.0f} cm"
            out.append(Finding("warn", p.name,
                               f"{text}: not determined by these strips (σ {two_digits(s * 100)} "
                               f"cm), more than {limit}" if p.unit == "m" else
                               f"{text}: not determined (its σ moves a point {where}; "
                               f"limit {limit})",
                               ACTIONS.get(p.name, GENERIC_ACTION)))
        else:
            where_text = f" ({where})" if where else ""
            out.append(Finding("pass", p.name, f"{text}: determined to this σ{where_text}"))
    return out


#: what "determined" means, on every strip verdict (the report and the CLI show it)
DETERMINED_NOTE = ("\"determined\" says how closely these strips fix a parameter if the model "
                   "holds (its σ), not that the value is correct: that rests on the global test, "
                   "the residuals, the overlaps and, when both methods ran, their agreement")


#: two methods' estimates differing by more than this many combined σ (see
#: :func:`agreement_finding`) fail
AGREEMENT_LIMIT = 3.0


def agreement_finding(results: dict) -> Finding:
    """Do two methods' calibrations of the same strips agree? Per shared parameter the difference d
    and z = d / √(σ_a² + σ_b²); FAIL when any |z| > :data:`AGREEMENT_LIMIT`.

    The two estimates come from the same strips, trajectory and trajectory model, so their errors
    are positively correlated (ρ > 0: the shared trajectory errors move both alike); the σ of
    the difference is then √(σ_a² + σ_b² − 2ρσ_aσ_b) ≤ √(σ_a² + σ_b²). The combination without
    ρ (unknown: it would need the two methods' joint covariance) is therefore an upper bound on the
    difference's σ: z is, if anything, too small, and a FAIL at 3 (< 0.3 % by chance per parameter
    for ρ = 0, less for ρ > 0) is not a false alarm from an optimistic σ; measured on simulated
    UAV surveys: docs/validation.md. Each σ is the method's own, already scaled by its σ0."""
    (ma, ra), (mb, rb) = list(results.items())[:2]
    va, vb, sa, sb = ra.solution.values, rb.solution.values, ra.solution.sigma, rb.solution.sigma
    rows, worst = [], []
    for p in ra.solution.parameters.free:
        if p.name.startswith(NUISANCE) or p.name not in sb:
            continue
        both = math.hypot(sa[p.name], sb[p.name])
        if not math.isfinite(both) or both <= 0:
            continue
        d = va[p.name] - vb[p.name]
        z = abs(d) / both
        unit = "°" if p.display_unit == "deg" else f" {p.display_unit}"
        difference = f"{p.to_display(d):+.3g}{unit} ± {p.to_display(both):.2g}{unit}"
        text = f"{p.name} {ma} − {mb} = {difference} (|z| = {z:.1f})"
        rows.append((z, text))
        if z > AGREEMENT_LIMIT:
            worst.append(text)
    check = f"{ma} and {mb} agree"
    combination = (f"z = difference / √(σ_{ma}² + σ_{mb}²), an upper bound on its σ as both use "
                   f"the same strips; limit {AGREEMENT_LIMIT:g}")
    if worst:
        return Finding("fail", check, "they disagree: " + "; ".join(worst) + f" ({combination})",
                       "one method is misled by these strips (see each one's global test and "
                       "residuals): use neither result until the cause is found; the tie planes' "
                       "and VGICP's pairs can be compared in the report")
    if not rows:
        return Finding(NOTE, check, "no parameter estimated by both methods with a finite σ")
    z, text = max(rows)
    return Finding("pass", check, f"largest difference {text} ({combination})")


def noise_finding(result, sigma_rows: np.ndarray | None) -> Finding:
    """Residuals after against the noise floor the correspondences' scatter predicts."""
    r = np.asarray(result.residuals_after, float)
    down = result.solution.residuals_after.get("downweighted_fraction", 0.0)
    if sigma_rows is None or sigma_rows.size != r.size or r.size == 0:
        return Finding("pass", "residuals", f"RMS {r.std() * 1e3:.1f} mm after calibration")
    scale = 1.4826 * float(np.median(np.abs(r / sigma_rows)))
    detail = (f"robust spread {scale:.2f}× the noise floor the correspondences' scatter predicts "
              f"(median σ {np.median(sigma_rows) * 1e3:.1f} mm; RMS "
              f"{np.sqrt(np.mean(r * r)) * 1e3:.1f} mm), {down:.1%} down-weighted as clutter")
    if scale <= 1.5:
        return Finding("pass", "residuals", detail)
    return Finding("warn", "residuals", detail,
                   "the strips disagree beyond their noise where the model says they "
                   "should agree: check the dz maps for strips or places that stand out")


def correlation_findings(sol) -> list[Finding]:
    names = [n for n in sol.parameters.free_names if not n.startswith(NUISANCE)]
    idx = [sol.parameters.free_names.index(n) for n in names]
    corr = sol.correlation[np.ix_(idx, idx)]
    out = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            rho = corr[i, j]
            if np.isfinite(rho) and abs(rho) > CORRELATION_LIMIT:
                lever_j = names[j] in ACTIONS and names[j].startswith("lever")
                weaker = names[j] if lever_j else names[i]
                out.append(Finding("warn", f"{names[i]} and {names[j]}",
                                   f"ρ = {rho:+.3f}: the strips barely tell them apart, and "
                                   "their σ are large",
                                   f"{weaker}: {ACTIONS.get(weaker, GENERIC_ACTION)}"))
    return out


def still_moving(result) -> tuple[str, float, float] | None:
    """(name, last step / σ, steps to come / σ) of the estimated non-nuisance parameter the outer
    loop left furthest from where its last two steps were heading, or None — the loop's own rule
    (:func:`calidar.strips.convergence.moving`: a last step over 0.2σ with more than 1σ to come at
    its rate; issue 26/32: the 10⁹ run's pitch moved 1.8σ in its last outer iteration, 74 % of the
    one before, and ended 7.7σ off), here on the final σ."""
    outer, sol = result.outer, result.solution
    if len(outer) < 2 or any("values" not in o for o in outer[-3:]):
        return None
    return moving([o["values"] for o in outer[-3:]], sol.sigma, NUISANCE)


def convergence_finding(result) -> Finding:
    outer = result.outer
    moved = " → ".join(f"{o['mean_distance_m'] * 1e3:.1f}" for o in outer)
    settled = len(outer) > 1 and not any("outer loop stopped" in w for w in result.warnings)
    moving = still_moving(result)
    if moving is not None:
        name, step, left = moving
        more = "as much again or more" if not np.isfinite(left) else f"≈ {left:.1f} σ more"
        return Finding("fail", "convergence",
                       f"the outer loop stopped after {len(outer)} iterations while {name} still "
                       f"moved {step:+.1f} σ an iteration ({more} at the rate of its last two "
                       f"steps; mean correspondence distance {moved} mm): the estimate has not "
                       "converged",
                       "run again with more outer iterations (--config FILE with [solver] "
                       "max_outer = 80 and threshold_m = 1e-6, whichever the method)")
    if result.solution.converged and settled:
        return Finding("pass", "convergence",
                       f"{len(outer)} outer iterations, mean correspondence distance {moved} mm")
    return Finding("warn", "convergence",
                   f"not settled after {len(outer)} outer iterations ({moved} mm)",
                   "check the nominal sensor (a start far from the truth), or run again from the "
                   "calibrated sensor.toml")


def overlap_finding(stages) -> Finding:
    """Swath differences as delivered against the last stage (new mounting and trajectory
    corrections)."""
    first, last = stages[0], stages[-1]
    before = {(q.a, q.b): q for q in first.pairs}
    worse, rms_b, rms_a, med_a = [], [], [], []
    for q in last.pairs:
        b = before.get((q.a, q.b))
        if b is None or b.rmsdz_m is None or q.rmsdz_m is None:
            continue
        rms_b.append(b.rmsdz_m)
        rms_a.append(q.rmsdz_m)
        med_a.append(abs(q.median_dz_m))
        if q.rmsdz_m > b.rmsdz_m + WORSE_M:
            worse.append(f"{q.a}–{q.b} {b.rmsdz_m * 1e3:.1f} → {q.rmsdz_m * 1e3:.1f} mm")
    if not rms_b:
        return Finding("warn", "overlaps", "no pair had smooth overlapping surfaces to compare",
                       "check the overlaps (classification, side overlap)")
    detail = (f"median RMSDz over {len(rms_b)} pairs {np.median(rms_b) * 1e3:.1f} → "
              f"{np.median(rms_a) * 1e3:.1f} mm ({last.label}); largest |median dz| after "
              f"{max(med_a) * 1e3:.1f} mm")
    if worse:
        return Finding("warn", "overlaps", detail + "; worse after: " + ", ".join(worse),
                       "look at those pairs' dz maps: a local problem (a trajectory outage, a "
                       "moving object) or an error the estimated parameters do not cover")
    if max(med_a) > OFFSET_LIMIT_M:
        return Finding("warn", "overlaps", detail +
                       f": strips still offset by more than {OFFSET_LIMIT_M * 1e3:.0f} mm",
                       "an error the calibration did not estimate shifts whole strips: trajectory "
                       "errors (leave the trajectory model on) or a parameter held fixed")
    return Finding("pass", "overlaps", detail +
                   " (with trajectory corrections the overlaps close whatever the "
                   "mounting: this says the strips fit, not that the mounting is right)")


ACCURACY_ACTION = ("give the trajectory's accuracy file (POSPac smrmsg) with "
                   "--trajectory-accuracy, or put it beside the SBET as smrmsg*.out")


def accuracy_finding(level: dict) -> Finding:
    """The trajectory accuracy estimated from the overlaps (a TrajectoryLevel's dict): a pass where
    every group of priors was estimated or bounded (held at the upper end the data leave it,
    named with the range they allow when the mounting's σ were averaged over it), a warning
    naming those the data cannot tell (the survey-grade default kept there) and
    the criterion."""
    groups = level["groups"]
    weak = [f"{g.replace('_', ' ')} (redundancy {v['redundancy_at_stated_sigma']:.1f} < "
            f"{level['min_redundancy']:g})"
            for g, v in groups.items() if not v["estimated"] and not v.get("bounded")]
    bounded = [f"{g.replace('_', ' ')} (redundancy {v['redundancy_at_stated_sigma']:.0f} at the "
               f"default, information {v['information']:.1f} at its estimate"
               + (f"; ×{min(v['sigma_factor_nodes']):.2g}–×{max(v['sigma_factor_nodes']):.2g} "
                  "at 10–90 % of what they allow" if v.get("sigma_factor_nodes") else "") + ")"
               for g, v in groups.items() if v.get("bounded")]
    factors = ", ".join(
        f"{g.replace('_', ' ')} ×{v['sigma_factor']:.2g}"
        + (f" ± {100 * v['sigma_factor_relative_sigma']:.0f} %" if v["estimated"] else "")
        + (" at most" if v.get("bounded") else "")
        for g, v in groups.items())
    if level["source"] == "data":
        detail = ("no accuracy file found; trajectory accuracy estimated from the overlaps: "
                  f"{level['headline']}; source: data (the survey-grade default's σ {factors})")
    else:
        detail = ("no accuracy file found, and the overlaps cannot tell the trajectory's "
                  f"accuracy: survey-grade default assumed, {level['headline']}; the σ of the "
                  "results hold only if the trajectory is that good")
    if level.get("over_time"):  # calidar.strips.trajectory_level_time
        spans = [(g, [seg[g]["sigma_factor"] for seg in level["over_time"]["segments"]])
                 for g in level["over_time"]["tau_log_sigma"]]
        moving = [(g, f) for g, f in spans if max(f) > 1.01 * min(f)]
        moved = ", ".join(f"{g.replace('_', ' ')} ×{min(f):.2g}–×{max(f):.2g}" for g, f in moving)
        detail += "; over the flight (per segment, pooled in time): " + (moved or "constant")
    if bounded:
        carried = any(v.get("sigma_factor_nodes") for v in groups.values())
        detail += ("; the data bound but do not measure " + ", ".join(bounded)
                   + ": held at the upper end they leave it (its σ conservative)"
                   + ("; the mounting's σ averaged over the range they allow" if carried else ""))
    if weak:
        detail += ("; the data cannot tell " + ", ".join(weak)
                   + ": the survey-grade default kept there")
    action = ACCURACY_ACTION if weak else ""
    return Finding("warn" if weak else "pass", "trajectory accuracy", detail, action)


def notes_findings(notes: list[str], warnings: list[str],
                   level: dict | None = None) -> list[Finding]:
    out = [] if level is None else [accuracy_finding(level)]
    for n in notes:
        if n.startswith("no trajectory accuracy found"):
            if level is None:
                out.append(Finding("warn", "trajectory accuracy", n, ACCURACY_ACTION))
        elif n.startswith("trajectory model off"):
            out.append(Finding("warn", "trajectory model", n,
                               "leave the trajectory model on (the default)"))
    for w in warnings:
        if w.startswith("strip pairs skipped"):
            out.append(Finding("warn", "pairs", w,
                               "check those pairs' overlap (too small, vegetation, water)"))
    return out


def strip_verdict(result, stages, notes: list[str] = (), accuracy_text: str | None = None,
                  others: list[Finding] = ()) -> Verdict:
    """The verdict of a :class:`calidar.strips.calibrate.CalibrationResult` with its overlap
    quality stages (calidar.strips.report.QualityStage), the run's notes and ``others`` (findings
    about the whole run, e.g. :func:`agreement_finding`)."""
    sol = result.solution
    shown = [p.name for p in sol.parameters.free if not p.name.startswith(NUISANCE)]
    n_traj = sum(p.name.startswith(TRAJECTORY_PREFIX) for p in sol.parameters.free)
    ranges = np.concatenate([s.obs.range_m[:: max(1, len(s) // 2000)] for s in result.strips])
    what = result.matcher.label
    exact = ", trajectory taken as exact"
    trajectory = f", with {n_traj:,} trajectory corrections" if n_traj else exact
    summary = (f"{', '.join(shown)} from {len(result.pairs)} overlapping pairs of "
               f"{len(result.strips)} strips ({what}, {result.outer[-1]['n_obs']:,} observations)"
               + trajectory)
    global_test = sigma0_finding(sol)
    parameters = parameter_findings(result, float(np.median(ranges)), global_test)
    findings = vertical_findings(result, moved_parameters(parameters, sol), LENGTH_LIMIT_M)
    findings += [Finding(NOTE, "determined", DETERMINED_NOTE), global_test, *finding_or_none(sol),
                 *others, noise_finding(result, result.row_sigma)]
    findings += correlation_findings(sol) + [convergence_finding(result), overlap_finding(stages)]
    level = sol.extra.get("trajectory_accuracy_estimate")
    findings += notes_findings(list(notes), sol.warnings, level)
    return Verdict(summary, findings)
