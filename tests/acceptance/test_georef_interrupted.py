"""An interrupted ``calidar inverse`` / ``regeoref`` (SIGTERM, SIGINT; a real subprocess) leaves no
temporary file and no partial result (issue 16)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from calidar import georef
from calidar.io import write_las, write_sbet
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory

N_POINTS = 3_000_000  #: enough for the run to last seconds after its temporary output appears


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    d = tmp_path_factory.mktemp("big")
    n = 2001
    t = 400000.0 + 0.01 * np.arange(n)
    tr = Trajectory(t, np.radians(37.7) + 1e-6 * np.arange(n), np.full(n, np.radians(-119.0)), np.full(n, 3000.0),
                    np.zeros(n), np.zeros(n), np.zeros(n))
    rng = np.random.default_rng(0)
    tp = np.sort(rng.uniform(t[1], t[-2], N_POINTS))
    xyz = georef.to_crs(georef.forward(tr, Sensor(), tp, rng.uniform(2500, 3000, N_POINTS),
                                       rng.uniform(-0.5, 0.5, N_POINTS)), "EPSG:32611")
    las = write_las(d / "big.las", xyz, "EPSG:32611", gps_time=tp, scan_angle_deg=np.zeros(N_POINTS), point_source_id=1)
    return las, write_sbet(d / "sbet.out", tr), Sensor().write(d / "s.toml")


@pytest.mark.parametrize("command", ["inverse", "regeoref"])
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_interrupted_run_leaves_nothing(survey, tmp_path, command, signum):
    las, sbet, toml = survey
    out = tmp_path / ("v.csv" if command == "inverse" else "out")
    args = ["--out", str(out)] if command == "inverse" else ["--from", str(toml), "--to", str(toml), "--out", str(out)]
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "calidar", command, str(las), "-t", str(sbet), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 120
    while not any(p.name.startswith(f".{out.name}") for p in tmp_path.iterdir()):  # the run's temporary output
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.02)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signum, err
    assert err.strip() == "interrupted" + (" (SIGTERM)" if signum == signal.SIGTERM else "")
    assert list(tmp_path.iterdir()) == []  # no temporary file, no partial result
