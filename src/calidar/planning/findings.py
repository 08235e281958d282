"""What a prediction means in plain words: which parameters the plan will not determine, why,
and what to fly instead."""

from __future__ import annotations

import numpy as np

from calidar.planning.predict import SEPARATION_LIMIT, Prediction
from calidar.strips.verdict import ACTIONS, CORRELATION_LIMIT, GENERIC_ACTION

#: parameters no overlap can see: they move every strip alike
COMMON_SHIFT = {
    "lever_arm_z": "a vertical lever-arm error shifts every strip alike (level flight), and the "
                   "overlaps only compare strips with each other",
    "range_offset": "a range offset shifts every strip alike near nadir, and the overlaps only "
                    "compare strips with each other",
    "height_bias": "a common height shift is invisible in the overlaps",
}
#: pairs one flying height cannot part: (boresight angle, lever arm, the direction it moves points)
ONE_HEIGHT_PAIRS = (("boresight_pitch", "lever_arm_x", "along track", "along-track"),
                    ("boresight_roll", "lever_arm_y", "across track", "across-track"))


def shown(name: str, unit: str, value: float) -> str:
    """A σ in the unit users read: degrees, centimetres, ppm."""
    if not np.isfinite(value):
        return "∞ (not seen at all)"
    if unit == "rad":
        return f"{np.degrees(value):.5f}°"
    if unit == "m":
        return f"{value * 100:.2f} cm"
    if name == "range_scale":
        return f"{value * 1e6:.1f} ppm"
    return f"{value:.3g}"


def _why(pred: Prediction, k: int) -> str:
    """Why parameter k is not determined, in plain words."""
    name = pred.names[k]
    partners = [(b if a == name else a, rho)
                for a, b, rho in pred.correlated_pairs(CORRELATION_LIMIT) if name in (a, b)]
    if not np.isfinite(pred.sigma[k]):
        return COMMON_SHIFT.get(name, "the tie planes of this plan do not move when it changes")
    one_height = len(pred.heights) == 1
    involved = {name, *[p for p, _ in partners]}
    for angle, lever, moves, which in ONE_HEIGHT_PAIRS:
        if involved >= {angle, lever} and one_height:
            rotation = angle.removeprefix("boresight_")
            return (f"every line flies at {pred.heights[0]:g} m: a {rotation} error moves points "
                    f"{moves} by height × angle, as an {which} lever-arm error does")
    if partners:
        return "; ".join(f"ρ = {rho:+.3f} with {p}" for p, rho in partners)
    if name == "lever_arm_x" and one_height and "boresight_pitch" in pred.names:
        rho = pred.correlation[k, pred.names.index("boresight_pitch")]
        return (f"every line flies at {pred.heights[0]:g} m, where an along-track lever-arm error "
                f"moves points as a pitch error does (ρ = {rho:+.2f} with boresight_pitch), and "
                "the trajectory's own position errors hide the rest")
    if name == "boresight_yaw":
        return ("a heading error shows only where the terrain slopes or roofs tilt, far from the "
                "line")
    if name.startswith("lever_arm"):
        return ("the trajectory's own position errors (its stated accuracy) hide a lever-arm error "
                "of this size")
    return "too few tie planes see it"


def findings(pred: Prediction) -> list[dict]:
    """One entry per estimated parameter: determined or not, why, and the action."""
    out = []
    for k, name in enumerate(pred.names):
        effect, limit = pred.ground_effect(k), pred.limit(k)
        ok = pred.determined(k)
        entry = {"parameter": name, "sigma": shown(name, pred.units[k], float(pred.reported[k])),
                 "error_sigma": shown(name, pred.units[k], float(pred.sigma[k])), "determined": ok,
                 "ground_effect_m": effect if np.isfinite(effect) else None, "limit_m": limit}
        if not ok:
            entry["why"] = _why(pred, k)
            entry["action"] = ACTIONS.get(name, GENERIC_ACTION)
        out.append(entry)
    for a, b, rho in pred.correlated_pairs(SEPARATION_LIMIT):
        action = ACTIONS.get(b if b.startswith("lever") else a, GENERIC_ACTION)
        out.append({"parameter": f"{a} and {b}", "determined": False,
                    "why": f"ρ = {rho:+.3f}: this plan cannot separate them", "action": action})
    return out


def headline(pred: Prediction) -> str:
    """One sentence: good or poor, and the worst parameter."""
    k = pred.worst()
    worst = f"{pred.names[k]} σ {shown(pred.names[k], pred.units[k], float(pred.reported[k]))}"
    bad = [n for i, n in enumerate(pred.names) if not pred.determined(i)]
    if not pred.poor:
        return f"good: every estimated parameter is determined (the weakest: {worst})"
    pairs = [f"{a}/{b}" for a, b, _ in pred.correlated_pairs(SEPARATION_LIMIT)]
    parts = []
    if bad:
        parts.append(f"not determined: {', '.join(bad)}")
    if pairs:
        parts.append(f"inseparable: {', '.join(pairs)}")
    return f"poor: {'; '.join(parts)} (the weakest: {worst})"
