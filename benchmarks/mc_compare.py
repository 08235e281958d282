"""Two versions' Monte-Carlo rows on the same surveys: how far did a change move each result, in σ?

    python benchmarks/mc_compare.py BEFORE.jsonl AFTER.jsonl [--method vgicp]

The rows are ``strips_montecarlo.py --json``'s (the same seeds calibrated by two installations).
Per survey (seed, source) found in both: |error_after − error_before| / σ_before per angle, σ_after /
σ_before and the outer iterations; then over the surveys the largest and the median |Δ|/σ per
angle, the largest |σ ratio − 1| and the RMS of error/σ of each version (±1/√(2n)). A change that
only moves the last bits gives |Δ|/σ ≈ 1e-10; "small" for a change of method is ≪ 0.2.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def rows(path: Path, method: str) -> dict[tuple, dict]:
    out = {}
    for line in path.read_text().splitlines():
        r = json.loads(line)
        if r["method"] == method:
            out[(r["seed"], r["source"])] = r
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--method", default="vgicp")
    args = ap.parse_args()
    before, after = rows(args.before, args.method), rows(args.after, args.method)
    shift, ratio, z_before, z_after = [], [], [], []
    for key in sorted(set(before) & set(after)):
        b, a = before[key], after[key]
        e0, e1 = np.array(b["error_deg"]), np.array(a["error_deg"])
        s0, s1 = np.array(b["sigma_deg"]), np.array(a["sigma_deg"])
        shift.append(np.abs(e1 - e0) / s0)
        ratio.append(s1 / s0)
        z_before.append(e0 / s0)
        z_after.append(e1 / s1)
        print(f"seed {key[0]} ({key[1]}): |Δ|/σ {' '.join(f'{v:.2e}' for v in shift[-1])}, σ ratio "
              f"{' '.join(f'{v:.5f}' for v in ratio[-1])}, outer iterations "
              f"{b['outer_iterations']} → {a['outer_iterations']}")
    if not shift:
        raise SystemExit(f"no survey of method {args.method!r} in both files")
    shift, ratio = np.array(shift), np.array(ratio)
    rms = [np.sqrt(np.mean(np.square(z), axis=0)) for z in (z_before, z_after)]
    print(f"{len(shift)} surveys: |Δ|/σ largest {' / '.join(f'{v:.2g}' for v in shift.max(axis=0))}, "
          f"median {' / '.join(f'{v:.2g}' for v in np.median(shift, axis=0))} (roll / pitch / yaw); "
          f"σ ratio within 1 ± {np.abs(ratio - 1).max():.2g}; RMS z "
          f"{' / '.join(f'{v:.3f}' for v in rms[0])} → {' / '.join(f'{v:.3f}' for v in rms[1])} "
          f"(±{1 / np.sqrt(2 * len(shift)):.2f})")


if __name__ == "__main__":
    main()
