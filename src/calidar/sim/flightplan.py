"""Flight plans: parallel lines at a height above ground, with same/opposite/cross directions.

Everything is in the scene's ENU frame (m); azimuths are clockwise from north (rad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.errors import InputError

DIRECTIONS = ("same", "opposite", "cross")


@dataclass(frozen=True)
class FlightLine:
    """One scanning line: the platform flies from ``start`` to ``end`` (ENU xy, m) at
    ``altitude_m``."""

    number: int  #: 1-based; becomes the LAS point_source_id
    start: np.ndarray  #: (2,) m
    end: np.ndarray  #: (2,) m
    altitude_m: float  #: ENU z of the flight, m

    @property
    def direction(self) -> np.ndarray:
        """Unit vector (2,) east, north of the flight direction."""
        d = self.end - self.start
        return d / np.linalg.norm(d)

    @property
    def azimuth(self) -> float:
        """Flight direction clockwise from north, rad."""
        return float(np.arctan2(self.direction[0], self.direction[1]))

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(self.end - self.start))


def check_plan_inputs(height_agl_m: float, speed_mps: float, side_overlap: float,
                      half_fov_rad: float, directions: str) -> None:
    """Raise a clear error for impossible flight-plan values (m, m/s, ratio, rad)."""
    if not np.isfinite(height_agl_m) or height_agl_m <= 0:
        raise InputError(None, "height_agl_m",
                         f"expected a height above ground > 0 m, got {height_agl_m}")
    if not np.isfinite(speed_mps) or speed_mps <= 0:
        raise InputError(None, "speed_mps", f"expected a speed > 0 m/s, got {speed_mps}")
    if not 0 < side_overlap < 1:
        raise InputError(None, "side_overlap",
                         f"expected a fraction strictly between 0 and 1, got {side_overlap}")
    if not 0 < half_fov_rad < np.radians(80):
        raise InputError(None, "fov", "expected a half field of view in (0, 80) deg, got "
                         f"{np.degrees(half_fov_rad):.3g} deg")
    if directions not in DIRECTIONS:
        raise InputError(None, "directions",
                         f"expected one of {', '.join(DIRECTIONS)}, got {directions!r}")


def plan_lines(extent: tuple[float, float, float, float], ground_m: float, height_agl_m: float,
               half_fov_rad: float, side_overlap: float, directions: str,
               speed_mps: float = 1.0) -> list[FlightLine]:
    """North–south lines covering ``extent`` (xmin, xmax, ymin, ymax, m) with the given side
    overlap.

    ``ground_m``: mean terrain height (ENU z); lines fly at ground + height_agl. ``same``: every
    line northbound; ``opposite``: alternate directions; ``cross``: ``opposite`` plus two
    east–west lines through the middle flown in opposite directions.
    """
    check_plan_inputs(height_agl_m, speed_mps, side_overlap, half_fov_rad, directions)
    xmin, xmax, ymin, ymax = extent
    swath = 2 * height_agl_m * np.tan(half_fov_rad)
    spacing = swath * (1 - side_overlap)
    usable = (xmax - xmin) - swath  # line centres keep the whole swath inside the scene
    if usable < 0:
        raise InputError(None, "height_agl_m",
                         f"swath {swath:.0f} m is wider than the scene ({xmax - xmin:.0f} m)")
    n = int(np.floor(usable / spacing)) + 1
    xs = (xmin + xmax) / 2 + (np.arange(n) - (n - 1) / 2) * spacing
    alt = ground_m + height_agl_m
    margin = 0.05 * (ymax - ymin)
    lines = []
    for k, x in enumerate(xs):
        a, b = np.array([x, ymin + margin]), np.array([x, ymax - margin])
        if directions != "same" and k % 2 == 1:
            a, b = b, a
        lines.append(FlightLine(k + 1, a, b, alt))
    if directions == "cross":
        xm = 0.05 * (xmax - xmin)
        ym = (ymin + ymax) / 2
        for k, sgn in enumerate((1, -1)):
            y = ym + sgn * spacing / 4
            a, b = np.array([xmin + xm, y]), np.array([xmax - xm, y])
            lines.append(FlightLine(n + k + 1, a if sgn > 0 else b, b if sgn > 0 else a, alt))
    return lines
