"""Each control target's survey error as one nuisance parameter of the strip adjustment (issue 28).

A control point is seen by the k strips that cover it; its survey error ε (σ_c, from the control
file) enters all k rows alike. Counting its variance in each row as if independent overweights
the control k-fold; counting it k times in each row (the earlier ``share_survey_error``) is exact
only for what every row sees alike (a common height), and wastes what the rows tell apart: the
strips see one point at different scan angles, and a range offset moves their surfaces by
different amounts there, which the common ε cannot mimic.

The right depth is the rows' joint distribution, r = J·θ − g·ε + e with ε ~ N(0, σ_c²) and e the
surfaces' own noise (independent): one nuisance parameter δ per control target with prior σ_c,
the row r − g·δ weighed by its surface noise alone. Marginalising δ gives back the generalised
least squares with the rows' full covariance D + σ_c²·g·gᵀ (Koch 1999, Parameter Estimation and
Hypothesis Testing in Linear Models, §3.4: random parameters with priors ≡ correlated observations;
tests/unit/strips/test_control_survey.py checks it against that GLS).

g per row (each kind's ``survey_design``): a control point's height correction δ (up) moves its
row r = n·(p̄ − c) by −n_z·δ; a control plane's error is its three coefficients' (height at the
centroid and two slopes, prior covariance C from its survey, one correlated group), which move a
row at p̄ by −n_z·(1, dx, dy)·δ (dx, dy: p̄ from the centroid); a reference cloud's is its datum.
The rows as the control kinds build them hold that survey variance (a row's own σ, what
solution.json's dz/σ uses); here it is taken out of the weight. :class:`SurveyErrors` wraps the
:class:`~calidar.strips.problem.StripProblem` after the residual protocol
(:mod:`calidar.adjust.residuals`): the nuisance columns are a typed :class:`~calidar.adjust.Block`
it owns, with their exact (constant) Jacobian −G.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp

from calidar.adjust import Block, Parameter, ParameterSet, ResidualProblem

#: every control target's survey-error parameter's name starts so (nuisance)
PREFIX = "control_survey_"
CONTROL_STRIP = -1  #: the control pseudo-strip's id (calidar.strips.problem.CONTROL_STRIP)


def per_target_parameters(sigma_m: np.ndarray) -> list[Parameter]:
    """One parameter per control target with a survey σ > 0: its survey error (m; a point's height,
    a plane's offset along its normal), prior 0 ± σ (what control points and planes answer to
    ``survey_parameters()``)."""
    return [Parameter(f"{PREFIX}{k}", 0.0, "m", prior_sigma=float(s))
            for k, s in enumerate(np.asarray(sigma_m, float)) if s > 0]


def per_target_design(sigma_m: np.ndarray, k: np.ndarray,
                      g: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:  # noqa: D401
    """The rows of targets ``k`` on :func:`per_target_parameters`' columns, each moved by ``g`` (n,)
    per unit of its target's survey error, and the variance to take out of each row's σ² (its
    target's survey variance, which the row's own σ holds)."""
    sigma = np.asarray(sigma_m, float)
    column = np.cumsum(sigma > 0) - 1  # target → its parameter's column (those with σ > 0)
    has = sigma[k] > 0
    rows = np.flatnonzero(has)
    M = sp.csr_matrix((np.asarray(g, float)[has], (rows, column[k[has]])),
                      shape=(len(k), int(np.sum(sigma > 0))))
    return M, np.where(has, sigma[k] ** 2, 0.0)


def survey_parameters(control) -> list[Parameter]:
    """The control's survey-error parameters (its kind says which: ``survey_parameters()``)."""
    return control.survey_parameters()


def with_survey_parameters(params: ParameterSet, control) -> ParameterSet:
    """``params`` with the control's survey-error parameters appended (none without control)."""
    return params if control is None else ParameterSet([*params, *survey_parameters(control)])


def row_places(inner, i: int) -> np.ndarray:
    """Where the rows of correspondence set ``i`` of a StripProblem stand (n, 3) local m: the strip
    side's weighted points at the nominal sensor (the calibration moves them by cm)."""
    c = inner.corrs[i]
    if inner.centroids is not None:
        side = inner.centroids[i][0]
        return side(inner.nominal) / np.maximum(side.rowsum, 1e-300)[:, None]
    from calidar.strips.strip import georeference_pose

    pts = georeference_pose(inner.nominal, inner.pose(c.strip_a))
    return (c.A @ pts) / np.maximum(np.asarray(c.A.sum(axis=1)).ravel(), 1e-300)[:, None]


class SurveyErrors(ResidualProblem):
    """``inner`` (a StripProblem whose parameters hold :func:`survey_parameters`) with each control
    row's survey error as the nuisance parameter of its target: residuals r − G·δ, row σ without
    the survey part, Jacobian [∂r/∂θ, −G]. Everything else (``index``, ``split``, ``clusters``,
    calling it: residuals against the surveyed control) is the inner problem's."""

    def __init__(self, inner, control):
        self.inner, self.parameters = inner, inner.parameters
        self.absolute_sigma = inner.absolute_sigma
        self.prior_correlation = (*inner.prior_correlation,
                                  *getattr(control, "survey_correlation", tuple)())
        names = [p.name for p in survey_parameters(control)]
        self.block = Block.of(self.parameters.names, {n: j for j, n in enumerate(names)})
        sigma2 = np.broadcast_to(np.asarray(inner.sigma, float), (len(inner.sigma),)).copy() ** 2
        parts, start = [], 0
        for i, c in enumerate(inner.corrs):
            n = c.n_obs * (3 if c.normal is None else 1)
            if c.strip_b == CONTROL_STRIP:
                # one target per row, in row order
                k = inner.index[CONTROL_STRIP][c.B.tocsr().indices]
                M, removed = control.survey_design(k, c.normal, row_places(inner, i))
                sigma2[start:start + n] = np.maximum(sigma2[start:start + n] - removed, 1e-12)
                parts.append(M)
            else:
                parts.append(sp.csr_matrix((n, len(names))))
            start += n
        G = sp.vstack(parts, format="csr") if parts else sp.csr_matrix((0, len(names)))
        self.G = G[:, list(self.block.keys)]  # in the block's order
        self.sigma = np.sqrt(sigma2)
        free = self.parameters.free_names
        own = set(self.block.names)
        self.inner_free = [p for p in self.parameters.free if p.name not in own]
        order = ([i for i, n in enumerate(free) if n not in own]
                 + [i for i, n in enumerate(free) if n in own])
        self._nuisance = [self.block.names.index(free[i]) for i in order[len(self.inner_free):]]
        self._order = None if order == list(range(len(order))) else np.argsort(order)

    def __getattr__(self, name):
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    def __call__(self, values: Mapping[str, float]) -> np.ndarray:
        """The inner problem's residuals: the strips against the control as surveyed."""
        return self.inner(values)

    def residuals(self, values: Mapping[str, float]) -> np.ndarray:
        return np.asarray(self.inner.residuals(values), float) - self.G @ self.block.take(values)

    def jacobian(self, values: Mapping[str, float]):
        J = self.inner.jacobian(values, self.inner_free)
        G = -self.G[:, self._nuisance]
        if sp.issparse(J):
            out = sp.hstack([sp.csr_matrix(J), G], format="csr")
        else:
            out = np.hstack([np.asarray(J, float).reshape(G.shape[0], -1), G.toarray()])
        return out if self._order is None else out[:, self._order]

    def survey_errors(self, solution) -> dict[int, tuple[float, float]]:
        """Per control target with a parameter: its estimated survey error and σ (m)."""
        return {k: (float(solution.values[n]), float(solution.sigma[n]))
                for n, k in zip(self.block.names, self.block.keys)
                if n in solution.values}
