"""Trajectory errors as nuisance parameters of the strip adjustment.

A GNSS/INS trajectory is wrong by a few centimetres and a few thousandths of a degree, and
the error wanders slowly (GNSS over tens of seconds). In the overlaps this looks much like a
mounting error, strip by strip. Modelled as corrections per strip — a shift (east, north,
up) and a small rotation about the local axes acting about the IMU position — given at knots
every ``block_s`` seconds and linear in time between them (a linear spline; the rigorous
strip adjustment of Glira, Pfeifer & Mandlburger 2016 corrects the trajectory with
time-dependent functions), with a-priori σ equal to the trajectory's stated accuracy: the
adjustment then separates what it can and the σ of the mounting include what it cannot.
Linear, not piecewise constant: a smooth error differs from its block mean by ≈ slope ×
block / √12 but from its chord by ≈ curvature × block² / 11, and the leftover reaches every
row of a block alike (measured on the airborne Monte-Carlo: the data's share of the angles'
error was 1.2–1.5× its σ with constant 1 s blocks, 0.9–1.2× with knots).

Knots are correlated as a Gauss–Markov process of correlation time ``correlation_s`` (a GNSS
error wanders for tens of seconds), handed to the engine as ``prior_correlation`` (independent
knots would let a strip's mean error shrink as 1/√knots and make the σ of the mounting too
small): first order (:data:`SHAPES` "gm1", the default) ρ(Δt) = exp(−|Δt|/T), or second order
("gm2") ρ = (1 + |Δt|/τ)·exp(−|Δt|/τ), τ = T/2, the smooth error of an integrated or smoothed
process without GM1's cusp at lag 0 (Gelb 1974, "Applied Optimal Estimation", ch. 3; Maybeck
1979, "Stochastic Models, Estimation, and Control" vol. 1, ch. 4). T = ``correlation_s`` is the
integral time ∫₀^∞ ρ for either shape: both hold the same power at zero frequency, S(0) = 2σ²T,
what the mean of a long stretch sees (gm2, measured on the simulator, states pitch and yaw σ
narrower than the errors: not the default; docs/validation.md, issue 26, thirteenth session). The
shifts are one process over the whole flight, correlated across lines by their time apart
(independent lines made the flight's mean height error, which only ground control observes, 10 %
more certain than it is; issue 28). Each row of the Jacobian then touches two knots per strip: it
is built sparse.

Without a prior (``position_sigma_m`` None) the whole-strip shifts are free and the first
strip is the datum: a strip-wise GNSS offset of unknown size.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numba import njit

from calidar.adjust import Parameter
from calidar import frames
from calidar.errors import InputError
from calidar.trajectory import Trajectory
from calidar.trajectory_accuracy import TrajectoryAccuracy, tilt_sigma

AXES = ("east", "north", "up")
#: the part of the shifts' prior variance that is each strip's own, not shared with the other lines
#: (:meth:`TrajectoryModel.flight_correlation`: keeps two strips flown at one time apart)
OWN_STRIP_SHARE = 0.05
#: every trajectory-correction parameter's name starts so (nuisance parameters)
PREFIX = "trajectory_"
#: the knots' correlation shapes: Gauss–Markov of first or second order (the module docstring)
SHAPES = ("gm1", "gm2")


def gauss_markov(dt: np.ndarray, integral_s: float | None, shape: str = "gm1") -> np.ndarray:
    """Correlation ρ at lags ``dt`` (s) of a Gauss–Markov process of integral time ``integral_s``
    (∫₀^∞ ρ, s; None: independent, ρ = [dt == 0]) and ``shape`` (:data:`SHAPES`)."""
    u = np.abs(np.asarray(dt, float))
    if integral_s is None:
        return (u == 0.0).astype(float)
    if shape == "gm1":
        return np.exp(-u / integral_s)
    if shape == "gm2":
        v = 2.0 * u / integral_s  # τ = T / 2
        return (1.0 + v) * np.exp(-v)
    raise InputError(None, "trajectory shape",
                     f"expected one of {', '.join(SHAPES)}, got {shape!r}")


class Knot(NamedTuple):
    """The block a trajectory parameter belongs to: a shift ("bias") or a rotation ("tilt") about
    one axis (0..2: east, north, up) of one strip at one knot."""

    kind: str
    axis: int
    strip: int
    knot: int


def _n_knots(block_s: float | None, t_min: float, t_max: float) -> int:
    return 1 if block_s is None else max(1, math.ceil((t_max - t_min) / block_s)) + 1


@lru_cache(maxsize=64)
def _layout(block_s: float | None, priors: bool, attitude: bool,
            spans: tuple[tuple[int, tuple[float, float]], ...]) -> dict[str, Knot]:
    """:meth:`TrajectoryModel.layout` for the model's knots and the strips' spans (sorted by id)."""
    ids = [i for i, _ in spans]
    if not priors:  # free whole-strip shifts, the first strip the datum
        return {f"{PREFIX}bias_{ax}_{i}": Knot("bias", a, i, 0)
                for i in ids[1:] for a, ax in enumerate(AXES)}
    out = {}
    for i, span in spans:
        for k in range(_n_knots(block_s, *span)):
            suffix = f"{i}" if block_s is None else f"{i}_{k}"
            for kind in ("bias", "tilt") if attitude else ("bias",):
                out.update({f"{PREFIX}{kind}_{ax}_{suffix}": Knot(kind, a, i, k)
                            for a, ax in enumerate(AXES)})
    return out


@dataclass(frozen=True)
class TrajectoryModel:
    """How trajectory errors enter the adjustment (see the module docstring)."""

    #: spacing of the knots (s); None: one constant correction per strip
    block_s: float | None = None
    #: prior σ of each knot's shift; None: free, first strip fixed
    position_sigma_m: float | None = None
    attitude_sigma_rad: float | None = None  #: prior σ of each knot's rotation; None: no rotations
    #: Gauss–Markov correlation time of the shifts (s); None: independent
    correlation_s: float | None = None
    attitude_correlation_s: float | None = None  #: the same for the rotations
    #: the trajectory's σ per epoch: the priors of every knot, per axis (the two σ above then
    #: unused)
    accuracy: TrajectoryAccuracy | None = None
    #: the priors' level to be estimated from the overlaps (no accuracy file: :attr:`accuracy` is a
    #: default to start from; :mod:`calidar.strips.trajectory_level`)
    estimate_level: bool = False
    #: the correlation's shape of the shifts and of the rotations (:data:`SHAPES`)
    shape: tuple[str, str] = ("gm1", "gm1")

    def __post_init__(self):
        for name in ("block_s", "position_sigma_m", "attitude_sigma_rad", "correlation_s",
                     "attitude_correlation_s"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise InputError(None, name, f"expected a number > 0, got {v}")
        for v in self.shape:
            gauss_markov(0.0, 1.0, v)  # an unknown shape: its error
        knots_or_attitude = self.block_s is not None or self.attitude_sigma_rad is not None
        if not self.has_priors and knots_or_attitude:
            raise InputError(None, "trajectory sigma", "knots and attitude corrections need the "
                             "trajectory's a-priori position σ (e.g. --trajectory-sigma "
                             "0.03,0.002)")

    @property
    def has_priors(self) -> bool:
        """Whether the corrections have priors (else: free whole-strip shifts, the first strip the
        datum)."""
        return self.position_sigma_m is not None or self.accuracy is not None

    @property
    def has_attitude(self) -> bool:
        """Whether the corrections include rotations."""
        return self.attitude_sigma_rad is not None or self.accuracy is not None

    def knot_sigma(self, span: tuple[float, float],
                   heading_rad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Prior σ of a strip's knots, (n, 3) shift east/north/up (m) and (n, 3) rotation about
        east/north/up (rad): from :attr:`accuracy` at the knots' times (the rotation about up gets
        heading's σ, the horizontal ones roll's and pitch's as the line's heading mixes them), else
        the model's two constants."""
        n = self.n_knots(*span)
        if self.accuracy is None:
            att = np.nan if self.attitude_sigma_rad is None else self.attitude_sigma_rad
            return np.full((n, 3), self.position_sigma_m), np.full((n, 3), att)
        pos, att = self.accuracy.at(span[0] + np.arange(n) * (self.block_s or 0.0))
        return pos[:, [1, 0, 2]], tilt_sigma(att, heading_rad)

    def n_knots(self, t_min: float, t_max: float) -> int:
        """Knots of a strip spanning [t_min, t_max] s: t_min, t_min + block_s, … up to ≥ t_max."""
        return _n_knots(self.block_s, t_min, t_max)

    def layout(self, spans: Mapping[int, tuple[float, float]]) -> dict[str, Knot]:
        """Every trajectory parameter of strips with time spans {id: (t_min, t_max)} s, by the name
        :meth:`parameters` gives it → its :class:`Knot` (shared: not to be changed)."""
        sorted_spans = tuple(sorted(spans.items()))
        return _layout(self.block_s, self.has_priors, self.has_attitude, sorted_spans)

    def correlation(self, n: int, kind: str = "bias") -> np.ndarray:
        """Prior correlation (n, n) of a strip's n knots along one axis, for shifts (``kind``
        "bias") or rotations ("tilt"): :func:`gauss_markov` at lags (k − l)·block_s."""
        tau = self.correlation_s if kind == "bias" else self.attitude_correlation_s
        if self.block_s is None:
            return np.eye(n)
        k = np.arange(n) * self.block_s
        return gauss_markov(k[:, None] - k[None, :], tau, self.shape[kind != "bias"])

    def knot_times(self, spans: Mapping[int, tuple[float, float]]) -> dict[int, np.ndarray]:
        """Each strip's knot times (s): its start, then every ``block_s`` (one knot: its start)."""
        step = self.block_s or 0.0
        return {i: spans[i][0] + step * np.arange(self.n_knots(*spans[i])) for i in sorted(spans)}

    def flight_correlation(self, spans: Mapping[int, tuple[float, float]]) -> np.ndarray:
        """Prior correlation of the shifts' knots of every strip (sorted by id, then knot) along one
        axis: one Gauss–Markov process in time over the whole flight, :func:`gauss_markov` (a
        GNSS error does not restart with each line: consecutive lines share it, and their mean, a
        vertical bias only ground control sees, is as uncertain as one process makes it), with
        :data:`OWN_STRIP_SHARE` of it each strip's own (knots of two strips at one time: not
        singular)."""
        times = self.knot_times(spans)
        t = np.concatenate(list(times.values()))
        strip = np.repeat(np.arange(len(times)), [v.size for v in times.values()])
        tau = self.correlation_s
        if self.block_s is None or tau is None:
            return np.eye(t.size)
        R = gauss_markov(t[:, None] - t[None, :], tau, self.shape[0])
        return np.where(strip[:, None] == strip[None, :], R, (1.0 - OWN_STRIP_SHARE) * R)

    def prior_correlation(self, spans: Mapping[int, tuple[float, float]]
                          ) -> list[tuple[list[str], np.ndarray]]:
        """The engine's ``prior_correlation`` groups: the shifts per axis over every strip's knots
        (:meth:`flight_correlation`), the rotations per strip and axis (about local axes that the
        lines' headings turn: not one process across lines; their 3.5 s outlives no turn)."""
        if self.block_s is None or not self.has_priors:
            return []
        out = []
        R = self.flight_correlation(spans)
        if np.any(R != np.eye(len(R))):
            knots = [(i, k) for i, t in self.knot_times(spans).items() for k in range(t.size)]
            out += [([f"trajectory_bias_{ax}_{i}_{k}" for i, k in knots], R) for ax in AXES]
        for i in sorted(spans) if self.has_attitude else ():
            n = self.n_knots(*spans[i])
            R = self.correlation(n, "tilt")
            if np.any(R != np.eye(n)):
                out += [([f"trajectory_tilt_{ax}_{i}_{k}" for k in range(n)], R) for ax in AXES]
        return out

    def parameters(self, spans: Mapping[int, tuple[float, float]],
                   headings: Mapping[int, float] | None = None) -> list[Parameter]:
        """Parameters for strips with time spans {id: (t_min, t_max)} s (``headings``: each
        strip's direction of flight, rad from north, for per-axis attitude priors)."""
        out = []
        ids = sorted(spans)
        if not self.has_priors:  # free whole-strip shifts, the first strip the datum
            return [Parameter(f"trajectory_bias_{ax}_{i}", 0.0, "m")
                    for i in ids[1:] for ax in AXES]
        for i in ids:
            shift, tilt = self.knot_sigma(spans[i], (headings or {}).get(i, 0.0))
            for k in range(shift.shape[0]):
                suffix = f"{i}" if self.block_s is None else f"{i}_{k}"
                out += [Parameter(f"trajectory_bias_{ax}_{suffix}", 0.0, "m", float(shift[k, a]))
                        for a, ax in enumerate(AXES)]
                if self.has_attitude:
                    out += [Parameter(f"trajectory_tilt_{ax}_{suffix}", 0.0, "rad",
                                      float(tilt[k, a])) for a, ax in enumerate(AXES)]
        return out


@dataclass(frozen=True)
class StripCorrection:
    """One strip's corrections: per knot a shift (m) and a rotation vector (rad), local ENU,
    linear in time between knots (constant before the first and after the last)."""

    t0: float  #: time of knot 0 (s)
    block_s: float | None  #: knot spacing (s); None: one knot, a constant correction
    shift: np.ndarray  #: (n_knots, 3) m
    tilt: np.ndarray  #: (n_knots, 3) rad

    def knots(self, time: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each time (s): the knots k, k + 1 around it and the weight f of k + 1 (the
        correction is (1 − f)·value[k] + f·value[k + 1])."""
        n = self.shift.shape[0]
        time = np.asarray(time, float)
        if self.block_s is None or n == 1:
            k = np.zeros(time.shape, dtype=np.int64)
            return k, k, np.zeros(time.shape)
        u = np.clip((time - self.t0) / self.block_s, 0.0, n - 1.0)
        k = np.minimum(np.floor(u).astype(np.int64), n - 2)
        return k, k + 1, u - k

    def apply(self, points: np.ndarray, origin: np.ndarray, time: np.ndarray, weight=1.0,
              knots: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Corrected ``points`` (M, 3) m: + shift + tilt × (points − origin), at each point's time
        (s).

        For averages of points (rows of a correspondence matrix) pass the row sums of the
        weights as ``weight``, the weighted sums as points and origin and the rows' mean times;
        ``knots``: ``self.knots(time)`` when already known (the same times corrected again)."""
        points = np.asarray(points, float)
        m = points.shape[0]
        if knots is None:
            knots = self.knots(np.broadcast_to(np.asarray(time, float), (m,)))
        k0, k1, f = knots
        origin = np.broadcast_to(np.asarray(origin, float), (m, 3))
        weight = np.broadcast_to(np.asarray(weight, float), (m,))
        return _apply_kernel(points, origin, weight, k0, k1, f, self.shift, self.tilt)


@njit(cache=True)
def _apply_kernel(points, origin, weight, k0, k1, f, shift, tilt):  # pragma: no cover - numba
    """StripCorrection.apply in one pass, the knots k0, k1 and weight f of each point given."""
    out = np.empty_like(points)
    s, w, d = np.empty(3), np.empty(3), np.empty(3)
    for i in range(points.shape[0]):
        a, b, g = k0[i], k1[i], f[i]
        for ax in range(3):
            s[ax] = (1.0 - g) * shift[a, ax] + g * shift[b, ax]
            w[ax] = (1.0 - g) * tilt[a, ax] + g * tilt[b, ax]
            d[ax] = points[i, ax] - origin[i, ax]
        out[i, 0] = points[i, 0] + weight[i] * s[0] + w[1] * d[2] - w[2] * d[1]
        out[i, 1] = points[i, 1] + weight[i] * s[1] + w[2] * d[0] - w[0] * d[2]
        out[i, 2] = points[i, 2] + weight[i] * s[2] + w[0] * d[1] - w[1] * d[0]
    return out


def corrections(values: Mapping[str, float], model: TrajectoryModel | None,
                spans: Mapping[int, tuple[float, float]]) -> dict[int, StripCorrection]:
    """The strips' corrections from parameter values (SI) named as
    :meth:`TrajectoryModel.parameters`."""
    if model is None:
        return {}
    out: dict[int, StripCorrection] = {}
    layout = model.layout(spans)
    for name, v in values.items():
        knot = layout.get(name)
        if knot is None:
            continue
        kind, ax, sid, k = knot
        if sid not in out:
            n = model.n_knots(*spans[sid])
            out[sid] = StripCorrection(spans[sid][0], model.block_s, np.zeros((n, 3)),
                                       np.zeros((n, 3)))
        (out[sid].shift if kind == "bias" else out[sid].tilt)[k, ax] = v
    return out


def knot_scatter(keys, model: TrajectoryModel,
                 spans: Mapping[int, tuple[float, float]]) -> dict[int, tuple]:
    """How a typed block of :class:`Knot` keys fills the strips' corrections, worked out once: per
    strip its knot count and, for shifts and rotations, (positions in the block, knot, axis)."""
    plan: dict[int, list] = {}
    for pos, (kind, ax, sid, k) in enumerate(keys):
        plan.setdefault(sid, [[], []])[kind != "bias"].append((pos, k, ax))
    return {sid: (model.n_knots(*spans[sid]),
                  *(np.array(part, dtype=np.intp).reshape(-1, 3).T for part in parts))
            for sid, parts in plan.items()}


def corrections_of(values: np.ndarray, scatter: Mapping[int, tuple], model: TrajectoryModel,
                   spans: Mapping[int, tuple[float, float]]) -> dict[int, StripCorrection]:
    """:func:`corrections` from a block's value vector and its :func:`knot_scatter` plan."""
    out = {}
    for sid, (n, bias, tilt) in scatter.items():
        shift, rot = np.zeros((n, 3)), np.zeros((n, 3))
        shift[bias[1], bias[2]] = values[bias[0]]
        rot[tilt[1], tilt[2]] = values[tilt[0]]
        out[sid] = StripCorrection(spans[sid][0], model.block_s, shift, rot)
    return out


def corrected_trajectory(traj: Trajectory, fixes: Mapping[int, StripCorrection],
                         spans: Mapping[int, tuple[float, float]], frame) -> Trajectory:
    """``traj`` with each strip's estimated corrections applied to its records: position + shift,
    attitude turned by the rotation vector (both local ENU of ``frame``, a
    :class:`calidar.strips.strip.LocalFrame`), at each record's time. The records of a strip are
    those bracketing its time span {id: (t0, t1)} s (so that interpolating the trajectory at any of
    its points uses corrected records only); other records are unchanged. Georeferencing with the
    result moves a point as the adjustment's correction does (to second order in the rotation)."""
    t = traj.time
    ecef = traj.ecef.copy()
    r_nb = frames.rpy_to_matrix(traj.roll, traj.pitch, traj.heading)
    r_eb = frames.r_en(traj.lat, traj.lon) @ r_nb
    touched = np.zeros(t.size, bool)
    for sid, fix in fixes.items():
        lo = max(int(np.searchsorted(t, spans[sid][0], side="right")) - 1, 0)
        hi = min(int(np.searchsorted(t, spans[sid][1], side="left")), t.size - 1)
        idx = np.arange(lo, hi + 1)
        k0, k1, f = fix.knots(t[idx])
        shift = (1.0 - f)[:, None] * fix.shift[k0] + f[:, None] * fix.shift[k1]
        tilt = (1.0 - f)[:, None] * fix.tilt[k0] + f[:, None] * fix.tilt[k1]
        ecef[idx] += shift @ frame.r_le
        turn = frame.r_le.T @ rotation_matrices(tilt) @ frame.r_le  # local → ECEF
        r_eb[idx] = turn @ r_eb[idx]
        touched[idx] = True
    lat, lon, h = frames.ecef_to_geodetic(ecef)
    lat, lon = np.where(touched, lat, traj.lat), np.where(touched, lon, traj.lon)
    h = np.where(touched, h, traj.height)
    roll, pitch, heading = frames.matrix_to_rpy(np.swapaxes(frames.r_en(lat, lon), -1, -2) @ r_eb)
    roll, pitch = np.where(touched, roll, traj.roll), np.where(touched, pitch, traj.pitch)
    heading = np.where(touched, heading, traj.heading)
    return Trajectory(t, lat, lon, h, roll, pitch, heading, traj.velocity_ned, traj.time_system,
                      f"{traj.source} (corrected)", dict(traj.extra))


def rotation_matrices(w: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of rotation vectors w (n, 3) rad (Rodrigues: the rotation by
    |w| about w/|w|; to first order v → v + w × v, as :meth:`StripCorrection.apply`)."""
    w = np.asarray(w, float)
    theta = np.linalg.norm(w, axis=1)
    K = np.zeros((w.shape[0], 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K -= np.swapaxes(K, 1, 2)
    small = theta < 1e-8
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(theta) / np.where(small, 1.0, theta))
    b = np.where(small, 0.5 - theta**2 / 24.0,
                 (1.0 - np.cos(theta)) / np.where(small, 1.0, theta) ** 2)
    return np.eye(3) + a[:, None, None] * K + b[:, None, None] * (K @ K)
