"""Compare two runs' results (solution*.json, quality.json): every number equal within a tolerance,
every string and flag equal; the run record (times, paths, versions), wall times and the output
folder's name left out (:data:`SKIP`).

A refactoring must not change results: run the same inputs through the landed code and the
changed one, then

    python benchmarks/compare_results.py OLD_FOLDER NEW_FOLDER [--tol 1e-9]

compares each JSON file the two folders share (and, given two JSON files, those). Prints the
largest difference and every value that differs; exit 1 when any does.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

#: left out: the run record (times, paths, command line, versions), the command that reproduces a
#: stage (it names the output folder) and the outer iterations' wall times
SKIP = {"run", "reproduce", "georeference_s", "match_s", "solve_s"}


def differences(a, b, tol: float, where: str = "") -> tuple[list[str], float]:
    """(what differs, the largest |a − b| of the numbers) between two JSON values."""
    if isinstance(a, dict) and isinstance(b, dict):
        out, worst = [], 0.0
        if set(a) - SKIP != set(b) - SKIP:
            out.append(f"{where}: keys {sorted(set(a) ^ set(b))} in one only")
        for k in sorted((set(a) & set(b)) - SKIP):
            d, w = differences(a[k], b[k], tol, f"{where}.{k}")
            out, worst = out + d, max(worst, w)
        return out, worst
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} items against {len(b)}"], 0.0
        out, worst = [], 0.0
        for k, (x, y) in enumerate(zip(a, b)):
            d, w = differences(x, y, tol, f"{where}[{k}]")
            out, worst = out + d, max(worst, w)
        return out, worst
    numbers = (int, float)
    if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool) and not isinstance(b, bool):
        if math.isnan(a) and math.isnan(b):
            return [], 0.0
        diff = abs(a - b)
        return ([f"{where}: {a!r} against {b!r}"] if not diff <= tol else []), diff
    return ([] if a == b else [f"{where}: {a!r} against {b!r}"]), 0.0


def pairs(old: Path, new: Path) -> list[tuple[Path, Path]]:
    """The JSON files to compare: the two given, or those of the same name in both folders."""
    if old.is_file():
        return [(old, new)]
    return [(p, new / p.name) for p in sorted(old.glob("*.json")) if (new / p.name).exists()]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path)
    parser.add_argument("--tol", type=float, default=1e-9, help="largest |old − new| of a number taken as equal")
    args = parser.parse_args(argv)
    found, bad = pairs(args.old, args.new), 0
    if not found:
        print(f"no JSON file in both {args.old} and {args.new}")
        return 1
    for a, b in found:
        diff, worst = differences(json.loads(a.read_text()), json.loads(b.read_text()), args.tol)
        print(f"{a.name}: {'equal' if not diff else f'{len(diff)} differences'}; largest |difference| {worst:.3g}")
        for line in diff[:20]:
            print("   ", line)
        bad += bool(diff)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
