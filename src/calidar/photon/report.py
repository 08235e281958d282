"""Report section of a CCR calibration: it renders a :class:`calidar.photon.ccr.CCRResult` and
computes nothing (the fitted curves, the likelihood surface and the checks are in the result)."""

from __future__ import annotations

import numpy as np

from calidar.photon.parameters import GEOLOCATION

TITLE = "Photon lidar: CCR geolocation calibration"


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def add_section(report, result, truth: dict | None = None, title: str = TITLE):
    """Append the calibration section (verdict at the top of the report) to a
    :class:`calidar.report.Report`."""
    report.add_verdict(result.verdict, "CCR calibration")
    sec = report.section(title)
    _intro(sec, result)
    estimated = {k: v for k, v in (truth or {}).items() if k in result.solution.values}
    sec.solution(result.solution, estimated)
    _sigma_table(sec, result, truth)
    _surfaces(sec, result, truth)
    _method_tables(sec, result)
    _counts_figure(sec, result)
    _cloud_figure(sec, result)
    _plan_figure(sec, result)
    return sec


def _intro(sec, result) -> None:
    lay = result.layout
    beams = ", ".join(sorted({p.label for p in result.passes if p.group_key in lay.groups}))
    tracks = len({w.pass_name for w in result.windows})
    shared = "one along/cross bias shared by all beams" if lay.shared_bias else "one bias per beam"
    spots = " (named by laser spot)" if any(k.startswith("spot") for k in lay.groups) else ""
    sec.text(f"{len(result.estimate.segments)} lit CCR segments in {tracks} beam track(s); beams: "
             f"{beams}; {shared}{spots}. " + METHOD_TEXT)
    held = result.estimate.fit.at_limit
    if held:
        values = ", ".join(f"{n} = {result.solution.values[n]:g}" for n in held)
        sec.text("Held at a bound: " + values + " (a shot-loss rate held at 0: the counts show no "
                 "lost shots; a diameter at its search limit: see the verdict). The σ of the "
                 "others profile over what is held (not taken as known).")
    for w in result.warnings:
        sec.warning(w)


#: the method and its σ in words (the report's introduction)
METHOD_TEXT = ("Bias = true − reported footprint position (along-track positive in the direction"
               " of travel, cross-track positive to the left). The estimate is the maximum of "
               "the exact likelihood of every shot's CCR photon count (binomial over the "
               "detector channels, lost shots, pointing jitter, background), started from the "
               "published grid search; the CCR peak photons Λ and the shot-loss rate q are "
               "nuisance parameters. σ below: for the geolocation parameters the 95 % "
               "profile-likelihood interval's wider half / 1.96 (deviance level 3.84, or 4.61 "
               "with fewer than 4 lit CCRs: a small sample), for the others the observed "
               "information (inverse Hessian of −log L). The residuals are the solver's "
               "√(2·(−log P + ½)) per shot (their squares sum to 2·(−log L) + shots), not "
               "distances.")


def _sigma_table(sec, result, truth) -> None:
    u = result.uncertainty
    rows = []
    for n in u.names:
        iv = u.profile.get(n)
        t = (truth or {}).get(n)
        v = result.solution.values[n]
        interval = None
        if iv:
            interval = f"{iv.low:.3f} … {iv.high:.3f}"
            interval += " (open)" if iv.open_low or iv.open_high else ""
        rows.append([n, v, u.sigma(n), u.observed.get(n), u.bootstrap.get(n), u.cramer_rao.get(n),
                     interval, t, None if t is None else v - t])
    if u.bootstrap_values is not None:
        boot = (f"bootstrap: {u.bootstrap_values.shape[0]} parametric replicates re-solved by the "
                "same code")
        boot += f" ({u.bootstrap_failed} without an estimate)" if u.bootstrap_failed else ""
    else:
        boot = "bootstrap off"
    header = ["parameter", "value", "σ", "σ observed info", "σ bootstrap", "σ Cramér–Rao",
              "95 % profile interval", "truth", "error"]
    sec.table(header, rows,
              caption=f"σ reported and three ways (m for the geolocation parameters); {boot}")
    for note in u.disagreements():
        sec.warning(note)


def _surfaces(sec, result, truth) -> None:
    plt = _plt()
    for s in result.uncertainty.surfaces:
        fig, ax = plt.subplots(figsize=(6.2, 4.6))
        im = ax.pcolormesh(s.x, s.y, np.minimum(s.deviance, 30.0), shading="auto", cmap="viridis_r")
        ax.contour(s.x, s.y, s.deviance, levels=[2.30, 5.99], colors=["w", "w"],
                   linestyles=["--", "-"])
        v = result.solution.values
        ax.plot(v[s.x_name], v[s.y_name], "r+", ms=14, mew=2, label="estimate (maximum likelihood)")
        g = result.estimate.grids[s.group]
        ax.plot(g.cross_bias, g.diameter, "wx", ms=8, label="published grid search")
        if truth and s.x_name in truth and s.y_name in truth:
            ax.plot(truth[s.x_name], truth[s.y_name], "o", mfc="none", mec="orange", ms=10,
                    label="truth")
        ax.set_xlabel(f"{s.x_name} (m)")
        ax.set_ylabel(f"{s.y_name} (m)")
        ax.legend(fontsize=7, loc="upper right")
        fig.colorbar(im, ax=ax, label="2·Δ(−log L), profiled (cut at 30)")
        sec.figure(fig, "Likelihood surface over cross-track bias × footprint diameter (every "
                        "other parameter re-maximised): solid white = the 95 % joint region (χ²₂ "
                        "5.99), dashed = 68 % (2.30)")


def _method_tables(sec, result) -> None:
    header = ["grid search (published method)", "along-track bias", "cross-track bias",
              "footprint diameter", "along RMS", "cross RMS", "shot-loss rate"]
    for key, g in zip(result.layout.groups, result.estimate.grids):
        sec.table(header, [[key, g.along_bias, g.cross_bias, g.diameter, g.rms_along,
                            float(g.rms_cross.min()), g.loss_rate]])
    fits = {(f.pass_name, f.ccr_id): f for f in result.fits}
    rows = []
    for s in result.estimate.segments:
        w, f = s.window, fits[(s.window.pass_name, s.window.ccr_id)]
        rows.append([w.pass_name.split("/")[-1], w.ccr_id, w.x_ccr, w.y_ccr, w.pole_height,
                     s.n_shots, s.missing_shots, s.length, s.midpoint, f.detections, f.expected,
                     f.z])
    sec.table(["pass", "CCR", "x_ccr", "y_ccr", "pole", "shots", "missing", "length", "midpoint",
               "detections", "expected", "z"], rows,
              caption="CCR segments (m) and how each CCR's detecting shots compare with the "
              "fitted model (z = (observed − expected)/σ)")


def _counts_figure(sec, result) -> None:
    plt = _plt()
    fits = result.fits[:12]
    fig, axes = plt.subplots(1, len(fits), figsize=(2.2 * len(fits) + 1, 2.6), squeeze=False,
                             sharey=True)
    for ax, f in zip(axes[0], fits):
        w = next(w for w in result.windows if (w.pass_name, w.ccr_id) == (f.pass_name, f.ccr_id))
        ax.plot(w.shot_x, w.counts, ".", ms=3, color="tab:red")
        ax.plot(f.curve_x, f.curve_mean, "-", color="tab:orange", lw=1)
        ax.set_title(f.ccr_id, fontsize=8)
        ax.set_xlabel("x (m)")
    axes[0][0].set_ylabel("CCR photons per shot")
    sec.figure(fig, "CCR photons recorded per shot (red) and the fitted model's expectation "
                    "(orange)")


def _cloud_figure(sec, result) -> None:
    plt = _plt()
    p = result.passes[0]
    wins = [w for w in result.windows if w.pass_name == p.name]
    if not wins:
        return
    lo, hi = min(w.x_ccr for w in wins) - 30, max(w.x_ccr for w in wins) + 30
    m = (p.x >= lo) & (p.x <= hi)
    fig, ax = plt.subplots(figsize=(10, 3.5))
    ax.plot(p.x[m & ~p.signal], p.h[m & ~p.signal], ".", ms=1, color="0.7", label="noise")
    ax.plot(p.x[m & p.signal], p.h[m & p.signal], ".", ms=1, color="tab:blue", label="signal")
    for w in wins:
        ax.plot(p.x[w.photon_index], p.h[w.photon_index], ".", ms=3, color="tab:red")
    g = (p.ground_x >= lo) & (p.ground_x <= hi)
    ax.plot(p.ground_x[g], p.ground_h[g], "k-", lw=0.8, label="ground spline")
    ax.set_xlabel("along-track distance (m)")
    ax.set_ylabel("height (m)")
    ax.legend(loc="upper right", fontsize=7, markerscale=4)
    sec.figure(fig, f"{p.name}: photons near the CCRs (red: counted CCR photons)")


def _plan_figure(sec, result) -> None:
    plt = _plt()
    segs = [s for s in result.estimate.segments if s.window.pass_name == result.passes[0].name][:12]
    if not segs:
        return
    lay, v = result.layout, result.solution.values
    fig, axes = plt.subplots(1, len(segs), figsize=(2.2 * len(segs) + 1, 3), squeeze=False,
                             sharey=True)
    t = np.linspace(0, 2 * np.pi, 100)
    for ax, s in zip(axes[0], segs):
        g = s.window.group
        b_a, b_c, diam = (v[lay.name(g, n)] for n in GEOLOCATION)
        for xe in (s.first, s.last):  # the footprint's circle centred there
            ax.plot(xe + b_a + diam / 2 * np.cos(t), b_c + diam / 2 * np.sin(t), "-",
                    color="tab:orange", lw=0.8)
        ax.plot(s.shot_x + b_a, np.full(s.n_shots, b_c), "|", color="tab:red")
        ax.axhline(b_c, color="tab:orange", lw=0.6, ls="--")
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.plot(s.window.x_ccr, s.window.y_ccr, "k^")
        ax.set_title(s.window.ccr_id, fontsize=8)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
    axes[0][0].set_ylabel("cross-track y (m, left +)")
    sec.figure(fig, "Fitted footprints (orange) at the first and last shot that saw each CCR (▲); "
                    "grey: reported track, dashed: fitted footprint track")
