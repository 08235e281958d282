"""Which line to add: candidate lines tried one by one, the one that best improves the worst
determined parameter kept.

Candidates follow the rules crews fly by (Habib et al. 2010, *Alternative methodologies for
LiDAR system calibration*, Remote Sensing 2: opposite directions for roll and pitch, lines with a
large lateral separation for heading, a second flying height to part the along-track lever arm
from pitch; cross lines): the middle and the two outermost lines flown back; the middle line at 1.5× its height; a line across
the block's middle, each way; a line beyond the outermost one, one swath out with 20 % side overlap.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from calidar.errors import CalidarError
from calidar.io.flight_lines import PlanLine
from calidar.planning.geometry import Instrument
from calidar.planning.predict import PlanSettings, Prediction, predict


@dataclass
class Suggestion:
    """A candidate line, what it is and the worst parameter's reported σ without and with it (SI)."""

    line: PlanLine
    kind: str
    parameter: str
    sigma_before: float
    sigma_after: float
    prediction: Prediction

    def to_dict(self) -> dict:
        return {**self.line.to_dict(), "kind": self.kind, "parameter": self.parameter,
                "sigma_before": self.sigma_before, "sigma_after": self.sigma_after,
                "improvement": self.sigma_before / self.sigma_after if self.sigma_after > 0 else None}


def candidates(lines: list[PlanLine], inst: Instrument) -> list[tuple[str, PlanLine]]:
    """Candidate lines for ``lines`` (numbers after the plan's)."""
    number = max(ln.number for ln in lines) + 1
    out = []
    seen = set()
    centre = np.mean([0.5 * (ln.start + ln.end) for ln in lines], axis=0)
    by_offset = sorted(lines, key=lambda ln: float(np.linalg.norm(0.5 * (ln.start + ln.end) - centre)))
    for ln in [*by_offset[:1], *by_offset[-2:]]:  # the middle and the two outermost lines flown back
        key = (round(float(ln.start[0] + ln.end[0]), 1), round(float(ln.start[1] + ln.end[1]), 1), ln.height_agl_m)
        if key in seen:
            continue
        seen.add(key)
        back = PlanLine(0, ln.end.copy(), ln.start.copy(), ln.height_agl_m, ln.speed_mps)
        twin = next((o for o in lines if np.allclose(o.start, back.start) and np.allclose(o.end, back.end)
                     and o.height_agl_m == back.height_agl_m), None)
        out.append((f"line {ln.number}'s track flown back" if twin is None else f"line {twin.number} flown again", back))
    mid = by_offset[0]
    out.append((f"the middle line at a second height ({1.5 * mid.height_agl_m:g} m)",
                PlanLine(0, mid.end.copy(), mid.start.copy(), 1.5 * mid.height_agl_m, mid.speed_mps)))
    d = mid.direction
    across = np.array([d[1], -d[0]])
    half = 0.5 * mid.length_m
    for sign in (1.0, -1.0):
        out.append(("a cross line through the middle", PlanLine(0, centre - sign * half * across,
                                                                centre + sign * half * across,
                                                                mid.height_agl_m, mid.speed_mps)))
    offsets = [float((0.5 * (ln.start + ln.end) - centre) @ across) for ln in lines]
    outer = lines[int(np.argmax(np.abs(offsets)))]
    side = 1.0 if offsets[int(np.argmax(np.abs(offsets)))] >= 0 else -1.0
    swath = 2.0 * outer.height_agl_m * np.tan(inst.half_fov_rad)
    shift = side * 0.8 * swath * across
    out.append(("a line further out (20 % side overlap)", PlanLine(0, outer.start + shift, outer.end + shift,
                                                                   outer.height_agl_m, outer.speed_mps)))
    return [(kind, replace(ln, number=number)) for kind, ln in out]


def suggest(lines: list[PlanLine], terrain, inst: Instrument, settings: PlanSettings, base: Prediction,
            progress=None, cache: dict | None = None) -> list[Suggestion]:
    """Every candidate's effect on the worst-determined parameter of ``base``, best first (``cache``:
    the tie planes :func:`predict` sampled for ``base``)."""
    worst = base.worst()
    name = base.names[worst]
    found, cache = [], {} if cache is None else cache
    cands = candidates(lines, inst)
    for k, (kind, cand) in enumerate(cands):
        try:
            pred = predict([*lines, cand], terrain, inst, settings, cache)
        except CalidarError:
            continue
        found.append(Suggestion(cand, kind, name, float(base.reported[worst]),
                                float(pred.reported[pred.names.index(name)]), pred))
        if progress:
            progress("trying candidate lines", k + 1, len(cands))
    return sorted(found, key=lambda s: s.sigma_after)
