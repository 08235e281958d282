"""The observations of a total-station range calibration, as read from (and written to) the
file format of :mod:`calidar.io.total_station`: angles in radians, distances in metres, σ SI."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FORMAT_LINE = "calidar-total-station 1"
ARCSEC = math.pi / (180.0 * 3600.0)  #: one arc-second in radians
ANGLE_UNITS = {"deg": math.pi / 180.0, "gon": math.pi / 200.0}  #: unit → radians per unit
FULL_CIRCLE = {"deg": 360.0, "gon": 400.0}
FEATURE_POINTS = ("A", "B", "C", "D")
BASE_COLUMNS = ("setup", "group", "point", "slope_m", "scanner_m")
#: longest slope distance or scanner range read (m); units are checked by magnitude later
MAX_DISTANCE_M = 1e6


@dataclass(frozen=True)
class Setup:
    """A total-station setup: its stated precision (SI) and its observation of P."""

    id: str
    angle_sigma: float  #: σ of one direction or vertical angle (rad)
    distance_sigma_m: float  #: constant part of the slope-distance σ (m)
    distance_sigma_ppm: float  #: distance-proportional part of the slope-distance σ (ppm)
    p_slope: float  #: slope distance O→P (m)
    p_va: float  #: vertical angle O→P (rad, up positive)
    p_hz: float  #: horizontal direction O→P (rad)
    line: int  #: line of the P observation

    def distance_sigma(self, slope_m: np.ndarray) -> np.ndarray:
        """σ (m) of slope distances ``slope_m`` (m): mm + ppm."""
        return self.distance_sigma_m + self.distance_sigma_ppm * 1e-6 * np.asarray(slope_m, float)


@dataclass(frozen=True)
class TotalStationObservations:
    """All targets (feature points A–D and E points), one entry per row, as arrays.

    ``kind`` is "feature" or "E"; ``setup`` indexes ``setups``; angles rad, distances m.
    """

    source: str
    setups: list[Setup]
    scanner_sigma: float  #: σ of one scanner range (m)
    setup: np.ndarray  #: (n,) int
    group: np.ndarray  #: (n,) str, "" for E points
    point: np.ndarray  #: (n,) str
    kind: np.ndarray  #: (n,) "feature" | "E"
    slope: np.ndarray  #: (n,) slope distance O→X (m)
    va: np.ndarray  #: (n,) vertical angle O→X (rad)
    hz: np.ndarray  #: (n,) horizontal direction O→X (rad)
    scanner: np.ndarray  #: (n,) scanner range (m)
    line: np.ndarray  #: (n,) line numbers in the file

    def __len__(self) -> int:
        return int(self.slope.size)

    def subset(self, keep: np.ndarray) -> "TotalStationObservations":
        """The observations with the targets selected by the boolean/int index ``keep``."""
        per_target = ("setup", "group", "point", "kind", "slope", "va", "hz", "scanner", "line")
        arrays = {k: getattr(self, k)[keep] for k in per_target}
        return TotalStationObservations(self.source, self.setups, self.scanner_sigma, **arrays)

    @property
    def groups(self) -> list[str]:
        """Group ids in file order."""
        return list(dict.fromkeys(self.group[self.kind == "feature"]))


#: Limits that keep a calibration's memory and time bounded: the fit's Jacobian holds
#: targets × (2 + 3·setups) numbers and each outlier rejected re-solves it (2 000 targets from
#: 50 setups: 2.4 MB, seconds). A field calibration has tens of targets from a few setups.
MAX_TARGETS = 2_000
MAX_SETUPS = 50
MAX_FILE_BYTES = 64 * 2**20  #: a file within the limits above takes well under 1 MB; comments aside
