"""Unit slips caught by magnitude: a scanner range must agree with the total station's distance
P→X to within its offset and scale (centimetres and ppm), so a ratio near 1000, 100, 3.28 or
39.4 is a unit, not an error of the scanner.

>>> unit_of_ratio(1000.4)
'millimetres'
>>> unit_of_ratio(1.01) is None
True
"""

from __future__ import annotations

import numpy as np

from calidar.errors import InputError
from calidar.io.total_station import TotalStationObservations

#: unit name → how many of it make a metre
UNIT_FACTORS = {"millimetres": 1e3, "centimetres": 1e2, "inches": 1 / 0.0254, "feet": 1 / 0.3048}
MATCH = 0.1  #: relative distance of a ratio from a unit factor that names the unit
PLAUSIBLE = (0.5, 2.0)  #: median scanner range / distance P→X a calibration can start from
ROW_UNITS = ("millimetres", "centimetres")  #: single rows this far off can only be a unit slip


def unit_of_ratio(ratio: float) -> str | None:
    """The unit whose factor ``ratio`` (value / metres) is within :data:`MATCH` of, else None."""
    for name, f in UNIT_FACTORS.items():
        if abs(ratio / f - 1.0) < MATCH:
            return name
    return None


def check_units(obs: TotalStationObservations, distance: np.ndarray) -> None:
    """Refuse scanner ranges (or total-station distances) in the wrong unit: the whole file by the
    median of scanner range / S_PX, then single rows in millimetres or centimetres.
    ``distance``: S_PX (m) of every target from the observed P."""
    ratio = obs.scanner / distance
    med = float(np.median(ratio))
    n = len(obs)
    if not PLAUSIBLE[0] <= med <= PLAUSIBLE[1]:
        _refuse_the_file(obs, med, n)
    for unit in ROW_UNITS:
        bad = np.flatnonzero(np.abs(ratio / UNIT_FACTORS[unit] - 1.0) < MATCH)
        if bad.size:
            i = bad[0]
            more = f" ({bad.size} rows like it)" if bad.size > 1 else ""
            raise InputError(obs.source, f"line {obs.line[i]}: scanner_m",
                             f"{obs.scanner[i]:g} is {ratio[i]:.0f}× the distance P→{obs.point[i]} "
                             f"from the total station ({distance[i]:.3f} m): expected metres; it "
                             f"looks like {unit}{more}")


def _refuse_the_file(obs: TotalStationObservations, med: float, n: int) -> None:
    """The error for a whole file whose median scanner range / S_PX ``med`` (of ``n`` targets) is
    implausible: naming the unit of the scanner ranges or of the slope distances when it looks
    like one."""
    said = (f"the scanner ranges are {med:.4g}× the distances P→X from the total station "
            f"(median of {n} targets)")
    if unit := unit_of_ratio(med):
        raise InputError(obs.source, "scanner_m",
                         f"{said}: expected metres; scanner_m looks like {unit}")
    if unit := unit_of_ratio(1.0 / med):
        raise InputError(obs.source, "slope_m",
                         f"{said}: expected metres; the total station's slope_m look like {unit}")
    raise InputError(obs.source, "scanner_m", f"{said}; expected them to agree within a few per "
                     "cent: check that both are in metres and that each row's scanner_m belongs "
                     "to its point")
