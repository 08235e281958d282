"""The command line's progress bar: drawn live on a terminal; on a pipe or a file, hidden as before
and no longer redrawn by rich's refresh thread (ten table layouts a second for no one)."""

from __future__ import annotations

import threading

import pytest
from rich.live import _RefreshThread

from calidar.cli import common


def _refreshing() -> bool:
    return any(isinstance(t, _RefreshThread) for t in threading.enumerate())


def test_no_refresh_thread_when_stderr_is_not_a_terminal(capsys: pytest.CaptureFixture[str]):
    assert not common.err_console.is_terminal  # pytest's captured stderr
    with common.progress_bar() as p:
        update = common.progress_callback(p)
        for done in range(5):
            update("reading strips", done, 5)
        assert not p.live.auto_refresh and not _refreshing()
    assert capsys.readouterr().err.strip() == ""  # hidden, as before (one line end at its stop)


def test_a_terminal_still_sees_it_drawn_live(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(common.err_console, "_force_terminal", True)
    assert common.err_console.is_terminal
    with common.progress_bar() as p:
        common.progress_callback(p)("reading strips", 1, 5)
        assert p.live.auto_refresh and _refreshing()
