"""The configuration of a per-point uncertainty run (``calidar tpu``) as one typed value, and its
TOML file: written beside the results (``config.toml``) and given again with ``--config`` to repeat
the run. In SI units, as the run used them to the last digit::

    trajectory_sigma = [0.05, 8.726646259971648e-05]   # position m, attitude rad
                                                       # (absent: the accuracy file's)

    [noise]                    # calidar.tpu.propagate.TpuSettings
    range_sigma_m = 0.01
    angle_sigma_rad = 3.490658503988659e-05
    beam_divergence_rad = 0.00025
    normal_cell_m = 2.0

    [inputs]                   # crs, time_system, geoid_undulation_m (the points), trajectory_crs,
                               # trajectory_angles, trajectory_heading, trajectory_columns
                               # (a text trajectory)

A key left out takes its default; an unknown key or a value of the wrong type or range is an error
naming the file and the key.

>>> import tempfile
>>> from calidar.tpu.propagate import TpuSettings
>>> config = TpuConfig(TpuSettings(range_sigma_m=0.02), trajectory_sigma=(0.05, 1e-4))
>>> TpuConfig.read(config.write(Path(tempfile.mkdtemp()) / "config.toml")) == config
True
>>> try:
...     TpuConfig(TpuSettings(range_sigma_m=-0.01))
... except InputError as e:
...     print(e)
noise.range_sigma_m (--range-sigma): expected a finite number in [0, 10] m, got -0.01
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from calidar.errors import InputError
from calidar.io.las import PointOptions
from calidar.pipelines.config_file import FileConfig, Key, trajectory_keys, point_keys
from calidar.pipelines.inputs import TrajectoryOptions
from calidar.tpu.propagate import TpuSettings
from calidar.trajectory_accuracy import MAX_ATTITUDE_SIGMA_RAD, MAX_POSITION_SIGMA_M
from calidar.validate import number

#: [noise] keys → (option, the option's unit, its factor to SI, low, high in the option's unit)
NOISE_RANGES = {"range_sigma_m": ("--range-sigma", "m", 1.0, 0.0, 10.0),
                "angle_sigma_rad": ("--angle-sigma", "deg", math.pi / 180.0, 0.0, 5.0),
                "beam_divergence_rad": ("--beam-divergence", "mrad", 1e-3, 0.0, 50.0),
                "normal_cell_m": (None, "m", 1.0, 0.01, 1000.0)}
#: TrajectoryOptions' fields with their choices
CHOICES = {"angles": ("deg", "rad"), "heading": ("true", "grid")}


@dataclass(frozen=True)
class TpuConfig(FileConfig):
    """What ``calidar tpu`` takes besides its files: the sensor's noise (SI), one trajectory σ for
    every epoch (position m, attitude rad; None: the trajectory's accuracy file), how the points and
    a text trajectory are read; every value checked when made.

    >>> TpuConfig(trajectory_sigma=(0.05, 1e-4)).to_dict()["trajectory_sigma"]
    [0.05, 0.0001]
    """

    KEYS = (Key("trajectory_sigma", "trajectory_sigma", "--trajectory-sigma"),
            *(Key(f"noise.{k}", f"noise.{k}", option)
              for k, (option, *_) in NOISE_RANGES.items()),
            *point_keys("points"), *trajectory_keys("trajectory_input"))
    COMMAND = "tpu"

    noise: TpuSettings = field(default_factory=TpuSettings)
    trajectory_sigma: tuple[float, float] | None = None
    points: PointOptions = field(default_factory=PointOptions)
    trajectory_input: TrajectoryOptions = field(default_factory=TrajectoryOptions)

    def __post_init__(self):
        for key, (option, unit, factor, lo, hi) in NOISE_RANGES.items():
            where = f"noise.{key} ({option})" if option else f"noise.{key}"
            number(getattr(self.noise, key) / factor, None, lo, hi, unit, field=where)
        if self.trajectory_sigma is not None:
            where = "trajectory_sigma (--trajectory-sigma)"
            if len(self.trajectory_sigma) != 2:
                raise InputError(None, where, "expected 2 values (position m, attitude rad), got "
                                 f"{self.trajectory_sigma}")
            position, attitude = self.trajectory_sigma
            number(position, None, 0.0, MAX_POSITION_SIGMA_M, "m", field=where, open_lo=True)
            number(attitude, None, 0.0, MAX_ATTITUDE_SIGMA_RAD, "rad", field=where, open_lo=True)
        for name, choices in CHOICES.items():
            value = getattr(self.trajectory_input, name)
            if value is not None and value not in choices:
                raise InputError(None, f"--trajectory-{name}",
                                 f"expected {' or '.join(choices)}, got {value!r}")
