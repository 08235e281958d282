"""The report of ``calidar trajectory``: per line a map view, height, attitude and σ over time,
the plausibility table, what could not be determined, and (when a known trajectory is given)
the errors against it."""

from __future__ import annotations

import numpy as np

from calidar.report.html import Report
from calidar.trajrec.reconstruct import LineTrajectory
from calidar.trajrec.summary import line_summary, summary_rows


def _line_figure(ln: LineTrajectory):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = ln.time - ln.time[0]
    fig, ax = plt.subplots(2, 2, figsize=(11, 7))
    sc = ax[0, 0].scatter(ln.enu[:, 0], ln.enu[:, 1], c=t, s=2, cmap="viridis")
    ax[0, 0].set_aspect("equal", adjustable="datalim")
    ax[0, 0].set(title="map view (local east/north of the line's centre)", xlabel="east [m]",
                 ylabel="north [m]")
    fig.colorbar(sc, ax=ax[0, 0], label="time [s]")
    up, sigma_up = ln.enu[:, 2], ln.sigma[:, 2]
    ax[0, 1].plot(t, up, lw=1)
    ax[0, 1].fill_between(t, up - 2 * sigma_up, up + 2 * sigma_up, alpha=0.3, label="± 2σ")
    ax[0, 1].set(title="height above the line's centre", xlabel="time [s]", ylabel="up [m]")
    ax[0, 1].legend()
    att = np.degrees(ln.attitude)
    for k, name in enumerate(("roll", "pitch")):
        ax[1, 0].plot(t, att[:, k], lw=1, label=name)
    heading = np.unwrap(ln.attitude[:, 2])
    ax[1, 0].plot(t, np.degrees(heading) - np.degrees(np.mean(heading)), lw=1,
                  label="heading − mean")
    ax[1, 0].set(title="attitude", xlabel="time [s]", ylabel="deg")
    ax[1, 0].legend()
    for k, name in enumerate(("σ east", "σ north", "σ up")):
        ax[1, 1].semilogy(t, ln.sigma[:, k], lw=1, label=f"{name} [m]")
    for k, name in enumerate(("σ roll", "σ pitch", "σ heading"), 3):
        ax[1, 1].semilogy(t, np.degrees(ln.sigma[:, k]), lw=1, ls="--", label=f"{name} [°]")
    ax[1, 1].set(title="σ per epoch (from the fit)", xlabel="time [s]")
    ax[1, 1].legend(fontsize=7, ncol=2)
    fig.suptitle(f"line {ln.label}")
    fig.tight_layout()
    return fig


def trajectory_report(run, commands: list[str], comparison: dict | None = None) -> Report:
    """The report of a :class:`calidar.pipelines.trajectory.TrajectoryRun`."""
    rep = Report("calidar trajectory: the flight path reconstructed from the points")
    sec = rep.section("Summary")
    times = run.timings
    sec.text(f"{len(run.lines)} flight line(s) from {len(run.files)} file(s) "
             f"({run.counts['points_read']} points read; lines from {run.lines_from}). "
             f"Reading {times['read_s']:.2f} s, fitting {times['fit_s']:.2f} s.")
    header, rows, fmts = summary_rows([line_summary(ln) for ln in run.lines])
    sec.table(header, rows,
              "Each reconstructed line (heights ellipsoidal; σ: medians over the line)", fmts)
    for n in run.notes:
        sec.warning(n)
    sec.code("\n".join(commands), "Reproduce with:")
    sec.references(REFERENCES)
    if comparison:
        cs = rep.section("Against a known trajectory")
        rows = [[k, v["median"], v["p95"]] for k, v in comparison.items()
                if isinstance(v, dict) and "median" in v]
        cs.table(["quantity", "median", "95th percentile"], rows,
                 "|reconstructed − known| at the reconstructed epochs", [None, ".4g", ".4g"])
    for ln in run.lines:
        caption = f"line {ln.label}: map view, height with ± 2σ, attitude, σ per epoch"
        rep.section(f"Line {ln.label}").figure(_line_figure(ln), caption)
    return rep


REFERENCES = ["Gatziolis D., McGaughey R. J. (2019), Reconstructing aircraft trajectories from "
              "multi-return airborne laser-scanning data, Remote Sensing 11(19):2258.",
              "ASPRS LAS specification 1.4 R15: GPS time, return number, scan angle."]
