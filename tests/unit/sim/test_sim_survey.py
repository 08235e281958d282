"""Survey simulator: truth recovery, noise levels, and the strip symptoms of each mounting error."""

import json
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
import pytest
from scipy.spatial import cKDTree

from calidar import frames, georef
from calidar.io.las import read_las
from calidar.io.sbet import read_sbet
from calidar.sensor import Sensor
from calidar.sim.scene import CLASS_BUILDING, CLASS_GROUND, CLASS_VEGETATION
from calidar.sim.survey import simulate_survey, survey_config

NOISELESS = dict(range_noise_m=0.0, angle_noise_rad=0.0, gnss_noise_m=0.0, attitude_noise_rad=0.0)
MOUNTING_ERRORS = {"boresight_roll": np.radians(0.07), "boresight_pitch": np.radians(-0.05),
                   "boresight_yaw": np.radians(0.12), "lever_arm_x": 0.04, "lever_arm_y": -0.03, "lever_arm_z": 0.06,
                   "range_offset": 0.05}


def truth_sensor(folder) -> Sensor:
    """The true sensor rebuilt from sensor.toml (nominal) and truth.json."""
    nominal = Sensor.read(folder / "sensor.toml")
    truth = json.loads((folder / "truth.json").read_text())["parameters"]
    values = {k: np.radians(p["value"]) if p["unit"] == "deg" else p["value"] for k, p in truth.items()}
    return nominal.with_parameters(**values)


def truly_georeferenced(result, folder):
    """Read the written strips and the SBET; inverse with the nominal sensor, forward with the truth (ENU)."""
    traj = read_sbet(folder / "sbet.out")
    nominal, truth = Sensor.read(folder / "sensor.toml"), truth_sensor(folder)
    for strip in result.strips:
        las = read_las(folder / "strips" / f"line_{strip.line.number:03d}.laz")
        assert las.crs.to_epsg() == int(result.crs.split(":")[1]) and np.all(las.point_source_id == strip.line.number)
        ecef = georef.regeoreference(traj, nominal, truth, las.gps_time, georef.from_crs(las.xyz, las.crs))
        yield strip, las, result.scene.ecef_to_enu(ecef)


def test_truth_json_and_outputs(tmp_path):
    res = simulate_survey(survey_config("uav", seed=2, density=0.01, errors={**MOUNTING_ERRORS, "range_scale": 2e-5,
                                                                               "scan_angle_offset": np.radians(0.01)}))
    res.write(tmp_path)
    doc = json.loads((tmp_path / "truth.json").read_text())
    p = doc["parameters"]
    assert p["boresight_roll"] == {"value": pytest.approx(0.07), "unit": "deg", "nominal": 0.0}
    assert p["lever_arm_z"]["value"] == pytest.approx(res.nominal.lever_arm_z + 0.06) and p["lever_arm_z"]["unit"] == "m"
    assert p["range_offset"]["value"] == pytest.approx(0.05) and p["scan_angle_scale"]["unit"] == "ratio"
    assert p["range_scale"] == {"value": pytest.approx(2e-5), "unit": "ratio", "nominal": 0.0}
    assert p["scan_angle_offset"] == {"value": pytest.approx(0.01), "unit": "deg", "nominal": 0.0}
    assert doc["noise"]["range_m"] == res.config.range_noise_m
    assert sorted(f.name for f in (tmp_path / "strips").iterdir()) == [f"line_{k:03d}.laz" for k in range(1, 5)]
    sbet = read_sbet(tmp_path / "sbet.out")
    assert sbet.rate_hz == pytest.approx(200.0) and np.allclose(sbet.roll, res.trajectory.roll)
    las = read_las(tmp_path / "strips" / "line_002.laz")
    assert np.all(np.diff(las.gps_time) >= 0)
    assert set(np.unique(las.classification)) == {CLASS_GROUND, CLASS_BUILDING, CLASS_VEGETATION}
    two = las.number_of_returns == 2
    assert two.any() and np.all(las.classification[two & (las.return_number == 1)] == CLASS_VEGETATION)
    assert np.abs(las.scan_angle_deg).max() == pytest.approx(35.0, abs=0.01)
    mem = res.las_points()[1]  # the in-memory twin of the file
    assert np.max(np.abs(mem.xyz - las.xyz)) <= 0.5e-3 + 1e-9 and np.array_equal(mem.gps_time, las.gps_time)
    assert np.array_equal(mem.classification, las.classification) and mem.crs == las.crs


def test_noiseless_truth_puts_points_back_on_the_surfaces(tmp_path):
    res = simulate_survey(survey_config("uav", seed=3, density=0.02, errors=MOUNTING_ERRORS, **NOISELESS))
    res.write(tmp_path)
    n_roof = 0
    for strip, las, enu in truly_georeferenced(res, tmp_path):
        # delivered with the nominal sensor: metres-level displacements (boresight × 80 m, lever arm, offset)
        assert np.median(np.linalg.norm(res.scene.ecef_to_enu(strip.ecef) - strip.true_enu, axis=1)) > 0.05
        assert np.max(np.linalg.norm(enu - strip.true_enu, axis=1)) < 2e-3  # LAS stores mm
        roof = (strip.surface >= 0) & res.scene.plane_is_roof[np.maximum(strip.surface, 0)]
        assert np.max(np.abs(res.scene.plane_distance(enu[roof], strip.surface[roof]))) < 2e-3
        n_roof += roof.sum()
        ground = strip.surface == -1
        dz = enu[ground, 2] - res.scene.terrain_height(enu[ground, 0], enu[ground, 1])
        assert np.max(np.abs(dz)) < 5e-3
    assert n_roof > 5000


def test_noisy_points_lie_on_roofs_within_the_simulated_noise(tmp_path):
    cfg = survey_config("uav", seed=4, density=0.02, errors=MOUNTING_ERRORS)
    res = simulate_survey(cfg)
    res.write(tmp_path)
    d = []
    for strip, las, enu in truly_georeferenced(res, tmp_path):
        roof = (strip.surface >= 0) & res.scene.plane_is_roof[np.maximum(strip.surface, 0)]
        d.append(res.scene.plane_distance(enu[roof], strip.surface[roof]))
    d = np.concatenate(d)
    r = cfg.height_agl_m
    # range along the near-vertical beam, GNSS, attitude (two tilt axes) and beam-angle noise
    predicted = np.sqrt(cfg.range_noise_m**2 + cfg.gnss_noise_m**2 + 2 * (r * cfg.attitude_noise_rad) ** 2
                        + (r * cfg.angle_noise_rad) ** 2)
    rms = np.sqrt(np.mean(d**2))
    assert 0.5 * predicted < rms < 1.5 * predicted, (rms, predicted)
    assert np.mean(np.abs(d) < 5 * predicted) > 0.999


def misalignment(a, b, along, across, centre):
    """Displacement of strip B relative to strip A (ENU points, m) from point-to-plane distances.

    Model: d(c) = (dz + tilt·c)·up + (shift + shear·c)·along + lateral·across, with c the
    across-track coordinate (m) from ``centre``; fitted by least squares with 3-MAD trimming.
    """
    dist, idx = cKDTree(a).query(b, k=10, distance_upper_bound=1.5)
    ok = np.all(np.isfinite(dist), axis=1)
    nb = a[idx[ok]]
    q = nb.mean(axis=1)
    x = nb - q[:, None]
    w, v = np.linalg.eigh(np.einsum("mki,mkj->mij", x, x) / x.shape[1])
    n, p = v[:, :, 0], b[ok]
    planar = (w[:, 0] < 0.04**2) & (w[:, 1] > 0.2**2)
    r = np.einsum("mi,mi->m", n, p - q)[planar]
    n, c = n[planar], (p[planar] - centre) @ across
    na, nc = n @ along, n @ across
    design = np.column_stack([n[:, 2], n[:, 2] * c, na, na * c, nc])
    keep = np.ones(r.size, bool)
    for _ in range(3):
        sol = np.linalg.lstsq(design[keep], r[keep], rcond=None)[0]
        res = r - design @ sol
        keep = np.abs(res) < 3 * 1.4826 * np.median(np.abs(res[keep]))
    return dict(zip(("dz", "tilt", "shift", "shear", "lateral"), sol))


SYMPTOM_RUNS = {"none": {}, "roll": {"boresight_roll": np.radians(0.1)}, "pitch": {"boresight_pitch": np.radians(0.1)},
                "yaw": {"boresight_yaw": np.radians(0.2)}}


@pytest.fixture(scope="module")
def symptoms():
    """Misalignment of the opposite-direction strips 1 (north) and 2 (south) for each error."""
    out = {}
    for name, errors in SYMPTOM_RUNS.items():
        res = simulate_survey(survey_config("uav", seed=5, density=0.15, vegetation=0.0, errors=errors))
        a, b = res.strips[0], res.strips[1]
        assert np.dot(a.line.direction, b.line.direction) < -0.99
        keep = [np.isin(s.classification, (CLASS_GROUND, CLASS_BUILDING)) for s in (a, b)]
        pa, pb = (res.scene.ecef_to_enu(s.ecef[k]) for s, k in zip((a, b), keep))
        along = np.r_[a.line.direction, 0.0]
        across = np.array([along[1], -along[0], 0.0])  # right of strip 1
        centre = np.r_[(a.line.start + b.line.start) / 2, 0.0]
        m = misalignment(pa, pb, along, across, centre)
        m["height"] = a.line.altitude_m - np.mean(b.true_enu[keep[1], 2])
        m["separation"] = float(np.linalg.norm(b.line.start[0] - a.line.start[0]))
        # shear of strip 1 itself: along-track displacement vs across-track distance from its line
        d = res.scene.ecef_to_enu(a.ecef) - a.true_enu
        c = (a.true_enu[:, :2] - a.line.start) @ across[:2]
        m["own_shear"] = np.polyfit(c, d @ along, 1)[0]
        out[name] = m
    return out


def test_no_error_no_misalignment(symptoms):
    m = symptoms["none"]
    assert abs(m["tilt"]) < 2e-4 and abs(m["shift"]) < 0.03 and abs(m["own_shear"]) < 1e-4


def test_roll_error_tilts_opposite_strips_across_track(symptoms):
    m, base = symptoms["roll"], symptoms["none"]
    expected = 2 * np.tan(np.radians(0.1))  # each strip tilts by δr, in opposite senses
    assert abs(m["tilt"] - base["tilt"]) == pytest.approx(expected, rel=0.15)
    assert abs(m["shift"] - base["shift"]) < 0.05  # and does not shift them along track


def test_pitch_error_shifts_opposite_strips_along_track(symptoms):
    m, base = symptoms["pitch"], symptoms["none"]
    expected = 2 * m["height"] * np.tan(np.radians(0.1))  # H·δp forward in each flight direction
    assert abs(m["shift"] - base["shift"]) == pytest.approx(expected, rel=0.15)
    assert abs(m["tilt"] - base["tilt"]) < 2e-4


def test_yaw_error_shears_strips_at_the_swath_edges(symptoms):
    m, base = symptoms["yaw"], symptoms["none"]
    dy = np.radians(0.2)
    # each strip is sheared: along-track displacement grows with distance from its line
    assert abs(m["own_shear"]) == pytest.approx(dy, rel=0.1)
    # in the overlap (edge of both swaths) the two shears differ by δy × line separation
    assert abs(m["shift"] - base["shift"]) == pytest.approx(dy * m["separation"], rel=0.2)
    assert abs(m["tilt"] - base["tilt"]) < 2e-4


@dataclass(frozen=True)
class ConeScanner:
    """A minimal rotating scanner (beam on a cone of half-angle ``cone`` around nadir), for pluggability."""

    cone: float = np.radians(15.0)
    model: str = "test-cone"
    units: ClassVar[dict] = {"cone": "rad"}

    def directions(self, angles):
        b = np.asarray(angles, float)
        return np.stack([np.sin(self.cone) * np.cos(b), np.sin(self.cone) * np.sin(b),
                         np.full_like(b, np.cos(self.cone))], axis=-1)

    def angles(self, directions):
        u = np.asarray(directions, float)
        return np.mod(np.arctan2(u[:, 1], u[:, 0]), 2 * np.pi)

    def parameters(self):
        return {"cone": self.cone}

    def with_parameters(self, **values):
        return replace(self, **values)

    def to_toml(self):
        return {"model": self.model, "cone_deg": float(np.degrees(self.cone))}


def test_any_scanner_model_plugs_in():
    nominal = Sensor(scanner=ConeScanner())
    cfg = survey_config("uav", seed=6, density=0.01, nominal=nominal, scan_rate_hz=20.0,
                        errors={"boresight_yaw": np.radians(0.1), "cone": np.radians(0.02)}, **NOISELESS)
    res = simulate_survey(cfg)
    swath = 2 * cfg.height_agl_m * np.tan(np.radians(15.0))  # the plan uses the cone's across-track extent
    assert len(res.lines) == int((cfg.scene.width_m - swath) / (swath * (1 - cfg.side_overlap))) + 1 == 12
    s = res.strips[0]
    assert np.allclose(s.angles, np.mod(2 * np.pi * 20.0 * np.sqrt(0.01) * s.gps_time, 2 * np.pi), atol=1e-6)
    for s in res.strips:
        ecef = georef.regeoreference(res.trajectory, res.nominal, res.truth, s.gps_time, s.ecef)
        assert np.max(np.linalg.norm(res.scene.ecef_to_enu(ecef) - s.true_enu, axis=1)) < 1e-6
    assert res.truth_dict()["parameters"]["cone"] == {"value": pytest.approx(15.02), "unit": "deg", "nominal": pytest.approx(15.0)}


def test_per_strip_trajectory_errors_move_each_strip_by_its_bias():
    res = simulate_survey(survey_config("uav", seed=7, density=0.01, strip_error_sigma=(0.2, 0, 0, 0), **NOISELESS))
    doc = res.truth_dict()["strips"]
    biases = np.array([s["position_bias_m"] for s in doc])
    assert np.all(np.abs(biases) > 0) and np.std(biases) > 0.05  # strips differ
    for strip, entry in zip(res.strips, doc):
        d_enu = res.scene.ecef_to_enu(strip.ecef) - strip.true_enu
        expected = frames.R_ENU_NED @ np.array(entry["position_bias_m"])  # NED bias seen in ENU
        assert np.allclose(np.median(d_enu, axis=0), expected, atol=2e-3)


def test_per_strip_attitude_bias_and_drift_reach_the_sbet():
    sigma = (0.0, 0.0, np.radians(0.05), np.radians(0.002))
    res = simulate_survey(survey_config("uav", seed=7, density=0.01, strip_error_sigma=sigma, **NOISELESS))
    tr, true = res.trajectory, res.trajectory_true
    for strip, entry in zip(res.strips, res.truth_dict()["strips"]):
        t_a, t_b = strip.gps_time[0], strip.gps_time[-1]
        k = np.flatnonzero((tr.time > t_a) & (tr.time < t_b))[::500]
        measured = np.degrees([tr.roll[k] - true.roll[k], tr.pitch[k] - true.pitch[k], tr.heading[k] - true.heading[k]])
        # bias + drift × (t − window middle); the scan window runs from the first to the last shot
        tc = tr.time[k] - 0.5 * (t_a + t_b)
        expected = np.array(entry["attitude_bias_deg"])[:, None] + np.array(entry["attitude_drift_deg_per_s"])[:, None] * tc
        assert np.allclose(measured, expected, atol=2e-4)


def test_linear_scan_patterns():
    from calidar.errors import InputError
    from calidar.sim.patterns import linear_pattern

    half, rate = np.radians(30.0), 50.0
    t = np.linspace(0.0, 1.0 / rate, 1001)
    osc = linear_pattern(t, rate, half, "oscillating")  # one period = two scan lines
    assert osc.max() == pytest.approx(half) and osc.min() == pytest.approx(-half) and osc[0] == pytest.approx(osc[-1])
    assert np.mean(np.isclose(np.abs(np.diff(osc)), 4 * half / 1000)) > 0.99  # constant angular speed
    poly = linear_pattern(t[:-1], rate, half, "polygon")  # sawtooth: one line per period, always the same way
    assert np.all(np.diff(poly) > 0) and poly[0] == pytest.approx(-half)
    with pytest.raises(InputError, match="scan_pattern"):
        linear_pattern(t, rate, half, "spiral")
    res = simulate_survey(survey_config("uav", seed=8, density=0.01, scan_pattern="polygon"))
    s = res.strips[0].scan_angle_deg[res.strips[0].return_number == 1]
    assert np.mean(np.diff(s) > 0) > 0.95  # polygon: scan angle rises shot after shot


def test_trajectory_errors_follow_the_smrmsg_written_beside_the_sbet(tmp_path):
    """σ per axis (down 1.5×, heading 10× the others) changing over the flight: the measured
    trajectory's errors divided by the σ the smrmsg.out states at their time are unit normal
    on every axis — over many draws: one short flight's errors are one sample of a process that
    wanders for 10 s, its own RMS 0.5–1.25× the σ and its mean over the flight part of the error
    (normalising each draw to its own std about its mean made the flight-wide part 1.3× what
    its σ says: issue 28) — and the file reads back as written."""
    from calidar.io.smrmsg import read_smrmsg
    from calidar.sim.motion import measured_trajectory

    res = simulate_survey(survey_config("uav", seed=4, density=0.005, trajectory_sigma_scale=(1, 1, 1.5, 1, 1, 10),
                                        trajectory_sigma_variation=0.5))
    res.write(tmp_path)
    acc = read_smrmsg(tmp_path / "smrmsg.out")
    t = res.trajectory.time
    assert np.allclose(acc.position_m, res.accuracy.position_m)
    assert len(acc) == np.floor(t[-1]) - np.ceil(t[0]) + 1 and np.all(np.diff(acc.time) == 1.0)  # 1 Hz, whole seconds
    tt = res.trajectory_true
    pos, att = acc.at(tt.time)

    def z_of(tm):
        d_ned = np.einsum("nji,nj->ni", frames.r_en(tt.lat, tt.lon), tm.ecef - tt.ecef)
        d_att = np.stack([tm.roll - tt.roll, tm.pitch - tt.pitch, np.angle(np.exp(1j * (tm.heading - tt.heading)))], 1)
        return np.concatenate([d_ned / pos, d_att / att], axis=1)

    z = z_of(res.trajectory)
    assert np.all((z.std(axis=0) > 0.3) & (z.std(axis=0) < 2.0)), z.std(axis=0)  # the survey's own draw
    draws = np.stack([z_of(measured_trajectory(tt, np.random.default_rng(k), pos, att)) for k in range(60)])
    rms = np.sqrt(np.mean(draws**2, axis=(0, 1)))  # 60 flights: ±0.05 (position) for honest σ
    assert np.allclose(rms, 1.0, atol=0.12), rms
    flight_mean = draws[:, :, :3].mean(axis=1)  # the flights' mean errors: part of the σ, not beyond it
    assert np.sqrt(np.mean(flight_mean**2)) < 0.6
    med = acc.medians()
    assert 7 < med["heading_rms_deg"] / med["roll_rms_deg"] < 14 and med["down_rms_m"] > med["north_rms_m"]
    assert acc.attitude_rad[:, 2].max() / acc.attitude_rad[:, 2].min() > 1.5  # it changes over the flight
