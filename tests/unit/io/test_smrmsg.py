"""The trajectory's accuracy: POSPac smrmsg files, σ columns of text trajectories, where they are found."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.io.smrmsg import find_beside, read_smrmsg, write_smrmsg
from calidar.trajectory import Trajectory
from calidar.trajectory_accuracy import TrajectoryAccuracy

REAL = "pospac_smrmsg/smrmsg.smrmsg"


def _own_reading(path):
    """The file as the format says, read here independently: 80-byte records of 10 little-endian
    float64 — time, north/east/down RMS (m), 3 velocity RMS (m/s), roll/pitch/heading RMS (arc-minutes)."""
    raw = path.read_bytes()
    n = len(raw) // 80
    rec = np.frombuffer(raw, dtype=np.dtype("<f8")).reshape(n, 10)
    return n, rec


def test_real_smrmsg_reads_as_its_bytes_say(real_data):
    path = real_data / REAL
    n, rec = _own_reading(path)
    acc = read_smrmsg(path)
    assert len(acc) == n == 21902 and path.stat().st_size == 80 * n
    assert (acc.time[0], acc.time[-1]) == (536258.0, 558159.0)  # 1 Hz over 21 901 s
    med = acc.medians()
    for k, name in enumerate(("north_rms_m", "east_rms_m", "down_rms_m")):
        assert med[name] == pytest.approx(np.median(rec[:, 1 + k]), rel=1e-12)
    for k, name in enumerate(("roll_rms_deg", "pitch_rms_deg", "heading_rms_deg")):
        assert med[name] == pytest.approx(np.median(rec[:, 7 + k]) / 60.0, rel=1e-12)  # arc-minutes → degrees
    # what a POSPac solution says about itself: a few cm, 0.002° roll/pitch, heading ~8× worse
    assert 0.03 < med["north_rms_m"] < 0.06 and 0.002 < med["roll_rms_deg"] < 0.003
    assert 6 < med["heading_rms_deg"] / med["roll_rms_deg"] < 10


def test_info_prints_records_span_and_medians(cli, real_data):
    code, out, err = cli("info", real_data / REAL, "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["records"] == 21902 and d["time_start_s"] == 536258.0 and d["time_end_s"] == 558159.0
    assert set(d["median"]) == {"north_rms_m", "east_rms_m", "down_rms_m", "roll_rms_deg", "pitch_rms_deg",
                                "heading_rms_deg"}
    code, out, err = cli("info", real_data / REAL)
    assert code == 0 and "heading_rms_deg" in out


def test_write_read_round_trip(tmp_path):
    t = 1000.0 + np.arange(5.0)
    pos = np.array([[0.03, 0.04, 0.05]]) * (1 + np.arange(5))[:, None]
    att = np.radians([[0.002, 0.0025, 0.02]]).repeat(5, 0)
    back = read_smrmsg(write_smrmsg(tmp_path / "smrmsg.out", TrajectoryAccuracy(t, pos, att)))
    assert np.array_equal(back.time, t) and np.allclose(back.position_m, pos, rtol=0, atol=1e-15)
    assert np.allclose(back.attitude_rad, att, rtol=1e-15)
    # between epochs σ are interpolated linearly; outside them the end values are held
    p, a = back.at([1000.5, 999.0, 1010.0])
    assert p[0, 0] == pytest.approx(0.045) and p[1, 0] == pytest.approx(0.03) and p[2, 0] == pytest.approx(0.15)


def _raw(tmp_path, rec, extra_bytes=b""):
    path = tmp_path / "smrmsg_bad.out"
    path.write_bytes(np.asarray(rec, "<f8").tobytes() + extra_bytes)
    return path


GOOD = [[1000.0, 0.03, 0.03, 0.05, 0.01, 0.01, 0.01, 0.12, 0.12, 1.0],
        [1001.0, 0.03, 0.03, 0.05, 0.01, 0.01, 0.01, 0.12, 0.12, 1.0]]


@pytest.mark.parametrize("change, field, problem", [
    (lambda r: r, "size", "expected a multiple of 80 bytes"),  # 3 stray bytes appended below
    (lambda r: r[:1] + [r[1][:3] + [float("nan")] + r[1][4:]], "down_rms", "expected finite values in [0, 100] m, got nan (1 of 2 values, first at record 1)"),
    (lambda r: [r[0][:8] + [-0.1] + r[0][9:]] + r[1:], "pitch_rms", "expected finite values in [0, 600] arc-min, got -0.1"),
    (lambda r: [r[1], r[0]], "time", "expected strictly increasing times"),
])
def test_bad_smrmsg_names_file_and_field(tmp_path, change, field, problem):
    path = _raw(tmp_path, change([list(x) for x in GOOD]), b"abc" if field == "size" else b"")
    with pytest.raises(InputError) as e:
        read_smrmsg(path)
    assert str(e.value).startswith(f"{path}: {field}: ") and problem in str(e.value)


def test_times_not_covering_the_strips_name_the_file(tmp_path):
    acc = read_smrmsg(_raw(tmp_path, GOOD))
    acc.check_covers({1: (1000.2, 1000.9)})  # inside
    acc.check_covers({1: (999.5, 1001.5)})  # one epoch's spacing of slack
    with pytest.raises(InputError, match=r"smrmsg_bad.out: time: the accuracy file covers 1000.000–1001.000 s, "
                                         r"but 1 of 2 strips \(7\) have times 1000.500–1100.000 s outside it"):
        acc.check_covers({1: (1000.0, 1001.0), 7: (1000.5, 1100.0)})


def test_found_beside_the_sbet(tmp_path):
    (tmp_path / "sbet_047.out").write_bytes(b"")
    assert find_beside(tmp_path / "sbet_047.out") is None
    (tmp_path / "smrmsg_012.out").write_bytes(b"")
    assert find_beside(tmp_path / "sbet_047.out") == tmp_path / "smrmsg_012.out"  # the only one
    (tmp_path / "smrmsg_099.out").write_bytes(b"")
    with pytest.raises(InputError, match="found 2 smrmsg files beside it .* none named smrmsg_047.out"):
        find_beside(tmp_path / "sbet_047.out")
    (tmp_path / "SMRMSG_047.out").write_bytes(b"")
    assert find_beside(tmp_path / "sbet_047.out") == tmp_path / "SMRMSG_047.out"  # the SBET's own
    assert find_beside(tmp_path / "trajectory.txt") is None


def test_text_trajectory_sigma_columns(tmp_path):
    from calidar.io.trajectory import read_trajectory
    from calidar.pipelines.boresight import resolve_accuracy

    head = "time,lat,lon,height,roll,pitch,heading,SDNorth,SDEast,SDHeight,SDRoll,SDPitch,SDHeading\n"
    rows = "".join(f"{1000 + k},45.0,7.0,500,0.1,0.2,{30 + k},0.02,0.03,0.05,0.002,0.003,{0.01 * (k + 1)}\n"
                   for k in range(3))
    path = tmp_path / "traj.csv"
    path.write_text(head + rows)
    traj = read_trajectory(path)
    acc, found, note = resolve_accuracy(path, traj)
    assert note is None and "σ columns" in acc.source
    assert np.allclose(acc.position_m[0], [0.02, 0.03, 0.05])
    assert np.allclose(np.degrees(acc.attitude_rad[:, 2]), [0.01, 0.02, 0.03])  # the file's degrees, in rad
    path.write_text(head.replace(",SDHeading", "") + "".join(r.rsplit(",", 1)[0] + "\n" for r in rows.splitlines()))
    with pytest.raises(InputError, match=r"traj.csv: columns: has the σ columns .* but not \['sigma_heading'\]"):
        read_trajectory(path)
    path.write_text(head + rows.replace("0.03,0.05,0.002", "0.03,-0.05,0.002", 1))
    with pytest.raises(InputError, match="traj.csv: sigma_down: expected finite values in"):
        read_trajectory(path)
    # no source at all: the survey-grade default, and a note that says so
    plain = Trajectory(traj.time, traj.lat, traj.lon, traj.height, traj.roll, traj.pitch, traj.heading)
    acc, found, note = resolve_accuracy(tmp_path / "sbet.out", plain)
    assert found is None and note.startswith("no trajectory accuracy found") and acc.constant
