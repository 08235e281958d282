"""CCR geolocation calibration against simulated truth; bad-input handling; the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calidar.errors import CalibrationError, InputError
from calidar.photon.ccr import (PARAMETERS, CCRSurvey, SearchSettings, SystemParameters, calibrate, prepare_pass,
                                read_ccr_csv)
from calidar.sim.photons import PhotonSimConfig, simulate_pass, write_ccr_csv

SYSTEM = SystemParameters()


def _solve(cfg: PhotonSimConfig, bootstrap: int = 200):
    sim = simulate_pass(cfg)
    survey = CCRSurvey(sim.ccr_id, sim.ccr_height, lat=sim.ccr_lat, lon=sim.ccr_lon)
    result = calibrate([prepare_pass(sim.beam, SYSTEM, "sim")], survey, SYSTEM, SearchSettings(bootstrap=bootstrap))
    err = {k: result.solution.values[k] - sim.truth[k] for k in PARAMETERS}
    return sim, result, err


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_many_lit_ccrs_recover_bias_and_diameter(seed):
    sim, result, err = _solve(PhotonSimConfig(seed=seed, n_ccr=12, ccr_spacing=45.0))
    assert len(result.segments) == 12
    assert abs(err["along_track_bias"]) < 0.5
    assert abs(err["cross_track_bias"]) < 0.5
    assert abs(err["footprint_diameter"]) < 1.0
    sigma = result.solution.sigma
    for k in PARAMETERS:  # bootstrap σ consistent with the actual error
        assert 0.05 < sigma[k] < 1.5
        assert abs(err[k]) < 3.0 * sigma[k]
    # each CCR's side of the footprint track is resolved jointly
    true_sides = np.sign(np.array(sim.truth["ccr_y"]) - sim.truth["cross_track_bias"])
    sides = {s.ccr_id: side for s, side in zip(result.segments, result.grid.sides)}
    wrong = [cid for cid, ts in zip(sim.ccr_id, true_sides) if sides[cid] != ts and abs(
        sim.truth["ccr_y"][sim.ccr_id.index(cid)] - sim.truth["cross_track_bias"]) > 0.5]
    assert not wrong


TWO_CCR = dict(n_ccr=2, ccr_dropout=1 / 3, n_unlit=1)


@pytest.mark.slow
def test_two_lit_ccrs_with_a_third_of_shots_lost():
    """Seeds 0–19, all errors within 3 bootstrap σ. The goal "within 1 m" is NOT met on every
    seed, because the data do not hold that information (test_two_lit_ccrs_information_limit:
    the Cramér–Rao σ of D is ≈ 0.66 m and of the along-track bias ≈ 0.41 m, so even an
    efficient unbiased estimator misses 1 m in D on ~13 % of passes; the exact maximum
    likelihood on counts drawn from the model itself misses it on 12–19 %). Measured here:
    RMS along/cross/D 0.41/0.27/0.85 m; D within 1 m on 14 of 20, along on 19 of 20."""
    errors, z = [], []
    for seed in range(20):
        sim, result, err = _solve(PhotonSimConfig(seed=seed, **TWO_CCR))
        assert len(result.segments) == 2
        assert any("no CCR photons found for CCR CCR03" in w for w in result.warnings)
        errors.append([err[k] for k in PARAMETERS])
        z.append([abs(err[k]) / result.solution.sigma[k] for k in PARAMETERS])
    errors, z = np.abs(np.array(errors)), np.array(z)
    assert np.all(z < 3.0), z.max(axis=0)
    rms = np.sqrt(np.mean(errors**2, axis=0))
    assert rms[0] < 0.5 and rms[1] < 0.5 and rms[2] < 1.0, rms
    assert np.all(errors[:, 1] < 1.0) and np.sum(errors[:, 0] < 1.0) >= 19
    assert np.sum(errors[:, 2] < 1.0) >= 14 and errors[:, 2].max() < 1.5


def test_two_lit_ccrs_information_limit():
    """Cramér–Rao bound at the truth: 2 lit CCRs with a third of the shots lost fix D to
    ≈ 0.66 m at best (1 m is 1.5σ), 12 lit CCRs to ≈ 0.17 m."""
    from calidar.photon.likelihood import cramer_rao_sigma

    def bound(cfg):
        sim = simulate_pass(cfg)
        t, n = sim.truth, int(cfg.length / cfg.shot_spacing)
        xs = cfg.shot_spacing * np.arange(n)
        near = [np.flatnonzero(np.abs(xs - x) < 17.5) for x in t["ccr_x"][:cfg.n_ccr]]
        x_shot = np.concatenate([xs[i] for i in near])
        xc = np.concatenate([np.full(i.size, x) for i, x in zip(near, t["ccr_x"])])
        yc = np.concatenate([np.full(i.size, y) for i, y in zip(near, t["ccr_y"])])
        v = {"along_track_bias": t["along_track_bias"], "cross_track_bias": t["cross_track_bias"],
             "footprint_diameter": cfg.footprint_diameter, "ccr_peak_photons": cfg.ccr_photons,
             "shot_loss_rate": cfg.ccr_dropout}
        return cramer_rao_sigma(x_shot, xc, yc, v, cfg.channels, cfg.jitter)

    two = bound(PhotonSimConfig(seed=2, **TWO_CCR))
    assert 0.55 < two["footprint_diameter"] < 0.8 and 0.3 < two["along_track_bias"] < 0.5
    many = bound(PhotonSimConfig(seed=2, n_ccr=12, ccr_spacing=45.0))
    assert many["footprint_diameter"] < 0.25 and many["along_track_bias"] < 0.1


def test_several_passes_are_solved_jointly():
    bias = dict(along_bias=1.7, cross_bias=-2.2)
    a = simulate_pass(PhotonSimConfig(seed=21, n_ccr=6, **bias))
    b = simulate_pass(PhotonSimConfig(seed=22, n_ccr=6, lat0_deg=32.6, azimuth_deg=-170.0, **bias))
    survey = CCRSurvey([f"A{i}" for i in a.ccr_id] + [f"B{i}" for i in b.ccr_id],
                       np.concatenate([a.ccr_height, b.ccr_height]),
                       lat=np.concatenate([a.ccr_lat, b.ccr_lat]), lon=np.concatenate([a.ccr_lon, b.ccr_lon]))
    result = calibrate([prepare_pass(a.beam, SYSTEM, "A"), prepare_pass(b.beam, SYSTEM, "B")], survey, SYSTEM)
    assert len(result.segments) == 12
    assert {s.pass_name for s in result.segments} == {"A", "B"}
    # each pass's CCRs lie outside the other pass: warned, not used
    assert sum("outside the pass" in w for w in result.warnings) == 12
    v = result.solution.values
    assert abs(v["along_track_bias"] - 1.7) < 0.5
    assert abs(v["cross_track_bias"] + 2.2) < 0.5
    assert abs(v["footprint_diameter"] - 11.0) < 1.0


def test_xy_survey_with_several_passes_is_refused(tmp_path):
    a = simulate_pass(PhotonSimConfig(seed=21, n_ccr=3, length=600.0))
    p = tmp_path / "ccr_xy.csv"
    p.write_text("id,x,y,height\n" + "".join(
        f"{i},{x:.3f},{y:.3f},{h}\n" for i, x, y, h in zip(a.ccr_id, a.ccr_x, a.ccr_y, a.ccr_height)))
    passes = [prepare_pass(a.beam, SYSTEM, "A"), prepare_pass(a.beam, SYSTEM, "B")]
    with pytest.raises(InputError, match=r"ccr_xy.csv: columns: x,y are along/cross-track positions in ONE pass"):
        calibrate(passes, read_ccr_csv(p), SYSTEM)


def test_delta_h_is_the_smaller_of_dead_time_and_pulse_bounds():
    assert SystemParameters(3.2e-9, 1.0e-9).delta_h == pytest.approx(299_792_458.0 * 3.2e-9 / 2)
    assert SystemParameters(3.2e-9, 0.1e-9).delta_h == pytest.approx(3 * 299_792_458.0 * 0.1e-9)


def test_ccr_file_with_unknown_columns(tmp_path):
    p = tmp_path / "ccr.csv"
    p.write_text("id,lat,lon,height,colour\nA,32.4,-106.4,2.0,red\n")
    with pytest.raises(InputError, match=r"ccr.csv: header: unknown column\(s\) colour; expected id,lat,lon,height"):
        read_ccr_csv(p)
    p.write_text("id,lat,lon,height\nA,32.4,west,2.0\n")
    with pytest.raises(InputError, match="line 2: lon: expected a number"):
        read_ccr_csv(p)


def test_ccrs_outside_the_pass_and_no_ccr_photons(tmp_path):
    sim = simulate_pass(PhotonSimConfig(seed=5, n_ccr=3, length=600.0, ccr_spacing=60.0))
    p = prepare_pass(sim.beam, SYSTEM, "sim")
    far = CCRSurvey(["far"], np.array([2.0]), lat=np.radians([33.0]), lon=np.radians([-106.4]))
    with pytest.raises(CalibrationError, match="no CCR photons found in any pass: .*CCR far lies outside the pass"):
        calibrate([p], far, SYSTEM)
    wrong_height = CCRSurvey(sim.ccr_id, sim.ccr_height + 20.0, lat=sim.ccr_lat, lon=sim.ccr_lon)
    with pytest.raises(CalibrationError, match="no CCR photons found for CCR CCR01"):
        calibrate([p], wrong_height, SYSTEM)
    one = CCRSurvey(sim.ccr_id[:1], sim.ccr_height[:1], lat=sim.ccr_lat[:1], lon=sim.ccr_lon[:1])
    with pytest.raises(CalibrationError, match="need at least two CCRs at different cross-track offsets"):
        calibrate([p], one, SYSTEM)


def test_cli_simulate_ccr_denoise(cli, tmp_path):
    sim_dir, out = tmp_path / "sim", tmp_path / "out"
    code, _, err = cli("simulate", "photons", "--seed", "4", "--n-ccr", "8", "--out", sim_dir)
    assert code == 0, err
    code, _, err = cli("ccr", sim_dir / "ATL03_sim.h5", "--ccr", sim_dir / "ccr.csv", "--truth",
                       sim_dir / "truth.json", "--bootstrap", "50", "--out", out)
    assert code == 0, err
    doc = json.loads((out / "solution.json").read_text())
    for k in PARAMETERS:
        p = doc["parameters"][k]
        assert p["unit"] == "m" and p["sigma"] > 0
        assert abs(p["error"]) < (0.5 if "bias" in k else 1.0)
    assert "RMS surface" in (out / "report.html").read_text()
    # refuses to overwrite without --force; bad CCR file → one-line error, exit 1
    code, _, err = cli("ccr", sim_dir / "ATL03_sim.h5", "--ccr", sim_dir / "ccr.csv", "--out", out)
    assert code == 1 and "--force" in err
    bad = tmp_path / "bad.csv"
    bad.write_text("name,x,y\n")
    code, _, err = cli("ccr", sim_dir / "ATL03_sim.h5", "--ccr", bad, "--out", tmp_path / "o2")
    assert code == 1 and "unknown column(s) name" in err and "Traceback" not in err
    code, _, err = cli("denoise", sim_dir / "ATL03_sim.h5", "--beam", "gt2l", "--out", tmp_path / "p.csv")
    assert code == 1 and "gt2l: beam group missing" in err
    code, _, err = cli("denoise", sim_dir / "ATL03_sim.h5", "--out", tmp_path / "p.csv")
    assert code == 0, err
    rows = np.genfromtxt(tmp_path / "p.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert len(rows.dtype.names) == 10 and set(np.unique(rows["signal"])) == {0, 1}


def test_ccr_csv_round_trip(tmp_path):
    p = write_ccr_csv(tmp_path / "c.csv", ["a", "b"], np.radians([32.4, 32.5]), np.radians([-106.4, -106.3]), [2.0, 3.5])
    s = read_ccr_csv(p)
    assert s.ids == ["a", "b"]
    np.testing.assert_allclose(np.degrees(s.lat), [32.4, 32.5])
    np.testing.assert_allclose(s.height, [2.0, 3.5])


def test_demo_step_adds_a_report_section(tmp_path):
    from calidar.demo.photon import photon_step
    from calidar.report import Report

    report = Report()
    photon_step(report, tmp_path, seed=2)
    assert [s.title for s in report.sections] == ["Photon lidar: CCR geolocation calibration"]
    doc = json.loads((tmp_path / "photon" / "ccr" / "solution.json").read_text())
    assert abs(doc["parameters"]["along_track_bias"]["error"]) < 0.5


def test_survey_in_track_coordinates(tmp_path):
    sim = simulate_pass(PhotonSimConfig(seed=7, n_ccr=8))
    p = tmp_path / "ccr_xy.csv"
    p.write_text("id,x,y,height\n" + "".join(
        f"{i},{x:.3f},{y:.3f},{h}\n" for i, x, y, h in zip(sim.ccr_id, sim.ccr_x, sim.ccr_y, sim.ccr_height)))
    survey = read_ccr_csv(p)
    result = calibrate([prepare_pass(sim.beam, SYSTEM, "sim")], survey, SYSTEM, SearchSettings(bootstrap=0))
    v = result.solution.values
    assert abs(v["along_track_bias"] - sim.truth["along_track_bias"]) < 0.5
    assert abs(v["cross_track_bias"] - sim.truth["cross_track_bias"]) < 0.5
    assert "least squares" in result.solution.extra["sigma_source"]
