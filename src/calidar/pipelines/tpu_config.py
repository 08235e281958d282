"""The configuration of a per-point uncertainty run (``calidar tpu``) as one typed value, and its TOML
file: written beside the results (``config.toml``) and given again with ``--config`` to repeat the run.
In SI units, as the run used them to the last digit::

    trajectory_sigma = [0.05, 8.726646259971648e-05]   # position m, attitude rad (absent: the accuracy file's)

    [noise]                    # calidar.tpu.propagate.TpuSettings
    range_sigma_m = 0.01
    angle_sigma_rad = 3.490658503988659e-05
    beam_divergence_rad = 0.00025
    normal_cell_m = 2.0

    [inputs]                   # crs, time_system, geoid_undulation_m (the points), trajectory_crs,
                               # trajectory_angles, trajectory_heading, trajectory_columns (a text trajectory)

A key left out takes its default; an unknown key or a value of the wrong type or range is an error
naming the file and the key.

>>> import tempfile
>>> from calidar.tpu.propagate import TpuSettings
>>> config = TpuConfig(TpuSettings(range_sigma_m=0.02), trajectory_sigma=(0.05, 1e-4))
>>> TpuConfig.read(config.write(Path(tempfile.mkdtemp()) / "config.toml")) == config
True
>>> TpuConfig(TpuSettings(range_sigma_m=-0.01))
Traceback (most recent call last):
calidar.errors.InputError: noise.range_sigma_m (--range-sigma): expected a finite number in [0, 10] m, got -0.01
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass, field
from pathlib import Path

from calidar.errors import InputError
from calidar.io.las import PointOptions
from calidar.pipelines.config_toml import (build, inputs_table, known, read_document, section, table, typed,
                                           write_document)
from calidar.pipelines.inputs import TrajectoryOptions
from calidar.tpu.propagate import TpuSettings
from calidar.trajectory_accuracy import MAX_ATTITUDE_SIGMA_RAD, MAX_POSITION_SIGMA_M
from calidar.validate import number

#: [noise] keys → (option, the option's unit, its factor to SI, low, high in the option's unit)
NOISE_RANGES = {"range_sigma_m": ("--range-sigma", "m", 1.0, 0.0, 10.0),
                "angle_sigma_rad": ("--angle-sigma", "deg", math.pi / 180.0, 0.0, 5.0),
                "beam_divergence_rad": ("--beam-divergence", "mrad", 1e-3, 0.0, 50.0),
                "normal_cell_m": (None, "m", 1.0, 0.01, 1000.0)}
#: [inputs] keys → (PointOptions | TrajectoryOptions, field)
INPUT_KEYS = {"crs": ("points", "crs"), "time_system": ("points", "time_system"),
              "geoid_undulation_m": ("points", "geoid_undulation_m"), "trajectory_crs": ("trajectory", "crs"),
              "trajectory_angles": ("trajectory", "angles"), "trajectory_heading": ("trajectory", "heading"),
              "trajectory_columns": ("trajectory", "columns")}
CHOICES = {"trajectory_angles": ("deg", "rad"), "trajectory_heading": ("true", "grid")}


@dataclass(frozen=True)
class TpuConfig:
    """What ``calidar tpu`` takes besides its files: the sensor's noise (SI), one trajectory σ for every
    epoch (position m, attitude rad; None: the trajectory's accuracy file), how the points and a text
    trajectory are read; every value checked when made.

    >>> TpuConfig(trajectory_sigma=(0.05, 1e-4)).to_dict()["trajectory_sigma"]
    [0.05, 0.0001]
    """

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
                raise InputError(None, where, f"expected 2 values (position m, attitude rad), got {self.trajectory_sigma}")
            number(self.trajectory_sigma[0], None, 0.0, MAX_POSITION_SIGMA_M, "m", field=where, open_lo=True)
            number(self.trajectory_sigma[1], None, 0.0, MAX_ATTITUDE_SIGMA_RAD, "rad", field=where, open_lo=True)
        for key, choices in CHOICES.items():
            value = getattr(self.trajectory_input, INPUT_KEYS[key][1])
            if value is not None and value not in choices:
                raise InputError(None, key, f"expected {' or '.join(choices)}, got {value!r}")

    def to_dict(self) -> dict:
        """The TOML file's document (SI; None values left out)."""
        doc: dict = {} if self.trajectory_sigma is None else {"trajectory_sigma": list(self.trajectory_sigma)}
        doc["noise"] = {k: getattr(self.noise, k) for k in NOISE_RANGES}
        owners = {"points": self.points, "trajectory": self.trajectory_input}
        doc["inputs"] = inputs_table(owners, INPUT_KEYS)
        return doc

    def write(self, path: Path) -> Path:
        """Write the TOML file (atomically); returns its path."""
        return write_document(path, self.to_dict(), "calidar tpu configuration: give it again with --config "
                              "to repeat the run")

    @classmethod
    def read(cls, path: Path) -> TpuConfig:
        """The configuration of a TOML file (keys left out: their defaults)."""
        from calidar.sensor import validated_crs

        path = Path(path)
        doc = read_document(path)
        known(doc, {"trajectory_sigma", "noise", "inputs"}, path)
        sigma = typed(doc.get("trajectory_sigma"), tuple[float, float] | None, path, "trajectory_sigma")
        noise = section(TpuSettings, table(doc, "noise", path), path, "noise")
        inputs = table(doc, "inputs", path)
        known(inputs, set(INPUT_KEYS), path, "inputs.")
        parts: dict[str, dict] = {"points": {}, "trajectory": {}}
        hints = {"points": typing.get_type_hints(PointOptions), "trajectory": typing.get_type_hints(TrajectoryOptions)}
        for k, v in inputs.items():
            owner, name = INPUT_KEYS[k]
            parts[owner][name] = typed(v, str | None if name == "crs" else hints[owner][name], path, f"inputs.{k}")
            if k.endswith("crs"):
                validated_crs(v, str(path), f"inputs.{k}")
        points = build(path, "inputs", lambda: PointOptions(**parts["points"]))
        trajectory = build(path, "inputs", lambda: TrajectoryOptions(**parts["trajectory"]))
        return build(path, "", lambda: cls(noise, sigma, points, trajectory))
