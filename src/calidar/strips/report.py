"""The strip-calibration section of the HTML report (``calidar boresight`` and the demo).

It renders results and computes nothing: the calibration result, the overlap quality the
pipeline measured (:class:`QualityStage`, one per state of the strips, each with the commands
that reproduce it) and the trajectory accuracy used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.report import Report
from calidar.report.chart_picture import correlation_png, histogram_png
from calidar.report.map_picture import map_png
from calidar.strips.calibrate import CalibrationResult
from calidar.strips.config import control_kind
from calidar.strips.quality import PairQuality
from calidar.strips.verdict import NUISANCE

#: the trajectory prior's shapes (:data:`calidar.strips.trajectory_errors.SHAPES`) in words
ORDER = {"gm1": "first order", "gm2": "second order"}

REFERENCES = [
    "Besl, P. J., McKay, N. D. (1992). A method for registration of 3-D shapes. IEEE Transactions "
    "on Pattern Analysis and Machine Intelligence 14(2), 239–256. (The outer loop: "
    "re-match, re-solve.)",
    "Glira, P., Pfeifer, N., Mandlburger, G. (2016). Rigorous strip adjustment of UAV-based "
    "laserscanning data including time-dependent correction of trajectory errors. Photogrammetric "
    "Engineering & Remote Sensing 82(12), 945–954. (Trajectory corrections as functions of "
    "time.)",
    "Koide, K., Yokozuka, M., Oishi, S., Banno, A. (2021). Voxelized GICP for fast and accurate 3D "
    "point cloud registration. IEEE International Conference on Robotics and Automation (ICRA), "
    "11054–11059. (VGICP.)",
    "Smyth, G. K. (2004). Linear models and empirical Bayes methods for assessing differential "
    "expression in microarray experiments. Statistical Applications in Genetics and Molecular "
    "Biology 3(1), article 3. (Moderated variances of the tie planes.)",
    "Liang, K.-Y., Zeger, S. L. (1986). Longitudinal data analysis using generalized linear "
    "models. Biometrika 73(1), 13–22; Cameron, A. C., Miller, D. L. (2014). Robust inference for "
    "dyadic data. Working paper, University of California, Davis. (Cluster-robust σ.)",
    "Heidemann, H. K. (2018). Lidar base specification (version 1.3). U.S. Geological Survey "
    "Techniques and Methods, book 11, chapter B4. (Swath-overlap difference, RMSDz.)",
    "Hausman, J. A. (1978). Specification tests in econometrics. Econometrica 46(6), 1251–1271. "
    "(The model check: the shift's covariance as the difference of the two covariances.)",
]


@dataclass
class QualityStage:
    """The overlap quality of the strips in one state, and what reproduces it."""

    label: str  #: "as delivered", "new mounting", "new mounting + trajectory corrections"
    command: str  #: the command(s) that reproduce it from the written files
    pairs: list[PairQuality]


def _mm(v):
    return None if v is None else 1e3 * v


def quality_table(sec, stages: list[QualityStage]) -> None:
    """Per pair: cells, median dz and RMSDz (mm) in every stage."""
    by_pair = [{(q.a, q.b): q for q in st.pairs} for st in stages]
    keys = [(q.a, q.b) for q in stages[0].pairs]
    rows = []
    for key in keys:
        qs = [b.get(key) for b in by_pair]
        medians = [_mm(q.median_dz_m) if q else None for q in qs]
        rmsdz = [_mm(q.rmsdz_m) if q else None for q in qs]
        rows.append([f"{key[0]}–{key[1]}", qs[0].n_cells, qs[0].n_points_a, qs[0].n_points_b]
                    + medians + rmsdz)
    short = ["before", "mounting", "mounting + trajectory"][:len(stages)]
    header = (["pair", "cells", "points a", "points b"] + [f"median dz {s} [mm]" for s in short]
              + [f"RMSDz {s} [mm]" for s in short])
    used = sorted({d["description"] for q in stages[0].pairs for d in q.points_a + q.points_b})
    sec.table(header, rows,
              "Swath-overlap differences dz = a − b on smooth, gently sloped cells of the whole "
              "strips (USGS Lidar Base Specification), in mm; cells and points compared (as "
              "delivered). Points used: "
              + ("; ".join(used) or "all") + ".",
              formats=[None, "d", "d", "d"] + [".1f"] * (2 * len(stages)))


def correction_table(sec, result: CalibrationResult) -> None:
    """Per strip: the largest estimated trajectory shift (horizontal, vertical, mm) and tilt (″)."""
    rows = []
    for sid, c in sorted(result.corrections.items()):
        horizontal = 1e3 * float(np.max(np.hypot(c.shift[:, 0], c.shift[:, 1])))
        vertical = 1e3 * float(np.max(np.abs(c.shift[:, 2])))
        roll_pitch = 3600 * float(np.degrees(np.max(np.abs(c.tilt[:, :2]))))
        heading = 3600 * float(np.degrees(np.max(np.abs(c.tilt[:, 2]))))
        rows.append([sid, c.shift.shape[0], horizontal, vertical, roll_pitch, heading])
    sec.table(["strip", "knots", "max horizontal shift [mm]", "max vertical shift [mm]",
               "max roll/pitch tilt [″]", "max heading tilt [″]"], rows,
              "Estimated trajectory corrections (sbet_corrected.out holds them).",
              formats=[None, "d", ".1f", ".1f", ".2f", ".2f"])


def unevenness_text(pairs: list[dict], pooled: dict | None = None) -> str:
    """VGICP's unevenness length ℓ, ``pooled`` over the survey's pairs at the first matching pass
    (:func:`calidar.strips.unevenness_length.pooled_fit`'s record), with the pairs' own readings
    (``pairs``' "unevenness"), one sentence; "" when none was estimated."""
    fits = [p["unevenness"] for p in pairs if p.get("unevenness")]
    if not fits or pooled is None:
        return ""
    length = np.array([f["length_m"] for f in fits])
    low, high = pooled["length_range_m"]
    return (f"VGICP's rows: the ground's unevenness correlated over ℓ = {pooled['length_m']:.2g} m "
            f"(95 % range {low:.2g}–{high:.2g} m; 0: uncorrelated), read from the points about "
            f"their local planes in {pooled['rows']:,} neighbourhoods of {pooled['pairs']} pairs "
            f"at the first matching pass and kept for the later ones (each pair alone: "
            f"{length.min():.2g}–{length.max():.2g} m), unevenness σ_u "
            f"{pooled['sigma_u_m'] * 1e3:.1f} mm over the points' noise σ_e "
            f"{pooled['sigma_e_m'] * 1e3:.1f} mm (the pairs' median); each row's σ counts the "
            "unevenness as the two strips sample it.")


def add_report_section(report: Report, result: CalibrationResult,
                       truth: dict[str, float] | None = None,
                       quality: list[QualityStage] | None = None, title: str | None = None,
                       accuracy=None, map_pair: tuple[int, int] | None = None,
                       classes: str | None = None):
    """Add a section: what was done (``classes``: which LAS classes the strips' points are of),
    parameters (with truth, SI dict, when given), correlations, residual histograms, the overlap
    quality stages with their commands and the dz maps of ``map_pair`` (a, b) before and after,
    references."""
    sol = result.solution
    sec = report.section(title or f"Strip calibration ({result.method})")
    n_obs = result.outer[-1]["n_obs"] if result.outer else 0
    distances = " → ".join(f"{o['mean_distance_m'] * 1e3:.1f}" for o in result.outer)
    sec.text(f"{len(result.strips)} strips, {len(result.overlaps)} overlapping pairs, "
             f"{len(result.pairs)} used; {n_obs:,} observations ({result.matcher.label}); "
             f"{len(result.outer)} outer iterations (re-matching [1]), mean correspondence "
             "distance " + distances + " mm."
             + (f" The strips' points: {classes}." if classes else ""))
    uneven = unevenness_text(result.pairs, sol.extra.get("strips", {}).get("unevenness"))
    if uneven:
        sec.text(uneven)
    if result.trajectory_model is not None and result.corrections:
        m = result.trajectory_model
        sec.text("Trajectory errors estimated as corrections per strip [2]: a shift and a "
                 f"rotation at knots every {m.block_s:g} s, linear in between, Gauss–Markov "
                 f"correlated over {m.correlation_s:g} s (position, {ORDER[m.shape[0]]}) and "
                 f"{m.attitude_correlation_s:g} s (attitude, {ORDER[m.shape[1]]}), with the "
                 "trajectory's own accuracy "
                 "as priors: "
                 + (accuracy.describe() if accuracy is not None else "see solution.json") + ".")
    sec.solution(sol, truth, residual_unit="mm", residual_factor=1e3)
    shown = [n for n in sol.parameters.free_names if not n.startswith(NUISANCE)]
    if len(shown) > 1:
        idx = [sol.parameters.free_names.index(n) for n in shown]
        sec.picture(correlation_png(sol.correlation[np.ix_(idx, idx)], shown),
                    "Correlations of the estimated parameters (|ρ| near 1: the strips barely tell "
                    "the two apart).")
    before_mm = 1e3 * np.asarray(result.residuals_before)
    after_mm = 1e3 * np.asarray(result.residuals_after)
    sec.picture(histogram_png(before_mm, after_mm, unit="mm"),
                "Correspondence residuals at the nominal sensor (first matching) and after "
                "calibration (last matching).")
    if result.corrections:
        sec.heading("Trajectory corrections")
        correction_table(sec, result)
    over_time = sol.extra.get("trajectory_accuracy_estimate", {}).get("over_time")
    if over_time:
        from calidar.strips.trajectory_level_time import (LEVEL_TABLE_HEADER, level_table_rows,
                                                          level_table_text)

        sec.heading("Trajectory accuracy over the flight (estimated)")
        sec.text(level_table_text(over_time))
        sec.table(LEVEL_TABLE_HEADER, level_table_rows(over_time))
    if "control" in sol.extra:
        _control_part(sec, sol.extra["control"])
    if sol.extra.get("model_check"):
        _model_check_part(sec, sol.extra["model_check"])
    if quality:
        _quality_part(sec, quality, map_pair)
    sec.heading("References")
    sec.references(REFERENCES)
    return sec


def _control_part(sec, control: dict) -> None:
    """The ground control's residuals (calidar boresight --control): per control point and strip."""
    kind = control_kind(control.get("kind"))
    sec.heading("Ground control")
    missing = control["not_covered"]
    not_covered = ""
    if missing:
        more = " …" if len(missing) > 20 else ""
        not_covered = f"; not covered by any strip: {', '.join(missing[:20])}" + more
    sec.text(f"{control['n_used']} of {control['n_points']} "
             f"{control.get('label', 'control points')} observed by the strips around them "
             + kind.dz_meaning + not_covered + ".")
    rows = [[r["id"], r["strip"], None if r["dz_before_m"] is None else 100 * r["dz_before_m"],
             100 * r["dz_after_m"], 100 * r["sigma_m"],
             abs(r["dz_after_m"]) / r["sigma_m"] if r["sigma_m"] > 0 else None]
            for r in control["points"]]
    if len(rows) > MAX_CONTROL_ROWS:  # a reference cloud: hundreds of cells; the worst ones shown
        sec.text(f"The {MAX_CONTROL_ROWS} rows of {len(rows)} with the largest |dz|/σ after "
                 "(solution.json lists all).")
        rows = sorted(rows, key=lambda r: -(r[5] or 0.0))[:MAX_CONTROL_ROWS]
    sec.table([kind.row_noun, "strip", "dz before (cm)", "dz after (cm)", "σ (cm)", "|dz|/σ after"],
              rows, formats=[None, None, "+.1f", "+.1f", ".1f", ".2f"])


MAX_CONTROL_ROWS = 40  #: the ground-control table's rows at most (the worst in |dz|/σ)


def _model_check_part(sec, check: dict) -> None:
    """The model check (calidar.strips.model_check): each structural parameter not estimated, freed
    in turn."""
    from calidar.strips.model_check_verdict import value_text

    sec.heading("Model check")
    sec.text("Each structural parameter the calibration held at its nominal value, freed on its "
             "own on the same final correspondences, weights and trajectory model (one linear "
             f"solve each, {check['seconds']:.1f} s in all): the value the overlaps give it, its "
             "z, and the largest shift it causes in an estimated parameter, in that parameter's "
             "own σ and with the shift's σ from the difference of the two covariances [7] (whose "
             "z is the freed parameter's). See the verdict's \"model check\" finding.")
    rows = []
    for name, c in check["candidates"].items():
        if not c["separable"]:
            what = (f"the same as {c['same_as']} (a rotation about the scanner's x axis)"
                    if c.get("same_as") else "not separable from the estimated parameters")
            rows.append([name, what, None, None, None, None])
            continue
        shifts = c.get("shifts") or {}
        worst = max(shifts, key=lambda k: abs(shifts[k]["in_own_sigma"]), default=None)
        s = shifts.get(worst, {})
        shift = None if worst is None else value_text(s["unit"], s["shift"], s["sigma"])
        rows.append([name, value_text(c["unit"], c["value"], c["sigma"]), c["z"], worst, shift,
                     s.get("in_own_sigma")])
    sec.table(["freed parameter", "value the overlaps give it", "z", "most moved", "its shift",
               "shift / its own σ"],
              rows, formats=[None, None, "+.1f", None, None, "+.1f"])


def _quality_part(sec, quality: list[QualityStage], map_pair: tuple[int, int] | None) -> None:
    sec.heading("Overlap quality, and how to reproduce it")
    rows = []
    for st in quality:
        med = [abs(q.median_dz_m) for q in st.pairs if q.median_dz_m is not None]
        rms = [q.rmsdz_m for q in st.pairs if q.rmsdz_m is not None]
        rows.append([st.label, len(st.pairs), 1e3 * float(np.median(rms)) if rms else None,
                     1e3 * max(med) if med else None])
    sec.table(["strips", "pairs", "median RMSDz [mm]", "largest |median dz| [mm]"], rows,
              "Summary of the three states of the strips (per pair below).",
              formats=[None, "d", ".1f", ".1f"])
    quality_table(sec, quality)
    for st in quality:
        sec.code(st.command, f"{st.label}: reproduced by")
    for st in (quality[0], quality[-1]):
        q = next((q for q in st.pairs if (q.a, q.b) == map_pair), None)
        if q is not None and q.grid.size:
            title = (f"strips {q.a} − {q.b}, {st.label}: median dz "
                     f"{1e3 * (q.median_dz_m or 0):+.1f} mm, RMSDz {1e3 * (q.rmsdz_m or 0):.1f} mm")
            label = f"dz = z({q.a}) − z({q.b}) [mm]"
            sec.picture(map_png(1e3 * q.grid, q.origin, q.cell_m, title, label),
                        f"Pair {q.a}–{q.b} ({st.label}; side by side with the most smooth cells), "
                        "on its own colour scale.")


def add_comparison_section(report: Report, results: dict[str, CalibrationResult],
                           truth: dict[str, float] | None = None):
    """A section comparing the same calibration by several methods: per parameter each value ± σ,
    the difference of the first two in units of their combined σ, and the truth when known."""
    (ma, ra), (mb, rb) = list(results.items())[:2]
    sec = report.section(f"{ma} and {mb} compared")
    va, vb, sa, sb = ra.solution.values, rb.solution.values, ra.solution.sigma, rb.solution.sigma
    rows = []
    for p in ra.solution.parameters.free:
        if p.name.startswith(NUISANCE) or p.name not in sb:
            continue
        d = va[p.name] - vb[p.name]
        both = np.hypot(sa[p.name], sb[p.name])
        row = [p.name, p.display_unit,
               f"{p.to_display(va[p.name]):.6g} ± {p.to_display(sa[p.name]):.2g}",
               f"{p.to_display(vb[p.name]):.6g} ± {p.to_display(sb[p.name]):.2g}", p.to_display(d),
               abs(d) / both if both > 0 else None]
        if truth and p.name in truth:
            row += [p.to_display(truth[p.name]), p.to_display(va[p.name] - truth[p.name]),
                    p.to_display(vb[p.name] - truth[p.name])]
        rows.append(row)
    header = ["parameter", "unit", f"{ma} (± σ)", f"{mb} (± σ)", f"{ma} − {mb}",
              "|difference| / combined σ"]
    if truth:
        header += ["truth", f"{ma} error", f"{mb} error"]
    sec.table(header, rows,
              "The two solutions use the same strips and model; a difference well beyond 3 "
              "combined σ means one method's correspondences are biased (for example tie planes on "
              "vegetation or VGICP pairs on edges). Values in the unit of each row.",
              formats=[None, None, None, None, ".3g", ".2f", ".6g", ".3g", ".3g"])

    def seconds(r, key):
        return sum(o.get(key, 0.0) for o in r.outer)

    rows = [[m, r.outer[-1]["n_obs"], len(r.outer), seconds(r, "georeference_s"),
             seconds(r, "match_s"), seconds(r, "solve_s"),
             1e3 * r.solution.residuals_after.get("rms")] for m, r in results.items()]
    sec.table(["method", "observations", "outer iterations", "georeference [s]", "match [s]",
               "solve [s]", "RMS residual after [mm]"], rows,
              formats=[None, "d", "d", ".2f", ".2f", ".2f", ".2f"])
    return sec
