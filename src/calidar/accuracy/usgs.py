"""The USGS Lidar Base Specification in ``calidar accuracy`` (issue 28): its absolute vertical
accuracy at the checkpoints (NVA RMSEz, VVA 95th percentile) and, with ``--swaths``, its swath
checks (intraswath smooth-surface precision, interswath RMSDz and max |dz|), judged by the same
functions as ``calidar quality`` (:mod:`calidar.strips.usgs`), for the verdict, accuracy.json and
the report. A quality level also sets the pulse density and more; only the accuracy is judged
here."""

from __future__ import annotations

from dataclasses import dataclass, field

from calidar.verdict import NOTE, Finding

SECTION_TEXT = (
    "The NVA RMSEz is the one reported above (ASPRS Edition 2: the checkpoints' survey error "
    "included). The thresholds are those of versions 1.2 to 2020 rev. A as read for calidar; their "
    "agreement with the current 2025 revision was not verified (docs/validation.md). A quality "
    "level also sets the pulse density, not checked here."
)


@dataclass
class SwathChecks:
    """The swath checks of ``--swaths``: the three checks and each line's precision, or why they
    do not apply (``note``: one flight line, no overlap)."""

    checks: list = field(default_factory=list)  #: calidar.strips.usgs.UsgsCheck
    precisions: list = field(default_factory=list)  #: calidar.strips.usgs.LinePrecision
    note: str = ""


def absolute(a) -> list:
    """The absolute checks (:class:`calidar.strips.usgs.UsgsCheck`) of an Assessment: the RMSEz
    reported (ASPRS Edition 2: the checkpoints' survey error included) and the VVA 95th
    percentile."""
    from calidar.strips.usgs import absolute_checks

    acc = a.accuracy
    return absolute_checks(acc.rmse_m, acc.n_nva, acc.vva95_m, acc.n_vva)


def _levels(check) -> str:
    """The quality levels a check meets at its tightest threshold met: "meets QL1/QL2 (≤ 10 cm)"."""
    from calidar.strips.usgs import threshold_m

    if not check.levels_met:
        return "meets no quality level"
    best_m = threshold_m(check.name, check.levels_met[0])
    same = [ql for ql in check.levels_met if threshold_m(check.name, ql) == best_m]
    return f"meets {'/'.join(same)} (≤ {best_m * 100:g} cm)"


def usgs_findings(a) -> list[Finding]:
    """The verdict's USGS findings: the absolute accuracy (pass when the NVA RMSEz meets a quality
    level, warn when it meets none), and the swath checks when run (else a note)."""
    from calidar.strips.usgs import ABSOLUTE_THRESHOLDS_M

    out = []
    nva, vva = absolute(a)
    if nva.value_m is not None:
        rmse_cm = nva.value_m * 100
        parts = [f"NVA RMSEz {rmse_cm:.1f} cm at {nva.n_cells} checkpoints {_levels(nva)}"]
        if vva.value_m is not None:
            parts.append(f"VVA 95th percentile {vva.value_m * 100:.1f} cm at {vva.n_cells} "
                         f"{_levels(vva)}")
        detail = "; ".join(parts) + " (accuracy only: a quality level also sets the pulse density)"
        if nva.levels_met:
            out.append(Finding("pass", "USGS absolute accuracy", detail))
        else:
            loosest_cm = ABSOLUTE_THRESHOLDS_M["QL3"][0] * 100
            out.append(Finding("warn", "USGS absolute accuracy", detail,
                               f"QL3, the loosest, asks for NVA RMSEz ≤ {loosest_cm:g} cm: see the "
                               "flight lines and checkpoints holding the error"))
    out.append(_swath_finding(getattr(a, "usgs_swaths", None)))
    return out


def _swath_finding(swaths) -> Finding:
    """The swath checks' finding: a note when not run or not applicable, else pass when all
    meet one quality level."""
    from calidar.strips.usgs import common_level

    if swaths is None:
        return Finding(NOTE, "USGS swath checks",
                       "not run (relative accuracy within and between swaths)",
                       "give --swaths, or run calidar quality on the swaths")
    if swaths.note:
        return Finding(NOTE, "USGS swath checks", f"do not apply: {swaths.note}")
    level = common_level(swaths.checks)
    measured = [f"{c.name} {c.value_m * 100:.1f} cm {c.status}" for c in swaths.checks
                if c.value_m is not None]
    detail = "; ".join(measured) or "nothing measured"
    if level:
        return Finding("pass", "USGS swath checks", detail + f": all meet {level}", "")
    return Finding("warn", "USGS swath checks", detail,
                   "calidar quality shows which pairs and lines")


def usgs_dict(a) -> dict:
    """accuracy.json's "usgs": the specification, the absolute checks and the swath checks."""
    from calidar.strips.usgs import ABSOLUTE_SPECIFICATION, SPECIFICATION, common_level

    swaths = getattr(a, "usgs_swaths", None)
    checks = [c.to_dict() for c in absolute(a)]
    doc = {"absolute": {"specification": ABSOLUTE_SPECIFICATION, "checks": checks}}
    if swaths is not None:
        doc["swaths"] = {"specification": SPECIFICATION, "note": swaths.note or None,
                         "meets": common_level(swaths.checks) if swaths.checks else None,
                         "checks": [c.to_dict() for c in swaths.checks],
                         "lines": [p.to_dict() for p in swaths.precisions]}
    return doc


def usgs_section(rep, a) -> None:
    """The report's section: each check's value against the thresholds of every quality level."""
    from calidar.strips.usgs import ABSOLUTE_SPECIFICATION, SPECIFICATION, THRESHOLDS_M, threshold_m

    sec = rep.section("USGS Lidar Base Specification")
    swaths = getattr(a, "usgs_swaths", None)
    checks = absolute(a) + ([] if swaths is None else swaths.checks)
    rows = []
    for c in checks:
        thresholds = [f"≤ {threshold_m(c.name, ql) * 100:g}" for ql in THRESHOLDS_M]
        value_cm = None if c.value_m is None else c.value_m * 100
        rows.append([c.name, value_cm, c.n_cells, *thresholds, c.status])
    header = ["check", "value [cm]", "checkpoints / cells", *(f"{ql} [cm]" for ql in THRESHOLDS_M),
              "result"]
    caption = ABSOLUTE_SPECIFICATION + (f"; {SPECIFICATION}" if swaths is not None else "")
    sec.table(header, rows, caption, formats=[None, ".2f", "d", None, None, None, None, None])
    text = SECTION_TEXT
    if swaths is None:
        text += (" The swath checks (relative accuracy) were not run: give --swaths, or run "
                 "calidar quality.")
    elif swaths.note:
        text += f" The swath checks do not apply: {swaths.note}."
    sec.text(text)
