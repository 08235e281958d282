"""Plausibility of the geometry that georeferencing assumes (issue 27): points seen from the
trajectory must lie below it, within a scanner's field of view, at across-track angles that
match the file's scan-angle field; and their heights must agree with what those scan angles
imply (a vertical-datum check, issue 26).

A sample of each chunk (:data:`SAMPLE_POINTS` points evenly spread) is compared with the
trajectory in the local level frame of the sensor (north, east, down; the across-track axis
from the heading): d = point − sensor, ``down`` its vertical component (the sensor's height
above the point), ``across`` its horizontal component to the right of the heading. Gross
failures (wrong CRS or UTM zone, wrong trajectory, wrong time system) raise one
:class:`calidar.errors.InputError` naming the likely cause; the vertical offset is a warning.

Vertical offset: with the file's scan angle θ (LAS: from nadir, aircraft roll included; positive
right) the points' across-track offsets satisfy across = (down + δ) tan(θ + r), r a constant roll
or boresight bias; linearized, across − down tanθ = δ tanθ + r down sec²θ, solved by least
squares over the sample (points with 5° ≤ |θ| ≤ 60°, the outermost degree left out: a
whole-degree bin at the edge of the field of view holds half a bin), each row divided by
down·sec²θ (an error in θ moves across by that much; equal weights would understate σ). δ ≠ 0
means the heights are δ m too high for the angles: e.g. heights above a geoid taken as
ellipsoidal (δ = −N). With LAS 1.2's whole-degree scan angles each point's δ scatters by ~0.25 %
of the height; hundreds of points bring the estimate's σ below a metre.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calidar import frames
from calidar.errors import InputError

SAMPLE_POINTS = 1000  #: points of each chunk checked
MAX_OFF_NADIR_DEG = 75.0  #: a median look angle beyond this is no airborne scan
#: median along-track offset over height beyond this (31°): no scanner looks so far ahead
MAX_ALONG_TRACK = 0.6
#: median | |computed| − |file's| | across-track angle beyond this: wrong geometry
MAX_SCAN_ANGLE_MISMATCH_DEG = 10.0
MIN_VERTICAL_WARNING_M = 5.0  #: |δ| below this is not reported
CAUSES = ("wrong CRS or UTM zone (--crs), wrong trajectory or its CRS (--trajectory-crs), or wrong "
          "time system (--time-system)")


def sample_rows(n: int, k: int = SAMPLE_POINTS) -> np.ndarray:
    """At most ``k`` row numbers evenly spread over ``n`` rows."""
    return np.arange(n) if n <= k else np.linspace(0, n - 1, k).astype(np.int64)


def local_geometry(traj, t: np.ndarray,
                   ecef: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(down, across, along) m of points (N, 3) ECEF at times t seen from the trajectory: the
    sensor's height above each point, the horizontal offset right of and along its heading."""
    pos, _ = traj.interpolate(t)
    _, _, heading = traj.interpolate_rpy(t)
    lat, lon, _ = frames.ecef_to_geodetic(pos)
    ned = np.einsum("nji,nj->ni", frames.r_en(lat, lon), ecef - pos)  # R_en^T d
    ch, sh = np.cos(heading), np.sin(heading)
    along = ch * ned[:, 0] + sh * ned[:, 1]
    across = -sh * ned[:, 0] + ch * ned[:, 1]
    return ned[:, 2], across, along


def traj_speed(traj, t: np.ndarray) -> float:
    """The trajectory's median ground speed (m/s) over the times ``t``."""
    i = np.clip(np.searchsorted(traj.time, t), 1, traj.time.size - 1)
    moved = np.linalg.norm(traj.ecef[i] - traj.ecef[i - 1], axis=1)
    return float(np.median(moved / (traj.time[i] - traj.time[i - 1])))


@dataclass
class GeometryCheck:
    """Samples of a file's points against a trajectory, chunk by chunk (:meth:`add`), and the
    vertical offset their scan angles imply over the whole file (:meth:`vertical_offset`)."""

    source: object  #: the points' file (for messages)
    #: (down, across, scan angle deg) samples with scan angles
    rows: list = field(default_factory=list)
    seen: int = 0  #: points of the chunks added so far (the next chunk's first point)
    #: what the points are, for messages (default: "points i–j" of the file)
    label: str | None = None

    def add(self, traj, t: np.ndarray, ecef: np.ndarray, scan_angle_deg: np.ndarray | None,
            size: int | None = None) -> None:
        """Check a sample of the file's next chunk (``size`` points when the arrays are already a
        sample of it); raise when its geometry is impossible."""
        first, self.seen = self.seen, self.seen + (t.size if size is None else size)
        if t.size == 0:
            return
        k = sample_rows(t.size)
        ok = np.isfinite(t[k])
        k = k[ok]
        if k.size == 0:
            return
        down, across, along = local_geometry(traj, t[k], ecef[k])
        where = self.label or f"points {first}–{self.seen - 1}"
        self._check_position(where, down, across, along, lambda: traj_speed(traj, t[k]))
        if scan_angle_deg is None:
            return
        theta = np.asarray(scan_angle_deg, float)[k]
        if not np.any(theta):
            return  # a file without scan angles (all 0)
        computed = np.degrees(np.arctan2(across, down))
        miss = float(np.median(np.abs(np.abs(computed) - np.abs(theta))))
        if miss > MAX_SCAN_ANGLE_MISMATCH_DEG:
            raise InputError(self.source, "scan_angle", f"{where}: the across-track angles from "
                             f"the trajectory ({np.min(computed):.1f}…{np.max(computed):.1f}°) "
                             "differ from the file's scan angles "
                             f"({theta.min():.1f}…{theta.max():.1f}°) by a median {miss:.1f}°; "
                             f"expected them to agree: {CAUSES}, or heights in another vertical "
                             "datum (--crs, --geoid-undulation)")
        self.rows.append(np.stack([down, across, theta], axis=1))

    def _check_position(self, where: str, down, across, along, speed) -> None:
        """Raise when the sample lies above the sensor, too far off nadir or too far ahead of or
        behind it (``speed()``: the aircraft's, m/s, to state the time offset that would explain
        it)."""
        height = float(np.median(down))
        if height <= 0:
            raise InputError(self.source, "z", f"{where}: the points lie a median {-height:.0f} m "
                             "above the trajectory at their times; expected them below the sensor: "
                             f"{CAUSES}")
        look = np.degrees(np.arctan2(np.hypot(across, along), down))
        if float(np.median(look)) > MAX_OFF_NADIR_DEG:
            ahead, side = float(np.median(along)), float(np.median(np.abs(across)))
            causes = CAUSES
            if abs(ahead) > 3 * side:
                offset = ahead / max(speed(), 1e-3)
                causes = (f"a time offset ({offset:+.1f} s at the aircraft's speed: wrong time "
                          "system, UTC against GPS time?), or " + CAUSES)
            distance = np.median(np.hypot(across, along))
            raise InputError(self.source, "xyz", f"{where}: the points lie a median {distance:.0f} "
                             f"m sideways from the trajectory at their times ({ahead:+.0f} m along "
                             f"its heading, {side:.0f} m across), {height:.0f} m below it (look "
                             f"angle {np.median(look):.1f}° from nadir, expected below "
                             f"{MAX_OFF_NADIR_DEG:g}°): {causes}")
        ahead = float(np.median(along))
        if abs(ahead) > MAX_ALONG_TRACK * height:
            side = "ahead of" if ahead > 0 else "behind"
            raise InputError(self.source, "gps_time", f"{where}: the points lie a median "
                             f"{abs(ahead):.0f} m {side} the sensor at their times, {height:.0f} m "
                             f"below it (expected within {MAX_ALONG_TRACK:g}× the height): a time "
                             f"offset of about {ahead / max(speed(), 1e-3):+.1f} s (wrong time "
                             f"system, UTC against GPS time?), or {CAUSES}")

    def vertical_offset(self) -> tuple[float, float, float] | None:
        """(δ m, its σ m, median sensor height above the points m) from the scan angles, or None
        when too few points have usable angles (see the module's docstring)."""
        if not self.rows:
            return None
        down, across, theta = np.concatenate(self.rows).T
        # the outermost degree left out: whole-degree angles there are biased inwards
        edge = np.abs(theta).max() - 1.0
        use = (np.abs(theta) >= 5.0) & (np.abs(theta) <= min(60.0, edge))
        if np.count_nonzero(use) < 30 or np.unique(np.sign(theta[use])).size < 2:
            return None
        if np.median(np.sign(across[use]) * np.sign(theta[use])) < 0:
            theta = -theta  # a file whose scan angles are positive to the left
        down, across, tan = down[use], across[use], np.tan(np.radians(theta[use]))
        # an angle error ε moves across by down·sec²θ·ε: rows in angle units
        w = 1.0 / (down * (1 + tan**2))
        a = np.stack([tan, down * (1 + tan**2)], axis=1) * w[:, None]
        b = (across - down * tan) * w
        keep = np.ones(b.size, bool)
        for _ in range(3):  # trimmed least squares: points beyond 3 robust σ left out
            x, *_ = np.linalg.lstsq(a[keep], b[keep], rcond=None)
            r = b - a @ x
            s = 1.4826 * np.median(np.abs(r[keep])) + 1e-9
            keep = np.abs(r) <= 3 * s
        cov = np.linalg.pinv(a[keep].T @ a[keep]) * float(np.mean(r[keep] ** 2))
        return float(x[0]), float(np.sqrt(cov[0, 0])), float(np.median(down))

    def vertical_warning(self, reference: str) -> str | None:
        """A warning when the heights disagree with the scan angles by more than
        :data:`MIN_VERTICAL_WARNING_M` and 5σ; ``reference``: the vertical reference used."""
        est = self.vertical_offset()
        if est is None:
            return None
        delta, sigma, height = est
        if abs(delta) < max(MIN_VERTICAL_WARNING_M, 5 * sigma, 0.005 * height):
            return None
        ranges = "shorter" if delta > 0 else "longer"
        return (f"{self.source}: the heights are {delta:+.1f} ± {sigma:.1f} m off what the file's "
                f"scan angles imply (sensor {height:.0f} m above the points; ranges {ranges} than "
                f"the scan angles imply): a vertical-datum mismatch? Heights were taken as "
                f"{reference}")


def heights_notes(crs, geoid_undulation_m: float | None, check=None,
                  relative: bool = False) -> list[str]:
    """What a command tells about heights (issue 26): the vertical reference it used, the warning
    for a CRS without a vertical part unless the scan angles of every file (``check``: a
    :class:`GeometryCheck` or a list of them) confirm the heights, and the vertical-offset warning
    of each file whose heights they contradict. ``relative``: the command compares strips with
    each other only (a datum offset common to all does not change its results): the statement
    alone."""
    from calidar.crs import vertical_reference

    if crs is None:
        return []
    reference, warning = vertical_reference(crs, geoid_undulation_m)
    if relative:
        common = ("; an offset of the datum common to every strip does not change the differences"
                  if warning else "")
        return [f"heights: {reference}{common}"]
    checks = [] if check is None else check if isinstance(check, list) else [check]
    estimates = [c.vertical_offset() for c in checks]
    offsets = [w for w in (c.vertical_warning(reference) for c in checks) if w]
    if warning and checks and all(e is not None for e in estimates) and not offsets:
        worst = max(estimates, key=lambda e: abs(e[0]))
        what = "the file's" if len(checks) == 1 else f"all {len(checks)} files'"
        return [f"heights: {reference}, confirmed by {what} scan angles (the heights agree with "
                f"them to {worst[0]:+.1f} ± {worst[1]:.1f} m)"]
    return [f"heights: {warning or reference}", *offsets]
