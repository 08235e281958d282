"""The two-step method as prescribed (ΔS from scan-circle groups, then Δ from E points).

Step 1: for each group i of feature points A–D, ΔS_i = mean over the group of
(scanner range − S_PX), S_PX from the law of cosines; ΔS = mean of the ΔS_i.
Step 2: for each E point, true distance = S_PE + ΔS and Δ_j = scanner range − true distance;
Δ = mean of the Δ_j. The 95 % intervals here are the classical ones, from the scatter of
the ΔS_i (Student t, n_groups − 1 dof) and of the Δ_j (Welch–Satterthwaite dof for Δ, which
also carries the uncertainty of ΔS); they do not see errors common to all points of a
setup (the P observation) — the least-squares fit in :mod:`calidar.rangecal.fit` does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from calidar.io.total_station import TotalStationObservations


def mean_interval(values: np.ndarray, level: float = 0.95) -> tuple[float, float | None, float | None]:
    """Mean, its σ (scatter/√n) and the t half-width at ``level`` (None with fewer than 2 values)."""
    values = np.asarray(values, float)
    m = float(values.mean())
    if values.size < 2:
        return m, None, None
    s = float(values.std(ddof=1) / np.sqrt(values.size))
    return m, s, float(stats.t.ppf(0.5 + level / 2, values.size - 1) * s)


@dataclass
class MethodResult:
    """ΔS per group and overall, Δ_j per E point and Δ (all m), with σ and 95 % half-widths."""

    groups: list[str]
    group_delta_s: np.ndarray  #: ΔS_i (m)
    delta_s: float  #: ΔS (m)
    delta_s_sigma: float | None
    delta_s_half_width: float | None  #: 95 % half-width (m)
    e_points: list[str]
    e_lines: np.ndarray
    e_delta: np.ndarray  #: Δ_j (m)
    delta: float | None  #: Δ (m); None without E points
    delta_sigma: float | None
    delta_half_width: float | None

    def to_dict(self) -> dict:
        """JSON-ready summary (m)."""
        def iv(v, h):
            return None if v is None or h is None else [v - h, v + h]

        return {
            "groups": {g: float(v) for g, v in zip(self.groups, self.group_delta_s)},
            "delta_s_m": self.delta_s, "delta_s_sigma_m": self.delta_s_sigma,
            "delta_s_interval95_m": iv(self.delta_s, self.delta_s_half_width),
            "e_points": [{"point": p, "line": int(n), "delta_m": float(v)}
                         for p, n, v in zip(self.e_points, self.e_lines, self.e_delta)],
            "delta_m": self.delta, "delta_sigma_m": self.delta_sigma,
            "delta_interval95_m": iv(self.delta, self.delta_half_width),
        }


def two_step_method(obs: TotalStationObservations, distance: np.ndarray, level: float = 0.95) -> MethodResult:
    """The prescribed method on ``obs`` with P→X distances ``distance`` (m, one per target)."""
    diff = obs.scanner - distance
    groups = obs.groups
    g_ds = np.array([diff[(obs.kind == "feature") & (obs.group == g)].mean() for g in groups])
    ds, ds_sig, ds_hw = mean_interval(g_ds, level)
    is_e = obs.kind == "E"
    e_delta = obs.scanner[is_e] - (distance[is_e] + ds)
    delta = delta_sig = delta_hw = None
    if e_delta.size:
        delta = float(e_delta.mean())
        if e_delta.size >= 2 and ds_sig is not None:
            var_e = e_delta.var(ddof=1) / e_delta.size
            delta_sig = float(np.sqrt(var_e + ds_sig**2))
            # Welch–Satterthwaite degrees of freedom of the sum of two estimated variances
            nu = delta_sig**4 / (var_e**2 / (e_delta.size - 1) + ds_sig**4 / (len(groups) - 1))
            delta_hw = float(stats.t.ppf(0.5 + level / 2, nu) * delta_sig)
    return MethodResult(groups, g_ds, ds, ds_sig, ds_hw, list(obs.point[is_e]), obs.line[is_e], e_delta,
                        delta, delta_sig, delta_hw)
