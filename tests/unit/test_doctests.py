"""Every docstring example of the package runs as written (issue 29): the doctests of each module
holding one, in a temporary folder. The public API's modules are run by tests/unit/test_api.py and the
configurations' by tests/unit/strips/test_config.py; this covers every other module."""

from __future__ import annotations

import doctest
import importlib
import tempfile
from pathlib import Path

import pytest

import calidar

SRC = Path(__file__).resolve().parents[2] / "src" / "calidar"
ELSEWHERE = {m for m, _ in calidar._API.values()} | {"calidar.strips.config", "calidar.pipelines.strip_config"}


def _module(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


WITH_EXAMPLES = sorted(_module(p) for p in SRC.rglob("*.py") if ">>> " in p.read_text(encoding="utf-8"))


def test_the_other_tests_run_theirs():
    assert ELSEWHERE <= set(WITH_EXAMPLES) and len(set(WITH_EXAMPLES) - ELSEWHERE) >= 10


@pytest.mark.parametrize("module", sorted(set(WITH_EXAMPLES) - ELSEWHERE))
def test_docstring_examples_run(module, tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # the examples' tempfile.mkdtemp() land here
    monkeypatch.chdir(tmp_path)  # and nothing they write lands in the checkout
    result = doctest.testmod(importlib.import_module(module), optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{module}: {result.failed} of {result.attempted} examples failed (see the output)"
