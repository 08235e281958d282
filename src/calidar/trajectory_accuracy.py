"""How accurate a GNSS/INS trajectory is, epoch by epoch: the σ of its position and attitude.

Post-processing software states it beside every trajectory (POSPac's ``smrmsg`` file beside
the SBET, read by :mod:`calidar.io.smrmsg`; σ columns of text exports). The strip calibrator
takes these σ as the priors of its trajectory corrections (time-varying, per axis: heading is
often known ten times worse than roll and pitch). Without any such source the calibrator starts
from a documented default for a survey-grade GNSS/INS (:data:`SURVEY_GRADE`) and estimates the
level from the overlaps (:mod:`calidar.strips.trajectory_level`), keeping the default only where
the data cannot tell, and the run says which.

σ are standard deviations in SI: position north/east/down (m), attitude roll/pitch/heading (rad).

>>> acc = TrajectoryAccuracy.uniform(0.03, np.radians(0.002), source="--trajectory-sigma")
>>> pos, att = acc.at(np.array([1000.0]))
>>> float(pos[0, 2]), round(float(np.degrees(att[0, 2])), 4)
(0.03, 0.002)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calidar.errors import InputError

#: names of the position (m) and attitude (rad) σ columns, in order
POSITION_FIELDS = ("north_rms", "east_rms", "down_rms")
ATTITUDE_FIELDS = ("roll_rms", "pitch_rms", "heading_rms")
#: a larger position σ is no GNSS/INS solution a calibration can use (or a unit error)
MAX_POSITION_SIGMA_M = 100.0
MAX_ATTITUDE_SIGMA_RAD = float(np.radians(10.0))  #: likewise for attitude


@dataclass(frozen=True, eq=False)
class TrajectoryAccuracy:
    """σ of a trajectory per epoch (see the module docstring)."""

    time: np.ndarray  #: (N,) GPS s, strictly increasing
    position_m: np.ndarray  #: (N, 3) σ north, east, down, m
    attitude_rad: np.ndarray  #: (N, 3) σ roll, pitch, heading, rad
    velocity_mps: np.ndarray | None = None  #: (N, 3) σ north, east, down velocity, m/s (smrmsg)
    source: str = "<memory>"
    constant: bool = False  #: one σ for all times (no coverage to check)

    def __post_init__(self):
        t = np.atleast_1d(np.asarray(self.time, float))
        object.__setattr__(self, "time", t)
        position = self._sigmas("position_m", "m", MAX_POSITION_SIGMA_M)
        object.__setattr__(self, "position_m", position)
        attitude = self._sigmas("attitude_rad", "rad", MAX_ATTITUDE_SIGMA_RAD)
        object.__setattr__(self, "attitude_rad", attitude)
        if not np.all(np.isfinite(t)):
            message = f"expected finite times, {int(np.sum(~np.isfinite(t)))} are NaN/inf"
            raise InputError(self.source, "time", message)
        if t.size > 1 and np.any(np.diff(t) <= 0):
            i = int(np.flatnonzero(np.diff(t) <= 0)[0])
            raise InputError(self.source, "time", "expected strictly increasing times, record "
                             f"{i + 1} ({t[i + 1]:.3f} s) follows {t[i]:.3f} s")

    def _sigmas(self, name: str, unit: str, hi: float) -> np.ndarray:
        """The field ``name`` as (N, 3) σ, each finite and in (0, hi] ``unit``, else a clear
        error."""
        fields = POSITION_FIELDS if name == "position_m" else ATTITUDE_FIELDS
        a = np.asarray(getattr(self, name), float).reshape(-1, 3)
        if a.shape[0] != self.time.size:
            raise InputError(self.source, name,
                             f"expected {self.time.size} rows of 3 σ, got {a.shape[0]}")
        bad = ~(np.isfinite(a) & (a > 0) & (a <= hi))
        if bad.any():
            i, j = np.argwhere(bad)[0]
            count = int(bad[:, j].sum())
            raise InputError(self.source, fields[j], f"expected σ in (0, {hi:.4g}] {unit}, record "
                             f"{i} has {float(a[i, j]):g} {unit} ({count} such records)")
        return a

    @classmethod
    def uniform_ned(cls, position_m, attitude_rad, source: str) -> "TrajectoryAccuracy":
        """One σ for all times: position (north, east, down) m and attitude (roll, pitch,
        heading) rad."""
        return cls(np.zeros(1), np.broadcast_to(np.asarray(position_m, float), (1, 3)),
                   np.broadcast_to(np.asarray(attitude_rad, float), (1, 3)), None, source, True)

    @classmethod
    def uniform(cls, position_m: float, attitude_rad: float, source: str) -> "TrajectoryAccuracy":
        """The same σ on every axis (m, rad) at all times."""
        return cls.uniform_ned([position_m] * 3, [attitude_rad] * 3, source)

    def __len__(self) -> int:
        return self.time.size

    def at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """σ at times t (s): position (n, 3) m and attitude (n, 3) rad, linear between epochs
        (the first and last epoch's σ held outside them)."""
        t = np.atleast_1d(np.asarray(t, float))
        if self.constant or self.time.size == 1:
            return (np.repeat(self.position_m[:1], t.size, 0),
                    np.repeat(self.attitude_rad[:1], t.size, 0))

        def interp(a):
            return np.stack([np.interp(t, self.time, a[:, k]) for k in range(3)], axis=1)

        return interp(self.position_m), interp(self.attitude_rad)

    def check_covers(self, spans: dict[int, tuple[float, float]], what: str = "strip") -> None:
        """A clear error when the σ do not cover the strips' time spans {id: (t0, t1)} s (one
        epoch's spacing of slack at either end)."""
        if self.constant:
            return
        slack = float(np.median(np.diff(self.time))) if self.time.size > 1 else 0.0
        first, last = self.time[0] - slack, self.time[-1] + slack
        out = {i: s for i, s in spans.items() if s[0] < first or s[1] > last}
        if out:
            t0, t1 = min(s[0] for s in out.values()), max(s[1] for s in out.values())
            ids = ", ".join(map(str, sorted(out)))
            raise InputError(self.source, "time",
                             f"the accuracy file covers {self.time[0]:.3f}–{self.time[-1]:.3f} s, "
                             f"but {len(out)} of {len(spans)} {what}s ({ids}) have times "
                             f"{t0:.3f}–{t1:.3f} s outside it; expected the file that belongs to "
                             "this trajectory")

    def medians(self) -> dict[str, float]:
        """Median σ per field: north/east/down_rms_m, roll/pitch/heading_rms_deg."""
        position = np.median(self.position_m, axis=0)
        attitude = np.degrees(np.median(self.attitude_rad, axis=0))
        out = {f"{f}_m": float(position[k]) for k, f in enumerate(POSITION_FIELDS)}
        out |= {f"{f}_deg": float(attitude[k]) for k, f in enumerate(ATTITUDE_FIELDS)}
        return out

    def describe(self) -> str:
        """One line: median σ in cm and degrees, and where they come from."""
        m = self.medians()
        kind = "" if self.constant else "median "
        position = "/".join(f"{m[f + '_m'] * 100:.1f}" for f in POSITION_FIELDS)
        attitude = "/".join(f"{m[f + '_deg']:.4f}" for f in ATTITUDE_FIELDS)
        return (f"{kind}position σ north/east/down {position} cm, attitude σ "
                f"roll/pitch/heading {attitude}° ({self.source})")

    def to_dict(self) -> dict:
        d = {"source": self.source, "constant": self.constant, "median": self.medians()}
        if not self.constant:
            d |= {"records": len(self), "time_start_s": float(self.time[0]),
                  "time_end_s": float(self.time[-1])}
        return d


#: The start when a trajectory comes without any statement of its accuracy (its level is then
#: estimated from the overlaps; this stays where they cannot tell it): a survey-grade
#: airborne GNSS/INS after post-processing — 5 cm horizontal and 8 cm vertical position,
#: 0.003° roll and pitch, 0.008° heading. That is the order of the post-processed figures
#: survey-grade GNSS/INS makers state, and of the real POSPac smrmsg in the test data
#: (medians 4/4/5 cm, 0.0022° roll and pitch, 0.017° heading); deliberately not optimistic.
SURVEY_GRADE = TrajectoryAccuracy.uniform_ned(
    [0.05, 0.05, 0.08], np.radians([0.003, 0.003, 0.008]),
    "default for a survey-grade GNSS/INS (no accuracy file found)")


def tilt_sigma(attitude_rad: np.ndarray, heading_rad: float) -> np.ndarray:
    """σ (n, 3) of a rotation about local east, north and up from roll/pitch/heading σ (n, 3)
    on a line flown at ``heading_rad`` (from north): roll turns about the direction of flight,
    pitch about the right wing, heading about the vertical (the tilt about "up" gets heading's
    σ)."""
    s, c = math.sin(heading_rad), math.cos(heading_rad)
    roll2, pitch2 = attitude_rad[:, 0] ** 2, attitude_rad[:, 1] ** 2
    east = np.sqrt(roll2 * s * s + pitch2 * c * c)
    north = np.sqrt(roll2 * c * c + pitch2 * s * s)
    return np.stack([east, north, attitude_rad[:, 2]], axis=1)
