"""The configuration of ``calidar accuracy`` as one typed value, and its TOML file
(``config.toml`` beside accuracy.json; ``--config`` repeats the run)::

    radius_m = 5.0             # ground points within this of a checkpoint form its TIN
    max_edge_m = 5.0           # longest edge of the triangle holding a checkpoint
                               # (absent: radius_m)
    survey_sigma_m = 0.02      # the checkpoints' survey RMSE (absent: the file's sigma column)
    target_class_cm = 10.0     # the vertical accuracy class the contract asks for (absent: none)
    classes = [2]              # LAS classes taken as ground (absent: 2, else last returns)
    swaths = false             # also the USGS swath checks
    checkpoints_crs = "EPSG:6340"

    [inputs]                   # crs, time_system, geoid_undulation_m: how the points are read

>>> import tempfile
>>> config = AccuracyConfig(AccuracySettings(radius_m=3.0, classes=(2,)))
>>> AccuracyConfig.read(config.write(Path(tempfile.mkdtemp()) / "config.toml")) == config
True
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from calidar.io.las import PointOptions
from calidar.pipelines.accuracy import AccuracySettings
from calidar.pipelines.config_file import FileConfig, Key, crs_decoder, point_keys


@dataclass(frozen=True)
class AccuracyConfig(FileConfig):
    """What ``calidar accuracy`` takes besides its files: the assessment's settings and how the
    points are read."""

    KEYS = (Key("radius_m", "settings.radius_m", "--radius"),
            Key("max_edge_m", "settings.max_edge_m", "--max-edge"),
            Key("survey_sigma_m", "settings.survey_sigma_m", "--survey-sigma"),
            Key("target_class_cm", "settings.target_class_cm", "--class"),
            Key("classes", "settings.classes", "--classes"),
            Key("swaths", "settings.swaths", "--swaths"),
            Key("checkpoints_crs", "settings.checkpoints_crs", "--checkpoints-crs",
                decode=crs_decoder("--checkpoints-crs")), *point_keys())
    COMMAND = "accuracy"

    settings: AccuracySettings = field(default_factory=AccuracySettings)
    points: PointOptions = field(default_factory=PointOptions)

    def check(self) -> None:
        """The settings in their ranges."""
        from calidar.validate import integer

        self.settings.checked()
        for c in self.settings.classes or ():
            integer(c, "--classes", 0, 255)
