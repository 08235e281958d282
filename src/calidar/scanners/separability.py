"""Which structural errors of a scanner can be told apart from the boresight, and why.

Points of one scan (revolution or FOV) at range R in the body frame, p(β) = R · R_bs · u(β; θ),
depend on θ = (boresight roll, pitch, yaw, structural components). Each error enters through its
linearised components (:meth:`calidar.scanners.sources.ErrorSource.parts`: the eccentricity as
ε/r·cos C and ε/r·sin C, because e·sin(β − C) = e cos C · sin β − e sin C · cos β and C is
undefined at ε = 0; a wedge axis tilt as its x and y parts). From the Jacobian J = ∂p/∂θ:

* ``correlation``: the correlation matrix of the least-squares estimate (JᵀJ)⁺ — the best case,
  every point position known (control);
* ``unexplained``: for each component (and each error at its analysed phase), the fraction
  ‖J_k − J_b a‖ / ‖J_k‖ of its point signature that no boresight rotation a can reproduce
  (0: indistinguishable; 1: orthogonal);
* ``mimic``: the boresight rotation (rad per rad or per unit ratio) that best imitates it.

Palmer, A = 45°, B = 7.5°: δ_L acts as a boresight pitch of −2 δ_L (the laser-fixed frame tilts
the mirror, doubled on reflection) plus a β-dependent residual of relative size ≈ sin 2B (6.6 %),
so δ_L and pitch correlate at 0.997; δ_R changes the size of the oval, which no rotation does
(unexplained 99.7 %); the eccentricity components move points along the oval by
(ε/r)·sin(β − C), which shifts the fore and aft ends sideways like a roll but not the sides
(ε sin C ↔ roll correlation ≈ −0.6), and have no constant part that a yaw could absorb.
Linear scanner: a scan-angle offset *is* a boresight roll (unexplained 0).
:func:`control_adjustment` runs the Palmer question through the adjustment engine with noisy
simulated control points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.adjust import FunctionProblem, Parameter, ParameterSet, SolverOptions, solve
from calidar.frames import rpy_to_matrix
from calidar.scanners import PalmerScanner, Scanner
from calidar.scanners.sources import ErrorSource, error_sources

BORESIGHT = ("boresight_roll", "boresight_pitch", "boresight_yaw")
STRUCTURAL = ("eccentricity_cos", "eccentricity_sin", "delta_l", "delta_r")  #: Palmer's components
SEPARATION_SAMPLES = 360  #: angles over the pattern for the Jacobian


@dataclass(frozen=True)
class Separability:
    """Jacobian-based separability of structural components from the boresight (see the module
    docstring)."""

    names: tuple[str, ...]  #: BORESIGHT + the components
    jacobian: np.ndarray  #: (3N, 3 + k) m per rad (or per unit ratio)
    correlation: np.ndarray  #: (3 + k, 3 + k)
    #: component or error name → fraction of its signature no boresight reproduces
    unexplained: dict[str, float]
    #: component or error name → best-imitating boresight (roll, pitch, yaw)
    mimic: dict[str, np.ndarray]
    singular_values: np.ndarray  #: of the column-normalised Jacobian
    columns: dict[str, np.ndarray]  #: error name → its Jacobian column (3N,) at the analysed phase
    range_m: float
    angles: np.ndarray  #: (N,) the pattern's observations, rad

    def corr(self, a: str, b: str) -> float:
        return float(self.correlation[self.names.index(a), self.names.index(b)])

    def left_after_boresight(self, name: str, value_si: float) -> np.ndarray:
        """Displacements (N, 3) m an error of ``value_si`` leaves after the best boresight (first
        order)."""
        col = self.columns[name] - self.jacobian[:, :3] @ self.mimic[name]
        return (col * value_si).reshape(-1, 3)


def _points(scanner: Scanner, angles: np.ndarray, range_m: float, rpy=(0.0, 0.0, 0.0),
            params=None) -> np.ndarray:
    """Body-frame points (3N,) m of the pattern with a boresight ``rpy`` (rad) and scanner
    ``params`` (SI)."""
    u = (scanner.with_parameters(**params) if params else scanner).directions(angles)
    return (range_m * u @ rpy_to_matrix(*rpy).T).ravel()


def _column(fn, step: float) -> np.ndarray:
    """The derivative of ``fn`` at 0 by central differences of ``step``."""
    return (fn(step) - fn(-step)) / (2.0 * step)


def _fit_boresight(jb: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, float]:
    """Best boresight a (3,) imitating ``col`` and the fraction of ``col`` it leaves."""
    a = np.linalg.lstsq(jb, col, rcond=None)[0]
    norm = np.linalg.norm(col)
    return a, float(np.linalg.norm(col - jb @ a) / norm) if norm > 0 else 0.0


def separability(scanner: Scanner, sources: list[ErrorSource], angles: np.ndarray,
                 range_m: float, step: float = 1e-7) -> Separability:
    """Separability from the boresight of every component of ``sources`` over the pattern
    ``angles``."""
    comps = [(name, fn) for src in sources for name, fn in src.parts()]

    def rotated(axis: np.ndarray):
        return lambda h: _points(scanner, angles, range_m, rpy=h * axis)

    def changed(fn):
        return lambda h: _points(scanner, angles, range_m, params=fn(h))

    cols = [_column(rotated(axis), step) for axis in np.eye(3)]
    cols += [_column(changed(fn), step) for _, fn in comps]
    j = np.stack(cols, axis=1)
    cov = np.linalg.pinv(j.T @ j)
    s = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    jb = j[:, :3]
    columns = {src.name: _column(changed(src.apply), step) for src in sources}
    unexplained, mimic = {}, {}
    for name, col in [(n, j[:, 3 + k]) for k, (n, _) in enumerate(comps)] + list(columns.items()):
        mimic[name], unexplained[name] = _fit_boresight(jb, col)
    sv = np.linalg.svd(j / np.maximum(np.linalg.norm(j, axis=0), 1e-300), compute_uv=False)
    correlation = np.clip(cov / np.outer(s, s), -1.0, 1.0)
    return Separability(BORESIGHT + tuple(n for n, _ in comps), j, correlation, unexplained, mimic,
                        sv, columns, float(range_m), np.asarray(angles, float))


def palmer_separability(scanner: PalmerScanner | None = None, range_m: float = 500.0,
                        n: int = SEPARATION_SAMPLES, step: float = 1e-7) -> Separability:
    """Separability of the Palmer structural parameters (:data:`STRUCTURAL`) from the boresight."""
    beta = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return separability(scanner or PalmerScanner(), error_sources("palmer"), beta, range_m, step)


#: the parameters :func:`control_adjustment` estimates by default: the boresight and every
#: Palmer structural parameter
CONTROL_FREE = BORESIGHT + ("eccentricity_ratio", "eccentricity_phase", "delta_l", "delta_r")


def control_adjustment(truth: dict[str, float], *, range_m: float = 500.0, n: int = 720,
                       noise_m: float = 0.02, seed: int = 0,
                       free: tuple[str, ...] = CONTROL_FREE):
    """Estimate boresight + Palmer parameters through the adjustment engine from noisy control
    points.

    Simulates one revolution at ``range_m`` with the ``truth`` (SI; keys from the boresight
    names and PalmerScanner parameters), adds N(0, noise_m²) to every coordinate, and solves
    starting from zero boresight, δ_L = δ_R = 0 and ε/r = 1e-4, C = 0 (C is undefined at
    ε = 0). Returns the :class:`calidar.adjust.Solution` (its correlation shows the δ_L–pitch
    degeneracy).
    """
    rng = np.random.default_rng(seed)
    beta = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    base = PalmerScanner()

    def points(v: dict[str, float]) -> np.ndarray:
        params = {k: v[k] for k in v if k in base.units}
        return _points(base, beta, range_m, rpy=[v[k] for k in BORESIGHT], params=params)

    full = {k: 0.0 for k in BORESIGHT} | base.parameters() | truth
    observed = points(full) + rng.normal(0.0, noise_m, 3 * n)
    start = {k: 0.0 for k in BORESIGHT} | base.parameters() | {"eccentricity_ratio": 1e-4}
    params = ParameterSet([Parameter(k, start[k], base.units.get(k, "rad"), free=k in free)
                           for k in start])
    def residuals(v: dict[str, float]) -> np.ndarray:
        return points(v) - observed

    return solve(FunctionProblem(residuals, params, sigma=noise_m), SolverOptions(robust=None))
