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


def _footprint(xy, line, n_bins: int = 40):
    """Outline (M, 2) of a strip's points: across-track extremes in along-track bins, ENU m."""
    if len(xy) < 10:
        return None
    along, across = line.direction, np.array([line.direction[1], -line.direction[0]])
    a, c = (xy - line.start) @ along, (xy - line.start) @ across
    edges = np.linspace(a.min(), a.max(), n_bins + 1)
    k = np.clip(np.digitize(a, edges) - 1, 0, n_bins - 1)
    lo, hi = np.full(n_bins, np.nan), np.full(n_bins, np.nan)
    np.fmin.at(lo, k, c)
    np.fmax.at(hi, k, c)
    mid = 0.5 * (edges[1:] + edges[:-1])
    mid[0], mid[-1] = edges[0], edges[-1]
    ok = np.isfinite(lo)
    ring_a = np.r_[mid[ok], mid[ok][::-1], mid[ok][0]]
    ring_c = np.r_[lo[ok], hi[ok][::-1], lo[ok][0]]
    return line.start + np.outer(ring_a, along) + np.outer(ring_c, across)


def coverage_map(result):
    """Terrain heights with building roofs, tree crowns, strip footprints and the trajectory."""
    sc = result.scene
    xmin, xmax, ymin, ymax = sc.extent
    fig, ax = plt.subplots(figsize=(8.5, 7))
    extent = (xmin, xmax, ymin, ymax)
    im = ax.imshow(sc.heights, origin="lower", extent=extent, cmap="terrain", alpha=0.85)
    fig.colorbar(im, ax=ax, label="terrain height (ENU up) [m]", shrink=0.8)
    roofs = np.flatnonzero(sc.plane_is_roof[sc.tri_plane]) if sc.tri.size else []
    for k in roofs:
        ax.fill(sc.tri[k, :, 0], sc.tri[k, :, 1], color="firebrick", lw=0)
    if sc.tree_radius.size:
        crown_size = (sc.tree_radius / (xmax - xmin) * 500) ** 2  # marker area, points²
        ax.scatter(sc.tree_center[:, 0], sc.tree_center[:, 1], s=crown_size,
                   color="darkgreen", alpha=0.5, lw=0)
    pts, ids = _enu_points(result, 100_000)
    colors = plt.cm.tab10(np.arange(len(result.strips)) % 10)
    for k, s in enumerate(result.strips):
        outline = _footprint(pts[ids == s.line.number, :2], s.line)
        if outline is not None:
            ax.fill(outline[:, 0], outline[:, 1], color=colors[k], alpha=0.12, lw=0)
            ax.plot(outline[:, 0], outline[:, 1], color=colors[k], lw=1.2,
                    label=f"strip {s.line.number}")
    p = result.scene.ecef_to_enu(result.trajectory_true.ecef[::20])
    ax.plot(p[:, 0], p[:, 1], "k-", lw=0.8, label="trajectory")
    for k, ln in enumerate(result.lines):
        arrow = dict(arrowstyle="->", color=colors[k], lw=2)
        ax.annotate("", xy=ln.end, xytext=ln.start, arrowprops=arrow)
        ax.text(*ln.start, f" {ln.number}", color="k", fontsize=9, weight="bold")
    pad = 0.15 * max(xmax - xmin, ymax - ymin)
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymin - pad, ymax + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_title("Scene (roofs red, crowns green), strip footprints and flight lines")
    ax.legend(loc="upper left", bbox_to_anchor=(1.25, 1.0), fontsize=8)
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
        h, _, _ = np.histogram2d(p[:, 1], p[:, 0], bins=(ny, nx),
                                 range=((ymin, ymax), (xmin, xmax)))
        count += h
    dens = count / cell_m**2
    fig, ax = plt.subplots(figsize=(8.5, 6.5))
    vmax = np.percentile(dens[dens > 0], 99) if np.any(dens > 0) else 1.0
    im = ax.imshow(dens, origin="lower", extent=(xmin, xmax, ymin, ymax), cmap="viridis", vmin=0,
                   vmax=vmax)
    fig.colorbar(im, ax=ax, label="points per m²", shrink=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    covered = dens[dens > 0]
    ax.set_title(f"Point density ({cell_m:.3g} m cells): median {np.median(covered):.3g} pts/m² "
                 "where covered")
    return fig


def trajectory_plot(result):
    """Roll, pitch, heading, speed and height of the true trajectory over time; scan windows
    shaded."""
    tr = result.trajectory_true
    t = tr.time - tr.time[0]
    speed = np.linalg.norm(tr.velocity_ned, axis=1)
    fig, axes = plt.subplots(5, 1, figsize=(9, 9), sharex=True)
    series = [(np.degrees(tr.roll), "roll [°]"), (np.degrees(tr.pitch), "pitch [°]"),
              (np.degrees(np.unwrap(tr.heading)), "heading\n(unwrapped) [°]"),
              (speed, "speed [m/s]"), (tr.height, "height [m]")]
    for ax, (y, label) in zip(axes, series):
        ax.plot(t, y, lw=0.7)
        ax.set_ylabel(label)
        for s in result.strips:
            if len(s):
                start, end = s.gps_time[0] - tr.time[0], s.gps_time[-1] - tr.time[0]
                ax.axvspan(start, end, color="orange", alpha=0.15, lw=0)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel(f"time since {tr.time[0]:.0f} s GPS week seconds [s] (scanning shaded)")
    fig.suptitle("True trajectory (200 Hz): turbulence, speed changes and turns")
    fig.tight_layout()
    return fig


def overlap_differences(result, cell_m: float | None = None, min_points: int = 3):
    """Height differences (m) between adjacent strips where they overlap, from ground points.

    Per strip, the mean height of its ground returns in each grid cell; where the next strip
    covers the same cell, the difference next − this is drawn. Mounting errors show here
    before any calibration (e.g. a roll error tilts opposite strips against each other).
    """
    sc = result.scene
    xmin, xmax, ymin, ymax = sc.extent
    cell_m = cell_m or max((xmax - xmin) / 150, 1.0)
    nx, ny = int((xmax - xmin) / cell_m), int((ymax - ymin) / cell_m)
    grids = []
    for s in result.strips:
        p = sc.ecef_to_enu(s.ecef[s.classification == 2])
        j = np.clip(((p[:, 0] - xmin) / cell_m).astype(int), 0, nx - 1)
        i = np.clip(((p[:, 1] - ymin) / cell_m).astype(int), 0, ny - 1)
        n = np.bincount(i * nx + j, minlength=nx * ny)
        z = np.bincount(i * nx + j, p[:, 2], minlength=nx * ny) / np.maximum(n, 1)
        grids.append(np.where(n >= min_points, z, np.nan).reshape(ny, nx))
    diff = np.full((ny, nx), np.nan)
    pairs = [(a, b) for a, b in zip(range(len(grids)), range(1, len(grids)))
             if np.dot(result.lines[a].direction, result.lines[b].direction) < -0.5]
    for a, b in pairs:
        d = grids[b] - grids[a]
        diff = np.where(np.isfinite(d), d, diff)
    fig, ax = plt.subplots(figsize=(8.5, 6.5))
    lim = np.nanpercentile(np.abs(diff), 98) if np.any(np.isfinite(diff)) else 0.1
    im = ax.imshow(diff, origin="lower", extent=(xmin, xmax, ymin, ymax), cmap="RdBu_r", vmin=-lim,
                   vmax=lim)
    fig.colorbar(im, ax=ax, label="height difference, next − previous strip [m]", shrink=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    rms = np.sqrt(np.nanmean(diff**2)) if np.any(np.isfinite(diff)) else float("nan")
    ax.set_title(f"Overlaps of opposite adjacent strips (ground, {cell_m:.3g} m cells): "
                 f"RMS {rms * 100:.3g} cm")
    return fig
