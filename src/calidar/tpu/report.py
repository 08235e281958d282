"""The ``calidar tpu`` report: per file the THU/TVU percentiles, TVU by scan angle, a map and
histograms of a sample of the points. Renders only."""

from __future__ import annotations


import numpy as np

from calidar.report import Report


def _figures(results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    for r in results:
        s = r.sample
        axes[0].hist(s["thu"] * 100, bins=60, histtype="step", label=r.path.name)
        axes[1].hist(s["tvu"] * 100, bins=60, histtype="step", label=r.path.name)
        axes[2].scatter(s["xy"][:, 0], s["xy"][:, 1], c=s["tvu"] * 100, s=0.3, cmap="viridis",
                        vmin=np.percentile(np.concatenate([q.sample["tvu"] for q in results]) * 100, 1),
                        vmax=np.percentile(np.concatenate([q.sample["tvu"] for q in results]) * 100, 99))
    axes[0].set(xlabel="total horizontal uncertainty THU, 1σ [cm]", ylabel="points (sample)")
    axes[1].set(xlabel="total vertical uncertainty TVU, 1σ [cm]")
    axes[2].set(xlabel="x [CRS units]", ylabel="y", title="TVU [cm] (1 %–99 % colour range)")
    axes[2].set_aspect("equal", adjustable="datalim")
    fig.colorbar(axes[2].collections[0], ax=axes[2])
    if len(results) <= 8:
        axes[0].legend(fontsize=7)
    fig.tight_layout()
    return fig


def tpu_report(results, doc: dict) -> Report:
    """The report of a ``calidar tpu`` run (``doc``: what tpu.json holds); the pipeline writes it."""
    report = Report("calidar tpu: per-point uncertainty")
    s = report.section("Per-point uncertainty (TPU)")
    s.text("Each point's horizontal (THU, radial: √(σ_east² + σ_north²)) and vertical (TVU) 1σ, propagated "
           "through the lidar equation from the trajectory's accuracy, the range and encoder noise, the beam's "
           "footprint on the local surface" + (" and the calibration's covariance" if doc["calibration"] else "")
           + " (Glennie 2007). Written into each file as the extra bytes total_thu and total_tvu, in metres.")
    if doc.get("accuracy_note"):
        s.warning(doc["accuracy_note"])
    a = doc["accuracy"]["median"]
    st = doc["settings"]
    s.table(["input", "value"], [
        ["trajectory accuracy", f"{doc['accuracy']['source']}: position σ N/E/D {a['north_rms_m'] * 100:.1f}/"
         f"{a['east_rms_m'] * 100:.1f}/{a['down_rms_m'] * 100:.1f} cm, attitude σ roll/pitch/heading "
         f"{a['roll_rms_deg']:.4f}/{a['pitch_rms_deg']:.4f}/{a['heading_rms_deg']:.4f}°"],
        ["range noise σ", f"{st['range_sigma_m'] * 100:.2f} cm"],
        ["encoder angle σ", f"{np.degrees(st['angle_sigma_rad']):.4f}°"],
        ["beam divergence", f"{st['beam_divergence_rad'] * 1e3:.3f} mrad (full angle)"],
        ["calibration covariance", "none given" if not doc["calibration"] else
         f"{doc['calibration']['file']}: {', '.join(doc['calibration']['parameters'])}"],
    ], caption="What was propagated")
    rows = [[r.path.name, r.n_points, r.thu["median"] * 100, r.thu["p95"] * 100, r.tvu["median"] * 100,
             r.tvu["p95"] * 100, r.tvu["max"] * 100] for r in results]
    s.table(["file", "points", "THU median [cm]", "THU 95 % [cm]", "TVU median [cm]", "TVU 95 % [cm]", "TVU max [cm]"],
            rows, caption="Per file (percentiles of a sample of up to 100 000 points)",
            formats=[None, None, ".2f", ".2f", ".2f", ".2f", ".2f"])
    bins = [[r.path.name, f"{b['scan_angle_deg'][0]:.0f}–{b['scan_angle_deg'][1]:.0f}°", b["median"] * 100,
             b["p95"] * 100] for r in results for b in r.tvu_by_scan_angle]
    if bins:
        s.table(["file", "|scan angle|", "TVU median [cm]", "TVU 95 % [cm]"], bins, caption="TVU by scan angle",
                formats=[None, None, ".2f", ".2f"])
    s.figure(_figures(results), "THU and TVU of a sample of the points, and TVU on a map")
    return report
