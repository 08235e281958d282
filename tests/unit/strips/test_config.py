"""The strip calibration's one configuration (issue 29): typed values checked when made, a TOML
file that gives the same configuration back, the command line's options on top of it, and no
option string parsed below the CLI."""

from __future__ import annotations

import ast
import math
from dataclasses import replace
from pathlib import Path

import pytest

from calidar.errors import InputError
from calidar.io.las import PointOptions
from calidar.pipelines.inputs import TrajectoryOptions
from calidar.pipelines.strip_config import StripConfig
from calidar.ingest.settings import IngestSettings
from calidar.adjust import SolverOptions
from calidar.strips.config import CalibrationConfig, Estimate, StripSettings, TiePlanes, TrajectorySettings, Vgicp
from calidar.strips.planes import PlaneSettings
from calidar.strips.vgicp import VgicpSettings

SRC = Path(__file__).resolve().parents[3] / "src" / "calidar"
#: modules that still parse names with a regular expression, each with its issue (the set only shrinks;
#: empty since the trajectory knots are addressed by TrajectoryModel.layout everywhere, issue 29)
REGEX_ALLOWANCE: set[str] = set()


#: the library below the CLI that takes a typed configuration: none of it parses an option string
SCANNED = ("strips", "adjust", "planning", "ingest", "rangecal", "photon", "tpu", "scanners", "pipelines")


#: single modules of io held to it too: the ATL03 reader takes the beams as a tuple (--beam parsed at the edge)
SCANNED_MODULES = ("io/atl03.py",)


def _library_modules():
    return sorted([*(p for package in SCANNED for p in (SRC / package).glob("*.py")),
                   *(p for m in SCANNED_MODULES if (p := SRC / m).is_file())])


def _option_parsing(path: Path) -> list[str]:
    """Where ``path`` parses option strings: a split on a comma or semicolon, float()/int() of a
    parameter annotated str, a parse_* helper of calidar.validate or the CLI, a regular expression."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for fn in ast.walk(tree):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        strs = {a.arg for a in [*fn.args.args, *fn.args.kwonlyargs]
                if a.annotation is not None and ast.unparse(a.annotation).replace(" ", "") in ("str", "str|None")}
        for node in ast.walk(fn):
            if not isinstance(node, ast.Call):
                continue
            f = node.func
            if isinstance(f, ast.Attribute) and f.attr in ("split", "rsplit") and node.args \
                    and isinstance(node.args[0], ast.Constant) and node.args[0].value in (",", ";"):
                found.append(f"{fn.name}:{node.lineno}: .split({node.args[0].value!r})")
            if isinstance(f, ast.Name) and f.id in ("float", "int") and node.args \
                    and isinstance(node.args[0], ast.Name) and node.args[0].id in strs:
                found.append(f"{fn.name}:{node.lineno}: {f.id}() of the str {node.args[0].id}")
            name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
            if name in ("parse_floats", "parse_estimate", "parse_methods", "parse_sigma"):
                found.append(f"{fn.name}:{node.lineno}: {name}()")
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [a.name for a in node.names] + ([node.module] if isinstance(node, ast.ImportFrom) else [])
            if "re" in names and path.relative_to(SRC).as_posix() not in REGEX_ALLOWANCE:
                found.append(f"{node.lineno}: import re")
    return found


def test_nothing_below_the_cli_parses_option_strings():
    found = {p.relative_to(SRC).as_posix(): f for p in _library_modules() if (f := _option_parsing(p))}
    assert found == {}, f"option strings parsed below the CLI: {found}"


def test_the_scan_finds_what_it_looks_for(tmp_path):
    """The scan above is no empty check: each kind of parsing it names is found."""
    bad = tmp_path / "bad.py"
    bad.write_text("import re\n\ndef f(text: str, sigma: str | None = None):\n"
                   "    a, b = text.split(',')\n    return float(sigma), parse_floats(text, 2, 'x')\n")
    global SRC
    old, SRC = SRC, tmp_path
    try:
        found = _option_parsing(bad)
    finally:
        SRC = old
    assert [f.split(": ", 1)[1] for f in found] == [".split(',')", "float() of the str sigma", "parse_floats()",
                                                     "import re"]


def test_regex_allowance_names_only_what_still_breaks():
    for rel in REGEX_ALLOWANCE:
        assert "import re" in (SRC / rel).read_text(encoding="utf-8"), f"{rel} no longer uses re: drop it"


def test_the_configurations_have_no_untyped_fields():
    import dataclasses

    from calidar.pipelines.boresight import BoresightInputs
    from calidar.pipelines.quality import QualityConfig
    from calidar.strips.quality import QualitySettings

    for cls in (StripConfig, CalibrationConfig, StripSettings, TrajectorySettings, Estimate, TiePlanes, Vgicp,
                BoresightInputs, SolverOptions, QualityConfig, QualitySettings):
        untyped = [f.name for f in dataclasses.fields(cls) if "object" in str(f.type) or f.type in ("", "Any")]
        assert not untyped, (cls.__name__, untyped)


def _everything_changed() -> StripConfig:
    """A configuration that differs from the defaults in every section."""
    cal = CalibrationConfig(
        Estimate.of("boresight", "lever_arm_x", "range_scale"),
        (Vgicp(VgicpSettings(voxel_m=(4.0, 1.0), num_neighbors=10, pair_distance_m=0.2), threshold_m=5e-4),
         TiePlanes(PlaneSettings(cell_m=2.0, max_rms_m=0.05))),
        TrajectorySettings(block_s=2.0, correlation_s=(30.0, 5.0), sigma=(0.03, math.radians(0.002))),
        StripSettings(overlap_cell_m=4.0, max_outer=3, threshold_m=1e-3, cluster_s=None,
                      adjustment=SolverOptions(robust=None, robust_scale=False, max_iter=20, tol=1e-9,
                                               covariance="sandwich")), model_check=False)
    return StripConfig(cal, IngestSettings(budget_points=None, block_cells=3, gap_s=5.0,
                                          points=PointOptions("EPSG:32632", "adjusted", 47.5)),
                       TrajectoryOptions("EPSG:32615", "rad", "grid", ("time", "-", "lat")), "EPSG:4326")


@pytest.mark.parametrize("config", [StripConfig(), _everything_changed(),
                                    StripConfig(CalibrationConfig(trajectory=None))], ids=["defaults", "all", "off"])
def test_the_file_gives_the_same_configuration_back(config, tmp_path):
    path = config.write(tmp_path / "config.toml")
    back = StripConfig.read(path)
    assert back.calibration.estimate == config.calibration.estimate
    assert back.calibration.matchers == config.calibration.matchers
    t, u = back.calibration.trajectory, config.calibration.trajectory
    assert (t is None) == (u is None)
    if t is not None:  # the attitude σ is written in degrees: back to 1 ulp
        assert (t.block_s, t.correlation_s) == (u.block_s, u.correlation_s)
        assert t.sigma == u.sigma or t.sigma == pytest.approx(u.sigma, rel=1e-15)
    assert back.calibration.solver == config.calibration.solver
    assert back.calibration.model_check == config.calibration.model_check
    assert back.ingest == config.ingest and back.trajectory_input == config.trajectory_input
    assert back.control_crs == config.control_crs


@pytest.mark.parametrize("text, key, what", [
    ("[solver]\nmax_outer = 8\nwobble = 1\n", "solver.wobble", "unknown key"),
    ("colour = 1\n", "colour", "unknown key"),
    ("[trajectory_model]\nblock_s = \"one\"\n", "trajectory_model.block_s", "expected float"),
    ("[solver]\nmax_outer = 2.5\n", "solver.max_outer", "expected int"),
    ("[planes]\ntarget_points = true\n", "planes.target_points", "expected int"),
    ("estimate = \"boresight\"\n", "estimate", "expected a list"),
    ("estimate = [\"boresight\", \"wobble\"]\n", "estimate", "wobble"),
    ("method = [\"planes\", \"planes\"]\n", "method", "each once"),
    ("[trajectory_model]\ncorrelation_s = [20.0, 0.0]\n", "trajectory_model", "--trajectory-correlation"),
    ("[trajectory_model]\nsigma = [0.03, 20.0]\n", "trajectory_model.sigma", "rad"),
    ("[vgicp]\nkind = \"plane_to_plane\"\n", "vgicp", "kind"),
    ("[vgicp]\nroughness_factor = -0.5\n", "vgicp", "roughness_factor"),
    ("[inputs]\ntime_system = \"fortnight\"\n", "inputs", "time-system"),
    ("[ingest]\nstrip_points = \"all\"\n", "ingest.strip_points", "expected int"),
    ("[solver]\nrobust = \"tukey\"\n", "solver.robust", "expected cauchy, huber or none"),
    ("[solver]\nmax_iter = -1\n", "solver", "max_iter"),
    ("[solver]\nadjustment = 1\n", "solver.adjustment", "unknown key"),
    ("[solver]\nstep_in_sigma = 0.1\n", "solver.step_in_sigma", "unknown key"),
    ("[solver]\ncovariance = \"hc0\"\n", "solver", "covariance must be one of"),
    ("model_check = \"yes\"\n", "model_check", "expected bool"),
])
def test_a_wrong_key_is_named_with_its_file(text, key, what, tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(text)
    with pytest.raises(InputError) as e:
        StripConfig.read(path)
    message = str(e.value)
    assert message.startswith(f"{path}: ") and key in message and what in message and "\n" not in message, message


def test_the_command_lines_defaults_are_the_configurations():
    from calidar.cli import boresight as cli
    from calidar.cli.boresight_config import strip_config

    defaults = TrajectorySettings()
    assert cli.TRAJECTORY_BLOCK_S == defaults.block_s
    assert tuple(float(v) for v in cli.TRAJECTORY_CORRELATION.split(",")) == defaults.correlation_s
    assert cli.BUDGET_POINTS == IngestSettings().budget_points
    assert strip_config(None, {}) == StripConfig()


def test_options_given_replace_the_files_settings(tmp_path):
    from calidar.cli.boresight_config import strip_config

    path = _everything_changed().write(tmp_path / "config.toml")
    kept = strip_config(path, {})
    assert kept.calibration.matchers == _everything_changed().calibration.matchers
    given = strip_config(path, {"method": "planes", "estimate": "boresight", "trajectory_sigma": "0.05,0.004",
                                "strip_points": 0, "crs": "EPSG:32633"})
    cal = given.calibration
    assert cal.matchers == (TiePlanes(PlaneSettings(cell_m=2.0, max_rms_m=0.05)),)  # the file's tie-plane settings
    assert cal.estimate == Estimate.of("boresight")
    assert cal.trajectory == replace(kept.calibration.trajectory, sigma=(0.05, math.radians(0.004)))
    assert given.ingest.budget_points is None and given.points.crs == "EPSG:32633"
    assert given.points.time_system == "gps_adjusted_standard" and given.ingest.block_cells == 3  # the file's
    assert strip_config(path, {"trajectory_model": "off"}).calibration.trajectory is None
    assert strip_config(path, {"model_check": "on"}).calibration.model_check is True  # the file's: off
    with pytest.raises(InputError, match="--model-check: expected on or off, got 'maybe'"):
        strip_config(path, {"model_check": "maybe"})
    with pytest.raises(InputError, match="--trajectory-model: is off, so --trajectory-accuracy and --trajectory-sigma"):
        strip_config(path, {"trajectory_model": "off", "trajectory_sigma": "0.03,0.002"})


@pytest.mark.parametrize("module", ["calidar.strips.config", "calidar.pipelines.strip_config"])
def test_the_configurations_examples_run(module, tmp_path, monkeypatch):
    import doctest
    import importlib
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    result = doctest.testmod(importlib.import_module(module), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0, result


def test_the_engine_reads_on_the_solvers_overlap_grid():
    """One overlap grid: the streaming engine's settings (``config.ingest``, handed to it whole) carry the
    solver's cell and minimum of common cells, however the configuration was made or changed."""
    solver = StripSettings(overlap_cell_m=3.0, min_overlap_cells=6)
    config = StripConfig(CalibrationConfig(solver=solver), IngestSettings(budget_points=50_000))
    assert (config.ingest.cell_m, config.ingest.min_cells, config.ingest.budget_points) == (3.0, 6, 50_000)
    changed = replace(config, calibration=replace(config.calibration, solver=StripSettings(overlap_cell_m=7.5)))
    assert (changed.ingest.cell_m, changed.ingest.min_cells) == (7.5, StripSettings().min_overlap_cells)
    assert StripConfig().ingest.cell_m == StripSettings().overlap_cell_m
