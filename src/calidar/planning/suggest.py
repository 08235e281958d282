"""Which line to add: candidate lines tried one by one, the one that best improves the worst
determined parameter kept.

Candidates follow the rules crews fly by (Habib et al. 2010, *Alternative methodologies for LiDAR
system calibration*, Remote Sensing 2: opposite directions for roll and pitch, lines with a large
lateral separation for heading, a second flying height to part the along-track lever arm from pitch;
cross lines): the middle and the two outermost lines flown back; the middle line at 1.5× its height;
a line across the block's middle, each way; a line beyond the outermost one, one swath out with 20 %
side overlap.
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
    """A candidate line, what it is and the worst parameter's reported σ without and with it
    (SI)."""

    line: PlanLine
    kind: str
    parameter: str
    sigma_before: float
    sigma_after: float
    prediction: Prediction

    def to_dict(self) -> dict:
        """plan.json's entry: the line, what it is, the σ without and with it (SI)."""
        improvement = self.sigma_before / self.sigma_after if self.sigma_after > 0 else None
        return {**self.line.to_dict(), "kind": self.kind, "parameter": self.parameter,
                "sigma_before": self.sigma_before, "sigma_after": self.sigma_after,
                "improvement": improvement}


def _same_line(a: PlanLine, b: PlanLine) -> bool:
    """Same start, end and height above ground."""
    return (np.allclose(a.start, b.start) and np.allclose(a.end, b.end)
            and a.height_agl_m == b.height_agl_m)


def _flown_back(lines: list[PlanLine], by_offset: list[PlanLine]) -> list[tuple[str, PlanLine]]:
    """The middle and the two outermost lines flown back (once each; "flown again" when the plan
    already has that line in the other direction)."""
    out, seen = [], set()
    for ln in [*by_offset[:1], *by_offset[-2:]]:
        mid_x2, mid_y2 = ln.start + ln.end  # twice the line's middle
        key = (round(float(mid_x2), 1), round(float(mid_y2), 1), ln.height_agl_m)
        if key in seen:
            continue
        seen.add(key)
        back = PlanLine(0, ln.end.copy(), ln.start.copy(), ln.height_agl_m, ln.speed_mps)
        twin = next((o for o in lines if _same_line(o, back)), None)
        if twin is None:
            out.append((f"line {ln.number}'s track flown back", back))
        else:
            out.append((f"line {twin.number} flown again", back))
    return out


def candidates(lines: list[PlanLine], inst: Instrument) -> list[tuple[str, PlanLine]]:
    """Candidate lines for ``lines`` (numbers after the plan's)."""
    number = max(ln.number for ln in lines) + 1
    centre = np.mean([0.5 * (ln.start + ln.end) for ln in lines], axis=0)

    def offset_m(ln: PlanLine) -> float:
        return float(np.linalg.norm(0.5 * (ln.start + ln.end) - centre))

    by_offset = sorted(lines, key=offset_m)
    out = _flown_back(lines, by_offset)
    mid = by_offset[0]
    higher = PlanLine(0, mid.end.copy(), mid.start.copy(), 1.5 * mid.height_agl_m, mid.speed_mps)
    out.append((f"the middle line at a second height ({higher.height_agl_m:g} m)", higher))
    d = mid.direction
    across = np.array([d[1], -d[0]])
    half = 0.5 * mid.length_m
    for sign in (1.0, -1.0):
        cross = PlanLine(0, centre - sign * half * across, centre + sign * half * across,
                         mid.height_agl_m, mid.speed_mps)
        out.append(("a cross line through the middle", cross))
    offsets = [float((0.5 * (ln.start + ln.end) - centre) @ across) for ln in lines]
    outermost = int(np.argmax(np.abs(offsets)))
    outer = lines[outermost]
    side = 1.0 if offsets[outermost] >= 0 else -1.0
    swath = 2.0 * outer.height_agl_m * np.tan(inst.half_fov_rad)
    shift = side * 0.8 * swath * across
    further = PlanLine(0, outer.start + shift, outer.end + shift, outer.height_agl_m,
                       outer.speed_mps)
    out.append(("a line further out (20 % side overlap)", further))
    return [(kind, replace(ln, number=number)) for kind, ln in out]


def suggest(lines: list[PlanLine], terrain, inst: Instrument, settings: PlanSettings,
            base: Prediction, progress=None, cache: dict | None = None) -> list[Suggestion]:
    """Every candidate's effect on the worst-determined parameter of ``base``, best first
    (``cache``: the tie planes :func:`predict` sampled for ``base``)."""
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
