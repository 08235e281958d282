"""The checkpoints' word in the boresight verdict (issue 28): ``calidar boresight --checkpoints
FILE`` tests the calibrated strips against surveyed ground points that are not in the adjustment.

The overlaps cannot see a height error shared by every strip (a range offset, a vertical lever arm
or trajectory bias): a calibration may close them and still miss the ground. At each open-ground
checkpoint the surface is the TIN of the strips' points around it
(:func:`calidar.accuracy.tin.tin_heights`, as ``calidar accuracy`` and the ASPRS procedure take it),
before (as delivered) and after (the calibrated sensor and trajectory corrections); dz = surface −
checkpoint; the statistics are ASPRS Edition 2's (:func:`calidar.accuracy.asprs.vertical_accuracy`).
The finding fails when ``--class X`` is given and the calibrated strips do not meet the X-cm class;
it warns when their mean dz departs from zero by more than :data:`BIAS_T` standard errors (missing
the ground, whatever the class), or when the calibration made the fit to the ground worse. The
strips kept by the ingest hold only the points near overlaps and near control and checkpoints
(:func:`calidar.pipelines.control.read_ground`); the checkpoints choose which points are
kept, their heights never enter the adjustment."""

from __future__ import annotations

import numpy as np

from calidar.verdict import Finding

#: the strips' points within this of a checkpoint form its TIN (the ingest keeps them)
TIN_RADIUS_M = 3.0
BIAS_T = 3.0  #: |mean dz| above this many standard errors: the strips miss the ground
#: RMSEz after above this × before (and beyond its noise): the calibration moved away from the
#: ground
WORSE = 1.2


def _dz(result, checkpoints, calibrated: bool) -> np.ndarray:
    """surface − checkpoint (m; NaN: no triangle of points around it), strips of ``result``."""
    from calidar.accuracy.tin import tin_heights
    from calidar.strips.control import near_control

    pts, ids = [], []
    for st in result.strips:
        idx = near_control(st.points, checkpoints, TIN_RADIUS_M)
        if idx.size:
            pts.append(result.georeference(st, calibrated, idx))
            ids.append(np.full(idx.size, st.id))
    if not pts:
        return np.full(len(checkpoints.ids), np.nan)
    h = tin_heights(np.vstack(pts), np.concatenate(ids), checkpoints.local[:, :2], TIN_RADIUS_M,
                    TIN_RADIUS_M)
    return h.z - checkpoints.local[:, 2]


def checkpoint_test(result, checkpoints) -> dict:
    """The checkpoints (:class:`calidar.strips.control.ControlPoints`, σ 0: not given) against the
    strips before and after the calibration: per point dz, and the ASPRS statistics of each."""
    from calidar.accuracy.asprs import vertical_accuracy

    sigma = np.asarray(checkpoints.sigma_m, float)
    survey = float(np.sqrt(np.mean(sigma**2))) if np.any(sigma > 0) else None
    dz = {stage: _dz(result, checkpoints, stage == "after") for stage in ("before", "after")}
    acc = {stage: vertical_accuracy(d[np.isfinite(d)], (), survey) for stage, d in dz.items()}
    return {"dz": dz, "accuracy": acc, "ids": [str(i) for i in checkpoints.ids]}


def _cm(v: float | None) -> str:
    return "—" if v is None else f"{v * 100:.1f} cm"


def checkpoint_findings(inputs, result) -> list[Finding]:
    """The verdict's "checkpoints (ground)" finding of a boresight run with ``--checkpoints``
    (none without); the test also goes to solution.json (``solution.extra["checkpoints"]``)."""
    from calidar.accuracy.asprs import class_name

    checkpoints = getattr(inputs, "checkpoints", None)
    if checkpoints is None:
        return []
    target = inputs.config.checkpoint_class_cm
    t = checkpoint_test(result, checkpoints)
    before, after = t["accuracy"]["before"], t["accuracy"]["after"]
    result.solution.extra["checkpoints"] = {
        "target_class_cm": target, "before": before.to_dict(), "after": after.to_dict(),
        "points": [{"id": i, "dz_before_m": _num(b), "dz_after_m": _num(a)}
                   for i, b, a in zip(t["ids"], t["dz"]["before"], t["dz"]["after"])]}
    check = "checkpoints (ground)"
    if after.rmse_m is None:
        none = f"none of the {len(t['ids'])} checkpoints has the strips' points around it"
        return [Finding("warn", check, none,
                        "check the checkpoints' coordinates and CRS (--checkpoints-crs)")]
    detail = _detail(before, after, missing=len(t["ids"]) - after.n_nva)
    action = ("a height error the overlaps cannot see (range offset, vertical lever arm, vertical "
              "trajectory bias, or the vertical datum/geoid): give ground control (--control FILE) "
              "and --estimate …,range_offset or height_bias; then calidar accuracy on the "
              "recalibrated strips")
    if target is not None and not after.meets(target):
        not_met = f": the {class_name(target)} class asked for (--class) is NOT met"
        return [Finding("fail", check, detail + not_met, action)]
    if after.sdom_m is not None and abs(after.mean_m) > BIAS_T * after.sdom_m:
        side = "above" if after.mean_m > 0 else "below"
        off = (f": the calibrated strips lie {abs(after.mean_m) * 100:.1f} cm {side} the ground "
               f"({abs(after.mean_m) / after.sdom_m:.1f} standard errors)")
        return [Finding("warn", check, detail + off, action)]
    rmse_noise_m = 2 * (after.rmse_sigma_m or 0.0)
    if before.rmse_m is not None and after.rmse_m > WORSE * before.rmse_m + rmse_noise_m:
        worse = ": the calibration fits the ground worse than the delivered strips"
        return [Finding("warn", check, detail + worse,
                        "check the estimated parameters against the mounting's records; " + action)]
    asked = f" (the {class_name(target)} class asked for)" if target else ""
    return [Finding("pass", check, detail + asked)]


def _detail(before, after, missing: int) -> str:
    """The finding's figures: RMSEz before → after, the mean dz ± its standard error (cm), the
    statement of the accuracy class met and the checkpoints without points around them."""
    sdom = f" ± {after.sdom_m * 100:.1f}" if after.sdom_m else ""
    without = f"; {missing} without the strips' points around them" if missing else ""
    return (f"{after.n_nva} checkpoints, not in the adjustment: RMSEz {_cm(before.rmse_m)} → "
            f"{_cm(after.rmse_m)}, mean dz {after.mean_m * 100:+.1f}{sdom} cm; "
            f"{after.statement()}{without}")


def _num(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None
