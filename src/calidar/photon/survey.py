"""The surveyed CCRs and each CCR's position in a pass's track.

A CCR survey (read by :func:`calidar.io.ccr_survey.read_ccr_survey`) gives geodetic positions or
track positions (m along track, m cross-track left of ONE pass's reported track). A pass's track
is not straight over thousands of km, so each CCR is placed on a straight track line fitted to
the photons within ``local_m`` of the photon nearest to it (over a few km a ground track is
straight to millimetres).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calidar.frames import geodetic_to_ecef
from calidar.io.ccr_survey import CCRSurveyRows
from calidar.photon.track import TrackLine


@dataclass(frozen=True)
class CCRSurvey(CCRSurveyRows):
    """Surveyed CCRs: geodetic (rad) or track (m) positions, and pole heights above ground (m) —
    a survey file's rows (:class:`calidar.io.ccr_survey.CCRSurveyRows`), placed on a pass's track
    by :meth:`in_track`."""

    @classmethod
    def from_rows(cls, rows: CCRSurveyRows) -> CCRSurvey:
        """The survey of a file's rows (:func:`calidar.io.ccr_survey.read_ccr_survey`)."""
        return cls(list(rows.ids), rows.height, rows.lat, rows.lon, rows.x, rows.y, rows.source)

    def in_track(self, x_m: np.ndarray, lat_rad: np.ndarray, lon_rad: np.ndarray,
                 local_m: float = 1000.0,
                 subsample: int = 20) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(along-track x, cross-track y left positive, distance to the nearest photon) of every
        CCR (m) in the track of a pass whose photons are at along-track ``x_m`` and lat/lon (rad).
        The nearest photon is searched on every ``subsample``-th photon (a few m apart)."""
        if self.lat is None:
            return self.x, self.y, np.zeros(len(self.ids))
        step = max(1, int(subsample))
        pts = geodetic_to_ecef(lat_rad[::step], lon_rad[::step], 0.0)
        ccr = geodetic_to_ecef(self.lat, self.lon, 0.0)
        xk, yk, dist = (np.full(len(self.ids), np.nan) for _ in range(3))
        order = np.argsort(x_m, kind="stable") if np.any(np.diff(x_m) < 0) else None
        xs = x_m if order is None else x_m[order]
        for k in range(len(self.ids)):
            d2 = np.einsum("ij,ij->i", pts - ccr[k], pts - ccr[k])
            i = int(np.argmin(d2)) * step
            dist[k] = float(np.sqrt(d2.min()))
            lo, hi = np.searchsorted(xs, [x_m[i] - local_m, x_m[i] + local_m])
            near = slice(lo, hi) if order is None else order[lo:hi]
            if hi - lo < 10:
                continue
            line = TrackLine.fit(x_m[near], lat_rad[near], lon_rad[near])
            a, b = line.to_track(self.lat[k:k + 1], self.lon[k:k + 1])
            xk[k], yk[k] = a[0], b[0]
        return xk, yk, dist
