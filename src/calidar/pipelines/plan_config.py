"""The configuration of ``calidar plan`` as one typed value, and its TOML file (``config.toml``
beside plan.json; ``--config`` repeats the run). SI, as the run used them::

    pulse_rate_hz = 20000.0
    fov_deg = 70.0
    range_sigma_m = 0.01
    angle_sigma_deg = 0.002
    estimate = ["boresight"]
    trajectory_sigma_m_rad = [0.02, 3.490658503988659e-05]   # position m, attitude rad
    platform_motion_rad = [0.02617993877991494, 0.017453292519943295]   # roll and pitch, heading
    suggest = true
    simulate = 0

    [terrain]                  # kind = "flat" (height_m), "scene" (preset, seed) or "dem" (path)
    kind = "flat"
    height_m = 0.0

>>> import tempfile
>>> from calidar.pipelines.plan import PlanOptions, TerrainChoice
>>> config = PlanConfig(PlanOptions(TerrainChoice("scene", seed=2), fov_deg=60.0))
>>> PlanConfig.read(config.write(Path(tempfile.mkdtemp()) / "config.toml")) == config
True
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from calidar.errors import InputError
from calidar.pipelines.config_file import FileConfig, Key, text
from calidar.pipelines.plan import PlanOptions, check_estimate, check_numbers, check_terrain
from calidar.strips.config import Estimate


def estimate_of(names: tuple[str, ...]) -> Estimate:
    """The parameters a plan predicts, by name (``trajectory_bias`` refused: a plan always models
    the trajectory)."""
    if "trajectory_bias" in names:
        raise InputError(None, "--estimate", "trajectory_bias is always modelled; expected sensor "
                         "parameters (boresight, lever_arm, range_offset, …)")
    try:
        return Estimate.of(*names)
    except InputError as e:
        raise InputError(None, "--estimate", e.problem) from None


@dataclass(frozen=True)
class PlanConfig(FileConfig):
    """What ``calidar plan`` takes besides its files
    (:class:`calidar.pipelines.plan.PlanOptions`)."""

    KEYS = (*(Key(f"terrain.{k}", f"options.terrain.{k}", "--terrain")
              for k in ("kind", "height_m", "preset", "seed")),
            Key("terrain.path", "options.terrain.path", "--terrain", str | None, encode=text,
                decode=Path),
            Key("pulse_rate_hz", "options.pulse_rate_hz", "--pulse-rate"),
            Key("fov_deg", "options.fov_deg", "--fov"),
            Key("range_sigma_m", "options.range_sigma_m", "--range-sigma"),
            Key("angle_sigma_deg", "options.angle_sigma_deg", "--angle-sigma"),
            Key("estimate", "options.estimate", "--estimate", tuple[str, ...],
                encode=lambda e: e.names(), decode=estimate_of),
            Key("trajectory_sigma_m_rad", "options.trajectory_sigma", "--trajectory-sigma"),
            Key("platform_motion_rad", "options.platform_motion", "--platform-motion"),
            Key("suggest", "options.suggest", "--suggest"),
            Key("simulate", "options.simulate", "--simulate"))
    COMMAND = "plan"

    options: PlanOptions = field(default_factory=PlanOptions)

    def check(self) -> None:
        """Every option in its range, before a file is read (an error naming the option)."""
        check_terrain(self.options.terrain)
        check_numbers(self.options)
        check_estimate(self.options.estimate)
