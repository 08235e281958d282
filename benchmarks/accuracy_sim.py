"""``calidar accuracy`` against the simulator's truth, through the pipelines the commands call: per
seed a UAV survey with a boresight error and 40 checkpoints (30 open, 10 under trees, survey σ
1 cm), the NVA tested as delivered and after ``calidar boresight`` + ``calidar regeoref``. The
truth of each stage is the points' own height above the true terrain (sim/checkpoints.py,
``data_truth``). Prints per seed and stage the measured RMSE_V(data), its 95 % χ² interval, the
truth's RMSE (TIN error over open ground ⊕ survey σ), whether the interval holds it, the class,
and the time of ``calidar accuracy``.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/accuracy_sim.py [--seeds N]
"""

import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from calidar.crs import from_crs
from calidar.io.las import read_las
from calidar.pipelines.accuracy import measure_accuracy
from calidar.pipelines.boresight import calibrate_strips
from calidar.pipelines.georef import regeoreference_strips
from calidar.sim.checkpoints import data_truth, simulate_checkpoints
from calidar.sim.survey import simulate_survey, survey_config

ERRORS = {"boresight_roll": np.radians(0.10), "boresight_pitch": np.radians(-0.08), "boresight_yaw": np.radians(0.10)}
SIGMA_M = 0.01


def _truth(scene, files, cp_xy) -> float:
    parts = []
    for f in files:
        p = read_las(f)
        parts.append(SimpleNamespace(ecef=from_crs(p.xyz, p.crs), classification=p.classification))
    return float(np.hypot(data_truth(scene, parts, cp_xy, np.random.default_rng(0))[2], SIGMA_M))


def one(seed: int, tmp: Path) -> list[tuple]:
    res = simulate_survey(survey_config("uav", seed=seed, vegetation=0.2, errors=ERRORS))
    sim = res.write(tmp / f"sim{seed}")
    cps = simulate_checkpoints(res, 40, SIGMA_M, seed=seed)
    cps.write(sim)
    cp_xy = res.scene.ecef_to_enu(from_crs(cps.xyz_true, res.crs))[:, :2]
    strips = sorted((sim / "strips").glob("*.laz"))
    (tmp / f"cal{seed}").mkdir()
    calibrate_strips(strips, sim / "sbet.out", sim / "sensor.toml").write(tmp / f"cal{seed}")
    (tmp / f"re{seed}").mkdir()
    regeoreference_strips(strips, sim / "sbet.out", sim / "sensor.toml", tmp / f"cal{seed}" / "sensor.toml",
                          tmp / f"re{seed}")
    rows = []
    for stage, files in (("delivered", strips), ("calibrated", sorted((tmp / f"re{seed}").glob("*.laz")))):
        t0 = time.perf_counter()
        a = measure_accuracy(files, sim / "checkpoints.csv")
        dt = time.perf_counter() - t0
        acc, truth = a.accuracy, _truth(res.scene, files, cp_xy)
        lo, hi = acc.rmse_interval_m
        rows.append((seed, stage, acc.rmse_data_m, lo, hi, truth, lo <= truth <= hi, acc.class_cm, acc.n_nva, dt,
                     sum(len(read_las(f, fields=())) for f in files)))
    return rows


def main(seeds: int = 3) -> None:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(seeds):
            rows += one(seed, Path(tmp))
            for r in rows[-2:]:
                print(f"seed {r[0]} {r[1]:10s} RMSE_V(data) {r[2] * 100:5.2f} cm  95 % [{r[3] * 100:5.2f}, "
                      f"{r[4] * 100:5.2f}]  truth {r[5] * 100:5.2f} cm  {'in' if r[6] else 'OUT'}  class {r[7]:g} cm  "
                      f"({r[8]} NVA)  accuracy {r[9]:.1f} s for {r[10]:,} points", flush=True)
    held = sum(r[6] for r in rows)
    z = [(r[2] - r[5]) / (r[5] / np.sqrt(2 * r[8])) for r in rows]
    print(f"{held} of {len(rows)} intervals hold the truth; (RMSE − truth)/(truth/√(2n)): mean {np.mean(z):+.2f}, "
          f"RMS {np.sqrt(np.mean(np.square(z))):.2f}")
    for stage in ("delivered", "calibrated"):
        m = [r for r in rows if r[1] == stage]
        print(f"{stage}: mean RMSE_V(data) {np.mean([r[2] for r in m]) * 100:.2f} cm, truth "
              f"{np.mean([r[5] for r in m]) * 100:.2f} cm")


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=3, help="simulated surveys (default 3)")
    main(parser.parse_args().seeds)
