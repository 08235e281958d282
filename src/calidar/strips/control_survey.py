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

g per row: a control point's height correction δ (up) moves its row r = n·(p̄ − c) by −n_z·δ
(:meth:`calidar.strips.control.ControlPoints.survey_coefficients`); a control plane's offset δ
along its normal moves its row by −δ (:meth:`calidar.strips.control_planes.ControlPlanes.survey_coefficients`).
The rows as the control kinds build them hold the survey variance σ_c² (a row's own σ); here it
is taken out of the weight (the rest stays: the surface's noise, a plane's tilt at the strip's
points). :class:`SurveyErrors` wraps the :class:`~calidar.strips.problem.StripProblem` after the
residual protocol (:mod:`calidar.adjust.residuals`): the nuisance columns are a typed
:class:`~calidar.adjust.Block` it owns, with their exact (constant) Jacobian −G.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp

from calidar.adjust import Block, Parameter, ParameterSet, ResidualProblem

PREFIX = "control_survey_"  #: every control target's survey-error parameter's name starts so (nuisance)
CONTROL_STRIP = -1  #: the control pseudo-strip's id (calidar.strips.problem.CONTROL_STRIP)


def survey_parameters(control) -> list[Parameter]:
    """One parameter per control target with a survey σ > 0: its survey error (m; a point's height,
    a plane's offset along its normal), prior 0 ± σ."""
    return [Parameter(f"{PREFIX}{k}", 0.0, "m", prior_sigma=float(s))
            for k, s in enumerate(np.asarray(control.sigma_m, float)) if s > 0]


def with_survey_parameters(params: ParameterSet, control) -> ParameterSet:
    """``params`` with the control's survey-error parameters appended (none without control)."""
    return params if control is None else ParameterSet([*params, *survey_parameters(control)])


class SurveyErrors(ResidualProblem):
    """``inner`` (a StripProblem whose parameters hold :func:`survey_parameters`) with each control
    row's survey error as the nuisance parameter of its target: residuals r − G·δ, row σ without
    the survey part, Jacobian [∂r/∂θ, −G]. Everything else (``index``, ``split``, ``clusters``,
    calling it: residuals against the surveyed control) is the inner problem's."""

    def __init__(self, inner, control, targets: Mapping[int, int] | None = None):
        """``targets``: the control pseudo-strip's point index → control target (default: the same)."""
        self.inner, self.parameters = inner, inner.parameters
        self.prior_correlation = inner.prior_correlation
        self.block = Block.of(self.parameters.names, {f"{PREFIX}{k}": k for k in range(len(control.ids))})
        column = {k: j for j, k in enumerate(self.block.keys)}
        sigma2 = np.broadcast_to(np.asarray(inner.sigma, float), (len(inner.sigma),)).copy() ** 2
        rows, cols, coef, start = [], [], [], 0
        for c in inner.corrs:
            n = c.n_obs * (3 if c.normal is None else 1)
            if c.strip_b == CONTROL_STRIP:
                k = inner.index[CONTROL_STRIP][c.B.tocsr().indices]  # one target per row, in row order
                g = control.survey_coefficients(c.normal)
                has = np.array([kk in column for kk in k], bool)
                rows.append(start + np.flatnonzero(has))
                cols.append(np.array([column[kk] for kk in k[has]], np.int64))
                coef.append(g[has])
                at = start + np.flatnonzero(has)
                sigma2[at] = np.maximum(sigma2[at] - np.asarray(control.sigma_m, float)[k[has]] ** 2, 1e-12)
            start += n
        cat = (lambda a, t: np.concatenate(a) if a else np.zeros(0, t))
        self.G = sp.csr_matrix((cat(coef, float), (cat(rows, np.int64), cat(cols, np.int64))),
                               shape=(start, len(self.block.names)))
        self.sigma = np.sqrt(sigma2)
        free = self.parameters.free_names
        own = set(self.block.names)
        self.inner_free = [p for p in self.parameters.free if p.name not in own]
        order = [i for i, n in enumerate(free) if n not in own] + [i for i, n in enumerate(free) if n in own]
        self._nuisance = [self.block.names.index(free[i]) for i in order[len(self.inner_free):]]
        self._order = None if order == list(range(len(order))) else np.argsort(order)

    def __getattr__(self, name):
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    def __call__(self, values: Mapping[str, float]) -> np.ndarray:
        """The inner problem's residuals: the strips against the surveyed control (no survey correction)."""
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
        return {k: (float(solution.values[n]), float(solution.sigma[n])) for n, k in zip(self.block.names, self.block.keys)
                if n in solution.values}
