"""The sections of the ``calidar accuracy`` report: the statement and statistics, the residual map
and histogram, where the error is (flight lines, checkpoints), the checkpoint table, the method."""

from __future__ import annotations

import numpy as np

from calidar.accuracy.asprs import (LEGACY_95_FACTOR, MIN_NVA_CHECKPOINTS, OUTLIER_FACTOR,
                                    class_name)
from calidar.accuracy.usgs import usgs_section
from calidar.accuracy.verdict import disagreeing_strips, tilted_strips

REFERENCES = [
    "ASPRS Positional Accuracy Standards for Digital Geospatial Data, Edition 2, Version 1.0 "
    "(American Society for Photogrammetry and Remote Sensing, August 2023).",
    "Q. Abdullah, The ASPRS Positional Accuracy Standards, Edition 2: the geospatial mapping "
    "industry guide to best practices, Photogrammetric Engineering & Remote Sensing 89(10), "
    "581–588, 2023.",
    "H. K. Heidemann, Lidar Base Specification, U.S. Geological Survey Techniques and Methods "
    "11-B4 (current revision).",
]
WHAT_TO_DO = (
    "What to do when the class is not met: a bias common to all checkpoints (mean ≫ its standard "
    "error) is a vertical offset of the block — check the vertical datum and geoid of points and "
    "checkpoints, then a range offset, vertical lever arm or vertical trajectory bias, which the "
    "strip overlaps cannot see. Flight lines whose own surfaces depart in opposite directions point"
    " to the mounting: calibrate it (calidar boresight) and re-georeference (calidar regeoref). "
    "Errors grouped in one area or one line point to the trajectory there. Scattered large "
    "residuals point to the checkpoints or the ground classification."
)
METHOD = (
    "At each checkpoint the ground surface is the linear interpolation in the triangle of a TIN "
    "(Delaunay) of the ground points around it that contains the checkpoint, as the ASPRS and USGS "
    "procedures test lidar; dz = surface − checkpoint. Outliers (|dz| > {factor:g} × "
    "RMSE_V(data)) are listed and kept. Points used per file:"
)


def _cm(v) -> float | None:
    return None if v is None else 100.0 * v


def residual_figure(a):
    """Map of the residuals at the checkpoints (NVA circles, VVA triangles, unused crosses, outliers
    ringed) beside the histogram of the NVA and VVA residuals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, hx) = plt.subplots(1, 2, figsize=(12, 5), gridspec_kw={"width_ratios": [1.25, 1]})
    xy, dz = a.xyz[:, :2] - a.xyz[:, :2].min(axis=0), a.dz * 100
    used = a.used
    lim = max(float(np.nanmax(np.abs(dz))) if used.any() else 1.0, 1e-3)
    for mask, marker, label in ((a.nva, "o", "non-vegetated"), (a.vva, "^", "vegetated")):
        sc = ax.scatter(xy[mask, 0], xy[mask, 1], c=dz[mask], cmap="RdBu_r", vmin=-lim, vmax=lim,
                        marker=marker, s=70, edgecolors="k", linewidths=0.5, label=label)
    ax.scatter(xy[~used, 0], xy[~used, 1], marker="x", c="0.4", s=50, label="not tested")
    out = a.outliers()
    ax.scatter(xy[out, 0], xy[out, 1], facecolors="none", edgecolors="m", s=260, linewidths=1.5,
               label="outlier")
    for i in range(len(xy)):
        ax.annotate(str(a.checkpoints.ids[i]), xy[i], fontsize=6, xytext=(3, 3),
                    textcoords="offset points")
    fig.colorbar(sc, ax=ax, label="dz = surface − checkpoint [cm]")
    ax.set(xlabel="x − min [m]", ylabel="y − min [m]", title="Residuals at the checkpoints",
           aspect="equal")
    ax.legend(fontsize=7, loc="best")
    bins = np.linspace(-lim, lim, 25)
    hx.hist([dz[a.nva], dz[a.vva]], bins=bins, stacked=True, label=["non-vegetated", "vegetated"],
            color=["#3b7dd8", "#5aa05a"])
    acc = a.accuracy
    if acc.rmse_data_m is not None:
        for s in (-1, 1):
            hx.axvline(s * acc.rmse_data_m * 100, color="k", ls="--", lw=1)
        hx.axvline(acc.mean_m * 100, color="r", lw=1, label=f"mean {acc.mean_m * 100:+.1f} cm")
    hx.set(xlabel="dz [cm]", ylabel="checkpoints", title="Histogram (dashed: ± RMSE_V(data))")
    hx.legend(fontsize=7)
    fig.tight_layout()
    return fig


def _statistics(sec, a) -> None:
    """The table of ASPRS Edition 2 statistics (cm), each with a note on how it is computed."""
    acc = a.accuracy
    iv = acc.rmse_interval_m or (None, None)
    interval = None if iv[0] is None else f"{iv[0] * 100:.2f} … {iv[1] * 100:.2f}"
    accuracy_class = None if acc.class_cm is None else class_name(acc.class_cm)
    rows = [["NVA checkpoints tested", acc.n_nva, f"Edition 2 minimum {MIN_NVA_CHECKPOINTS}"],
            ["RMSE_V(data) [cm]", _cm(acc.rmse_data_m), "sqrt(Σdz²/n) over the NVA checkpoints"],
            ["  95 % interval [cm]", interval, "χ²_n: n·RMSE²/ρ² for normal errors"],
            ["RMSE_V(survey) [cm]", _cm(acc.rmse_survey_m), a.survey_source],
            ["RMSE_V = RMSEz reported [cm]", _cm(acc.rmse_m), "sqrt(data² + survey²), Edition 2"],
            ["accuracy class", accuracy_class, "smallest X with RMSE_V ≤ X"],
            ["legacy 95 % (1.96 × RMSEz) [cm]", _cm(acc.legacy95_m),
             f"NSSDA, older contracts ({LEGACY_95_FACTOR})"],
            ["mean dz [cm]", _cm(acc.mean_m), "bias"],
            ["standard deviation [cm]", _cm(acc.std_m), "n − 1"],
            ["standard error of the mean [cm]", _cm(acc.sdom_m), "std/√n"],
            ["VVA checkpoints tested", acc.n_vva, ""],
            ["VVA 95th percentile |dz| [cm]", _cm(acc.vva95_m),
             "reported, no pass/fail (Edition 2)"],
            ["VVA RMSE [cm]", _cm(acc.vva_rmse_m), ""]]
    sec.table(["statistic", "value", "note"],
              [[r[0], f"{r[1]:.2f}" if isinstance(r[1], float) else r[1], r[2]] for r in rows])


def _slope_text(e) -> str | None:
    """A flight line's dz against scan angle, mm/° ± σ (None when not fitted)."""
    if e.slope_m_per_deg is None:
        return None
    return f"{e.slope_m_per_deg * 1000:+.2f} ± {e.slope_sigma_m_per_deg * 1000:.2f}"


def _line_table(sec, a) -> None:
    """Each flight line's own TIN at the NVA checkpoints: mean, RMSE (cm), slope, finding."""
    bad = {e.point_source_id for e in disagreeing_strips(a)}
    tilted = {e.point_source_id for e in tilted_strips(a)}
    rows = []
    for e in a.strip_errors:
        flagged = (("mean differs", bad), ("tilted", tilted))
        found = [t for t, lines in flagged if e.point_source_id in lines]
        rows.append([e.point_source_id, e.n, e.mean_m * 100, e.rmse_m * 100, _slope_text(e),
                     ", ".join(found)])
    header = ["flight line", "NVA checkpoints", "mean dz [cm]", "RMSE [cm]",
              "dz / scan angle [mm/°]", "finding"]
    sec.table(header, rows,
              "Each flight line's own ground TIN against the NVA checkpoints it covers",
              formats=[None, "d", "+.2f", ".2f", None, None])


def _where(rep, a) -> None:
    """Where the error is: the flight lines' table, the largest NVA residuals, what to do."""
    sec = rep.section("Where the error is")
    if a.strip_errors:
        _line_table(sec, a)
    if a.accuracy.rmse_m is None:
        return
    worst = [i for i in np.argsort(-np.abs(np.nan_to_num(a.dz))) if a.nva[i]][:8]
    rows = [[str(a.checkpoints.ids[i]), a.xyz[i, 0], a.xyz[i, 1], a.dz[i] * 100,
             ", ".join(map(str, a.heights.strips[i]))] for i in worst]
    sec.table(["checkpoint", "x", "y", "dz [cm]", "flight lines"], rows,
              "The largest NVA residuals", formats=[None, ".2f", ".2f", "+.2f", None])
    sec.text(WHAT_TO_DO)


def add_sections(rep, a) -> None:
    """The sections of the accuracy report for an :class:`calidar.accuracy.assess.Assessment`."""
    sec = rep.section("Vertical accuracy (ASPRS Positional Accuracy Standards, Edition 2)")
    sec.text(a.accuracy.statement() + ".")
    _statistics(sec, a)
    rep.section("Residual map and histogram").figure(
        residual_figure(a), "dz = TIN surface − checkpoint height; outliers: |dz| > 3 × "
                            "RMSE_V(data), kept in the statistics")
    _where(rep, a)
    usgs_section(rep, a)
    _checkpoint_table(rep.section("Checkpoints"), a)
    sec = rep.section("Method")
    sec.text(METHOD.format(factor=OUTLIER_FACTOR))
    sec.table(["file", "points used"], [[str(k), s.describe()] for k, s in a.selections.items()])
    sec.references(REFERENCES)


def _checkpoint_table(sec, a) -> None:
    """One row per checkpoint: where it is, its σ, the surface there and dz (cm), the TIN."""
    rows = []
    for r in a.rows():
        note = "outlier" if r["outlier"] else (r["not_used"] or "")
        rows.append([r["id"], r["line"], r["cover"], r["x"], r["y"], r["z"], _cm(r["sigma_m"]),
                     r["surface_z"], _cm(r["dz_m"]), r["ground_points"], r["triangle_edge_m"],
                     ", ".join(map(str, r["strips"])), note])
    header = ["id", "line", "cover", "x", "y", "z", "σ [cm]", "surface z", "dz [cm]", "ground pts",
              "edge [m]", "lines", "note"]
    sec.table(header, rows, formats=[None, "d", None, ".3f", ".3f", ".3f", ".1f", ".3f", "+.2f",
                                     "d", ".2f", None, None])
