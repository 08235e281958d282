"""Report section of a CCR calibration: photon cloud, CCR segments, fitted footprints, RMS surface."""

from __future__ import annotations

import numpy as np

from calidar.photon.ccr import PARAMETERS, CCRResult, mean_ccr_photons


def add_section(report, result: CCRResult, truth: dict | None = None, title: str = "Photon lidar: CCR geolocation calibration"):
    """Append the calibration section to a :class:`calidar.report.Report` (truth in m, optional)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sec = report.section(title)
    sol = result.solution
    sec.text(
        f"{len(result.segments)} CCR segments from {len(result.passes)} pass(es). Bias = true − reported footprint "
        "position (along-track positive in the direction of travel, cross-track positive to the left). "
        f"σ: {sol.extra['sigma_source']}. Shot-loss rate inside the segments: {result.loss_rate:.1%}."
    )
    sec.solution(sol, {k: truth[k] for k in PARAMETERS} if truth else None)
    sec.text("The grid search below is the published method (chords and midpoints); the values above refine it by "
             "least squares on every shot's CCR photon count (Gaussian footprint energy blurred by the pointing jitter, "
             "Poisson photons, one photon per detector channel, background), with the CCR peak photon rate and the "
             "shot-loss rate as nuisance parameters.")
    crb = sol.extra["cramer_rao_sigma"]
    sec.text("Cramér–Rao bound at the estimate (the smallest σ any unbiased estimate from these shots can have): "
             + ", ".join(f"{k} {crb[k]:.2f} m" for k in PARAMETERS) + ".")
    g = result.grid
    sec.table(["grid search (method)", "along-track bias", "cross-track bias", "footprint diameter", "min RMS"],
              [["value (m)", g.along_bias, g.cross_bias, g.diameter, float(g.total.min())]])
    d_l = sol.extra["system"]["shot_spacing_m"]
    sec.table(["pass", "CCR", "x_ccr", "y_ccr", "photons", "shots", "missing", "length", "chord", "midpoint", "side"],
              [[s.pass_name.split("/")[-1], s.ccr_id, s.x_ccr, s.y_ccr, int(s.photon_index.size), s.n_shots,
                s.missing_shots(d_l), s.length, float(c), s.midpoint, "left" if side > 0 else "right"]
               for s, c, side in zip(result.segments, result.chords, g.sides)],
              caption="CCR segments (m); side = which side of the fitted footprint track the CCR lies on")

    # photon cloud around the CCRs of the first pass
    p = result.passes[0]
    segs = [s for s in result.segments if s.pass_name == p.name]
    lo = min(s.x_ccr for s in segs) - 30
    hi = max(s.x_ccr for s in segs) + 30
    m = (p.x >= lo) & (p.x <= hi)
    fig, ax = plt.subplots(figsize=(10, 3.5))
    ax.plot(p.x[m & ~p.signal], p.h[m & ~p.signal], ".", ms=1, color="0.7", label="noise")
    ax.plot(p.x[m & p.signal], p.h[m & p.signal], ".", ms=1, color="tab:blue", label="signal")
    for s in segs:
        ax.plot(p.x[s.photon_index], p.h[s.photon_index], ".", ms=3, color="tab:red")
    xs = np.linspace(lo, hi, 400)
    ax.plot(xs, p.ground(xs), "k-", lw=0.8, label="ground spline")
    ax.set_xlabel("along-track distance (m)")
    ax.set_ylabel("height (m)")
    ax.legend(loc="upper right", fontsize=7, markerscale=4)
    sec.figure(fig, "Photon cloud near the CCRs (red: CCR segment photons)")

    # plan view: CCRs, fitted footprint track, footprints at the segment ends
    v = sol.values
    b_a, b_c, diam = v["along_track_bias"], v["cross_track_bias"], v["footprint_diameter"]
    fig, axes = plt.subplots(1, len(segs), figsize=(2.2 * len(segs) + 1, 3), squeeze=False, sharey=True)
    t = np.linspace(0, 2 * np.pi, 100)
    for ax, s in zip(axes[0], segs):
        for xe in (s.first, s.last):
            ax.plot(xe + b_a + diam / 2 * np.cos(t), b_c + diam / 2 * np.sin(t), "-", color="tab:orange", lw=0.8)
        ax.plot(s.shot_x + b_a, np.full(s.n_shots, b_c), "|", color="tab:red")
        ax.axhline(b_c, color="tab:orange", lw=0.6, ls="--")
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.plot(s.x_ccr, s.y_ccr, "k^")
        ax.set_title(s.ccr_id, fontsize=8)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
    axes[0][0].set_ylabel("cross-track y (m, left +)")
    sec.figure(fig, "Fitted footprints (orange) at the first and last shot that saw each CCR (▲); "
                    "grey: reported track, dashed: fitted footprint track")

    # per-shot CCR photon counts against the fitted footprint model
    fig, axes = plt.subplots(1, len(segs), figsize=(2.2 * len(segs) + 1, 2.6), squeeze=False, sharey=True)
    n_ch = sol.extra["system"]["channels"]
    jitter = sol.extra["system"]["pointing_jitter_m"]
    for ax, s in zip(axes[0], segs):
        xm = np.linspace(s.window_x.min(), s.window_x.max(), 300)
        lam = mean_ccr_photons(xm, s.x_ccr, s.y_ccr, v, jitter)
        ax.plot(s.window_x, s.window_counts, ".", ms=3, color="tab:red")
        ax.plot(xm, (1 - v["shot_loss_rate"]) * n_ch * -np.expm1(-lam / n_ch) + s.background, "-", color="tab:orange",
                lw=1)
        ax.set_title(s.ccr_id, fontsize=8)
        ax.set_xlabel("x (m)")
    axes[0][0].set_ylabel("CCR photons per shot")
    sec.figure(fig, "CCR photons recorded per shot (red) and the fitted expectation (orange)")

    fig, ax = plt.subplots(figsize=(6, 4))
    im = ax.pcolormesh(g.cross_biases, g.diameters, g.total, shading="auto", cmap="viridis",
                       vmax=np.percentile(g.total, 60))
    ax.plot(g.cross_bias, g.diameter, "r+", ms=12, label="grid minimum")
    ax.plot(b_c, diam, "wx", ms=8, label="least squares")
    if truth:
        ax.plot(truth["cross_track_bias"], truth["footprint_diameter"], "o", mfc="none", mec="w", label="truth")
    ax.set_xlabel("cross-track bias (m)")
    ax.set_ylabel("footprint diameter (m)")
    ax.legend(fontsize=7)
    fig.colorbar(im, ax=ax, label="along RMS + cross RMS (m)")
    sec.figure(fig, "RMS surface of the grid search over footprint diameter and cross-track bias")
    return sec
