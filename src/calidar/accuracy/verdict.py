"""The verdict of ``calidar accuracy``: the class statement, the checkpoint count against the
standard's minimum, a vertical bias, outliers, unused checkpoints, the vegetated figure and
the flight lines that disagree at the checkpoints — each with what to do."""

from __future__ import annotations

import numpy as np

from calidar.accuracy.asprs import MIN_NVA_CHECKPOINTS, VVA_REFERENCE_FACTOR, class_name
from calidar.accuracy.usgs import usgs_findings
from calidar.verdict import Finding, Verdict

BIAS_T = 3.0  #: |mean| > 3 standard errors: a vertical bias
STRIP_T = 3.0  #: two lines' mean residuals apart by > 3 standard errors: they disagree
LISTED = 8  #: ids named in a finding before "and N more"


def _cm(v: float, sign: bool = False) -> str:
    return f"{v * 100:{'+' if sign else ''}.1f} cm"


def _names(items: list[str]) -> str:
    more = len(items) - LISTED
    return ", ".join(items[:LISTED]) + (f" and {more} more" if more > 0 else "")


def disagreeing_strips(a) -> list:
    """The flight lines whose mean residual at the checkpoints departs from the others' by more than
    STRIP_T standard errors (each line's against the mean of all lines), largest first."""
    s = [e for e in a.strip_errors if e.n >= 3]
    if len(s) < 2:
        return []
    means = np.array([e.mean_m for e in s])
    se = np.array([e.rmse_m / np.sqrt(e.n) for e in s])
    centre = np.average(means, weights=1.0 / np.maximum(se, 1e-4) ** 2)
    t = np.abs(means - centre) / np.maximum(se, 1e-4)
    return [s[i] for i in np.argsort(-t) if t[i] > STRIP_T]


def tilted_strips(a) -> list:
    """The flight lines whose residuals change with the scan angle by more than STRIP_T σ."""
    return [e for e in a.strip_errors if e.slope_m_per_deg is not None
            and abs(e.slope_m_per_deg) > STRIP_T * max(e.slope_sigma_m_per_deg, 1e-9)]


def _class_finding(acc, target_cm: float | None) -> Finding:
    """The class statement of ASPRS Edition 2 (RMSE_V of the NVA checkpoints), against
    ``target_cm`` when given."""
    if acc.rmse_m is None:
        return Finding("fail", "NVA accuracy class",
                       "no non-vegetated checkpoint has a ground surface under it",
                       "check that the checkpoints lie on the data, in its CRS, with ground points "
                       "(class 2) near them")
    detail = acc.statement()
    if acc.rmse_interval_m is not None:
        lo, hi = acc.rmse_interval_m
        detail += (f"; RMSE_V(data) 95 % interval {_cm(lo)} … {_cm(hi)} (χ², {acc.n_nva} "
                   "checkpoints)")
    if target_cm is None:
        return Finding("pass", "NVA accuracy class", detail)
    target = class_name(target_cm)
    if acc.meets(target_cm):
        return Finding("pass", f"NVA {target} class", detail)
    return Finding("fail", f"NVA {target} class", detail + f": the {target} class is NOT met",
                   "see 'where the error is' below: the flight lines and checkpoints holding it")


def _bias_finding(acc) -> Finding | None:
    """A vertical bias: the NVA mean residual against its standard error (None under 5)."""
    if acc.sdom_m is None or acc.n_nva < 5:
        return None
    t = abs(acc.mean_m) / max(acc.sdom_m, 1e-6)
    detail = (f"mean dz {_cm(acc.mean_m, True)} ± {_cm(acc.sdom_m)} "
              f"(standard deviation {_cm(acc.std_m)})")
    if t <= BIAS_T:
        return Finding("pass", "vertical bias", detail + ": consistent with no bias")
    return Finding("warn", "vertical bias", detail + f": a bias of {t:.1f} standard errors",
                   "a vertical offset of the whole block, invisible in the strip overlaps: check "
                   "the vertical datum and geoid of points and checkpoints, then a range offset, "
                   "vertical lever arm or a vertical trajectory bias; ground control in the "
                   "adjustment determines them")


def _count_finding(acc) -> Finding:
    """The NVA checkpoint count against Edition 2's minimum."""
    if acc.n_nva >= MIN_NVA_CHECKPOINTS:
        return Finding("pass", "checkpoint count",
                       f"{acc.n_nva} NVA checkpoints tested (Edition 2: ≥ {MIN_NVA_CHECKPOINTS})")
    return Finding("warn", "checkpoint count",
                   f"{acc.n_nva} NVA checkpoints tested; Edition 2 asks for at least "
                   f"{MIN_NVA_CHECKPOINTS}",
                   "survey more non-vegetated checkpoints, spread over the project; until then "
                   "the class statement is provisional")


def _checkpoint_findings(a) -> list[Finding]:
    """What the checkpoints lack: their survey σ, outliers among them, those not tested."""
    acc, cp = a.accuracy, a.checkpoints
    findings = []
    if a.survey_rmse_m is None and acc.rmse_m is not None:
        findings.append(Finding("warn", "checkpoint survey accuracy",
                                "not given: the tested RMSEz is the data's alone",
                                "give the checkpoints' σ (a sigma column, or --survey-sigma): "
                                "Edition 2 includes the survey's error in the reported accuracy"))
    if out := a.outliers():
        items = [f"{cp.ids[i]} ({_cm(a.dz[i], True)})" for i in out]
        findings.append(Finding("warn", "outliers",
                                f"|dz| > 3 × RMSE at {len(out)} checkpoint(s): {_names(items)}; "
                                "kept in the statistics",
                                "look at each: a surface changed since the survey, a mistyped "
                                "height, a wrong land cover or a misclassified ground point"))
    if unused := a.unused():
        items = [f"{i}: {r}" for i, r in unused]
        findings.append(Finding("warn", "checkpoints not tested",
                                f"{len(unused)} of {len(cp)}: {_names(items)}",
                                "check that they lie on the delivered data; a larger --radius / "
                                "--max-edge accepts sparser ground"))
    return findings


def _vva_finding(acc) -> Finding:
    """The vegetated 95th percentile, reported without pass/fail (Edition 2), with Edition 1's
    reference for the class met."""
    ref = ""
    if acc.class_cm is not None:
        ref = (f" (Edition 1's reference for the {class_name(acc.class_cm)} class: "
               f"≤ {acc.class_cm * VVA_REFERENCE_FACTOR:g} cm)")
    return Finding("pass", "VVA",
                   f"95th percentile of |dz| {_cm(acc.vva95_m)} over {acc.n_vva} vegetated "
                   f"checkpoints, reported without pass/fail as Edition 2 says{ref}")


def _line_findings(a) -> list[Finding]:
    """Flight lines whose own surface is tilted across the swath or offset from the others'."""
    findings = []
    if tilted := tilted_strips(a):
        items = [f"line {e.point_source_id} {e.slope_m_per_deg * 1000:+.1f} ± "
                 f"{e.slope_sigma_m_per_deg * 1000:.1f} mm/°" for e in tilted]
        findings.append(Finding("warn", "dz against scan angle",
                                "the residuals of a line's own surface change with the scan "
                                f"angle: {_names(items)}",
                                "a tilt across the swath is the signature of the mounting "
                                "(boresight roll) or a scan-angle error: calibrate it (calidar "
                                "boresight) and re-georeference (calidar regeoref)"))
    if bad := disagreeing_strips(a):
        items = [f"line {e.point_source_id} {_cm(e.mean_m, True)} at {e.n}" for e in bad]
        findings.append(Finding("warn", "flight lines",
                                "mean dz of a line's own surface differs from the others': "
                                f"{_names(items)} checkpoints",
                                "lines off in opposite directions point to the mounting "
                                "(calidar boresight); one line off to its trajectory"))
    return findings


def accuracy_verdict(a, target_cm: float | None = None) -> Verdict:
    """The verdict of an :class:`calidar.accuracy.assess.Assessment`."""
    acc = a.accuracy
    findings = [_class_finding(acc, target_cm), _count_finding(acc)]
    if (bias := _bias_finding(acc)) is not None:
        findings.append(bias)
    findings += _checkpoint_findings(a)
    if acc.vva95_m is not None:
        findings.append(_vva_finding(acc))
    findings += _line_findings(a)
    findings += usgs_findings(a)
    summary = (f"vertical accuracy at {acc.n_nva + acc.n_vva} of {len(a.checkpoints)} checkpoints "
               f"({acc.n_nva} NVA, {acc.n_vva} VVA)")
    return Verdict(summary, findings)
