"""Read any supported trajectory: Applanix SBET (binary) or ASCII/CSV with named columns."""

from __future__ import annotations

from pathlib import Path

from calidar.errors import InputError
from calidar.io.sbet import read_sbet
from calidar.io.trajectory_text import read_trajectory_text
from calidar.trajectory import Trajectory

SBET_SUFFIXES = (".out", ".sbet", ".smrmsg")


def is_binary(path: Path, probe_bytes: int = 4096) -> bool:
    """Whether the file starts with bytes that are not UTF-8 text."""
    with open(path, "rb") as f:
        head = f.read(probe_bytes)
    if b"\0" in head:
        return True
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as e:
        return e.start < len(head) - 4  # a multi-byte character cut at the probe's end is still text
    return False


def read_trajectory(path: str | Path, **text_options) -> Trajectory:
    """SBET when the file is binary, else an ASCII/CSV trajectory read with ``text_options``
    (see :func:`calidar.io.trajectory_text.read_trajectory_text`)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "trajectory file not found")
    if is_binary(path) or (path.suffix.lower() in SBET_SUFFIXES and path.stat().st_size == 0):
        given = {k: v for k, v in text_options.items() if v is not None}
        if given:
            raise InputError(path, sorted(given)[0], "is an option of text trajectories; this file is a binary SBET")
        return read_sbet(path)
    return read_trajectory_text(path, **text_options)
