"""The configuration of ``calidar trajectory`` as one typed value, and its TOML file
(``<name>.config.toml`` beside the trajectory written; ``--config`` repeats the run). SI, as the run
used them::

    rate_hz = 50.0
    points_per_s = 600.0
    knot_s = 0.25
    use_scan_angles = true
    planar_scanner = true
    scan_plane_yaw_rad = 0.0

    [mount_sigma]              # prior σ of calidar.trajrec.mounting.NAMES (--encoder-sigma,
                               # --scan-plane-sigma)
    scan_offset_rad = 0.0017453292519943296
    scan_scale = 0.003
    ...

    [inputs]                   # crs, time_system, geoid_undulation_m: how the points are read

>>> import tempfile
>>> from dataclasses import replace
>>> config = TrajectoryConfig(replace(TrajectorySettings(), rate_hz=10.0))
>>> TrajectoryConfig.read(config.write(Path(tempfile.mkdtemp()) / "config.toml")) == config
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from calidar.errors import InputError
from calidar.io.las import PointOptions
from calidar.pipelines.config_file import FileConfig, Key, point_keys
from calidar.pipelines.trajectory import TrajectorySettings
from calidar.trajrec.mounting import NAMES

#: calidar.trajrec.mounting.NAMES → (TOML key, the option giving it, the option's unit in SI, its
#: largest value)
MOUNT_KEYS = {"scan_offset": ("scan_offset_rad", "--encoder-sigma", math.radians(1.0)),
              "scan_scale": ("scan_scale", "--encoder-sigma", 0.01),
              "scan_plane_yaw": ("scan_plane_yaw_rad", "--scan-plane-sigma", math.radians(1.0)),
              "scan_plane_pitch": ("scan_plane_pitch_rad", "--scan-plane-sigma", math.radians(1.0)),
              "scan_curvature": ("scan_curvature_rad", "--encoder-sigma", math.radians(1.0)),
              "scan_cone": ("scan_cone_rad", "--scan-plane-sigma", math.radians(1.0))}
MOUNT_MAX = 10.0  #: the largest prior σ, in the options' units (deg, %)


@dataclass(frozen=True)
class TrajectoryConfig(FileConfig):
    """What ``calidar trajectory`` takes besides its files: the reconstruction's settings and how
    the points are read."""

    KEYS = (Key("rate_hz", "settings.rate_hz", "--rate"),
            Key("points_per_s", "settings.points_per_s", "--points-per-second"),
            Key("knot_s", "settings.fit.knot_s", "--knot-spacing"),
            Key("use_scan_angles", "settings.fit.use_scan_angles", "--no-scan-angles"),
            Key("planar_scanner", "settings.fit.planar_scanner", "--scanner"),
            Key("scan_plane_yaw_rad", "settings.fit.scan_plane_yaw", "--scan-plane-yaw"),
            *(Key(f"mount_sigma.{key}", f"settings.fit.mount_sigma.{NAMES.index(name)}", option,
                  float)
              for name, (key, option, _) in MOUNT_KEYS.items()),
            *point_keys())
    COMMAND = "trajectory"

    settings: TrajectorySettings = field(default_factory=TrajectorySettings)
    points: PointOptions = field(default_factory=PointOptions)

    def check(self) -> None:
        """Every value in its range (an error naming the option)."""
        from calidar.validate import number

        s = self.settings
        number(s.rate_hz, "--rate", 0.1, 1000.0, "Hz")
        number(s.points_per_s, "--points-per-second", 10.0, 1e6, "1/s")
        number(s.fit.knot_s, "--knot-spacing", 0.02, 10.0, "s")
        number(s.fit.scan_plane_yaw, "--scan-plane-yaw", -math.pi / 2, math.pi / 2, "rad")
        if len(s.fit.mount_sigma) != len(NAMES):
            raise InputError(None, "--encoder-sigma",
                             f"expected {len(NAMES)} prior σ, got {len(s.fit.mount_sigma)}")
        for name, (_, option, unit) in MOUNT_KEYS.items():
            sigma = s.fit.mount_sigma[NAMES.index(name)]
            number(sigma, option, 0.0, MOUNT_MAX * unit, "" if name == "scan_scale" else "rad")
