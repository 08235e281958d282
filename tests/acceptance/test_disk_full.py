"""Every command that writes, on a full disk and on a read-only file system (issue 27): exit 1,
one line naming ``--out`` and the cause, nothing left behind, the inputs unchanged. Real
subprocesses writing onto a small tmpfs (mounted by the test: it needs root; skipped where
mounting is not permitted), filled to the last byte."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

ENV = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
FREE_BYTES = 0  #: left free on the tmpfs: the smallest output (a sensor.toml) needs a page

S = "{S}"
STRIPS = [f"{S}/strips/line_001.laz", f"{S}/strips/line_002.laz", f"{S}/strips/line_003.laz", f"{S}/strips/line_004.laz"]
TRAJ = ["--trajectory", f"{S}/sbet.out"]
#: (id, arguments, output name: a folder or a file inside the tmpfs)
COMMANDS = [
    ("simulate-photons", ["simulate", "photons", "--length", "200"], "o"),
    ("simulate-total-station", ["simulate", "total-station"], "o"),
    ("simulate-survey", ["simulate", "survey", "--density", "0.02"], "o"),
    ("boresight", ["boresight", *STRIPS, *TRAJ, "--sensor", f"{S}/sensor.toml"], "o"),
    ("boresight-write-strips", ["boresight", *STRIPS, *TRAJ, "--sensor", f"{S}/sensor.toml", "--write-strips"], "o"),
    ("regeoref", ["regeoref", *STRIPS[:2], *TRAJ, "--from", f"{S}/sensor.toml", "--to", f"{S}/sensor.toml"], "o"),
    ("inverse", ["inverse", STRIPS[0], *TRAJ], "o.csv"),
    ("quality", ["quality", *STRIPS], "o"),
    ("range-cal", ["range-cal", "{T}/observations.csv"], "o"),
    ("ccr", ["ccr", "{P}/ATL03_sim.h5", "--ccr", "{P}/ccr.csv", "--bootstrap", "2"], "o"),
    ("denoise", ["denoise", "{P}/ATL03_sim.h5"], "o.csv"),
    ("scanner-analyze", ["scanner", "analyze", "--model", "linear", "--range", "100"], "o"),
    ("sensor-import", ["sensor", "import", "{X}", "--from", "pdal-scan2imu"], "o.toml"),
]


@pytest.fixture(scope="module")
def tmpfs(tmp_path_factory):
    d = tmp_path_factory.mktemp("tmpfs")
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(d)], capture_output=True).returncode:
        pytest.skip("mounting a tmpfs is not permitted here")
    yield d
    subprocess.run(["umount", str(d)], check=True)


def _fill(d, free: int) -> None:
    """Fill the tmpfs ``d`` but ``free`` bytes (a file ``filler``)."""
    (d / "filler").unlink(missing_ok=True)
    st = os.statvfs(d)
    size = st.f_bavail * st.f_frsize - free
    with open(d / "filler", "wb") as f:
        f.write(b"\0" * size)


IDENTITY = "1 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1\n"  #: a PDAL scan2imu matrix: scanner axes = body axes


def _run(corpus, d, args, name):
    out = d / name
    scan2imu = d.parent / "scan2imu.txt"  # outside the tmpfs
    scan2imu.write_text(IDENTITY)
    argv = [a.format(S=corpus.root / "survey", T=corpus.root / "total-station", P=corpus.root / "photons",
                     B=corpus.root / "bad", X=scan2imu) for a in args]
    r = subprocess.run([sys.executable, "-m", "calidar", *argv, "--out", str(out)], capture_output=True, text=True,
                       env=ENV, timeout=300)
    return r, out, argv


@pytest.mark.slow
@pytest.mark.parametrize("args, name", [pytest.param(a, n, id=i) for i, a, n in COMMANDS])
def test_disk_full(corpus, tmpfs, args, name):
    _fill(tmpfs, FREE_BYTES)
    r, out, argv = _run(corpus, tmpfs, args, name)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 1, r.stderr
    assert "Traceback" not in r.stderr + r.stdout and "internal error" not in r.stderr, r.stderr
    # --out and the cause (and the file, when the failing library names it)
    assert len(lines) == 1 and lines[0].startswith(f"error: {out}: cannot write "), r.stderr
    assert lines[0].endswith(": No space left on device") and ".calidar-" not in lines[0], r.stderr
    assert sorted(p.name for p in tmpfs.iterdir()) == ["filler"]  # nothing left behind
    corpus.check_unchanged(argv)


@pytest.mark.slow
@pytest.mark.parametrize("args, name", [pytest.param(a, n, id=i) for i, a, n in COMMANDS
                                        if i in ("simulate-total-station", "scanner-analyze", "inverse", "denoise")])
def test_read_only_destination(corpus, tmpfs, args, name):
    """A read-only file system: the message names --out (never the hidden temporary) and the cause."""
    (tmpfs / "filler").unlink(missing_ok=True)
    subprocess.run(["mount", "-o", "remount,ro", str(tmpfs)], check=True)
    try:
        r, out, _ = _run(corpus, tmpfs, args, name)
    finally:
        subprocess.run(["mount", "-o", "remount,rw", str(tmpfs)], check=True)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 1, r.stderr
    assert len(lines) == 1 and lines[0].startswith(f"error: {out}: ") and "Read-only file system" in lines[0], r.stderr
    assert ".calidar-" not in r.stderr and f"/.{name}" not in r.stderr
    assert list(tmpfs.iterdir()) == []
