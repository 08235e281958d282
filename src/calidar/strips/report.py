"""The strip-calibration section of the HTML report (shared by ``calidar boresight`` and the demo)."""

from __future__ import annotations

import numpy as np

from calidar.report import Report
from calidar.report.plots import residual_histogram
from calidar.strips.calibrate import CalibrationResult
from calidar.strips.quality import PairQuality, QualitySettings, dz_figure, swath_difference
from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX


def pair_quality(result: CalibrationResult, settings: QualitySettings | None = None) -> list[tuple[PairQuality, PairQuality]]:
    """Swath differences of every overlapping pair before (delivered) and after calibration."""
    by_id = {s.id: s for s in result.strips}
    out = []
    for o in result.overlaps:
        a, b = by_id[o.a], by_id[o.b]
        before = swath_difference(o.a, a.points[o.index_a], o.b, b.points[o.index_b], settings)
        after = swath_difference(o.a, result.georeference(a, index=o.index_a), o.b,
                                 result.georeference(b, index=o.index_b), settings)
        out.append((before, after))
    return out


def add_report_section(report: Report, result: CalibrationResult, truth: dict[str, float] | None = None,
                       quality: list[tuple[PairQuality, PairQuality]] | None = None, title: str | None = None):
    """Add a section: parameters (with truth, SI dict, when given), residual histograms, per-pair quality."""
    sol = result.solution
    sec = report.section(title or f"Strip calibration ({result.method})")
    n_obs = result.outer[-1]["n_obs"] if result.outer else 0
    sec.text(f"{len(result.strips)} strips, {len(result.overlaps)} overlapping pairs, {len(result.pairs)} used; "
             f"{n_obs} observations ({'tie planes' if result.method == 'planes' else 'VGICP correspondences'}); "
             f"{len(result.outer)} outer iterations (re-matching), mean correspondence distance "
             + " → ".join(f"{o['mean_distance_m'] * 1e3:.1f}" for o in result.outer) + " mm.")
    sec.solution(sol, truth)
    sec.figure(residual_histogram(np.asarray(result.residuals_before), np.asarray(result.residuals_after)),
               "Correspondence residuals at the nominal sensor (first matching) and after calibration (last matching).")
    quality = pair_quality(result) if quality is None else quality
    f = lambda v: None if v is None else round(v, 4)  # noqa: E731
    rows = [[f"{b.a}–{b.b}", b.n_cells, f(b.median_dz_m), f(a.median_dz_m), f(b.rmsdz_m), f(a.rmsdz_m),
             f(b.dx_m), f(a.dx_m), f(b.dy_m), f(a.dy_m)] for b, a in quality]
    sec.table(["pair", "cells", "median dz before", "after", "RMSDz before", "after", "dx before", "after",
               "dy before", "after"], rows,
              "Swath-overlap differences dz = a − b on smooth gentle surfaces, and planimetric offsets from "
              "sloped planes (m; — where the slopes cannot determine them).")
    if quality:
        worst = max(range(len(quality)), key=lambda i: quality[i][0].rmsdz_m or 0.0)
        b, a = quality[worst]
        lim = float(np.nanpercentile(np.abs(b.grid), 98)) if np.isfinite(b.grid).any() else None
        sec.figure(dz_figure(b, lim), f"Pair {b.a}–{b.b} before calibration (the pair with the largest RMSDz).")
        sec.figure(dz_figure(a, lim), f"Pair {a.a}–{a.b} after calibration, same colour scale.")
    return sec


def add_comparison_section(report: Report, results: dict[str, CalibrationResult], truth: dict[str, float] | None = None):
    """A section comparing the same calibration by several methods: per parameter each value ± σ,
    the difference of the first two in units of their combined σ, and the truth when known."""
    (ma, ra), (mb, rb) = list(results.items())[:2]
    sec = report.section(f"{ma} and {mb} compared")
    va, vb, sa, sb = ra.solution.values, rb.solution.values, ra.solution.sigma, rb.solution.sigma
    rows = []
    for p in ra.solution.parameters.free:
        if p.name.startswith(TRAJECTORY_PREFIX) or p.name not in sb:
            continue
        d = va[p.name] - vb[p.name]
        both = np.hypot(sa[p.name], sb[p.name])
        row = [p.name, p.display_unit, f"{p.to_display(va[p.name]):.6g} ± {p.to_display(sa[p.name]):.2g}",
               f"{p.to_display(vb[p.name]):.6g} ± {p.to_display(sb[p.name]):.2g}", f"{p.to_display(d):.3g}",
               f"{abs(d) / both:.2f}" if both > 0 else None]
        if truth and p.name in truth:
            row += [p.to_display(truth[p.name]), p.to_display(va[p.name] - truth[p.name]),
                    p.to_display(vb[p.name] - truth[p.name])]
        rows.append(row)
    header = ["parameter", "unit", f"{ma} (± σ)", f"{mb} (± σ)", f"{ma} − {mb}", "|difference| / combined σ"]
    if truth:
        header += ["truth", f"{ma} error", f"{mb} error"]
    sec.table(header, rows, "The two solutions use the same strips and model; a difference well beyond 3 combined σ "
              "means one method's correspondences are biased (for example tie planes on vegetation or VGICP pairs "
              "on edges).")

    def seconds(r, key):
        return sum(o.get(key, 0.0) for o in r.outer)

    sec.table(["method", "observations", "outer iterations", "georeference (s)", "match (s)", "solve (s)",
               "RMS residual after (m)"],
              [[m, r.outer[-1]["n_obs"], len(r.outer), round(seconds(r, "georeference_s"), 2),
                round(seconds(r, "match_s"), 2), round(seconds(r, "solve_s"), 2),
                r.solution.residuals_after.get("rms")] for m, r in results.items()])
    return sec
