"""Benchmark: the strip adjustment's normal equations — what a sparse or banded factorisation would save.

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/normal_equations.py \
        [--size 8.75] [--method planes] [--repeat 5]

The survey of ``benchmarks/strips_scale.py`` (cached under ``--cache``, not timed) is calibrated once as
``calidar boresight`` does (:func:`calidar.calibrate_strips`, the trajectory model on); every normal
matrix the solver forms is counted, and the last one's inputs (J, W, priors) kept. On it, in CPU seconds
of this process on one BLAS thread (medians of ``--repeat``): JᵀWJ as the solver forms it (numba, dense
result), the dense Cholesky factorisation and solve the solver does per trial step (LAPACK potrf/potrs),
and the inverse the solution takes once (potrf + potri); then the options for a kept symbolic analysis:
the pattern's density (JᵀWJ alone and with the priors' precision, whose exact zeros ``inv(R)`` leaves as
round-off), the half-width of the band left by reverse Cuthill–McKee with the densest columns (the
sensor's) put last, and SuperLU (scipy ``splu``, minimum-degree ordering on AᵀA + A, symmetric mode)
on N with the priors' round-off dropped, with its fill and its difference from the dense solution.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_scale import simulate  # noqa: E402  (the shared 8-strip survey at a size)


def median_cpu(fn, repeat: int):
    """(median CPU seconds of ``repeat`` calls, the last result)."""
    times, out = [], None
    for _ in range(repeat):
        t = time.process_time()
        out = fn()
        times.append(time.process_time() - t)
    return float(np.median(times)), out


def capture(sim: Path, method: str) -> tuple[dict, int]:
    """The last normal equations' inputs of one calibration and how many normal matrices it formed."""
    import calidar
    from dataclasses import replace

    from calidar.adjust import solver
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import matchers_named

    seen, original = [], solver._Fit.normal_equations

    def keep(self, J, w, r=None, x=None):
        out = original(self, J, w, r, x)
        seen.append(dict(J=J, w=w, priors=self.priors, N=out[0], g=out[1]))
        del seen[:-1]
        keep.count += 1
        return out

    keep.count = 0
    solver._Fit.normal_equations = keep
    cfg = StripConfig()
    cfg = replace(cfg, calibration=replace(cfg.calibration, matchers=matchers_named(method)))
    try:
        calidar.calibrate_strips(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml", cfg)
    finally:
        solver._Fit.normal_equations = original
    return seen[-1], keep.count


def main() -> None:
    import scipy.linalg as sl
    import scipy.sparse as sp
    import scipy.sparse.linalg as sla
    from scipy.sparse.csgraph import reverse_cuthill_mckee
    from threadpoolctl import threadpool_limits

    from calidar.adjust.normals import normal_matrix, solve_damped

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=8.75, help="survey size, million points")
    ap.add_argument("--method", default="planes", choices=["planes", "vgicp"])
    ap.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir()) / "calidar_bench_strips_scale")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    sim = simulate(args.cache, args.size)
    last, count = capture(sim, args.method)
    J, w, N, g = last["J"].tocsr(), last["w"], last["N"], last["g"]
    n = N.shape[0]
    with threadpool_limits(1, user_api="blas"):
        t_gram, NJ = median_cpu(lambda: normal_matrix(J, w), args.repeat)
        t_solve, x = median_cpu(lambda: solve_damped(N, g), args.repeat)
        t_inv, _ = median_cpu(lambda: sl.lapack.dpotri(sl.cho_factor(N, lower=True)[0], lower=True), args.repeat)
        scale = np.sqrt(np.outer(np.diag(N), np.diag(N)))
        Ns = np.where(np.abs(N) < 1e-13 * scale, 0.0, N)
        S = sp.csc_matrix(Ns)
        t_lu, lu = median_cpu(lambda: sla.splu(S, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                               options=dict(SymmetricMode=True)), args.repeat)
        x_lu = lu.solve(g)
    nz = NJ != 0
    degree = nz.sum(axis=1)
    border = np.flatnonzero(degree > max(64, 0.2 * n))
    rest = np.setdiff1d(np.arange(n), border)
    order = rest[reverse_cuthill_mckee(sp.csr_matrix(nz[np.ix_(rest, rest)]), symmetric_mode=True)]
    i, j = np.nonzero(nz[np.ix_(order, order)])
    print(f"{args.size:g} M points, {args.method}: {count} normal matrices formed; the last: {n} parameters, "
          f"J {J.shape[0]} rows × {J.nnz} nonzeros")
    print(f"  JᵀWJ (numba, dense) {t_gram:.3f} s; dense Cholesky + solve {t_solve:.3f} s; inverse (potrf + potri) "
          f"{t_inv:.3f} s")
    print(f"  nonzeros: JᵀWJ {np.count_nonzero(NJ) / n**2:.1%}, N with the priors {np.count_nonzero(N) / n**2:.1%} "
          f"({np.count_nonzero(Ns) / n**2:.1%} without their round-off < 1e-13)")
    print(f"  reverse Cuthill–McKee of JᵀWJ's pattern, {border.size} dense columns last: half-band "
          f"{int(np.max(np.abs(i - j)))} of {rest.size}")
    print(f"  SuperLU (MMD on AᵀA + A, symmetric mode) {t_lu:.3f} s, fill {lu.L.nnz + lu.U.nnz} "
          f"({(lu.L.nnz + lu.U.nnz) / n**2:.1%} of n²), solution differs from the dense one by "
          f"{np.max(np.abs(x_lu - x)) / np.max(np.abs(x)):.1e} relative")


if __name__ == "__main__":
    main()
