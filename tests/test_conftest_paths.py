"""Where the tests look for the real data by default (CALIDAR_REAL_DATA unset)."""

import importlib.util
from pathlib import Path


def _root_conftest():
    """tests/conftest.py by its path (``import conftest`` may find tests/acceptance/conftest.py)."""
    spec = importlib.util.spec_from_file_location("calidar_tests_root_conftest", Path(__file__).with_name("conftest.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


default_real_data = _root_conftest().default_real_data


def _layout(tmp_path):
    """A main checkout tmp/main (git dir tmp/main/.git), a worktree tmp/wt/x and tmp/shared/data/real."""
    real = tmp_path / "shared" / "data" / "real"
    real.mkdir(parents=True)
    gitdir = tmp_path / "main" / ".git" / "worktrees" / "x"
    gitdir.mkdir(parents=True)
    (gitdir / "commondir").write_text("../..\n")
    wt = tmp_path / "wt" / "x"
    wt.mkdir(parents=True)
    (wt / ".git").write_text(f"gitdir: {gitdir}\n")
    return real, wt


def test_fresh_clone_finds_shared_beside_it(tmp_path):
    real, _ = _layout(tmp_path)
    (tmp_path / "main" / "src").mkdir()
    assert default_real_data(tmp_path / "main") == real


def test_worktree_finds_shared_beside_the_main_checkout(tmp_path):
    real, wt = _layout(tmp_path)
    assert not (wt.parent / "shared").exists()
    assert default_real_data(wt) == real


def test_absent_data_names_the_usual_place(tmp_path):
    (tmp_path / "repo").mkdir()
    assert default_real_data(tmp_path / "repo") == tmp_path / "shared" / "data" / "real"
