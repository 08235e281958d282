"""The typed configurations of ``calidar range-cal``, ``ccr`` and ``tpu`` (issue 29): each is checked
when made, written as the TOML file a user keeps and read back equal; a bad value in the file names the
file and the key; options on the command line replace the file's settings."""

from __future__ import annotations

import math

import pytest

from calidar.errors import InputError
from calidar.photon.passes import SystemParameters
from calidar.photon.search import SearchSettings
from calidar.pipelines.ccr_config import CCRConfig
from calidar.pipelines.inputs import PointOptions, TrajectoryOptions
from calidar.pipelines.rangecal_config import RangeCalConfig
from calidar.pipelines.tpu_config import TpuConfig
from calidar.tpu.propagate import TpuSettings

CONFIGS = [
    RangeCalConfig(), RangeCalConfig(tolerance_m=0.05, fix_scale=True),
    CCRConfig(), CCRConfig(("gt1l", "gt3r"), SearchSettings(8.5, 14.0, bootstrap=7, seed=3, shared_bias=True),
                           SystemParameters(dead_time=3.3 * 1e-9, channels=4, pointing_jitter=0.1)),
    TpuConfig(), TpuConfig(TpuSettings(0.02, math.radians(0.003), 0.3 * 1e-3, 1.5), (0.04, math.radians(0.004)),
                           PointOptions("EPSG:32632", "week", 47.3), TrajectoryOptions("EPSG:32632", "rad", "grid",
                                                                                       ("time", "x", "y"))),
]


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: type(c).__name__)
def test_a_configuration_reads_back_equal_from_its_file(config, tmp_path):
    path = config.write(tmp_path / "config.toml")
    assert type(config).read(path) == config
    assert path.read_text().startswith(f"# calidar ")


BAD = [
    (RangeCalConfig, "tolerance_m = 0.0\n", "tolerance_m (--tolerance): expected a finite number in (0, 10] m, got 0.0"),
    (RangeCalConfig, "tolerance_m = nan\n", "tolerance_m (--tolerance)"),
    (RangeCalConfig, 'tolerance_m = "5 cm"\n', "tolerance_m: expected float, got '5 cm'"),
    (RangeCalConfig, "fix_scale = 1\n", "fix_scale: expected bool, got 1"),
    (RangeCalConfig, "[acceptance]\ntolerance_m = 0.05\n", "acceptance: unknown key; expected one of fix_scale, "
                                                           "tolerance_m"),
    (CCRConfig, "[search]\nbootstrap = 1.5\n", "search.bootstrap: expected int, got 1.5"),
    (CCRConfig, "[search]\nbootstrap = -1\n", "search.bootstrap (--bootstrap): expected an integer in [0, 10000]"),
    (CCRConfig, "[search]\nmax_bias = 1e9\n", "search.max_bias (--max-bias): expected a finite number in [0.5, 200]"),
    (CCRConfig, "[search]\ndiameter_min = 20.0\n", "diameter_min, diameter_max (--diameter-range): expected MIN < MAX"),
    (CCRConfig, "[search]\nwobble = 1\n", "search.wobble: unknown key"),
    (CCRConfig, "[system]\nchannels = 0\n", "system.channels (--channels): expected an integer in [1, 64], got 0"),
    (CCRConfig, "[system]\ndead_time_s = 3.2\n", "system.dead_time_s (--dead-time-ns): expected a finite number in "
                                                  "[0.1, 100] ns"),
    (CCRConfig, 'beams = ["gt1l", "gt1l"]\n', "beams (--beam): expected all, or one or more of"),
    (CCRConfig, "beams = 3\n", "beams: expected a list of one or more values, got 3"),
    (CCRConfig, "system = 3\n", "system: expected a table [system], got 3"),
    (TpuConfig, "[noise]\nangle_sigma_rad = 1.0\n", "noise.angle_sigma_rad (--angle-sigma): expected a finite number "
                                                    "in [0, 5] deg"),
    (TpuConfig, "[noise]\nbeam_divergence_rad = -1e-3\n", "noise.beam_divergence_rad (--beam-divergence)"),
    (TpuConfig, "[noise]\nnormal_cell_m = 0.0\n", "noise.normal_cell_m: expected a finite number in [0.01, 1000] m"),
    (TpuConfig, "trajectory_sigma = [0.05, 0.0]\n", "trajectory_sigma (--trajectory-sigma): expected a finite number "
                                                    "in (0,"),
    (TpuConfig, '[inputs]\ntime_system = "utc"\n', "inputs (--time-system): expected one of"),
    (TpuConfig, '[inputs]\ntrajectory_angles = "grad"\n', "trajectory_angles: expected deg or rad, got 'grad'"),
    (TpuConfig, '[inputs]\ntrajectory_columns = "time,x,y"\n', "inputs.trajectory_columns: expected a list"),
    (TpuConfig, "noise = [1]\n", "noise: expected a table [noise]"),
]


@pytest.mark.parametrize("cls, text, message", BAD, ids=[f"{c.__name__}-{t.strip()[:24]}" for c, t, _ in BAD])
def test_a_bad_value_in_the_file_names_the_file_and_the_key(cls, text, message, tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(text)
    with pytest.raises(InputError) as e:
        cls.read(path)
    assert str(e.value).startswith(f"{path}: ") and message in str(e.value), str(e.value)
    assert "\n" not in str(e.value)


def test_options_given_replace_the_files_settings(tmp_path):
    from calidar.cli.ccr import ccr_config
    from calidar.cli.rangecal import range_cal_config
    from calidar.cli.tpu import tpu_config

    path = RangeCalConfig(tolerance_m=0.05, fix_scale=True).write(tmp_path / "rc.toml")
    assert range_cal_config(path, {}) == RangeCalConfig(0.05, True)
    assert range_cal_config(path, {"tolerance": 0.02}) == RangeCalConfig(0.02, True)
    assert range_cal_config(None, {"fix_scale": True}) == RangeCalConfig(None, True)

    path = CCRConfig(("gt1l",), SearchSettings(bootstrap=7, diameter_step=0.2)).write(tmp_path / "ccr.toml")
    cfg = ccr_config(path, {"bootstrap": 0, "diameter_range": "9,14", "dead_time_ns": 3.0})
    assert cfg.beams == ("gt1l",) and cfg.search.diameter_step == 0.2 and cfg.search.bootstrap == 0
    assert (cfg.search.diameter_min, cfg.search.diameter_max, cfg.system.dead_time) == (9.0, 14.0, 3.0 * 1e-9)
    assert ccr_config(path, {"beam": "all"}).beams is None and ccr_config(None, {"beam": "GT2L"}).beams == ("gt2l",)
    with pytest.raises(InputError, match=r"^--diameter-step: expected a finite number in \[0.01, 2\] m, got 0.0"):
        ccr_config(path, {"diameter_step": 0.0})  # an option given: the error names the option

    path = TpuConfig(TpuSettings(range_sigma_m=0.03), (0.05, 1e-4)).write(tmp_path / "tpu.toml")
    cfg = tpu_config(path, {"angle_sigma": 0.004, "crs": "EPSG:32632"})
    assert cfg.noise.range_sigma_m == 0.03 and cfg.trajectory_sigma == (0.05, 1e-4)
    assert cfg.noise.angle_sigma_rad == math.radians(0.004) and str(cfg.points.crs) == "EPSG:32632"
    assert tpu_config(path, {"trajectory_sigma": "0.1,0.01"}).trajectory_sigma == (0.1, math.radians(0.01))
    with pytest.raises(InputError, match=r"noise.range_sigma_m \(--range-sigma\)"):
        tpu_config(None, {"range_sigma": -1.0})


def test_the_command_lines_defaults_are_the_configurations():
    """Without --config and options, each command runs with its configuration's defaults."""
    from calidar.cli.ccr import ccr_config
    from calidar.cli.rangecal import range_cal_config
    from calidar.cli.tpu import tpu_config

    assert range_cal_config(None, {}) == RangeCalConfig()
    assert ccr_config(None, {}) == CCRConfig(None, SearchSettings(), SystemParameters())
    assert tpu_config(None, {}) == TpuConfig()
