"""GPS time systems of LAS files: GPS week seconds and adjusted standard GPS time (GPS time −
1e9 s, LAS 1.2+ with global-encoding bit 0 set), and the conversions between them
(docs/conventions.md, "Time systems")."""

from __future__ import annotations

import numpy as np

from calidar.errors import InputError
from calidar.trajectory import SECONDS_PER_WEEK

ADJUSTED_STANDARD_OFFSET_S = 1e9  #: adjusted standard GPS time = GPS time − 1e9 s


def single_gps_week(t_min_adjusted_s: float, t_max_adjusted_s: float, source=None) -> int:
    """The GPS week holding adjusted standard GPS times from ``t_min`` to ``t_max`` (s); an error
    naming both weeks when they differ (week seconds would jump back to 0 at the boundary)."""
    w0, w1 = (int(np.floor((t + ADJUSTED_STANDARD_OFFSET_S) / SECONDS_PER_WEEK))
              for t in (t_min_adjusted_s, t_max_adjusted_s))
    if w0 != w1:
        span = f"{t_min_adjusted_s:.3f}–{t_max_adjusted_s:.3f} s"
        raise InputError(source, "gps_time",
                         f"adjusted standard GPS times {span} span GPS weeks {w0}–{w1}; expected "
                         "one week (split the file at the week boundary)")
    return w0


def adjusted_standard_in_week(t_adjusted_s, gps_week: int) -> np.ndarray:
    """Adjusted standard GPS times (s) → seconds since the start of GPS week ``gps_week``."""
    week_start = gps_week * SECONDS_PER_WEEK - ADJUSTED_STANDARD_OFFSET_S  # a whole number of s
    return np.asarray(t_adjusted_s, float) - week_start


def adjusted_standard_to_week_seconds(t_adjusted_s, source=None) -> tuple[np.ndarray, int]:
    """Adjusted standard GPS times (s) → (GPS week seconds, GPS week number).

    The week comes from the times themselves; times spanning a week boundary are an error
    (:func:`single_gps_week`). For a file read in chunks, take the week of the whole file
    (``calidar.cli.georef.check_coverage`` streams it) and convert each chunk with
    :func:`adjusted_standard_in_week`.
    """
    t = np.asarray(t_adjusted_s, float)
    finite = t[np.isfinite(t)]
    if finite.size == 0:
        return t, 0
    week = single_gps_week(float(finite.min()), float(finite.max()), source)
    return adjusted_standard_in_week(t, week), week


def week_seconds_to_adjusted_standard(t_week_s, gps_week: int) -> np.ndarray:
    """GPS week seconds of ``gps_week`` → adjusted standard GPS time (s)."""
    return np.asarray(t_week_s, float) + gps_week * SECONDS_PER_WEEK - ADJUSTED_STANDARD_OFFSET_S
