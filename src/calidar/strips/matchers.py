"""The matchers: how the correspondences between two overlapping strips are found.

A matcher is an object that owns its settings, its matching, the outer loop's stop (how much
the mean correspondence distance may still change, m) and the words the report and the verdict
use for its observations. The calibrator (:mod:`calidar.strips.calibrate`) only calls
:meth:`Matcher.match`; a new kind of correspondence is a new subclass of :class:`Matcher` (a
frozen dataclass), named in :data:`calidar.strips.config.MATCHERS`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from calidar.strips.correspond import Correspondences
from calidar.strips.global_test import SKIPPED_RMS, T_MODEL
from calidar.strips.planes import PlaneSettings, match_pair_planes
from calidar.strips.vgicp import VgicpSettings, match_pair_vgicp


class Matcher:
    """What the calibrator asks of a matcher (frozen, picklable: it travels to Dask workers). A
    subclass declares ``name``, ``label`` and ``sigma0_reading`` (no defaults: each kind says how
    its σ0 is read) and its ``threshold_m`` and :meth:`match`; ``holds_gil`` defaults to False."""

    name: ClassVar[str]  #: how ``--method`` and the outputs name it (solution_<name>.json)
    label: ClassVar[str]  #: its observations in words ("tie planes")
    threshold_m: float  #: the outer loop stops when the mean distance changes by less (m)
    #: how the global test reads the σ0 of its robust rows whose σ are estimated from their points
    #: (:data:`calidar.strips.global_test.T_MODEL` or ``SKIPPED_RMS``; recorded in the solution)
    sigma0_reading: ClassVar[str]
    #: its matching holds the GIL, so in-process runs match pairs in worker processes
    #: (:mod:`calidar.strips.processes`) rather than threads (:mod:`calidar.strips.outer_loop`)
    holds_gil: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        missing = [a for a in ("name", "label", "sigma0_reading") if not hasattr(cls, a)]
        if missing:
            raise TypeError(f"matcher {cls.__name__} does not declare {', '.join(missing)}")

    def match(self, strip_a: int, points_a: np.ndarray, strip_b: int,
              points_b: np.ndarray) -> Correspondences:
        """The correspondences of two strips' overlapping points ((N, 3) local m each)."""
        raise NotImplementedError


@dataclass(frozen=True)
class TiePlanes(Matcher):
    """Tie planes (:func:`calidar.strips.planes.match_pair_planes`): one point-to-plane row per
    small planar patch seen by both strips."""

    name: ClassVar[str] = "planes"
    label: ClassVar[str] = "tie planes"
    #: a plane's σ from its points: Student-t rows of the plane fit's degrees of freedom
    sigma0_reading: ClassVar[str] = T_MODEL
    settings: PlaneSettings = field(default_factory=PlaneSettings)
    threshold_m: float = 2e-4  #: the matching is deterministic: 0.2 mm

    def match(self, strip_a: int, points_a: np.ndarray, strip_b: int,
              points_b: np.ndarray) -> Correspondences:
        return match_pair_planes(strip_a, points_a, strip_b, points_b, self.settings)


@dataclass(frozen=True)
class Vgicp(Matcher):
    """VGICP registration and nearest neighbours (:func:`calidar.strips.vgicp.match_pair_vgicp`)."""

    name: ClassVar[str] = "vgicp"
    label: ClassVar[str] = "VGICP correspondences"
    #: rows right in the mean, not row by row (issue 26, eighth session): the skipped RMS
    sigma0_reading: ClassVar[str] = SKIPPED_RMS
    settings: VgicpSettings = field(default_factory=VgicpSettings)
    #: re-matching alone moves the mean distance by ~0.1 mm, so the tie planes' 0.2 mm would rarely
    #: stop it
    threshold_m: float = 1e-3
    holds_gil: ClassVar[bool] = True  #: small_gicp holds the GIL

    def match(self, strip_a: int, points_a: np.ndarray, strip_b: int,
              points_b: np.ndarray) -> Correspondences:
        return match_pair_vgicp(strip_a, points_a, strip_b, points_b, self.settings)

    def with_unevenness_length(self, length_m: float) -> "Vgicp":
        """The same matcher with the unevenness's ℓ (m) fixed (the survey's pooled fit)."""
        return replace(self, settings=replace(self.settings, unevenness_length_m=length_m))
