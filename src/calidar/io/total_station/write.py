"""Writing total-station observations in the file format of :mod:`calidar.io.total_station`."""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from calidar.io.total_station.observations import (ANGLE_UNITS, ARCSEC, FORMAT_LINE, FULL_CIRCLE,
                                                   TotalStationObservations)
from calidar.outputs import write_text_atomic


def format_observations(obs: TotalStationObservations, angle_unit: str = "deg",
                        vertical: str = "zd", comments: Iterable[str] = ()) -> str:
    """The file text of ``obs`` with angles in ``angle_unit`` ("deg" | "gon") as vertical
    angles ("va") or zenith distances ("zd"); rows in the order of ``obs`` after each setup's
    P."""
    if angle_unit not in ANGLE_UNITS or vertical not in ("va", "zd"):
        raise ValueError("angle_unit must be deg|gon and vertical va|zd, got "
                         f"{angle_unit!r}, {vertical!r}")
    k = 1.0 / ANGLE_UNITS[angle_unit]
    full = FULL_CIRCLE[angle_unit]

    def angles(va, hz):
        v = va * k if vertical == "va" else (math.pi / 2 - va) * k
        return f"{(hz * k) % full:.7f}", f"{v:.7f}"

    out = [f"#! {FORMAT_LINE}"] + [f"# {c}" for c in comments]
    out.append(f"#! scanner_sigma_mm: {obs.scanner_sigma * 1e3:g}")
    for s in obs.setups:
        out.append(f"#! setup: {s.id} angle_arcsec={s.angle_sigma / ARCSEC:g} "
                   f"distance_mm={s.distance_sigma_m * 1e3:g} "
                   f"distance_ppm={s.distance_sigma_ppm:g}")
    out.append(f"setup,group,point,hz_{angle_unit},{vertical}_{angle_unit},slope_m,scanner_m")
    for i, s in enumerate(obs.setups):
        h, v = angles(s.p_va, s.p_hz)
        out.append(f"{s.id},,P,{h},{v},{s.p_slope:.4f},")
        for j in np.flatnonzero(obs.setup == i):
            h, v = angles(obs.va[j], obs.hz[j])
            distances = f"{obs.slope[j]:.4f},{obs.scanner[j]:.4f}"
            out.append(f"{s.id},{obs.group[j]},{obs.point[j]},{h},{v},{distances}")
    return "\n".join(out) + "\n"


def write_observations(path: str | Path, obs: TotalStationObservations, angle_unit: str = "deg",
                       vertical: str = "zd", comments: Iterable[str] = (),
                       force: bool = False) -> Path:
    """Write ``obs`` atomically in the file format of this module."""
    text = format_observations(obs, angle_unit, vertical, comments)
    return write_text_atomic(path, text, force)
