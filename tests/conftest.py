"""Shared fixtures: where the real data live, and a CLI runner."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REAL_DATA = Path(os.environ.get("CALIDAR_REAL_DATA", Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real")).resolve()


@pytest.fixture
def real_data() -> Path:
    """The real-data folder; skips the test (with the reason) when it is absent."""
    if not REAL_DATA.is_dir():
        pytest.skip(f"real data not found at {REAL_DATA} (set CALIDAR_REAL_DATA)")
    return REAL_DATA


@pytest.fixture
def cli(capsys):
    """Run the calidar CLI in-process: cli("info", "x.las") → (exit_code, stdout, stderr)."""
    from calidar.cli import run

    def _run(*args: str):
        code = run([str(a) for a in args])
        out = capsys.readouterr()
        return code, out.out, out.err

    return _run
