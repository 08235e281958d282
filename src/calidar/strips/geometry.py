"""What a flight geometry can and cannot determine, in plain words."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from calidar.strips.strip import Strip

Pairs = Sequence[tuple[int, int]]  #: overlapping strips, as (id of a, id of b)
#: the parameters a same-direction-only geometry cannot see (they shift every strip alike)
SAME_WAY_BLIND = ("boresight_pitch", "lever_arm_x", "lever_arm_y", "lever_arm_z")


def pair_kind(strips: Sequence[Strip], pairs: Pairs) -> dict[tuple[int, int], str]:
    """How each overlapping pair was flown: "same" (headings within 30°), "opposite" (within
    30° of reversed) or "cross" (anything else)."""
    heading = {s.id: s.heading_enu() for s in strips}
    out = {}
    for a, b in pairs:
        d = abs((heading[a] - heading[b] + np.pi) % (2 * np.pi) - np.pi)
        out[a, b] = "same" if d < np.radians(30) else "opposite" if d > np.radians(150) else "cross"
    return out


def pair_kinds(strips: Sequence[Strip], pairs: Pairs) -> set[str]:
    """The kinds of :func:`pair_kind` the pairs hold."""
    return set(pair_kind(strips, pairs).values())


def geometry_warnings(strips: Sequence[Strip], pairs: Pairs, free: Sequence[str]) -> list[str]:
    """Plain-words warnings about parameters the flight geometry cannot determine."""
    kinds = pair_kinds(strips, pairs)
    out = []
    if kinds == {"same"}:
        hit = [p for p in SAME_WAY_BLIND if p in free]
        if hit:
            out.append(
                f"{', '.join(hit)} poorly determined: all overlapping strips are parallel and "
                "flown the same way, so these errors shift every strip by the same amount and "
                "the overlaps cannot see it (fly lines in the opposite direction and across)")
    elif "cross" not in kinds and any(p.startswith("lever_arm") for p in free):
        out.append("lever arm weakly determined: no cross lines, only parallel strips "
                   "(fly a line across them)")
    if "lever_arm_z" in free:
        out.append("lever_arm_z is determined only through attitude changes (a vertical lever-arm "
                   "error shifts every strip up or down alike); expect a large σ")
    return out
