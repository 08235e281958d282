"""The model check's verdict finding (:mod:`calidar.strips.model_check`): does a structural
parameter the calibration did not estimate show in the overlaps, and would freeing it move the
estimated ones?

Per candidate the freed value's z (Wald; with one parameter freed, every estimated parameter's
Hausman z is the same number) and the largest shift of an estimated parameter in units of its own σ:

- |z| ≤ :data:`Z_WARN` for every candidate: pass (the overlaps see none of them);
- |z| > :data:`Z_WARN` and a shift > :data:`SHIFT_LIMIT` of its own σ: warn, and FAIL when
  |z| > :data:`Z_FAIL` — the estimated values rest on a held parameter the overlaps say is wrong;
- |z| > :data:`Z_WARN` with every shift within :data:`SHIFT_LIMIT` σ: a note (the overlaps see it,
  the estimates hardly depend on it).

The thresholds are measured (benchmarks/model_check.py; docs/validation.md, "Model check").
"""

from __future__ import annotations

import math

from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX
from calidar.verdict import NOTE, Finding, angle_text, length_text

#: |z| of a freed parameter above which the overlaps see it (warn when it moves the estimates)
Z_WARN = 3.0
#: |z| above which a freed parameter that moves the estimates fails the calibration
Z_FAIL = 5.0
#: a shift of an estimated parameter beyond this many of its own σ is one that matters
SHIFT_LIMIT = 2.0
#: the --estimate name of each candidate's group
GROUP = {"range_offset": "range_offset", "scan_angle_scale": "scan_angle_scale",
         "scan_angle_offset": "scan_angle_offset", "lever_arm_x": "lever_arm_x",
         "lever_arm_y": "lever_arm_y"}
WHAT = {"range_offset": "a range offset", "scan_angle_scale": "a scan-angle "
        "scale error", "scan_angle_offset": "a scan-angle offset",
        "lever_arm_x": "an along-track lever-arm error",
        "lever_arm_y": "an across-track lever-arm error"}


def value_text(unit: str, value: float, sigma: float | None = None) -> str:
    """A value in solution.json's display units (deg, m, ppm, 1: a ratio), as the verdict says."""
    if unit == "m":
        return length_text(value, sigma)
    if unit == "deg":
        return angle_text(math.radians(value), None if sigma is None else math.radians(sigma))
    k = 1.0 if unit == "ppm" else 1e6  # ratios as ppm
    return f"{value * k:+.0f} ppm" + ("" if sigma is None else f" ± {sigma * k:.0f} ppm")


def _shift_text(name: str, s: dict) -> str:
    return f"{name} by {value_text(s['unit'], s['shift'])} ({abs(s['in_own_sigma']):.1f}× its σ)"


def _candidate(name: str, c: dict, sol) -> tuple[str, str]:
    """(status, text) of one separable candidate."""
    z = c["z"]
    shifts = c.get("shifts", {})
    worst = max(shifts, key=lambda s: abs(shifts[s]["in_own_sigma"]), default=None)
    moved = worst is not None and abs(shifts[worst]["in_own_sigma"]) > SHIFT_LIMIT
    value = value_text(c['unit'], c['value'], c['sigma'])
    seen = f"the overlaps show {WHAT[name]} of {value} (z = {z:+.1f})"
    if abs(z) <= Z_WARN:
        return "pass", f"{name} {value} (z = {z:+.1f})"
    if not moved:
        where = "" if worst is None else f"; it moves {_shift_text(worst, shifts[worst])}"
        return NOTE, (f"{seen}, not estimated{where}: freed, it moves no estimate by more than "
                      f"{SHIFT_LIMIT:g} of its σ "
                      "(estimating it is the better model; the estimates hardly change)")
    status = "fail" if abs(z) > Z_FAIL else "warn"
    return status, (f"freeing {name} moves {_shift_text(worst, shifts[worst])}; {seen} that is "
                    "not estimated")


def model_check_finding(check: dict, sol) -> Finding:
    """The verdict finding of the model check (``solution.extra["model_check"]``) of ``sol``."""
    rank = {"fail": 3, "warn": 2, NOTE: 1, "pass": 0}
    rows, skipped = [], []
    for name, c in check["candidates"].items():
        if c["separable"]:
            rows.append((name, *_candidate(name, c, sol)))
        else:
            skipped.append(f"{name} is {c['same_as']}" if c.get("same_as") else
                           f"{name}: not separable from the estimated parameters")
    tail = f" (not tested: {'; '.join(skipped)})" if skipped else ""
    if check.get("not_run"):
        return Finding(NOTE, "model check", f"not run: {check['not_run']}")
    if not rows:
        return Finding(NOTE, "model check", "no parameter left to free" + tail)
    status = max((r[1] for r in rows), key=rank.get)
    if status == "pass":
        z = ", ".join(r[2] for r in rows)
        return Finding("pass", "model check",
                       f"each structural parameter not estimated, freed in turn, is within "
                       f"{Z_WARN:g} σ of its nominal value: {z}" + tail)
    flagged = sorted((r for r in rows if r[1] == status),
                     key=lambda r: -abs(check["candidates"][r[0]]["z"]))
    detail = "; ".join(r[2] for r in flagged)
    if len(flagged) > 1:
        detail = (f"{detail} — each freed alone: alternative explanations of one misfit, "
                  "the first the clearest")
    if status == NOTE:
        return Finding(NOTE, "model check", detail + tail)
    estimated = [p.name for p in sol.parameters.free if not p.name.startswith(TRAJECTORY_PREFIX)]
    best = flagged[0][0]
    estimate = f"--estimate {_estimate_text(estimated)},{GROUP[best]}"
    if status == "fail":
        action = (f"estimate {best} ({estimate}) and run again, or give --control / --checkpoints, "
                  "which tell it from the mounting; until then the estimated values are not to "
                  "be used")
    else:
        action = f"estimate {best} ({estimate}) and compare, or give --control / --checkpoints"
    limit = Z_FAIL if status == 'fail' else Z_WARN
    return Finding(status, "model check",
                   detail + f" (|z| > {limit:g}, shift > {SHIFT_LIMIT:g} σ)" + tail, action)


def moved_parameters(findings: list[Finding], sol) -> list[Finding]:
    """``findings`` (one per estimated parameter) with those a flagged candidate of the model check
    moves beyond :data:`SHIFT_LIMIT` of their σ no longer "determined": their value rests on a held
    parameter the overlaps say is wrong (the model check's status, and what moves them)."""
    check = sol.extra.get("model_check") if isinstance(sol.extra, dict) else None
    if not check or "candidates" not in check:
        return findings
    moved: dict[str, tuple[str, str, float, float]] = {}
    for name, c in check["candidates"].items():
        status = _candidate(name, c, sol)[0] if c["separable"] else "pass"
        if status not in ("warn", "fail"):
            continue
        for p, s in c["shifts"].items():
            clearest = abs(c["z"]) > moved.get(p, ("", "", 0, 0))[3]
            if abs(s["in_own_sigma"]) > SHIFT_LIMIT and clearest:
                moves = f"freeing {name} moves it by {value_text(s['unit'], s['shift'])}"
                moved[p] = (status, moves, s["in_own_sigma"], abs(c["z"]))
    out = []
    for f in findings:
        if f.check in moved and f.status in ("pass", "warn"):
            status, why, k, _ = moved[f.check]
            f = Finding(status, f.check,
                        f"{f.detail.split(': ')[0]}: not determined — {why} ({abs(k):.1f}× this "
                        "σ): the value rests on a parameter held that the overlaps say is wrong",
                        "see the model check")
        out.append(f)
    return out


def _estimate_text(names: list[str]) -> str:
    """The --estimate value of these parameters (groups where whole)."""
    from calidar.errors import InputError
    from calidar.strips.config import Estimate

    try:
        return ",".join(Estimate(frozenset(names)).names())
    except InputError:  # a name the configuration does not know: list them as they are
        return ",".join(names)


def finding_or_none(sol) -> list[Finding]:
    """[the model check's finding] when the solution holds one, else []."""
    check = sol.extra.get("model_check") if isinstance(sol.extra, dict) else None
    return [] if not check or not isinstance(check, dict) or "candidates" not in check else [
        model_check_finding(check, sol)]

