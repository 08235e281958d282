"""Before/after of one change on the same cached surveys: per cell and method, RMS z per angle, the
mean σ ratio after/before per angle, σ0 (the global test's) before and after, and the sandwich's record.

    PYTHONPATH=src python benchmarks/strips_mc_compare.py AFTER.jsonl [AFTER2.jsonl …] \
        [--before BEFORE.jsonl …]

AFTER and BEFORE are ``strips_montecarlo.py --json`` rows of the same seeds (e.g. ``--covariance
sandwich`` after, issue 26). The estimates must be the same (a covariance change moves no value):
the largest |Δ error| is printed to show it. An AFTER row without a BEFORE row of its seed (a
``--covariance sandwich`` row records the IRLS σ beside its own, ``covariance.irls_sigma``) takes
those IRLS σ as "before"; the last column then gives the model part's σ ÷ the final σ (the
cluster-robust max: 1 where the model part is what is reported), IRLS → sandwich.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def _rows(paths: list[Path]) -> dict:
    out = {}
    for line in (ln for path in paths for ln in path.read_text().splitlines()):
        r = json.loads(line)
        out[(r["preset"], r["directions"], r["method"], r["seed"])] = r
    return out


def _recorded(rows: dict) -> tuple[dict, dict]:
    """Two views of rows run with the sandwich σ, the rows read unchanged: (the IRLS σ they
    recorded as their σ, with the IRLS model part's share; the rows as run, with the sandwich
    model part's share)."""
    irls, sandwich = {}, {}
    for key, r in rows.items():
        rec = r["covariance"]
        names = list(rec["irls_sigma"])
        angles = [n for n in names if n.startswith("boresight")] or names[:3]
        irls[key] = {**r, "sigma_deg": [float(np.degrees(rec["irls_sigma"][n])) for n in angles],
                     "model_share": [rec["irls_model_sigma"][n] / rec["irls_sigma"][n] for n in angles]}
        sandwich[key] = {**r, "model_share": [rec["model_sigma"][n] / np.radians(s)
                                              for n, s in zip(angles, r["sigma_deg"])]}
    return irls, sandwich


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("after", type=Path, nargs="+")
    ap.add_argument("--before", type=Path, nargs="*", default=[])
    args = ap.parse_args()
    after = _rows(args.after)
    recorded, shared = _recorded({k: r for k, r in after.items()
                                  if "irls_sigma" in (r.get("covariance") or {})})
    after = {**after, **shared}
    before = {**recorded, **_rows(args.before)}
    keys = sorted(set(before) & set(after))
    print("| cell | method | n | RMS z r / p / y before → after | σ after ÷ before r / p / y "
          "| max abs z before → after | σ0 test before → after | sandwich f, q^½ (mean) | max abs Δ error "
          "| model σ ÷ σ |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for cell in sorted({k[:3] for k in keys}):
        sel = [k for k in keys if k[:3] == cell]
        b = [before[k] for k in sel]
        a = [after[k] for k in sel]
        err_b, err_a = (np.array([r["error_deg"] for r in rows]) for rows in (b, a))
        sig_b, sig_a = (np.array([r["sigma_deg"] for r in rows]) for rows in (b, a))
        rms_b, rms_a = (np.sqrt(np.mean((e / s) ** 2, axis=0)) for e, s in ((err_b, sig_b), (err_a, sig_a)))
        ratio = np.mean(sig_a / sig_b, axis=0)
        cov = [r.get("covariance") or {} for r in a]
        f = np.mean([c.get("variance_factor", np.nan) for c in cov])
        q = np.mean([c.get("psi_sigma0", np.nan) for c in cov])
        s0b = np.mean([r["sigma0_test"] for r in b])
        s0a = np.mean([r["sigma0_test"] for r in a])
        n = len(sel)
        print(f"| {cell[0]} {cell[1]} ({sel[0][3]}–{sel[-1][3]}) | {cell[2]} | {n} | "
              + " / ".join(f"{v:.2f}" for v in rms_b) + " → " + " / ".join(f"{v:.2f}" for v in rms_a)
              + f" (±{1 / np.sqrt(2 * n):.2f}) | " + " / ".join(f"{v:.3f}" for v in ratio)
              + f" | {np.abs(err_b / sig_b).max():.2f} → {np.abs(err_a / sig_a).max():.2f}"
              + f" | {s0b:.3f} → {s0a:.3f} | {f:.3f}, {q:.3f} | {np.abs(err_a - err_b).max():.1e}° | "
              + _shares(b, a) + " |")


def _shares(before: list[dict], after: list[dict]) -> str:
    """Mean model σ ÷ σ per angle, before → after (when every row recorded them)."""
    if not all("model_share" in r for r in before + after):
        return ""
    return " → ".join(" / ".join(f"{v:.2f}" for v in np.mean([r["model_share"] for r in rows], axis=0))
                      for rows in (before, after))


if __name__ == "__main__":
    main()
