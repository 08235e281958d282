"""Shared fixtures: where the real data live, and a CLI runner."""

from __future__ import annotations

import os
from pathlib import Path

import pytest



def default_real_data(repo: Path) -> Path:
    """``<repo>/../shared/data/real``; from a git worktree (``.git`` is a file "gitdir: ..."), also
    the same folder beside the main checkout, the parent of git's common dir. The first that exists."""
    candidates = [repo.parent / "shared" / "data" / "real"]
    git = repo / ".git"
    if git.is_file() and git.read_text().startswith("gitdir:"):
        gitdir = (repo / git.read_text()[len("gitdir:"):].strip()).resolve()  # <common>/worktrees/<name>
        common = gitdir / "commondir"
        common_dir = (gitdir / common.read_text().strip()).resolve() if common.is_file() else gitdir.parents[1]
        candidates.append(common_dir.parent.parent / "shared" / "data" / "real")
    return next((c for c in candidates if c.is_dir()), candidates[0])


REAL_DATA = Path(os.environ.get("CALIDAR_REAL_DATA") or default_real_data(Path(__file__).resolve().parents[1])).resolve()


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
