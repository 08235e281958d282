"""Ground control as observations of the strip adjustment (issue 28): the building block.

A control point (surveyed x, y, z with σ) observes a strip's local surface: the residual is the
height of the strip's quadratic surface around it above the control point, along the surface's
normal, r = n · (Σ wᵢ·pᵢ − c) (:func:`calidar.strips.control_surface.local_surface`: the weights w
read the quadric at the control point c; > 0 when the strip's surface lies above it, as ``calidar
accuracy``'s dz), with σ² = σ_control² + the quadric's noise there (a plane misses the ground's
curvature, an error shared by every strip at the point and absent from σ: docs/validation.md,
"Ground control in the strip adjustment"). The rows are
:class:`~calidar.strips.correspond.Correspondences` between the strip and a *control pseudo-strip*
(id :data:`CONTROL_ID`) whose :class:`Pose` (:func:`control_pose`) puts each "point" at its control
point with a zero rotation: the lidar equation then returns the control point itself whatever the
sensor, with no derivative and no trajectory correction (the pseudo-strip has no time span), so
:class:`~calidar.strips.problem.StripProblem` and its analytic Jacobian take control rows unchanged,
beside the tie planes. Range offset, vertical lever arm and vertical trajectory biases, which the
overlaps cannot see, are then observed (tests/unit/strips/test_control.py).

``calidar boresight --control FILE`` wires them in: the ingest keeps the overlap cells around
each control point (:func:`cells_near`), the calibrator keeps each strip's points near them
(:func:`near_control`) and adds :func:`control_correspondences` to every matching; the rows'
residuals before and after go to solution.json (:func:`control_rows`, :func:`control_summary`).
With control, ``--estimate ...,height_bias`` adds a height shift common to every strip (a vertical
trajectory bias; :data:`calidar.strips.problem.HEIGHT_BIAS`), which only the control rows observe
(:func:`check_estimate` refuses it without them); it is folded into every strip's trajectory
correction (:func:`with_height_bias`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from calidar.strips.control_surface import MIN_POINTS, local_surface
from calidar.strips.control_survey import per_target_design, per_target_parameters
from calidar.strips.correspond import Correspondences
from calidar.strips.problem import CONTROL_STRIP
from calidar.strips.strip import Pose

#: the id of the control pseudo-strip (-1; StripProblem leaves it out of height_bias)
CONTROL_ID = CONTROL_STRIP
RADIUS_M = 2.0  #: a strip's points within this (x, y) of a control point form its surface
#: points kept this much farther than RADIUS_M from a control point: the calibration moves them
#: (by cm), and the rows are formed anew from the re-georeferenced points each matching
MARGIN_M = 1.0


@dataclass(frozen=True)
class ControlPoints:
    """Control points in the strips' local frame (m). What the calibrator, the pipeline, the verdict
    and the report ask of ground control of any kind (:data:`calidar.strips.config.CONTROL_KINDS`;
    control planes: :class:`calidar.strips.control_planes.ControlPlanes`): ``ids``, ``local`` (the
    control pseudo-strip's points), ``sigma_m`` (each one's survey σ, shared by the strips that see
    it), :meth:`keep_xy`, :meth:`rows` (its rows and, through them, their Jacobian),
    :meth:`survey_parameters` and :meth:`survey_design` (its survey errors as nuisance parameters),
    and the class attributes below (its names and words, how its file is recognised and read). A new
    kind is one module with such a class, and its name in ``CONTROL_KINDS``."""

    kind: ClassVar[str] = "points"  #: its name (CONTROL_KINDS, solution.json's control.kind)
    label: ClassVar[str] = "control points"  #: what the report and solution.json call its targets
    #: what the verdict calls them ("… with 10 ground control points")
    words: ClassVar[str] = "ground control points"
    row_noun: ClassVar[str] = "control point"  #: one target, the report table's first column
    #: what a row's dz and σ are, in the report's ground-control section
    dz_meaning: ClassVar[str] = ("(dz: the strip's local surface minus the control point, "
                                 "vertically; σ: the point's survey σ and the surface's scatter)")
    #: its file, as the verdict's action names it
    how_to_give: ClassVar[str] = "points: id, x, y, z, sigma"
    #: targets no strip covers are expected (a cloud reaching beyond the strips), not a warning
    reaches_beyond_strips: ClassVar[bool] = False
    #: reading at the edge (pipelines/control.py): ``accepts(path)`` whether a --control file is of
    #: this kind (None: any file no other kind accepts), ``reader(path[, sigma_m])`` its io reader
    #: (None: the checkpoint CSV, read as --checkpoints are), ``takes_sigma`` whether
    #: --control-sigma goes with it
    accepts: ClassVar = None
    reader: ClassVar = None
    takes_sigma: ClassVar[bool] = False

    ids: np.ndarray  #: (n,) str
    local: np.ndarray  #: (n, 3) m
    sigma_m: np.ndarray  #: (n,) survey σ of each, m

    @classmethod
    def notes(cls, f, targets) -> tuple[str, ...]:
        """What the run's notes say of the file ``f`` read and its targets (none)."""
        return ()

    def keep_xy(self) -> np.ndarray:
        """(n, 2) the places the calibrator keeps the points around (``RADIUS_M + MARGIN_M``)."""
        return np.asarray(self.local, float)[:, :2]

    def rows(self, strip_id: int, index: np.ndarray, points: np.ndarray,
             n_strip_points: int) -> Correspondences | None:
        """:func:`control_correspondences` of a strip's points near control."""
        return control_correspondences(strip_id, index, points, n_strip_points, self)

    def survey_parameters(self) -> list:
        """Each point's survey error (its height) as a nuisance parameter
        (:mod:`calidar.strips.control_survey`)."""
        return per_target_parameters(self.sigma_m)

    def survey_design(self, k: np.ndarray, normals: np.ndarray, at: np.ndarray | None = None):
        """Rows of points ``k`` with ``normals``: a point's height error moves its row r = n·(p̄ −
        c) by −n_z per unit; the row's own σ holds its σ_c²
        (:func:`calidar.strips.control_survey.per_target_design`; ``at``, the rows' places,
        unused)."""
        return per_target_design(self.sigma_m, k, np.asarray(normals, float)[:, 2])


def control_pose(control: ControlPoints, template: Pose) -> Pose:
    """The control pseudo-strip's poses: position = the control point, rotation zero, so that
    p = r + R·(…) = r for every sensor (``template``: a real strip's poses, for the angles'
    shape)."""
    n = len(control.ids)
    angles = np.zeros((n, *template.angles.shape[1:]))
    return Pose(np.arange(n), np.asarray(control.local, float), np.zeros((n, 3, 3)), np.zeros(n),
                angles)


def control_correspondences(strip_id: int, index: np.ndarray, points: np.ndarray,
                            n_strip_points: int, control: ControlPoints, radius_m: float = RADIUS_M,
                            min_points: int = MIN_POINTS) -> Correspondences | None:
    """Rows between strip ``strip_id`` (its points ``index`` at local ``points`` (M, 3), of
    ``n_strip_points`` in all) and the control points it covers; None when it covers none."""
    from scipy.spatial import cKDTree  # here: runs without control points need no scipy.spatial

    tree = cKDTree(np.asarray(points)[:, :2])
    rows, cols, weights, normals, sigmas, targets = [], [], [], [], [], []
    for k, near in enumerate(tree.query_ball_point(control.local[:, :2], radius_m)):
        if len(near) < min_points:
            continue
        fit = local_surface(points[near], control.local[k])
        if fit is None:
            continue
        w, normal, var = fit
        r = len(normals)
        rows += [r] * len(near)
        cols += list(np.asarray(index)[near])
        weights += list(w)
        normals.append(normal)
        sigmas.append(np.sqrt(control.sigma_m[k] ** 2 + var * normal[2] ** 2))
        targets.append(k)
    return rows_to_correspondences(strip_id, (rows, cols, weights), normals, sigmas, targets,
                                   (n_strip_points, len(control.ids)), "control")


def rows_to_correspondences(strip_id: int, entries: tuple, normals: list, sigmas: list,
                            targets: list, shape: tuple[int, int],
                            label: str) -> Correspondences | None:
    """Control rows gathered as lists into :class:`Correspondences` against the control
    pseudo-strip: ``entries`` (row, strip point, weight) of each row's point average, one normal, σ
    (m) and control target per row, ``shape`` (the strip's points, the control targets); None when
    there is no row."""
    if not normals:
        return None
    rows, cols, weights = entries
    n = len(normals)
    A = sp.csr_matrix((weights, (rows, cols)), shape=(n, shape[0]))
    B = sp.csr_matrix((np.ones(n), (np.arange(n), targets)), shape=(n, shape[1]))
    return Correspondences(strip_id, CONTROL_ID, A, B, np.array(normals), np.array(sigmas), label)


def check_estimate(estimate, control) -> None:
    """An error when ``height_bias`` is to be estimated without control (``control`` None): the
    overlaps cannot see a height shift common to every strip, so nothing would bound it."""
    if "height_bias" in estimate and control is None:
        from calidar.errors import InputError

        raise InputError(None, "--estimate",
                         "height_bias (a height shift common to every strip) needs ground control: "
                         "the overlaps cannot see it; expected --control FILE with it, or "
                         "height_bias left out")


def with_height_bias(fix: dict, h: float, spans: dict) -> dict:
    """The strips' trajectory corrections
    (:class:`~calidar.strips.trajectory_errors.StripCorrection` by id) with the common
    ``height_bias`` ``h`` (m, up) added to every knot's shift (a constant correction for a strip
    that had none), so that sbet_corrected.out and the overlap quality carry it."""
    from dataclasses import replace

    from calidar.strips.trajectory_errors import StripCorrection

    if not h:
        return fix
    up = np.array([0.0, 0.0, h])
    out = {i: replace(c, shift=c.shift + up) for i, c in fix.items()}
    for i, (t0, _) in spans.items():
        out.setdefault(i, StripCorrection(t0, None, up[None].copy(), np.zeros((1, 3))))
    return out


def near_control(points: np.ndarray, control: ControlPoints,
                 reach_m: float = RADIUS_M + MARGIN_M) -> np.ndarray:
    """Sorted indices of the ``points`` (local (N, 3) m) within ``reach_m`` (x, y) of the control's
    places (:meth:`ControlPoints.keep_xy`: the points; over a control plane, its patch)."""
    if len(points) == 0:
        return np.zeros(0, np.int64)
    from scipy.spatial import cKDTree

    tree = cKDTree(np.asarray(points)[:, :2])
    hits = tree.query_ball_point(control.keep_xy(), reach_m)
    found = [np.asarray(h, np.int64) for h in hits if len(h)]
    return np.unique(np.concatenate(found)) if found else np.zeros(0, np.int64)


def cells_near(xy: np.ndarray, cell_m: float, reach_m: float = RADIUS_M + MARGIN_M) -> np.ndarray:
    """Sorted keys (as :func:`calidar.strips.overlap.cell_keys`) of the grid cells of ``cell_m``
    that come within ``reach_m`` of a control point at ``xy`` (N, 2) m (every cell the square of
    half-side ``reach_m`` around it touches)."""
    from calidar.strips.overlap import cell_keys

    xy = np.asarray(xy, float).reshape(-1, 2)
    steps = np.arange(-reach_m, reach_m + cell_m, cell_m)
    steps = np.unique(np.clip(steps, -reach_m, reach_m))
    dx, dy = (a.ravel() for a in np.meshgrid(steps, steps))
    around = (xy[:, None, :] + np.stack([dx, dy], axis=1)[None]).reshape(-1, 2)
    return np.unique(cell_keys(around, cell_m))


def control_rows(problem, residuals: np.ndarray) -> list[dict]:
    """Per control row of a :class:`~calidar.strips.problem.StripProblem` with its ``residuals``:
    the control point's index, the strip, the residual along the plane's normal (m, > 0: the
    strip's surface above the control point), its vertical part dz (m) and σ (m)."""
    out = []
    if CONTROL_ID not in problem.index:
        return out
    which = problem.index[CONTROL_ID]
    for c, r in problem.split(residuals):
        if c.strip_b != CONTROL_ID:
            continue
        k = which[c.B.tocsr().indices]  # one control point per row, in row order
        nz = np.abs(c.normal[:, 2])
        sigma = np.broadcast_to(np.asarray(c.sigma_m, float), r.shape)
        for j in range(r.size):
            out.append({"point": int(k[j]), "strip": int(c.strip_a), "residual_m": float(r[j]),
                        "dz_m": float(r[j] / max(nz[j], 1e-6)), "sigma_m": float(sigma[j])})
    return out


def control_summary(control: ControlPoints, before: list[dict], after: list[dict]) -> dict:
    """What solution.json holds of the control: per control point and strip covering it, dz
    before (nominal sensor) and after (calibrated), with the row's own σ (the survey's and the
    surface's; "weight_sigma_m": the σ it is weighed by, the surface's alone: the survey error is
    the point's own nuisance parameter, :mod:`calidar.strips.control_survey`); the points no strip
    covered; the weighted mean and RMS of dz after (m)."""
    first = {(b["point"], b["strip"]): b["dz_m"] for b in before}
    rows = [{"id": str(control.ids[a["point"]]), "strip": a["strip"],
             "dz_before_m": first.get((a["point"], a["strip"])),
             "dz_after_m": a["dz_m"], "sigma_m": a["sigma_m"],
             "weight_sigma_m": float(np.sqrt(max(a["sigma_m"] ** 2
                                                 - control.sigma_m[a["point"]] ** 2, 0.0))),
             "survey_sigma_m": float(control.sigma_m[a["point"]])} for a in after]
    used = {a["point"] for a in after}
    dz = np.array([a["dz_m"] for a in after])
    s = np.array([r["sigma_m"] for r in rows])
    w = 1.0 / np.maximum(s, 1e-9) ** 2
    return {"kind": control.kind, "label": control.label, "n_points": len(control.ids),
            "n_used": len(used), "n_rows": len(rows),
            "not_covered": [str(control.ids[k]) for k in range(len(control.ids)) if k not in used],
            "mean_dz_after_m": float(np.sum(w * dz) / np.sum(w)) if dz.size else None,
            "rms_dz_after_m": float(np.sqrt(np.mean(dz**2))) if dz.size else None,
            "rms_dz_before_m": (float(np.sqrt(np.mean([b["dz_m"] ** 2 for b in before])))
                                if before else None),
            "points": rows}


def vertical_shift(result) -> tuple[float, float, float] | None:
    """The estimated trajectory height correction averaged over every strip's knots (plus the
    common ``height_bias`` when estimated): its value, σ (m, from the covariance: aᵀ C a with
    a = 1/K on the K "up" shift parameters) and its σ from the trajectory priors alone (aᵀ P a, P
    the priors' Gauss–Markov covariance); None without trajectory corrections. The overlaps see only
    differences between strips: this average (a vertical trajectory bias) is fixed by the priors
    alone unless ground control observes it."""
    solution = result.solution
    free = solution.parameters.free_names
    model = getattr(result, "trajectory_model", None)
    layout = {} if model is None else model.layout({st.id: st.time_span for st in result.strips})
    up = [j for j, n in enumerate(free)
          if (k := layout.get(n)) is not None and k.kind == "bias" and k.axis == 2]
    if not up:
        return None
    a = np.zeros(len(free))
    a[up] = 1.0 / len(up)
    all_values = solution.values  # (a dict built per access: once, not per parameter)
    values = np.array([all_values[n] for n in free])
    prior = {p.name: (p.prior_sigma or 0.0) / len(up) for p in solution.parameters.free
             if p.name in {free[j] for j in up}}
    var_prior = 0.0
    spans = {st.id: st.time_span for st in result.strips}
    groups = [] if model is None else model.prior_correlation(spans)
    for names, R in groups:
        if names[0] in prior and all(n in prior for n in names):
            w = np.array([prior.pop(n) for n in names])
            var_prior += float(w @ R @ w)
    var_prior += sum(w * w for w in prior.values())  # knots without correlation
    if "height_bias" in free:  # the common shift, estimated too: no prior bounds it
        a[free.index("height_bias")] = 1.0
        var_prior = np.inf
    sigma = float(np.sqrt(max(a @ solution.covariance @ a, 0.0)))
    return float(a @ values), sigma, float(np.sqrt(var_prior))
