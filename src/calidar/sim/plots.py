"""Report figures of a simulated survey: coverage map, point density, trajectory."""

from __future__ import annotations

import numpy as np

from calidar.report import plots as _plots  # noqa: F401  (selects the Agg backend)

import matplotlib.pyplot as plt  # noqa: E402


def _enu_points(result, max_points: int = 200_000):
    """Delivered points of every strip in the scene's ENU frame (subsampled), with strip numbers."""
    n = result.n_points
    step = max(1, n // max_points)
    pts, ids = [], []
    for s in result.strips:
        p = result.scene.ecef_to_enu(s.ecef[::step])
        pts.append(p)
        ids.append(np.full(len(p), s.line.number))
    return np.concatenate(pts), np.concatenate(ids)


def coverage_map(result):
    """Terrain heights with building roofs, tree crowns, strip footprints and the trajectory."""
    sc = result.scene
    xmin, xmax, ymin, ymax = sc.extent
    fig, ax = plt.subplots(figsize=(8.5, 7))
    im = ax.imshow(sc.heights, origin="lower", extent=(xmin, xmax, ymin, ymax), cmap="terrain", alpha=0.85)
    fig.colorbar(im, ax=ax, label="terrain height (ENU up) [m]", shrink=0.8)
    roofs = np.flatnonzero(sc.plane_is_roof[sc.tri_plane]) if sc.tri.size else []
    for k in roofs:
        ax.fill(sc.tri[k, :, 0], sc.tri[k, :, 1], color="firebrick", lw=0)
    if sc.tree_radius.size:
        ax.scatter(sc.tree_center[:, 0], sc.tree_center[:, 1], s=(sc.tree_radius / (xmax - xmin) * 500) ** 2,
                   color="darkgreen", alpha=0.5, lw=0)
    pts, ids = _enu_points(result, 60_000)
    colors = plt.cm.tab10(np.arange(len(result.strips)) % 10)
    for k, s in enumerate(result.strips):
        m = ids == s.line.number
        ax.scatter(pts[m, 0], pts[m, 1], s=0.3, color=colors[k], alpha=0.25, lw=0)
    p = result.scene.ecef_to_enu(result.trajectory_true.ecef[::20])
    ax.plot(p[:, 0], p[:, 1], "k-", lw=0.8, label="trajectory")
    for k, ln in enumerate(result.lines):
        ax.annotate("", xy=ln.end, xytext=ln.start, arrowprops=dict(arrowstyle="->", color=colors[k], lw=2))
        ax.text(*ln.start, f" {ln.number}", color="k", fontsize=9, weight="bold")
    pad = 0.15 * max(xmax - xmin, ymax - ymin)
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymin - pad, ymax + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_title("Scene (roofs red, crowns green), strips (colours) and flight lines")
    ax.legend(loc="upper right")
    return fig


def density_map(result, cell_m: float | None = None):
    """Points per m² (all strips, all returns) on a grid."""
    sc = result.scene
    xmin, xmax, ymin, ymax = sc.extent
    cell_m = cell_m or max((xmax - xmin) / 150, 1.0)
    nx, ny = int((xmax - xmin) / cell_m), int((ymax - ymin) / cell_m)
    count = np.zeros((ny, nx))
    for s in result.strips:
        p = sc.ecef_to_enu(s.ecef)
        h, _, _ = np.histogram2d(p[:, 1], p[:, 0], bins=(ny, nx), range=((ymin, ymax), (xmin, xmax)))
        count += h
    dens = count / cell_m**2
    fig, ax = plt.subplots(figsize=(8.5, 6.5))
    vmax = np.percentile(dens[dens > 0], 99) if np.any(dens > 0) else 1.0
    im = ax.imshow(dens, origin="lower", extent=(xmin, xmax, ymin, ymax), cmap="viridis", vmin=0, vmax=vmax)
    fig.colorbar(im, ax=ax, label="points per m²", shrink=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    covered = dens[dens > 0]
    ax.set_title(f"Point density ({cell_m:.3g} m cells): median {np.median(covered):.3g} pts/m² where covered")
    return fig


def trajectory_plot(result):
    """Roll, pitch, heading, speed and height of the true trajectory over time; scan windows shaded."""
    tr = result.trajectory_true
    t = tr.time - tr.time[0]
    speed = np.linalg.norm(tr.velocity_ned, axis=1)
    fig, axes = plt.subplots(5, 1, figsize=(9, 9), sharex=True)
    series = [(np.degrees(tr.roll), "roll [°]"), (np.degrees(tr.pitch), "pitch [°]"),
              (np.degrees(np.unwrap(tr.heading)), "heading [°]"), (speed, "speed [m/s]"), (tr.height, "height [m]")]
    for ax, (y, label) in zip(axes, series):
        ax.plot(t, y, lw=0.7)
        ax.set_ylabel(label)
        for s in result.strips:
            if len(s):
                ax.axvspan(s.gps_time[0] - tr.time[0], s.gps_time[-1] - tr.time[0], color="orange", alpha=0.15, lw=0)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel(f"time since {tr.time[0]:.0f} s GPS week seconds [s] (scanning shaded)")
    fig.suptitle("True trajectory (200 Hz): turbulence, speed changes and turns")
    fig.tight_layout()
    return fig
