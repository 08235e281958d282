"""The docs stay true to the code: docs/architecture.md is the design only (short), and every
figure of docs/validation.md names a benchmark script, options and tests that exist."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
MAX_ARCHITECTURE_LINES = 250
#: a backticked command span naming a benchmark: `benchmarks/NAME.py [ARGS…]`
BENCHMARK_COMMAND = re.compile(r"`(benchmarks/[\w/]+\.py)([^`]*)`")
PATH = re.compile(r"(?<![\w./-])((?:[a-z_]+/)+[a-z_0-9]+\.py)\b")


def test_architecture_is_short():
    n = len((DOCS / "architecture.md").read_text(encoding="utf-8").splitlines())
    assert n <= MAX_ARCHITECTURE_LINES, f"docs/architecture.md has {n} lines; the design fits in {MAX_ARCHITECTURE_LINES}"


def test_every_benchmark_command_in_validation_exists():
    text = (DOCS / "validation.md").read_text(encoding="utf-8")
    commands = BENCHMARK_COMMAND.findall(text)
    assert len(commands) >= 10
    for script, args in commands:
        path = ROOT / script
        assert path.is_file(), f"docs/validation.md names {script}, which does not exist"
        source = path.read_text(encoding="utf-8")
        for option in re.findall(r"(?<!\S)(--[a-z][\w-]*)", args):
            assert f'"{option}"' in source, f"docs/validation.md: {script} takes no option {option}"


@pytest.mark.parametrize("doc", ["architecture.md", "strips.md", "validation.md", "conventions.md"])
def test_every_module_and_test_path_named_exists(doc):
    """Paths like `pipelines/boresight.py` (under src/calidar), `tests/unit/...py`, `benchmarks/...py`."""
    text = (DOCS / doc).read_text(encoding="utf-8")
    missing = []
    for path in sorted(set(PATH.findall(text))):
        candidates = [ROOT / path, ROOT / "src" / "calidar" / path, ROOT / "src" / path]
        if not any(c.is_file() for c in candidates):
            missing.append(path)
    assert not missing, f"docs/{doc} names files that do not exist: {missing}"


#: a backticked dotted name such as `georef.forward` or `calidar.strips.pca.eigh3` (call parentheses allowed)
DOTTED = re.compile(r"`((?:calidar\.)?[a-z_]+(?:\.[A-Za-z_][A-Za-z_0-9]*)+)(?:\([^`]*\))?`")
FILE_SUFFIXES = {"py", "toml", "json", "out", "csv", "las", "laz", "h5", "html", "txt", "md"}


def _resolves(name: str) -> bool:
    """Whether ``name`` (relative to the calidar package) names an existing module or attribute."""
    import importlib

    parts = name.split(".")
    parts = parts if parts[0] == "calidar" else ["calidar", *parts]
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for attr in parts[k:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


@pytest.mark.parametrize("doc", ["architecture.md", "strips.md", "validation.md", "conventions.md", "sensor.md"])
def test_every_code_name_named_exists(doc):
    """`module.function` names whose first part is a calidar module or package exist in the code."""
    text = (DOCS / doc).read_text(encoding="utf-8")
    src = ROOT / "src" / "calidar"
    names = {n for n in DOTTED.findall(text) if n.rsplit(".", 1)[-1] not in FILE_SUFFIXES}
    ours = {n for n in names if n.startswith("calidar.") or (src / n.split(".")[0]).is_dir()
            or (src / f"{n.split('.')[0]}.py").is_file()}
    missing = sorted(n for n in ours if not _resolves(n))
    assert not missing, f"docs/{doc} names code that does not exist: {missing}"
