"""Read any supported trajectory: Applanix SBET (binary), ASCII/CSV with named columns, or the
per-pulse positions and attitudes of an Optech CSD file."""

from __future__ import annotations

from pathlib import Path

from calidar.errors import InputError
from calidar.io.optech_csd import csd_trajectory, is_csd, read_csd
from calidar.io.sbet import read_sbet
from calidar.io.trajectory_text import read_trajectory_text
from calidar.trajectory import Trajectory
from calidar.validate import existing_file

SBET_SUFFIXES = (".out", ".sbet", ".smrmsg")
#: the CLI options of the text-trajectory reader's arguments
TEXT_OPTIONS = {"crs": "--trajectory-crs", "angles": "--trajectory-angles",
                "heading_reference": "--trajectory-heading", "columns": "--trajectory-columns"}


def is_binary(path: Path, probe_bytes: int = 4096) -> bool:
    """Whether the file starts with control characters other than tab, line feed, carriage return
    and form feed (binary). Text in another encoding than UTF-8 is text: its reader says so."""
    with open(path, "rb") as f:
        head = f.read(probe_bytes)
    return bool(head.translate(None, b"\t\n\r\f").translate(None, bytes(range(32, 256))))


def read_trajectory(path: str | Path, **text_options) -> Trajectory:
    """An Optech CSD's pulses (by its signature), an SBET when the file is binary, else an ASCII/CSV
    trajectory read with ``text_options`` (see
    :func:`calidar.io.trajectory_text.read_trajectory_text`; options given as None are not given,
    and giving one for a binary file is an error).

    >>> import tempfile, numpy as np, calidar
    >>> t = np.arange(0.0, 1.0, 0.01)  # 100 Hz, one second
    >>> n = t.size
    >>> traj = calidar.Trajectory(time=t, lat=np.radians(47.0 + 1e-5 * t),
    ...                           lon=np.full(n, np.radians(8.0)), height=np.full(n, 500.0),
    ...                           roll=np.zeros(n), pitch=np.zeros(n), heading=np.full(n, 0.1))
    >>> folder = Path(tempfile.mkdtemp())
    >>> sbet = calidar.read_trajectory(calidar.write_sbet(folder / "sbet.out", traj))
    >>> text = calidar.read_trajectory(calidar.write_trajectory_text(folder / "traj.csv", traj))
    >>> bool(np.allclose(sbet.lat, text.lat, rtol=0, atol=1e-12)), text.source.endswith("traj.csv")
    (True, True)
    """
    path = existing_file(path, "trajectory file")
    given = {k: v for k, v in text_options.items() if v is not None}
    binary = is_binary(path) or (path.suffix.lower() in SBET_SUFFIXES and path.stat().st_size == 0)
    if binary and given:
        kind = "an Optech CSD" if is_csd(path) else "a binary SBET"
        raise InputError(path, TEXT_OPTIONS.get(sorted(given)[0], sorted(given)[0]),
                         f"is an option of text trajectories; this file is {kind}")
    if binary:
        traj = csd_trajectory(read_csd(path)) if is_csd(path) else read_sbet(path)
    else:
        traj = read_trajectory_text(path, **given)
    check_motion(traj)
    return traj


MAX_SPEED_M_S = 2000.0  #: far faster than any survey aircraft (jets cruise below 260 m/s)
#: roll or pitch changing faster: a glitch, not a manoeuvre (turns: 10–30 °/s)
MAX_TILT_RATE_DEG_S = 500.0


def check_motion(traj: Trajectory) -> None:
    """Error when consecutive records imply an impossible speed or roll/pitch rate (a position or
    attitude glitch, or positions in the wrong unit), naming the record and the field."""
    import numpy as np

    dt = np.diff(traj.time)
    speed = np.linalg.norm(np.diff(traj.ecef, axis=0), axis=1) / dt
    fast = np.flatnonzero(speed > MAX_SPEED_M_S)

    def records(i: int) -> str:
        return f"records {i}–{i + 1} ({traj.time[i]:.3f}–{traj.time[i + 1]:.3f} s)"

    if fast.size:
        i = int(fast[0])
        raise InputError(traj.source, "position",
                         f"{records(i)} move {speed[i] * dt[i]:.1f} m in {dt[i]:.3g} s "
                         f"({speed[i]:.3g} m/s; {fast.size} such steps); expected below "
                         f"{MAX_SPEED_M_S:g} m/s: a position glitch or a wrong unit")
    for name in ("roll", "pitch"):
        rate = np.degrees(np.abs(np.diff(getattr(traj, name)))) / dt
        bad = np.flatnonzero(rate > MAX_TILT_RATE_DEG_S)
        if bad.size:
            i = int(bad[0])
            raise InputError(traj.source, name,
                             f"{records(i)} change by {rate[i] * dt[i]:.2f}° ({rate[i]:.3g} °/s; "
                             f"{bad.size} such steps); expected below {MAX_TILT_RATE_DEG_S:g} °/s: "
                             "an attitude glitch or a wrong unit")
