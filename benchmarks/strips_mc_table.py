"""The issue-26 Monte-Carlo table from ``strips_montecarlo.py``'s rows (issue 26, ninth session).

    python benchmarks/strips_mc_table.py ROWS.jsonl [ROWS2.jsonl ...] [--pool]
    python benchmarks/strips_mc_table.py NONE.jsonl --source default --against SMRMSG.jsonl [...]

One markdown row per cell (preset, scene, directions, trees) and method: surveys (seeds), RMS
of z = error/σ per angle (± its sampling spread 1/√(2n)), mean z, largest |z| per angle, the
count of |z| > 3.5, σ0 as the global test reads it (``sigma0_test``) inside its χ² 95 % range
and within ±7 % of 1, and the outer iterations' mean (largest). ``--pool`` adds one row per
scene (airborne, uav, urban) of two cells or more and method, over that scene's rows (tenth
session; was over all rows read). Only the ``smrmsg`` source's rows (the accuracy file beside
the SBET); ``--source default``: the rows calibrated without it (the "none" rows, the level
estimated from the overlaps), and ``--against ROWS.jsonl`` then prints per angle the median
(range) of their σ over those rows' σ on the same surveys (eleventh session).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def cell_of(r: dict) -> str:
    """A row's cell: e.g. 'uav urban cross, 0 %'."""
    scene = scene_of(r)
    pattern = r.get("directions", "cross")
    return f"{scene} {pattern}, {100 * r.get('vegetation', 0.0):.0f} %"


def scene_of(r: dict) -> str:
    """A row's scene: 'airborne', 'uav' or 'urban'."""
    return "urban" if r.get("scene") == "urban" else r.get("preset", "airborne")


def seeds_text(seeds: list[int]) -> str:
    """[860, 861, …, 879, 930] → '860–879, 930'."""
    out, run = [], [seeds[0]]
    for s in seeds[1:]:
        if s == run[-1] + 1:
            run.append(s)
        else:
            out.append(run)
            run = [s]
    out.append(run)
    return ", ".join(f"{r[0]}–{r[-1]}" if len(r) > 1 else f"{r[0]}" for r in out)


def line(label: str, method: str, sel: list[dict]) -> str:
    """One markdown row over the rows ``sel``."""
    z = np.array([np.divide(r["error_deg"], r["sigma_deg"]) for r in sel])
    n = len(sel)
    s0 = np.array([r["sigma0_test"] for r in sel])
    lo, hi = np.array([r["sigma0_range"] for r in sel]).T
    outer = [r["outer_iterations"] for r in sel]
    f = lambda v, fmt: " / ".join(format(x, fmt) for x in v)  # noqa: E731
    return (f"| {label} | {method} | {n} ({seeds_text(sorted({r['seed'] for r in sel}))}) | "
            f"{f(np.sqrt(np.mean(z**2, 0)), '.2f')} (±{1 / np.sqrt(2 * n):.2f}) | "
            f"{f(z.mean(0), '+.2f')} | {f(np.abs(z).max(0), '.2f')} | "
            f"{int(np.sum(np.abs(z) > 3.5))} | {s0.mean():.3f} ({s0.min():.3f}–{s0.max():.3f}) | "
            f"{int(np.sum((s0 >= lo) & (s0 <= hi)))} / {int(np.sum(np.abs(s0 - 1) <= 0.07))} | "
            f"{np.mean(outer):.1f} ({max(outer)}) |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", type=Path, nargs="+", help="strips_montecarlo.py --json files")
    ap.add_argument("--pool", action="store_true", help="also one row per method over all")
    ap.add_argument("--source", default="smrmsg", help="the rows' accuracy source (default: smrmsg)")
    ap.add_argument("--against", type=Path, nargs="+", default=None,
                    help="σ ratio against these smrmsg rows (same seeds, cell and method)")
    args = ap.parse_args()
    rows = _rows(args.rows, args.source)
    print("| cell | method | surveys (seeds) | RMS z roll / pitch / yaw | mean z | max abs z "
          "| abs z > 3.5 | σ0 mean (min–max) | σ0 in χ² range / ±7 % | outer iterations |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for cell in sorted({cell_of(r) for r in rows}):
        for method in sorted({r["method"] for r in rows if cell_of(r) == cell}):
            sel = [r for r in rows if (cell_of(r), r["method"]) == (cell, method)]
            print(line(cell, method, sel))
    if args.pool:
        for scene in sorted({scene_of(r) for r in rows}):
            if len({cell_of(r) for r in rows if scene_of(r) == scene}) < 2:
                continue  # its one cell's rows above
            for method in sorted({r["method"] for r in rows if scene_of(r) == scene}):
                print(line(f"**{scene}, pooled**", method,
                           [r for r in rows if (scene_of(r), r["method"]) == (scene, method)]))
    if args.against is not None:
        ref = {(r["seed"], r["method"], cell_of(r)): r for r in _rows(args.against, "smrmsg")}
        ratio = np.array([np.divide(r["sigma_deg"], ref[k]["sigma_deg"]) for r in rows
                          if (k := (r["seed"], r["method"], cell_of(r))) in ref])
        print(f"σ ÷ the smrmsg rows' σ on {len(ratio)} surveys, roll / pitch / yaw: median "
              + " / ".join(f"{v:.2f}" for v in np.median(ratio, 0)) + "; range "
              + ", ".join(f"{a:.2f}–{b:.2f}" for a, b in zip(ratio.min(0), ratio.max(0))))


def _rows(paths: list[Path], source: str) -> list[dict]:
    """The rows of ``source`` in ``paths``, the last run of each survey, cell and method."""
    rows = [json.loads(x) for p in paths for x in p.read_text().splitlines() if x.strip()]
    return list({(r["seed"], r["method"], cell_of(r)): r for r in rows
                 if r.get("source", "smrmsg") == source}.values())


if __name__ == "__main__":
    main()
