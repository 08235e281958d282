"""The model check: would a structural parameter that is not estimated move the estimated ones?

A calibration estimates some sensor parameters (by default the boresight) and holds the others at
their nominal values. When one of those held is wrong — a range offset nobody estimated — the
trajectory corrections and the estimated angles absorb it, the overlaps close, σ0 is fine, and the
angles are wrong by many σ. The overlaps can nevertheless tell: freed, such a parameter takes a
value far beyond its σ and moves the angles.

After the adjustment converged, on the SAME final rows, robust weights and trajectory model, each
candidate (:data:`CANDIDATES`: a sensor parameter the scanner model has, not estimated, not a datum
defect of the overlaps such as ``lever_arm_z``) is freed on its own, by one linear solve
(a Gauss–Newton step of the full model from the restricted optimum; the model is linear in these
parameters over such steps). With N the restricted normal matrix (priors included), j the freed
parameter's Jacobian column, W the final weights, r the residuals and g the restricted gradient:

    n = JᵀWj,  m = jᵀWj,  b = N⁻¹n,  S = m − nᵀb   (the Schur complement: the freed parameter's
                                                     information left after the others)
    φ̂ = −(jᵀWr − bᵀg) / S,   Δθ = −b·φ̂        (the freed value; the shift of the estimated ones)

var(φ̂) = f/S with f the restricted solution's variance factor (Wald test z = φ̂/σ(φ̂)), raised to
the cluster-robust (sandwich) variance over the same trajectory segments as the solution's σ
(Liang & Zeger 1986; the dyadic form of Cameron & Miller 2014) where that is larger. The shift's
covariance is Hausman's (1978) difference of the two covariances on the shared parameters,
cov(Δθ) = C_full − C_restricted = f·b·bᵀ/S (block inversion of the full normal matrix), in which
each shift's z equals the freed parameter's Wald z: with one parameter freed, the two tests are
one. What the verdict weighs besides z is how far the shift moves each angle in units of the
angle's own σ (:mod:`calidar.strips.model_check_verdict`).

A candidate whose column the others (with their priors) already explain (S ≤ :data:`SINGULAR`·m)
is reported as not separable; one that IS an estimated parameter (:data:`ALIASES`: a linear
scanner's scan-angle offset is the boresight roll) is not freed. The freed value's σ is the
cluster-robust one on the full model's residuals (r moved linearly by the full step): the σ the
calibration would state with the parameter estimated.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Mapping, Sequence

import numpy as np
import scipy.linalg as sl

from calidar.adjust import Parameter
from calidar.adjust.solution import determined
from calidar.memory import release_memory

#: structural parameters the check frees, one at a time, when the scanner model has them and they
#: are not estimated. Not candidates: the lever arm's height and a common height bias (datum defects
#: of the overlaps), and the range scale — at one flying height nearly a common height shift, known
#: through the trajectory's priors rather than the overlaps (1.4 % of its information left after the
#: others on a UAV survey); freed, it moved no angle by more than 0.2 of its σ, and its z was
#: over-dispersed on clean surveys (RMS 1.4 over 30: docs/validation.md, "Model check")
CANDIDATES = ("range_offset", "scan_angle_scale", "scan_angle_offset", "lever_arm_x", "lever_arm_y")
#: the freed column is not separable when its information left after the estimated parameters is
#: below this fraction of its own (its multiple correlation with them R² > 1 − SINGULAR)
SINGULAR = 1e-6
UNITS = {"range_offset": "m", "scan_angle_scale": "1", "scan_angle_offset": "rad",
         "lever_arm_x": "m", "lever_arm_y": "m"}


#: a candidate that IS an estimated parameter, not computed: the linear scanner's scan-angle offset
#: turns every beam about the scanner's x axis, u(θ + δ) = Rx(−δ)·u(θ), so R_bs·u(θ + δ) is the
#: boresight with roll − δ (Rz(yaw)·Ry(pitch)·Rx(roll − δ)): the boresight roll itself
ALIASES = {"scan_angle_offset": "boresight_roll"}


def candidates(nominal_parameters: Mapping[str, float], free: Sequence[str]) -> list[str]:
    """The :data:`CANDIDATES` this sensor has, the calibration did not estimate and no estimated
    parameter is (:data:`ALIASES`)."""
    return [c for c in CANDIDATES if c in nominal_parameters and c not in free
            and ALIASES.get(c) not in free]


class Groups:
    """A grouping of the observations for cluster-robust variances, indexed once: (n,) one group
    each, or (n, 2) two groups (dyadic: observations correlated when they share either)."""

    def __init__(self, grouping: np.ndarray):
        c = np.asarray(grouping).reshape(len(grouping), -1)
        nodes, g = np.unique(c, return_inverse=True)
        self.g, self.G = g.reshape(c.shape), nodes.size
        self.dyads = None
        if c.shape[1] == 2:  # each pair of groups, in either order, one dyad
            pairs = np.sort(self.g, axis=1)
            self.dyads = np.unique(pairs, axis=0, return_inverse=True)[1].ravel()

    def variance(self, e: np.ndarray) -> float:
        """Cluster-robust variance of Σᵢ eᵢ (eᵢ: one observation's part of a linear statistic):
        Σ_g S_g² (dyadic: − Σ_dyads S_d², counted twice) · G/(G − 1), the scalar case of
        :func:`calidar.adjust.solver.solve`'s sandwich (Cameron & Miller 2014)."""
        if self.G < 2:
            return 0.0
        sums = sum(np.bincount(self.g[:, k], weights=e, minlength=self.G)
                   for k in range(self.g.shape[1]))
        total = float(np.sum(sums ** 2))
        if self.dyads is not None:
            total -= float(np.sum(np.bincount(self.dyads, weights=e) ** 2))
        return max(total, 0.0) * self.G / (self.G - 1)


class FreedFit:
    """The restricted adjustment's normal equations at its optimum, factored once, and the freed
    fit of any extra column (:meth:`free`). J (n × p, dense or sparse), w (n,) the final weights
    (× 1/σ²), r (n,) residuals, N (p × p) the normal matrix with priors, g (p,) the gradient with
    priors, factor the solution's variance factor, groupings the cluster groupings (may be
    empty)."""

    def __init__(self, J, w: np.ndarray, r: np.ndarray, N: np.ndarray, g: np.ndarray, factor: float,
                 groupings: Sequence[np.ndarray] = ()):
        self.J, self.g, self.factor = J, g, factor
        self.w, self.r = np.asarray(w, float), np.asarray(r, float)
        self.groups = [Groups(grouping) for grouping in groupings]
        if not determined(N):  # a direction the strips do not determine: nothing to test
            raise np.linalg.LinAlgError("singular normal matrix")
        self.cho = sl.cho_factor(N, lower=True)
        # the restricted model's own remaining step (≈ 0 at its optimum)
        self.rest = -sl.cho_solve(self.cho, g)

    def free(self, j: np.ndarray) -> dict:
        """The freed parameter of Jacobian column ``j`` (n,): its value φ̂, σ (model,
        cluster-robust, used), z, the shifts Δθ of the estimated parameters with their σ
        (:func:`hausman`), and the Schur complement's share of its information (1: independent of
        the others, 0: singular).

        The cluster-robust σ takes the full model's residuals (r moved by the full step, linear):
        the σ the calibration would state with the parameter estimated (a Wald test)."""
        wj = self.w * j
        n = np.asarray(self.J.T @ wj).ravel()
        m = float(j @ wj)
        b = sl.cho_solve(self.cho, n)
        S = m - float(n @ b)
        share = S / m if m > 0 else 0.0
        if not share > SINGULAR:
            return {"separable": False, "information_share": share}
        phi = -(float(wj @ self.r) - float(b @ self.g)) / S
        var_model = self.factor / S
        r_full = self.r + np.asarray(self.J @ (self.rest - b * phi)).ravel() + j * phi
        e = (j - np.asarray(self.J @ b).ravel()) * self.w * r_full / S  # each row's part of φ̂
        var_cluster = max((groups.variance(e) for groups in self.groups), default=0.0)
        sigma = float(np.sqrt(max(var_model, var_cluster)))
        return {"separable": True, "information_share": share, "value": phi, "sigma": sigma,
                "sigma_model": float(np.sqrt(var_model)),
                "sigma_cluster": float(np.sqrt(var_cluster)), "z": phi / sigma, "shift": -b * phi,
                "shift_sigma": np.abs(b) * sigma, "b": b}  # σ(Δθ)ᵢ = √hausman()ᵢᵢ


def hausman(b: np.ndarray, sigma_phi: float) -> np.ndarray:
    """cov(Δθ) = C_full − C_restricted on the shared parameters for one freed parameter: b·bᵀ·σ(φ̂)²
    (b = N⁻¹n: by block inversion the full normal matrix's inverse on θ is N⁻¹ + b·bᵀ/S;
    Hausman 1978)."""
    return np.outer(b, b) * sigma_phi ** 2


def columns(problem_for, values: Mapping[str, float], names: Sequence[str],
            scanner: Sequence[str]) -> dict:
    """∂residuals/∂(each of ``names``) at ``values``, from a problem on the same rows in which they
    are free (``problem_for(names)`` builds one): analytic for range and lever arm (one problem for
    all of them), central differences for the ``scanner``'s angle parameters (which re-georeference
    every referenced point)."""
    out = {}
    analytic = [n for n in names if n not in scanner]
    if analytic:
        J = problem_for(analytic).jacobian(values,
                                           [Parameter(n, values[n], UNITS[n]) for n in analytic])
        out.update(zip(analytic, np.asarray(J, float).T))
    release_memory()  # the analytic problem's working arrays, freed in the threads' own arenas
    angles = [n for n in names if n in scanner]
    problem = problem_for(angles) if angles else None
    for n in angles:
        h = Parameter(n, values[n], UNITS[n]).diff_step
        up, down = problem({**values, n: values[n] + h}), problem({**values, n: values[n] - h})
        out[n] = (np.asarray(up, float) - np.asarray(down, float)) / (2.0 * h)
    return out


def check(est, problem_for, nominal_parameters: Mapping[str, float], scanner: Sequence[str],
          groupings: Sequence[np.ndarray], shown: Sequence[str],
          restricted_sigma: Mapping[str, float]) -> dict:
    """The model check of a converged :class:`calidar.adjust.solver.Estimate`: every candidate
    freed in turn (:class:`FreedFit`). ``problem_for(names)``: the strip problem on the same rows
    with ``names`` free too (see :func:`columns`); ``scanner``: the scanner model's parameter names;
    ``groupings``: the solution's cluster groupings; ``shown``: the estimated parameters whose
    shifts are reported (not the trajectory corrections); ``restricted_sigma``: their σ in the
    calibration (SI). Returns per candidate its freed value, σ, z and the shifts in the units
    solution.json shows (deg, m, ppm), the wall and CPU seconds it took and their parts."""
    with _one_blas_thread():
        return _check(est, problem_for, nominal_parameters, scanner, groupings, shown,
                      restricted_sigma)


def _one_blas_thread():
    """LAPACK on one thread, as the solver's: its Cholesky of ~1 300 parameters takes 0.04 s on one
    thread and 10× that on two of a busy machine (calidar.adjust.solver)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency of scikit-learn
        return contextlib.nullcontext()
    return threadpool_limits(1, user_api="blas")


def _check(est, problem_for, nominal_parameters, scanner, groupings, shown,
           restricted_sigma) -> dict:
    clock, cpu = time.perf_counter(), time.process_time()
    fit, x, r, w = est.fit, est.x, est.r, est.w
    free = fit.params.free_names
    J, N = est.normals  # the solution's (computed once)
    g = fit.gradient(J, w, r, x)
    try:
        freed = FreedFit(J, w, r, N, g, fit.variance_factor(r, w, x), groupings)
    except (np.linalg.LinAlgError, ValueError):
        # a direction the data do not determine: nothing to test against
        return {"candidates": {}, "seconds": time.perf_counter() - clock,
                "cpu_seconds": time.process_time() - cpu,
                "not_run": "the adjustment's normal matrix is singular (a parameter the strips do "
                           "not determine)"}
    values = fit.params.values_with(x)
    index = [free.index(s) for s in shown]
    out = {}
    names = candidates(nominal_parameters, free)
    # CPU: on a shared machine the wall time waits
    parts = {"normal_matrix_cpu_s": time.process_time() - cpu}
    cols = columns(problem_for, values, names, scanner)
    parts["columns_cpu_s"] = time.process_time() - cpu - parts["normal_matrix_cpu_s"]
    for name in (c for c in CANDIDATES if c in nominal_parameters and c not in free
                 and c not in names):
        out[name] = {"separable": False, "information_share": 0.0,
                     "unit": Parameter(name, 0.0, UNITS[name]).display_unit,
                     "same_as": ALIASES[name]}
    for name in names:
        usable = np.all(np.isfinite(cols[name]))
        f = freed.free(cols[name]) if usable else {"separable": False, "information_share": 0.0}
        out[name] = _display(f, Parameter(name, 0.0, UNITS[name]),
                             {s: fit.params[s] for s in shown}, index,
                             restricted_sigma)
    used = time.process_time() - cpu
    parts["solves_cpu_s"] = used - parts["normal_matrix_cpu_s"] - parts["columns_cpu_s"]
    out = {name: out[name] for name in CANDIDATES if name in out}  # in the candidates' order
    return {"candidates": out, "seconds": time.perf_counter() - clock, "cpu_seconds": used,
            "parts": parts}


def _display(f: dict, p: Parameter, shown: Mapping[str, Parameter], index: Sequence[int],
             restricted_sigma: Mapping[str, float]) -> dict:
    """One freed fit (:meth:`FreedFit.free`) in display units, the shifts by estimated parameter."""
    out = {"separable": f["separable"], "information_share": f["information_share"],
           "unit": p.display_unit}
    if not f["separable"]:
        return out
    out.update({k: p.to_display(f[k]) for k in ("value", "sigma", "sigma_model", "sigma_cluster")},
               z=f["z"])
    out["shifts"] = {}
    for (name, q), i in zip(shown.items(), index):
        own = restricted_sigma[name]
        out["shifts"][name] = {"shift": q.to_display(f["shift"][i]),
                               "sigma": q.to_display(f["shift_sigma"][i]),
                               "own_sigma": q.to_display(own), "unit": q.display_unit,
                               "in_own_sigma": float(f["shift"][i] / own) if own > 0
                               else float("inf")}
    return out
