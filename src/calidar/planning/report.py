"""The ``calidar plan`` report: the plan on a map, the predicted σ as a table and a picture, what
will not be determined and why, the suggested lines, and the simulations when asked. Renders
only."""

from __future__ import annotations


import numpy as np

from calidar.planning.findings import shown
from calidar.report import Report


def _map(doc: dict, terrain_image):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 6.5))
    if terrain_image is not None:
        img, extent = terrain_image
        im = ax.imshow(img, extent=extent, origin="lower", cmap="gist_earth", alpha=0.8)
        fig.colorbar(im, ax=ax, label="surface height [m]", shrink=0.8)
    half = np.tan(np.radians(doc["instrument"]["half_fov_deg"]))
    cmap = plt.get_cmap("tab10")
    for k, ln in enumerate(doc["lines"]):
        s, e = np.array(ln["start"]), np.array(ln["end"])
        d = (e - s) / np.linalg.norm(e - s)
        w = ln["height_agl_m"] * half * np.array([d[1], -d[0]])
        poly = np.array([s + w, e + w, e - w, s - w, s + w])
        c = cmap(k % 10)
        ax.fill(poly[:, 0], poly[:, 1], color=c, alpha=0.12)
        ax.annotate("", e, s, arrowprops=dict(arrowstyle="->", color=c, lw=2))
        ax.text(*s, f"{ln['line']} ({ln['height_agl_m']:g} m)", color=c, fontsize=9,
                ha="center", va="top")
    for sug in doc.get("suggestions", [])[:1]:
        s, e = np.array(sug["start"]), np.array(sug["end"])
        ax.annotate("", e, s, arrowprops=dict(arrowstyle="->", color="red", lw=2, ls="--"))
        ax.text(*e, "suggested", color="red", fontsize=9)
    ax.set(xlabel="east [m]", ylabel="north [m]",
           title="Planned lines (arrows: direction; shaded: swaths)")
    ax.set_aspect("equal", adjustable="datalim")
    fig.tight_layout()
    return fig


def _sigma_picture(doc: dict):
    """Each parameter's σ against what counts as determined, as bars (log scale, ≤ 10)."""
    import matplotlib.pyplot as plt

    rows = doc["parameters"]
    fig, ax = plt.subplots(figsize=(8, 0.6 + 0.5 * len(rows)))
    ratio = [r["ground_effect_m"] / r["limit_m"] if r["ground_effect_m"] is not None else 10.0
             for r in rows]
    colors = ["tab:green" if r["determined"] else "tab:red" for r in rows]
    ax.barh([r["parameter"] for r in rows], np.minimum(ratio, 10.0), color=colors)
    ax.axvline(1.0, color="k", ls="--", lw=1)
    ax.set(xlabel="predicted σ's effect on the ground / what counts as determined (2 cm angles, "
                  "1 cm lengths)", xscale="log")
    ax.invert_yaxis()
    fig.tight_layout()
    return fig


PREDICTED_HOW = (
    "Predicted before flying, from the tie planes the planned lines will share (sampled on the "
    "terrain at the scanner's density, not simulated point by point) and the same observation "
    "equations, weights and trajectory priors the strip adjustment (calidar boresight) uses: σ = "
    "√diag of the inverted normal matrix. A parameter is determined when its reported σ moves a "
    "point by at most 2 cm at the median range ({median_range_m:.0f} m), a length when its σ is at "
    "most 1 cm."
)
TWO_SIGMAS = (
    "Two σ per parameter: the one the calibration will report (N⁻¹ with its weights and priors; "
    "its verdict judges by it), and the expected error — the same estimator with the rows' real "
    "scatter (the points' noise: the surface's own unevenness lies under both patches of a tie "
    "plane and largely cancels, so on rough ground the reported σ of angles seen on slopes are "
    "conservative)."
)


def plan_report(doc: dict, pred, terrain_image=None, verdict=None, record=None) -> Report:
    """The report of a ``calidar plan`` run (``doc``: what plan.json holds); the pipeline writes
    it."""
    report = Report("calidar plan: predicted calibration of a planned flight")
    report.record = record
    if verdict is not None:
        report.add_verdict(verdict)
    _verdict_section(report, doc, terrain_image)
    _sigma_section(report, doc, pred)
    if doc.get("suggestions"):
        _suggestion_section(report, doc)
    if doc.get("simulation"):
        _simulation_section(report, doc, pred)
    return report


def _verdict_section(report: Report, doc: dict, terrain_image) -> None:
    """The headline, how it was predicted, the map and what the prediction assumed."""
    s = report.section("Verdict on the plan")
    (s.warning if doc["poor"] else s.text)(doc["headline"])
    s.text(PREDICTED_HOW.format(median_range_m=doc["median_range_m"]))
    s.figure(_map(doc, terrain_image), "The plan on the terrain")
    ins = doc["instrument"]
    n_planes = sum(p["tie_planes"] for p in doc["pairs"])
    s.table(["input", "value"], [
        ["terrain", doc["terrain"]], ["pulse rate", f"{ins['pulse_rate_hz']:g} Hz"],
        ["field of view", f"{2 * ins['half_fov_deg']:g}° (full)"],
        ["range / angle noise", f"{ins['range_noise_m'] * 100:g} cm / {ins['angle_noise_deg']:g}°"],
        ["trajectory accuracy", doc["trajectory"]], ["estimated", ", ".join(doc["estimate"])],
        ["tie planes", f"{n_planes} in {len(doc['pairs'])} overlapping pairs"],
    ], caption="What the prediction assumed")


def _sigma_section(report: Report, doc: dict, pred) -> None:
    """Per parameter: both σ, the ground effect, determined or not, why and what to fly."""
    from calidar.report.chart_picture import correlation_png

    s = report.section("Predicted σ")
    s.text(TWO_SIGMAS)
    rows = []
    for r in doc["findings"]:
        effect = r.get("ground_effect_m")
        moves = "" if effect is None else f"{effect * 100:.2f} cm"
        rows.append([r["parameter"], r.get("sigma", ""), r.get("error_sigma", ""), moves,
                     "yes" if r["determined"] else "NO", r.get("why", ""), r.get("action", "")])
    s.table(["parameter", "σ reported", "expected error σ", "moves a point by", "determined",
             "why not", "what to fly"], rows, caption="Per estimated parameter")
    s.figure(_sigma_picture(doc), "Each σ against what counts as determined (red: not determined)")
    if len(pred.names) > 1:
        corr = np.where(np.isfinite(pred.correlation), pred.correlation, np.nan)
        s.picture(correlation_png(corr, pred.names), "Predicted correlations")


def _suggestion_section(report: Report, doc: dict) -> None:
    """Each candidate line with the worst-determined parameter's σ now and with it."""
    s = report.section("Suggested lines")
    s.text("Each candidate added to the plan on its own; the worst-determined parameter's "
           "predicted σ with it (best first). The first is drawn dashed on the map.")
    rows = []
    for c in doc["suggestions"]:
        (x0, y0), (x1, y1) = c["start"], c["end"]
        line = f"({x0:.0f}, {y0:.0f}) → ({x1:.0f}, {y1:.0f}), {c['height_agl_m']:g} m"
        rows.append([c["kind"], line, c["parameter"],
                     shown(c["parameter"], c["unit"], c["sigma_before"]),
                     shown(c["parameter"], c["unit"], c["sigma_after"])])
    s.table(["candidate", "line (start → end, height)", "parameter", "σ now", "σ with it"], rows)


def _simulation_section(report: Report, doc: dict, pred) -> None:
    """The simulated surveys' RMS error against the predicted σ, per parameter."""
    sim = doc["simulation"]
    s = report.section("Confirmed by simulation")
    s.text(f"{sim['runs']} surveys of this plan simulated and calibrated end to end (true mounting "
           "errors drawn per survey): the RMS error against the truth beside the predicted σ (a "
           "ratio near 1 says the prediction holds; its sampling spread is "
           f"±{1 / np.sqrt(2 * sim['runs']):.2f}).")
    rows = []
    for n, u, p, r in zip(pred.names, pred.units, pred.sigma, pred.reported):
        rms = sim["rms_error"][n]
        rows.append([n, shown(n, u, r), shown(n, u, p), shown(n, u, rms), f"{rms / r:.2f}",
                     f"{rms / p:.2f}", shown(n, u, sim["mean_sigma"][n])])
    s.table(["parameter", "predicted σ (reported)", "expected error σ", "RMS error",
             "RMS / predicted σ", "RMS / expected error σ", "calibrations' mean σ"], rows)
