"""Where the tests look for the real data by default (CALIDAR_REAL_DATA unset)."""

from conftest import default_real_data


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
