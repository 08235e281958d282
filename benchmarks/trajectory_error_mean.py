"""The flight-wide mean of the simulator's trajectory height error, against what the strip
adjustment's priors say of it (issue 28: the part of the trajectory error only ground control sees).

    PYTHONPATH=src python benchmarks/trajectory_error_mean.py [--seed 100] [--draws 300]

One UAV flight of ``benchmarks/control_montecarlo.py`` (200 m, cross lines): its lines' time windows,
then ``--draws`` trajectory errors drawn on it by ``calidar.sim.motion.measured_trajectory`` (as the
simulator draws them now: stationary, of the smrmsg's σ) and, for comparison, scaled the old way (each
draw to its own std about its mean). For each: the spread of the mean height error over the lines'
times; the per-line mean's spread; the ratio of a draw's own std to the process's. Against: the prior
of that mean under the model's 1 s knots, Gauss–Markov 20 s, (a) independent per line, (b) one
process over the flight (:meth:`calidar.strips.trajectory_errors.TrajectoryModel.flight_correlation`),
and the simulator's own process, Gaussian-smoothed with kernel σ 10 s: correlation exp(−Δt²/400).
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np


def main(argv=None) -> None:
    from calidar.sim.flightplan import plan_lines
    from calidar.sim.motion import fly, measured_trajectory, trajectory_sigma
    from calidar.sim.scene import build_scene, scene_seed
    from calidar.sim.survey import GPS_WEEK_START_S, half_field_of_view, survey_config
    from calidar.strips.trajectory_errors import TrajectoryModel

    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--draws", type=int, default=300)
    a = ap.parse_args(argv)
    cfg = survey_config("uav", seed=a.seed, density=0.2, directions="cross")
    cfg = replace(cfg, scene=replace(cfg.scene, width_m=200.0, length_m=200.0, vegetation_fraction=0.0))
    ss = np.random.SeedSequence(cfg.seed)
    _, rng_motion, _, _, _, rng_sigma = (np.random.default_rng(s) for s in ss.spawn(6))
    lat0, lon0, h0 = cfg.origin_deg
    scene = build_scene(cfg.scene, scene_seed(cfg.seed, cfg.scene_seed), np.radians(lat0), np.radians(lon0), h0)
    half = half_field_of_view(cfg.nominal.scanner, cfg.scan_rate_hz, cfg.half_fov_rad, cfg.scan_pattern)
    lines = list(plan_lines(scene.extent, float(np.mean(scene.heights)), cfg.height_agl_m, half, cfg.side_overlap,
                            cfg.directions, cfg.motion.speed_mps))
    truth, windows = fly(scene, lines, cfg.motion, rng_motion, GPS_WEEK_START_S)
    sig_pos, sig_att = trajectory_sigma(cfg, truth.time, rng_sigma)
    t = truth.time
    on = np.zeros(t.size, bool)
    for w0, w1 in windows:
        on |= (t >= w0) & (t <= w1)
    print(f"{len(windows)} lines of {np.mean([b - c for c, b in windows]):.0f} s over {t[-1] - t[0]:.0f} s; σ "
          f"{cfg.gnss_noise_m * 100:.0f} cm")
    stationary, own_std, ratio = [], [], []
    sigma_up = float(sig_pos[0, 2])
    for k in range(a.draws):
        dh = measured_trajectory(truth, np.random.default_rng(k), sig_pos, sig_att).height - truth.height
        stationary.append(dh[on].mean())
        own_std.append((dh * (sigma_up / dh.std()))[on].mean())  # the old scaling: the draw's own std about its mean
        ratio.append(dh.std() / sigma_up)
    sd_s, sd_o = np.std(stationary), np.std(own_std)
    spans = {i: (w0, w1) for i, (w0, w1) in enumerate(windows)}
    model = TrajectoryModel(1.0, sigma_up, correlation_s=20.0)
    R = model.flight_correlation(spans)
    sizes = [v.size for v in model.knot_times(spans).values()]
    strip = np.repeat(np.arange(len(sizes)), sizes)
    own = np.where(strip[:, None] == strip[None, :], R, 0.0)
    tt = np.concatenate(list(model.knot_times(spans).values()))
    sim = np.exp(-((tt[:, None] - tt[None, :]) ** 2) / 400.0)
    s = sigma_up
    print(f"flight-mean height error, sd over {a.draws} draws: stationary (now) {100 * sd_s:.2f} cm, each draw scaled "
          f"to its own std (before) {100 * sd_o:.2f} cm")
    print(f"prior of the knots' mean: independent lines {100 * s * np.sqrt(own.mean()):.2f} cm, one process over the "
          f"flight {100 * s * np.sqrt(R.mean()):.2f} cm; the simulator's process {100 * s * np.sqrt(sim.mean()):.2f} cm")
    print(f"a draw's std about its mean / the process's σ: median {np.median(ratio):.2f} (5–95 %: "
          f"{np.percentile(ratio, 5):.2f}–{np.percentile(ratio, 95):.2f})")


if __name__ == "__main__":
    main()
