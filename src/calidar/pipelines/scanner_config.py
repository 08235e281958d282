"""The configuration of ``calidar scanner analyze`` as one typed value, and its TOML file
(``config.toml`` beside summary.json; ``--config`` repeats the run)::

    model = "palmer"
    range_m = 100.0
    spec_arcsec = 10.0
    axis_angle_deg = 45.0      # and the other design values of
                               # calidar.scanners.settings.AnalysisSettings

    [errors]                   # the structural errors (absent: the published example values)
    eccentricity_ratio = 0.001
    delta_l_deg = 0.01

>>> import tempfile
>>> from calidar.scanners.settings import AnalysisSettings
>>> config = ScannerConfig(AnalysisSettings("palmer", 100.0, {"delta_l": 0.01}))
>>> ScannerConfig.read(config.write(Path(tempfile.mkdtemp()) / "config.toml")) == config
True
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from calidar.pipelines.config_file import FileConfig, Key
from calidar.scanners.settings import AnalysisSettings

#: the settings' fields → their options (calidar.scanners.settings.LIMITS, --model and --points)
SETTINGS_OPTIONS = {"model": "--model", "range_m": "--range", "spec_arcsec": "--spec-arcsec",
                    "phase_deg": "--phase", "axis_tilt_azimuth_deg": "--axis-tilt-azimuth",
                    "grating_radius_mm": "--grating-radius-mm",
                    "fov_deg": "--fov", "points": "--points", "axis_angle_deg": "--axis-angle",
                    "mirror_tilt_deg": "--mirror-tilt", "wedge_angle_deg": "--wedge-angle",
                    "refractive_index": "--refractive-index"}
#: the [errors] keys (name and unit) → (the error's name, its option)
ERROR_KEYS = {"eccentricity_ratio": ("eccentricity", "--eccentricity"),
              "delta_l_deg": ("delta_l", "--delta-l"), "delta_r_deg": ("delta_r", "--delta-r"),
              "wedge_angle_error_deg": ("wedge_angle_error", "--wedge-angle-error"),
              "axis_tilt_deg": ("axis_tilt", "--axis-tilt"),
              "scan_angle_offset_deg": ("scan_angle_offset", "--scan-angle-offset"),
              "scan_angle_scale_ppm": ("scan_angle_scale", "--scan-angle-scale")}


@dataclass(frozen=True)
class ScannerConfig(FileConfig):
    """What ``calidar scanner analyze`` takes: the analysis's settings (model, range, errors,
    design)."""

    KEYS = (*(Key(k, f"settings.{k}", o) for k, o in SETTINGS_OPTIONS.items()),
            *(Key(f"errors.{k}", f"settings.errors.{name}", o, float | None)
              for k, (name, o) in ERROR_KEYS.items()))
    COMMAND = "scanner analyze"

    settings: AnalysisSettings = field(default_factory=lambda: AnalysisSettings("", 0.0))

    def check(self) -> None:
        """Every number in its range, the errors the model's (an error naming the option)."""
        self.settings.checked()
