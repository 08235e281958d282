"""A bounded trajectory level's uncertainty carried into the mounting's σ (issue 26, twelfth
session): a linear problem whose truth is known, through calidar.strips.trajectory_level's
estimate_level and carry_uncertainty as calidar boresight runs them."""

from types import SimpleNamespace

import numpy as np

import calidar.strips.trajectory_level as tl
from calidar.strips.trajectory_errors import Knot
from calidar.trajectory_accuracy import SURVEY_GRADE

N = 60  # knots per group
NOISE = 0.3  # the overlaps' σ on a knot (two looks each)
TIE = 0.01  # the σ of the one observation tying the mounting to the first heading knot
HEADING, TILT = 0.06, 0.5  # the true σ factors (stated: 1)


def _problem(seed: int):
    """Parameters [mounting, N heading knots, N tilt knots]; each knot seen twice (σ ``NOISE``),
    the mounting only through mounting + heading knot 0 (σ ``TIE``): it is known as well as that
    knot is, which the heading priors' level decides, and that one observation checks no prior.
    Returns the normal terms (weighted), the priors at the stated σ 1, the names, the layout, the
    true mounting."""
    rng = np.random.default_rng(seed)
    m = 0.7
    x = np.concatenate([[m], HEADING * rng.standard_normal(N), TILT * rng.standard_normal(N)])
    looks = np.repeat(np.eye(2 * N), 2, axis=0) / NOISE
    A = np.zeros((looks.shape[0] + 1, 2 * N + 1))
    A[:-1, 1:] = looks
    A[-1, [0, 1]] = 1.0 / TIE
    y = A @ x + rng.standard_normal(A.shape[0])  # weighted rows: unit noise
    terms = (A.T @ A, A.T @ -y, float(y @ y), float(A.shape[0]), np.zeros(2 * N + 1))
    names = ["boresight_yaw"] + [f"h{i}" for i in range(N)] + [f"t{i}" for i in range(N)]
    layout = {f"h{i}": Knot("tilt", 2, 0, i) for i in range(N)}
    layout |= {f"t{i}": Knot("tilt", 0, 0, i) for i in range(N)}
    priors = [(np.arange(1, N + 1), np.zeros(N), np.eye(N)),
              (np.arange(N + 1, 2 * N + 1), np.zeros(N), np.eye(N))]
    return terms, priors, names, layout, m


def _est(terms, priors, names):
    free = [SimpleNamespace(name=n) for n in names]
    return SimpleNamespace(fit=SimpleNamespace(priors=priors, free=free), terms=terms)


def _calibrated(seed: int, monkeypatch):
    """(mounting's error, its σ as reported, its plug-in σ at the held level, the level)."""
    terms, priors, names, layout, m = _problem(seed)
    monkeypatch.setattr(tl, "normal_terms", lambda est: est.terms)
    level = tl.estimate_level(_est(terms, priors, names), SURVEY_GRADE, layout)
    # the adjustment again with the level's priors, as calidar boresight does
    f = np.array([1.0] + [level.factor("heading")] * N + [level.factor("attitude_horizontal")] * N)
    held = [(idx, c, P / np.outer(f[idx], f[idx])) for idx, c, P in priors]
    Nm = terms[0].copy()
    for idx, _, P in held:
        Nm[np.ix_(idx, idx)] += P
    Q = np.linalg.inv(Nm)
    x = Q @ -terms[1]
    solution = SimpleNamespace(parameters=SimpleNamespace(free_names=names), covariance=Q.copy())
    tl.carry_uncertainty(level, _est(terms, held, names), solution, layout)
    return x[0] - m, float(np.sqrt(solution.covariance[0, 0])), float(np.sqrt(Q[0, 0])), level


def test_a_bounded_levels_uncertainty_is_carried_not_held_at_its_upper_end(monkeypatch):
    """Heading bounded (true 0.06 of the stated σ; bounded on 39 of 40 draws, held at its upper
    end); the mounting is known as well as heading knot 0 is. Held at the upper end alone its
    plug-in σ is too wide: RMS of error/σ 0.72 over the bounded draws (main before the twelfth
    session carried only estimated groups). Averaged over the level's confidence distribution
    below that end (its nodes, reported), about the estimate as it stands: 0.91, inside
    1 ± 2/√(2·40). (The same with the truth at 0.04, 0.08, 0.12: 0.84, 0.96, 1.08 against 0.68,
    0.76, 0.86 held: conservative where the truth lies deep in the flat part of the likelihood.)"""
    z, z_held, sigma, held, levels = [], [], [], [], []
    for seed in range(40):
        err, s, plug_in, level = _calibrated(seed, monkeypatch)
        if "heading" not in (level.bounded or {}):
            continue
        z.append(err / s)
        z_held.append(err / plug_in)
        sigma.append(s)
        held.append(plug_in)
        levels.append(level)
    assert len(z) >= 36, len(z)
    rms, rms_held = np.sqrt(np.mean(np.square(z))), np.sqrt(np.mean(np.square(z_held)))
    band = 2.0 / np.sqrt(2.0 * len(z))
    assert abs(rms - 1.0) < band, (rms, rms_held)
    assert rms_held < 1.0 - band, rms_held  # what the rule is for: the held σ too wide here
    assert np.mean(sigma) < 0.9 * np.mean(held), (np.mean(sigma), np.mean(held))
    for level in levels:  # the range carried, reported
        nodes = level.nodes["heading"]
        assert tl.FLOOR_FACTOR <= min(nodes) and max(nodes) <= level.factor("heading")
        assert list(nodes) == sorted(nodes)
        assert level.to_dict()["groups"]["heading"]["sigma_factor_nodes"] == list(nodes)
