"""The two-step method as prescribed (ΔS from scan-circle groups, then Δ from E points).

Step 1: for each group i of feature points A–D, ΔS_i = mean over the group of
(scanner range − S_PX), S_PX from the law of cosines; ΔS = mean of the ΔS_i.
Step 2: for each E point, true distance = S_PE + ΔS and Δ_j = scanner range − true distance;
Δ = mean of the Δ_j.

ΔS and Δ are linear in the observation errors, so their σ follow by linear propagation
of the stated precisions (scanner noise, each target's polar observation, and each setup's
P observation, which is common to all its targets); the 95 % intervals are ±1.96 σ. With
a range scale error k, ΔS estimates offset + k·(mean feature-point range) and Δ the scale
effect k·(mean E range − that range) — the least-squares fit separates the two.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from calidar.io.total_station import TotalStationObservations


def propagated_sigma(obs: TotalStationObservations, weights: np.ndarray, partials: np.ndarray,
                     sigma: np.ndarray) -> float:
    """σ (m) of Σ w_i·(scanner_i − S_PX,i): ``sigma`` (n,) the σ of each target's own
    observations (scanner + polar, m), ``partials`` (n, 6) of S_PX; P's errors are shared per
    setup."""
    var = float(np.sum(weights**2 * sigma**2))
    for i, s in enumerate(obs.setups):
        g = -np.sum(weights[obs.setup == i, None] * partials[obs.setup == i, :3], axis=0)
        slope_sigma = float(s.distance_sigma(s.p_slope))
        var += g[0] ** 2 * slope_sigma ** 2 + (g[1] ** 2 + g[2] ** 2) * s.angle_sigma**2
    return float(np.sqrt(var))


@dataclass
class MethodResult:
    """ΔS per group and overall, Δ_j per E point and Δ (all m), with σ and 95 % half-widths."""

    groups: list[str]
    group_delta_s: np.ndarray  #: ΔS_i (m)
    delta_s: float  #: ΔS (m)
    delta_s_sigma: float
    delta_s_half_width: float  #: 95 % half-width (m)
    e_points: list[str]
    e_lines: np.ndarray
    e_delta: np.ndarray  #: Δ_j (m)
    delta: float | None  #: Δ (m); None without E points
    delta_sigma: float | None
    delta_half_width: float | None
    feature_group: np.ndarray  #: (k,) group of each feature point used
    feature_point: np.ndarray  #: (k,) its name (A–D)
    feature_diff: np.ndarray  #: (k,) scanner range − S_PX (m)

    def to_dict(self) -> dict:
        """JSON-ready summary (m)."""
        def iv(v, h):
            return None if v is None else [v - h, v + h]

        return {
            "groups": {g: float(v) for g, v in zip(self.groups, self.group_delta_s)},
            "delta_s_m": self.delta_s, "delta_s_sigma_m": self.delta_s_sigma,
            "delta_s_interval95_m": iv(self.delta_s, self.delta_s_half_width),
            "e_points": [{"point": p, "line": int(n), "delta_m": float(v)}
                         for p, n, v in zip(self.e_points, self.e_lines, self.e_delta)],
            "delta_m": self.delta, "delta_sigma_m": self.delta_sigma,
            "delta_interval95_m": iv(self.delta, self.delta_half_width),
        }


def two_step_method(obs: TotalStationObservations, distance: np.ndarray, partials: np.ndarray,
                    sigma: np.ndarray, level: float = 0.95) -> MethodResult:
    """The prescribed method on ``obs``: ``distance`` S_PX (m), its ``partials`` (n, 6) and
    the σ (m) of each target's own observations, one per target."""
    z = float(stats.norm.ppf(0.5 + level / 2))
    diff = obs.scanner - distance
    groups = obs.groups
    members = [(obs.kind == "feature") & (obs.group == g) for g in groups]
    g_ds = np.array([diff[m].mean() for m in members])
    w_ds = np.zeros(len(obs))
    for m in members:
        w_ds[m] = 1.0 / (m.sum() * len(groups))
    ds = float(w_ds @ diff)
    ds_sig = propagated_sigma(obs, w_ds, partials, sigma)
    is_e = obs.kind == "E"
    e_delta = diff[is_e] - ds
    delta = delta_sig = delta_hw = None
    if e_delta.size:
        w_d = np.where(is_e, 1.0 / max(is_e.sum(), 1), 0.0) - w_ds
        delta = float(w_d @ diff)
        delta_sig = propagated_sigma(obs, w_d, partials, sigma)
        delta_hw = z * delta_sig
    feat = obs.kind == "feature"
    return MethodResult(groups, g_ds, ds, ds_sig, z * ds_sig,
                        list(obs.point[is_e]), obs.line[is_e], e_delta, delta, delta_sig, delta_hw,
                        obs.group[feat], obs.point[feat], diff[feat])


LEVEL_CRITICAL = 3.29  #: |height offset / σ| above which A or B is not level with P (α = 0.001)


def level_check(obs: TotalStationObservations) -> dict:
    """Does the geometry meet the method's premise, A and B level with P (scanner set level)?
    Height of A/B above P, h = S_OX sin β_X − S_OP sin β_P (m), its σ from the stated
    precisions, and the largest |h|/σ; ``level`` is False above LEVEL_CRITICAL."""
    ab = (obs.kind == "feature") & np.isin(obs.point, ["A", "B"])
    if not ab.any():
        return {"level": True, "max_abs_height_m": 0.0, "max_abs_z": 0.0, "worst_line": None}
    setups = np.array([[s.p_slope, s.p_va, s.angle_sigma, float(s.distance_sigma(s.p_slope))]
                       for s in obs.setups])
    s_p, va_p, ang, sig_sp = setups[obs.setup[ab]].T
    s_x, va_x = obs.slope[ab], obs.va[ab]
    dh = s_x * np.sin(va_x) - s_p * np.sin(va_p)
    sig_sx = np.array([float(obs.setups[i].distance_sigma(s)) for i, s in zip(obs.setup[ab], s_x)])
    var = ((np.sin(va_x) * sig_sx) ** 2 + (s_x * np.cos(va_x) * ang) ** 2
           + (np.sin(va_p) * sig_sp) ** 2 + (s_p * np.cos(va_p) * ang) ** 2)
    z = dh / np.sqrt(var)
    worst = int(np.argmax(np.abs(z)))
    return {"level": bool(abs(z[worst]) <= LEVEL_CRITICAL),
            "max_abs_height_m": float(np.max(np.abs(dh))),
            "max_abs_z": float(abs(z[worst])), "worst_line": int(obs.line[ab][worst])}
