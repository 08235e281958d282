"""Two runs' solution files agree: every parameter's value and σ, and every other number.

Used to hold a refactoring of the engine to the last landed code (issue 29: results identical to
1e-9). Run the same command with two installations into two folders, then

    python benchmarks/solutions_equal.py OLD_FOLDER NEW_FOLDER [--tol 1e-9]

compares each ``solution*.json`` and ``sensor*.toml`` present in both: the parameters' values and σ
(display units: deg, m, ppm) to ``--tol`` absolute, every other number of solution.json (σ0,
correlations, residual statistics, history, verdict figures, trajectory corrections) to ``--tol``
relative to max(1, |value|); timings, paths and dates are left out. Exit 1 when anything differs.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path

SKIP = re.compile(r"(^run$|_s$|seconds|elapsed|time_s|date|path|version|^timings?$)")


def leaves(doc, path=""):
    """(path, number) of every finite-or-not number in a JSON document, skipping timing/provenance keys."""
    if isinstance(doc, dict):
        for k, v in doc.items():
            if not SKIP.search(str(k)):
                yield from leaves(v, f"{path}/{k}")
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from leaves(v, f"{path}[{i}]")
    elif isinstance(doc, (int, float)) and not isinstance(doc, bool):
        yield path, float(doc)


def compare_json(a: Path, b: Path, tol: float) -> tuple[float, float, list[str]]:
    """(largest |Δ| of parameter values and σ, largest relative Δ of the other numbers, differences)."""
    da, db = json.loads(a.read_text()), json.loads(b.read_text())
    bad, worst_par, worst_other = [], 0.0, 0.0
    pa, pb = dict(leaves(da)), dict(leaves(db))
    for key in sorted(set(pa) | set(pb)):
        if key not in pa or key not in pb:
            bad.append(f"{a.name}{key}: only in {'new' if key in pb else 'old'}")
            continue
        x, y = pa[key], pb[key]
        if math.isnan(x) and math.isnan(y) or x == y:
            continue
        d = abs(x - y)
        if key.startswith("/parameters/"):
            worst_par = max(worst_par, d)
            if not d <= tol:
                bad.append(f"{a.name}{key}: {x!r} vs {y!r}")
        else:
            rel = d / max(1.0, abs(x))
            worst_other = max(worst_other, rel)
            if not rel <= tol:
                bad.append(f"{a.name}{key}: {x!r} vs {y!r}")
    return worst_par, worst_other, bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", type=Path)
    ap.add_argument("new", type=Path)
    ap.add_argument("--tol", type=float, default=1e-9)
    args = ap.parse_args(argv)
    files = sorted(p.name for p in args.old.glob("solution*.json") if (args.new / p.name).exists())
    if not files:
        print(f"no solution*.json in both {args.old} and {args.new}")
        return 1
    failed = False
    for name in files:
        par, other, bad = compare_json(args.old / name, args.new / name, args.tol)
        print(f"{name}: parameters max |Δ| {par:.3g}, other numbers max rel Δ {other:.3g}"
              + ("" if not bad else f", {len(bad)} beyond {args.tol:g}"))
        for line in bad[:20]:
            print("   ", line)
        failed |= bool(bad)
    for p in sorted(args.old.glob("sensor*.toml")):
        q = args.new / p.name
        if q.exists():
            same = _numbers(p) == _numbers(q) or _close(_numbers(p), _numbers(q), args.tol)
            print(f"{p.name}: {'equal' if same else 'DIFFERENT'}")
            failed |= not same
    return 1 if failed else 0


def _numbers(path: Path) -> list[float]:
    text = "\n".join(line for line in path.read_text().splitlines() if not re.search(r"date|version|source", line))
    return [float(m) for m in re.findall(r"(?<![\w.])[-+]?\d+\.?\d*(?:[eE][-+]?\d+)?", text)]


def _close(a: list[float], b: list[float], tol: float) -> bool:
    return len(a) == len(b) and all(abs(x - y) <= tol * max(1.0, abs(x)) for x, y in zip(a, b))


if __name__ == "__main__":
    sys.exit(main())
