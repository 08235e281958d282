"""The typed configurations of every command but boresight (issue 29): each is checked when made,
written as the TOML file a user keeps and read back equal; a bad value in the file names the file, the
key and its option; options on the command line replace the file's settings."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from calidar.errors import InputError
from calidar.photon.passes import SystemParameters
from calidar.photon.search import SearchSettings
from calidar.pipelines.ccr_config import CCRConfig
from calidar.pipelines.inputs import PointOptions, TrajectoryOptions
from calidar.pipelines.rangecal_config import RangeCalConfig
from calidar.pipelines.tpu_config import TpuConfig
from calidar.tpu.propagate import TpuSettings
from calidar.pipelines.accuracy import AccuracySettings
from calidar.pipelines.accuracy_config import AccuracyConfig
from calidar.pipelines.denoise import DenoiseConfig
from calidar.pipelines.georef import GeorefConfig
from calidar.pipelines.plan import PlanOptions, TerrainChoice
from calidar.pipelines.plan_config import PlanConfig
from calidar.pipelines.quality import QualityConfig
from calidar.pipelines.scanner_config import ScannerConfig
from calidar.pipelines.trajectory import TrajectorySettings
from calidar.pipelines.trajectory_config import TrajectoryConfig
from calidar.scanners.settings import AnalysisSettings
from calidar.strips.config import Estimate
from calidar.strips.quality import QualitySettings

CONFIGS = [
    RangeCalConfig(), RangeCalConfig(tolerance_m=0.05, fix_scale=True),
    CCRConfig(), CCRConfig(("gt1l", "gt3r"), SearchSettings(8.5, 14.0, bootstrap=7, seed=3, shared_bias=True),
                           SystemParameters(dead_time=3.3 * 1e-9, channels=4, pointing_jitter=0.1)),
    TpuConfig(), TpuConfig(TpuSettings(0.02, math.radians(0.003), 0.3 * 1e-3, 1.5), (0.04, math.radians(0.004)),
                           PointOptions("EPSG:32632", "week", 47.3), TrajectoryOptions("EPSG:32632", "rad", "grid",
                                                                                       ("time", "x", "y"))),
    QualityConfig(), QualityConfig(QualitySettings(cell_m=3.0), (2, 6), PointOptions("EPSG:32632", "adjusted", -3.5)),
    AccuracyConfig(), AccuracyConfig(AccuracySettings("EPSG:6340", 0.03, 8.0, 6.0, 10.0, (2, 8), True)),
    PlanConfig(), PlanConfig(PlanOptions(TerrainChoice("dem", path=Path("dem.tif")), 30_000.0, 60.0, 0.02, 0.004,
                                         Estimate.of("boresight", "lever_arm_z"), (0.05, 1e-4), False, 3, (0.01, 0.02))),
    ScannerConfig(AnalysisSettings("linear", 80.0)),
    ScannerConfig(AnalysisSettings("wedge", 80.0, {"axis_tilt": 0.5, "wedge_angle_error": -0.1}, wedge_angle_deg=15.0)),
    DenoiseConfig(), DenoiseConfig(("gt2r", "gt1l"), 0.8),
    GeorefConfig(), GeorefConfig("EPSG:32611", 12.5),
    TrajectoryConfig(), TrajectoryConfig(replace(TrajectorySettings(), rate_hz=20.0, points_per_s=300.0),
                                         PointOptions(time_system="week")),
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
    (CCRConfig, "[search]\ndiameter_min = 20.0\n", "search.diameter_min (--diameter-range): expected MIN < MAX"),
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
    (TpuConfig, '[inputs]\ntime_system = "utc"\n', "inputs.time_system (--time-system): expected one of"),
    (TpuConfig, '[inputs]\ntrajectory_angles = "grad"\n', "inputs.trajectory_angles (--trajectory-angles): expected deg or rad, "
                                                             "got 'grad'"),
    (TpuConfig, '[inputs]\ntrajectory_columns = "time,x,y"\n', "inputs.trajectory_columns: expected a list"),
    (TpuConfig, "noise = [1]\n", "noise: expected a table [noise]"),
    (QualityConfig, "cell_m = 0.0\n", "cell_m (--cell): expected a finite number in [0.01, 1000] m, got 0.0"),
    (QualityConfig, "classes = [2, 300]\n", "classes (--classes): expected LAS classes"),
    (QualityConfig, '[inputs]\ncrs = "EPSG:0"\n', "inputs.crs (--crs): expected a CRS pyproj knows"),
    (AccuracyConfig, "max_edge_m = 1e6\n", "max_edge_m (--max-edge): expected a finite number in [0.1, 100] m"),
    (AccuracyConfig, "swaths = 1\n", "swaths: expected bool, got 1"),
    (PlanConfig, "simulate = 1000\n", "simulate (--simulate): expected 0 to 200"),
    (PlanConfig, "platform_motion_rad = [0.01]\n", "platform_motion_rad: expected a list of 2 values"),
    (PlanConfig, '[terrain]\nkind = "dem"\n', "terrain.kind (--terrain): expected flat, scene or dem"),
    (ScannerConfig, 'model = "wedge"\nrange_m = -5.0\n', "range_m (--range): expected a finite number in (0,"),
    (ScannerConfig, 'model = "linear"\nrange_m = 50.0\npoints = 2\n', "points (--points): expected an integer"),
    (ScannerConfig, 'model = "linear"\nrange_m = 50.0\n\n[errors]\nspin = 1.0\n', "errors.spin: unknown key"),
    (DenoiseConfig, 'beams = "all"\n', "beams: expected a list"),
    (DenoiseConfig, "shot_spacing_m = 50.0\n", "shot_spacing_m (--shot-spacing-m): expected a finite number in [0.05,"),
    (GeorefConfig, 'crs = "EPSG:0"\n', "crs (--crs): expected a CRS"),
    (TrajectoryConfig, "knot_s = 100.0\n", "knot_s (--knot-spacing): expected a finite number in [0.02, 10] s"),
    (TrajectoryConfig, "scan_plane_yaw_rad = 2.0\n", "scan_plane_yaw_rad (--scan-plane-yaw)"),
    (TrajectoryConfig, "[mount_sigma]\nscan_cone_rad = -0.1\n", "mount_sigma.scan_cone_rad (--scan-plane-sigma)"),
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


def test_options_given_replace_the_files_settings_of_every_command(tmp_path):
    """The options (their parameters' values, as typer gives them) on a file of each command's configuration:
    the option's value replaces its key, the file's other keys stay, a bad option is named by the option."""
    from calidar.cli.accuracy import OPTIONS as ACCURACY
    from calidar.cli.common import config_values
    from calidar.cli.denoise import OPTIONS as DENOISE
    from calidar.cli.quality import OPTIONS as QUALITY
    from calidar.cli.scanner import OPTIONS as SCANNER
    from calidar.cli.trajectory import OPTIONS as TRAJECTORY

    for cls, options, config, given, check in (
            (QualityConfig, QUALITY, QualityConfig(QualitySettings(cell_m=3.0), (2,)), {"classes": "6, 2"},
             lambda c: c.settings.cell_m == 3.0 and c.classes == (2, 6)),
            (AccuracyConfig, ACCURACY, AccuracyConfig(AccuracySettings(radius_m=8.0, survey_sigma_m=0.03)),
             {"radius": 6.0, "crs": "EPSG:32632"},
             lambda c: c.settings.radius_m == 6.0 and c.settings.survey_sigma_m == 0.03 and c.points.crs == "EPSG:32632"),
            (ScannerConfig, SCANNER, ScannerConfig(AnalysisSettings("palmer", 100.0, {"delta_l": 0.01})),
             {"delta_r": 0.02, "range_m": 50.0},
             lambda c: c.settings.errors == {"delta_l": 0.01, "delta_r": 0.02} and c.settings.range_m == 50.0),
            (DenoiseConfig, DENOISE, DenoiseConfig(("gt1l",), 0.8), {"beam": "all"},
             lambda c: c.beams is None and c.shot_spacing_m == 0.8),
            (TrajectoryConfig, TRAJECTORY, TrajectoryConfig(replace(TrajectorySettings(), rate_hz=20.0)),
             {"no_scan_angles": True, "scan_plane_yaw": 13.96},
             lambda c: c.settings.rate_hz == 20.0 and not c.settings.fit.use_scan_angles
             and c.settings.fit.scan_plane_yaw == math.radians(13.96))):
        path = config.write(tmp_path / f"{cls.__name__}.toml")
        assert cls.configure(path, {}) == config
        assert check(cls.configure(path, config_values(given, options))), cls.__name__
    path = QualityConfig(QualitySettings(cell_m=3.0)).write(tmp_path / "q.toml")
    with pytest.raises(InputError, match=r"^--cell: expected a finite number"):
        QualityConfig.configure(path, {"settings.cell_m": -1.0})


def test_each_nested_value_is_put_in_once():
    """A cross-field check sees every value of the file at once (diameter_min above the default maximum is
    fine with the file's own maximum), whatever the order of the keys."""
    config = CCRConfig.configure_values({"search.diameter_min": 16.0, "search.diameter_max": 20.0}, {}, "mine.toml")
    assert (config.search.diameter_min, config.search.diameter_max) == (16.0, 20.0)


def test_the_command_lines_defaults_are_the_configurations():
    """Without --config and options, each command runs with its configuration's defaults."""
    from calidar.cli.ccr import ccr_config
    from calidar.cli.rangecal import range_cal_config
    from calidar.cli.tpu import tpu_config

    assert range_cal_config(None, {}) == RangeCalConfig()
    assert ccr_config(None, {}) == CCRConfig(None, SearchSettings(), SystemParameters())
    assert tpu_config(None, {}) == TpuConfig()
    for cls in (QualityConfig, AccuracyConfig, PlanConfig, DenoiseConfig, GeorefConfig, TrajectoryConfig):
        assert cls.configure(None, {}) == cls()
