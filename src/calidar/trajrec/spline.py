"""Uniform cubic B-splines over time: the basis of the reconstructed trajectory's channels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Spline:
    """A uniform cubic B-spline on [t0, t0 + n_intervals·step] (s): ``n_coef`` = n_intervals + 3."""

    t0: float
    step: float
    n_intervals: int

    @classmethod
    def covering(cls, t_start: float, t_end: float, step: float) -> "Spline":
        n = max(int(np.ceil((t_end - t_start) / step - 1e-9)), 1)
        return cls(float(t_start), float(step), n)

    @property
    def n_coef(self) -> int:
        return self.n_intervals + 3

    @property
    def t_end(self) -> float:
        return self.t0 + self.n_intervals * self.step

    def basis(self, t) -> tuple[np.ndarray, np.ndarray]:
        """(first coefficient index (N,), weights (N, 4)) of times ``t``: value = Σ_j w_j · c[i +
        j], the uniform cubic B-spline's blending functions."""
        i, f = self._interval(t)
        f2, f3 = f * f, f * f * f
        blend = [(1 - f) ** 3, 3 * f3 - 6 * f2 + 4, -3 * f3 + 3 * f2 + 3 * f + 1, f3]
        w = np.stack(blend, axis=1) / 6.0
        return i, w

    def _interval(self, t) -> tuple[np.ndarray, np.ndarray]:
        """(interval index (N,), fraction of it (N,)) of times ``t`` (s)."""
        u = (np.asarray(t, float) - self.t0) / self.step
        i = np.clip(np.floor(u).astype(np.int64), 0, self.n_intervals - 1)
        return i, u - i

    def evaluate(self, coef: np.ndarray, t) -> np.ndarray:
        """Values at ``t`` of coefficients (n_coef,) or (n_coef, k)."""
        i, w = self.basis(t)
        idx = i[:, None] + np.arange(4)
        c = np.asarray(coef)
        return np.einsum("nj,nj...->n...", w, c[idx])

    def derivative(self, coef: np.ndarray, t) -> np.ndarray:
        """First derivative (per s) at ``t``."""
        i, f = self._interval(t)
        blend = [-(1 - f) ** 2, 3 * f * f - 4 * f, -3 * f * f + 2 * f + 1, f * f]
        w = np.stack(blend, axis=1) / (2.0 * self.step)
        c = np.asarray(coef)
        return np.einsum("nj,nj...->n...", w, c[i[:, None] + np.arange(4)])

    def fit(self, t, values, smooth: float = 1e-6) -> np.ndarray:
        """Least-squares coefficients of samples (t, values (N,) or (N, k)), lightly regularised by
        second differences (weight ``smooth``) so that sparse samples still give a unique answer."""
        i, w = self.basis(t)
        a = np.zeros((len(t), self.n_coef))
        np.add.at(a, (np.arange(len(t))[:, None], i[:, None] + np.arange(4)), w)
        d2 = np.diff(np.eye(self.n_coef), 2, axis=0)
        n = a.T @ a + smooth * max(len(t), 1) * d2.T @ d2
        return np.linalg.solve(n, a.T @ np.asarray(values, float))
