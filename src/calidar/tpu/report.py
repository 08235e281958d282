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
    tvu_cm = np.concatenate([q.sample["tvu"] for q in results]) * 100
    vmin, vmax = np.percentile(tvu_cm, 1), np.percentile(tvu_cm, 99)
    for r in results:
        s = r.sample
        axes[0].hist(s["thu"] * 100, bins=60, histtype="step", label=r.path.name)
        axes[1].hist(s["tvu"] * 100, bins=60, histtype="step", label=r.path.name)
        axes[2].scatter(s["xy"][:, 0], s["xy"][:, 1], c=s["tvu"] * 100, s=0.3, cmap="viridis",
                        vmin=vmin, vmax=vmax)
    axes[0].set(xlabel="total horizontal uncertainty THU, 1σ [cm]", ylabel="points (sample)")
    axes[1].set(xlabel="total vertical uncertainty TVU, 1σ [cm]")
    axes[2].set(xlabel="x [CRS units]", ylabel="y", title="TVU [cm] (1 %–99 % colour range)")
    axes[2].set_aspect("equal", adjustable="datalim")
    fig.colorbar(axes[2].collections[0], ax=axes[2])
    if len(results) <= 8:
        axes[0].legend(fontsize=7)
    fig.tight_layout()
    return fig


def _inputs_rows(doc: dict) -> list[list[str]]:
    """The "What was propagated" table: the trajectory's median σ, the sensor's noise, the
    calibration's covariance (``doc``: what tpu.json holds)."""
    a = doc["accuracy"]["median"]
    st = doc["settings"]
    position = "/".join(f"{a[f'{axis}_rms_m'] * 100:.1f}" for axis in ("north", "east", "down"))
    attitude = "/".join(f"{a[f'{axis}_rms_deg']:.4f}" for axis in ("roll", "pitch", "heading"))
    cal = doc["calibration"]
    return [
        ["trajectory accuracy", f"{doc['accuracy']['source']}: position σ N/E/D {position} cm, "
         f"attitude σ roll/pitch/heading {attitude}°"],
        ["range noise σ", f"{st['range_sigma_m'] * 100:.2f} cm"],
        ["encoder angle σ", f"{np.degrees(st['angle_sigma_rad']):.4f}°"],
        ["beam divergence", f"{st['beam_divergence_rad'] * 1e3:.3f} mrad (full angle)"],
        ["calibration covariance",
         f"{cal['file']}: {', '.join(cal['parameters'])}" if cal else "none given"],
    ]


def _per_file_tables(s, results) -> None:
    """The THU/TVU percentiles per file (cm) and TVU by |scan angle|."""
    rows = []
    for r in results:
        cm = [r.thu["median"], r.thu["p95"], r.tvu["median"], r.tvu["p95"], r.tvu["max"]]
        rows.append([r.path.name, r.n_points] + [v * 100 for v in cm])
    header = ["file", "points", "THU median [cm]", "THU 95 % [cm]", "TVU median [cm]",
              "TVU 95 % [cm]", "TVU max [cm]"]
    s.table(header, rows, caption="Per file (percentiles of a sample of up to 100 000 points)",
            formats=[None, None, ".2f", ".2f", ".2f", ".2f", ".2f"])
    bins = [[r.path.name, "{:.0f}–{:.0f}°".format(*b["scan_angle_deg"]), b["median"] * 100,
             b["p95"] * 100] for r in results for b in r.tvu_by_scan_angle]
    if bins:
        s.table(["file", "|scan angle|", "TVU median [cm]", "TVU 95 % [cm]"], bins,
                caption="TVU by scan angle", formats=[None, None, ".2f", ".2f"])


def tpu_report(results, doc: dict) -> Report:
    """The report of a ``calidar tpu`` run (``doc``: what tpu.json holds); pipelines write it."""
    report = Report("calidar tpu: per-point uncertainty")
    s = report.section("Per-point uncertainty (TPU)")
    calibration = " and the calibration's covariance" if doc["calibration"] else ""
    s.text("Each point's horizontal (THU, radial: √(σ_east² + σ_north²)) and vertical (TVU) 1σ, "
           "propagated through the lidar equation from the trajectory's accuracy, the range and "
           f"encoder noise, the beam's footprint on the local surface{calibration} (Glennie 2007). "
           "Written into each file as the extra bytes total_thu and total_tvu, in metres.")
    if doc.get("accuracy_note"):
        s.warning(doc["accuracy_note"])
    s.table(["input", "value"], _inputs_rows(doc), caption="What was propagated")
    _per_file_tables(s, results)
    s.figure(_figures(results), "THU and TVU of a sample of the points, and TVU on a map")
    return report
