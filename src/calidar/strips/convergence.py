"""When the strip calibrator's outer loop has converged: one rule for the loop and the verdict
(issue 26/32), and the loop's extrapolation along a steady direction.

The loop (:func:`calidar.strips.outer_loop.outer_loop`) stopped when the mean correspondence
distance settled; on the 10⁹ run's kept cells the distance settled (< 0.2 mm) while the pitch still
moved 1.8σ an outer iteration and ended 7.7σ off. :func:`moving` is the rule the verdict applies
(:func:`calidar.strips.verdict.still_moving`), now also the loop's: an estimated parameter whose
last step exceeds :data:`STILL_STEP_SIGMA` of its σ and, at the rate of its last two steps, has
more than :data:`STILL_LEFT_SIGMA` still to come (a geometric series, s·ρ/(1 − ρ)) keeps the
loop going.

:func:`extrapolated` is the acceleration of ICP by Besl & McKay (1992, *A method for registration of
3-D shapes*, §IV.D): when successive steps point the same way (within
:data:`ALIGNED_DEG` in the parameters' σ), the loop jumps ahead along them by the rest of their
geometric series; the next matching and adjustment then start there (they correct an overshoot as
any other start: only the matching's state enters the rows, the adjustment's start does not).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from calidar.strips.control_survey import PREFIX as CONTROL_PREFIX
from calidar.strips.trajectory_errors import PREFIX as TRAJECTORY_PREFIX

#: nuisance parameters: not watched by the rule — nor judged, compared or shown in the correlations
#: by the verdict (the trajectory's errors, the control's survey errors)
NUISANCE = (TRAJECTORY_PREFIX, CONTROL_PREFIX)
#: the rule's thresholds (σ of each parameter): the last step, and the steps still to come
STILL_STEP_SIGMA = 0.2
STILL_LEFT_SIGMA = 1.0
#: successive steps (all free parameters, in their σ) within this angle count as one direction
ALIGNED_DEG = 10.0
#: the extrapolation's largest multiple of the last step (ρ ≤ 0.9)
MAX_JUMP = 9.0


def moving(values: Sequence[Mapping[str, float]], sigma: Mapping[str, float],
           skip: tuple[str, ...] = ()) -> tuple[str, float, float] | None:
    """(name, last step / σ, steps to come / σ) of the parameter of ``sigma`` (none whose name
    starts with ``skip``) the last three outer iterations' ``values`` leave furthest from where its
    last two steps were heading, or None. After two iterations a step over
    :data:`STILL_LEFT_SIGMA` counts as still moving (its rate unknown: as much again to come)."""
    if len(values) < 2:
        return None
    v0, v1, v2 = values[-3:] if len(values) > 2 else (None, *values[-2:])
    worst = None
    for name, s in sigma.items():
        if name.startswith(skip) or not s > 0 or name not in v2:
            continue
        s2 = (v2[name] - v1[name]) / s
        s1 = s2 if v0 is None else (v1[name] - v0[name]) / s
        rho = s2 / s1 if s1 != 0 else 0.0
        left = abs(s2) * rho / (1.0 - rho) if 0.0 < rho < 1.0 else (np.inf if rho >= 1.0 else 0.0)
        least = STILL_STEP_SIGMA if v0 is not None else STILL_LEFT_SIGMA
        if abs(s2) > least and left > STILL_LEFT_SIGMA and (
                worst is None or left > worst[2]):
            worst = (name, s2, left)
    return worst


def extrapolated(values: Sequence[Mapping[str, float]], sigma: Mapping[str, float],
                 free: Sequence[str], skip: tuple[str, ...] = ()) -> dict[str, float] | None:
    """The ``free`` parameters' values (by name) ahead of the last of ``values`` by the rest of the
    last two steps' geometric series, when those steps of the parameters the rule watches (scaled
    by ``sigma``; none whose name starts with ``skip``) point within :data:`ALIGNED_DEG` of each
    other and shrink (0 < ρ < 1); None otherwise. Every free parameter jumps by the same multiple
    of its last step (the nuisance parameters crawl with the watched ones)."""
    if len(values) < 3:
        return None
    watch = [n for n in free if not n.startswith(skip) and sigma.get(n, 0.0) > 0]
    scale = np.array([sigma[n] for n in watch])
    v0, v1, v2 = (np.array([v[n] for n in watch]) for v in values[-3:])
    s1, s2 = (v1 - v0) / scale, (v2 - v1) / scale
    n1, n2 = np.linalg.norm(s1), np.linalg.norm(s2)
    if not (n1 > 0 and n2 > 0) or s1 @ s2 / (n1 * n2) < np.cos(np.radians(ALIGNED_DEG)):
        return None
    rho = n2 / n1
    if not rho < 1.0:
        return None
    jump = min(rho / (1.0 - rho), MAX_JUMP)
    last, before = values[-1], values[-2]
    return {n: float(last[n] + jump * (last[n] - before[n])) for n in free}
