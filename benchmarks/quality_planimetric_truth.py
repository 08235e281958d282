"""`calidar quality`'s planimetric offsets against the true displacement a trajectory's errors cause (issue 26).

A UAV survey is simulated twice from one seed: with the simulator's trajectory errors (GNSS
position σ 2 cm, τ 10 s; attitude σ 0.002°, τ 2 s) and without them. The pulses, the surfaces they
hit and the range noise are the same, so each point's displacement is the difference of its two
positions: the truth, varying along each strip. The truth of a pair (dx, dy of a relative to b) is
the mean horizontal displacement difference over the cells the estimate rests on (roof cells of
the overlap, 2 m, holding points of both lines; the estimator weighs them by their slope, so this
truth is itself uncertain by the field's variation over the overlap, reported as "spread").

    nice -n 10 .venv/bin/python benchmarks/quality_planimetric_truth.py --seeds 7-9

Prints per pair: estimate ± σ, truth, (estimate − truth)/σ, and the RMS of those.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

CELL_M = 2.0


def _lines(folder: Path) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """{line: (xyz (N, 3), classification (N,))} of a simulated survey's strips, in file order."""
    import laspy

    out = {}
    for p in sorted((folder / "strips").glob("*.laz")):
        las = laspy.read(p)
        out[int(las.point_source_id[0])] = (np.column_stack([las.x, las.y, las.z]), np.asarray(las.classification))
    return out


def _cell_means(xy: np.ndarray, values: np.ndarray) -> dict[tuple[int, int], np.ndarray]:
    keys, inv = np.unique(np.floor(xy / CELL_M).astype(np.int64), axis=0, return_inverse=True)
    inv = inv.ravel()
    n = np.bincount(inv)
    means = np.stack([np.bincount(inv, values[:, k]) for k in range(values.shape[1])], axis=1) / n[:, None]
    return {tuple(k): m for k, m in zip(keys, means) if True}


def run(seed: int, work: Path) -> list[tuple]:
    from calidar.pipelines.quality import QualityConfig, measure
    from calidar.sim.survey import simulate_survey, survey_config

    noisy, clean = work / f"noisy{seed}", work / f"clean{seed}"
    if not ((noisy / "truth.json").exists() and (clean / "truth.json").exists()):  # --work: kept, reused
        simulate_survey(survey_config("uav", seed=seed, directions="cross")).write(noisy, force=True)
        simulate_survey(survey_config("uav", seed=seed, directions="cross", gnss_noise_m=0.0,
                                      attitude_noise_rad=0.0)).write(clean, force=True)
    ln, lc = _lines(noisy), _lines(clean)
    disp = {}
    for i in ln:
        (pn, cls), (pc, _) = ln[i], lc[i]
        assert len(pn) == len(pc), "the two simulations did not shoot the same pulses"
        roof = cls == 6
        disp[i] = _cell_means(pc[roof, :2], (pn - pc)[roof, :2])
    _, _, pairs, _, _, _ = measure(sorted((noisy / "strips").glob("*.laz")), QualityConfig(classes=(2, 6)))
    rows = []
    for q in pairs:
        if q.dx_m is None:
            continue
        common = sorted(set(disp[q.a]) & set(disp[q.b]))
        diff = np.array([disp[q.a][k] - disp[q.b][k] for k in common])
        truth, spread = diff.mean(axis=0), diff.std(axis=0)
        z = ((q.dx_m - truth[0]) / q.sigma_dx_m, (q.dy_m - truth[1]) / q.sigma_dy_m)
        rows.append((seed, q.a, q.b, q.dx_m, q.sigma_dx_m, truth[0], spread[0], q.dy_m, q.sigma_dy_m, truth[1],
                     spread[1], *z))
        print(f"seed {seed} {q.a}–{q.b}: dx {1e3 * q.dx_m:+.1f} ± {1e3 * q.sigma_dx_m:.1f} mm, truth "
              f"{1e3 * truth[0]:+.1f} (spread {1e3 * spread[0]:.1f}); dy {1e3 * q.dy_m:+.1f} ± {1e3 * q.sigma_dy_m:.1f}, "
              f"truth {1e3 * truth[1]:+.1f} (spread {1e3 * spread[1]:.1f}); z ({z[0]:+.2f}, {z[1]:+.2f})", flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="7-7")
    ap.add_argument("--work", type=Path, help="keep the simulated surveys here (and reuse them)")
    args = ap.parse_args()
    a, _, b = args.seeds.partition("-")
    rows = []
    with tempfile.TemporaryDirectory(prefix="calidar-bench-") as tmp:
        for seed in range(int(a), int(b or a) + 1):
            rows += run(seed, args.work or Path(tmp))
    z = np.array([r[-2:] for r in rows]).reshape(-1, 2)
    if z.size:
        print(f"{len(rows)} pairs determined: RMS z dx {np.sqrt(np.mean(z[:, 0] ** 2)):.2f}, dy "
              f"{np.sqrt(np.mean(z[:, 1] ** 2)):.2f}; max |z| {np.abs(z).max():.2f}; "
              f"|z| ≤ 2: {np.mean(np.abs(z) <= 2):.0%}")


if __name__ == "__main__":
    main()
