"""The verdict of a range calibration: the correction with its uncertainty, whether the residuals
match the stated precisions (global test), the outliers found, the acceptance against a
tolerance, and the method's premises (level targets, distances that separate scale from offset)."""

from __future__ import annotations

import numpy as np

from calidar.rangecal import RangeCalibration
from calidar.report.numbers import signed
from calidar.verdict import Finding, Verdict

MM, PPM = 1e3, 1e6
SIGMA0_FAIL = 3.0  #: σ0 above which the model or the stated precisions are badly wrong
CORRELATED = 0.95  #: |ρ(offset, scale)| above which the distances barely separate them
NAMED_OUTLIERS = 5  #: outliers named in the verdict (all are in the report's table)
TRUTH_SIGMAS = 3.0  #: |error| / σ against a simulation's truth that passes


def stated_precisions(result: RangeCalibration) -> str:
    """The precisions the file states: scanner noise and each distinct total-station precision."""
    obs = result.observations
    ts = dict.fromkeys(f"angles {s.angle_sigma * 180 / np.pi * 3600:g}″, distances "
                       f"{s.distance_sigma_m * MM:g} mm + {s.distance_sigma_ppm:g} ppm"
                       for s in obs.setups)
    return f"scanner ranges {obs.scanner_sigma * MM:g} mm; total station {'; '.join(ts)}"


def _correction(result: RangeCalibration) -> Finding:
    sol, fit = result.solution, result.fit
    off, s_off = sol.values["range_offset"] * MM, sol.sigma["range_offset"] * MM
    lo, hi = fit.interval("range_offset")
    text = (f"range offset {signed(off, 2)} ± {s_off:.2f} mm "
            f"(95 %: {signed(lo * MM, 2)} … {signed(hi * MM, 2)} mm)")
    if fit.interval("range_scale") is not None:
        k, s_k = sol.values["range_scale"] * PPM, sol.sigma["range_scale"] * PPM
        klo, khi = fit.interval("range_scale")
        text += (f", range scale {signed(k, 1)} ± {s_k:.1f} ppm (95 %: {signed(klo * PPM, 1)} … "
                 f"{signed(khi * PPM, 1)} ppm)")
        how = "true distance = (scanner range − offset) / (1 + scale)"
    else:
        text += (", range scale held at 0 (--fix-scale: a scale error is inside the offset at "
                 "these distances)")
        how = "true distance = scanner range − offset"
    return Finding("pass", "range correction", f"{text}; correct the ranges as {how}")


def _global_test(result: RangeCalibration) -> Finding:
    g = result.fit.global_test
    s0, (lo, hi) = g["sigma0"], g["sigma0_range95"]
    detail = (f"σ0 = {s0:.2f} (χ² {g['chi2']:.1f} on {g['dof']:.0f} degrees of freedom; 0.95 "
              f"range {lo:.2f}–{hi:.2f}) against the stated precisions "
              f"({stated_precisions(result)})")
    check = "residuals vs the stated precisions"
    if g["passed"]:
        return Finding("pass", check, detail + ": they agree")
    if s0 < lo:
        return Finding("warn", check,
                       f"{detail}: the residuals are {1 / s0:.1f}× smaller than stated",
                       "the stated precisions are pessimistic; the σ above keep them (not scaled "
                       "down) — state the instruments' real precisions for honest intervals")
    status = "fail" if s0 > SIGMA0_FAIL else "warn"
    action = ("check scanner_sigma_mm and the setups' precisions in the file; if they are right, "
              "look for targets observed on the wrong point or an effect the model lacks")
    if status == "fail":
        action += " — do not use this result until resolved"
    return Finding(status, check, f"{detail}: the residuals are {s0:.1f}× larger than stated; "
                   "the σ above are scaled up by σ0", action)


def _named(rejected: list[dict]) -> str:
    """The first :data:`NAMED_OUTLIERS` rejected targets in words (and how many more)."""
    def one(r):
        group = f" (group {r['group']})" if r["group"] else ""
        return (f"line {r['line']} point {r['point']}{group}: residual "
                f"{signed(r['residual_m'] * MM, 1)} mm, w = {signed(r['w'], 1)}")

    named = "; ".join(one(r) for r in rejected[:NAMED_OUTLIERS])
    if len(rejected) > NAMED_OUTLIERS:
        named += (f"; and {len(rejected) - NAMED_OUTLIERS} more (the report's table, "
                  "solution.json → outliers)")
    return named


def _outliers(result: RangeCalibration) -> Finding:
    fit, n = result.fit, len(result.observations)
    if not fit.rejected:
        return Finding("pass", "outliers", "none: every standardized residual |w| ≤ 3.29 over the "
                       f"{n} targets (data snooping, α = 0.001)")
    named = _named(fit.rejected)
    stopped = any("data snooping stopped" in w for w in result.solution.warnings)
    if stopped:
        return Finding("fail", "outliers", f"data snooping stopped after {len(fit.rejected)} "
                       f"rejections (the 20 % limit) with targets still above |w| = 3.29: {named}",
                       "the stated precisions are too optimistic or the data hold a systematic "
                       "error: resolve it before using this result")
    return Finding("warn", "outliers",
                   f"{len(fit.rejected)} of {n} targets rejected by data snooping: {named}",
                   "check these targets in the field notes and re-measure them if you can; the "
                   "result above excludes them")


def _acceptance(result: RangeCalibration) -> list[Finding]:
    a = result.acceptance
    if a is None:
        return []
    lo, hi = a["distance_range_m"]
    where = "within" if a["passed"] else "beyond"
    detail = ("the uncorrected range error |offset + scale·d| with its 95 % uncertainty reaches "
              f"{a['max_bound95_m'] * MM:.2f} mm over the calibrated distances {lo:.1f}–{hi:.1f} "
              f"m: {where} the tolerance of {a['tolerance_m'] * MM:.2f} mm")
    if a["passed"]:
        return [Finding("pass", "acceptance", detail)]
    return [Finding("fail", "acceptance", detail, "the scanner's raw ranges are out of tolerance: "
                    "apply the range correction above and re-check it, or have the scanner "
                    "serviced")]


def _premises(result: RangeCalibration) -> list[Finding]:
    out, lv, sol = [], result.level, result.solution
    if not lv["level"]:
        height_mm = lv["max_abs_height_m"] * MM
        out.append(Finding("warn", "targets level with P",
                           f"A/B lie up to {height_mm:.1f} mm above or below P "
                           f"({lv['max_abs_z']:.1f} σ, line {lv['worst_line']}): the scanner was "
                           "not set level",
                           "the fit uses 3-D distances and stays valid, the two-step method's ΔS "
                           "does not; level the scanner at the next calibration"))
    if "range_scale" in sol.sigma:
        rho = float(sol.correlation[0, 1])
        d = result.fit.distance[result.fit.keep]
        if abs(rho) > CORRELATED:
            out.append(Finding("warn", "scale vs offset",
                               f"ρ = {signed(rho, 3)}: the targets' distances ({d.min():.1f}–"
                               f"{d.max():.1f} m) barely separate the scale from the offset",
                               "add E points or groups at shorter and longer distances, or fix "
                               "the scale (--fix-scale)"))
    return out


def _truth(result: RangeCalibration, truth: dict[str, float] | None) -> list[Finding]:
    if not truth:
        return []
    sol = result.solution
    z = {k: (sol.values[k] - truth[k]) / sol.sigma[k] for k in sol.sigma if k in truth}

    def error(k, v):
        factor, unit = (MM, "mm") if k == "range_offset" else (PPM, "ppm")
        return f"{k} {signed((sol.values[k] - truth[k]) * factor, 2)} {unit} ({abs(v):.1f} σ)"

    text = ", ".join(error(k, v) for k, v in z.items())
    ok = all(abs(v) <= TRUTH_SIGMAS for v in z.values())
    action = "" if ok else (f"beyond {TRUTH_SIGMAS:g} σ happens by chance in 0.3 % of runs: "
                            "check the simulation")
    return [Finding("pass" if ok else "warn", "against the simulation's truth", f"errors {text}",
                    action)]


def range_verdict(result: RangeCalibration, truth: dict[str, float] | None = None) -> Verdict:
    """The verdict of a range calibration; ``truth`` (SI by parameter name) adds a check against
    it."""
    obs = result.observations
    what = "range offset and scale" if "range_scale" in result.solution.sigma else "range offset"
    summary = (f"{what} of the scanner from {int(result.fit.keep.sum())} of {len(obs)} targets "
               f"({len(obs.groups)} groups, {int(np.sum(obs.kind == 'E'))} E points) observed "
               f"from {len(obs.setups)} total-station setup(s)")
    findings = [_correction(result), _global_test(result), _outliers(result), *_acceptance(result),
                *_premises(result), *_truth(result, truth)]
    return Verdict(summary, findings)
