"""Monte-Carlo study of the CCR calibration against simulated truth (issue 19's acceptance).

For each seed a pass is simulated (sim.photons: photons, dead time, background, jitter, lost
shots), calibrated by calidar.photon.ccr.calibrate (the maximum likelihood) and compared with the
truth; the Cramér–Rao σ is the inverse Fisher information AT THE TRUTH on the same shots.
Reported per geolocation parameter: RMS error, RMS Cramér–Rao σ and their ratio, the mean of
(error/σ)² for the observed-information σ (1 when σ is honest), and the coverage of the 95 %
profile-likelihood intervals (and of ±1.96 σ).

Configurations:
  two      2 lit CCRs (+1 out of reach), a third of the shots lost
  eight    8 lit CCRs
  twelve   12 lit CCRs, 45 m apart
  passes   two passes of 8 lit CCRs each (same bias), solved jointly, against each alone
With ``--model`` the counts are drawn from the likelihood itself (at the truth, on each seed's
shots) instead of coming from the simulated photons: the exact MLE's own limit, free of any
difference between the simulator and the model.

Run (one core): NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/photon_study.py two --seeds 0:40
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from calidar.errors import CalibrationError
from calidar.photon.ccr import calibrate
from calidar.photon.estimate import estimate
from calidar.photon.likelihood import count_distribution, simulate_counts
from calidar.photon.parameters import GEOLOCATION
from calidar.photon.passes import SystemParameters, prepare_pass
from calidar.photon.search import SearchSettings
from calidar.photon.survey import CCRSurvey
from calidar.sim.photons import PhotonSimConfig, simulate_pass

CONFIGS = {
    "two": dict(n_ccr=2, ccr_dropout=1 / 3, n_unlit=1),
    "eight": dict(n_ccr=8),
    "twelve": dict(n_ccr=12, ccr_spacing=45.0),
}
SYSTEM = SystemParameters()


def survey_of(*sims) -> CCRSurvey:
    return CCRSurvey([f"{k}{i}" for k, s in enumerate(sims) for i in s.ccr_id], np.concatenate([s.ccr_height for s in sims]),
                     lat=np.concatenate([s.ccr_lat for s in sims]), lon=np.concatenate([s.ccr_lon for s in sims]))


def truth_values(sim, cfg) -> dict[str, float]:
    return {**{k: sim.truth[k] for k in GEOLOCATION}, "ccr_peak_photons": cfg.ccr_photons,
            "shot_loss_rate": cfg.ccr_dropout}


def cramer_rao(result, truth: dict[str, float]) -> np.ndarray:
    """Cramér–Rao σ of the geolocation parameters at the truth, on the result's shots (all 5 parameters free)."""
    names = result.layout.names
    info = result.problem.information({n: truth[n.split("[")[0]] for n in names}, names)
    sig = np.sqrt(np.diag(np.linalg.inv(info)))
    return np.array([sig[names.index(k)] for k in GEOLOCATION])


def one(cfg: PhotonSimConfig, settings: SearchSettings, model: bool = False):
    """(errors, observed σ, Cramér–Rao σ, profile-interval cover flags, bootstrap σ) of one seed."""
    sim = simulate_pass(cfg)
    survey = survey_of(sim)
    result = calibrate([prepare_pass(sim.beam, survey, SYSTEM, "sim")], survey, SYSTEM, settings)
    truth = truth_values(sim, cfg)
    crb = cramer_rao(result, truth)
    if model:  # the same shots, counts drawn from the likelihood at the truth
        table, _ = count_distribution(result.layout.theta(truth), result.problem.shots, SYSTEM.pointing_jitter)
        counts = np.split(simulate_counts(table, np.random.default_rng(cfg.seed + 1000)),
                          np.cumsum([w.shot_x.size for w in result.windows])[:-1])
        fit = estimate(result.windows, result.problem, settings, SYSTEM.shot_spacing, counts).fit
        v, s = fit.solution.values, fit.solution.sigma
        return np.array([v[k] - truth[k] for k in GEOLOCATION]), np.array([s[k] for k in GEOLOCATION]), crb, None, None
    v, s, u = result.solution.values, result.solution.sigma, result.uncertainty
    err = np.array([v[k] - truth[k] for k in GEOLOCATION])
    # a parameter held at its bound (the verdict fails it) has no σ and no interval: counted as not covered
    cover = np.array([k in u.profile and u.profile[k].covers(truth[k]) for k in GEOLOCATION])
    boot = np.array([u.bootstrap.get(k, np.nan) for k in GEOLOCATION]) if u.bootstrap else None
    if result.verdict.status == "fail":
        print(f"  seed {cfg.seed}: verdict FAIL ({'; '.join(f.detail for f in result.verdict.findings if f.status == 'fail')})")
    return err, np.array([s.get(k, np.nan) for k in GEOLOCATION]), crb, cover, boot


def passes_pair(seed: int, settings: SearchSettings):
    """Errors of pass A alone and of A and B (same bias, 8 lit CCRs each) solved jointly."""
    bias = dict(along_bias=float(np.random.default_rng(seed).uniform(-3, 3)),
                cross_bias=float(np.random.default_rng(seed + 7).uniform(-3, 3)))
    a = simulate_pass(PhotonSimConfig(seed=2 * seed, n_ccr=8, **bias))
    b = simulate_pass(PhotonSimConfig(seed=2 * seed + 1, n_ccr=8, lat0_deg=32.6, azimuth_deg=-170.0, **bias))
    survey = survey_of(a, b)
    pa, pb = prepare_pass(a.beam, survey, SYSTEM, "A"), prepare_pass(b.beam, survey, SYSTEM, "B")
    truth = np.array([a.truth[k] for k in GEOLOCATION])
    alone = calibrate([pa], survey, SYSTEM, settings).solution.values
    joint = calibrate([pa, pb], survey, SYSTEM, settings).solution.values
    return np.array([alone[k] for k in GEOLOCATION]) - truth, np.array([joint[k] for k in GEOLOCATION]) - truth


def summarise(name: str, errs, sig, crb, cover, boot, failed: int, seconds: float) -> None:
    errs, sig, crb = np.array(errs), np.array(sig), np.array(crb)
    rms, rcr = np.sqrt((errs**2).mean(axis=0)), np.sqrt((crb**2).mean(axis=0))
    print(f"{name}: {len(errs)} seeds ({failed} without an estimate), {seconds:.0f} s")
    print("  parameter            RMS err   RMS CR σ  ratio   mean(err/σ)²  Wald95 cover  profile95 cover  bootσ/obsσ")
    for i, k in enumerate(GEOLOCATION):
        z2 = float(np.nanmean((errs[:, i] / sig[:, i]) ** 2))
        wald = float(np.mean(np.abs(errs[:, i]) <= 1.96 * np.nan_to_num(sig[:, i])))
        prof = f"{np.mean(np.array(cover)[:, i]):.3f}" if cover else "—"
        bo = f"{np.nanmean(np.array(boot)[:, i] / sig[:, i]):.3f}" if boot else "—"
        print(f"  {k:20s} {rms[i]:8.3f} {rcr[i]:9.3f} {rms[i] / rcr[i]:6.3f} {z2:12.3f} {wald:12.3f} {prof:>15s} {bo:>11s}")
    if cover:
        print(f"  profile 95 % intervals cover the truth on {int(np.sum(cover))} of {np.size(cover)} cases")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("config", choices=[*CONFIGS, "passes"])
    ap.add_argument("--model", action="store_true", help="counts drawn from the likelihood at the truth")
    ap.add_argument("--seeds", default="0:40", help="first:last (exclusive)")
    ap.add_argument("--bootstrap", type=int, default=0, help="parametric bootstrap replicates per seed")
    a = ap.parse_args()
    lo, hi = map(int, a.seeds.split(":"))
    settings = SearchSettings(bootstrap=a.bootstrap, surface_points=0)
    t0 = time.perf_counter()
    if a.config == "passes":
        pairs = [passes_pair(s, settings) for s in range(lo, hi)]
        one_rms = np.sqrt(np.mean([p[0] ** 2 for p in pairs], axis=0))
        joint_rms = np.sqrt(np.mean([p[1] ** 2 for p in pairs], axis=0))
        print(f"passes: {hi - lo} pairs, {time.perf_counter() - t0:.0f} s")
        for i, k in enumerate(GEOLOCATION):
            print(f"  {k:20s} one pass RMS {one_rms[i]:.3f}  two jointly {joint_rms[i]:.3f}  ratio "
                  f"{joint_rms[i] / one_rms[i]:.3f} (1/√2 = 0.707)")
        return
    rows, failed = [], 0
    for seed in range(lo, hi):
        try:
            rows.append(one(PhotonSimConfig(seed=seed, **CONFIGS[a.config]), settings, a.model))
        except CalibrationError as e:
            failed += 1
            print(f"  seed {seed}: {e}")
    errs, sig, crb, cover, boot = zip(*rows)
    summarise(a.config + (" (counts from the model)" if a.model else ""), errs, sig, crb, None if cover[0] is None else cover, None if boot[0] is None else boot,
              failed, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
