"""Fixtures of the acceptance tests: the bad-input corpus (built once per session) and its checker."""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest
from bad_inputs_corpus import build, snapshot


@dataclass(frozen=True)
class Corpus:
    """The corpus folder: ``survey/`` (strips, sbet.out, smrmsg.out, sensor.toml, truth.json),
    ``photons/`` (ATL03_sim.h5, ccr.csv, truth.json), ``total-station/`` (observations.csv,
    truth.json), ``bad/`` (corrupt copies), and each file's sha256, size and time when built."""

    root: Path
    hashes: dict[str, str]
    stats: dict[str, tuple[int, int]]  #: (size, mtime ns) of every file: any write shows

    @staticmethod
    def stat(root: Path) -> dict[str, tuple[int, int]]:
        return {p.relative_to(root).as_posix(): (p.stat().st_size, p.stat().st_mtime_ns)
                for p in root.rglob("*") if p.is_file()}

    def args(self, args, out: Path) -> list[str]:
        """``args`` with {S} survey, {P} photons, {T} total-station, {B} bad, {O} ``out`` filled in."""
        r = self.root
        return [a.format(S=r / "survey", P=r / "photons", T=r / "total-station", B=r / "bad", O=out) for a in args]

    def check_unchanged(self, argv: list[str]) -> None:
        """No file of the corpus added, removed, resized or written to; every file named in ``argv``
        (or inside a folder named there) byte-identical."""
        now = self.stat(self.root)
        assert set(now) == set(self.stats), f"corpus files added/removed: {set(now) ^ set(self.stats)}"
        assert now == self.stats, f"corpus files written: {[k for k in now if now[k] != self.stats[k]]}"
        named = []
        for a in argv:
            p = Path(a).resolve()  # a link named on the command line: the file or folder it points to
            if p.is_relative_to(self.root.resolve()) and p.exists():
                named += [p] if p.is_file() else [q for q in p.rglob("*") if q.is_file()]
        for p in named:
            rel = p.relative_to(self.root.resolve()).as_posix()
            assert snapshot_one(p) == self.hashes[rel], f"input modified: {rel}"


def snapshot_one(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="session")
def corpus(tmp_path_factory) -> Corpus:
    from calidar.cli import run

    root = tmp_path_factory.mktemp("corpus")
    build(root, lambda *a: (run([str(x) for x in a]), "", ""))
    return Corpus(root, snapshot(root), Corpus.stat(root))


@pytest.fixture
def bad_input(corpus, cli, tmp_path):
    """Run one corpus case: ``bad_input(args, code, *substrings)``; asserts the exit code, no
    traceback or "internal error", a one-line error (exit 1) or the usage line (exit 2) holding
    every substring, the inputs unchanged and nothing left behind in the output's folder."""

    def _check(args, code: int, *substrings: str):
        work = Path(tempfile.mkdtemp(dir=tmp_path))
        argv = corpus.args(args, work / "out")
        rc, out, err = cli(*argv)
        assert "Traceback" not in out + err and "internal error" not in out + err, err
        assert rc == code, f"exit {rc}, expected {code}; stderr: {err}; stdout: {out[-500:]}"
        if code == 1:
            errors = [line for line in err.splitlines() if line.startswith("error: ")]
            others = [line for line in err.splitlines() if line.strip() and not line.startswith(("error: ", "warning: "))]
            assert len(errors) == 1 and not others, err  # one error line (warnings before it allowed)
            message = errors[0]
        else:
            message = err + out  # a usage error: the usage line (the help for a bare group)
            assert "Usage: calidar" in message, err
        for s in substrings:
            assert s in message, f"{s!r} not in {message!r}"
        corpus.check_unchanged(argv)
        assert list(work.iterdir()) == [], f"left behind: {list(work.iterdir())}"
        return message

    return _check
