"""The bad-input corpus's inputs: one tiny simulated survey, one ATL03 simulation, one total-station
simulation (made by calidar's own ``simulate`` commands), and corrupt copies of them made with
numpy / laspy / h5py. Built once per test session into one folder; every case compares that
folder's files (their sha256) with the snapshot taken when it was built."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import h5py
import laspy
import numpy as np

SBET_FIELDS = 17  #: float64 per SBET record: time, lat, lon, height, 3 velocities, roll, pitch, heading, ...
SMRMSG_FIELDS = 10  #: float64 per smrmsg record: time, 3 position σ, 3 velocity σ, 3 attitude σ (arc-min)


def snapshot(root: Path) -> dict[str, str]:
    """sha256 of every file under ``root`` (relative path → digest)."""
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def build(root: Path, cli) -> None:
    """Simulate the three inputs into ``root`` with ``cli(*args) -> (code, out, err)``, then the
    corrupt copies into ``root/bad``."""
    for args in (("survey", "--density", "0.02"), ("total-station",), ("photons", "--length", "200")):
        code, _, err = cli("simulate", *args, "--out", root / args[0])
        assert code == 0, err
    bad = root / "bad"
    bad.mkdir()
    _sensors(root / "survey" / "sensor.toml", bad)
    _trajectories(root / "survey", bad)
    _strips(root / "survey" / "strips", bad)
    _photons(root / "photons", bad)
    _observations(root / "total-station" / "observations.csv", bad)
    _texts(bad)
    _control_planes(root / "survey" / "strips", bad)
    _links(root, bad)


def _sensors(good: Path, bad: Path) -> None:
    text = good.read_text()
    edits = {
        "sensor_nan.toml": ("boresight_roll_deg = 0.0", "boresight_roll_deg = nan"),
        "sensor_inf.toml": ("boresight_pitch_deg = 0.0", "boresight_pitch_deg = inf"),
        "sensor_roll1e6.toml": ("boresight_roll_deg = 0.0", "boresight_roll_deg = 1e6"),
        "sensor_scale.toml": ("scale_ppm = 0.0", "scale_ppm = -2e6"),
        "sensor_string.toml": ("boresight_yaw_deg = 0.0", 'boresight_yaw_deg = "abc"'),
        "sensor_typo.toml": ("boresight_yaw_deg", "boresight_yaw_dg"),
        "sensor_missing.toml": ("boresight_yaw_deg = 0.0\n", ""),
        "sensor_lever2.toml": ("lever_arm_m = [0.05, 0.0, 0.12]", "lever_arm_m = [0.05, 0.0]"),
        "sensor_lever_huge.toml": ("lever_arm_m = [0.05, 0.0, 0.12]", "lever_arm_m = [1e6, 0.0, 0.12]"),
        "sensor_model.toml": ('model = "linear"', 'model = "spiral"'),
        "sensor_syntax.toml": ("[mounting]", "[mounting"),
        "sensor_offset_nan.toml": ("offset_m = 0.0", "offset_m = nan"),
        "sensor_crs.toml": ('crs = "EPSG:32632"', 'crs = "EPSG:999999"'),
    }
    for name, (old, new) in edits.items():
        assert old in text, (name, old)
        (bad / name).write_text(text.replace(old, new))
    (bad / "sensor_empty.toml").write_text("")
    (bad / "sensor_latin1.toml").write_bytes("# capteur à balayage\n".encode("latin-1") + text.encode())


def _records(path: Path, n_fields: int) -> np.ndarray:
    return np.fromfile(path, dtype="<f8").reshape(-1, n_fields)


def _trajectories(survey: Path, bad: Path) -> None:
    sbet = _records(survey / "sbet.out", SBET_FIELDS)
    n = len(sbet)
    for name, col, value in (("sbet_height1e9.out", 3, 1e9), ("sbet_roll50rad.out", 7, 50.0),
                             ("sbet_nan_time.out", 0, np.nan), ("sbet_lat_deg.out", 1, 45.0)):
        a = sbet.copy()
        a[n // 2: n // 2 + 3, col] = value
        a.tofile(bad / name)
    back = sbet.copy()
    back[n // 2, 0] = back[0, 0] - 10.0
    back.tofile(bad / "sbet_backwards.out")
    sbet[: n // 20].tofile(bad / "sbet_short.out")  # 5 % of the flight: does not cover the strips
    t = laspy.read(survey / "strips" / "line_002.laz").gps_time
    mid = (float(t.min()) + float(t.max())) / 2
    sbet[np.abs(sbet[:, 0] - mid) > 5.0].tofile(bad / "sbet_gap.out")  # 10 s without records amid line 2
    (bad / "sbet_truncated.out").write_bytes((survey / "sbet.out").read_bytes()[:-7])
    (bad / "sbet_empty.out").write_bytes(b"")
    (bad / "sbet_text.out").write_text("this is not an SBET\n" * 17)

    acc = _records(survey / "smrmsg.out", SMRMSG_FIELDS)
    (bad / "acc_truncated.out").write_bytes((survey / "smrmsg.out").read_bytes()[:-3])
    (bad / "acc").mkdir()  # named as POSPac names it, away from the SBETs of bad/
    (bad / "acc" / "smrmsg_truncated.out").write_bytes((survey / "smrmsg.out").read_bytes()[:-3])
    for name, col, value in (("acc_negative.out", 1, -0.02), ("acc_nan.out", 8, np.nan), ("acc_huge.out", 3, 1e7)):
        a = acc.copy()
        a[len(a) // 2, col] = value
        a.tofile(bad / name)
    acc[:3].tofile(bad / "acc_short.out")  # three seconds: does not cover the strips

    deg = np.c_[sbet[:400, 0], np.degrees(sbet[:400, 1:3]), sbet[:400, 3], np.degrees(sbet[:400, 7:10])]
    header = "time,lat,lon,height,roll,pitch,heading\n"
    rows = "".join(",".join(f"{v:.9f}" for v in r) + "\n" for r in deg)
    (bad / "traj_latin1.txt").write_bytes(("# trajectoire lissée\n" + header).encode("latin-1") + rows.encode())
    (bad / "traj_nan.txt").write_text(header + rows.replace(rows.splitlines()[5], "nan,nan,nan,nan,nan,nan,nan", 1))
    (bad / "traj_words.txt").write_text(header + rows + "a,b,c,d,e,f,g\n")


def _las_subset(src: Path, dst: Path, n: int = 2000, edit=None) -> None:
    las = laspy.read(src)
    las.points = las.points[:n]
    if edit is not None:
        edit(las)
    las.write(dst)


def _trajectory_cases(first: Path, bad: Path) -> None:
    """What ``calidar trajectory`` cannot work with (issue 30): no GPS time, neither scan angles nor
    multi-return pulses, every pulse a line of its own, a line of 0.2 s."""
    las = laspy.read(first)
    laspy.convert(las, point_format_id=0, file_version="1.2").write(bad / "no_gps_time.las")

    def flat(d):  # one point a GPS time: no multi-return pulse
        d.points = d.points[np.unique(np.asarray(d.gps_time), return_index=True)[1]]
        d.scan_angle[:] = 0
        d.return_number[:], d.number_of_returns[:] = 1, 1
    _las_subset(first, bad / "no_scan_no_returns.laz", 20000, flat)

    def own_lines(d):
        flat(d)
        d.point_source_id[:] = np.arange(len(d.points)) % 60000
    _las_subset(first, bad / "one_pulse_per_line.laz", 20000, own_lines)
    t = np.asarray(las.gps_time)
    _las_subset(first, bad / "short_line.laz", int(np.searchsorted(np.sort(t), t.min() + 0.2)))


def _strips(strips: Path, bad: Path) -> None:
    first = strips / "line_001.laz"
    _las_subset(first, bad / "empty.laz", 0)
    _las_subset(first, bad / "a[b]c.laz", 0)
    shutil.copy(first, bad / "copy_of_line_001.laz")
    _las_subset(first, bad / "nan_time.las", edit=lambda d: d.gps_time.__setitem__(slice(10, 20), np.nan))
    _trajectory_cases(first, bad)

    def huge(d):
        d.header.offsets = np.array([1e300, 0.0, 0.0])
    _las_subset(first, bad / "huge.las", edit=huge)

    def far(d):
        d.x = d.x + 25_000.0
        d.point_source_id[:] = 9
    _las_subset(strips / "line_004.laz", bad / "far.laz", 10**9, far)
    _las_subset(first, bad / "count.las")
    # a "reference cloud" with no smooth cell: heights scattered by ±1 m (boresight --control rough.laz)
    _las_subset(first, bad / "rough.laz", 20000, lambda d: setattr(d, "z", d.z + np.random.default_rng(1).uniform(-1, 1, len(d.z))))
    raw = bytearray((bad / "count.las").read_bytes())
    raw[247:255] = np.uint64(3000).tobytes()  # LAS 1.4 point count: 3000 in the header, 2000 records
    (bad / "count.las").write_bytes(bytes(raw))
    raw[247:255] = np.uint64(1000).tobytes()  # and 1000: the reader would silently stop half-way
    raw[107:111] = np.uint32(1000).tobytes()
    (bad / "count_low.las").write_bytes(bytes(raw))
    (bad / "truncated.laz").write_bytes(first.read_bytes()[: first.stat().st_size // 2])
    (bad / "garbage.laz").write_text("not a point cloud\n" * 50)
    (bad / "strip[bold]x.laz").write_text("not a point cloud either\n")
    (bad / "zero.las").write_bytes(b"")
    from calidar.io.las import read_las, write_las

    p = read_las(first)
    write_las(bad / "geoid.laz", p.xyz[:2000], "EPSG:32632+3855", gps_time=p.gps_time[:2000],
              scan_angle_deg=p.scan_angle_deg[:2000], point_source_id=1)


def _photons(ph: Path, bad: Path) -> None:
    src = ph / "ATL03_sim.h5"
    shutil.copy(src, bad / "atl03_zero.h5")
    with h5py.File(bad / "atl03_zero.h5", "r+") as f:
        for group in ("heights", "geolocation"):
            g = f[f"gt1l/{group}"]
            for name in list(g):
                d = g[name]
                shape, dtype = (0, *d.shape[1:]), d.dtype
                del g[name]
                g.create_dataset(name, shape=shape, dtype=dtype)
    for name, field, value in (("atl03_badlat.h5", "lat_ph", 200.0), ("atl03_nan_h.h5", "h_ph", np.nan),
                               ("atl03_nan_time.h5", "delta_time", np.nan)):
        shutil.copy(src, bad / name)
        with h5py.File(bad / name, "r+") as f:
            f[f"gt1l/heights/{field}"][5] = value
    with h5py.File(bad / "not_atl03.h5", "w") as f:
        f["x"] = np.arange(3)
    (bad / "atl03_truncated.h5").write_bytes(src.read_bytes()[:2000])
    (bad / "atl03_text.h5").write_text("not HDF5\n")
    ccr = (ph / "ccr.csv").read_text()
    head, first, *rest = ccr.splitlines()
    (bad / "ccr_latin1.csv").write_bytes(("# réflecteurs\n" + ccr).encode("latin-1"))
    (bad / "ccr_nocol.csv").write_text("id,lat,lon\n" + "".join(r.rsplit(",", 1)[0] + "\n" for r in [first, *rest]))
    (bad / "ccr_nan.csv").write_text(ccr.replace(first, first.split(",")[0] + ",nan,-106.4,3.0"))
    (bad / "ccr_lat100.csv").write_text(ccr.replace(first, first.split(",")[0] + ",100.0,-106.4,3.0"))
    (bad / "ccr_empty.csv").write_text(head + "\n")


def _observations(obs: Path, bad: Path) -> None:
    lines = obs.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("setup,"))
    cols = lines[k].split(",")
    si, zi, hi = cols.index("scanner_m"), cols.index("slope_m"), cols.index("zd_deg")

    def edit(name, fn, only_first=False):
        rows = []
        done = False
        for line in lines[k + 1:]:
            parts = line.split(",")
            if parts[si] and not (only_first and done):
                fn(parts)
                done = True
            rows.append(",".join(parts))
        (bad / name).write_text("\n".join(lines[: k + 1] + rows) + "\n")

    edit("obs_mm.csv", lambda p: p.__setitem__(si, f"{float(p[si]) * 1000:.1f}"))
    edit("obs_nan.csv", lambda p: p.__setitem__(zi, "nan"), only_first=True)
    edit("obs_negative.csv", lambda p: p.__setitem__(zi, "-7.5"), only_first=True)
    edit("obs_zd400.csv", lambda p: p.__setitem__(hi, "400.0"), only_first=True)
    (bad / "obs_nocol.csv").write_text("\n".join(lines[:k] + [",".join(r.split(",")[:-1]) for r in lines[k:]]) + "\n")
    (bad / "obs_header.csv").write_text("\n".join(lines[: k + 1]) + "\n")
    (bad / "obs_latin1.csv").write_bytes("\n".join(lines[:1] + ["# relevé à Zürich"] + lines[1:]).encode("latin-1"))


def _control_planes(strips: Path, bad: Path) -> None:
    """``calidar boresight --control`` control-surface files (issue 28), each wrong in one way, placed
    over the survey's first strip (its CRS)."""
    x, y, z = laspy.read(next(iter(sorted(strips.glob("*.laz"))))).header.mins + [20.0, 20.0, 10.0]
    roof = [(x, y, z), (x + 8, y, z), (x + 8, y + 6, z + 3), (x, y + 6, z + 3)]

    def write(name, rows, head="plane,x,y,z,sigma"):
        (bad / name).write_text(head + "\n" + "".join(",".join(str(v) for v in r) + "\n" for r in rows))

    write("planes_nosigma.csv", [("R1", *p) for p in roof], "plane,x,y,z")
    write("planes_nan.csv", [("R1", *p, 0.01) for p in roof[:2]] + [("R1", x + 8, y + 6, "nan", 0.01), ("R1", *roof[3], 0.01)])
    write("planes_two.csv", [("R1", *p, 0.01) for p in roof[:2]])
    write("planes_sigma0.csv", [("R1", *p, 0.0) for p in roof])
    write("planes_line.csv", [("R1", x + k, y, z, 0.01) for k in (0, 4, 8)])
    write("planes_off.csv", [("R1", *p, 0.01) for p in roof[:3]] + [("R1", x, y + 6, z + 3.4, 0.01),
                                                                    ("R1", x + 4, y + 3, z + 1.5, 0.01)])


def _texts(bad: Path) -> None:
    (bad / "truth_latin1.json").write_bytes('{"note": "vérité"}'.encode("latin-1"))
    (bad / "truth_notjson.json").write_text("{not json")
    (bad / "truth_list.json").write_text("[1, 2]\n")
    configs = {  # calidar boresight --config files, each wrong in one key
        "config_unknown.toml": 'estimate = ["boresight"]\n\n[solver]\nmax_outer = 8\nwobble = 1\n',
        "config_unknown_section.toml": '[trajectory]\nblock_s = 1.0\n',
        "config_type.toml": '[trajectory_model]\nblock_s = "one"\n',
        "config_estimate.toml": 'estimate = ["boresight", "everything"]\n',
        "config_estimate_text.toml": 'estimate = "boresight"\n',
        "config_method.toml": 'method = ["icp"]\n',
        "config_sigma.toml": '[trajectory_model]\nsigma = [0.03]\n',
        "config_block.toml": '[trajectory_model]\nblock_s = -1.0\n',
        "config_shape.toml": '[trajectory_model]\nshape = ["gm1", "gm3"]\n',
        "config_off.toml": '[trajectory_model]\non = false\nsigma = [0.03, 0.002]\n',
        "config_model_check.toml": 'model_check = "on"\n',
        "config_vgicp.toml": 'method = ["vgicp"]\n\n[vgicp]\nvoxel_m = [8.0, -2.0]\n',
        "config_crs.toml": '[inputs]\ncrs = "EPSG:999999"\n',
        "config_strip_points.toml": '[ingest]\nstrip_points = 1.5\n',
        "config_not_toml.toml": 'estimate = [boresight\n',
        # calidar range-cal / ccr / tpu --config files
        "rangecal_tolerance.toml": 'tolerance_m = -1.0\n',
        "rangecal_unknown.toml": 'tolerence_m = 0.05\n',
        "rangecal_fix_scale.toml": 'fix_scale = "yes"\n',
        "ccr_step.toml": '[search]\ndiameter_step = 5.0\n',
        "ccr_range.toml": '[search]\ndiameter_min = 15.0\ndiameter_max = 8.0\n',
        "ccr_beams.toml": 'beams = ["gt9x"]\n',
        "ccr_system.toml": '[system]\ndead_time_s = "fast"\n',
        "ccr_unknown.toml": '[system]\ndead_time_ns = 3.2\n',
        "tpu_noise.toml": '[noise]\nrange_sigma_m = -0.01\n',
        "tpu_sigma.toml": 'trajectory_sigma = [0.05]\n',
        "tpu_crs.toml": '[inputs]\ncrs = "EPSG:999999"\n',
        "tpu_unknown.toml": '[noise]\nangle_sigma_deg = 0.002\n',
        # quality / accuracy / plan / scanner analyze / denoise / georef / trajectory --config files
        "quality_cell.toml": 'cell_m = 0.0\n',
        "quality_classes.toml": 'classes = [2, 300]\n',
        "accuracy_radius.toml": 'radius_m = -1.0\n',
        "accuracy_crs.toml": 'checkpoints_crs = "EPSG:0"\n',
        "plan_estimate.toml": 'estimate = ["heading"]\n',
        "plan_terrain.toml": '[terrain]\nkind = "moon"\n',
        "scanner_model.toml": 'model = "spiral"\nrange_m = 100.0\n',
        "scanner_error.toml": 'model = "palmer"\nrange_m = 100.0\n\n[errors]\nscan_angle_offset_deg = 0.1\n',
        "denoise_beams.toml": 'beams = ["gt9x"]\n',
        "denoise_spacing.toml": 'shot_spacing_m = "0.7 m"\n',
        "georef_geoid.toml": 'geoid_undulation_m = 1e6\n',
        "trajectory_rate.toml": 'rate_hz = 0.0\n',
        "trajectory_mount.toml": '[mount_sigma]\nscan_scale = -1.0\n',
    }
    for name, text in configs.items():
        (bad / name).write_text(text)
    (bad / "leeward_latin1.toml").write_bytes("# étalonnage\nutm_zone = 11\n".encode("latin-1"))
    (bad / "leeward_nan.toml").write_text("utm_zone = 11\nlever_arm = [0, 0, 0]\n\n[boresight]\nroll = nan\n"
                                          "pitch = 0\nyaw = 0\n")
    (bad / "leeward_missing.toml").write_text("utm_zone = 11\nlever_arm = [0, 0, 0]\n")
    (bad / "scan2imu_15.txt").write_text(" ".join(["1"] * 15) + "\n")
    (bad / "scan2imu_nan.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 nan 0 0 0 1\n")
    (bad / "scan2imu_skew.txt").write_text("2 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n")
    (bad / "garbage.csd").write_bytes(bytes(range(256)) * 4)


def _links(root: Path, bad: Path) -> None:
    """A hard link to the ATL03 file and a symbolic link to the strips' folder: outputs that would
    overwrite an input under another name."""
    import os

    os.link(root / "photons" / "ATL03_sim.h5", bad / "atl03_hardlink.csv")
    (bad / "strips_link").symlink_to(root / "survey" / "strips", target_is_directory=True)
