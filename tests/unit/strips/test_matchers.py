"""Matchers are objects (issue 29): a third one is one new class plus its name in the configuration
(:data:`calidar.strips.config.MATCHERS`); the calibrator, the report, the verdict and the TOML file
take it without a change, and no module branches on a matcher's name."""

from __future__ import annotations

import ast
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from calidar.pipelines.strip_config import StripConfig
from calidar.sensor import Sensor
from calidar.strips import config as strip_config
from calidar.strips.calibrate import calibrate
from calidar.strips.config import CalibrationConfig
from calidar.strips.planes import PlaneSettings, match_pair_planes
from calidar.strips.global_test import T_MODEL
from calidar.strips.matchers import Matcher
from strips_scene import survey

SRC = Path(__file__).resolve().parents[3] / "src" / "calidar"
TRUTH = Sensor(boresight_roll=np.radians(0.03), boresight_pitch=np.radians(-0.04), boresight_yaw=np.radians(0.05))
LINES = [((-250, -80, 0), 90, 500, 400), ((250, 80, 0), 270, 500, 400), ((0, -250, 0), 0, 500, 400)]
CALLS: list[tuple[int, int]] = []


@dataclass(frozen=True)
class EveryOtherPlane(Matcher):
    """The test double: tie planes, every other one kept (its own settings, threshold and label)."""

    name: ClassVar[str] = "every_other"
    label: ClassVar[str] = "every other tie plane"
    sigma0_reading: ClassVar[str] = T_MODEL  # how the global test reads its rows' σ0
    settings: PlaneSettings = field(default_factory=PlaneSettings)
    threshold_m: float = 5e-4

    def match(self, strip_a, points_a, strip_b, points_b):
        CALLS.append((strip_a, strip_b))
        c = match_pair_planes(strip_a, points_a, strip_b, points_b, self.settings)
        keep = np.arange(0, c.n_obs, 2)
        sigma = c.sigma_m[keep] if np.ndim(c.sigma_m) else c.sigma_m
        return replace(c, A=c.A[keep], B=c.B[keep], normal=c.normal[keep], sigma_m=sigma)


@pytest.fixture
def registered(monkeypatch):
    """The configuration's one change: the new matcher's name."""
    monkeypatch.setitem(strip_config.MATCHERS, EveryOtherPlane.name, EveryOtherPlane)


def test_a_third_matcher_is_one_class_and_its_name(registered, tmp_path):
    from calidar.report import Report
    from calidar.strips.report import QualityStage, add_report_section
    from calidar.strips.verdict import strip_verdict

    strips = survey(TRUTH, Sensor(), LINES, n=60_000, noise=0.03)
    CALLS.clear()
    result = calibrate(strips, Sensor(), CalibrationConfig(matchers=(EveryOtherPlane(),)))
    assert CALLS and set(CALLS) <= {(1, 2), (1, 3), (2, 3)}  # every pair matched by the double
    assert result.method == "every_other" and result.solution.extra["strips"]["method"] == "every_other"
    for name in ("boresight_roll", "boresight_pitch", "boresight_yaw"):
        err = result.solution.values[name] - getattr(TRUTH, name)
        assert abs(err) < 3 * result.solution.sigma[name] and abs(np.degrees(err)) < 0.005, name
    outer = [o["mean_distance_m"] for o in result.outer]
    assert len(outer) == 1 or abs(outer[-1] - outer[-2]) < 5e-4  # its own threshold stopped the loop
    stages = [QualityStage("as delivered", "", []), QualityStage("new mounting", "", [])]  # none measured here
    assert "every other tie plane" in strip_verdict(result, stages).summary
    report = Report("test")
    add_report_section(report, result, None, stages)
    assert any("every other tie plane" in b for b in report.sections[-1].blocks)
    # the configuration file names it, and gives it back with its settings
    path = tmp_path / "config.toml"
    path.write_text('method = ["every_other", "planes"]\n\n[every_other]\nthreshold_m = 0.001\nmax_rms_m = 0.05\n')
    matchers = StripConfig.read(path).calibration.matchers
    assert matchers[0] == EveryOtherPlane(PlaneSettings(max_rms_m=0.05), threshold_m=0.001)
    assert StripConfig.read(StripConfig(CalibrationConfig(matchers=matchers)).write(tmp_path / "again.toml")) \
        .calibration.matchers == matchers


def _names_compared(path: Path) -> list[str]:
    """Where ``path`` compares a value with a matcher's name, or keys a dict by one."""
    names = set(strip_config.MATCHERS)
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        consts = []
        if isinstance(node, ast.Compare):
            consts = [n for n in [node.left, *node.comparators] if isinstance(n, ast.Constant)]
        elif isinstance(node, ast.Dict):
            consts = [k for k in node.keys if isinstance(k, ast.Constant)]
        found += [f"{node.lineno}: {c.value!r}" for c in consts if c.value in names]
    return found


def test_no_module_branches_on_a_matchers_name():
    own = {"strips/matchers.py", "strips/config.py"}
    found = {p.relative_to(SRC).as_posix(): f for p in sorted(SRC.rglob("*.py"))
             if p.relative_to(SRC).as_posix() not in own and (f := _names_compared(p))}
    assert found == {}, f"branches on a matcher's name (give the matcher the behaviour instead): {found}"


def test_a_matcher_must_say_how_its_sigma0_is_read():
    """A new kind without ``sigma0_reading`` is refused where it is written, not at the global
    test; ``holds_gil`` has its default (threads, not processes)."""
    with pytest.raises(TypeError, match="does not declare sigma0_reading"):
        class Silent(Matcher):
            name: ClassVar[str] = "silent"
            label: ClassVar[str] = "silent rows"
    assert EveryOtherPlane.holds_gil is False
