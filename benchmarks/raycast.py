"""Ray-casting and end-to-end simulation speed of calidar.sim (a script, not a test).

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/raycast.py

The machine is shared, so rates are also given per CPU-second of this process.
Casts scan-pattern rays (±35° at 80 m, ±20° at 1000 m) into the ``uav`` and ``airborne``
preset scenes and times the full ``simulate_survey`` of the uav preset (density 1).
"""

from __future__ import annotations

import os
import time

import numpy as np

from calidar.sim.raycast import cast
from calidar.sim.scene import build_scene
from calidar.sim.survey import PRESETS, simulate_survey


def rays(n: int, height: float, half_fov: float, half_width: float, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays from random positions at ``height`` m with scan angles within ±half_fov rad."""
    o = np.column_stack([rng.uniform(-half_width, half_width, n), rng.uniform(-half_width, half_width, n),
                         np.full(n, height)])
    th = rng.uniform(-half_fov, half_fov, n)
    d = np.column_stack([0.03 * rng.normal(size=n), np.sin(th), -np.cos(th)])
    return o, d / np.linalg.norm(d, axis=1)[:, None], 1.0 - rng.random(n)


def main(n: int = 2_000_000) -> None:
    rng = np.random.default_rng(0)
    print(f"numba threads: {os.environ.get('NUMBA_NUM_THREADS', 'default')}")
    for name, cfg in PRESETS.items():
        lat, lon, h = cfg.origin_deg
        scene = build_scene(cfg.scene, 1, np.radians(lat), np.radians(lon), h)
        z = float(np.mean(scene.heights)) + cfg.height_agl_m
        half_width = 0.5 * min(cfg.scene.width_m, cfg.scene.length_m) - cfg.height_agl_m * np.tan(cfg.half_fov_rad) - 5
        o, d, u = rays(n, z, cfg.half_fov_rad, half_width, rng)
        cast(scene, o[:100], d[:100], u[:100])  # compile / load the cache
        t0, c0 = time.perf_counter(), time.process_time()
        hits = cast(scene, o, d, u)
        dt, dc = time.perf_counter() - t0, time.process_time() - c0
        print(f"{name:9s} scene: {len(scene.roof_type)} buildings, {scene.tri.shape[0]} triangles, "
              f"{scene.tree_radius.size} trees; {n / dt / 1e6:.2f} M rays/s wall, {n / dc / 1e6:.2f} M rays per "
              f"CPU-second ({np.mean(hits.surface != -2):.1%} hit)")
    t0, c0 = time.perf_counter(), time.process_time()
    res = simulate_survey(PRESETS["uav"])
    dt, dc = time.perf_counter() - t0, time.process_time() - c0
    print(f"simulate_survey(uav, density 1): {res.n_points / 1e6:.2f} M points in {dt:.1f} s wall, {dc:.1f} s CPU "
          f"= {res.n_points / dc / 1e6:.2f} M points per CPU-second end to end (trajectory, georeferencing, UTM)")


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()  # no options; --help
    main()
