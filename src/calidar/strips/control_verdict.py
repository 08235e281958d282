"""The verdict's word on what ground control fixes (issue 28): range offset, vertical lever arm
and the vertical trajectory bias (the strips' mean height correction), which a height error
shared by every strip hides from the overlaps; and the control points' own fit
(``calidar boresight --control``, :mod:`calidar.strips.control`)."""

from __future__ import annotations

import numpy as np

from calidar.strips.config import control_action, control_kind
from calidar.verdict import NOTE, Finding, two_digits


#: the parameters a height error common to all strips hides from the overlaps (ground control
#: observes them)
VERTICAL = ("range_offset", "lever_arm_z", "height_bias")


def words(control: dict) -> str:
    """What the control (solution.json's ``control``) is, in words: "ground control points",
    "control planes", … (its kind's :attr:`~calidar.strips.control.ControlPoints.words`)."""
    return control_kind(control.get("kind")).words


def vertical_findings(result, findings: list[Finding], limit_m: float) -> list[Finding]:
    """The findings of range offset and vertical lever arm told whether ground control fixed them,
    and the vertical trajectory bias (the strips' mean height correction): determined with control
    when its σ ≤ ``limit_m`` (the verdict's limit for lengths), else (or without control) not
    determined, naming --control."""
    from calidar.strips.control import vertical_shift

    sol = result.solution
    control = sol.extra.get("control")
    out = []
    for f in findings:
        if f.check in VERTICAL and control is None:
            relative = (" — by the overlaps' geometry only, relative to the trajectory's heights; "
                        "not tied to the ground" if f.status == "pass" else "")
            f = Finding(f.status, f.check, f.detail + relative,
                        "; or ".join(x for x in (f.action, control_action()) if x))
        elif f.check in VERTICAL and f.status == "pass":
            f = Finding(f.status, f.check, f.detail + f" with {control['n_used']} {words(control)}")
        out.append(f)
    shift = vertical_shift(result)
    estimated = any(n in sol.parameters.free_names for n in VERTICAL)
    if shift is not None:
        bias = _bias_finding(*shift, control, estimated, limit_m)
        out = [_with_the_whole(f, bias, shift[1]) for f in out] + [bias]
    return out + ([] if control is None else [control_finding(control)])


def _with_the_whole(f: Finding, bias: Finding, sigma_m: float) -> Finding:
    """``height_bias``'s finding when the whole common height correction (it + the trajectory knots'
    mean: the vertical trajectory bias) is determined: the control sees only that sum, and the split
    between the two follows the trajectory's priors (the flight's own mean height error, ≈ its σ /
    √(flight / correlation time)), so height_bias alone is as uncertain as that prior; what the
    corrected trajectory carries, the sum, is determined (issue 28)."""
    if f.check != "height_bias" or f.status == "pass" or bias.status != "pass":
        return f
    whole = (": the whole vertical correction (it and the trajectory's mean height correction: the "
             f"vertical trajectory bias, ±{two_digits(sigma_m * 100)} cm) is determined; its split "
             "between the two follows the trajectory's priors")
    return Finding("pass", f.check, f.detail.split(":")[0] + whole)


def _bias_finding(v: float, s: float, prior: float, control: dict | None, estimated: bool,
                  limit_m: float) -> Finding:
    """The vertical trajectory bias: determined with control when its σ is within ``limit_m`` and
    the control tells at least as much of it as the priors (σ ≤ σ_prior/√2: 1/σ² = 1/σ_prior² +
    1/σ_control², σ_control ≤ σ_prior)."""
    from_priors = (f"{two_digits(prior * 100)} cm from the trajectory's priors alone)"
                   if np.isfinite(prior) else "height_bias estimated: no prior)")
    text = (f"{v * 100:+.1f} ± {two_digits(s * 100)} cm (the strips' mean height correction; "
            + from_priors)
    check = "vertical trajectory bias"
    if control is None:
        unseen = (": not determined — a height error shared by every strip does not show in the "
                  "overlaps; only the trajectory's prior bounds it")
        return Finding("warn" if estimated else NOTE, check, text + unseen, control_action())
    if s <= limit_m and s <= prior / np.sqrt(2.0):
        by = f": determined by {control['n_used']} {words(control)}"
        return Finding("pass", check, text + by)
    weak = (": not determined beyond its prior even with the control (σ above "
            f"{limit_m * 100:.0f} cm, or the control tells less of it than the priors)")
    return Finding("warn", check, text + weak, "add control points spread over every strip")


def control_finding(control: dict) -> Finding:
    """The control points' fit after the calibration: dz RMS before → after against their σ."""
    rows = control["points"]
    chi = [r["dz_after_m"] / r["sigma_m"] for r in rows if r["sigma_m"] > 0]
    rms_z = float(np.sqrt(np.mean(np.square(chi)))) if chi else float("nan")
    label = control.get('label', 'control points')
    detail = (f"{control['n_used']} of {control['n_points']} {label} in the adjustment "
              f"({control['n_rows']} rows): dz RMS {control['rms_dz_before_m'] * 100:.1f} → "
              f"{control['rms_dz_after_m'] * 100:.1f} cm, RMS of dz/σ {rms_z:.2f}")
    missing = control["not_covered"]
    if missing:
        more = " …" if len(missing) > 5 else ""
        detail += f"; not covered by any strip: {', '.join(missing[:5])}" + more
    ok = (not missing or control_kind(control.get("kind")).reaches_beyond_strips) and rms_z < 3.0
    action = ("check the control points far off (solution.json: control) and their coordinates' "
              "CRS")
    return Finding("pass" if ok else "warn", "ground control", detail, "" if ok else action)
