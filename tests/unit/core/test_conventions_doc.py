"""docs/conventions.md's worked example, recomputed."""

import re
from pathlib import Path

import numpy as np

from calidar import frames, georef
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory

DOC = Path(__file__).resolve().parents[3] / "docs" / "conventions.md"


def _documented() -> dict[str, np.ndarray]:
    block = re.search(r"```text\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S).group(1)
    return {k.strip(): np.array([float(x) for x in v.split(",")]) for k, v in (ln.split("=") for ln in block.strip().splitlines())}


def test_worked_example_matches_the_code():
    doc = _documented()
    d = np.radians
    tr = Trajectory(np.array([0.0, 1.0]), np.full(2, d(45.0)), np.full(2, d(7.0)), np.full(2, 1000.0),
                    np.full(2, d(10.0)), np.zeros(2), np.full(2, d(90.0)))
    p = georef.forward(tr, Sensor(lever_arm_x=1.0), np.array([0.5]), np.array([1000.0]), np.array([d(10.0)]))[0]
    lat, lon, h = frames.ecef_to_geodetic(p)
    computed = {
        "imu_ecef_m": tr.ecef[0],
        "point_ned_m": frames.r_en(d(45.0), d(7.0)).T @ (p - tr.ecef[0]),
        "point_ecef_m": p,
        "point_lat_lon_deg": np.degrees([lat, lon]),
        "point_height_m": np.array([h]),
    }
    assert set(doc) == set(computed)
    for k, v in computed.items():
        tol = 1e-9 if k == "point_lat_lon_deg" else 1e-6
        assert np.allclose(doc[k], v, atol=tol, rtol=0), (k, doc[k], v)
