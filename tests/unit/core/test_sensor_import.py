"""Vendor mounting conventions → calidar's R_bs and lever arm (docs/sensor.md): each conversion
against an independent evaluation of the vendor's own published equation."""

from __future__ import annotations

import numpy as np
import pytest

from calidar import frames, georef
from calidar.errors import InputError
from calidar.io import read_las
from calidar.io.optech_csd import CsdHeader, read_csd
from calidar.sensor import Sensor
from calidar.sensor_import import (
    axes, from_leeward, from_optech_header, from_scan2imu, from_vendor, import_sensor, lever_arm_from_pospac,
    read_scan2imu,
)
from calidar.trajectory import Trajectory

RNG = np.random.default_rng(7)
SAMPLE = "optech_csd/sample.csd"


def _calidar_body(sensor: Sensor, rho, theta):
    """calidar's body-frame vector of a linear-scanner return: R_bs · ρ (0, sin θ, cos θ) + a_b."""
    return sensor.r_bs @ (rho * np.array([0.0, np.sin(theta), np.cos(theta)])) + sensor.lever_arm


def _zyx(roll, pitch, yaw):
    """Rz(yaw) · Ry(pitch) · Rx(roll) written out entry by entry (leeward's RollPitchYaw::as_matrix,
    PDAL's georeference Utils::getTransformation)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, sy * sr + cy * sp * cr],
                     [sy * cp, cy * cr + sy * sp * sr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _optech(roll, pitch, heading):
    """Optech's matrix as PDAL's io/OptechCommon.hpp writes it, entry by entry."""
    cr, sr, cp, sp, ch, sh = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(heading), np.sin(heading)
    return np.array([[cr * ch + sp * sr * sh, cp * sh, ch * sr - cr * sp * sh],
                     [ch * sp * sr - cr * sh, cp * ch, -sr * sh - cr * ch * sp],
                     [-cp * sr, sp, cp * cr]])


def _pdal_equation(p):
    """PDAL's readers.optech equation (pdal/util/Georeference.cpp), evaluated independently: the
    local-level vector M(attitude)·M(boresight)·ρ(sin α, 0, −cos α) turned into latitude/longitude
    offsets with the radii of curvature at the aircraft (no Earth curvature beyond that)."""
    a, f = 6378137.0, 1 / 298.257223563
    e2 = 2 * f - f * f
    b = np.add(p.header.misalignment_rad, p.header.imu_offsets_rad)
    out = []
    for k in range(len(p)):
        rho, alpha = p.range_m[k, 0], p.scan_angle[k]
        enu = _optech(p.roll[k], p.pitch[k], p.heading[k]) @ _optech(*b) @ [rho * np.sin(alpha), 0, -rho * np.cos(alpha)]
        w = np.sqrt(1 - e2 * np.sin(p.lat[k]) ** 2)
        out.append((np.degrees(p.lon[k] + enu[0] * w / (a * np.cos(p.lat[k]))),
                    np.degrees(p.lat[k] + enu[1] * w ** 3 / (a * (1 - e2))), p.height[k] + enu[2]))
    return np.array(out)


def test_georef_csd_agrees_with_pdal_equation(real_data, tmp_path):
    """calidar's lidar equation (exact in ECEF) and PDAL's local-level approximation of the same
    Optech conventions agree to centimetres: 14 mm horizontally, 5 mm vertically (a sign or axis
    mistake would be metres)."""
    from calidar.pipelines.georef import georeference_csd

    r = georeference_csd(real_data / SAMPLE, tmp_path / "p.las", crs="EPSG:4979")
    pts = read_las(r.points)
    pdal = georef.to_crs(georef.from_crs(_pdal_equation(read_csd(real_data / SAMPLE)), "EPSG:4979"), "EPSG:32617")
    ours = georef.to_crs(georef.from_crs(pts.xyz, "EPSG:4979"), "EPSG:32617")
    d = np.abs(ours - pdal)
    assert d[:, :2].max() < 0.02 and d[:, 2].max() < 0.01


def test_axes_maps():
    assert np.array_equal(axes("x,y,z"), np.eye(3))
    m = axes("y,x,-z")  # calidar x = vendor y, y = vendor x, z = −vendor z
    assert np.array_equal(m @ [1.0, 2.0, 3.0], [2.0, 1.0, -3.0])
    for bad in ("x,y", "x,x,z", "y,x,z", "x,y,w", "x,y,z,x"):
        with pytest.raises(InputError, match="right-handed"):
            axes(bad)


@pytest.mark.parametrize("k", range(5))
def test_optech_equals_pdal_georeference(k):
    """PDAL's Optech equation, local level (east, north, up): M(attitude) · M(boresight) · ρ (sin α, 0,
    −cos α). calidar's: R_nb · R_bs · ρ (0, sin α, cos α) in NED, R_bs from the header: the same
    vector (NED = the ENU axes swapped and z negated)."""
    att, mis, imu = RNG.uniform(-0.3, 0.3, 3), RNG.uniform(-0.05, 0.05, 3), RNG.uniform(-0.01, 0.01, 3)
    rho, alpha = 830.0, RNG.uniform(-0.3, 0.3)
    header = CsdHeader("Optech", "DASHMap", 5.2, 2048, 1660, (0.0, 1.0), 1, 1, tuple(mis), tuple(imu), 13.0, 1000.0)
    enu = _optech(*att) @ _optech(*(mis + imu)) @ (rho * np.array([np.sin(alpha), 0.0, -np.cos(alpha)]))
    sensor = from_optech_header(header)
    ned = frames.rpy_to_matrix(*att) @ _calidar_body(sensor, rho, alpha)
    assert np.allclose(ned, [enu[1], enu[0], -enu[2]], atol=1e-9)
    # the angles carry over: calidar's boresight roll/pitch/yaw are Optech's (summed) angles
    assert [sensor.boresight_roll, sensor.boresight_pitch, sensor.boresight_yaw] == pytest.approx(mis + imu, abs=1e-12)
    assert np.all(sensor.lever_arm == 0)


def _leeward_config(path, roll, pitch, yaw, lever):
    path.write_text(f"utm_zone = 11\nlever_arm = [{', '.join(map(str, lever))}]\n\n[boresight]\nroll = {roll!r}\n"
                    f"pitch = {pitch!r}\nyaw = {yaw!r}\n")
    return path


def test_leeward_equals_its_lidar_equation(tmp_path):
    """leeward (src/measurement.rs): body = R(roll, pitch, yaw) · ρ (cos α, 0, sin α) − lever_arm."""
    rpy, lever = (-1.52, -1.6, 0.03), np.array([0.3, -0.2, 0.5])
    sensor = from_leeward(_leeward_config(tmp_path / "c.toml", *rpy, lever))
    for alpha in (-0.4, 0.0, 0.25):
        body = _zyx(*rpy) @ (4500.0 * np.array([np.cos(alpha), 0.0, np.sin(alpha)])) - lever
        assert np.allclose(_calidar_body(sensor, 4500.0, alpha), body, atol=1e-9)
    assert np.allclose(sensor.lever_arm, -lever)


def test_leeward_real_config(real_data):
    """roll = pitch = −1.54 rad, yaw 0: the axis swap (−π/2, −π/2) plus 1.76° — calidar roll 0.054°,
    pitch 1.764°, yaw 1.765° (what the file says; docs/sensor.md compares it with the data)."""
    s = from_leeward(real_data / "leeward_sierra" / "config.toml")
    assert np.degrees([s.boresight_roll, s.boresight_pitch, s.boresight_yaw]) == pytest.approx(
        [0.0543, 1.7637, 1.7653], abs=1e-4)
    assert np.all(s.lever_arm == 0)
    exact = from_vendor(frames.rpy_to_matrix(-np.pi / 2, -np.pi / 2, 0.0), np.zeros(3), "x,y,z", "y,z,x")
    assert np.allclose([exact.boresight_roll, exact.boresight_pitch, exact.boresight_yaw], 0.0, atol=1e-12)


def test_scan2imu_equals_pdal_georeference():
    """PDAL filters.georeference (NED): ned = getTransformation(roll, pitch, yaw) · scan2imu · p, p in
    the scanner's own frame. A scanner whose beam is p = ρ (cos α, −sin α, 0): calidar's scanner
    axes x,y,z are its z, −y, x."""
    r = frames.rpy_to_matrix(*RNG.uniform(-0.5, 0.5, 3))
    t = np.array([0.12, -0.34, 0.56])
    sensor = from_scan2imu(np.r_[np.c_[r, t], [[0, 0, 0, 1]]], scanner="z,-y,x")
    att = RNG.uniform(-0.2, 0.2, 3)
    for alpha in (-0.5, 0.1, 0.6):
        ned = _zyx(*att) @ (r @ (100.0 * np.array([np.cos(alpha), -np.sin(alpha), 0.0])) + t)
        assert np.allclose(frames.rpy_to_matrix(*att) @ _calidar_body(sensor, 100.0, alpha), ned, atol=1e-9)


def test_scan2imu_files(tmp_path):
    m = np.r_[np.c_[frames.rpy_to_matrix(0.1, 0.2, 0.3), [1, 2, 3]], [[0, 0, 0, 1]]]
    text = " ".join(f"{v:.15f}" for v in m.ravel())
    (tmp_path / "m.txt").write_text(text)
    (tmp_path / "p.json").write_text('{"pipeline": ["in.rxp", {"type": "filters.georeference", "scan2imu": "'
                                     + text + '"}, "out.las"]}')
    for f in ("m.txt", "p.json"):
        assert np.allclose(read_scan2imu(tmp_path / f), m, atol=1e-12)
    (tmp_path / "s.txt").write_text(" ".join(["1"] * 16))
    with pytest.raises(InputError, match="expected a rigid transformation"):
        read_scan2imu(tmp_path / "s.txt")
    (tmp_path / "short.txt").write_text("1 0 0 0 1")
    with pytest.raises(InputError, match="expected 16 finite numbers"):
        read_scan2imu(tmp_path / "short.txt")
    with pytest.raises(InputError, match="--scanner-axes: only for --from pdal-scan2imu"):
        import_sensor("leeward", tmp_path / "m.txt", "y,x,-z")
    with pytest.raises(InputError, match="--from: expected one of leeward, optech-csd, pdal-scan2imu"):
        import_sensor("riegl", tmp_path / "m.txt")


def _line(n=50):
    t = 1000.0 + 0.01 * np.arange(n)
    lat, lon = np.radians(45.0) + 1e-7 * np.arange(n), np.full(n, np.radians(7.0))
    return Trajectory(t, lat, lon, np.full(n, 800.0), np.full(n, 0.05), np.full(n, 0.03), np.full(n, 0.4))


def test_pospac_lever_arms_land_points_alike():
    """An SBET output at the POS reference point with a_b = ref→sensor, and the same flight output at
    the IMU with a_b = ref→sensor − ref→IMU, give the same points."""
    ref_to_sensor, ref_to_imu = np.array([0.8, -0.25, 0.4]), np.array([-0.3, 0.2, 0.15])
    at_ref = _line()
    pos, q = at_ref.interpolate(at_ref.time)
    imu_e = pos + np.einsum("nij,j->ni", frames.quat_to_matrix(q), ref_to_imu)
    lat, lon, h = frames.ecef_to_geodetic(imu_e)  # the same body axes, in the IMU's own local level
    r_nb = np.swapaxes(frames.r_en(lat, lon), 1, 2) @ frames.quat_to_matrix(q)
    at_imu = Trajectory(at_ref.time, lat, lon, h, *frames.matrix_to_rpy(r_nb))
    t, rng_m, ang = at_ref.time[5:-5], np.full(40, 750.0), np.linspace(-0.3, 0.3, 40)
    p_ref = georef.forward(at_ref, Sensor(lever_arm_x=ref_to_sensor[0], lever_arm_y=ref_to_sensor[1],
                                          lever_arm_z=ref_to_sensor[2]), t, rng_m, ang)
    a_b = lever_arm_from_pospac(ref_to_sensor, ref_to_imu)
    p_imu = georef.forward(at_imu, Sensor(lever_arm_x=a_b[0], lever_arm_y=a_b[1], lever_arm_z=a_b[2]), t, rng_m, ang)
    assert np.max(np.abs(p_ref - p_imu)) < 1e-7  # m


def test_leica_lever_arm_axes():
    """Offsets measured x forward, y to port, z up (as NERC-ARF's Leica notes give them): calidar's
    body axes are x, −y, −z of those."""
    s = from_vendor(np.eye(3), [0.169, 0.102, 0.090], body="x,-y,-z", scanner="x,-y,-z")
    assert np.allclose(s.lever_arm, [0.169, -0.102, -0.090])
    assert np.allclose(s.r_bs, np.eye(3))  # same axes on both sides: no rotation
