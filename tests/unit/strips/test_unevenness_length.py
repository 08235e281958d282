"""ℓ of the surface's unevenness read from b's neighbourhoods (issue 26, thirteenth session;
:mod:`calidar.strips.unevenness_length`).

Surfaces with Gaussian-correlated unevenness of known ℓ (random Fourier features, as
``test_vgicp_row_sampling`` draws them) under white noise, half of the rows quiet, sampled as
b's 12 points over an airborne-like 3 m disc and a UAV-like 0.45 m one: the fit finds ℓ on its
grid's nearest node (nodes 2^(1/2) apart: within ×1.2 of the truth) and σ_u, σ_e within 10 %
where ℓ ≤ the disc's radius. Beyond it the points see mostly the unevenness's curvature
(σ_u²/ℓ⁴) and ℓ trades against σ_u: ℓ 5 m on 3 m discs reads 8–16 m over seeds 3–8 (only
"longer than the neighbourhoods" is asserted; the rows' Q/ḡ tends to a limit there). On white
noise alone it reads ℓ = 0 (the white formula)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.strips.unevenness_length import LENGTHS_M, estimate_length, pair_surface, pooled_fit
from calidar.strips.vgicp_planes import local_planes


def _field(rng, xy: np.ndarray, length_m: float, modes: int = 300) -> np.ndarray:
    """A unit-variance draw with correlation exp(−d²/2ℓ²) at ``xy`` (m)."""
    k = rng.normal(0.0, 1.0 / length_m, (modes, 2))
    return np.sqrt(2.0 / modes) * np.cos(xy @ k.T + rng.uniform(0, 2 * np.pi, modes)).sum(axis=1)


def _neighbourhoods(length_m: float, radius: float, noise: float, amp: float, seed: int,
                    n_rows: int = 1200):
    """b's rows (M, 12, 3), their planes' centroids and axes; half the rows rough."""
    rng = np.random.default_rng(seed)
    pts = []
    for i in range(n_rows):
        r, t = radius * np.sqrt(rng.uniform(0, 1, 12)), rng.uniform(0, 2 * np.pi, 12)
        xy = np.column_stack([r * np.cos(t), r * np.sin(t)])
        z = amp * (i % 2) * _field(rng, xy, length_m) + rng.normal(0.0, noise, 12)
        pts.append(np.column_stack([xy, z + 0.1 * xy[:, 0]]) + [100.0 * i, 0.0, 0.0])
    b = np.vstack(pts)
    planes = local_planes(b, np.array([[100.0 * i, 0.0, 0.0] for i in range(n_rows)]), 12, 1)
    return b[planes.index], planes.centroid, planes.eigvec


@pytest.mark.parametrize("length_m, radius, noise, amp", [
    (2.0, 3.0, 0.03, 0.3),    # airborne-like: 3 m discs, 3 cm noise
    (0.7, 3.0, 0.03, 0.1),    # unevenness shorter than the disc
    (5.0, 3.0, 0.03, 0.3),    # longer than the disc
    (0.5, 0.45, 0.005, 0.05)  # UAV-like: 0.45 m discs, 5 mm noise
])
def test_length_recovered(length_m, radius, noise, amp):
    fit = estimate_length(*_neighbourhoods(length_m, radius, noise, amp, seed=3))
    assert fit.length_range_m[0] <= fit.length_m <= fit.length_range_m[1]
    assert fit.sigma_e_m == pytest.approx(noise, rel=0.1)
    if length_m > radius:
        assert fit.length_m > radius
        return
    assert fit.length_m == pytest.approx(length_m, rel=0.2)
    assert fit.sigma_u_m == pytest.approx(amp, rel=0.1)
    assert fit.rows == 300


def test_white_noise_reads_white():
    """No correlated unevenness (rough and quiet rows differ only in their noise): ℓ = 0."""
    rows, centroid, axes = _neighbourhoods(2.0, 3.0, 0.03, 0.0, seed=4)
    fit = estimate_length(rows, centroid, axes)
    assert fit.length_m == 0.0
    assert fit.sigma_u_m < 0.3 * fit.sigma_e_m


def test_the_likelihood_tells_the_models_apart():
    """On a Gaussian-correlated surface the Gaussian R's maximum log L beats the exponential's
    on the same rows (the benchmark's model comparison on real strips rests on it)."""
    rows = _neighbourhoods(2.0, 3.0, 0.03, 0.3, seed=5)
    gauss, expo = (estimate_length(*rows, kernel=k) for k in ("gaussian", "exponential"))
    assert gauss.loglik > expo.loglik + 10.0


def test_grid_spans_the_brief():
    assert LENGTHS_M[0] == pytest.approx(0.25) and LENGTHS_M[-1] == pytest.approx(16.0)


def test_report_names_the_estimate():
    """The report's sentence: the pooled ℓ, its range, the pairs and rows it pooled, the pairs'
    own range; none without."""
    from calidar.strips.report import unevenness_text
    fit = {"length_range_m": [1.0, 3.0], "sigma_u_m": 0.04, "sigma_e_m": 0.03}
    pairs = [{"a": 1, "b": 2, "unevenness": fit | {"length_m": 2.0, "rows": 500}},
             {"a": 1, "b": 3, "unevenness": fit | {"length_m": 2.83, "rows": 400}},
             {"a": 2, "b": 3, "unevenness": fit | {"length_m": 1.41, "rows": 300}}]
    pooled = fit | {"length_m": 2.0, "rows": 1200, "pairs": 3}
    text = unevenness_text(pairs, pooled)
    assert "ℓ = 2 m (95 % range 1–3 m" in text and "1,200 neighbourhoods of 3 pairs" in text
    assert "each pair alone: 1.4–2.8 m" in text
    assert "σ_u 40.0 mm over the points' noise σ_e 30.0 mm" in text
    assert unevenness_text([{"a": 1, "b": 2, "n_obs": 10}], None) == ""


@pytest.mark.parametrize("length_m, n_rows", [(0.7, 40), (2.0, 60)])
def test_pooled_fit_reads_what_small_pairs_alone_read_badly(length_m, n_rows):
    """Ten small "pairs" (20 / 30 rough rows each, σ_u = σ_e = 3 cm on 3 m discs) read ℓ one by
    one off by a grid node or more most of the time (measured: 7 of 10 each, 0.35–8 m for 2 m);
    the sum of their log L surfaces (τ per pair) reads it on the nearest node, with a range
    narrower than the pairs' median one and σ_u, σ_e within 15 %."""
    alone, surfaces = [], []
    for seed in range(10, 20):
        rows = _neighbourhoods(length_m, 3.0, 0.03, 0.03, seed=seed, n_rows=n_rows)
        alone.append(estimate_length(*rows))
        surfaces.append(pair_surface(*rows))
    off = [abs(np.log(max(f.length_m, 0.1) / length_m)) > np.log(1.2) for f in alone]
    assert sum(off) >= 5
    pooled = pooled_fit(surfaces)
    assert pooled.length_m == pytest.approx(length_m, rel=0.2)
    assert pooled.rows == sum(f.rows for f in alone) == 10 * n_rows // 2
    low, high = pooled.length_range_m
    assert low <= pooled.length_m <= high
    widths = [np.log(f.length_range_m[1] / f.length_range_m[0]) for f in alone]
    assert np.log(high / low) < np.median(widths)
    assert pooled.sigma_u_m == pytest.approx(0.03, rel=0.15)
    assert pooled.sigma_e_m == pytest.approx(0.03, rel=0.15)


def test_one_pair_pooled_is_its_own_fit():
    """:func:`pooled_fit` of one surface is that pair's fit (one implementation of the fit)."""
    rows = _neighbourhoods(2.0, 3.0, 0.03, 0.3, seed=6, n_rows=200)
    one, own = pooled_fit([pair_surface(*rows)]), estimate_length(*rows)
    assert one == own and own.surface is not None and one.length_m > 0


def test_the_run_pools_the_first_pass_and_fixes_the_matcher():
    """After the first matching pass the run pools the pairs' surfaces, fixes the pooled ℓ in the
    VGICP matcher for the later passes (no fit then) and keeps each pair's own fit for the
    record (solution.json's pairs) with the pooled one beside it."""
    import scipy.sparse as sp

    from calidar.strips.correspond import Correspondences
    from calidar.strips.matchers import Vgicp
    from calidar.strips.outer_loop import Run
    from calidar.strips.overlap import Overlap

    run = Run.__new__(Run)
    run.matcher, run.unevenness, run.pair_fits = Vgicp(), None, {}
    run.settings = type("S", (), {"min_correspondences": 1})()
    corrs, surfaces = [], []
    for b, seed in ((2, 20), (3, 21), (4, 22)):
        fit = estimate_length(*_neighbourhoods(2.0, 3.0, 0.03, 0.03, seed=seed, n_rows=60))
        one = sp.csr_matrix(np.ones((1, 1)))
        corrs.append(Correspondences(1, b, one, one, np.array([[0.0, 0.0, 1.0]]),
                                     unevenness=fit.to_dict(), unevenness_surface=fit.surface))
        surfaces.append(fit.surface)
    run._pool_unevenness(corrs)
    pooled = pooled_fit(surfaces)
    assert run.matcher.settings.unevenness_length_m == pooled.length_m > 0
    assert run.unevenness == pooled.to_dict() | {"pairs": 3}
    later = [Correspondences(1, b, c.A, c.B, c.normal) for b, c in zip((2, 3, 4), corrs)]
    run.overlaps = [Overlap.__new__(Overlap) for _ in later]
    for o, b in zip(run.overlaps, (2, 3, 4)):
        object.__setattr__(o, "a", 1)
        object.__setattr__(o, "b", b)
    _, pairs, _ = run._usable(later, widened=True)
    assert [p["unevenness"] for p in pairs] == [c.unevenness for c in corrs]
    run._pool_unevenness(later)  # nothing to pool: kept
    assert run.matcher.settings.unevenness_length_m == pooled.length_m
